//! Nothing is lost per load cycle (issue 27.5): a C host (tests/c/load_cycles.c) loads the
//! FMU's library, instantiates, initialises, steps 3 times, frees the instance and dlcloses the
//! library, 4 times over, under valgrind's leak checker. Before the fix each cycle lost 640 B
//! definitely and 10.8 kB indirectly: rayon's deques reclaim memory through crossbeam-epoch,
//! whose global collector is a static of the unloaded library copy. The library tested is
//! `MPS_LEAK_LIB` if set (e.g. the FMU's stripped binary, or an older build to compare), else
//! the cdylib built with the tests.
use crate::common;
use mps_solid::fmi::model_description::guid;
use mps_solid::Scene;
use std::path::PathBuf;
use std::process::Command;

/// Load cycles in the run.
const CYCLES: usize = 4;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Bytes of a "definitely lost: N bytes in M blocks" line of valgrind's leak summary (0 when
/// valgrind found no leak at all and printed no summary).
fn lost(report: &str, kind: &str) -> u64 {
    report
        .lines()
        .find_map(|l| l.split(&format!("{kind} lost: ")).nth(1))
        .and_then(|rest| rest.split(" bytes").next())
        .map(|n| n.replace(',', "").trim().parse().expect("a byte count"))
        .unwrap_or(0)
}

#[test]
#[ignore = "slow (40 s under valgrind on a loaded 2-core machine): the full test command runs it"]
fn load_cycles_lose_nothing_under_valgrind() {
    if Command::new("valgrind").arg("--version").output().is_err() {
        println!(
            "SKIPPED: valgrind is not installed, so the load-cycle leak check did not run \
             (apt-get install valgrind)"
        );
        return;
    }
    let lib = std::env::var_os("MPS_LEAK_LIB")
        .map(PathBuf::from)
        .unwrap_or_else(common::built_library);
    let dir = std::env::temp_dir().join(format!("mps-leak-check-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("resources")).unwrap();
    let host = dir.join("load_cycles");
    let cc = Command::new("cc")
        .args([
            "-std=c99",
            "-O1",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
            "-I",
        ])
        .arg(root().join("vendor/fmi2"))
        .arg(root().join("tests/c/load_cycles.c"))
        .arg("-o")
        .arg(&host)
        .arg("-ldl")
        .output()
        .expect("run cc");
    assert!(
        cc.status.success(),
        "tests/c/load_cycles.c does not compile:\n{}",
        String::from_utf8_lossy(&cc.stderr)
    );
    let scene = Scene::load(&root().join("tests/data/small2d.json")).unwrap();
    std::fs::write(dir.join("resources/scene.json"), scene.to_json()).unwrap();
    let out = Command::new("valgrind")
        .args([
            "--leak-check=full",
            "--show-leak-kinds=definite,indirect",
            "--errors-for-leak-kinds=definite,indirect",
            "--error-exitcode=99",
        ])
        .arg(&host)
        .arg(&lib)
        .arg(guid(&scene))
        .arg(format!("file://{}/resources", dir.display()))
        .arg(CYCLES.to_string())
        // Two threads whatever the machine: the instance's worker threads are what leaked.
        .env("MPS_FMI_THREADS", "2")
        .output()
        .expect("run valgrind");
    std::fs::remove_dir_all(&dir).ok();
    let report = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(&format!("{CYCLES} load cycles done")),
        "the host failed:\n{stdout}\n{report}"
    );
    let (definite, indirect) = (lost(&report, "definitely"), lost(&report, "indirectly"));
    println!(
        "LEAK-CHECK {CYCLES} load cycles of {}: definitely lost {definite} B, indirectly lost \
         {indirect} B ({} B and {} B per cycle)",
        lib.display(),
        definite / CYCLES as u64,
        indirect / CYCLES as u64
    );
    assert_eq!(
        (definite, indirect, out.status.code()),
        (0, 0, Some(0)),
        "memory lost over {CYCLES} load cycles of {}:\n{report}",
        lib.display()
    );
}
