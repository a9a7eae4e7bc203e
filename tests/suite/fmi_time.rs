//! The FMU instance's time and call-sequence conformance (issue 27 items 9 and 11), through the
//! safe `Instance` API the C layer wraps: far from time zero a doStep simulates exactly its
//! communication step (the simulated time is kept relative to startTime) or is refused when the
//! step cannot be resolved; fmi2SetupExperiment refuses a stop time before the start time;
//! fmi2SetRealInputDerivatives is accepted where FMI 2.0 allows it; a doStep of minutes warns
//! the host before it starts (item 8).
use mps_solid::fmi::instance::{Instance, Logger, Mode, NoLogger, Status};
use mps_solid::fmi::model_description::guid;
use mps_solid::Scene;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// An instantiated (not initialised) instance of tests/data/small2d.json.
fn instance() -> Instance {
    instance_with(Arc::new(NoLogger))
}

/// [`instance`] with the host's logger.
fn instance_with(logger: Arc<dyn Logger>) -> Instance {
    static CALLS: AtomicUsize = AtomicUsize::new(0);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(&root.join("tests/data/small2d.json")).unwrap();
    let dir = std::env::temp_dir().join(format!(
        "mps-fmi-time-{}-{}",
        std::process::id(),
        CALLS.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("scene.json"), scene.to_json()).unwrap();
    let uri = format!("file://{}", dir.display());
    let i = Instance::instantiate("time", true, &guid(&scene), Some(&uri), logger, false).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    i
}

fn initialised(start: f64) -> Instance {
    let mut i = instance();
    i.setup_experiment(start, None).unwrap();
    i.enter_initialization_mode().unwrap();
    i.exit_initialization_mode().unwrap();
    i
}

/// The simulated time of the model (s since startTime).
fn elapsed(i: &mut Instance) -> f64 {
    i.simulated_time()
}

#[test]
fn steps_far_from_time_zero_simulate_their_step() {
    // Issue 27.9: with startTime 1e14, t + 0.005 rounds to t and the model never moved (0
    // sub-steps, fmi2OK); at 1e13 each 5 ms step simulated 5.86 ms (t + h rounded to the
    // spacing of doubles there, 1/512 s). The simulated time is now relative to startTime:
    // three steps of 5 ms simulate 15 ms at any start time, to round-off of the relative time
    // (a few ulps of 0.015, far below 1e-12 s).
    for start in [0.0, 1e6, 1e13, 1e14] {
        let mut i = initialised(start);
        let h = 0.005;
        let mut t = start;
        for _ in 0..3 {
            i.do_step(t, h)
                .unwrap_or_else(|e| panic!("start {start}: {}", e.message()));
            t += h;
        }
        let e = elapsed(&mut i);
        assert!(
            (e - 0.015).abs() < 1e-12,
            "start {start}: 3 steps of {h} s simulated {e} s"
        );
        // The host's own sum t is what the next call must pass (Reference-FMUs semantics:
        // currentCommunicationPoint is checked against where the last step ended).
        assert_eq!(i.time(), t, "start {start}");
        let wrong = t + 1.0 + 1e-6 * t.abs();
        let err = i.do_step(wrong, h).unwrap_err();
        assert!(
            err.message().contains("currentCommunicationPoint"),
            "start {start}: {}",
            err.message()
        );
    }
}

#[test]
fn a_step_below_the_resolution_of_the_time_is_refused() {
    // Issue 27.9: h = 1e-18 at t = 0.1 returned fmi2OK with no progress (0.1 + 1e-18 == 0.1).
    let mut i = initialised(0.0);
    i.do_step(0.0, 0.1).unwrap();
    let before = i.get_fmu_state().unwrap();
    let e = i.do_step(0.1, 1e-18).unwrap_err();
    assert_eq!(e.status(), Status::Error);
    let m = e.message();
    assert!(
        m.contains("communicationStepSize") && m.contains("resolution"),
        "{m}"
    );
    // Refused before any work: the instance is unchanged and can go on.
    assert_eq!(i.mode(), Mode::StepComplete);
    assert_eq!(i.get_fmu_state().unwrap(), before);
    i.do_step(0.1, 0.002).unwrap();
}

#[test]
fn stop_time_before_start_time_is_an_error() {
    // Issue 27.11: start 1.0, stop 0.0 must be fmi2Error with a message.
    let mut i = instance();
    let e = i.setup_experiment(1.0, Some(0.0)).unwrap_err();
    assert_eq!(e.status(), Status::Error);
    assert!(
        e.message().contains("stopTime") && e.message().contains("startTime"),
        "{}",
        e.message()
    );
    // Nothing was set: a correct call still works, and stopTime = startTime is accepted (an
    // empty experiment).
    i.setup_experiment(1.0, Some(1.0)).unwrap();
    let mut j = instance();
    j.setup_experiment(0.0, Some(2.0)).unwrap();
}

#[test]
fn input_derivatives_are_accepted_before_initialisation() {
    // Issue 27.11: FMI 2.0 allows fmi2SetRealInputDerivatives in the Instantiated state and in
    // initialisation mode (its table of allowed calls, section 4.2.4).
    let mut i = instance();
    let g = i.table().by_name("gravity_y").unwrap().value_reference;
    i.set_real_input_derivatives(&[g], &[1], &[2.0]).unwrap();
    i.setup_experiment(0.0, None).unwrap();
    i.set_real_input_derivatives(&[g], &[1], &[3.0]).unwrap();
    i.enter_initialization_mode().unwrap();
    i.set_real_input_derivatives(&[g], &[1], &[4.0]).unwrap();
    i.exit_initialization_mode().unwrap();
    i.set_real_input_derivatives(&[g], &[1], &[5.0]).unwrap();
    // Still refused after terminate (not allowed there), with the state named.
    i.terminate().unwrap();
    let e = i
        .set_real_input_derivatives(&[g], &[1], &[1.0])
        .unwrap_err();
    assert!(e.message().contains("Terminated"), "{}", e.message());
}

/// What reached the host's logger, in order, as it was called.
#[derive(Default)]
struct Recorded(Mutex<Vec<(Status, String, String)>>);

impl Logger for Recorded {
    fn log(&self, status: Status, category: &str, message: &str) {
        self.0
            .lock()
            .unwrap()
            .push((status, category.to_string(), message.to_string()));
    }
}

#[test]
fn a_do_step_of_minutes_warns_the_host_before_it_starts() {
    // Issue 27.8: an FMU accepted 1e7 sub-steps in one doStep (within solver.max_steps) and
    // blocked for many minutes without a word. Now a doStep whose estimated wall time is above
    // LONG_STEP_WARNING_S warns the host at once, with the step count and the estimate.
    //
    // Here solver.dt = 1e-8 s and h = 0.02 s: 2e6 sub-steps of 280 particles, a few minutes by
    // the solver's cost figures (Simulation::estimate_wall_time). So that the test does not run
    // them, a tip force of 1e15 N blows the model up in its first sub-step (8 particles of
    // 0.16 kg kicked by far more than half a spacing): the warning must already be with the
    // logger when the failed call returns, i.e. it was handed over during the call, not queued
    // for after it.
    let log = Arc::new(Recorded::default());
    let mut i = instance_with(log.clone());
    let vr = |i: &Instance, n: &str| i.table().by_name(n).unwrap().value_reference;
    let (dt, fy) = (vr(&i, "solver.dt"), vr(&i, "tip_load.fy"));
    i.set_real(&[dt], &[1e-8]).unwrap();
    i.setup_experiment(0.0, None).unwrap();
    i.enter_initialization_mode().unwrap();
    i.exit_initialization_mode().unwrap();
    // An ordinary step (200 sub-steps) says nothing.
    i.do_step(0.0, 2e-6).unwrap();
    assert!(
        log.0.lock().unwrap().is_empty(),
        "{:?}",
        log.0.lock().unwrap()
    );
    i.set_real(&[fy], &[1e15]).unwrap();
    let e = i.do_step(2e-6, 0.02).unwrap_err();
    assert!(e.message().contains("blow-up"), "{}", e.message());
    let heard = log.0.lock().unwrap().clone();
    assert_eq!(heard.len(), 1, "{heard:?}");
    let (status, category, message) = &heard[0];
    assert_eq!(
        (*status, category.as_str()),
        (Status::Warning, "logStatusWarning")
    );
    assert!(
        message.contains("fmi2DoStep(t = 2e-6, h = 0.02): ")
            && message.contains(" solver steps of 280 particles")
            && message.contains("of wall time on two cores before this call returns")
            && message.contains("shorter communication steps"),
        "{message}"
    );
    // The estimate it quotes: minutes (about 156 s at the cost figures of sim::STEP_COST).
    assert!(message.contains(" min of wall time"), "{message}");
}

/// The real-time figures' driver (`studies::realtime::fmu_timing`, `mps bench --realtime`)
/// steps the instance in whole communication steps to the end it is given and reports the
/// simulated time it reached: 0.013 s in steps of 1 ms is 13 steps, whose simulated time must
/// be 0.013 s to round-off (a driver that lost or added a step would be 1 ms off), and its
/// temporary resources are removed afterwards. A failing scene's error comes back as an error.
#[test]
fn fmu_timing_steps_the_instance_to_the_end() {
    use mps_solid::studies::realtime::fmu_timing;
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(&root.join("tests/data/small2d.json")).unwrap();
    let before: Vec<_> = temp_timing_dirs();
    let t = fmu_timing(&scene, 0.013, 1e-3).unwrap();
    assert!((t.simulated_s - 0.013).abs() < 1e-12, "{t:?}");
    assert!(
        t.setup_s > 0.0 && t.stepping_s > 0.0 && t.threads >= 1,
        "{t:?}"
    );
    assert!(t.real_time_factor().is_finite(), "{t:?}");
    assert_eq!(
        temp_timing_dirs(),
        before,
        "the timing's resources are removed"
    );
    let mut bad = scene.clone();
    bad.gravity.vector = vec![0.0, -1e30];
    let err = fmu_timing(&bad, 0.013, 1e-3).unwrap_err();
    assert!(!err.is_empty());
    assert_eq!(temp_timing_dirs(), before, "removed after a failure too");
}

/// The real-time driver's temporary directories of this process.
fn temp_timing_dirs() -> Vec<PathBuf> {
    let prefix = format!("mps-fmu-timing-{}-", std::process::id());
    let mut v: Vec<PathBuf> = std::fs::read_dir(std::env::temp_dir())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .map(|e| e.path())
        .collect();
    v.sort();
    v
}
