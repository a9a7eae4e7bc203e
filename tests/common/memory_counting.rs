//! A counting global allocator and the memory measurements built on it, shared by the memory
//! tests (tests/limits_memory.rs) and the memory benchmark (bench/memory.rs), each of which
//! installs `Counting` as its binary's global allocator.
#![allow(dead_code)]
use mps_solid::physics::world::{SetupObserver, SetupStage};
use mps_solid::{Scene, Simulation};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::Mutex;

/// The system allocator, counting the bytes in use and their peak.
pub struct Counting;

pub static NOW: AtomicUsize = AtomicUsize::new(0);
pub static PEAK: AtomicUsize = AtomicUsize::new(0);
/// One measurement at a time (tests run on several threads).
pub static MEASURE: Mutex<()> = Mutex::new(());

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

/// A cube (3D) or square (2D) of n particles a side, nothing held, no gravity, with the
/// default operator.
pub fn block(dim: usize, n: usize, re_factor: f64) -> Scene {
    block_with(dim, n, re_factor, "second_order")
}

/// `block` with the operator `model` (solver.model).
pub fn block_with(dim: usize, n: usize, re_factor: f64, model: &str) -> Scene {
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

/// Runs `f` on a pool of 2 threads, whatever RAYON_NUM_THREADS says (the test command runs
/// the tests on one thread each): the figures are those of the 2-core machine the bounds are
/// stated for. The pool is built before `f` reads the counters.
fn on_two_threads<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool of 2 threads")
        .install(f)
}

/// Peak bytes allocated while building the scene's simulation (beyond what was in use before).
pub fn measured_peak(scene: &Scene) -> usize {
    let _g = MEASURE.lock().unwrap();
    on_two_threads(|| {
        let base = NOW.load(Relaxed);
        PEAK.store(base, Relaxed);
        let sim = Simulation::new(scene).unwrap();
        let peak = PEAK.load(Relaxed) - base;
        drop(sim);
        peak
    })
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
pub struct Stages {
    pub stages: Vec<(SetupStage, usize, usize)>,
    pub built: usize,
    pub steps_peak: usize,
}

impl Stages {
    /// The highest peak of the build and the steps.
    pub fn peak(&self) -> usize {
        self.stages
            .iter()
            .map(|s| s.1)
            .chain([self.steps_peak, self.built])
            .max()
            .unwrap_or(0)
    }
}

/// The memory of building `scene` and taking `steps` stable steps, stage by stage.
pub fn measure_stages(scene: &Scene, steps: u32) -> Stages {
    let _g = MEASURE.lock().unwrap();
    on_two_threads(|| measure_stages_here(scene, steps))
}

fn measure_stages_here(scene: &Scene, steps: u32) -> Stages {
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

/// Prints the figures of `measure_stages` per particle.
pub fn report(label: &str, np: usize, m: &Stages) {
    let per = |b: usize| b as f64 / np as f64;
    for (stage, peak, now) in &m.stages {
        println!(
            "{label}: {:>15}: peak {:>6.0} B/particle, in use at its end {:>6.0}",
            stage.name(),
            per(*peak),
            per(*now)
        );
    }
    println!(
        "{label}: built world {:.0} B/particle, peak of the steps {:.0}, peak overall {:.0} ({} particles)",
        per(m.built),
        per(m.steps_peak),
        per(m.peak()),
        np
    );
}
