//! The safe FMU instance under the C ABI: the call-order state machine, variable access through
//! the variable table, doStep sub-stepping, FMU state as data, and the instance's own worker
//! threads. Every error is an [`FmiError`], mapped to its FMI status in one place
//! ([`FmiError::status`]).
use super::model_description::{guid, LOG_CATEGORIES};
use super::variables::{Causality, Quantity, VarType, VariableTable};
use crate::scene::Scene;
use crate::sim::{SimState, Simulation};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// fmi2Status values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
    Pending = 5,
}

/// Why a call failed.
#[derive(Clone, Debug, PartialEq)]
pub enum FmiError {
    /// The call is not allowed in the instance's current state.
    IllegalCall(String),
    /// A bad argument: unknown value reference, wrong type, NaN, out of range, bad state data...
    Invalid(String),
    /// The solver failed (blow-up) or the model could not be built.
    Solver(String),
    /// A status that is not provided (fmi2Discard by the standard).
    NotProvided(String),
    /// The instance can no longer be used.
    Fatal(String),
}

impl FmiError {
    /// The FMI status of an error: the one place where errors become status codes.
    pub fn status(&self) -> Status {
        match self {
            FmiError::IllegalCall(_) | FmiError::Invalid(_) | FmiError::Solver(_) => Status::Error,
            FmiError::NotProvided(_) => Status::Discard,
            FmiError::Fatal(_) => Status::Fatal,
        }
    }
    pub fn message(&self) -> &str {
        match self {
            FmiError::IllegalCall(m)
            | FmiError::Invalid(m)
            | FmiError::Solver(m)
            | FmiError::NotProvided(m)
            | FmiError::Fatal(m) => m,
        }
    }
}

pub type FmiResult<T> = Result<T, FmiError>;

/// Where log messages go (the host's logger callback, behind the C layer).
pub trait Logger: Send + Sync {
    fn log(&self, status: Status, category: &str, message: &str);
}

/// A logger that drops everything.
pub struct NoLogger;
impl Logger for NoLogger {
    fn log(&self, _: Status, _: &str, _: &str) {}
}

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

/// fmi2StatusKind values.
pub const DO_STEP_STATUS: i32 = 0;
pub const PENDING_STATUS: i32 = 1;
pub const LAST_SUCCESSFUL_TIME: i32 = 2;
pub const TERMINATED: i32 = 3;

/// Values of the inputs as the host set them (start values until then).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Inputs {
    gravity: [f64; 3],
    /// Whether the host replaced the scene's gravity law by a constant vector.
    gravity_set: bool,
    displacement: Vec<[f64; 3]>,
    load: Vec<[f64; 3]>,
}

impl Inputs {
    fn start(scene: &Scene) -> Self {
        let mut gravity = [0.0; 3];
        for (k, g) in scene.gravity.vector.iter().take(3).enumerate() {
            gravity[k] = *g;
        }
        Inputs {
            gravity,
            gravity_set: false,
            displacement: vec![[0.0; 3]; scene.boundaries.len()],
            load: vec![[0.0; 3]; scene.loads.len()],
        }
    }
}

/// The complete state of an instance as plain data (`fmi2GetFMUstate`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FmuState {
    /// The scene with the parameter values in force.
    params: Scene,
    inputs: Inputs,
    time: f64,
    last_successful_time: f64,
    stop_time: Option<f64>,
    sim: SimState,
}

/// Magic and version of serialised FMU states.
const STATE_MAGIC: &[u8; 8] = b"MPSFMUST";
const STATE_VERSION: u32 = 1;

/// A rayon pool whose threads are std threads this instance owns and joins when dropped, so
/// that none outlives `fmi2FreeInstance` (hosts unload the library right after).
#[cfg(feature = "parallel")]
pub struct WorkerPool {
    pool: Option<rayon::ThreadPool>,
    handles: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>>,
}

#[cfg(feature = "parallel")]
impl WorkerPool {
    /// Threads: `MPS_FMI_THREADS` if set, else the available parallelism. The threads are
    /// spawned from a short-lived thread of the library's own, never from the host's thread:
    /// spawning registers a TLS destructor on the spawning thread that would keep the library
    /// from unloading (see [`super::ffi::run_on_os_thread`]).
    pub fn new(name: &str) -> Result<Self, String> {
        super::ffi::run_on_os_thread(|| Self::spawn(name))?
    }

    fn spawn(name: &str) -> Result<Self, String> {
        let n = std::env::var("MPS_FMI_THREADS")
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
            .filter(|&n| n > 0)
            .unwrap_or_else(|| {
                std::thread::available_parallelism()
                    .map(|n| n.get())
                    .unwrap_or(1)
            });
        let handles: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>> = Arc::default();
        let h = handles.clone();
        let prefix: String = format!("fmu-{}", name.chars().take(8).collect::<String>());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .spawn_handler(move |thread| {
                let idx = thread.index();
                let handle = std::thread::Builder::new()
                    .name(format!("{prefix}-{idx}"))
                    .spawn(move || thread.run())?;
                h.lock().unwrap_or_else(|e| e.into_inner()).push(handle);
                Ok(())
            })
            .build()
            .map_err(|e| format!("cannot start worker threads: {e}"))?;
        Ok(WorkerPool {
            pool: Some(pool),
            handles,
        })
    }
    /// Runs f on the pool (rayon work inside f uses this pool's threads).
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(p) => p.install(f),
            None => f(),
        }
    }
}

#[cfg(feature = "parallel")]
impl Drop for WorkerPool {
    fn drop(&mut self) {
        drop(self.pool.take());
        let handles: Vec<_> = self
            .handles
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .drain(..)
            .collect();
        for h in handles {
            let _ = h.join();
        }
    }
}

/// Without the `parallel` feature there are no worker threads.
#[cfg(not(feature = "parallel"))]
pub struct WorkerPool;

#[cfg(not(feature = "parallel"))]
impl WorkerPool {
    pub fn new(_name: &str) -> Result<Self, String> {
        Ok(WorkerPool)
    }
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        f()
    }
}

/// Turns an `fmuResourceLocation` URI into a directory: `file:///abs/path`, `file:/abs/path`
/// and `file://localhost/abs/path`, percent-encoded or not, with or without a trailing '/'.
pub fn resource_dir(uri: &str) -> Result<PathBuf, String> {
    let rest = uri
        .strip_prefix("file://localhost/")
        .map(|r| format!("/{r}"))
        .or_else(|| uri.strip_prefix("file:///").map(|r| format!("/{r}")))
        .or_else(|| {
            uri.strip_prefix("file:/")
                .filter(|r| !r.starts_with('/'))
                .map(|r| format!("/{r}"))
        })
        .ok_or_else(|| {
            format!("fmuResourceLocation '{uri}' is not a local file URI (file:///path)")
        })?;
    let bytes = rest.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("fmuResourceLocation '{uri}' has a bad percent escape"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    let s = String::from_utf8(out)
        .map_err(|_| format!("fmuResourceLocation '{uri}' is not UTF-8 once decoded"))?;
    Ok(PathBuf::from(s))
}

/// Reads and checks the scene of an FMU's resources directory.
pub fn load_scene(dir: &Path) -> Result<Scene, String> {
    let path = dir.join("scene.json");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| format!("cannot read the FMU's scene {}: {e}", path.display()))?;
    Scene::from_json(&text)
        .map_err(|e| format!("the FMU's scene {} is invalid: {e}", path.display()))
}

/// One FMU instance.
pub struct Instance {
    name: String,
    /// The scene the FMU was packed with.
    scene: Scene,
    /// The scene with the parameter values set by the host.
    params: Scene,
    table: VariableTable,
    sim: Option<Simulation>,
    /// Parameters changed since the simulation was built.
    stale: bool,
    pool: WorkerPool,
    mode: Mode,
    inputs: Inputs,
    time: f64,
    last_successful_time: f64,
    stop_time: Option<f64>,
    /// Output values at `time` (index = value reference), from the last successful step.
    outputs: Vec<f64>,
    /// Whether the energies in `outputs` are those of the current state.
    energies_fresh: bool,
    logger: Arc<dyn Logger>,
    logging_on: bool,
    categories: [bool; LOG_CATEGORIES.len()],
}

/// Relative tolerance of time comparisons.
fn time_tol(t: f64) -> f64 {
    1e-9 * t.abs().max(1.0)
}

impl Instance {
    /// fmi2Instantiate: checks the type, reads the scene from the resources and the GUID.
    pub fn instantiate(
        name: &str,
        co_simulation: bool,
        fmu_guid: &str,
        resource_location: Option<&str>,
        logger: Arc<dyn Logger>,
        logging_on: bool,
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
        let expected = guid(&scene);
        if fmu_guid != expected {
            return Err(format!(
                "GUID mismatch: the host passed {fmu_guid} but this FMU (scene '{}', mps-solid {}) has {expected}",
                scene.name,
                env!("CARGO_PKG_VERSION")
            ));
        }
        let pool = WorkerPool::new(name)?;
        let table = VariableTable::new(&scene);
        let inst = Instance {
            name: name.to_string(),
            params: scene.clone(),
            inputs: Inputs::start(&scene),
            outputs: vec![0.0; table.vars.len()],
            energies_fresh: false,
            scene,
            table,
            sim: None,
            stale: true,
            pool,
            mode: Mode::Instantiated,
            time: 0.0,
            last_successful_time: 0.0,
            stop_time: None,
            logger,
            logging_on,
            categories: [true; LOG_CATEGORIES.len()],
        };
        inst.event(&format!(
            "instantiated '{}' (scene '{}', {} variables)",
            inst.name,
            inst.scene.name,
            inst.table.vars.len()
        ));
        Ok(inst)
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }
    pub fn time(&self) -> f64 {
        self.time
    }
    pub fn table(&self) -> &VariableTable {
        &self.table
    }

    fn category_on(&self, name: &str) -> bool {
        LOG_CATEGORIES
            .iter()
            .position(|(c, _)| *c == name)
            .is_some_and(|i| self.categories[i])
    }

    /// Logs an event (category logEvents) when debug logging is on.
    fn event(&self, msg: &str) {
        if self.logging_on && (self.category_on("logEvents") || self.category_on("logAll")) {
            self.logger.log(Status::Ok, "logEvents", msg);
        }
    }

    fn trace(&self, msg: &str) {
        if self.logging_on && self.category_on("logAll") {
            self.logger.log(Status::Ok, "logAll", msg);
        }
    }

    /// Logs an error of a call (always: errors are not debug messages).
    pub fn report(&self, function: &str, e: &FmiError) {
        let category = match e.status() {
            Status::Warning | Status::Discard => "logStatusWarning",
            _ => "logStatusError",
        };
        self.logger.log(
            e.status(),
            category,
            &format!("{function}: {}", e.message()),
        );
    }

    fn require(&self, function: &str, allowed: &[Mode]) -> FmiResult<()> {
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

    /// fmi2SetDebugLogging.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[String]) -> FmiResult<()> {
        let mut enabled = [categories.is_empty(); LOG_CATEGORIES.len()];
        for c in categories {
            let i = LOG_CATEGORIES
                .iter()
                .position(|(n, _)| n == c)
                .ok_or_else(|| {
                    FmiError::Invalid(format!(
                        "unknown log category '{c}' (known: {})",
                        LOG_CATEGORIES.map(|(n, _)| n).join(", ")
                    ))
                })?;
            enabled[i] = true;
        }
        self.logging_on = on;
        self.categories = enabled;
        Ok(())
    }

    /// fmi2SetupExperiment: the tolerance is ignored (the solver's step is set by stability).
    pub fn setup_experiment(&mut self, start: f64, stop: Option<f64>) -> FmiResult<()> {
        self.require("fmi2SetupExperiment", &[Mode::Instantiated])?;
        if !(start.is_finite() && start.abs() <= time_tol(0.0)) {
            return Err(FmiError::Invalid(format!(
                "startTime = {start}: the scene starts at t = 0 (restore an FMU state to start elsewhere)"
            )));
        }
        if let Some(s) = stop {
            if !(s.is_finite() && s > start) {
                return Err(FmiError::Invalid(format!(
                    "stopTime = {s} must be finite and after startTime = {start}"
                )));
            }
        }
        self.stop_time = stop;
        self.time = 0.0;
        self.last_successful_time = 0.0;
        Ok(())
    }

    /// Builds (or rebuilds after parameter changes) the simulation on the instance's threads
    /// and applies the inputs set so far.
    fn build(&mut self) -> FmiResult<()> {
        if !self.stale && self.sim.is_some() {
            return Ok(());
        }
        let params = &self.params;
        let mut sim = self
            .pool
            .install(|| Simulation::new(params))
            .map_err(|e| FmiError::Solver(format!("cannot build the model: {e}")))?;
        if self.inputs.gravity_set {
            sim.set_gravity(self.inputs.gravity);
        }
        for (g, d) in self.inputs.displacement.iter().enumerate() {
            sim.set_group_displacement(g, *d);
        }
        for (r, f) in self.inputs.load.iter().enumerate() {
            sim.set_load(r, *f);
        }
        self.event(&format!(
            "built the model: {} particles, {} bonds, solver step {:.4e} s",
            sim.particles(),
            sim.bonds(),
            sim.max_dt()
        ));
        self.sim = Some(sim);
        self.stale = false;
        self.refresh_outputs()
    }

    /// Recomputes the cached outputs that are cheap (probes, reactions, counters) and marks
    /// the energies stale (they cost a pass over all bonds: computed on demand). Fails, leaving
    /// the cache alone, if any value is not finite.
    fn refresh_outputs(&mut self) -> FmiResult<()> {
        let Some(sim) = &self.sim else {
            return Ok(());
        };
        let table = &self.table;
        let new: Vec<Option<f64>> = self.pool.install(|| {
            table
                .vars
                .iter()
                .map(|v| match v.quantity {
                    Quantity::ProbeDisplacement(p, k) => Some(sim.probe_displacement(p)[k]),
                    Quantity::Reaction(g, k) => Some(sim.group_reaction(g)[k]),
                    Quantity::FractureCount => Some(sim.broken_bonds() as f64),
                    Quantity::Steps => Some(sim.steps() as f64),
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
                sim.time()
            )));
        }
        for (o, n) in self.outputs.iter_mut().zip(new) {
            if let Some(n) = n {
                *o = n;
            }
        }
        self.energies_fresh = false;
        Ok(())
    }

    /// Brings the cached energies up to date. After a failed step they describe the state the
    /// solver stopped in if finite, else they keep the last finite values.
    fn update_energies(&mut self) {
        if self.energies_fresh {
            return;
        }
        let Some(sim) = &self.sim else {
            return;
        };
        let (ke, se) = self
            .pool
            .install(|| (sim.kinetic_energy(), sim.strain_energy()));
        for (v, o) in self.table.vars.iter().zip(self.outputs.iter_mut()) {
            match v.quantity {
                Quantity::KineticEnergy if ke.is_finite() => *o = ke,
                Quantity::StrainEnergy if se.is_finite() => *o = se,
                _ => {}
            }
        }
        self.energies_fresh = true;
    }

    /// fmi2EnterInitializationMode: builds the simulation.
    pub fn enter_initialization_mode(&mut self) -> FmiResult<()> {
        self.require("fmi2EnterInitializationMode", &[Mode::Instantiated])?;
        self.build()?;
        self.mode = Mode::InitializationMode;
        self.event("entered initialization mode");
        Ok(())
    }

    /// fmi2ExitInitializationMode: rebuilds if parameters changed during initialisation.
    pub fn exit_initialization_mode(&mut self) -> FmiResult<()> {
        self.require("fmi2ExitInitializationMode", &[Mode::InitializationMode])?;
        self.build()?;
        self.mode = Mode::StepComplete;
        self.event("exited initialization mode");
        Ok(())
    }

    /// fmi2Terminate.
    pub fn terminate(&mut self) -> FmiResult<()> {
        self.require("fmi2Terminate", &[Mode::StepComplete])?;
        self.mode = Mode::Terminated;
        self.event(&format!("terminated at t = {}", self.time));
        Ok(())
    }

    /// fmi2Reset: back to the instantiated state with the scene's parameters and start values.
    pub fn reset(&mut self) -> FmiResult<()> {
        self.params = self.scene.clone();
        self.inputs = Inputs::start(&self.scene);
        self.sim = None;
        self.stale = true;
        self.outputs = vec![0.0; self.table.vars.len()];
        self.energies_fresh = false;
        self.time = 0.0;
        self.last_successful_time = 0.0;
        self.stop_time = None;
        self.mode = Mode::Instantiated;
        self.event("reset");
        Ok(())
    }

    fn var(&self, vr: u32, ty: VarType) -> FmiResult<&super::variables::Variable> {
        let v = self.table.get(vr).ok_or_else(|| {
            FmiError::Invalid(format!(
                "unknown value reference {vr} (this FMU has {} variables, 0..{})",
                self.table.vars.len(),
                self.table.vars.len().saturating_sub(1)
            ))
        })?;
        if v.ty != ty {
            return Err(FmiError::Invalid(format!(
                "value reference {vr} ('{}') is a {} variable, not {}",
                v.name,
                v.ty.name(),
                ty.name()
            )));
        }
        Ok(v)
    }

    const GET_MODES: [Mode; 4] = [
        Mode::InitializationMode,
        Mode::StepComplete,
        Mode::Error,
        Mode::Terminated,
    ];

    fn value(&self, vr: u32, ty: VarType) -> FmiResult<f64> {
        let v = self.var(vr, ty)?;
        Ok(match v.quantity {
            q @ (Quantity::Density(_)
            | Quantity::Young(_)
            | Quantity::Poisson(_)
            | Quantity::SolverDt
            | Quantity::Damping
            | Quantity::FractureStrain) => {
                VariableTable::parameter_value(&self.params, q).unwrap_or(0.0)
            }
            Quantity::Gravity(k) => self.inputs.gravity[k],
            Quantity::GroupDisplacement(g, k) => self.inputs.displacement[g][k],
            Quantity::Load(r, k) => self.inputs.load[r][k],
            _ => self.outputs[vr as usize],
        })
    }

    fn prepare_get(&mut self, function: &str) -> FmiResult<()> {
        self.require(function, &Self::GET_MODES)?;
        if self.mode == Mode::InitializationMode && self.stale {
            self.build()?;
        }
        Ok(())
    }

    /// fmi2GetReal.
    pub fn get_real(&mut self, vr: &[u32], out: &mut [f64]) -> FmiResult<()> {
        self.prepare_get("fmi2GetReal")?;
        if vr.iter().any(|&r| {
            self.table.get(r).is_some_and(|v| {
                matches!(v.quantity, Quantity::KineticEnergy | Quantity::StrainEnergy)
            })
        }) {
            self.update_energies();
        }
        for (r, o) in vr.iter().zip(out.iter_mut()) {
            *o = self.value(*r, VarType::Real)?;
        }
        Ok(())
    }

    /// fmi2GetInteger.
    pub fn get_integer(&mut self, vr: &[u32], out: &mut [i32]) -> FmiResult<()> {
        self.prepare_get("fmi2GetInteger")?;
        for (r, o) in vr.iter().zip(out.iter_mut()) {
            *o = self.value(*r, VarType::Integer)?.min(i32::MAX as f64) as i32;
        }
        Ok(())
    }

    /// fmi2GetBoolean / fmi2GetString: this FMU has no such variables.
    pub fn get_none(&mut self, function: &str, kind: &str, vr: &[u32]) -> FmiResult<()> {
        self.require(function, &Self::GET_MODES)?;
        match vr.first() {
            None => Ok(()),
            Some(r) => Err(FmiError::Invalid(format!(
                "unknown value reference {r}: this FMU has no {kind} variables"
            ))),
        }
    }

    const SET_MODES: [Mode; 3] = [
        Mode::Instantiated,
        Mode::InitializationMode,
        Mode::StepComplete,
    ];

    /// fmi2SetReal: checks every value first and applies none if one is bad.
    pub fn set_real(&mut self, vr: &[u32], values: &[f64]) -> FmiResult<()> {
        self.require("fmi2SetReal", &Self::SET_MODES)?;
        for (&r, &x) in vr.iter().zip(values) {
            let v = self.var(r, VarType::Real)?;
            match v.causality {
                Causality::Output => {
                    return Err(FmiError::Invalid(format!(
                        "'{}' (value reference {r}) is an output and cannot be set",
                        v.name
                    )))
                }
                Causality::Parameter if self.mode == Mode::StepComplete => {
                    return Err(FmiError::Invalid(format!(
                        "'{}' (value reference {r}) is a fixed parameter: it can be set only before \
                         fmi2ExitInitializationMode",
                        v.name
                    )))
                }
                _ => {}
            }
            if !x.is_finite() {
                return Err(FmiError::Invalid(format!(
                    "'{}' (value reference {r}) cannot be set to {x}: values must be finite (nothing was set)",
                    v.name
                )));
            }
            if v.causality == Causality::Parameter {
                let mut probe = self.params.clone();
                VariableTable::set_parameter(&mut probe, v.quantity, x).map_err(|m| {
                    FmiError::Invalid(format!(
                        "'{}' cannot be set to {x}: {m} (nothing was set)",
                        v.name
                    ))
                })?;
            }
        }
        let mut gravity_changed = false;
        for (&r, &x) in vr.iter().zip(values) {
            let q = self.table.vars[r as usize].quantity;
            match q {
                Quantity::Gravity(k) => {
                    if self.inputs.gravity[k].to_bits() != x.to_bits() {
                        self.inputs.gravity[k] = x;
                        gravity_changed = true;
                    }
                }
                Quantity::GroupDisplacement(g, k) => {
                    self.inputs.displacement[g][k] = x;
                    let d = self.inputs.displacement[g];
                    if let Some(sim) = &mut self.sim {
                        sim.set_group_displacement(g, d);
                    }
                }
                Quantity::Load(l, k) => {
                    self.inputs.load[l][k] = x;
                    let f = self.inputs.load[l];
                    if let Some(sim) = &mut self.sim {
                        sim.set_load(l, f);
                    }
                }
                _ => {
                    VariableTable::set_parameter(&mut self.params, q, x)
                        .map_err(FmiError::Invalid)?;
                    self.stale = true;
                }
            }
        }
        if gravity_changed {
            if !self.inputs.gravity_set {
                self.event("gravity set by the host: the scene's gravity law is replaced by a constant vector");
            }
            self.inputs.gravity_set = true;
            let g = self.inputs.gravity;
            if let Some(sim) = &mut self.sim {
                sim.set_gravity(g);
            }
        }
        Ok(())
    }

    /// fmi2SetInteger: the only Integer variables are outputs.
    pub fn set_integer(&mut self, vr: &[u32]) -> FmiResult<()> {
        self.require("fmi2SetInteger", &Self::SET_MODES)?;
        if let Some(&r) = vr.first() {
            let v = self.var(r, VarType::Integer)?;
            return Err(FmiError::Invalid(format!(
                "'{}' (value reference {r}) is an output and cannot be set",
                v.name
            )));
        }
        Ok(())
    }

    /// fmi2SetBoolean / fmi2SetString: this FMU has no such variables.
    pub fn set_none(&mut self, function: &str, kind: &str, vr: &[u32]) -> FmiResult<()> {
        self.require(function, &Self::SET_MODES)?;
        match vr.first() {
            None => Ok(()),
            Some(r) => Err(FmiError::Invalid(format!(
                "unknown value reference {r}: this FMU has no {kind} variables"
            ))),
        }
    }

    /// fmi2DoStep: advances from t to exactly t + h with the solver's stable sub-steps.
    pub fn do_step(&mut self, t: f64, h: f64) -> FmiResult<()> {
        self.require("fmi2DoStep", &[Mode::StepComplete])?;
        if !(h.is_finite() && h > 0.0) {
            return Err(FmiError::Invalid(format!(
                "communicationStepSize = {h} must be positive and finite"
            )));
        }
        if !(t.is_finite() && (t - self.time).abs() <= time_tol(t)) {
            return Err(FmiError::Invalid(format!(
                "currentCommunicationPoint = {t} but the last step ended at {}",
                self.time
            )));
        }
        let t_end = t + h;
        if let Some(stop) = self.stop_time {
            if t_end > stop + time_tol(stop) {
                return Err(FmiError::Invalid(format!(
                    "the step would end at {t_end}, after stopTime = {stop}"
                )));
            }
        }
        let sim = self
            .sim
            .as_mut()
            .ok_or_else(|| FmiError::Fatal("no model built".into()))?;
        let res = self.pool.install(|| sim.advance_to(t_end));
        let res = match res {
            Ok(n) => self.refresh_outputs().map(|_| n),
            Err(e) => Err(FmiError::Solver(format!(
                "step from t = {t} to {t_end} failed: {e}"
            ))),
        };
        match res {
            Ok(n) => {
                self.time = t_end;
                self.last_successful_time = t_end;
                self.trace(&format!("doStep t = {t}, h = {h}: {n} solver steps"));
                Ok(())
            }
            Err(e) => {
                self.mode = Mode::Error;
                Err(e)
            }
        }
    }

    /// fmi2CancelStep: doStep is synchronous.
    pub fn cancel_step(&mut self) -> FmiResult<()> {
        Err(FmiError::Invalid(
            "fmi2CancelStep is not supported: fmi2DoStep is synchronous and never returns fmi2Pending".into(),
        ))
    }

    const STATUS_MODES: [Mode; 3] = [Mode::StepComplete, Mode::Error, Mode::Terminated];

    /// fmi2GetStatus: only meaningful after fmi2Pending, which this FMU never returns.
    pub fn get_status(&self, kind: i32) -> FmiResult<Status> {
        self.require("fmi2GetStatus", &Self::STATUS_MODES)?;
        Err(FmiError::NotProvided(format!(
            "status kind {kind} is not provided: fmi2DoStep is synchronous and never returns fmi2Pending"
        )))
    }

    /// fmi2GetRealStatus: fmi2LastSuccessfulTime.
    pub fn get_real_status(&self, kind: i32) -> FmiResult<f64> {
        self.require("fmi2GetRealStatus", &Self::STATUS_MODES)?;
        if kind == LAST_SUCCESSFUL_TIME {
            Ok(self.last_successful_time)
        } else {
            Err(FmiError::NotProvided(format!(
                "status kind {kind} is not provided as a Real (only fmi2LastSuccessfulTime)"
            )))
        }
    }

    /// fmi2GetIntegerStatus: no Integer status is defined by FMI 2.0.
    pub fn get_integer_status(&self, kind: i32) -> FmiResult<i32> {
        self.require("fmi2GetIntegerStatus", &Self::STATUS_MODES)?;
        Err(FmiError::NotProvided(format!(
            "status kind {kind} is not provided as an Integer"
        )))
    }

    /// fmi2GetBooleanStatus: fmi2Terminated (this FMU never asks to stop: false).
    pub fn get_boolean_status(&self, kind: i32) -> FmiResult<bool> {
        self.require("fmi2GetBooleanStatus", &Self::STATUS_MODES)?;
        if kind == TERMINATED {
            Ok(false)
        } else {
            Err(FmiError::NotProvided(format!(
                "status kind {kind} is not provided as a Boolean (only fmi2Terminated)"
            )))
        }
    }

    /// fmi2GetStringStatus: fmi2PendingStatus is only meaningful after fmi2Pending.
    pub fn get_string_status(&self, kind: i32) -> FmiResult<&'static str> {
        self.require("fmi2GetStringStatus", &Self::STATUS_MODES)?;
        Err(FmiError::NotProvided(format!(
            "status kind {kind} is not provided: no asynchronous step is ever pending"
        )))
    }

    const STATE_MODES: [Mode; 4] = [
        Mode::InitializationMode,
        Mode::StepComplete,
        Mode::Error,
        Mode::Terminated,
    ];

    /// fmi2GetFMUstate.
    pub fn get_fmu_state(&mut self) -> FmiResult<FmuState> {
        self.require("fmi2GetFMUstate", &Self::STATE_MODES)?;
        if self.stale {
            self.build()?;
        }
        let sim = self
            .sim
            .as_ref()
            .ok_or_else(|| FmiError::Fatal("no model built".into()))?;
        let s = FmuState {
            params: self.params.clone(),
            inputs: self.inputs.clone(),
            time: self.time,
            last_successful_time: self.last_successful_time,
            stop_time: self.stop_time,
            sim: sim.state(),
        };
        self.event(&format!("FMU state captured at t = {}", self.time));
        Ok(s)
    }

    /// fmi2SetFMUstate: rebuilds the model if the state's parameters differ; after an error
    /// or termination the instance continues in StepComplete.
    pub fn set_fmu_state(&mut self, s: &FmuState) -> FmiResult<()> {
        self.require("fmi2SetFMUstate", &Self::STATE_MODES)?;
        if s.inputs.displacement.len() != self.scene.boundaries.len()
            || s.inputs.load.len() != self.scene.loads.len()
        {
            return Err(FmiError::Invalid(
                "the FMU state belongs to another scene".into(),
            ));
        }
        if s.params != self.params || self.sim.is_none() || self.stale {
            let mut p = s.params.clone();
            std::mem::swap(&mut p, &mut self.params);
            self.stale = true;
            if let Err(e) = self.build() {
                self.params = p;
                self.stale = true;
                return Err(e);
            }
        }
        let sim = self
            .sim
            .as_mut()
            .ok_or_else(|| FmiError::Fatal("no model built".into()))?;
        sim.set_state(&s.sim)
            .map_err(|e| FmiError::Invalid(format!("cannot restore the FMU state: {e}")))?;
        self.inputs = s.inputs.clone();
        self.time = s.time;
        self.last_successful_time = s.last_successful_time;
        self.stop_time = s.stop_time;
        self.refresh_outputs()?;
        if self.mode != Mode::InitializationMode {
            self.mode = Mode::StepComplete;
        }
        self.event(&format!("FMU state restored at t = {}", self.time));
        Ok(())
    }

    /// Checks a state may be freed (any state but fatal ones; the C layer frees it).
    pub fn free_fmu_state(&self) -> FmiResult<()> {
        Ok(())
    }

    /// fmi2SerializeFMUstate: magic, format version, the GUID, then bincode of the state.
    pub fn serialize_fmu_state(&self, s: &FmuState) -> FmiResult<Vec<u8>> {
        let guid = guid(&self.scene);
        let mut out = Vec::new();
        out.extend_from_slice(STATE_MAGIC);
        out.extend_from_slice(&STATE_VERSION.to_le_bytes());
        out.extend_from_slice(&(guid.len() as u32).to_le_bytes());
        out.extend_from_slice(guid.as_bytes());
        bincode::serialize_into(&mut out, s)
            .map_err(|e| FmiError::Invalid(format!("cannot serialise the FMU state: {e}")))?;
        Ok(out)
    }

    /// fmi2DeSerializeFMUstate: checks magic, version and GUID.
    pub fn deserialize_fmu_state(&self, bytes: &[u8]) -> FmiResult<FmuState> {
        let bad = |m: &str| FmiError::Invalid(format!("not a serialised state of this FMU: {m}"));
        if bytes.len() < 16 || &bytes[..8] != STATE_MAGIC {
            return Err(bad("bad magic"));
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
        if version != STATE_VERSION {
            return Err(bad(&format!(
                "format version {version}, expected {STATE_VERSION}"
            )));
        }
        let n = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
        let g = bytes.get(16..16 + n).ok_or_else(|| bad("truncated"))?;
        if g != guid(&self.scene).as_bytes() {
            return Err(bad("it was made by an FMU with another GUID"));
        }
        let s: FmuState = bincode::deserialize(&bytes[16 + n..])
            .map_err(|e| bad(&format!("cannot decode: {e}")))?;
        if s.inputs.displacement.len() != self.scene.boundaries.len()
            || s.inputs.load.len() != self.scene.loads.len()
        {
            return Err(bad("it belongs to another scene"));
        }
        Ok(s)
    }

    /// An unsupported function: logs why and fails.
    pub fn unsupported(function: &str, why: &str) -> FmiError {
        FmiError::Invalid(format!("{function} is not supported: {why}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resource_uris() {
        assert_eq!(
            resource_dir("file:///tmp/a%20b/").unwrap(),
            PathBuf::from("/tmp/a b/")
        );
        assert_eq!(
            resource_dir("file:/tmp/x").unwrap(),
            PathBuf::from("/tmp/x")
        );
        assert_eq!(
            resource_dir("file://localhost/tmp/x").unwrap(),
            PathBuf::from("/tmp/x")
        );
        assert!(resource_dir("http://example/x").is_err());
        assert!(resource_dir("/tmp/x").is_err());
        assert!(resource_dir("file:///tmp/%zz").is_err());
    }

    #[test]
    fn error_statuses() {
        assert_eq!(FmiError::IllegalCall("x".into()).status(), Status::Error);
        assert_eq!(FmiError::NotProvided("x".into()).status(), Status::Discard);
        assert_eq!(FmiError::Fatal("x".into()).status(), Status::Fatal);
    }
}
