//! The C ABI against the official FMI 2.0 headers (vendor/fmi2): tests/c/signatures.c, which
//! includes them and include/mps_fmi.h and assigns each of our functions to the standard's
//! function-pointer type, compiles with -Werror; a wrong signature would not.
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn compile(src: &Path) -> std::process::Output {
    let out = std::env::temp_dir().join(format!(
        "mps-c-abi-{}-{}.o",
        std::process::id(),
        src.file_stem().unwrap().to_string_lossy()
    ));
    let o = Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-c"])
        .arg("-I")
        .arg(root().join("vendor/fmi2"))
        .arg("-I")
        .arg(root().join("include"))
        .arg(src)
        .arg("-o")
        .arg(&out)
        .output()
        .expect("run cc");
    std::fs::remove_file(&out).ok();
    o
}

/// The common and co-simulation functions of the official fmi2Functions.h.
fn standard_functions() -> Vec<String> {
    let h = std::fs::read_to_string(root().join("vendor/fmi2/fmi2Functions.h")).unwrap();
    let me = [
        "fmi2EnterEventMode",
        "fmi2NewDiscreteStates",
        "fmi2EnterContinuousTimeMode",
        "fmi2CompletedIntegratorStep",
        "fmi2SetTime",
        "fmi2SetContinuousStates",
        "fmi2GetDerivatives",
        "fmi2GetEventIndicators",
        "fmi2GetContinuousStates",
        "fmi2GetNominalsOfContinuousStates",
    ];
    h.lines()
        .filter_map(|l| l.trim().strip_prefix("FMI2_Export "))
        .filter_map(|l| l.split_whitespace().nth(1))
        .map(|n| n.trim_end_matches(';').to_string())
        .filter(|n| !me.contains(&n.as_str()))
        .collect()
}

#[test]
fn signatures_match_the_standard() {
    let o = compile(&root().join("tests/c/signatures.c"));
    assert!(
        o.status.success(),
        "tests/c/signatures.c does not compile:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn every_standard_function_is_declared_and_checked() {
    let fns = standard_functions();
    assert_eq!(fns.len(), 34, "{fns:?}");
    let ours = std::fs::read_to_string(root().join("include/mps_fmi.h")).unwrap();
    let checks = std::fs::read_to_string(root().join("tests/c/signatures.c")).unwrap();
    for f in &fns {
        assert!(
            ours.contains(&format!(" {f}(")) || ours.contains(&format!("*{f}(")),
            "{f} missing from include/mps_fmi.h"
        );
        assert!(
            checks.contains(&format!("CHECK({f})")),
            "{f} not checked in signatures.c"
        );
    }
}

#[test]
fn a_wrong_signature_fails_to_compile() {
    let src = std::env::temp_dir().join(format!("mps_c_abi_wrong_{}.c", std::process::id()));
    std::fs::write(
        &src,
        "#include \"fmi2Functions.h\"\n\
         fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, int no_set, int extra);\n",
    )
    .unwrap();
    let o = compile(&src);
    std::fs::remove_file(&src).ok();
    assert!(
        !o.status.success(),
        "a conflicting declaration must not compile"
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("conflicting types"));
}
