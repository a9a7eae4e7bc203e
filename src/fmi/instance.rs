//! The safe FMU instance under the C ABI: the call-order state machine, variable access through
//! the variable table, doStep sub-stepping, FMU state as data, and the instance's own worker
//! threads. Every error is an [`FmiError`], mapped to its FMI status in one place
//! ([`FmiError::status`]).
use super::model_description::{guid, LOG_CATEGORIES};
use super::variables::{Causality, Quantity, VarType, VariableTable};
use crate::scene::limits::num;
use crate::scene::Scene;
use crate::sim::{SimState, Simulation};
use serde::{Deserialize, Serialize};
use std::cell::{Cell, RefCell};
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
    /// The solver failed (blow-up, material collapse, overlap) or the model could not be built.
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

/// Where the gravity vector comes from (Integer parameter `gravity_source`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum GravitySource {
    /// The scene's gravity law (constant, or the Eq. (46) ramp); the gravity inputs are ignored.
    Scene = 1,
    /// The inputs gravity_x/y/z, held over each step (or linear with input derivatives).
    Inputs = 2,
}

impl GravitySource {
    /// The default of a scene: its own law when it has a time law (the ramp), else the inputs
    /// (whose start values are the scene's constant vector, so both agree until a host sets them).
    pub fn default_for(scene: &Scene) -> Self {
        if scene.gravity.paper_ramp_period.is_some() {
            GravitySource::Scene
        } else {
            GravitySource::Inputs
        }
    }
    pub fn from_int(v: i32) -> Option<Self> {
        match v {
            1 => Some(GravitySource::Scene),
            2 => Some(GravitySource::Inputs),
            _ => None,
        }
    }
}

/// When a boundary displacement input takes effect (Integer parameter `boundary_input_timing`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum BoundaryTiming {
    /// FMI 2.0 semantics, what generic masters (fmpy, fmusim, libcosim) expect: the value set
    /// before doStep(t, h) is the displacement at t, held over the step, or extrapolated linearly
    /// with the derivative of fmi2SetRealInputDerivatives.
    AtStepStart = 1,
    /// The value set before doStep(t, h) is reached at t + h, moving linearly from where the
    /// group is: a smooth motion that lags the master's signal by one communication step.
    AtStepEnd = 2,
}

impl BoundaryTiming {
    pub fn from_int(v: i32) -> Option<Self> {
        match v {
            1 => Some(BoundaryTiming::AtStepStart),
            2 => Some(BoundaryTiming::AtStepEnd),
            _ => None,
        }
    }
}

/// Values of the inputs as the host set them (start values until then), their first
/// derivatives for the next step, and the FMU-level settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Inputs {
    gravity: [f64; 3],
    displacement: Vec<[f64; 3]>,
    load: Vec<[f64; 3]>,
    /// d/dt of the inputs, set by fmi2SetRealInputDerivatives for the next doStep only.
    gravity_rate: [f64; 3],
    displacement_rate: Vec<[f64; 3]>,
    load_rate: Vec<[f64; 3]>,
    gravity_source: GravitySource,
    boundary_timing: BoundaryTiming,
}

impl Inputs {
    fn start(scene: &Scene) -> Self {
        let mut gravity = [0.0; 3];
        for (k, g) in scene.gravity.vector.iter().take(3).enumerate() {
            gravity[k] = *g;
        }
        Inputs {
            gravity,
            displacement: vec![[0.0; 3]; scene.boundaries.len()],
            load: vec![[0.0; 3]; scene.loads.len()],
            gravity_rate: [0.0; 3],
            displacement_rate: vec![[0.0; 3]; scene.boundaries.len()],
            load_rate: vec![[0.0; 3]; scene.loads.len()],
            gravity_source: GravitySource::default_for(scene),
            boundary_timing: BoundaryTiming::AtStepStart,
        }
    }
    fn clear_rates(&mut self) {
        self.gravity_rate = [0.0; 3];
        self.displacement_rate
            .iter_mut()
            .for_each(|r| *r = [0.0; 3]);
        self.load_rate.iter_mut().for_each(|r| *r = [0.0; 3]);
    }
    fn fits(&self, scene: &Scene) -> bool {
        self.displacement.len() == scene.boundaries.len()
            && self.displacement_rate.len() == scene.boundaries.len()
            && self.load.len() == scene.loads.len()
            && self.load_rate.len() == scene.loads.len()
    }
}

/// The complete state of an instance as plain data (`fmi2GetFMUstate`), bound to its FMU by
/// the GUID (a hash of the scene and the library version) and the particle count.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FmuState {
    /// GUID of the FMU that made the state.
    guid: String,
    /// Particles of the model when the state was taken.
    particles: u64,
    /// Whether the state was taken after fmi2EnterInitializationMode (else in Instantiated).
    initialized: bool,
    /// The scene with the parameter values in force.
    params: Scene,
    inputs: Inputs,
    start_time: f64,
    time: f64,
    last_successful_time: f64,
    stop_time: Option<f64>,
    sim: SimState,
}

/// Magic and version of serialised FMU states. Version 3: a body's initial velocity is a
/// tagged enum (uniform or field) in the state's scene. Version 4: a body's material carries
/// its strain energy law (`material.law`) and a boundary its mirror face (`mirror`, null when
/// absent) in the state's scene. Version 5: the world's state carries the retained energy
/// shares of particles whose re-fit at a break was limited and the energy released by breaks.
const STATE_MAGIC: &[u8; 8] = b"MPSFMUST";
const STATE_VERSION: u32 = 5;
/// Largest serialised state accepted (bytes): bounds the allocations of a decoded state.
const MAX_STATE_BYTES: u64 = 1 << 34;

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

/// One log message waiting to be handed to the host's logger.
#[derive(Clone, Debug, PartialEq)]
pub struct LogRecord {
    pub status: Status,
    pub category: &'static str,
    pub message: String,
}

/// Records kept at most between two flushes (a host that never returns control would
/// otherwise grow the buffer without bound); later ones are counted and reported.
const MAX_PENDING_LOG: usize = 1000;

/// One FMU instance.
pub struct Instance {
    name: String,
    guid: String,
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
    /// startTime of fmi2SetupExperiment: the scene's time 0 (its time laws start here).
    start_time: f64,
    time: f64,
    last_successful_time: f64,
    stop_time: Option<f64>,
    /// Output values at `time` (index = value reference), from the last successful step.
    outputs: Vec<f64>,
    /// Whether the energies in `outputs` are those of the current state.
    energies_fresh: bool,
    /// Whether the gravity inputs were set while the scene's law is in force (warned once).
    gravity_ignored_warned: bool,
    logger: Arc<dyn Logger>,
    /// Messages of the current call: handed to the logger after the call has released the
    /// instance ([`Instance::take_log`]), so a logger may call back into the instance.
    pending_log: RefCell<Vec<LogRecord>>,
    dropped_log: Cell<usize>,
    logging_on: bool,
    categories: [bool; LOG_CATEGORIES.len()],
}

/// Relative tolerance of time comparisons.
fn time_tol(t: f64) -> f64 {
    1e-9 * t.abs().max(1.0)
}

/// Every value of a state that must be finite is (a corrupted or foreign state is refused
/// before it touches the instance).
fn state_is_finite(s: &FmuState) -> bool {
    let f3 = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    s.time.is_finite()
        && s.start_time.is_finite()
        && s.last_successful_time.is_finite()
        && s.stop_time.is_none_or(f64::is_finite)
        && f3(&s.inputs.gravity)
        && f3(&s.inputs.gravity_rate)
        && s.inputs.displacement.iter().all(f3)
        && s.inputs.displacement_rate.iter().all(f3)
        && s.inputs.load.iter().all(f3)
        && s.inputs.load_rate.iter().all(f3)
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
            guid: expected,
            params: scene.clone(),
            inputs: Inputs::start(&scene),
            outputs: vec![0.0; table.vars.len()],
            energies_fresh: false,
            gravity_ignored_warned: false,
            scene,
            table,
            sim: None,
            stale: true,
            pool,
            mode: Mode::Instantiated,
            start_time: 0.0,
            time: 0.0,
            last_successful_time: 0.0,
            stop_time: None,
            logger,
            pending_log: RefCell::new(Vec::new()),
            dropped_log: Cell::new(0),
            logging_on,
            categories: [true; LOG_CATEGORIES.len()],
        };
        inst.event(&format!(
            "instantiated '{}' (scene '{}', {} variables)",
            inst.name,
            inst.scene.name,
            inst.table.vars.len()
        ));
        // Under-resolved geometry: from the particles alone (the parameters change no geometry),
        // so it is known here, before the model is built.
        for w in inst.scene.warnings() {
            inst.warn(w.to_string());
        }
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

    fn log(&self, status: Status, category: &'static str, message: String) {
        let mut log = self.pending_log.borrow_mut();
        if log.len() < MAX_PENDING_LOG {
            log.push(LogRecord {
                status,
                category,
                message,
            });
        } else {
            self.dropped_log.set(self.dropped_log.get() + 1);
        }
    }

    /// The messages logged since the last call, in order. The C layer takes them while it holds
    /// the instance and hands them to the host's logger after releasing it.
    pub fn take_log(&self) -> Vec<LogRecord> {
        let mut out = std::mem::take(&mut *self.pending_log.borrow_mut());
        let dropped = self.dropped_log.replace(0);
        if dropped > 0 {
            out.push(LogRecord {
                status: Status::Warning,
                category: "logStatusWarning",
                message: format!("{dropped} further log messages were dropped"),
            });
        }
        out
    }

    /// Hands the pending messages to the instance's logger (for Rust callers of this API; the C
    /// layer uses [`Instance::take_log`] so that no lock is held while the host's logger runs).
    pub fn flush_log(&self) {
        for r in self.take_log() {
            self.logger.log(r.status, r.category, &r.message);
        }
    }

    /// Logs an event (category logEvents) when debug logging is on.
    fn event(&self, msg: &str) {
        if self.logging_on && (self.category_on("logEvents") || self.category_on("logAll")) {
            self.log(Status::Ok, "logEvents", msg.to_string());
        }
    }

    fn trace(&self, msg: &str) {
        if self.logging_on && self.category_on("logAll") {
            self.log(Status::Ok, "logAll", msg.to_string());
        }
    }

    /// Logs a warning (always: warnings are not debug messages).
    fn warn(&self, msg: String) {
        self.log(Status::Warning, "logStatusWarning", msg);
    }

    /// Logs an error of a call (always: errors are not debug messages).
    pub fn report(&self, function: &str, e: &FmiError) {
        let category = match e.status() {
            Status::Warning | Status::Discard => "logStatusWarning",
            _ => "logStatusError",
        };
        self.log(e.status(), category, format!("{function}: {}", e.message()));
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
    /// startTime becomes the scene's time 0: its time laws (the Eq. (46) ramp) start there.
    pub fn setup_experiment(&mut self, start: f64, stop: Option<f64>) -> FmiResult<()> {
        self.require("fmi2SetupExperiment", &[Mode::Instantiated])?;
        if !start.is_finite() {
            return Err(FmiError::Invalid(format!(
                "startTime = {start} must be finite"
            )));
        }
        if let Some(s) = stop {
            if !(s.is_finite() && s > start) {
                return Err(FmiError::Invalid(format!(
                    "stopTime = {s} must be finite and after startTime = {start}"
                )));
            }
        }
        if self.sim.as_ref().is_some_and(|s| s.time() != 0.0) {
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
    fn build(&mut self) -> FmiResult<()> {
        if !self.stale && self.sim.is_some() {
            return Ok(());
        }
        let params = &self.params;
        let sim = self
            .pool
            .install(|| Simulation::new(params))
            .map_err(|e| FmiError::Solver(format!("cannot build the model: {e}")))?;
        self.event(&format!(
            "built the model: {} particles, {} bonds, solver step {:.4e} s",
            sim.particles(),
            sim.bonds(),
            sim.max_dt()
        ));
        // What only the built model knows (the scene's own warnings were logged at
        // instantiation): second-order bodies without the closure at their free faces.
        let known = self.scene.warnings();
        for w in sim.warnings() {
            if !known.contains(w) {
                self.warn(w.to_string());
            }
        }
        self.sim = Some(sim);
        self.stale = false;
        self.refresh_outputs()
    }

    /// The cheap outputs (probes, reactions, counters) of a simulation, in table order (None
    /// for the others); an error if one is not finite.
    fn cheap_outputs(&self, sim: &Simulation) -> FmiResult<Vec<Option<f64>>> {
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

    fn store_outputs(&mut self, new: Vec<Option<f64>>) {
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
    fn refresh_outputs(&mut self) -> FmiResult<()> {
        let Some(sim) = &self.sim else {
            return Ok(());
        };
        let new = self.cheap_outputs(sim)?;
        self.store_outputs(new);
        Ok(())
    }

    /// Brings the cached energies up to date; a non-finite energy is an error (never a stale
    /// or NaN value handed out with fmi2OK).
    fn update_energies(&mut self) -> FmiResult<()> {
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
                    self.time
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
        self.event("entered initialization mode");
        Ok(())
    }

    /// fmi2ExitInitializationMode: rebuilds if parameters changed during initialisation.
    pub fn exit_initialization_mode(&mut self) -> FmiResult<()> {
        self.require("fmi2ExitInitializationMode", &[Mode::InitializationMode])?;
        self.build()?;
        self.mode = Mode::StepComplete;
        self.event(&format!(
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
        self.gravity_ignored_warned = false;
        self.start_time = 0.0;
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
            Quantity::GravitySource => self.inputs.gravity_source as i32 as f64,
            Quantity::BoundaryTiming => self.inputs.boundary_timing as i32 as f64,
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
            self.update_energies()?;
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

    /// Checks that variable `r` may be set now (not an output, a parameter only before
    /// fmi2ExitInitializationMode).
    fn settable(&self, r: u32, ty: VarType) -> FmiResult<&super::variables::Variable> {
        let v = self.var(r, ty)?;
        match v.causality {
            Causality::Output => Err(FmiError::Invalid(format!(
                "'{}' (value reference {r}) is an output and cannot be set",
                v.name
            ))),
            Causality::Parameter if self.mode == Mode::StepComplete => {
                Err(FmiError::Invalid(format!(
                    "'{}' (value reference {r}) is a fixed parameter: it can be set only before \
                     fmi2ExitInitializationMode",
                    v.name
                )))
            }
            _ => Ok(v),
        }
    }

    /// fmi2SetReal: checks every value first and applies none if one is bad. Inputs take effect
    /// at the next doStep.
    pub fn set_real(&mut self, vr: &[u32], values: &[f64]) -> FmiResult<()> {
        self.require("fmi2SetReal", &Self::SET_MODES)?;
        for (&r, &x) in vr.iter().zip(values) {
            let v = self.settable(r, VarType::Real)?;
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
                        "'{}' cannot be set to {}: {m} (nothing was set)",
                        v.name,
                        num(x)
                    ))
                })?;
            }
        }
        for (&r, &x) in vr.iter().zip(values) {
            let q = self.table.vars[r as usize].quantity;
            match q {
                Quantity::Gravity(k) => {
                    if self.inputs.gravity_source == GravitySource::Scene
                        && x != self.inputs.gravity[k]
                        && !self.gravity_ignored_warned
                    {
                        self.gravity_ignored_warned = true;
                        self.warn(format!(
                            "fmi2SetReal: gravity_{} set to {x} while gravity_source = 1 (the \
                             scene's gravity law): the gravity inputs are ignored; set the \
                             parameter gravity_source = 2 to drive gravity from the inputs",
                            ["x", "y", "z"][k]
                        ));
                    }
                    self.inputs.gravity[k] = x;
                }
                Quantity::GroupDisplacement(g, k) => self.inputs.displacement[g][k] = x,
                Quantity::Load(l, k) => self.inputs.load[l][k] = x,
                _ => {
                    VariableTable::set_parameter(&mut self.params, q, x)
                        .map_err(FmiError::Invalid)?;
                    self.stale = true;
                }
            }
        }
        Ok(())
    }

    /// fmi2SetInteger: the Integer parameters gravity_source and boundary_input_timing.
    pub fn set_integer(&mut self, vr: &[u32], values: &[i32]) -> FmiResult<()> {
        self.require("fmi2SetInteger", &Self::SET_MODES)?;
        let mut gravity = self.inputs.gravity_source;
        let mut timing = self.inputs.boundary_timing;
        for (&r, &x) in vr.iter().zip(values) {
            let v = self.settable(r, VarType::Integer)?;
            let bad = || {
                FmiError::Invalid(format!(
                    "'{}' (value reference {r}) cannot be set to {x}: allowed values are 1 and 2 \
                     (nothing was set)",
                    v.name
                ))
            };
            match v.quantity {
                Quantity::GravitySource => gravity = GravitySource::from_int(x).ok_or_else(bad)?,
                Quantity::BoundaryTiming => timing = BoundaryTiming::from_int(x).ok_or_else(bad)?,
                _ => {
                    return Err(FmiError::Invalid(format!(
                        "'{}' (value reference {r}) cannot be set",
                        v.name
                    )))
                }
            }
        }
        if gravity != self.inputs.gravity_source {
            self.event(&format!("gravity_source = {}", gravity as i32));
            self.gravity_ignored_warned = false;
        }
        self.inputs.gravity_source = gravity;
        self.inputs.boundary_timing = timing;
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

    /// fmi2SetRealInputDerivatives: first derivatives of the Real inputs for the next doStep
    /// (canInterpolateInputs): over the step an input is `u + du/dt (tau - t)`. They apply to
    /// that one step and are cleared after it.
    pub fn set_real_input_derivatives(
        &mut self,
        vr: &[u32],
        order: &[i32],
        values: &[f64],
    ) -> FmiResult<()> {
        self.require(
            "fmi2SetRealInputDerivatives",
            &[Mode::InitializationMode, Mode::StepComplete],
        )?;
        for ((&r, &o), &x) in vr.iter().zip(order).zip(values) {
            let v = self.var(r, VarType::Real)?;
            if v.causality != Causality::Input {
                return Err(FmiError::Invalid(format!(
                    "'{}' (value reference {r}) is not an input: only inputs have derivatives",
                    v.name
                )));
            }
            if o != 1 {
                return Err(FmiError::Invalid(format!(
                    "derivative order {o} of '{}': only first derivatives are used \
                     (linear interpolation over the step; nothing was set)",
                    v.name
                )));
            }
            if !x.is_finite() {
                return Err(FmiError::Invalid(format!(
                    "the derivative of '{}' cannot be {x}: values must be finite (nothing was set)",
                    v.name
                )));
            }
        }
        for (&r, &x) in vr.iter().zip(values) {
            match self.table.vars[r as usize].quantity {
                Quantity::Gravity(k) => self.inputs.gravity_rate[k] = x,
                Quantity::GroupDisplacement(g, k) => self.inputs.displacement_rate[g][k] = x,
                Quantity::Load(l, k) => self.inputs.load_rate[l][k] = x,
                _ => {}
            }
        }
        Ok(())
    }

    /// Hands the inputs to the simulation for the step [time, time + h] (simulation time).
    fn apply_inputs(sim: &mut Simulation, inputs: &Inputs, h: f64) {
        let t = sim.time();
        if inputs.gravity_source == GravitySource::Inputs {
            sim.set_gravity_linear(inputs.gravity, inputs.gravity_rate, t);
        }
        for (r, (f, df)) in inputs.load.iter().zip(&inputs.load_rate).enumerate() {
            sim.set_load(r, *f, *df, t);
        }
        for (g, (d, dd)) in inputs
            .displacement
            .iter()
            .zip(&inputs.displacement_rate)
            .enumerate()
        {
            match inputs.boundary_timing {
                BoundaryTiming::AtStepStart => {
                    let end = [d[0] + dd[0] * h, d[1] + dd[1] * h, d[2] + dd[2] * h];
                    sim.set_group_motion(g, *d, end, t, t + h);
                }
                BoundaryTiming::AtStepEnd => {
                    let now = sim.group_displacement(g);
                    sim.set_group_motion(g, now, *d, t, t + h);
                }
            }
        }
    }

    /// fmi2DoStep: advances from t to exactly t + h with the solver's stable sub-steps. A step
    /// that would take more than `solver.max_steps` solver steps is refused before any work,
    /// leaving the instance as it was.
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
        let sim_end = t_end - self.start_time;
        let sim = self
            .sim
            .as_mut()
            .ok_or_else(|| FmiError::Fatal("no model built".into()))?;
        // Refused before any work, the instance unchanged (not an Error state).
        sim.check_work(sim_end).map_err(|e| {
            FmiError::Invalid(format!(
                "doStep(t = {}, h = {}) refused: {e}; use shorter communication steps",
                num(t),
                num(h)
            ))
        })?;
        Self::apply_inputs(sim, &self.inputs, sim_end - sim.time());
        let res = self.pool.install(|| sim.advance_to(sim_end));
        let res = match res {
            Ok(n) => self.refresh_outputs().map(|_| n),
            Err(e) => Err(FmiError::Solver(format!(
                "step from t = {t} to {t_end} failed: {e}"
            ))),
        };
        self.inputs.clear_rates();
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

    /// fmi2CancelStep: doStep is synchronous (it never returns fmi2Pending), so there is never a
    /// step to cancel; the work of one doStep is bounded by `solver.max_steps` instead.
    pub fn cancel_step(&mut self) -> FmiResult<()> {
        Err(FmiError::Invalid(
            "fmi2CancelStep is not supported: fmi2DoStep is synchronous and never returns \
             fmi2Pending (the work of one step is bounded by solver.max_steps)"
                .into(),
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

    const STATE_MODES: [Mode; 5] = [
        Mode::Instantiated,
        Mode::InitializationMode,
        Mode::StepComplete,
        Mode::Error,
        Mode::Terminated,
    ];

    /// fmi2GetFMUstate: allowed from fmi2Instantiate on (the model is built for it if needed).
    pub fn get_fmu_state(&mut self) -> FmiResult<FmuState> {
        self.require("fmi2GetFMUstate", &Self::STATE_MODES)?;
        if self.stale {
            self.build()?;
        }
        let sim = self
            .sim
            .as_ref()
            .ok_or_else(|| FmiError::Fatal("no model built".into()))?;
        let state = self.pool.install(|| sim.state());
        let s = FmuState {
            guid: self.guid.clone(),
            particles: sim.particles() as u64,
            initialized: self.mode != Mode::Instantiated,
            params: self.params.clone(),
            inputs: self.inputs.clone(),
            start_time: self.start_time,
            time: self.time,
            last_successful_time: self.last_successful_time,
            stop_time: self.stop_time,
            sim: state,
        };
        self.event(&format!("FMU state captured at t = {}", self.time));
        Ok(s)
    }

    /// Refuses a state of another FMU, another model or with non-finite values.
    fn check_state(&self, s: &FmuState) -> FmiResult<()> {
        let bad = |m: String| FmiError::Invalid(format!("the FMU state is refused: {m}"));
        if s.guid != self.guid {
            return Err(bad(format!(
                "it was taken from another FMU (GUID {}, this FMU has {})",
                s.guid, self.guid
            )));
        }
        if !s.inputs.fits(&self.scene) {
            return Err(bad("its inputs belong to another scene".into()));
        }
        if !state_is_finite(s) {
            return Err(bad("it holds non-finite values".into()));
        }
        if let Err(e) = s.params.validate() {
            return Err(bad(format!("its parameters are invalid: {e}")));
        }
        Ok(())
    }

    /// fmi2SetFMUstate: restores everything or nothing. The model is rebuilt (on the instance's
    /// threads) if the state's parameters differ; a state taken after initialisation continues
    /// in StepComplete (fmusim's --initial-fmu-state-file steps right after restoring), one taken
    /// before it returns to Instantiated.
    pub fn set_fmu_state(&mut self, s: &FmuState) -> FmiResult<()> {
        self.require("fmi2SetFMUstate", &Self::STATE_MODES)?;
        self.check_state(s)?;
        let rebuild = s.params != self.params || self.sim.is_none() || self.stale;
        let restore = |sim: &mut Simulation| -> FmiResult<()> {
            if sim.particles() as u64 != s.particles {
                return Err(FmiError::Invalid(format!(
                    "the FMU state is refused: it has {} particles, this model {}",
                    s.particles,
                    sim.particles()
                )));
            }
            sim.set_state(&s.sim)
                .map_err(|e| FmiError::Invalid(format!("cannot restore the FMU state: {e}")))
        };
        if rebuild {
            let params = &s.params;
            let mut sim = self.pool.install(|| Simulation::new(params)).map_err(|e| {
                FmiError::Invalid(format!("cannot build the FMU state's model: {e}"))
            })?;
            self.pool.install(|| restore(&mut sim))?;
            let outputs = self.cheap_outputs(&sim)?;
            self.sim = Some(sim);
            self.params = s.params.clone();
            self.stale = false;
            self.store_outputs(outputs);
        } else {
            let sim = self
                .sim
                .as_mut()
                .ok_or_else(|| FmiError::Fatal("no model built".into()))?;
            let previous = self.pool.install(|| sim.state());
            let restored = self.pool.install(|| restore(sim));
            let outputs = restored.and_then(|_| {
                let sim = self.sim.as_ref().expect("built");
                self.cheap_outputs(sim)
            });
            match outputs {
                Ok(o) => self.store_outputs(o),
                Err(e) => {
                    let sim = self.sim.as_mut().expect("built");
                    self.pool
                        .install(|| sim.set_state(&previous))
                        .map_err(|e| FmiError::Fatal(format!("cannot roll back: {e}")))?;
                    return Err(e);
                }
            }
        }
        self.inputs = s.inputs.clone();
        self.start_time = s.start_time;
        self.time = s.time;
        self.last_successful_time = s.last_successful_time;
        self.stop_time = s.stop_time;
        self.mode = match (s.initialized, self.mode) {
            (false, _) => Mode::Instantiated,
            (true, Mode::InitializationMode) => Mode::InitializationMode,
            (true, _) => Mode::StepComplete,
        };
        self.event(&format!("FMU state restored at t = {}", self.time));
        Ok(())
    }

    /// Checks a state may be freed (any state but fatal ones; the C layer frees it).
    pub fn free_fmu_state(&self) -> FmiResult<()> {
        Ok(())
    }

    fn bincode() -> impl bincode::Options {
        use bincode::Options;
        bincode::DefaultOptions::new()
            .with_fixint_encoding()
            .with_little_endian()
            .with_limit(MAX_STATE_BYTES)
    }

    /// fmi2SerializeFMUstate: magic, format version, the GUID, the payload length, bincode of
    /// the state, and a CRC-32 of everything before it.
    pub fn serialize_fmu_state(&self, s: &FmuState) -> FmiResult<Vec<u8>> {
        use bincode::Options;
        let payload = Self::bincode()
            .serialize(s)
            .map_err(|e| FmiError::Invalid(format!("cannot serialise the FMU state: {e}")))?;
        let g = self.guid.as_bytes();
        let mut out = Vec::with_capacity(32 + g.len() + payload.len());
        out.extend_from_slice(STATE_MAGIC);
        out.extend_from_slice(&STATE_VERSION.to_le_bytes());
        out.extend_from_slice(&(g.len() as u32).to_le_bytes());
        out.extend_from_slice(g);
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        Ok(out)
    }

    /// fmi2DeSerializeFMUstate: checks the length, checksum, magic, version and GUID before
    /// decoding, and the decoded state against this FMU.
    pub fn deserialize_fmu_state(&self, bytes: &[u8]) -> FmiResult<FmuState> {
        use bincode::Options;
        let bad = |m: &str| FmiError::Invalid(format!("not a serialised state of this FMU: {m}"));
        if bytes.len() < 28 || &bytes[..8] != STATE_MAGIC {
            return Err(bad("bad magic"));
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
        if version != STATE_VERSION {
            return Err(bad(&format!(
                "format version {version}, expected {STATE_VERSION}"
            )));
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        if crc32fast::hash(body).to_le_bytes() != crc {
            return Err(bad(
                "checksum mismatch (the data was truncated or corrupted)",
            ));
        }
        let n = u32::from_le_bytes(body[12..16].try_into().expect("4 bytes")) as usize;
        let g = body.get(16..16 + n).ok_or_else(|| bad("truncated"))?;
        if g != self.guid.as_bytes() {
            return Err(bad("it was made by an FMU with another GUID"));
        }
        let len_at = 16 + n;
        let len = body
            .get(len_at..len_at + 8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
            .ok_or_else(|| bad("truncated"))?;
        let payload = &body[len_at + 8..];
        if payload.len() as u64 != len {
            return Err(bad(&format!(
                "the payload has {} bytes, its header says {len}",
                payload.len()
            )));
        }
        let s: FmuState = Self::bincode()
            .deserialize(payload)
            .map_err(|e| bad(&format!("cannot decode: {e}")))?;
        self.check_state(&s)?;
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

    /// An initialised instance of tests/data/small2d.json, stepped 3 times.
    fn small2d() -> Instance {
        // One directory per call: the tests run in parallel threads, and a shared scene file
        // could be read while another test truncates it.
        static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir =
            std::env::temp_dir().join(format!("mps-instance-unit-{}-{call}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene =
            Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small2d.json"))
                .unwrap();
        std::fs::write(dir.join("scene.json"), scene.to_json()).unwrap();
        let uri = format!("file://{}", dir.display());
        let mut i = Instance::instantiate(
            "unit",
            true,
            &guid(&scene),
            Some(&uri),
            Arc::new(NoLogger),
            false,
        )
        .unwrap();
        i.setup_experiment(0.0, None).unwrap();
        i.enter_initialization_mode().unwrap();
        i.exit_initialization_mode().unwrap();
        for k in 0..3 {
            i.do_step(k as f64 * 0.002, 0.002).unwrap();
        }
        i
    }

    fn first_x(s: &mut FmuState) -> &mut f64 {
        match &mut s.sim {
            SimState::D2(w) => &mut w.u[5][0],
            SimState::D3(w) => &mut w.u[5][0],
        }
    }

    #[test]
    fn a_failed_set_fmu_state_changes_nothing() {
        // Issue 8.8: a rejected fmi2SetFMUstate overwrote time, inputs and particles. A state
        // of this FMU whose particles are not finite passes the header checks, is restored into
        // the model, found bad (non-finite outputs) and rolled back.
        let mut i = small2d();
        let mut good = i.get_fmu_state().unwrap();
        i.do_step(0.006, 0.002).unwrap();
        let before = i.get_fmu_state().unwrap();
        *first_x(&mut good) = f64::NAN;
        good.time = 123.0;
        let e = i.set_fmu_state(&good).unwrap_err();
        assert!(e.message().contains("non-finite"), "{}", e.message());
        assert_eq!(i.time(), 0.008);
        assert_eq!(i.mode(), Mode::StepComplete);
        assert_eq!(
            i.get_fmu_state().unwrap(),
            before,
            "state changed by a failed call"
        );
        // Parameters that differ go through a rebuild: refused the same way.
        let mut other = before.clone();
        other.params.bodies[0].material.density *= 2.0;
        *first_x(&mut other) = f64::INFINITY;
        assert!(i.set_fmu_state(&other).is_err());
        assert_eq!(i.get_fmu_state().unwrap(), before);
    }

    #[test]
    fn a_state_with_a_non_finite_input_is_refused() {
        // Found by the fmu_state fuzz target: a state whose input was NaN was restored and the
        // NaN read back with fmi2OK.
        let mut i = small2d();
        let before = i.get_fmu_state().unwrap();
        let mut bad = before.clone();
        bad.inputs.displacement[0][1] = f64::NAN;
        let e = i.set_fmu_state(&bad).unwrap_err();
        assert!(e.message().contains("non-finite"), "{}", e.message());
        let bytes = i.serialize_fmu_state(&bad).unwrap();
        assert!(i.deserialize_fmu_state(&bytes).is_err());
        assert_eq!(i.get_fmu_state().unwrap(), before);
    }

    #[test]
    fn non_finite_energies_are_errors_not_stale_values() {
        // Issue 8.10: a NaN energy was handed out as the last finite value with fmi2OK.
        let mut i = small2d();
        let ke = i.table().by_name("kinetic_energy").unwrap().value_reference;
        let mut out = [0.0];
        i.get_real(&[ke], &mut out).unwrap();
        assert!(out[0].is_finite());
        // (A state with a NaN is refused on restore: poke the model directly.)
        match i.sim.as_mut().unwrap() {
            Simulation::D2(m) => m.world.p.v[7][1] = f64::NAN,
            Simulation::D3(m) => m.world.p.v[7][1] = f64::NAN,
        }
        i.energies_fresh = false;
        let e = i.get_real(&[ke], &mut out).unwrap_err();
        assert!(
            e.message().contains("kinetic_energy is NaN"),
            "{}",
            e.message()
        );
    }

    #[test]
    fn error_statuses() {
        assert_eq!(FmiError::IllegalCall("x".into()).status(), Status::Error);
        assert_eq!(FmiError::NotProvided("x".into()).status(), Status::Discard);
        assert_eq!(FmiError::Fatal("x".into()).status(), Status::Fatal);
    }
}
