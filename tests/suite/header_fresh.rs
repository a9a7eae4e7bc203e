//! include/mps_fmi.h is what cbindgen makes of src/fmi/ffi.rs today (regenerate it with
//! `MPS_BLESS=1 cargo test --release --test suite header_fresh::`).
use std::path::PathBuf;

#[test]
fn header_is_fresh() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(root.join("cbindgen.toml")).expect("cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_crate(&root)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header");
    let mut fresh = Vec::new();
    bindings.write(&mut fresh);
    let fresh = String::from_utf8(fresh).unwrap();
    let path = root.join("include/mps_fmi.h");
    if std::env::var_os("MPS_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &fresh).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    for name in [
        "fmi2Instantiate",
        "fmi2DoStep",
        "fmi2DeSerializeFMUstate",
        "fmi2GetStringStatus",
    ] {
        assert!(
            fresh.contains(name),
            "{name} missing from the generated header"
        );
    }
    assert!(
        committed == fresh,
        "include/mps_fmi.h is stale: regenerate it with `MPS_BLESS=1 cargo test --release --test suite header_fresh::`"
    );
}
