//! Command line: run a scene, pack an FMU; with the `studies` feature also the paper's cases,
//! the benchmark and case 3 (src/bin/mps/studies.rs).
use clap::{Parser, Subcommand, ValueEnum};
#[cfg(feature = "studies")]
mod studies;
use indicatif::{ProgressBar, ProgressStyle};
use mps_solid::physics::ElasticModel;
use mps_solid::runner::{energy_csv, run_scene_with, series_csv, RunEvent, RunOptions};
use mps_solid::Scene;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "mps",
    version,
    about = "MPS particle solver for elastic solids (Amaro Junior, Cheng & Tsukamoto)"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Clone, Copy, ValueEnum)]
enum Model {
    SecondOrder,
    Corrected,
    Paper,
    PaperLocal,
}

impl From<Model> for ElasticModel {
    fn from(m: Model) -> Self {
        match m {
            Model::SecondOrder => ElasticModel::SecondOrder,
            Model::Corrected => ElasticModel::Corrected,
            Model::Paper => ElasticModel::Paper,
            Model::PaperLocal => ElasticModel::PaperLocal,
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a scene file (JSON or TOML): probe series as CSV, a summary, optionally JSON.
    Run {
        scene: PathBuf,
        /// Directory for probes.csv and summary.json (and energy.csv).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Also write energy.csv: kinetic, strain and contact energy and their sum at every
        /// output sample (a serial pass over the bonds per sample).
        #[arg(long)]
        energy: bool,
        /// Also write the bodies' surfaces as meshes with their displacements for ParaView:
        /// surface_NNNN.vtu (triangles; lines in 2D) at up to 101 evenly spaced output samples
        /// and surface.pvd listing them with their times.
        #[arg(long)]
        surface: bool,
        /// Print the result (including the series) as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Pack a scene into an FMI 2.0 co-simulation FMU.
    Pack {
        /// Scene files (JSON or TOML); one FMU each.
        #[arg(required = true)]
        scenes: Vec<PathBuf>,
        /// Output file of a single scene (default: <scene name>.fmu).
        #[arg(long, conflicts_with = "out_dir")]
        out: Option<PathBuf>,
        /// Directory for the FMUs, <scene name>.fmu each.
        #[arg(long)]
        out_dir: Option<PathBuf>,
        /// The built library (default: libmps_solid.so next to this program).
        #[arg(long)]
        lib: Option<PathBuf>,
        /// Write each scene's modelDescription.xml (without its generation time) as DIR/<name>.xml.
        #[arg(long, value_name = "DIR", conflicts_with = "check_xml")]
        write_xml: Option<PathBuf>,
        /// Fail when DIR/<name>.xml differs from the scene's generated modelDescription.xml.
        #[arg(long, value_name = "DIR")]
        check_xml: Option<PathBuf>,
        /// Only write or check the XML (--write-xml / --check-xml); pack nothing.
        #[arg(long)]
        xml_only: bool,
    },
    #[cfg(feature = "studies")]
    #[command(flatten)]
    Study(studies::StudyCmd),
}

fn progress(len: f64, label: &str) -> ProgressBar {
    let pb = ProgressBar::new((len * 1e6) as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:>24} [{bar:40}] {percent:>3}% {elapsed_precise} eta {eta}",
        )
        .unwrap()
        .progress_chars("=> "),
    );
    pb.set_message(label.to_string());
    pb
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode, String> {
    match cli.cmd {
        Cmd::Run {
            scene,
            out,
            energy,
            surface,
            json,
        } => {
            let sc = Scene::load(&scene).map_err(|e| e.to_string())?;
            // The output files are opened before the run, so an unusable --out fails now.
            std::fs::create_dir_all(&out)
                .map_err(|e| format!("cannot create the directory {}: {e}", out.display()))?;
            let csv = out.join("probes.csv");
            let summary_path = out.join("summary.json");
            let energy_path = out.join("energy.csv");
            let open = |p: &std::path::Path| {
                std::fs::File::create(p).map_err(|e| format!("cannot write {}: {e}", p.display()))
            };
            let (mut csv_file, mut summary_file) = (open(&csv)?, open(&summary_path)?);
            let mut energy_file = if energy {
                Some(open(&energy_path)?)
            } else {
                None
            };
            let pb = progress(sc.end_time, &sc.name);
            // --surface: the mesh is made at the first state, then written every `stride`
            // samples (at most 101 files).
            let samples = (sc.end_time / sc.output_interval - 1e-9).ceil().max(1.0) as u64;
            let stride = samples.div_ceil(100).max(1);
            let mut mesh = None;
            let mut pvd = mps_solid::output::PvdWriter::new();
            let mut state_index = 0u64;
            let mut surface_error: Option<String> = None;
            let r = run_scene_with(&sc, RunOptions { energy }, |e| match e {
                RunEvent::Warning(w) => pb.suspend(|| eprintln!("warning: {w}")),
                RunEvent::Sample(t) => pb.set_position((t * 1e6) as u64),
                RunEvent::State(sim) => {
                    let k = state_index;
                    state_index += 1;
                    if !surface
                        || surface_error.is_some()
                        || (!k.is_multiple_of(stride) && k != samples)
                    {
                        return;
                    }
                    if mesh.is_none() {
                        match sim.surface_mesh(&sc) {
                            Ok(m) => mesh = Some(m),
                            Err(e) => {
                                surface_error = Some(e.to_string());
                                return;
                            }
                        }
                    }
                    let m = mesh.as_ref().expect("made above");
                    let name = format!(
                        "surface_{:04}.vtu",
                        k / stride + u64::from(!k.is_multiple_of(stride))
                    );
                    let path = out.join(&name);
                    match mps_solid::output::write_surface_vtu(
                        &path,
                        m,
                        &sim.surface_displacement(m),
                        sim.time(),
                    ) {
                        Ok(()) => pvd.add(sim.time(), name),
                        Err(e) => surface_error = Some(e),
                    }
                }
            });
            pb.finish_and_clear();
            if let Some(e) = &surface_error {
                return Err(format!("--surface: {e}"));
            }
            if surface && r.is_ok() {
                let p = out.join("surface.pvd");
                pvd.write(&p)?;
            }
            let r = r.inspect_err(|_| {
                // Leave no empty output files behind a refused run.
                let _ = std::fs::remove_file(&csv);
                let _ = std::fs::remove_file(&summary_path);
                if energy {
                    let _ = std::fs::remove_file(&energy_path);
                }
            })?;
            use std::io::Write;
            csv_file
                .write_all(series_csv(&r.series, r.dimension).as_bytes())
                .map_err(|e| format!("cannot write {}: {e}", csv.display()))?;
            if let Some(f) = &mut energy_file {
                f.write_all(energy_csv(&r.series).as_bytes())
                    .map_err(|e| format!("cannot write {}: {e}", energy_path.display()))?;
            }
            let mut summary = serde_json::to_value(&r).expect("serialisable");
            summary.as_object_mut().expect("object").remove("series");
            summary_file
                .write_all(serde_json::to_string_pretty(&summary).unwrap().as_bytes())
                .map_err(|e| format!("cannot write {}: {e}", summary_path.display()))?;
            if json {
                println!("{}", serde_json::to_string(&r).unwrap());
            } else {
                println!(
                    "{}: {} particles, {} bonds, {} steps of {:.3e} s (critical {:.3e} s) to t = {} s in {:.2} s ({:.3e} pair-updates/s)",
                    r.scene, r.particles, r.bonds, r.steps, r.dt, r.critical_dt, r.end_time, r.wall_time_s, r.pair_updates_per_s
                );
                for (name, u) in &r.final_displacement {
                    println!(
                        "  probe {name}: u = [{:.6e}, {:.6e}, {:.6e}] m",
                        u[0], u[1], u[2]
                    );
                }
                if let (Some(f), Some(p)) = (r.frequency_hz, r.peak_m) {
                    println!("  frequency {f:.4} Hz, peak {p:.6e} m");
                }
                println!("  series written to {}", csv.display());
                if energy {
                    println!("  energies written to {}", energy_path.display());
                }
            }
            if let Some(e) = &r.error {
                eprintln!("error: the run stopped early: {e}");
                return Ok(ExitCode::FAILURE);
            }
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Pack {
            scenes,
            out,
            out_dir,
            lib,
            write_xml,
            check_xml,
            xml_only,
        } => {
            if out.is_some() && scenes.len() > 1 {
                return Err("--out names one file: with several scenes use --out-dir".into());
            }
            let lib = match lib {
                Some(l) => l,
                None => std::env::current_exe()
                    .map_err(|e| format!("cannot locate this program (for --lib): {e}"))?
                    .with_file_name("libmps_solid.so"),
            };
            let mut failed = false;
            for scene in &scenes {
                if let Err(e) = pack_one(
                    scene,
                    &lib,
                    out.as_deref(),
                    out_dir.as_deref(),
                    write_xml.as_deref(),
                    check_xml.as_deref(),
                    xml_only,
                ) {
                    if scenes.len() == 1 {
                        eprintln!("error: {e}");
                    } else {
                        eprintln!("error: {}: {e}", scene.display());
                    }
                    failed = true;
                }
            }
            Ok(if failed {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            })
        }
        #[cfg(feature = "studies")]
        Cmd::Study(cmd) => studies::run(cmd),
    }
}

/// `mps pack` of one scene: the FMU (unless `xml_only`), then the modelDescription.xml written
/// or checked against DIR/<name>.xml (the canonical form, without generationDateAndTime).
fn pack_one(
    scene: &std::path::Path,
    lib: &std::path::Path,
    out: Option<&std::path::Path>,
    out_dir: Option<&std::path::Path>,
    write_xml: Option<&std::path::Path>,
    check_xml: Option<&std::path::Path>,
    xml_only: bool,
) -> Result<(), String> {
    use mps_solid::fmi::pack::{model_description_xml, pack_fmu, same_file};
    let sc = Scene::load(scene).map_err(|e| e.to_string())?;
    if !xml_only {
        let out = match (out, out_dir) {
            (Some(o), _) => o.to_path_buf(),
            (None, Some(d)) => d.join(format!("{}.fmu", sc.name)),
            (None, None) => PathBuf::from(format!("{}.fmu", sc.name)),
        };
        if out == scene || same_file(&out, scene) {
            return Err(format!(
                "--out {} is the scene file itself; choose another output",
                out.display()
            ));
        }
        for w in sc.warnings() {
            eprintln!("warning: {w}");
        }
        if let Some(d) = out_dir {
            std::fs::create_dir_all(d)
                .map_err(|e| format!("cannot create the directory {}: {e}", d.display()))?;
        }
        pack_fmu(&sc, lib, &out)?;
        println!("wrote {}", out.display());
    }
    let xml = model_description_xml(&sc);
    if let Some(dir) = write_xml {
        let f = dir.join(format!("{}.xml", sc.name));
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create the directory {}: {e}", dir.display()))?;
        std::fs::write(&f, &xml).map_err(|e| format!("cannot write {}: {e}", f.display()))?;
        println!("wrote {}", f.display());
    }
    if let Some(dir) = check_xml {
        let f = dir.join(format!("{}.xml", sc.name));
        match std::fs::read_to_string(&f) {
            Ok(committed) if committed == xml => println!("{} is up to date", f.display()),
            Ok(_) => {
                return Err(format!(
                    "{} is stale: regenerate it with `mps pack --xml-only --write-xml {} {}`",
                    f.display(),
                    dir.display(),
                    scene.display()
                ))
            }
            Err(e) => {
                return Err(format!(
                    "{}: {e} (generate it with --write-xml)",
                    f.display()
                ))
            }
        }
    }
    Ok(())
}
