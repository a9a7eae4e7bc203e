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
    small2d_with(velocity, fractured_surfaces, "corrected")
}

fn small2d_with(velocity: [f64; 2], fractured_surfaces: bool, model: &str) -> World<2> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v: Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("tests/data/small2d.json")).unwrap(),
    )
    .unwrap();
    // No gravity: kinetic + strain + contact is then the whole energy.
    v["gravity"] = serde_json::json!({ "vector": [0.0, 0.0] });
    v["bodies"][0]["velocity"] = serde_json::json!(velocity);
    v["solver"] = serde_json::json!({
        "model": model,
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
fn run(w: World<2>, t_end: f64) -> (f64, f64, f64, u64) {
    run_at(w, t_end, 1.0)
}

/// `run` at `factor` times the automatic step.
fn run_at(mut w: World<2>, t_end: f64, factor: f64) -> (f64, f64, f64, u64) {
    let dt = w.max_dt() * factor;
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

/// Open defect (issue 7): below the automatic step the same impacts create energy, with both
/// operators. The rises come in the steps in which bonds break: re-fitting a particle's
/// operator to its remaining bonds (`ElasticOperator::refresh_particle`) can raise its strain
/// energy at fixed positions, e.g. 25.1 J -> 70.3 J on 2 broken pairs (corrected, v = -y, half
/// the automatic step: 23 of 64 refreshes raise it, by 85 J in all); steps without breaks
/// conserve to 2 J. Measured, largest total after the first step: corrected +15.9 % (0.5 x the
/// automatic step) and +20.9 % (0.25 x); second_order +46 % and an overlap stop at the
/// automatic step (`examples/fracture_energy_dt.rs`). Bound as in the test above (10-step
/// mean, 0.1 %). Fails today; run with `--ignored`.
#[test]
#[ignore = "open defect: an operator refresh at a bond break can raise the strain energy"]
fn fracture_creates_no_energy_at_any_step() {
    for model in ["corrected", "second_order"] {
        for factor in [1.0, 0.5, 0.25] {
            let (e0, _, mean10, _) = run_at(small2d_with([0.0, -5.0], true, model), 5e-3, factor);
            assert!(
                mean10 <= e0 * 1.001,
                "{model}, {factor} x the automatic step: energy rose from {e0} J to {mean10} J (10-step mean)"
            );
        }
    }
}
