//! Fracture never creates energy (issue 7): the small2d cantilever thrown against its own holder
//! at 5 m/s with fracture_strain 0.01 and fractured-surface contact on. A broken bond releases its
//! stored energy; the contact across it must not push at the moment it breaks. Before the fix the
//! held layer sits half a spacing from the first free layer, so a broken bond of that pair started
//! at 0.5 l0 inside the contact range and the contact spring added ~60 J per broken pair
//! (547 J -> 884 J kinetic + strain in 0.5 ms).
use mps_solid::physics::World;
use mps_solid::scene::{Model, Scene};
use serde_json::Value;

fn small2d(velocity: [f64; 2], fractured_surfaces: bool) -> World<2> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v: Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("tests/data/small2d.json")).unwrap(),
    )
    .unwrap();
    // No gravity: kinetic + strain + contact is then the whole energy.
    v["gravity"] = serde_json::json!({ "vector": [0.0, 0.0] });
    v["bodies"][0]["velocity"] = serde_json::json!(velocity);
    v["solver"] = serde_json::json!({
        "fracture_strain": 0.01,
        "contact": { "fractured_surfaces": fractured_surfaces }
    });
    let scene = Scene::from_json(&v.to_string()).unwrap();
    Model::<2>::build(&scene).unwrap().world
}

fn total(w: &World<2>) -> f64 {
    w.kinetic_energy() + w.strain_energy() + w.contact_energy()
}

/// Runs `t_end` seconds step by step; returns (energy after the first step, largest energy
/// after it, largest mean over 10 consecutive steps after it, broken pairs). The first step
/// stops the held particles (their kinetic energy is taken out by the holder), so the
/// reference is the energy after it.
fn run(mut w: World<2>, t_end: f64) -> (f64, f64, f64, u64) {
    let dt = w.max_dt();
    w.step(dt).unwrap();
    let e0 = total(&w);
    let mut e = vec![];
    while w.time < t_end {
        w.step(dt).unwrap();
        e.push(total(&w));
    }
    let emax = e.iter().fold(e0, |a, &b| a.max(b));
    let mean10 = e
        .windows(10)
        .map(|x| x.iter().sum::<f64>() / 10.0)
        .fold(f64::MIN, f64::max);
    (e0, emax, mean10, w.broken_pairs)
}

#[test]
fn fracture_on_impact_creates_no_energy() {
    for vel in [[0.0, -5.0], [5.0, 0.0], [-5.0, 0.0]] {
        let (e0, emax, mean10, broken) = run(small2d(vel, true), 5e-3);
        eprintln!(
            "v = {vel:?}: E0 = {e0:.2} J, max E = {emax:.2} J ({:+.3} %), largest 10-step mean {:+.3} %, broken pairs {broken}",
            100.0 * (emax / e0 - 1.0),
            100.0 * (mean10 / e0 - 1.0)
        );
        assert!(broken > 0, "the scenario must break bonds");
        // Symplectic Euler's energy measured at the step ends oscillates from step to step by
        // O(dt omega) of the energy in the highest modes (period ~4 steps at the default
        // safety) around a conserved shadow energy; created energy (the defect: +60 % in 5 ms)
        // persists. Measured with the C1 contact onset: single steps up to +1.2 % (v = -y), the
        // 10-step mean never above -0.13 %.
        assert!(
            mean10 <= e0 * 1.001,
            "v = {vel:?}: energy rose from {e0} J to {mean10} J (10-step mean)"
        );
        assert!(
            emax <= e0 * 1.02,
            "v = {vel:?}: energy rose from {e0} J to {emax} J"
        );
    }
}
