//! The instance core: the [`Instance`] struct, fmi2Instantiate, the call-order state machine
//! ([`Mode`] and its checks), setup, initialisation, terminate and reset, the model build and
//! the cached outputs.
use super::inputs::{BoundaryTiming, GravitySource, Inputs};
use super::logging::{LogRecord, Logger, PendingLog};
use super::resources::{load_closure, load_scene, resource_dir};
use super::status::Status;
use super::status::{FmiError, FmiResult};
use super::worker_pool::WorkerPool;
use crate::fmi::model_description::guid;
use crate::fmi::variables::{Quantity, VariableTable};
use crate::physics::world::{SetupMemo, SetupObserver, SetupStage};
use crate::scene::limits::num;
use crate::scene::Scene;
use crate::sim::{SimState, Simulation};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The FMI 2.0 co-simulation states this FMU distinguishes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Mode {
    Instantiated,
    InitializationMode,
    StepComplete,
    /// After a doStep returned fmi2Error: values can be read, the state restored, the
    /// instance reset or freed.
    Error,
    Terminated,
}

impl Mode {
    fn name(self) -> &'static str {
        match self {
            Mode::Instantiated => "Instantiated",
            Mode::InitializationMode => "InitializationMode",
            Mode::StepComplete => "StepComplete",
            Mode::Error => "Error",
            Mode::Terminated => "Terminated",
        }
    }
}

/// What a set-up in progress (fmi2EnterInitializationMode, fmi2ExitInitializationMode after
/// parameter changes) shares with other threads: whether one runs, and the request to stop it
/// (fmi2CancelStep from another thread; see `ffi::fmi2CancelStep`).
#[derive(Debug, Default)]
pub struct SetupControl {
    building: AtomicBool,
    cancel: AtomicBool,
}

impl SetupControl {
    /// Whether a set-up is running.
    pub fn building(&self) -> bool {
        self.building.load(Ordering::SeqCst)
    }
    /// Asks the running set-up to stop at its next stage boundary; false if none runs.
    pub fn cancel(&self) -> bool {
        self.cancel.store(true, Ordering::SeqCst);
        self.building()
    }
}

/// The set-up's observer of an instance: each stage to the host's logger as it ends (category
/// logEvents), and the stop requested by fmi2CancelStep.
pub(super) struct SetupLog<'a> {
    pub(super) logger: Option<Arc<dyn Logger>>,
    pub(super) control: &'a SetupControl,
    /// The instance's closure from its earlier builds (the parameters change no geometry).
    pub(super) memo: &'a SetupMemo,
}

impl SetupObserver for SetupLog<'_> {
    fn stage_done(&self, stage: SetupStage, seconds: f64, detail: &str) {
        if let Some(l) = &self.logger {
            let detail = if detail.is_empty() {
                String::new()
            } else {
                format!(" ({detail})")
            };
            l.log(
                Status::Ok,
                "logEvents",
                &format!("set-up: {} took {seconds:.2} s{detail}", stage.name()),
            );
        }
    }
    fn stop(&self) -> Option<String> {
        self.control
            .cancel
            .load(Ordering::SeqCst)
            .then(|| "fmi2CancelStep was called".to_string())
    }
    fn stop_flag(&self) -> Option<&AtomicBool> {
        Some(&self.control.cancel)
    }
    fn memo(&self) -> Option<&SetupMemo> {
        Some(self.memo)
    }
}

/// The parameters a simulation was built from and its initial state.
pub(super) struct Built {
    pub(super) params: Scene,
    pub(super) initial: SimState,
    /// Wall time of the build (s), for the log of a reuse.
    pub(super) seconds: f64,
}

/// One FMU instance.
pub struct Instance {
    name: String,
    pub(super) guid: String,
    /// The scene the FMU was packed with.
    pub(super) scene: Scene,
    /// The scene with the parameter values set by the host.
    pub(super) params: Scene,
    pub(super) table: VariableTable,
    pub(super) sim: Option<Simulation>,
    /// What `sim` was built from and its state right after the build: fmi2Reset rewinds the
    /// built model to it, and a build for the same parameters restores it instead of
    /// building again (the set-up, seconds for a closed body, runs once per parameter set).
    pub(super) built: Option<Built>,
    /// What its builds keep for the next (the second-order operator's closure: the
    /// parameters change the materials, the step and the damping, never the geometry).
    pub(super) memo: SetupMemo,
    /// Parameters changed since the simulation was built.
    pub(super) stale: bool,
    pub(super) pool: WorkerPool,
    pub(super) mode: Mode,
    pub(super) inputs: Inputs,
    /// startTime of fmi2SetupExperiment: the scene's time 0 (its time laws start here).
    pub(super) start_time: f64,
    pub(super) time: f64,
    pub(super) last_successful_time: f64,
    pub(super) stop_time: Option<f64>,
    /// Output values at `time` (index = value reference), from the last successful step.
    pub(super) outputs: Vec<f64>,
    /// Whether the energies in `outputs` are those of the current state.
    pub(super) energies_fresh: bool,
    /// Whether the gravity inputs were set while the scene's law is in force (warned once).
    pub(super) gravity_ignored_warned: bool,
    /// The messages of the current call (handed to the logger after the call has released the
    /// instance: [`Instance::take_log`]) and the debug-logging switches.
    pub(super) log: PendingLog,
    /// The running set-up's state, shared with fmi2CancelStep.
    pub(super) control: Arc<SetupControl>,
}

impl Instance {
    /// fmi2Instantiate: checks the type, reads the scene from the resources and the GUID. The
    /// solver work runs on a rayon pool of the instance's own ([`WorkerPool::new`]; the C
    /// layer passes its own threads to `instantiate_with_pool`).
    pub fn instantiate(
        name: &str,
        co_simulation: bool,
        fmu_guid: &str,
        resource_location: Option<&str>,
        logger: Arc<dyn Logger>,
        logging_on: bool,
    ) -> Result<Instance, String> {
        Self::instantiate_with_pool(
            name,
            co_simulation,
            fmu_guid,
            resource_location,
            logger,
            logging_on,
            WorkerPool::new,
        )
    }

    /// [`Instance::instantiate`] with the worker pool that `pool` starts (called with the
    /// instance name once the arguments are checked).
    pub(crate) fn instantiate_with_pool(
        name: &str,
        co_simulation: bool,
        fmu_guid: &str,
        resource_location: Option<&str>,
        logger: Arc<dyn Logger>,
        logging_on: bool,
        pool: impl FnOnce(&str) -> Result<WorkerPool, String>,
    ) -> Result<Instance, String> {
        if !co_simulation {
            return Err(
                "this FMU supports Co-Simulation only (fmuType must be fmi2CoSimulation)".into(),
            );
        }
        let uri = resource_location
            .ok_or("fmuResourceLocation is NULL: the FMU needs its resources/scene.json")?;
        let dir = resource_dir(uri)?;
        let scene = load_scene(&dir)?;
        let (memo, shipped) = match load_closure(&dir) {
            None => (SetupMemo::default(), None),
            Some(Ok(m)) => (m, Some(Ok(()))),
            Some(Err(e)) => (SetupMemo::default(), Some(Err(e))),
        };
        let expected = guid(&scene);
        if fmu_guid != expected {
            return Err(format!(
                "GUID mismatch: the host passed {fmu_guid} but this FMU (scene '{}', mps-solid {}) has {expected}",
                scene.name,
                env!("CARGO_PKG_VERSION")
            ));
        }
        let pool = pool(name)?;
        let table = VariableTable::new(&scene);
        let inst = Instance {
            name: name.to_string(),
            guid: expected,
            params: scene.clone(),
            inputs: Inputs::start(&scene),
            outputs: vec![0.0; table.vars.len()],
            energies_fresh: false,
            gravity_ignored_warned: false,
            scene,
            table,
            sim: None,
            built: None,
            memo,
            stale: true,
            pool,
            mode: Mode::Instantiated,
            start_time: 0.0,
            time: 0.0,
            last_successful_time: 0.0,
            stop_time: None,
            log: PendingLog::new(logger, logging_on),
            control: Arc::default(),
        };
        inst.log.event(&format!(
            "instantiated '{}' (scene '{}', {} variables)",
            inst.name,
            inst.scene.name,
            inst.table.vars.len()
        ));
        match shipped {
            Some(Ok(())) => inst.log.event(
                "the resources hold the closure `mps pack` computed: the first build takes it",
            ),
            Some(Err(e)) => inst.log.warn(format!(
                "{e}; the default operator's closure is computed at initialisation instead"
            )),
            None => {}
        }
        // Under-resolved geometry: from the particles alone (the parameters change no geometry),
        // so it is known here, before the model is built.
        // On the instance's threads: the check runs parallel loops, which must not start
        // rayon's global pool (its threads would outlive the instance).
        for w in inst.pool.install(|| inst.scene.warnings()) {
            inst.log.warn(w.to_string());
        }
        Ok(inst)
    }

    /// The state of a running set-up, for fmi2CancelStep from another thread.
    pub fn setup_control(&self) -> Arc<SetupControl> {
        self.control.clone()
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }
    /// Where the last step ended, in the host's time (startTime plus the simulated time, as
    /// the host sums it): what the next doStep's currentCommunicationPoint must be.
    pub fn time(&self) -> f64 {
        self.time
    }
    /// The simulated time since startTime (s): what the model has advanced (0 before the
    /// model is built).
    pub fn simulated_time(&self) -> f64 {
        self.sim.as_ref().map_or(0.0, |s| s.time())
    }
    pub fn table(&self) -> &VariableTable {
        &self.table
    }

    /// The messages logged since the last call, in order. The C layer takes them while it holds
    /// the instance and hands them to the host's logger after releasing it.
    pub fn take_log(&self) -> Vec<LogRecord> {
        self.log.take()
    }

    /// Hands the pending messages to the instance's logger (for Rust callers of this API; the C
    /// layer uses [`Instance::take_log`] so that no lock is held while the host's logger runs).
    pub fn flush_log(&self) {
        self.log.flush()
    }

    /// Logs an error of a call (always: errors are not debug messages).
    pub fn report(&self, function: &str, e: &FmiError) {
        self.log.report(function, e)
    }

    /// fmi2SetDebugLogging.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[String]) -> FmiResult<()> {
        self.log.set_debug_logging(on, categories)
    }

    pub(super) fn require(&self, function: &str, allowed: &[Mode]) -> FmiResult<()> {
        if allowed.contains(&self.mode) {
            Ok(())
        } else {
            Err(FmiError::IllegalCall(format!(
                "illegal call sequence: {function} is not allowed in state {} (allowed in: {})",
                self.mode.name(),
                allowed
                    .iter()
                    .map(|m| m.name())
                    .collect::<Vec<_>>()
                    .join(", ")
            )))
        }
    }

    /// fmi2SetupExperiment: the tolerance is ignored (the solver's step is set by stability).
    /// startTime becomes the scene's time 0: its time laws (the Eq. (46) ramp) start there.
    pub fn setup_experiment(&mut self, start: f64, stop: Option<f64>) -> FmiResult<()> {
        self.require("fmi2SetupExperiment", &[Mode::Instantiated])?;
        if !start.is_finite() {
            return Err(FmiError::Invalid(format!(
                "startTime = {} must be finite",
                num(start)
            )));
        }
        if let Some(s) = stop {
            if !s.is_finite() {
                return Err(FmiError::Invalid(format!("stopTime = {s} must be finite")));
            }
            if s < start {
                return Err(FmiError::Invalid(format!(
                    "stopTime = {} is before startTime = {} (nothing was set)",
                    num(s),
                    num(start)
                )));
            }
        }
        if !self.stale && self.sim.as_ref().is_some_and(|s| s.time() != 0.0) {
            return Err(FmiError::IllegalCall(
                "fmi2SetupExperiment after a restored FMU state that is not at the start: the \
                 state already fixes the time"
                    .into(),
            ));
        }
        self.stop_time = stop;
        self.start_time = start;
        self.time = start;
        self.last_successful_time = start;
        Ok(())
    }

    /// Builds (or rebuilds after parameter changes) the simulation on the instance's threads.
    pub(super) fn build(&mut self) -> FmiResult<()> {
        if !self.stale && self.sim.is_some() {
            return Ok(());
        }
        if self.rewind_to_built()? {
            return self.refresh_outputs();
        }
        let started = std::time::Instant::now();
        let params = &self.params;
        // The stages reach the host's logger as they end (the logger is called with the
        // instance locked: a logger that calls back into it is refused, see ffi::guard).
        let observer = SetupLog {
            logger: self.log.immediate("logEvents"),
            control: &self.control,
            memo: &self.memo,
        };
        self.control.cancel.store(false, Ordering::SeqCst);
        self.control.building.store(true, Ordering::SeqCst);
        let sim = self
            .pool
            .install(|| Simulation::new_observed(params, &observer));
        self.control.building.store(false, Ordering::SeqCst);
        let sim = sim.map_err(|e| FmiError::Solver(format!("cannot build the model: {e}")))?;
        self.log.event(&format!(
            "built the model: {} particles, {} bonds, solver step {:.4e} s",
            sim.particles(),
            sim.bonds(),
            sim.max_dt()
        ));
        // What only the built model knows (the scene's own warnings were logged at
        // instantiation): second-order bodies without the closure at their free faces.
        let known = self.pool.install(|| self.scene.warnings());
        for w in sim.warnings() {
            if !known.contains(w) {
                self.log.warn(w.to_string());
            }
        }
        let initial = self.pool.install(|| sim.state());
        self.built = Some(Built {
            params: self.params.clone(),
            initial,
            seconds: started.elapsed().as_secs_f64(),
        });
        self.sim = Some(sim);
        self.stale = false;
        self.refresh_outputs()
    }

    /// Rewinds the built model to its initial state when it was built from the current
    /// parameters (after fmi2Reset, or parameters set back to those of the build): the same
    /// model as a new build gives, bit for bit, without its set-up. False: a build is needed.
    pub(super) fn rewind_to_built(&mut self) -> FmiResult<bool> {
        let (Some(sim), Some(built)) = (self.sim.as_mut(), self.built.as_ref()) else {
            return Ok(false);
        };
        if built.params != self.params {
            return Ok(false);
        }
        let restored = self.pool.install(|| sim.set_state(&built.initial));
        if let Err(e) = restored {
            // Not expected (the state is the model's own); a build is the way back.
            self.log.event(&format!(
                "the built model could not be rewound ({e}); building it again"
            ));
            self.sim = None;
            self.built = None;
            return Ok(false);
        }
        self.log.event(&format!(
            "rewound the model built for these parameters to its initial state (its set-up of {:.3} s skipped)",
            built.seconds
        ));
        self.stale = false;
        Ok(true)
    }

    /// The cheap outputs (probes, reactions, counters) of a simulation, in table order (None
    /// for the others); an error if one is not finite.
    pub(super) fn cheap_outputs(&self, sim: &Simulation) -> FmiResult<Vec<Option<f64>>> {
        let table = &self.table;
        let n_loads = self.scene.loads.len();
        let new: Vec<Option<f64>> = self.pool.install(|| {
            let loads: Vec<_> = (0..n_loads).map(|r| sim.load_motion(r)).collect();
            table
                .vars
                .iter()
                .map(|v| match v.quantity {
                    Quantity::ProbeDisplacement(p, k) => Some(sim.probe_displacement(p)[k]),
                    Quantity::ProbeVelocity(p, k) => Some(sim.probe_velocity(p)[k]),
                    Quantity::LoadDisplacement(r, k) => Some(loads[r].0[k]),
                    Quantity::LoadVelocity(r, k) => Some(loads[r].1[k]),
                    Quantity::Reaction(g, k) => Some(sim.group_reaction(g)[k]),
                    Quantity::FractureCount => Some(sim.broken_bonds() as f64),
                    Quantity::Steps => Some(sim.steps() as f64),
                    Quantity::FractureEnergy => Some(sim.fracture_energy()),
                    _ => None,
                })
                .collect()
        });
        if let Some((i, _)) = new
            .iter()
            .enumerate()
            .find(|(_, x)| x.is_some_and(|x| !x.is_finite()))
        {
            return Err(FmiError::Solver(format!(
                "output {} became non-finite at t = {}",
                self.table.vars[i].name,
                self.start_time + sim.time()
            )));
        }
        Ok(new)
    }

    pub(super) fn store_outputs(&mut self, new: Vec<Option<f64>>) {
        for (o, n) in self.outputs.iter_mut().zip(new) {
            if let Some(n) = n {
                *o = n;
            }
        }
        self.energies_fresh = false;
    }

    /// Recomputes the cached outputs that are cheap and marks the energies stale (they cost a
    /// pass over all bonds: computed on demand). Fails, leaving the cache alone, if any value is
    /// not finite.
    pub(super) fn refresh_outputs(&mut self) -> FmiResult<()> {
        let Some(sim) = &self.sim else {
            return Ok(());
        };
        let new = self.cheap_outputs(sim)?;
        self.store_outputs(new);
        Ok(())
    }

    /// Brings the cached energies up to date; a non-finite energy is an error (never a stale
    /// or NaN value handed out with fmi2OK).
    pub(super) fn update_energies(&mut self) -> FmiResult<()> {
        if self.energies_fresh {
            return Ok(());
        }
        let Some(sim) = &self.sim else {
            return Ok(());
        };
        let (ke, se) = self
            .pool
            .install(|| (sim.kinetic_energy(), sim.strain_energy()));
        for (name, e) in [("kinetic_energy", ke), ("strain_energy", se)] {
            if !e.is_finite() {
                return Err(FmiError::Solver(format!(
                    "{name} is {e} at t = {}: the state is not valid (see the solver's earlier messages)",
                    num(self.time)
                )));
            }
        }
        for (v, o) in self.table.vars.iter().zip(self.outputs.iter_mut()) {
            match v.quantity {
                Quantity::KineticEnergy => *o = ke,
                Quantity::StrainEnergy => *o = se,
                _ => {}
            }
        }
        self.energies_fresh = true;
        Ok(())
    }

    /// fmi2EnterInitializationMode: builds the simulation.
    pub fn enter_initialization_mode(&mut self) -> FmiResult<()> {
        self.require("fmi2EnterInitializationMode", &[Mode::Instantiated])?;
        self.build()?;
        self.mode = Mode::InitializationMode;
        self.log.event("entered initialization mode");
        Ok(())
    }

    /// fmi2ExitInitializationMode: rebuilds if parameters changed during initialisation.
    pub fn exit_initialization_mode(&mut self) -> FmiResult<()> {
        self.require("fmi2ExitInitializationMode", &[Mode::InitializationMode])?;
        self.build()?;
        self.mode = Mode::StepComplete;
        self.log.event(&format!(
            "exited initialization mode: gravity from {}; boundary displacement inputs {}",
            match self.inputs.gravity_source {
                GravitySource::Scene => "the scene's law (gravity inputs ignored)",
                GravitySource::Inputs => "the inputs gravity_*",
            },
            match self.inputs.boundary_timing {
                BoundaryTiming::AtStepStart =>
                    "act at the start of each step (held or extrapolated)",
                BoundaryTiming::AtStepEnd => "are reached at the end of each step",
            }
        ));
        Ok(())
    }

    /// fmi2Terminate.
    pub fn terminate(&mut self) -> FmiResult<()> {
        self.require("fmi2Terminate", &[Mode::StepComplete])?;
        self.mode = Mode::Terminated;
        self.log.event(&format!("terminated at t = {}", self.time));
        Ok(())
    }

    /// fmi2Reset: back to the instantiated state with the scene's parameters and start values.
    /// The built model is kept: the next build rewinds it to its initial state if the
    /// parameters are those it was built with (`rewind_to_built`), and builds anew otherwise.
    pub fn reset(&mut self) -> FmiResult<()> {
        self.params = self.scene.clone();
        self.inputs = Inputs::start(&self.scene);
        self.stale = true;
        self.outputs = vec![0.0; self.table.vars.len()];
        self.energies_fresh = false;
        self.gravity_ignored_warned = false;
        self.start_time = 0.0;
        self.time = 0.0;
        self.last_successful_time = 0.0;
        self.stop_time = None;
        self.mode = Mode::Instantiated;
        self.log.event("reset");
        Ok(())
    }

    /// An unsupported function: logs why and fails.
    pub fn unsupported(function: &str, why: &str) -> FmiError {
        FmiError::Invalid(format!("{function} is not supported: {why}"))
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::small2d;
    use super::Instance;
    use crate::fmi::variables::{Causality, VarType};
    use crate::sim::Simulation;

    /// Where the built model's particle positions live: the same address means the same model.
    fn model_id(i: &Instance) -> usize {
        match i.sim.as_ref().expect("built") {
            Simulation::D2(m) => m.world.p.x.as_ptr() as usize,
            Simulation::D3(m) => m.world.p.x.as_ptr() as usize,
        }
    }

    /// Every Real output (energies too), as bits.
    fn outputs(i: &mut Instance) -> Vec<u64> {
        let vrs: Vec<u32> = i
            .table()
            .vars
            .iter()
            .filter(|v| v.causality == Causality::Output && v.ty == VarType::Real)
            .map(|v| v.value_reference)
            .collect();
        let mut out = vec![0.0; vrs.len()];
        i.get_real(&vrs, &mut out).unwrap();
        out.iter().map(|x| x.to_bits()).collect()
    }

    /// Initialises at t = 0 and takes the fixture's 3 steps; the log of the initialisation.
    fn run(i: &mut Instance) -> Vec<String> {
        i.setup_experiment(0.0, None).unwrap();
        i.enter_initialization_mode().unwrap();
        i.exit_initialization_mode().unwrap();
        let log = i.take_log().into_iter().map(|r| r.message).collect();
        for k in 0..3 {
            i.do_step(k as f64 * 0.002, 0.002).unwrap();
        }
        log
    }

    fn said(log: &[String], what: &str) -> bool {
        log.iter().any(|m| m.contains(what))
    }

    #[test]
    fn reset_rewinds_the_built_model_to_the_same_run() {
        // fmpy's loops over one instance (simulate_fmu with fmu_instance, then reset) paid the
        // whole set-up on every run. The same parameters now rewind the model built for them:
        // the same outputs, bit for bit, without a build.
        let mut i = small2d();
        let first = outputs(&mut i);
        let id = model_id(&i);
        i.set_debug_logging(true, &[]).unwrap();
        i.reset().unwrap();
        let log = run(&mut i);
        assert!(said(&log, "rewound the model built"), "{log:?}");
        assert!(!said(&log, "built the model:"), "{log:?}");
        assert_eq!(model_id(&i), id, "the model was built again");
        assert_eq!(outputs(&mut i), first);
    }

    #[test]
    fn other_parameters_after_reset_build_anew_and_the_first_come_back() {
        let mut i = small2d();
        let first = outputs(&mut i);
        i.set_debug_logging(true, &[]).unwrap();
        let young = i.table().by_name("strip.young").unwrap().value_reference;
        i.reset().unwrap();
        i.set_real(&[young], &[2.0e6]).unwrap();
        let log = run(&mut i);
        assert!(said(&log, "built the model:"), "{log:?}");
        let stiffer = outputs(&mut i);
        assert_ne!(stiffer, first, "a stiffer strip must move differently");
        // That build took the closure of the first (the parameters change no geometry), and
        // its model is the one a build from scratch gives, bit for bit.
        assert!(i.memo.holds_closure());
        let mut fresh = small2d();
        fresh.reset().unwrap();
        (fresh.sim, fresh.built, fresh.memo) = (None, None, Default::default());
        fresh.set_real(&[young], &[2.0e6]).unwrap();
        run(&mut fresh);
        assert!(fresh.memo.holds_closure());
        assert_eq!(outputs(&mut fresh), stiffer);
        // Back to the scene's parameters: built anew (the kept model is the stiffer one),
        // the first run's bits; then rewound.
        i.reset().unwrap();
        let log = run(&mut i);
        assert!(said(&log, "built the model:"), "{log:?}");
        assert_eq!(outputs(&mut i), first);
        i.reset().unwrap();
        i.set_real(&[young], &[2.0e6]).unwrap();
        i.set_real(&[young], &[1.0e6]).unwrap();
        let log = run(&mut i);
        assert!(said(&log, "rewound the model built"), "{log:?}");
        assert_eq!(outputs(&mut i), first);
    }

    #[test]
    fn a_state_of_the_kept_model_restores_without_a_build_after_reset() {
        let mut i = small2d();
        let state = i.get_fmu_state().unwrap();
        let at3 = outputs(&mut i);
        let id = model_id(&i);
        i.do_step(0.006, 0.002).unwrap();
        i.reset().unwrap();
        i.set_fmu_state(&state).unwrap();
        assert_eq!(model_id(&i), id, "the model was built again");
        assert_eq!(outputs(&mut i), at3);
        i.do_step(0.006, 0.002).unwrap();
        // And the run from there is the one a fresh instance takes.
        let mut fresh = small2d();
        fresh.do_step(0.006, 0.002).unwrap();
        assert_eq!(outputs(&mut i), outputs(&mut fresh));
    }
}

#[cfg(test)]
mod shipped_closure {
    use super::super::{Logger, Status, CLOSURE_FILE};
    use super::Instance;
    use crate::fmi::model_description::guid;
    use crate::physics::world::{SetupMemo, SetupObserver};
    use crate::scene::Scene;
    use std::path::Path;
    use std::sync::{Arc, Mutex};

    #[derive(Default)]
    struct Captured(Mutex<Vec<String>>);
    impl Logger for Captured {
        fn log(&self, _: Status, _: &str, message: &str) {
            self.0.lock().unwrap().push(message.to_string());
        }
    }

    struct Keep(SetupMemo);
    impl SetupObserver for Keep {
        fn memo(&self) -> Option<&SetupMemo> {
            Some(&self.0)
        }
    }

    /// tests/data/small3d.json in a resources directory of its own, with `closure` as the
    /// shipped closure file (None: no file); the instance's log and its tip's u_z after 5 steps.
    fn run(tag: &str, closure: Option<&[u8]>) -> (Vec<String>, u64) {
        let dir =
            std::env::temp_dir().join(format!("mps-shipped-closure-{}-{tag}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene =
            Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small3d.json"))
                .unwrap();
        std::fs::write(dir.join("scene.json"), scene.to_json()).unwrap();
        if let Some(b) = closure {
            std::fs::write(dir.join(CLOSURE_FILE), b).unwrap();
        }
        let log = Arc::new(Captured::default());
        let uri = format!("file://{}", dir.display());
        let mut i =
            Instance::instantiate("unit", true, &guid(&scene), Some(&uri), log.clone(), true)
                .unwrap();
        i.setup_experiment(0.0, None).unwrap();
        i.enter_initialization_mode().unwrap();
        i.exit_initialization_mode().unwrap();
        for k in 0..5 {
            i.do_step(k as f64 * 0.002, 0.002).unwrap();
        }
        i.flush_log();
        let uz = i.table().by_name("tip.uz").unwrap().value_reference;
        let mut out = [0.0];
        i.get_real(&[uz], &mut out).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        let messages = log.0.lock().unwrap().clone();
        (messages, out[0].to_bits())
    }

    #[test]
    fn the_closure_shipped_by_pack_spares_the_first_build_and_a_damaged_one_is_computed() {
        // `mps pack` builds the model once; the closure it computed (the longest stage of a
        // set-up, the same for every value of the FMU's parameters) is in the resources, and
        // an instance's first build takes it: the same model, bit for bit.
        let scene =
            Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small3d.json"))
                .unwrap();
        let keep = Keep(SetupMemo::default());
        crate::sim::Simulation::new_observed(&scene, &keep).unwrap();
        let bytes = keep.0.closure_bytes().expect("small3d has a closure");
        let said = |log: &[String], what: &str| log.iter().any(|m| m.contains(what));
        let (log, fresh) = run("none", None);
        assert!(!said(&log, "earlier set-up"), "{log:?}");
        let (log, shipped) = run("good", Some(&bytes));
        assert!(said(&log, "the resources hold the closure"), "{log:?}");
        assert!(
            said(&log, "as an earlier set-up of this geometry closed them"),
            "{log:?}"
        );
        assert_eq!(shipped, fresh);
        let mut damaged = bytes.clone();
        let at = damaged.len() / 2;
        damaged[at] ^= 0x40;
        let (log, computed) = run("damaged", Some(&damaged));
        assert!(said(&log, "checksum does not match"), "{log:?}");
        assert!(!said(&log, "earlier set-up"), "{log:?}");
        assert_eq!(computed, fresh);
    }
}
