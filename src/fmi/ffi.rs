//! The exported FMI 2.0 functions (all common and co-simulation functions of fmi2Functions.h):
//! the crate's only unsafe code. Each export checks its pointers (nvr = 0 with a NULL array is
//! legal), copies the strings it is given, catches panics (fmi2Fatal, after which only
//! fmi2FreeInstance is accepted) and hands over to the safe [`Instance`].
//!
//! Safety contract of every `unsafe extern "C"` function here: the caller is an FMI 2.0 host;
//! pointers are NULL or valid for the documented number of elements, a component is one returned
//! by `fmi2Instantiate` and not yet freed, an FMU state one returned by this library for it.
#![allow(non_camel_case_types, non_snake_case, clippy::missing_safety_doc)]

use super::instance::{
    instance_threads, panic_message, FmiError, FmiResult, FmuState, Instance, Logger, SetupControl,
    Status, WorkerPool,
};
use std::ffi::{c_char, c_int, c_uint, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

pub type fmi2Component = *mut c_void;
pub type fmi2ComponentEnvironment = *mut c_void;
pub type fmi2FMUstate = *mut c_void;
pub type fmi2ValueReference = c_uint;
pub type fmi2Real = f64;
pub type fmi2Integer = c_int;
pub type fmi2Boolean = c_int;
pub type fmi2Char = c_char;
pub type fmi2String = *const fmi2Char;
pub type fmi2Byte = c_char;
/// An enum in C; read as an int so that no value the host passes is undefined behaviour.
pub type fmi2Type = c_int;
/// An enum in C; read as an int so that no value the host passes is undefined behaviour.
pub type fmi2StatusKind = c_int;

/// fmi2Status.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum fmi2Status {
    fmi2OK = 0,
    fmi2Warning = 1,
    fmi2Discard = 2,
    fmi2Error = 3,
    fmi2Fatal = 4,
    fmi2Pending = 5,
}

impl From<Status> for fmi2Status {
    fn from(s: Status) -> Self {
        match s {
            Status::Ok => fmi2Status::fmi2OK,
            Status::Warning => fmi2Status::fmi2Warning,
            Status::Discard => fmi2Status::fmi2Discard,
            Status::Error => fmi2Status::fmi2Error,
            Status::Fatal => fmi2Status::fmi2Fatal,
            Status::Pending => fmi2Status::fmi2Pending,
        }
    }
}

/// fmi2CallbackLogger: variadic; always called with the format "%s".
pub type fmi2CallbackLogger = Option<
    unsafe extern "C" fn(
        componentEnvironment: fmi2ComponentEnvironment,
        instanceName: fmi2String,
        status: fmi2Status,
        category: fmi2String,
        message: fmi2String,
        ...
    ),
>;

/// fmi2CallbackFunctions (the memory callbacks are not used: Rust allocates).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct fmi2CallbackFunctions {
    pub logger: fmi2CallbackLogger,
    pub allocateMemory: Option<unsafe extern "C" fn(nobj: usize, size: usize) -> *mut c_void>,
    pub freeMemory: Option<unsafe extern "C" fn(obj: *mut c_void)>,
    pub stepFinished: Option<
        unsafe extern "C" fn(componentEnvironment: fmi2ComponentEnvironment, status: fmi2Status),
    >,
    pub componentEnvironment: fmi2ComponentEnvironment,
}

/// The host's logger with the copied instance name.
struct CLogger {
    logger: fmi2CallbackLogger,
    env: fmi2ComponentEnvironment,
    name: CString,
}

// SAFETY: the environment pointer is only handed back to the host's own logger; FMI requires
// the host to accept calls from whichever thread calls into the instance.
unsafe impl Send for CLogger {}
unsafe impl Sync for CLogger {}

fn cstring(s: &str) -> CString {
    CString::new(s.replace('\0', " ")).expect("NULs removed")
}

impl Logger for CLogger {
    fn log(&self, status: Status, category: &str, message: &str) {
        if let Some(f) = self.logger {
            let (cat, msg) = (cstring(category), cstring(message));
            // SAFETY: all strings are NUL-terminated and outlive the call.
            unsafe {
                f(
                    self.env,
                    self.name.as_ptr(),
                    status.into(),
                    cat.as_ptr(),
                    c"%s".as_ptr(),
                    msg.as_ptr(),
                )
            };
        }
    }
}

/// What an `fmi2Component` points to.
struct Component {
    logger: Arc<dyn Logger>,
    inst: Mutex<Instance>,
    /// Set after a panic: the instance may be inconsistent.
    fatal: AtomicBool,
    /// The thread running a call on the instance (0: none): a call from that same thread while
    /// it runs (the host's logger calling back during a set-up message) is refused instead of
    /// deadlocking on the lock.
    owner: AtomicUsize,
    /// The instance's running set-up, which fmi2CancelStep may stop without the lock.
    setup: Arc<SetupControl>,
}

/// An id of the calling thread (never 0).
fn thread_id() -> usize {
    // SAFETY: pthread_self has no preconditions; glibc returns the thread's descriptor address.
    #[cfg(unix)]
    let id = unsafe { libc::pthread_self() } as usize;
    #[cfg(not(unix))]
    let id = {
        thread_local!(static MARK: u8 = const { 0 });
        MARK.with(|m| m as *const u8 as usize)
    };
    id.max(1)
}

/// Runs f on the instance behind c: the panic boundary and the status mapping of every call
/// that takes a component.
fn with_instance(
    c: fmi2Component,
    function: &str,
    f: impl FnOnce(&mut Instance) -> FmiResult<()>,
) -> fmi2Status {
    if c.is_null() {
        return fmi2Status::fmi2Error;
    }
    // SAFETY: c came from fmi2Instantiate (caller's contract).
    let comp = unsafe { &*(c as *const Component) };
    guard(comp, function, f)
}

fn guard(
    comp: &Component,
    function: &str,
    f: impl FnOnce(&mut Instance) -> FmiResult<()>,
) -> fmi2Status {
    if comp.fatal.load(Ordering::SeqCst) {
        comp.logger.log(
            Status::Error,
            "logStatusError",
            &format!("{function}: the instance is unusable after an internal error; only fmi2FreeInstance is allowed"),
        );
        return fmi2Status::fmi2Error;
    }
    let me = thread_id();
    if comp.owner.load(Ordering::SeqCst) == me {
        comp.logger.log(
            Status::Error,
            "logStatusError",
            &format!(
                "{function}: called from within a call on the same instance (the logger's \
                 callback during a set-up message?): call it after that call has returned"
            ),
        );
        return fmi2Status::fmi2Error;
    }
    // The instance's messages are handed to the host's logger only after the lock is released,
    // so that a logger may call back into the instance (fmi2GetReal while an error is logged).
    let r = catch_unwind(AssertUnwindSafe(|| {
        let mut inst = comp.inst.lock().unwrap_or_else(|e| e.into_inner());
        comp.owner.store(me, Ordering::SeqCst);
        let result = catch_unwind(AssertUnwindSafe(|| f(&mut inst)));
        comp.owner.store(0, Ordering::SeqCst);
        let result = result.unwrap_or_else(|p| std::panic::resume_unwind(p));
        let status = match result {
            Ok(()) => Status::Ok,
            Err(e) => {
                inst.report(function, &e);
                e.status()
            }
        };
        let log = inst.take_log();
        drop(inst);
        (status, log)
    }));
    match r {
        Ok((s, log)) => {
            let _ = catch_unwind(AssertUnwindSafe(|| {
                for m in log {
                    comp.logger.log(m.status, m.category, &m.message);
                }
            }));
            s.into()
        }
        Err(p) => {
            comp.fatal.store(true, Ordering::SeqCst);
            comp.logger.log(
                Status::Fatal,
                "logStatusError",
                &format!("{function}: internal error (panic): {}", panic_message(&*p)),
            );
            fmi2Status::fmi2Fatal
        }
    }
}

fn null(what: &str) -> FmiError {
    FmiError::Invalid(format!("{what} is NULL"))
}

/// A slice from a C array; NULL is legal when n = 0.
unsafe fn slice<'a, T>(p: *const T, n: usize, what: &str) -> FmiResult<&'a [T]> {
    if n == 0 {
        Ok(&[])
    } else if p.is_null() {
        Err(FmiError::Invalid(format!(
            "{what} is NULL but {n} values were requested"
        )))
    } else {
        Ok(std::slice::from_raw_parts(p, n))
    }
}

unsafe fn slice_mut<'a, T>(p: *mut T, n: usize, what: &str) -> FmiResult<&'a mut [T]> {
    if n == 0 {
        Ok(&mut [])
    } else if p.is_null() {
        Err(FmiError::Invalid(format!(
            "{what} is NULL but {n} values were requested"
        )))
    } else {
        Ok(std::slice::from_raw_parts_mut(p, n))
    }
}

/// Copies a C string (lossy UTF-8); None for NULL.
unsafe fn string(p: fmi2String) -> Option<String> {
    (!p.is_null()).then(|| CStr::from_ptr(p).to_string_lossy().into_owned())
}

/// Writes a state into *out: reuses the state already there (as the standard allows) or
/// allocates a new one.
unsafe fn put_state(out: *mut fmi2FMUstate, s: FmuState) {
    if (*out).is_null() {
        *out = Box::into_raw(Box::new(s)) as fmi2FMUstate;
    } else {
        *((*out) as *mut FmuState) = s;
    }
}

unsafe fn state_ref<'a>(s: fmi2FMUstate) -> FmiResult<&'a FmuState> {
    if s.is_null() {
        Err(null("FMUstate"))
    } else {
        Ok(&*(s as *const FmuState))
    }
}

// ---------------------------------------------------------------------------------------------
// Common functions.

/// fmi2GetTypesPlatform: "default".
#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

/// fmi2GetVersion: "2.0".
#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// fmi2SetDebugLogging: categories of modelDescription.xml; none = all.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    with_instance(c, "fmi2SetDebugLogging", |inst| {
        let cats = slice(categories, nCategories, "categories")?;
        let names = cats
            .iter()
            .map(|&p| string(p).ok_or_else(|| null("a category")))
            .collect::<FmiResult<Vec<_>>>()?;
        inst.set_debug_logging(loggingOn != 0, &names)
    })
}

/// fmi2Instantiate: NULL (with a logged reason) on a wrong type or GUID, unreadable resources.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instanceName: fmi2String,
    fmuType: fmi2Type,
    fmuGUID: fmi2String,
    fmuResourceLocation: fmi2String,
    functions: *const fmi2CallbackFunctions,
    visible: fmi2Boolean,
    loggingOn: fmi2Boolean,
) -> fmi2Component {
    let _ = visible;
    let r = catch_unwind(AssertUnwindSafe(|| {
        let (f, env) = if functions.is_null() {
            (None, std::ptr::null_mut())
        } else {
            let cb = *functions;
            (cb.logger, cb.componentEnvironment)
        };
        let name = string(instanceName);
        let logger = Arc::new(CLogger {
            logger: f,
            env,
            name: cstring(name.as_deref().unwrap_or("")),
        });
        let fail = |m: &str| {
            logger.log(
                Status::Error,
                "logStatusError",
                &format!("fmi2Instantiate: {m}"),
            );
            std::ptr::null_mut()
        };
        let Some(name) = name else {
            return fail("instanceName is NULL");
        };
        let Some(guid) = string(fmuGUID) else {
            return fail("fmuGUID is NULL");
        };
        let location = string(fmuResourceLocation);
        const CO_SIMULATION: c_int = 1;
        match Instance::instantiate_with_pool(
            &name,
            fmuType == CO_SIMULATION,
            &guid,
            location.as_deref(),
            logger.clone(),
            loggingOn != 0,
            instance_pool,
        ) {
            Ok(inst) => {
                for m in inst.take_log() {
                    logger.log(m.status, m.category, &m.message);
                }
                Box::into_raw(Box::new(Component {
                    logger: logger as Arc<dyn Logger>,
                    setup: inst.setup_control(),
                    inst: Mutex::new(inst),
                    fatal: AtomicBool::new(false),
                    owner: AtomicUsize::new(0),
                })) as fmi2Component
            }
            Err(m) => fail(&m),
        }
    }));
    r.unwrap_or(std::ptr::null_mut())
}

/// fmi2FreeInstance: drops the instance and joins its worker threads.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    if c.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        drop(Box::from_raw(c as *mut Component));
    }));
}

/// fmi2SetupExperiment: startTime must be 0; the tolerance is not used.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: fmi2Component,
    toleranceDefined: fmi2Boolean,
    tolerance: fmi2Real,
    startTime: fmi2Real,
    stopTimeDefined: fmi2Boolean,
    stopTime: fmi2Real,
) -> fmi2Status {
    let _ = (toleranceDefined, tolerance);
    with_instance(c, "fmi2SetupExperiment", |inst| {
        inst.setup_experiment(startTime, (stopTimeDefined != 0).then_some(stopTime))
    })
}

/// fmi2EnterInitializationMode.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
    with_instance(c, "fmi2EnterInitializationMode", |i| {
        i.enter_initialization_mode()
    })
}

/// fmi2ExitInitializationMode.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
    with_instance(c, "fmi2ExitInitializationMode", |i| {
        i.exit_initialization_mode()
    })
}

/// fmi2Terminate.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
    with_instance(c, "fmi2Terminate", |i| i.terminate())
}

/// fmi2Reset.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
    with_instance(c, "fmi2Reset", |i| i.reset())
}

/// fmi2GetReal.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    with_instance(c, "fmi2GetReal", |i| {
        let vr = slice(vr, nvr, "vr")?;
        let value = slice_mut(value, nvr, "value")?;
        i.get_real(vr, value)
    })
}

/// fmi2GetInteger.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Integer,
) -> fmi2Status {
    with_instance(c, "fmi2GetInteger", |i| {
        let vr = slice(vr, nvr, "vr")?;
        let value = slice_mut(value, nvr, "value")?;
        i.get_integer(vr, value)
    })
}

/// fmi2GetBoolean: this FMU has no Boolean variables.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    with_instance(c, "fmi2GetBoolean", |i| {
        let vr = slice(vr, nvr, "vr")?;
        slice_mut(value, nvr, "value")?;
        i.get_none("fmi2GetBoolean", "Boolean", vr)
    })
}

/// fmi2GetString: this FMU has no String variables.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2String,
) -> fmi2Status {
    with_instance(c, "fmi2GetString", |i| {
        let vr = slice(vr, nvr, "vr")?;
        slice_mut(value, nvr, "value")?;
        i.get_none("fmi2GetString", "String", vr)
    })
}

/// fmi2SetReal: parameters before the end of initialisation, inputs any time.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    with_instance(c, "fmi2SetReal", |i| {
        let vr = slice(vr, nvr, "vr")?;
        let value = slice(value, nvr, "value")?;
        i.set_real(vr, value)
    })
}

/// fmi2SetInteger: the Integer variables are outputs.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Integer,
) -> fmi2Status {
    with_instance(c, "fmi2SetInteger", |i| {
        let vr = slice(vr, nvr, "vr")?;
        let value = slice(value, nvr, "value")?;
        i.set_integer(vr, value)
    })
}

/// fmi2SetBoolean: this FMU has no Boolean variables.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    with_instance(c, "fmi2SetBoolean", |i| {
        let vr = slice(vr, nvr, "vr")?;
        slice(value, nvr, "value")?;
        i.set_none("fmi2SetBoolean", "Boolean", vr)
    })
}

/// fmi2SetString: this FMU has no String variables.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2String,
) -> fmi2Status {
    with_instance(c, "fmi2SetString", |i| {
        let vr = slice(vr, nvr, "vr")?;
        slice(value, nvr, "value")?;
        i.set_none("fmi2SetString", "String", vr)
    })
}

/// fmi2GetFMUstate: the state as data (reuses *FMUstate when it is not NULL).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(
    c: fmi2Component,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    with_instance(c, "fmi2GetFMUstate", |i| {
        if FMUstate.is_null() {
            return Err(null("FMUstate"));
        }
        let s = i.get_fmu_state()?;
        put_state(FMUstate, s);
        Ok(())
    })
}

/// fmi2SetFMUstate.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: fmi2Component, FMUstate: fmi2FMUstate) -> fmi2Status {
    with_instance(c, "fmi2SetFMUstate", |i| {
        i.set_fmu_state(state_ref(FMUstate)?)
    })
}

/// fmi2FreeFMUstate: *FMUstate = NULL is ignored.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(
    c: fmi2Component,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    with_instance(c, "fmi2FreeFMUstate", |i| {
        if FMUstate.is_null() {
            return Err(null("FMUstate"));
        }
        i.free_fmu_state()?;
        if !(*FMUstate).is_null() {
            drop(Box::from_raw(*FMUstate as *mut FmuState));
            *FMUstate = std::ptr::null_mut();
        }
        Ok(())
    })
}

/// fmi2SerializedFMUstateSize.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    with_instance(c, "fmi2SerializedFMUstateSize", |i| {
        if size.is_null() {
            return Err(null("size"));
        }
        *size = i.serialize_fmu_state(state_ref(FMUstate)?)?.len();
        Ok(())
    })
}

/// fmi2SerializeFMUstate.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    serializedState: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    with_instance(c, "fmi2SerializeFMUstate", |i| {
        let bytes = i.serialize_fmu_state(state_ref(FMUstate)?)?;
        if size < bytes.len() {
            return Err(FmiError::Invalid(format!(
                "the buffer holds {size} bytes but the state needs {} (fmi2SerializedFMUstateSize)",
                bytes.len()
            )));
        }
        let out = slice_mut(serializedState as *mut u8, bytes.len(), "serializedState")?;
        out.copy_from_slice(&bytes);
        Ok(())
    })
}

/// fmi2DeSerializeFMUstate: checks the header (magic, version, GUID).
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    serializedState: *const fmi2Byte,
    size: usize,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    with_instance(c, "fmi2DeSerializeFMUstate", |i| {
        if FMUstate.is_null() {
            return Err(null("FMUstate"));
        }
        let bytes = slice(serializedState as *const u8, size, "serializedState")?;
        let s = i.deserialize_fmu_state(bytes)?;
        put_state(FMUstate, s);
        Ok(())
    })
}

/// fmi2GetDirectionalDerivative: not supported (providesDirectionalDerivative is false).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    vUnknown_ref: *const fmi2ValueReference,
    nUnknown: usize,
    vKnown_ref: *const fmi2ValueReference,
    nKnown: usize,
    dvKnown: *const fmi2Real,
    dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    let _ = (
        vUnknown_ref,
        nUnknown,
        vKnown_ref,
        nKnown,
        dvKnown,
        dvUnknown,
    );
    with_instance(c, "fmi2GetDirectionalDerivative", |_| {
        Err(Instance::unsupported(
            "fmi2GetDirectionalDerivative",
            "the particle model provides no directional derivatives (providesDirectionalDerivative is false)",
        ))
    })
}

// ---------------------------------------------------------------------------------------------
// Co-simulation functions.

/// fmi2SetRealInputDerivatives: first derivatives of the inputs for the next step (canInterpolateInputs).
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    with_instance(c, "fmi2SetRealInputDerivatives", |i| {
        let vr = slice(vr, nvr, "vr")?;
        let order = slice(order, nvr, "order")?;
        let value = slice(value, nvr, "value")?;
        i.set_real_input_derivatives(vr, order, value)
    })
}

/// fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder = 0).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *mut fmi2Real,
) -> fmi2Status {
    let _ = (vr, nvr, order, value);
    with_instance(c, "fmi2GetRealOutputDerivatives", |_| {
        Err(Instance::unsupported(
            "fmi2GetRealOutputDerivatives",
            "output derivatives are not provided (maxOutputDerivativeOrder = 0)",
        ))
    })
}

/// fmi2DoStep: synchronous; lands exactly on currentCommunicationPoint + communicationStepSize.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: fmi2Component,
    currentCommunicationPoint: fmi2Real,
    communicationStepSize: fmi2Real,
    noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
) -> fmi2Status {
    let _ = noSetFMUStatePriorToCurrentPoint;
    with_instance(c, "fmi2DoStep", |i| {
        i.do_step(currentCommunicationPoint, communicationStepSize)
    })
}

/// fmi2CancelStep. FMI 2.0 defines it for a doStep that returned fmi2Pending, which this FMU
/// never returns (doStep is synchronous), and does not require an instance to accept calls from
/// two threads at once. The closest useful thing: called from another thread while a set-up
/// runs (fmi2EnterInitializationMode, or fmi2ExitInitializationMode after parameter changes),
/// it asks the set-up to stop (at its next stage boundary, or within an iteration of the
/// closure's solves, the longest stage) and returns fmi2OK at once, without
/// waiting for the instance; the set-up's call then returns fmi2Error ("stopped ...") and the
/// instance stays in the state it was in. A doStep cannot be stopped (its work is bounded by
/// solver.max_steps): fmi2Error, at once as well. With no call running: fmi2Error.
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
    if c.is_null() {
        return fmi2Status::fmi2Error;
    }
    // c came from fmi2Instantiate (caller's contract).
    let comp = &*(c as *const Component);
    let owner = comp.owner.load(Ordering::SeqCst);
    if owner == 0 || owner == thread_id() {
        return guard(comp, "fmi2CancelStep", |i| i.cancel_step());
    }
    let r = catch_unwind(AssertUnwindSafe(|| {
        if comp.setup.cancel() {
            fmi2Status::fmi2OK
        } else {
            comp.logger.log(
                Status::Error,
                "logStatusError",
                "fmi2CancelStep: the call running on another thread is not a set-up and cannot be \
                 stopped (a doStep's work is bounded by solver.max_steps)",
            );
            fmi2Status::fmi2Error
        }
    }));
    r.unwrap_or(fmi2Status::fmi2Fatal)
}

/// fmi2GetStatus: fmi2Discard (only meaningful after fmi2Pending, which never happens).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Status,
) -> fmi2Status {
    with_instance(c, "fmi2GetStatus", |i| {
        if value.is_null() {
            return Err(null("value"));
        }
        *value = i.get_status(s)?.into();
        Ok(())
    })
}

/// fmi2GetRealStatus: fmi2LastSuccessfulTime.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Real,
) -> fmi2Status {
    with_instance(c, "fmi2GetRealStatus", |i| {
        if value.is_null() {
            return Err(null("value"));
        }
        *value = i.get_real_status(s)?;
        Ok(())
    })
}

/// fmi2GetIntegerStatus: fmi2Discard (no Integer status kinds).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Integer,
) -> fmi2Status {
    with_instance(c, "fmi2GetIntegerStatus", |i| {
        if value.is_null() {
            return Err(null("value"));
        }
        *value = i.get_integer_status(s)?;
        Ok(())
    })
}

/// fmi2GetBooleanStatus: fmi2Terminated (always false).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    with_instance(c, "fmi2GetBooleanStatus", |i| {
        if value.is_null() {
            return Err(null("value"));
        }
        *value = i.get_boolean_status(s)? as fmi2Boolean;
        Ok(())
    })
}

/// fmi2GetStringStatus: fmi2Discard (no step is ever pending).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2String,
) -> fmi2Status {
    with_instance(c, "fmi2GetStringStatus", |i| {
        if value.is_null() {
            return Err(null("value"));
        }
        i.get_string_status(s).map(|_| ())
    })
}

/// The worker pool of an instance made by fmi2Instantiate: its own threads
/// ([`threads::InstanceThreads`]), which nothing outlives.
fn instance_pool(name: &str) -> Result<WorkerPool, String> {
    let t = threads::InstanceThreads::start(name, instance_threads())?;
    Ok(WorkerPool::with_executor(Box::new(t)))
}

mod threads;

#[cfg(test)]
mod tests;
