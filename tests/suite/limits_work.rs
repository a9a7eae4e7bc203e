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

/// small3d at a quarter of its spacing: 18,944 particles, whose set-up takes about 38 s on an
/// idle 2-core machine (its clamp has followers since issue 24, so the closure serves the body:
/// 36.6 s of it; the stable step 1.6 s).
fn slow_setup_scene() -> Scene {
    let mut s = Scene::load(
        &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/small3d.json"),
    )
    .unwrap();
    s.particle_spacing = 0.00625;
    s
}

/// Records the set-up's stages as they end, with the time they were told.
#[derive(Default)]
struct Stages(std::cell::RefCell<Vec<(&'static str, f64, String, Instant)>>);

impl mps_solid::physics::world::SetupObserver for Stages {
    fn stage_done(&self, stage: mps_solid::physics::world::SetupStage, seconds: f64, detail: &str) {
        self.0
            .borrow_mut()
            .push((stage.name(), seconds, detail.to_string(), Instant::now()));
    }
}

#[test]
fn set_up_stages_are_told_as_they_end() {
    // Issue 27.7: the set-up was silent until it returned. Each stage is told when it ends,
    // with its time; the stages' times add up to the set-up's wall time (the rest is
    // bookkeeping between them).
    let s = small2d();
    let stages = Stages::default();
    let t0 = Instant::now();
    Simulation::new_observed(&s, &stages).unwrap();
    let total = t0.elapsed().as_secs_f64();
    let v = stages.0.borrow();
    let names: Vec<&str> = v.iter().map(|x| x.0).collect();
    assert_eq!(
        names,
        [
            "particles",
            "bonds",
            // small2d's clamp: its face is found and followers hold it (issue 24).
            "clamps",
            "operator fits",
            "closure",
            "stable step",
            "initial forces"
        ]
    );
    // Told as they happen: the stable step ends well before the set-up returns... and each
    // stage was told after the previous one.
    assert!(v.windows(2).all(|w| w[0].3 <= w[1].3));
    let sum: f64 = v.iter().map(|x| x.1).sum();
    assert!(
        sum <= total * 1.001 && sum >= 0.5 * total,
        "{sum} of {total} s"
    );
    assert!(v[1].2.contains("bonds of 280 particles"), "{}", v[1].2);
}

#[test]
fn a_set_up_longer_than_its_bound_is_refused_early_with_its_estimate() {
    // Issue 27.7: a long set-up had no bound. solver.max_setup_seconds bounds it: estimated
    // once the bonds are found (the first few percent of the work) and refused then, with the
    // estimate in the message.
    let mut s = slow_setup_scene();
    s.solver.max_setup_seconds = 1.0;
    let stages = Stages::default();
    let e = Simulation::new_observed(&s, &stages)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("solver.max_setup_seconds = 1 s")
            && e.contains("the set-up would take about")
            && e.contains("bonds found in"),
        "{e}"
    );
    // Refused once the bonds were found, before the expensive stages.
    let names: Vec<&str> = stages.0.borrow().iter().map(|x| x.0).collect();
    assert_eq!(names, ["particles", "bonds"], "{e}");
    // Out of range: refused by the validation, naming the field.
    s.solver.max_setup_seconds = 0.0;
    let e = Simulation::new(&s).err().unwrap().to_string();
    assert!(e.contains("solver.max_setup_seconds"), "{e}");
}

/// A 15-across cube clamped by a region over wall layers (tests/data/clamped_cube.json): its
/// closure is most of its set-up (about 8 s of conjugate gradients on an idle 2-core machine).
fn clamped_cube() -> Scene {
    Scene::load(
        &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/clamped_cube.json"),
    )
    .unwrap()
}

/// Stops the set-up through its flag once set from another thread (as fmi2CancelStep does).
#[derive(Default)]
struct FlagStop {
    fits_done: std::sync::atomic::AtomicBool,
    flag: std::sync::atomic::AtomicBool,
}

impl mps_solid::physics::world::SetupObserver for FlagStop {
    fn stage_done(&self, stage: mps_solid::physics::world::SetupStage, _: f64, _: &str) {
        if stage.name() == "operator fits" {
            self.fits_done
                .store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }
    fn stop(&self) -> Option<String> {
        self.flag
            .load(std::sync::atomic::Ordering::SeqCst)
            .then(|| "the test asked".to_string())
    }
    fn stop_flag(&self) -> Option<&std::sync::atomic::AtomicBool> {
        Some(&self.flag)
    }
}

#[test]
fn a_stop_request_ends_the_closure_within_an_iteration() {
    // Issue 27.7: a stop request (fmi2CancelStep) was seen only at stage boundaries, so the
    // closure of a bulky clamped body (8 s here, 30-200 s for larger cubes on a loaded machine)
    // ran to its end first. Its conjugate gradients now poll the request every iteration (a
    // few ms each): the set-up ends within a second of it, saying how far the closure came.
    let s = clamped_cube();
    let obs = FlagStop::default();
    let (result, asked) = std::thread::scope(|sc| {
        let asker = sc.spawn(|| {
            while !obs.fits_done.load(std::sync::atomic::Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(2));
            }
            // Well inside the closure (its first iterations take some ms).
            std::thread::sleep(Duration::from_millis(300));
            obs.flag.store(true, std::sync::atomic::Ordering::SeqCst);
            Instant::now()
        });
        let r = Simulation::new_observed(&s, &obs).map(|_| ());
        (r, asker.join().unwrap())
    });
    let after = asked.elapsed().as_secs_f64();
    let e = result.expect_err("the set-up was stopped").to_string();
    assert!(
        e.contains("stopped during the closure stage")
            && e.contains("conjugate-gradient iteration")
            && e.contains("the test asked"),
        "{e}"
    );
    // One iteration on the 15^3 box is about 1 ms idle; a second allows for a loaded machine.
    assert!(
        after < 1.0,
        "the set-up ended {after:.2} s after the request: {e}"
    );
}

#[test]
fn the_bound_ends_the_closure_when_it_is_reached() {
    // Issue 27.7: solver.max_setup_seconds was checked only at stage boundaries; the estimate
    // made after the bonds puts the closure at 60 bonds-stage times, far below what a bulky
    // clamped body's closure takes (8 s here against an estimate near 1.5 s), so a bound in
    // between let it run to its end. The closure's iterations now check the bound: the set-up
    // ends at it (or is refused earlier by the estimate, on a machine slow enough for the
    // bonds stage to give a larger one), never past it by more than an iteration.
    let mut s = clamped_cube();
    // 18 particles across (the fixture's 15 close in 4-6 s on a loaded machine since the coarse
    // correction of boxes solved whole): its closure runs on a reduced box, over 10 s on the
    // machines of 2026-12-05, 3.5-5 s on the AVX-512 one of 2026-12-07 (where a bound of 4 s
    // was passed by the closure's end in one run of four), and the estimate after its bonds
    // stays under the bound (or refuses it, which the test accepts).
    let dp = 0.3 / 18.0;
    s.particle_spacing = dp;
    s.bodies[0].boxes[1].min[0] = -3.0 * dp;
    s.boundaries[0].region.min[0] = -3.0 * dp - 0.001;
    let bound = 2.0;
    s.solver.max_setup_seconds = bound;
    let t = Instant::now();
    let e = Simulation::new(&s).err().expect("refused").to_string();
    let took = t.elapsed().as_secs_f64();
    assert!(e.contains("solver.max_setup_seconds = 2 s"), "{e}");
    if !e.contains("the set-up would take about") {
        assert!(
            e.contains("during its closure stage")
                && e.contains("the closure of body 'cube'")
                && e.contains("conjugate-gradient iteration")
                && e.contains("s more"),
            "{e}"
        );
    }
    // The set-up's own clock starts after the scene's validation and fill (some ms); 0.5 s
    // allows for an iteration and a loaded machine.
    assert!(took < bound + 0.5, "refused after {took:.2} s: {e}");
}

/// Runs `mps run SCENE --out DIR` on `scene` (written to a scratch file); its exit status
/// success and stderr.
fn mps_run(scene: &Scene, name: &str) -> (bool, String) {
    let d = std::env::temp_dir().join(format!("mps-setup-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("scene.json");
    std::fs::write(&p, scene.to_json()).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_mps"))
        .args(["run", p.to_str().unwrap(), "--out"])
        .arg(d.join("out"))
        .output()
        .unwrap();
    std::fs::remove_dir_all(&d).ok();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn mps_run_refuses_a_set_up_beyond_its_bound_with_the_estimate() {
    // Issue 27.7 in the CLI: the refusal is an error naming the field, with the estimate,
    // given once the bonds are found (a second or two here, not the 38 s of the whole set-up).
    let mut s = slow_setup_scene();
    s.solver.max_setup_seconds = 1.0;
    s.end_time = 0.001;
    s.output_interval = 0.001;
    let (ok, err) = quick(12.0, || mps_run(&s, "bound"));
    assert!(!ok, "{err}");
    // (On a loaded machine the particles and bonds may pass the second after which the stages
    // are told: their lines may come first.)
    let first_other = err.lines().find(|l| !l.starts_with("set-up: "));
    assert!(
        first_other.is_some_and(|l| l.starts_with("error: "))
            && err.contains("solver.max_setup_seconds")
            && err.contains("the set-up would take about"),
        "{err}"
    );
    // A quick set-up (small2d: milliseconds) prints no stage lines.
    let (ok, err) = mps_run(&small2d(), "quick");
    assert!(ok && !err.contains("set-up:"), "{err}");
}

#[test]
#[ignore = "slow (5-6 s of set-up): the full test command runs it"]
fn mps_run_reports_a_long_set_up_on_stderr() {
    // Issue 27.7 in the CLI: a set-up longer than a second shows its stages on stderr. The
    // clamped cube at 16 particles across, its wall 3 layers deep as in the file: 5-6 s of
    // set-up on the 2-core machine (at 14 across 1.4 s, too near the second for a faster
    // machine; at 12 across, 2.6 s before the closure's solve read its stencils once per
    // stencil, now 0.7 s).
    let mut s = clamped_cube();
    let dp = 0.3 / 16.0;
    s.particle_spacing = dp;
    s.bodies[0].boxes[1].min[0] = -3.0 * dp;
    s.boundaries[0].region.min[0] = -3.0 * dp - 0.001;
    s.end_time = 1e-5;
    s.output_interval = 1e-5;
    let (ok, err) = mps_run(&s, "long");
    assert!(ok, "{err}");
    for stage in [
        "particles",
        "bonds",
        "operator fits",
        "closure",
        "stable step",
    ] {
        assert!(
            err.contains(&format!("set-up: {stage} took")),
            "{stage}:\n{err}"
        );
    }
}

/// Records the stages and lends a memo (as an FMU instance does across its builds).
#[derive(Default)]
struct WithMemo {
    stages: Stages,
    memo: mps_solid::physics::world::SetupMemo,
}

impl mps_solid::physics::world::SetupObserver for WithMemo {
    fn stage_done(&self, stage: mps_solid::physics::world::SetupStage, seconds: f64, detail: &str) {
        self.stages.stage_done(stage, seconds, detail);
    }
    fn memo(&self) -> Option<&mps_solid::physics::world::SetupMemo> {
        Some(&self.memo)
    }
}

impl WithMemo {
    /// What the last set-up's closure stage said.
    fn last_closure(&self) -> String {
        let v = self.stages.0.borrow();
        v.iter()
            .rev()
            .find(|x| x.0 == "closure")
            .expect("closure stage")
            .2
            .clone()
    }
}

#[test]
fn a_closure_is_taken_from_an_earlier_set_up_of_the_same_geometry_only() {
    // An FMU instance built again with other parameters (materials, step, damping: never the
    // geometry) paid the closure again, its longest stage. A set-up now takes the closure an
    // earlier one kept for the same geometry (hashed: positions, bonds, clamps, faces), and
    // the model it builds is the one a set-up from scratch builds, bit for bit; another
    // geometry computes its own.
    let s = small2d();
    let obs = WithMemo::default();
    Simulation::new_observed(&s, &obs).unwrap();
    assert!(obs.memo.holds_closure());
    assert!(
        !obs.last_closure().contains("earlier"),
        "{}",
        obs.last_closure()
    );
    let same_as_fresh = |scene: &Scene, obs: &WithMemo| {
        let mut a = Simulation::new_observed(scene, obs).unwrap();
        let mut b = Simulation::new(scene).unwrap();
        a.advance_to(0.01).unwrap();
        b.advance_to(0.01).unwrap();
        assert!(a.state() == b.state(), "the built models differ");
        assert_eq!(
            a.probe_displacement(0).map(f64::to_bits),
            b.probe_displacement(0).map(f64::to_bits)
        );
    };
    let mut other_params = s.clone();
    other_params.bodies[0].material.young *= 2.0;
    other_params.bodies[0].material.density *= 1.5;
    other_params.bodies[0].material.poisson = 0.25;
    other_params.solver.damping = 3.0;
    same_as_fresh(&other_params, &obs);
    assert!(
        obs.last_closure()
            .contains("as an earlier set-up of this geometry closed them"),
        "{}",
        obs.last_closure()
    );
    // As bytes (what `mps pack` ships in the FMU): read back, the same closure is taken.
    let bytes = obs.memo.closure_bytes().expect("a closure is kept");
    let shipped = WithMemo {
        stages: Stages::default(),
        memo: mps_solid::physics::world::SetupMemo::from_closure_bytes(&bytes).unwrap(),
    };
    same_as_fresh(&other_params, &shipped);
    assert!(
        shipped.last_closure().contains("earlier"),
        "{}",
        shipped.last_closure()
    );
    // Damaged bytes are refused with what is wrong.
    let refused = |b: &[u8]| {
        mps_solid::physics::world::SetupMemo::from_closure_bytes(b)
            .err()
            .expect("damaged bytes must be refused")
    };
    let mut flipped = bytes.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 1;
    assert!(refused(&flipped).contains("checksum"));
    assert!(refused(&bytes[..bytes.len() / 2]).contains("header says"));
    assert!(refused(&bytes[..20]).contains("truncated"));
    assert!(refused(b"not a closure at all").contains("not a closure"));
    let mut longer = s.clone();
    longer.bodies[0].boxes[0].max[0] += 0.05;
    longer.loads.clear();
    same_as_fresh(&longer, &obs);
    assert!(
        !obs.last_closure().contains("earlier"),
        "{}",
        obs.last_closure()
    );
}
