//! Runs a scene to its end time: probe time series, timing figures, measured frequency and peak
//! deflection. Shared by the command line, the case reports and the benchmark.
pub mod analysis;

use self::analysis::{dominant_frequency, peak};
use crate::physics::world::{SetupMemo, SetupObserver, SetupStage};
use crate::scene::limits::num;
use crate::scene::{axis_index, Scene, SceneWarning};
use crate::sim::Simulation;
use serde::Serialize;
use std::time::Instant;

/// Probe displacements over time.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Series {
    pub probes: Vec<String>,
    /// Sample times (s).
    pub time: Vec<f64>,
    /// `displacement[k][n]`: probe k at sample n (m).
    pub displacement: Vec<Vec<[f64; 3]>>,
    /// The energies at each sample when the run was asked for them (`RunOptions::energy`),
    /// else empty.
    pub energy: Vec<Energies>,
}

/// The energies of the whole scene at one instant (J; per metre of depth in 2D).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Energies {
    /// Kinetic energy of translation and particle rotation, 1/2 m v^2 + 1/2 I w^2 with the
    /// velocities of the last step (symplectic Euler: they lag the positions by half a step, so
    /// the sum oscillates by O(omega dt) around the conserved value).
    pub kinetic: f64,
    /// Elastic strain energy of the current positions.
    pub strain: f64,
    /// Contact potential energy of the current positions (0 without contact).
    pub contact: f64,
    /// Strain energy released by broken bonds so far (0 without fracture).
    pub fracture: f64,
}

impl Energies {
    /// The energies of a simulation now (the strain energy is a pass over the bonds).
    pub fn of(sim: &Simulation) -> Energies {
        Energies {
            kinetic: sim.kinetic_energy(),
            strain: sim.strain_energy(),
            contact: sim.contact_energy(),
            fracture: sim.fracture_energy(),
        }
    }
    /// kinetic + strain + contact (J): conserved by an undamped run without loads and gravity
    /// and without fracture; with fracture, total + fracture is (a break releases energy and
    /// never creates it).
    pub fn total(&self) -> f64 {
        self.kinetic + self.strain + self.contact
    }
}

/// What a run records besides the probes, and how it can be stopped.
#[derive(Clone, Copy, Debug, Default)]
pub struct RunOptions {
    /// The energies at every output sample (`Series::energy`). Costs a pass over the
    /// bonds per sample (in parallel; a fraction of a solver step).
    pub energy: bool,
    /// When this flag becomes true (e.g. set by a signal handler), the run stops after the
    /// current solver step as if it had failed there: `RunResult::error` says so and the series
    /// keeps what was computed.
    pub stop: Option<&'static std::sync::atomic::AtomicBool>,
}

/// What a run reports while it runs.
#[derive(Clone, Copy)]
pub enum RunEvent<'a> {
    /// The scene was built and will run; a warning of under-resolved geometry (before the
    /// first step).
    Warning(&'a SceneWarning),
    /// An output sample at this time (s) was taken.
    Sample(f64),
    /// A solver step ended at `time` (s); `steps` solver steps so far in this run.
    Step { time: f64, steps: u64 },
    /// A stage of the model's set-up ended after `seconds` (wall clock), as it happens.
    Setup {
        stage: SetupStage,
        seconds: f64,
        detail: &'a str,
    },
    /// The simulation at an output sample (the initial state first, then after each `Sample`):
    /// for output that needs more than the probes (`mps run --surface`).
    State(&'a Simulation),
}

/// Relays the set-up's stages to a run's `on_event` (the set-up runs on the calling thread).
struct SetupRelay<'a, F>(std::cell::RefCell<&'a mut F>, Option<&'a SetupMemo>);

impl<F: FnMut(RunEvent)> SetupObserver for SetupRelay<'_, F> {
    fn stage_done(&self, stage: SetupStage, seconds: f64, detail: &str) {
        let mut f = self.0.borrow_mut();
        (*f)(RunEvent::Setup {
            stage,
            seconds,
            detail,
        });
    }
    fn memo(&self) -> Option<&SetupMemo> {
        self.1
    }
}

/// Result of a run; `error` is set when the solver stopped early (the series keeps what was
/// computed up to then).
#[derive(Clone, Debug, Serialize)]
pub struct RunResult {
    pub scene: String,
    pub dimension: usize,
    pub particles: usize,
    /// Stored (directed) bonds.
    pub bonds: usize,
    /// Stability limit 2 / omega_max (s).
    pub critical_dt: f64,
    /// Largest step taken (s).
    pub dt: f64,
    pub steps: u64,
    pub end_time: f64,
    pub wall_time_s: f64,
    /// Directed bonds evaluated per second in the force loops (two passes per step).
    pub pair_updates_per_s: f64,
    /// Final displacement of each probe (m).
    pub final_displacement: Vec<(String, [f64; 3])>,
    /// Final reaction force of each boundary group (N).
    pub final_reaction: Vec<(String, [f64; 3])>,
    /// Final kinetic and strain energy (J).
    pub kinetic_energy: f64,
    pub strain_energy: f64,
    /// Frequency of the analysis probe (Hz), when the scene asks for it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frequency_hz: Option<f64>,
    /// Largest displacement component of the analysis probe over the run (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_m: Option<f64>,
    /// Warnings of under-resolved geometry (`Scene::warnings`).
    pub warnings: Vec<SceneWarning>,
    pub series: Series,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Refuses a built scene with nothing to simulate: no particle that is free to move and bonded
/// (a fully clamped body, single-particle bodies), whose stable step is infinite.
pub fn check_free_particles(sim: &Simulation) -> Result<(), String> {
    let crit = sim.critical_dt();
    if !crit.is_finite() {
        return Err(format!(
            "no free particle: every particle of the {} is held by a boundary group or has no \
             bond, so nothing can move elastically and the stable step is undefined (critical \
             dt = {}); free part of a body or give it more than one particle",
            if sim.particles() == 1 {
                "scene (a single particle)"
            } else {
                "scene"
            },
            num(crit)
        ));
    }
    Ok(())
}

/// Refuses a result holding a non-finite number (JSON would print it as null): the name of the
/// first such value and its time.
pub fn check_finite(r: &RunResult) -> Result<(), String> {
    let bad = |what: String, v: f64| -> Result<(), String> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(format!(
                "non-finite result: {what} = {} at t = {} s (scene '{}')",
                num(v),
                num(r.end_time),
                r.scene
            ))
        }
    };
    bad("critical_dt".into(), r.critical_dt)?;
    bad("dt".into(), r.dt)?;
    bad("kinetic_energy".into(), r.kinetic_energy)?;
    bad("strain_energy".into(), r.strain_energy)?;
    for (name, u) in &r.final_displacement {
        for (k, c) in u.iter().enumerate() {
            bad(format!("displacement of probe '{name}' [{k}]"), *c)?;
        }
    }
    for (name, f) in &r.final_reaction {
        for (k, c) in f.iter().enumerate() {
            bad(format!("reaction of group '{name}' [{k}]"), *c)?;
        }
    }
    if let Some(f) = r.frequency_hz {
        bad("frequency_hz".into(), f)?;
    }
    if let Some(p) = r.peak_m {
        bad("peak_m".into(), p)?;
    }
    for (n, e) in r.series.energy.iter().enumerate() {
        for (what, v) in [
            ("kinetic", e.kinetic),
            ("strain", e.strain),
            ("contact", e.contact),
            ("fracture", e.fracture),
        ] {
            if !v.is_finite() {
                return Err(format!(
                    "non-finite result: {what} energy = {} at t = {} s (scene '{}')",
                    num(v),
                    num(r.series.time[n]),
                    r.scene
                ));
            }
        }
    }
    for (k, series) in r.series.displacement.iter().enumerate() {
        for (n, u) in series.iter().enumerate() {
            if u.iter().any(|c| !c.is_finite()) {
                return Err(format!(
                    "non-finite result: displacement of probe '{}' at t = {} s",
                    r.series.probes[k],
                    num(r.series.time[n])
                ));
            }
        }
    }
    Ok(())
}

/// Runs a scene; `on_sample(time)` is called after every output sample (progress bars). Refused
/// before the first step: a scene without a free particle, and a run that would take more than
/// solver.max_steps steps. A run that produces a non-finite number is an error.
pub fn run_scene(scene: &Scene, mut on_sample: impl FnMut(f64)) -> Result<RunResult, String> {
    run_scene_with(scene, RunOptions::default(), |e| {
        if let RunEvent::Sample(t) = e {
            on_sample(t)
        }
    })
}

/// Builds a scene's model and refuses, before any step, a scene without a free particle and a
/// run that would take more work than the scene allows (solver.max_steps,
/// solver.max_particle_steps; the message gives its estimated wall time). The model is ready
/// for [`run_prepared`].
pub fn prepare(scene: &Scene) -> Result<Simulation, String> {
    prepare_with(scene, &mut |_| {})
}

/// [`prepare`], telling `on_event` of each stage of the set-up as it ends ([`RunEvent::Setup`]).
pub fn prepare_with<F: FnMut(RunEvent)>(
    scene: &Scene,
    on_event: &mut F,
) -> Result<Simulation, String> {
    prepare_with_memo(scene, None, on_event)
}

/// [`prepare_with`], taking the default operator's closure from `memo` where it holds one for
/// this geometry and keeping the one computed there otherwise (`mps run --closure-cache`).
pub fn prepare_with_memo<F: FnMut(RunEvent)>(
    scene: &Scene,
    memo: Option<&SetupMemo>,
    on_event: &mut F,
) -> Result<Simulation, String> {
    let sim = Simulation::new_observed(scene, &SetupRelay(std::cell::RefCell::new(on_event), memo))
        .map_err(|e| e.to_string())?;
    check_free_particles(&sim)?;
    sim.check_work(scene.end_time).map_err(|e| e.to_string())?;
    Ok(sim)
}

/// [`run_scene`] with options; `on_event` hears of the scene's warnings once it is built, of
/// every solver step and of every output sample.
pub fn run_scene_with(
    scene: &Scene,
    opts: RunOptions,
    mut on_event: impl FnMut(RunEvent),
) -> Result<RunResult, String> {
    let sim = prepare_with(scene, &mut on_event)?;
    run_prepared(scene, sim, opts, on_event)
}

/// Runs a model built by [`prepare`] from `scene` to the scene's end time.
pub fn run_prepared(
    scene: &Scene,
    mut sim: Simulation,
    opts: RunOptions,
    mut on_event: impl FnMut(RunEvent),
) -> Result<RunResult, String> {
    // Reported once the run is sure to start (a refused scene gets its error alone).
    for w in sim.warnings() {
        on_event(RunEvent::Warning(w));
    }
    let np = scene.probes.len();
    let mut series = Series {
        probes: scene.probes.iter().map(|p| p.name.clone()).collect(),
        ..Default::default()
    };
    series.displacement = vec![Vec::new(); np];
    let sample = |sim: &Simulation, series: &mut Series| {
        series.time.push(sim.time());
        for k in 0..np {
            series.displacement[k].push(sim.probe_displacement(k));
        }
        if opts.energy {
            series.energy.push(Energies::of(sim));
        }
    };
    sample(&sim, &mut series);
    on_event(RunEvent::State(&sim));
    let start = Instant::now();
    let n_out = (scene.end_time / scene.output_interval - 1e-9)
        .ceil()
        .max(1.0) as u64;
    let mut error = None;
    for k in 1..=n_out {
        let t = if k == n_out {
            scene.end_time
        } else {
            k as f64 * scene.output_interval
        };
        let mut steps = sim.steps();
        let advanced = sim.advance_to_with(t, |time| {
            steps += 1;
            on_event(RunEvent::Step { time, steps });
            !opts
                .stop
                .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
        });
        if let Err(e) = advanced {
            error = Some(e.to_string());
            break;
        }
        sample(&sim, &mut series);
        on_event(RunEvent::Sample(t));
        on_event(RunEvent::State(&sim));
    }
    let wall = start.elapsed().as_secs_f64();
    let (mut frequency_hz, mut peak_m) = (None, None);
    if let Some(a) = &scene.analysis {
        let k = scene
            .probes
            .iter()
            .position(|p| p.name == a.probe)
            .expect("validated");
        let c = axis_index(&a.component).expect("validated");
        let u: Vec<f64> = series.displacement[k].iter().map(|d| d[c]).collect();
        frequency_hz = dominant_frequency(
            &series.time,
            &u,
            0.5 / scene.end_time.max(1e-12) * 4.0,
            0.25 / scene.output_interval,
        );
        peak_m = Some(peak(&u));
    }
    let steps = sim.steps();
    let r = RunResult {
        scene: scene.name.clone(),
        dimension: scene.dimension,
        particles: sim.particles(),
        bonds: sim.bonds(),
        critical_dt: sim.critical_dt(),
        dt: sim.max_dt(),
        steps,
        end_time: sim.time(),
        wall_time_s: wall,
        pair_updates_per_s: 2.0 * sim.bonds() as f64 * steps as f64 / wall.max(1e-12),
        final_displacement: (0..np)
            .map(|k| (series.probes[k].clone(), sim.probe_displacement(k)))
            .collect(),
        final_reaction: scene
            .boundaries
            .iter()
            .enumerate()
            .map(|(g, b)| (b.name.clone(), sim.group_reaction(g)))
            .collect(),
        kinetic_energy: sim.kinetic_energy(),
        strain_energy: sim.strain_energy(),
        frequency_hz,
        peak_m,
        warnings: sim.warnings().to_vec(),
        series,
        error,
    };
    if let Err(e) = check_finite(&r) {
        return Err(match &r.error {
            Some(stop) => format!("the run stopped early: {stop}; {e}"),
            None => e,
        });
    }
    Ok(r)
}

/// The probe series as CSV: `time,<probe>.ux,<probe>.uy[,<probe>.uz]...`.
pub fn series_csv(s: &Series, dimension: usize) -> String {
    let comps = ["ux", "uy", "uz"];
    let mut out = String::from("time");
    for p in &s.probes {
        for c in &comps[..dimension] {
            out.push_str(&format!(",{p}.{c}"));
        }
    }
    out.push('\n');
    for (n, t) in s.time.iter().enumerate() {
        out.push_str(&format!("{t:.9e}"));
        for d in &s.displacement {
            for c in &d[n][..dimension] {
                out.push_str(&format!(",{c:.9e}"));
            }
        }
        out.push('\n');
    }
    out
}

/// The energy series as CSV:
/// `time,kinetic_energy,strain_energy,contact_energy,total_energy,fracture_energy` (s, J; J/m in
/// 2D), one row per output sample; fracture_energy is the strain energy released by breaks so
/// far.
pub fn energy_csv(s: &Series) -> String {
    let mut out = String::from(
        "time,kinetic_energy,strain_energy,contact_energy,total_energy,fracture_energy\n",
    );
    for (t, e) in s.time.iter().zip(&s.energy) {
        out.push_str(&format!(
            "{t:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e}\n",
            e.kinetic,
            e.strain,
            e.contact,
            e.total(),
            e.fracture
        ));
    }
    out
}
