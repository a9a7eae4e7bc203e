//! Test fixture of the instance's unit tests: an initialised instance that has stepped.
use super::{Instance, NoLogger};
use crate::fmi::model_description::guid;
use crate::scene::Scene;
use std::path::Path;
use std::sync::Arc;

/// An initialised instance of tests/data/small2d.json, stepped 3 times.
pub(super) fn small2d() -> Instance {
    // One directory per call: the tests run in parallel threads, and a shared scene file
    // could be read while another test truncates it.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("mps-instance-unit-{}-{call}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small2d.json"))
        .unwrap();
    std::fs::write(dir.join("scene.json"), scene.to_json()).unwrap();
    let uri = format!("file://{}", dir.display());
    let mut i = Instance::instantiate(
        "unit",
        true,
        &guid(&scene),
        Some(&uri),
        Arc::new(NoLogger),
        false,
    )
    .unwrap();
    i.setup_experiment(0.0, None).unwrap();
    i.enter_initialization_mode().unwrap();
    i.exit_initialization_mode().unwrap();
    for k in 0..3 {
        i.do_step(k as f64 * 0.002, 0.002).unwrap();
    }
    i
}
