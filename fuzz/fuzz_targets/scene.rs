//! Fuzz target: the scene parser. Any text goes through `Scene::from_json` (and
//! `Scene::from_toml`); a scene that validates must serialise back to a scene that parses to
//! the same JSON (the FMU's GUID is a hash of that JSON), and, when small enough, must build a
//! Simulation or be refused with an error, then take a couple of solver steps without a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use mps_fuzz::{particle_estimate, MAX_FUZZ_PARTICLES};
use mps_solid::{Scene, Simulation};

fn check(scene: Scene) {
    // from_json validated it already: validate must agree.
    scene.validate().expect("a parsed scene validates");
    let json = scene.to_json();
    let again = Scene::from_json(&json)
        .unwrap_or_else(|e| panic!("a valid scene's own JSON is refused: {e}\n{json}"));
    assert_eq!(
        again.to_json(),
        json,
        "JSON round trip changes the scene (and so the FMU's GUID)"
    );
    let Some(n) = particle_estimate(&scene) else {
        return;
    };
    if n > MAX_FUZZ_PARTICLES {
        return;
    }
    let Ok(mut sim) = Simulation::new(&scene) else {
        return;
    };
    let dt = sim.max_dt();
    // A step of a few ms per input at most: skip worlds whose step is not a sane number
    // (advance_to would loop u64::MAX times on dt = 0; see issue 8 item 1).
    if !(dt.is_finite() && dt > 0.0) || sim.particles() == 0 {
        return;
    }
    let _ = sim.advance_to(sim.time() + 2.0 * dt);
    let _ = (sim.kinetic_energy(), sim.strain_energy(), sim.state());
    for k in 0..scene.probes.len() {
        let _ = sim.probe_displacement(k);
    }
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(scene) = Scene::from_json(text) {
        check(scene);
    }
    if let Ok(scene) = Scene::from_toml(text) {
        check(scene);
    }
});
