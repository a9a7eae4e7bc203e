//! Packs scene files into FMUs and keeps modelDescription/<scene>.xml in step with them.
//!
//! ```text
//! cargo run --release --example pack_scenes -- --lib target/release/libmps_solid.so \
//!     --out target/fmu [--write-xml modelDescription | --check-xml modelDescription] SCENE...
//! ```
//! `--check-xml DIR` fails (exit 1) when DIR/<name>.xml differs from the generated XML;
//! `--write-xml DIR` rewrites them. Without `--lib`/`--out` nothing is packed. The XML files are
//! the canonical form, without the `generationDateAndTime` that packed FMUs carry (from
//! `SOURCE_DATE_EPOCH` when set, else the time of packing).
use mps_solid::fmi::pack::{model_description_xml, pack_fmu};
use mps_solid::Scene;
use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let (mut lib, mut out, mut write_xml, mut check_xml) = (None, None, None, None);
    let mut scenes = Vec::new();
    while let Some(a) = args.next() {
        let mut value = |name: &str| {
            args.next()
                .map(PathBuf::from)
                .unwrap_or_else(|| panic!("{name} needs a value"))
        };
        match a.as_str() {
            "--lib" => lib = Some(value("--lib")),
            "--out" => out = Some(value("--out")),
            "--write-xml" => write_xml = Some(value("--write-xml")),
            "--check-xml" => check_xml = Some(value("--check-xml")),
            "-h" | "--help" => {
                eprintln!("usage: pack_scenes [--lib LIB --out DIR] [--write-xml DIR | --check-xml DIR] SCENE...");
                return ExitCode::SUCCESS;
            }
            _ => scenes.push(PathBuf::from(a)),
        }
    }
    if scenes.is_empty() {
        eprintln!("pack_scenes: no scene files given");
        return ExitCode::FAILURE;
    }
    let mut failed = false;
    for path in &scenes {
        let scene = match Scene::load(path) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("{}: {e}", path.display());
                failed = true;
                continue;
            }
        };
        if let (Some(lib), Some(out)) = (&lib, &out) {
            let fmu = out.join(format!("{}.fmu", scene.name));
            match pack_fmu(&scene, lib, &fmu) {
                Ok(()) => println!("packed {}", fmu.display()),
                Err(e) => {
                    eprintln!("{}: {e}", path.display());
                    failed = true;
                }
            }
        }
        let xml = model_description_xml(&scene);
        if let Some(dir) = &write_xml {
            let f = dir.join(format!("{}.xml", scene.name));
            std::fs::create_dir_all(dir).expect("create the XML directory");
            std::fs::write(&f, &xml).expect("write the XML");
            println!("wrote {}", f.display());
        }
        if let Some(dir) = &check_xml {
            let f = dir.join(format!("{}.xml", scene.name));
            match std::fs::read_to_string(&f) {
                Ok(committed) if committed == xml => println!("{} is up to date", f.display()),
                Ok(_) => {
                    eprintln!(
                        "{} is stale: regenerate with `cargo run --release --example pack_scenes -- --write-xml {} {}`",
                        f.display(),
                        dir.display(),
                        path.display()
                    );
                    failed = true;
                }
                Err(e) => {
                    eprintln!("{}: {e} (generate it with --write-xml)", f.display());
                    failed = true;
                }
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
