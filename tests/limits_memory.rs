//! Out of memory (issue 8, item 2): the memory estimate of a scene bounds the measured peak of
//! building it (a counting allocator), a scene bigger than the memory available is refused
//! before anything is allocated, and the default particle limit refuses a 170^3 cube at once.
//! Issue 25: the default operator needs at most 3 kB per particle in 3D, and the memory of
//! each set-up stage is reported.
use mps_solid::physics::world::{SetupObserver, SetupStage};
use mps_solid::scene::memory::{self, Available};
use mps_solid::{Scene, Simulation};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::Mutex;

/// The system allocator, counting the bytes in use and their peak.
struct Counting;

static NOW: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// One measurement at a time (tests run on several threads).
static MEASURE: Mutex<()> = Mutex::new(());

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = NOW.fetch_add(l.size(), Relaxed) + l.size();
            PEAK.fetch_max(now, Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        NOW.fetch_sub(l.size(), Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new) };
        if !q.is_null() {
            // Old and new block coexist while realloc copies.
            let now = NOW.fetch_add(new, Relaxed) + new;
            PEAK.fetch_max(now, Relaxed);
            NOW.fetch_sub(l.size(), Relaxed);
        }
        q
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// A cube (3D) or square (2D) of n particles a side, nothing held, no gravity, with the
/// default operator.
fn block(dim: usize, n: usize, re_factor: f64) -> Scene {
    block_with(dim, n, re_factor, "second_order")
}

/// `block` with the operator `model` (solver.model).
fn block_with(dim: usize, n: usize, re_factor: f64, model: &str) -> Scene {
    let dp = 0.01;
    let side = n as f64 * dp;
    let v = |x: f64| vec![x; dim];
    let text = serde_json::json!({
        "name": "block",
        "dimension": dim,
        "particle_spacing": dp,
        "solver": { "model": model, "re_factor": re_factor, "max_particles": 100_000_000u64 },
        "bodies": [{
            "name": "b",
            "material": { "density": 1000.0, "young": 1e6, "poisson": 0.3 },
            "boxes": [{ "min": v(0.0), "max": v(side) }]
        }],
        "end_time": 0.01,
        "output_interval": 0.001
    })
    .to_string();
    Scene::from_json(&text).unwrap()
}

/// Peak bytes allocated while building the scene's simulation (beyond what was in use before).
fn measured_peak(scene: &Scene) -> usize {
    let _g = MEASURE.lock().unwrap();
    let base = NOW.load(Relaxed);
    PEAK.store(base, Relaxed);
    let sim = Simulation::new(scene).unwrap();
    let peak = PEAK.load(Relaxed) - base;
    drop(sim);
    peak
}

#[test]
#[ignore = "slow (118-203 s on a loaded 2-core machine): the full test command runs it"]
fn estimate_bounds_the_measured_peak() {
    let models = ["second_order", "corrected"];
    let calibrate = std::env::var("CALIBRATE").ok();
    // CALIBRATE=dim:n:re,... measures those blocks only (besides the defaults).
    let listed: Option<Vec<(usize, usize, f64)>> = calibrate.as_deref().and_then(|c| {
        c.split(',')
            .map(|t| {
                let f: Vec<&str> = t.split(':').collect();
                Some((
                    f.first()?.parse().ok()?,
                    f.get(1)?.parse().ok()?,
                    f.get(2)?.parse().ok()?,
                ))
            })
            .collect()
    });
    let calibrate = calibrate.is_some();
    let extra: Vec<(usize, usize, f64)> = if let Some(listed) = listed {
        listed
    } else if calibrate {
        // More sizes for recalibrating the constants of scene::memory.
        let mut v: Vec<(usize, usize, f64)> =
            [100, 150, 250, 400, 500].map(|n| (2, n, 2.1)).to_vec();
        v.extend([20, 25, 35, 45, 50, 60].map(|n| (3, n, 2.1)));
        v.extend([(2, 300, 1.5), (2, 300, 3.0), (3, 40, 1.5), (3, 40, 3.0)]);
        v
    } else {
        vec![]
    };
    let mut failures = Vec::new();
    for model in models {
        // second_order builds are slower (its fits and closure): smaller blocks, and in 3D only
        // the default re (the others take a minute each; CALIBRATE measures them: 1.33-1.50
        // times the peak at re = 1.5 and 3 dp, 27,000 and 64,000 particles).
        let sizes: &[(usize, usize, f64)] = if model == "second_order" {
            &[(2, 150, 2.1), (2, 200, 3.0), (2, 200, 1.5), (3, 15, 2.1)]
        } else {
            &[
                (2, 300, 2.1),
                (2, 200, 3.0),
                (2, 200, 1.5),
                (3, 40, 2.1),
                (3, 30, 3.0),
                (3, 30, 1.5),
            ]
        };
        for &(dim, n, re) in extra.iter().chain(sizes) {
            let s = block_with(dim, n, re, model);
            let e = memory::estimate(&s);
            let peak = measured_peak(&s);
            let np = n.pow(dim as u32);
            eprintln!(
                "{model} {dim}D {np} particles re {re}: peak {peak} B = {:.0} B/particle, estimate {} B/particle ({} bonds)",
                peak as f64 / np as f64,
                e.bytes_per_particle,
                e.bonds_per_particle
            );
            assert_eq!(e.particles, np as u64);
            if calibrate {
                continue;
            }
            // An upper bound, not a wild one: at most 30 % above the measured peak (the
            // allocator's doubling of growing lists moves the peak by 10-20 % between sizes).
            // All sizes are measured before the test fails, so that one run shows them all.
            if (e.bytes as f64) < peak as f64 {
                failures.push(format!(
                    "{model} {dim}D n {n} re {re}: estimate {} < peak {peak}",
                    e.bytes
                ));
            }
            if (e.bytes as f64) >= 1.3 * peak as f64 {
                failures.push(format!(
                    "{model} {dim}D n {n} re {re}: estimate {} far above peak {peak}",
                    e.bytes
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn too_big_for_the_memory_is_refused_before_building() {
    let s = block(3, 100, 2.1);
    let small = Available {
        bytes: 100_000_000,
        source: "test".into(),
    };
    let e = memory::check_against(&s, Some(&small))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("1000000 particles") && e.contains("100.0 MB") && e.contains("bodies"),
        "{e}"
    );
    assert!(memory::check_against(&s, None).is_ok());
    let big = Available {
        bytes: 100_000_000_000,
        source: "test".into(),
    };
    assert!(memory::check_against(&s, Some(&big)).is_ok());
}

#[test]
fn a_170_cube_is_refused_at_once_by_the_default_limit() {
    let mut s = block(3, 10, 2.1);
    s.solver = Default::default();
    s.bodies[0].boxes[0].max = vec![1.7; 3];
    let _g = MEASURE.lock().unwrap();
    let t = std::time::Instant::now();
    let before = NOW.load(Relaxed);
    let e = Simulation::new(&s).err().expect("refused").to_string();
    let grown = NOW.load(Relaxed).saturating_sub(before);
    assert!(
        e.contains("4913000 particles") && e.contains("max_particles"),
        "{e}"
    );
    assert!(e.contains("GB"), "the estimate is named: {e}");
    assert!(t.elapsed().as_secs_f64() < 0.5, "{:?}", t.elapsed());
    assert!(grown < 1 << 20, "nothing was built: {grown} bytes");
}

/// Peak and in-use bytes (beyond `base`) at the end of each set-up stage, the peak being the
/// highest within the stage: the counter's peak is reset to what is in use as a stage ends.
struct StageMemory {
    base: usize,
    rows: Mutex<Vec<(SetupStage, usize, usize)>>,
}

impl SetupObserver for StageMemory {
    fn stage_done(&self, stage: SetupStage, _seconds: f64, _detail: &str) {
        let now = NOW.load(Relaxed);
        let peak = PEAK.load(Relaxed);
        // The rows were reserved before the measurement: this push allocates nothing.
        self.rows
            .lock()
            .unwrap()
            .push((stage, peak - self.base, now - self.base));
        PEAK.store(now, Relaxed);
    }
}

/// Memory of one build and a few steps: per stage (peak within it, in use at its end), then
/// the peak of the steps and what the built world holds. Bytes beyond what was in use before.
#[derive(Clone)]
struct Stages {
    stages: Vec<(SetupStage, usize, usize)>,
    built: usize,
    steps_peak: usize,
}

impl Stages {
    /// The highest peak of the build and the steps.
    fn peak(&self) -> usize {
        self.stages
            .iter()
            .map(|s| s.1)
            .chain([self.steps_peak, self.built])
            .max()
            .unwrap_or(0)
    }
}

fn measure_stages(scene: &Scene, steps: u32) -> Stages {
    let _g = MEASURE.lock().unwrap();
    let rows = Mutex::new(Vec::with_capacity(32));
    let base = NOW.load(Relaxed);
    let obs = StageMemory { base, rows };
    PEAK.store(base, Relaxed);
    let mut sim = Simulation::new_observed(scene, &obs).unwrap();
    let built = NOW.load(Relaxed) - base;
    PEAK.store(NOW.load(Relaxed), Relaxed);
    let dt = sim.max_dt();
    for _ in 0..steps {
        sim.advance_to(sim.time() + dt).unwrap();
    }
    // The energy query of the outputs (energy.csv, the FMU's energies) is part of a step.
    assert!(sim.strain_energy().is_finite());
    let steps_peak = PEAK.load(Relaxed) - base;
    drop(sim);
    let stages = obs.rows.into_inner().unwrap();
    Stages {
        stages,
        built,
        steps_peak,
    }
}

/// The default operator's 40^3 cube, measured once for the tests that read it (a build of
/// 30-60 s: the stage report and the 3 kB bound share it).
fn second_order_40() -> &'static Stages {
    static MEASURED: std::sync::OnceLock<Stages> = std::sync::OnceLock::new();
    MEASURED.get_or_init(|| measure_stages(&block(3, 40, 2.1), 3))
}

/// Prints the figures of `measure_stages` per particle.
fn report(label: &str, np: usize, m: &Stages) {
    let per = |b: usize| b as f64 / np as f64;
    for (stage, peak, now) in &m.stages {
        eprintln!(
            "{label}: {:>15}: peak {:>6.0} B/particle, in use at its end {:>6.0}",
            stage.name(),
            per(*peak),
            per(*now)
        );
    }
    eprintln!(
        "{label}: built world {:.0} B/particle, peak of the steps {:.0}, peak overall {:.0} ({} particles)",
        per(m.built),
        per(m.steps_peak),
        per(m.peak()),
        np
    );
}

#[test]
#[ignore = "slow (220-410 s on a loaded 2-core machine): the full test command runs it"]
fn memory_by_setup_stage() {
    // Two cubes of the default operator in 3D (closure included) and one of `corrected`: the
    // figures of BENCHMARKS.md ("Issue 25: memory"). The difference between the two cubes'
    // figures over their particle counts is the cost per particle at large sizes, where the
    // closure's reduced box (at most 17^3 particles whatever the body's size) is amortised.
    let mut rows = Vec::new();
    for (model, n) in [
        ("second_order", 30),
        ("second_order", 40),
        ("corrected", 40),
    ] {
        let s = block_with(3, n, 2.1, model);
        let np = n * n * n;
        let m = if (model, n) == ("second_order", 40) {
            second_order_40().clone()
        } else {
            measure_stages(&s, 3)
        };
        report(&format!("{model} {n}^3"), np, &m);
        let e = memory::estimate(&s);
        // The guard's estimate bounds every stage, the steps and the built world.
        assert!(
            e.bytes as usize >= m.peak(),
            "{model} {n}^3: estimate {} B below the peak {} B",
            e.bytes,
            m.peak()
        );
        assert!(m.stages.len() >= 5, "{model}: the stages were told");
        rows.push((model, np, m));
    }
    // The cost per particle at large sizes, stage by stage: the difference of the two cubes'
    // figures over the difference of their particle counts; and what is left at no particles
    // (the fixed cost: the closure's reduced box).
    let (a, b) = (&rows[0], &rows[1]);
    let mut lines: Vec<(String, usize, usize)> =
        a.2.stages
            .iter()
            .zip(&b.2.stages)
            .map(|(x, y)| (format!("{} peak", x.0.name()), x.1, y.1))
            .collect();
    lines.push(("built world".into(), a.2.built, b.2.built));
    lines.push(("steps peak".into(), a.2.steps_peak, b.2.steps_peak));
    for (what, fa, fb) in lines {
        let slope = (fb as f64 - fa as f64) / (b.1 - a.1) as f64;
        eprintln!(
            "second_order {what}: {slope:.0} B/particle at large sizes, fixed {:.1} MB",
            (fa as f64 - slope * a.1 as f64) / 1e6
        );
    }
}

#[test]
#[ignore = "slow (shares its 40^3 build with memory_by_setup_stage: the binary's 5 tests take 71 s on an idle 2-core machine): the full test command runs it"]
fn second_order_needs_at_most_3_kb_per_particle_in_3d() {
    // Issue 25: at most 3 kB per particle in 3D for the default operator at re = 2.1 dp, the
    // peak over the whole build (closure included) and a few steps with the strain energy
    // query of the outputs. Size: the closure solves on a reduced box of at most 17^3
    // particles whatever the body's size, a fixed cost of about 40 MB (BENCHMARKS.md "Issue
    // 25: memory") on top of 1.7 kB per particle, which makes the closure the peak of a 30^3
    // cube (3.2 kB per particle there). From 40^3 (64,000 particles) on, the peak is the
    // first stable-step measurement, which grows with the particles (2.6 kB each at large
    // sizes), as in a large scene. Bound: the issue's, 3,000 B per particle.
    let n = 40;
    let np = n * n * n;
    let m = second_order_40();
    report("second_order 40^3", np, m);
    let per = m.peak() as f64 / np as f64;
    assert!(per <= 3000.0, "{per:.0} B per particle > 3000");
}
