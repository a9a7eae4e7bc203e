//! A limit on work (issue 8, item 1): an advance that would take more than solver.max_steps
//! solver steps is refused before the first step, with a message naming the time, the step
//! count, dt and the limit; the estimate matches the steps actually taken.
use mps_solid::physics::SimError;
use mps_solid::runner::run_scene;
use mps_solid::{Scene, Simulation};
use std::time::{Duration, Instant};

fn small2d() -> Scene {
    Scene::load(
        &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/small2d.json"),
    )
    .unwrap()
}

/// Runs f and checks it returns within `limit` (the refusals must not step at all).
fn quick<T>(limit: f64, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let r = f();
    assert!(
        t.elapsed() < Duration::from_secs_f64(limit),
        "took {:?}",
        t.elapsed()
    );
    r
}

#[test]
fn the_estimate_is_the_step_count() {
    let mut sim = Simulation::new(&small2d()).unwrap();
    for t in [1e-4, 3.3e-3, 0.01] {
        let n = sim.estimate_steps(t);
        assert_eq!(sim.advance_to(t).unwrap(), n, "to t = {t}");
    }
    assert_eq!(sim.estimate_steps(sim.time()), 0);
    assert_eq!(sim.estimate_steps(0.0), 0, "backwards");
    assert_eq!(sim.estimate_steps(f64::NAN), 0);
    let h = 1e6;
    let n = sim.estimate_steps(sim.time() + h);
    assert!((n as f64 - h / sim.max_dt()).abs() <= 2.0, "{n}");
}

#[test]
fn a_stiff_light_material_is_refused_before_stepping() {
    // E = 1e12 Pa, rho = 1e-3 kg/m^3: a wave speed of 3e7 m/s, about 1e-10 s steps.
    let mut s = small2d();
    s.bodies[0].material.young = 1e12;
    s.bodies[0].material.density = 1e-3;
    let mut sim = Simulation::new(&s).unwrap();
    let e = quick(0.5, || sim.advance_to(0.01)).unwrap_err();
    match &e {
        SimError::TooMuchWork {
            steps, limit, dt, ..
        } => {
            assert_eq!(*limit, 20_000_000);
            assert!(*steps > *limit && *dt < 1e-9, "{e}");
        }
        _ => panic!("{e}"),
    }
    let m = e.to_string();
    assert!(
        m.contains("advancing to t = 1e-2 s would take")
            && m.contains("solver steps of dt = ")
            && m.contains("more than solver.max_steps = 20000000"),
        "{m}"
    );
    assert!(m.len() < 400 && !m.contains("000000000000"), "{m}");
    // Nothing happened.
    assert_eq!((sim.time(), sim.steps()), (0.0, 0));
    // The whole run is refused the same way.
    let e = quick(0.5, || run_scene(&s, |_| {})).unwrap_err();
    assert!(e.contains("more than solver.max_steps"), "{e}");
}

#[test]
fn a_huge_step_is_refused_and_the_limit_is_configurable() {
    let mut s = small2d();
    s.end_time = 1e6;
    s.output_interval = 1.0;
    let e = quick(0.5, || run_scene(&s, |_| {})).unwrap_err();
    assert!(
        e.contains("advancing to t = 1e6 s would take") && e.contains("max_steps"),
        "{e}"
    );
    // An FMU's doStep(h = 1e6) is one advance.
    let mut sim = Simulation::new(&s).unwrap();
    assert!(matches!(
        quick(0.5, || sim.advance_to(1e6)),
        Err(SimError::TooMuchWork { .. })
    ));
    // A small limit refuses an ordinary advance; the step count is exact at the border.
    let sim = Simulation::new(&s).unwrap();
    let n = sim.estimate_steps(0.01);
    s.solver.max_steps = n;
    let mut sim = Simulation::new(&s).unwrap();
    assert!(matches!(
        sim.advance_to(0.011),
        Err(SimError::TooMuchWork { .. })
    ));
    assert_eq!(sim.advance_to(0.01).unwrap(), n);
}
