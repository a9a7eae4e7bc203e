//! Build script: the source id of the library, a checksum of every file of src/ except the
//! command line (src/bin), as the environment variable MPS_SOURCE_ID of the crate. The FMU's
//! library carries it (src/fmi/source_id.rs) and `mps pack` packs only a library whose id is
//! its own: a library built from other sources could number its variables differently from the
//! modelDescription.xml that this `mps` writes.
use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("build.rs: cannot list {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            files(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let src = root.join("src");
    let bin = src.join("bin");
    let mut all = Vec::new();
    files(&src, &mut all);
    all.retain(|p| !p.starts_with(&bin));
    let mut hasher = crc32fast::Hasher::new();
    let mut bytes = 0u64;
    for p in &all {
        let rel = p.strip_prefix(&root).expect("under the root");
        let data = std::fs::read(p)
            .unwrap_or_else(|e| panic!("build.rs: cannot read {}: {e}", p.display()));
        hasher.update(rel.to_string_lossy().as_bytes());
        hasher.update(&[0]);
        hasher.update(&(data.len() as u64).to_le_bytes());
        hasher.update(&data);
        bytes += data.len() as u64;
        println!("cargo:rerun-if-changed={}", p.display());
    }
    // Files, not directories: cargo scans a directory recursively, so src/ would take in
    // src/bin and a change of the command line alone would rebuild the library. A new module
    // is named in a file listed here, whose change reruns this script.
    println!(
        "cargo:rustc-env=MPS_SOURCE_ID={:08x}{:08x}",
        hasher.finalize(),
        bytes as u32
    );
}
