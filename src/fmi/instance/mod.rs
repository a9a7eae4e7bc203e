//! The safe FMU instance under the C ABI: the call-order state machine, variable access through
//! the variable table, doStep sub-stepping, FMU state as data, and the instance's own worker
//! threads. Every error is an [`FmiError`], mapped to its FMI status in one place
//! ([`FmiError::status`]).
//!
//! One concern per file; the dependencies point one way (each file uses only those listed
//! after it):
//! - `values`, `stepping`, `fmu_state`: the [`Instance`]'s fmi2Get/Set*, doStep and
//!   status queries, and FMU state functions;
//! - `lifecycle`: the [`Instance`] itself, fmi2Instantiate, the call-order state machine,
//!   setup/initialisation/terminate/reset, the model build and the cached outputs;
//! - `inputs`: the inputs and FMU-level settings;
//! - `worker_pool`: the instance's own threads;
//! - `resources`: the resources directory and its scene;
//! - `logging`: the logger and the pending log;
//! - `status`: statuses and errors.
mod fmu_state;
mod inputs;
mod lifecycle;
mod logging;
mod resources;
mod status;
mod stepping;
#[cfg(test)]
mod test_support;
mod values;
mod worker_pool;

pub use fmu_state::FmuState;
pub use inputs::{BoundaryTiming, GravitySource};
pub use lifecycle::{Instance, Mode, SetupControl};
pub use logging::{LogRecord, Logger, NoLogger};
pub use resources::{load_closure, load_scene, resource_dir, CLOSURE_FILE};
pub(crate) use status::panic_message;
pub use status::{FmiError, FmiResult, Status};
pub use stepping::{
    DO_STEP_STATUS, LAST_SUCCESSFUL_TIME, LONG_STEP_WARNING_S, PENDING_STATUS, TERMINATED,
};
pub use worker_pool::{instance_threads, WorkerPool};
