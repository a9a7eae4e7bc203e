//! Acts as a C host: loads the built cdylib (target/<profile>/libmps_solid.so) with libloading
//! and calls the exported fmi2* functions like an FMI 2.0 master, with a variadic C logger
//! (tests/c/logger_shim.c, compiled with the system C compiler) capturing every message.
#![allow(non_snake_case)]

mod common;

use libloading::Library;
use mps_solid::fmi::model_description::guid;
use mps_solid::fmi::variables::VariableTable;
use mps_solid::Scene;
use std::ffi::{c_char, c_int, c_uint, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::{null, null_mut};
use std::sync::{Mutex, OnceLock, RwLock};

const OK: c_int = 0;
const DISCARD: c_int = 2;
const ERROR: c_int = 3;
const FATAL: c_int = 4;
const CS: c_int = 1;

type Comp = *mut c_void;
type Vr = c_uint;

#[repr(C)]
#[derive(Clone, Copy)]
struct Callbacks {
    logger: *const c_void,
    allocate: *const c_void,
    free: *const c_void,
    step_finished: *const c_void,
    env: *mut c_void,
}

macro_rules! api {
    ($($name:ident : fn($($a:ty),*) $(-> $r:ty)?;)*) => {
        #[allow(dead_code)]
        struct Api {
            _lib: Library,
            $($name: unsafe extern "C" fn($($a),*) $(-> $r)?,)*
        }
        impl Api {
            fn load(path: &Path) -> Api {
                unsafe {
                    let lib = Library::new(path).unwrap_or_else(|e| panic!("cannot load {}: {e}", path.display()));
                    $(let $name = *lib
                        .get::<unsafe extern "C" fn($($a),*) $(-> $r)?>(concat!(stringify!($name), "\0").as_bytes())
                        .unwrap_or_else(|e| panic!("symbol {} missing: {e}", stringify!($name)));)*
                    Api { _lib: lib, $($name,)* }
                }
            }
        }
    };
}

api! {
    fmi2GetTypesPlatform: fn() -> *const c_char;
    fmi2GetVersion: fn() -> *const c_char;
    fmi2SetDebugLogging: fn(Comp, c_int, usize, *const *const c_char) -> c_int;
    fmi2Instantiate: fn(*const c_char, c_int, *const c_char, *const c_char, *const Callbacks, c_int, c_int) -> Comp;
    fmi2FreeInstance: fn(Comp);
    fmi2SetupExperiment: fn(Comp, c_int, f64, f64, c_int, f64) -> c_int;
    fmi2EnterInitializationMode: fn(Comp) -> c_int;
    fmi2ExitInitializationMode: fn(Comp) -> c_int;
    fmi2Terminate: fn(Comp) -> c_int;
    fmi2Reset: fn(Comp) -> c_int;
    fmi2GetReal: fn(Comp, *const Vr, usize, *mut f64) -> c_int;
    fmi2GetInteger: fn(Comp, *const Vr, usize, *mut c_int) -> c_int;
    fmi2GetBoolean: fn(Comp, *const Vr, usize, *mut c_int) -> c_int;
    fmi2GetString: fn(Comp, *const Vr, usize, *mut *const c_char) -> c_int;
    fmi2SetReal: fn(Comp, *const Vr, usize, *const f64) -> c_int;
    fmi2SetInteger: fn(Comp, *const Vr, usize, *const c_int) -> c_int;
    fmi2SetBoolean: fn(Comp, *const Vr, usize, *const c_int) -> c_int;
    fmi2SetString: fn(Comp, *const Vr, usize, *const *const c_char) -> c_int;
    fmi2GetFMUstate: fn(Comp, *mut *mut c_void) -> c_int;
    fmi2SetFMUstate: fn(Comp, *mut c_void) -> c_int;
    fmi2FreeFMUstate: fn(Comp, *mut *mut c_void) -> c_int;
    fmi2SerializedFMUstateSize: fn(Comp, *mut c_void, *mut usize) -> c_int;
    fmi2SerializeFMUstate: fn(Comp, *mut c_void, *mut c_char, usize) -> c_int;
    fmi2DeSerializeFMUstate: fn(Comp, *const c_char, usize, *mut *mut c_void) -> c_int;
    fmi2GetDirectionalDerivative: fn(Comp, *const Vr, usize, *const Vr, usize, *const f64, *mut f64) -> c_int;
    fmi2SetRealInputDerivatives: fn(Comp, *const Vr, usize, *const c_int, *const f64) -> c_int;
    fmi2GetRealOutputDerivatives: fn(Comp, *const Vr, usize, *const c_int, *mut f64) -> c_int;
    fmi2DoStep: fn(Comp, f64, f64, c_int) -> c_int;
    fmi2CancelStep: fn(Comp) -> c_int;
    fmi2GetStatus: fn(Comp, c_int, *mut c_int) -> c_int;
    fmi2GetRealStatus: fn(Comp, c_int, *mut f64) -> c_int;
    fmi2GetIntegerStatus: fn(Comp, c_int, *mut c_int) -> c_int;
    fmi2GetBooleanStatus: fn(Comp, c_int, *mut c_int) -> c_int;
    fmi2GetStringStatus: fn(Comp, c_int, *mut *const c_char) -> c_int;
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Compiles the variadic logger shim once per process.
fn shim() -> &'static Library {
    static SHIM: OnceLock<Library> = OnceLock::new();
    SHIM.get_or_init(|| {
        let out = std::env::temp_dir().join(format!("mps-fmi-shim-{}.so", std::process::id()));
        let status = std::process::Command::new("cc")
            .args(["-shared", "-fPIC", "-O1", "-Wall", "-Werror", "-I"])
            .arg(root().join("vendor/fmi2"))
            .arg(root().join("tests/c/logger_shim.c"))
            .arg("-o")
            .arg(&out)
            .status()
            .expect("run cc");
        assert!(status.success(), "compiling the logger shim failed");
        let lib = unsafe { Library::new(&out).unwrap() };
        unsafe {
            let set: libloading::Symbol<unsafe extern "C" fn(*const c_void)> =
                lib.get(b"shim_set_sink\0").unwrap();
            set(sink as *const c_void);
        }
        std::fs::remove_file(&out).ok();
        lib
    })
}

fn logger_ptr() -> *const c_void {
    unsafe {
        let f: libloading::Symbol<*const c_void> = shim().get(b"shim_logger\0").unwrap();
        *f
    }
}

/// Messages logged to one instance: (status, category, message, instance name).
#[derive(Default, Debug)]
struct Log(
    Mutex<Vec<(c_int, String, String, String)>>,
    /// When set: the component the logger calls back into (fmi2GetReal) on every message.
    std::sync::atomic::AtomicPtr<c_void>,
);

unsafe extern "C" fn sink(
    env: *mut c_void,
    name: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    let log = &*(env as *const Log);
    let s = |p: *const c_char| {
        if p.is_null() {
            "<NULL>".to_string()
        } else {
            CStr::from_ptr(p).to_string_lossy().into_owned()
        }
    };
    log.0
        .lock()
        .unwrap()
        .push((status, s(category), s(message), s(name)));
    let c = log.1.load(std::sync::atomic::Ordering::SeqCst);
    if !c.is_null() {
        // A logger that reads a value of the same instance while the message is delivered.
        let vr: Vr = 0;
        let mut x = 0.0;
        let st = (api().fmi2GetReal)(c, &vr, 1, &mut x);
        log.0
            .lock()
            .unwrap()
            .push((st, "reentered".into(), format!("{x}"), s(name)));
    }
}

impl Log {
    fn last(&self) -> (c_int, String, String) {
        let v = self.0.lock().unwrap();
        let l = v.last().expect("a logged message");
        (l.0, l.1.clone(), l.2.clone())
    }
    fn len(&self) -> usize {
        self.0.lock().unwrap().len()
    }
    fn all(&self) -> String {
        self.0
            .lock()
            .unwrap()
            .iter()
            .map(|m| format!("{m:?}\n"))
            .collect()
    }
}

fn api() -> &'static Api {
    static API: OnceLock<Api> = OnceLock::new();
    API.get_or_init(|| Api::load(&common::built_library()))
}

/// Tests that count threads take this lock for writing; all others for reading.
static PROCESS: RwLock<()> = RwLock::new(());

fn shared() -> std::sync::RwLockReadGuard<'static, ()> {
    PROCESS.read().unwrap_or_else(|e| e.into_inner())
}

/// An unpacked FMU directory (resources/scene.json) of a tests/data scene.
struct Unpacked {
    dir: PathBuf,
    scene: Scene,
}

impl Unpacked {
    fn new(scene_file: &str, tag: &str) -> Unpacked {
        let scene = Scene::load(&root().join("tests/data").join(scene_file)).unwrap();
        Self::from_scene(scene, tag)
    }
    fn from_scene(scene: Scene, tag: &str) -> Unpacked {
        let dir = std::env::temp_dir().join(format!(
            "mps-fmi-host-{}-{tag}-{}",
            std::process::id(),
            scene.name
        ));
        std::fs::create_dir_all(dir.join("resources")).unwrap();
        std::fs::write(dir.join("resources/scene.json"), scene.to_json()).unwrap();
        Unpacked { dir, scene }
    }
    fn uri(&self) -> String {
        format!("file://{}/resources", self.dir.display())
    }
    fn guid(&self) -> String {
        guid(&self.scene)
    }
    fn vr(&self, name: &str) -> Vr {
        VariableTable::new(&self.scene)
            .by_name(name)
            .unwrap_or_else(|| panic!("no variable {name}"))
            .value_reference
    }
}

impl Drop for Unpacked {
    fn drop(&mut self) {
        std::fs::remove_dir_all(&self.dir).ok();
    }
}

/// One instance with its log.
struct Inst {
    c: Comp,
    log: Box<Log>,
}

unsafe impl Send for Inst {}

impl Inst {
    fn new(u: &Unpacked) -> Inst {
        Self::with(u, &u.guid(), &u.uri(), true).expect("instantiate")
    }
    fn with(u: &Unpacked, guid: &str, uri: &str, logger: bool) -> Result<Inst, Box<Log>> {
        let _ = u;
        let log = Box::<Log>::default();
        let cb = Callbacks {
            logger: if logger { logger_ptr() } else { null() },
            allocate: null(),
            free: null(),
            step_finished: null(),
            env: &*log as *const Log as *mut c_void,
        };
        let (name, g, uri) = (cstr("inst"), cstr(guid), cstr(uri));
        let c = unsafe {
            (api().fmi2Instantiate)(name.as_ptr(), CS, g.as_ptr(), uri.as_ptr(), &cb, 0, 0)
        };
        if c.is_null() {
            Err(log)
        } else {
            Ok(Inst { c, log })
        }
    }
    fn init(&self, stop: Option<f64>) {
        unsafe {
            assert_eq!(
                (api().fmi2SetupExperiment)(
                    self.c,
                    0,
                    0.0,
                    0.0,
                    stop.is_some() as c_int,
                    stop.unwrap_or(0.0)
                ),
                OK
            );
            assert_eq!(
                (api().fmi2EnterInitializationMode)(self.c),
                OK,
                "{}",
                self.log.all()
            );
            assert_eq!(
                (api().fmi2ExitInitializationMode)(self.c),
                OK,
                "{}",
                self.log.all()
            );
        }
    }
    fn real(&self, vr: &[Vr]) -> Vec<f64> {
        let mut v = vec![f64::NAN; vr.len()];
        let s = unsafe { (api().fmi2GetReal)(self.c, vr.as_ptr(), vr.len(), v.as_mut_ptr()) };
        assert_eq!(s, OK, "{}", self.log.all());
        v
    }
    fn int(&self, vr: &[Vr]) -> Vec<c_int> {
        let mut v = vec![-1; vr.len()];
        let s = unsafe { (api().fmi2GetInteger)(self.c, vr.as_ptr(), vr.len(), v.as_mut_ptr()) };
        assert_eq!(s, OK, "{}", self.log.all());
        v
    }
    fn set(&self, vr: &[Vr], v: &[f64]) -> c_int {
        unsafe { (api().fmi2SetReal)(self.c, vr.as_ptr(), vr.len(), v.as_ptr()) }
    }
    fn step(&self, t: f64, h: f64) -> c_int {
        unsafe { (api().fmi2DoStep)(self.c, t, h, 1) }
    }
    /// Asserts an error status and that the last logged message contains `needle`.
    fn expect_err(&self, status: c_int, needle: &str) {
        assert_eq!(
            status,
            ERROR,
            "expected fmi2Error; log:\n{}",
            self.log.all()
        );
        let (s, cat, msg) = self.log.last();
        assert_eq!(s, ERROR, "{msg}");
        assert_eq!(cat, "logStatusError");
        assert!(msg.contains(needle), "'{msg}' does not contain '{needle}'");
    }
}

impl Drop for Inst {
    fn drop(&mut self) {
        unsafe { (api().fmi2FreeInstance)(self.c) };
    }
}

fn cstr(s: &str) -> CString {
    CString::new(s).unwrap()
}

/// All Real outputs of a scene, in table order.
fn real_outputs(u: &Unpacked) -> Vec<Vr> {
    VariableTable::new(&u.scene)
        .vars
        .iter()
        .filter(|v| v.causality == mps_solid::fmi::variables::Causality::Output)
        .filter(|v| v.ty == mps_solid::fmi::variables::VarType::Real)
        .map(|v| v.value_reference)
        .collect()
}

#[test]
fn platform_and_version() {
    let _g = shared();
    unsafe {
        assert_eq!(
            CStr::from_ptr((api().fmi2GetTypesPlatform)())
                .to_str()
                .unwrap(),
            "default"
        );
        assert_eq!(
            CStr::from_ptr((api().fmi2GetVersion)()).to_str().unwrap(),
            "2.0"
        );
    }
}

#[test]
fn normal_sequence_3d() {
    let _g = shared();
    let u = Unpacked::new("small3d.json", "normal");
    let i = Inst::new(&u);
    let (uz, ux, steps, ke, rz) = (
        u.vr("tip.uz"),
        u.vr("tip.ux"),
        u.vr("steps"),
        u.vr("kinetic_energy"),
        u.vr("clamp.reaction_z"),
    );
    unsafe {
        assert_eq!((api().fmi2SetupExperiment)(i.c, 1, 1e-6, 0.0, 1, 0.2), OK);
        assert_eq!((api().fmi2EnterInitializationMode)(i.c), OK);
    }
    // Initial outputs: the reference state.
    assert_eq!(i.real(&[uz, ux, ke]), vec![0.0; 3]);
    assert!(
        i.real(&[rz])[0].abs() < 1e-9,
        "reference state: no reaction but round-off"
    );
    assert_eq!(i.int(&[steps, u.vr("fracture_count")]), vec![0, 0]);
    assert_eq!(
        i.real(&[u.vr("gravity_z"), u.vr("beam.young")]),
        vec![-9.81, 1e6]
    );
    unsafe { assert_eq!((api().fmi2ExitInitializationMode)(i.c), OK) };
    let h = 0.002;
    for k in 0..50 {
        assert_eq!(i.step(k as f64 * h, h), OK, "{}", i.log.all());
    }
    let v = i.real(&[uz, ke, rz]);
    assert!(v[0] < 0.0 && v[0] > -0.1, "tip deflection {}", v[0]);
    assert!(v[1] > 0.0);
    assert!(
        v[2] > 0.0,
        "the clamp holds the beam up: reaction_z {}",
        v[2]
    );
    assert!(i.int(&[steps])[0] >= 50);
    let mut t = 0.0;
    unsafe {
        assert_eq!((api().fmi2GetRealStatus)(i.c, 2, &mut t), OK);
        assert_eq!(t, 49.0 * h + h);
        let mut term = -1;
        assert_eq!((api().fmi2GetBooleanStatus)(i.c, 3, &mut term), OK);
        assert_eq!(term, 0);
        assert_eq!((api().fmi2Terminate)(i.c), OK);
    }
    // Values stay readable after termination.
    assert_eq!(i.real(&[uz])[0], v[0]);
}

#[test]
fn normal_sequence_2d_with_prescribed_motion_and_load() {
    let _g = shared();
    let u = Unpacked::new("small2d.json", "normal");
    let table = VariableTable::new(&u.scene);
    assert!(table.by_name("tip.uz").is_none() && table.by_name("gravity_z").is_none());
    assert!(table.by_name("holder.dz").is_none() && table.by_name("tip_load.fz").is_none());
    let i = Inst::new(&u);
    i.init(None);
    let (gx, gy, dx, fy) = (
        u.vr("gravity_x"),
        u.vr("gravity_y"),
        u.vr("holder.dx"),
        u.vr("tip_load.fy"),
    );
    assert_eq!(i.set(&[gx, gy, dx], &[0.0, 0.0, 0.001]), OK);
    assert_eq!(i.real(&[dx, gy]), vec![0.001, 0.0]);
    let h = 0.002;
    assert_eq!(i.step(0.0, h), OK);
    // The group reaches the displacement set before the step at its end; the body follows.
    let (tip_ux, mid_uy, rx) = (u.vr("tip.ux"), u.vr("mid.uy"), u.vr("holder.reaction_x"));
    assert!(i.real(&[rx])[0] != 0.0);
    for k in 1..40 {
        assert_eq!(i.step(k as f64 * h, h), OK);
    }
    let ux = i.real(&[tip_ux])[0];
    assert!(ux > 0.0 && ux < 0.003, "tip ux {ux}");
    let uy = i.real(&[mid_uy])[0];
    // Not exactly 0: the probe sits on the axis between two rows of particles and is
    // interpolated from one side, from a fit of the Poisson contraction (antisymmetric in y,
    // -7e-5 m at the rows beside the axis, symmetric to 5e-9 relative). With the holder's face
    // found from the geometry (issue 24) the default operator reads 1.45 % of the tip's ux
    // there (the rigid grip before: below 1 %); bending under gravity would be 30 times that.
    assert!(
        uy.abs() < 2e-2 * ux,
        "no gravity, no load: no bending (mid uy {uy}, tip ux {ux})"
    );
    assert_eq!(i.set(&[fy], &[-5.0]), OK);
    for k in 40..80 {
        assert_eq!(i.step(k as f64 * h, h), OK);
    }
    assert!(
        i.real(&[u.vr("tip.uy")])[0] < -1e-5,
        "the tip load bends the strip down"
    );
}

#[test]
fn gravity_source_is_explicit() {
    // Issue 8.9: the scene's gravity law (the Eq. (46) ramp of small3d) is not dropped because an
    // input differs bitwise from its start value (-0.0, fmpy's interpolated -9.809999999999999):
    // the parameter gravity_source selects the law (1, the default of a scene with a ramp) or the
    // inputs (2); with 1, setting the inputs to other values is logged as ignored.
    let _g = shared();
    let u = Unpacked::new("small3d.json", "gravity");
    let (uz, gx, gz, src) = (
        u.vr("tip.uz"),
        u.vr("gravity_x"),
        u.vr("gravity_z"),
        u.vr("gravity_source"),
    );
    let run = |source: Option<c_int>, set: &[(Vr, f64)]| {
        let i = Inst::new(&u);
        if let Some(s) = source {
            assert_eq!(
                unsafe { (api().fmi2SetInteger)(i.c, &src, 1, &s) },
                OK,
                "{}",
                i.log.all()
            );
        }
        let mut v = 0;
        i.init(None);
        assert_eq!(unsafe { (api().fmi2GetInteger)(i.c, &src, 1, &mut v) }, OK);
        for (k, &(r, x)) in set.iter().enumerate() {
            assert_eq!(i.set(&[r], &[x]), OK, "set #{k}");
        }
        for k in 0..10 {
            assert_eq!(i.step(k as f64 * 0.002, 0.002), OK);
        }
        (v, i.real(&[uz])[0], i.log.all())
    };
    let (v, ramp, _) = run(None, &[]);
    assert_eq!(v, 1, "a scene with a ramp defaults to its own law");
    for set in [
        vec![(gx, -0.0)],
        vec![(gz, -9.809999999999999)],
        vec![(gz, -9.81), (gx, -0.0)],
    ] {
        let (_, x, log) = run(None, &set);
        assert_eq!(x.to_bits(), ramp.to_bits(), "{set:?} changed the ramp");
        let warned = log.contains("gravity inputs are ignored");
        assert_eq!(
            warned,
            set.iter().any(|&(r, x)| r == gz && x != -9.81),
            "{set:?}: {log}"
        );
    }
    // gravity_source = 2: the inputs, held: the full value at once deflects more than the ramp.
    let (v, sudden, _) = run(Some(2), &[]);
    assert_eq!(v, 2);
    assert!(sudden < ramp, "sudden {sudden} vs ramp {ramp}");
    let (_, same, _) = run(Some(2), &[(gx, -0.0), (gz, -9.81)]);
    assert_eq!(
        same.to_bits(),
        sudden.to_bits(),
        "-0.0 and 0.0 are the same gravity"
    );
    // Other values are refused, naming the variable.
    let i = Inst::new(&u);
    i.expect_err(
        unsafe { (api().fmi2SetInteger)(i.c, &src, 1, &3) },
        "'gravity_source' (value reference",
    );
}

#[test]
#[ignore = "slow (7 s on a loaded 2-core machine): the full test command runs it"]
fn parameters_before_and_during_initialisation() {
    let _g = shared();
    let u = Unpacked::new("small3d.json", "params");
    let (young, uz) = (u.vr("beam.young"), u.vr("tip.uz"));
    let run = |e: Option<f64>, during_init: bool| {
        let i = Inst::new(&u);
        unsafe { assert_eq!((api().fmi2SetupExperiment)(i.c, 0, 0.0, 0.0, 0, 0.0), OK) };
        if let (Some(e), false) = (e, during_init) {
            assert_eq!(i.set(&[young], &[e]), OK);
        }
        unsafe { assert_eq!((api().fmi2EnterInitializationMode)(i.c), OK) };
        if let (Some(e), true) = (e, during_init) {
            assert_eq!(i.set(&[young], &[e]), OK);
            assert_eq!(i.real(&[young])[0], e);
        }
        unsafe { assert_eq!((api().fmi2ExitInitializationMode)(i.c), OK) };
        for k in 0..40 {
            assert_eq!(i.step(k as f64 * 0.002, 0.002), OK);
        }
        // Parameters are fixed once initialisation is over.
        i.expect_err(i.set(&[young], &[1e7]), "fixed parameter");
        i.real(&[uz])[0]
    };
    let soft = run(None, false);
    let stiff = run(Some(4e6), false);
    assert!(stiff.abs() < 0.8 * soft.abs(), "stiff {stiff} soft {soft}");
    assert_eq!(run(Some(4e6), true).to_bits(), stiff.to_bits());
}

#[test]
fn wrong_call_order() {
    let _g = shared();
    let u = Unpacked::new("small3d.json", "order");
    let i = Inst::new(&u);
    let a = api();
    let uz = u.vr("tip.uz");
    let mut x = 0.0;
    let mut st: *mut c_void = null_mut();
    unsafe {
        // Instantiated.
        i.expect_err((a.fmi2DoStep)(i.c, 0.0, 0.01, 1), "illegal call sequence");
        i.expect_err(
            (a.fmi2GetReal)(i.c, &uz, 1, &mut x),
            "illegal call sequence",
        );
        i.expect_err((a.fmi2ExitInitializationMode)(i.c), "illegal call sequence");
        i.expect_err((a.fmi2Terminate)(i.c), "illegal call sequence");
        // FMI 2.0 allows fmi2GetFMUstate right after instantiation.
        assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK, "{}", i.log.all());
        assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
        i.expect_err(
            (a.fmi2GetRealStatus)(i.c, 2, &mut x),
            "illegal call sequence",
        );
        assert_eq!((a.fmi2EnterInitializationMode)(i.c), OK);
        // Initialization mode.
        i.expect_err(
            (a.fmi2EnterInitializationMode)(i.c),
            "illegal call sequence",
        );
        i.expect_err(
            (a.fmi2SetupExperiment)(i.c, 0, 0.0, 0.0, 0, 0.0),
            "illegal call sequence",
        );
        i.expect_err((a.fmi2DoStep)(i.c, 0.0, 0.01, 1), "illegal call sequence");
        i.expect_err((a.fmi2Terminate)(i.c), "illegal call sequence");
        assert_eq!((a.fmi2ExitInitializationMode)(i.c), OK);
        // Step complete.
        i.expect_err((a.fmi2ExitInitializationMode)(i.c), "illegal call sequence");
        i.expect_err(
            (a.fmi2EnterInitializationMode)(i.c),
            "illegal call sequence",
        );
        i.expect_err(
            (a.fmi2SetupExperiment)(i.c, 0, 0.0, 0.0, 0, 0.0),
            "illegal call sequence",
        );
        assert_eq!((a.fmi2DoStep)(i.c, 0.0, 0.01, 1), OK);
        assert_eq!((a.fmi2Terminate)(i.c), OK);
        // Terminated.
        i.expect_err((a.fmi2DoStep)(i.c, 0.01, 0.01, 1), "illegal call sequence");
        i.expect_err((a.fmi2Terminate)(i.c), "illegal call sequence");
        i.expect_err(i.set(&[u.vr("gravity_z")], &[1.0]), "illegal call sequence");
        i.expect_err(
            (a.fmi2EnterInitializationMode)(i.c),
            "illegal call sequence",
        );
        // Reset goes back to the start: the same run again gives the same numbers.
        let first = i.real(&[uz])[0];
        assert_eq!((a.fmi2Reset)(i.c), OK);
        i.expect_err(
            (a.fmi2GetReal)(i.c, &uz, 1, &mut x),
            "illegal call sequence",
        );
        i.init(None);
        assert_eq!(i.real(&[uz])[0], 0.0);
        assert_eq!((a.fmi2DoStep)(i.c, 0.0, 0.01, 1), OK);
        assert_eq!(i.real(&[uz])[0].to_bits(), first.to_bits());
    }
}

#[test]
fn do_step_arguments() {
    let _g = shared();
    let u = Unpacked::new("small3d.json", "dostep");
    let i = Inst::new(&u);
    i.init(Some(0.05));
    i.expect_err(i.step(0.0, 0.0), "communicationStepSize");
    i.expect_err(i.step(0.0, -0.01), "communicationStepSize");
    i.expect_err(i.step(0.0, f64::NAN), "communicationStepSize");
    i.expect_err(i.step(0.001, 0.01), "currentCommunicationPoint");
    i.expect_err(i.step(0.0, 0.06), "after stopTime");
    // Rejected calls change nothing: the run goes on. A step that does not divide the stop time
    // ends exactly on the stop time; the time never drifts.
    let h = 0.003;
    let mut t = 0.0;
    while t + h <= 0.05 {
        assert_eq!(i.step(t, h), OK);
        t += h;
    }
    assert_eq!(i.step(t, 0.05 - t), OK);
    let mut last = 0.0;
    unsafe { assert_eq!((api().fmi2GetRealStatus)(i.c, 2, &mut last), OK) };
    assert_eq!(last, t + (0.05 - t));
    i.expect_err(i.step(last, 0.001), "after stopTime");
    // A point within the tolerance (1e-9 relative) is accepted.
    let j = Inst::new(&u);
    j.init(None);
    assert_eq!(j.step(0.0, 0.01), OK);
    assert_eq!(j.step(0.01 + 1e-12, 0.01), OK);
}

#[test]
fn null_pointers() {
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small3d.json", "null");
    let vr: Vr = 0;
    let mut x = 0.0;
    let mut n: c_int = 0;
    unsafe {
        // NULL component: fmi2Error, no crash (there is no logger to tell).
        assert_eq!((a.fmi2EnterInitializationMode)(null_mut()), ERROR);
        assert_eq!((a.fmi2GetReal)(null_mut(), &vr, 1, &mut x), ERROR);
        assert_eq!((a.fmi2DoStep)(null_mut(), 0.0, 0.1, 0), ERROR);
        assert_eq!((a.fmi2SetDebugLogging)(null_mut(), 1, 0, null()), ERROR);
        assert_eq!((a.fmi2GetStatus)(null_mut(), 0, &mut n), ERROR);
        (a.fmi2FreeInstance)(null_mut());
        let i = Inst::new(&u);
        i.init(None);
        // nvr = 0 with NULL arrays is legal.
        assert_eq!((a.fmi2GetReal)(i.c, null(), 0, null_mut()), OK);
        assert_eq!((a.fmi2SetReal)(i.c, null(), 0, null()), OK);
        assert_eq!((a.fmi2GetInteger)(i.c, null(), 0, null_mut()), OK);
        assert_eq!((a.fmi2GetBoolean)(i.c, null(), 0, null_mut()), OK);
        assert_eq!((a.fmi2GetString)(i.c, null(), 0, null_mut()), OK);
        assert_eq!((a.fmi2SetInteger)(i.c, null(), 0, null()), OK);
        assert_eq!((a.fmi2SetBoolean)(i.c, null(), 0, null()), OK);
        assert_eq!((a.fmi2SetString)(i.c, null(), 0, null()), OK);
        i.expect_err((a.fmi2GetReal)(i.c, null(), 1, &mut x), "vr is NULL");
        i.expect_err((a.fmi2GetReal)(i.c, &vr, 1, null_mut()), "value is NULL");
        i.expect_err((a.fmi2SetReal)(i.c, null(), 2, &x), "vr is NULL");
        i.expect_err((a.fmi2SetReal)(i.c, &vr, 1, null()), "value is NULL");
        i.expect_err((a.fmi2GetInteger)(i.c, null(), 1, &mut n), "vr is NULL");
        i.expect_err(
            (a.fmi2SetDebugLogging)(i.c, 1, 2, null()),
            "categories is NULL",
        );
        let cats = [null::<c_char>()];
        i.expect_err(
            (a.fmi2SetDebugLogging)(i.c, 1, 1, cats.as_ptr()),
            "a category is NULL",
        );
        i.expect_err((a.fmi2GetFMUstate)(i.c, null_mut()), "FMUstate is NULL");
        i.expect_err((a.fmi2SetFMUstate)(i.c, null_mut()), "FMUstate is NULL");
        i.expect_err((a.fmi2FreeFMUstate)(i.c, null_mut()), "FMUstate is NULL");
        let mut none: *mut c_void = null_mut();
        assert_eq!(
            (a.fmi2FreeFMUstate)(i.c, &mut none),
            OK,
            "freeing *FMUstate = NULL is a no-op"
        );
        i.expect_err(
            (a.fmi2SerializedFMUstateSize)(i.c, null_mut(), &mut 0),
            "FMUstate is NULL",
        );
        i.expect_err(
            (a.fmi2DeSerializeFMUstate)(i.c, null(), 10, &mut none),
            "serializedState is NULL",
        );
        i.expect_err((a.fmi2GetRealStatus)(i.c, 2, null_mut()), "value is NULL");
        i.expect_err(
            (a.fmi2GetBooleanStatus)(i.c, 3, null_mut()),
            "value is NULL",
        );
        i.expect_err((a.fmi2GetStatus)(i.c, 0, null_mut()), "value is NULL");
        // Still alive and stepping.
        assert_eq!(i.step(0.0, 0.01), OK);
    }
    // NULL logger and NULL callbacks: the instance works, errors just are not reported.
    let quiet = Inst::with(&u, &u.guid(), &u.uri(), false).expect("NULL logger accepted");
    quiet.init(None);
    assert_eq!(quiet.set(&[999], &[1.0]), ERROR);
    assert_eq!(quiet.step(0.0, 0.01), OK);
    assert_eq!(quiet.log.len(), 0);
    unsafe {
        let (name, g, uri) = (cstr("nocb"), cstr(&u.guid()), cstr(&u.uri()));
        let c = (a.fmi2Instantiate)(name.as_ptr(), CS, g.as_ptr(), uri.as_ptr(), null(), 0, 1);
        assert!(!c.is_null());
        assert_eq!((a.fmi2EnterInitializationMode)(c), OK);
        assert_eq!((a.fmi2Terminate)(c), ERROR);
        (a.fmi2FreeInstance)(c);
        // NULL name and GUID: NULL, with a message.
        let log = Box::<Log>::default();
        let cb = Callbacks {
            logger: logger_ptr(),
            allocate: null(),
            free: null(),
            step_finished: null(),
            env: &*log as *const Log as *mut c_void,
        };
        assert!((a.fmi2Instantiate)(null(), CS, g.as_ptr(), uri.as_ptr(), &cb, 0, 0).is_null());
        assert!(log.last().2.contains("instanceName is NULL"));
        assert!((a.fmi2Instantiate)(name.as_ptr(), CS, null(), uri.as_ptr(), &cb, 0, 0).is_null());
        assert!(log.last().2.contains("fmuGUID is NULL"));
        assert!((a.fmi2Instantiate)(name.as_ptr(), CS, g.as_ptr(), null(), &cb, 0, 0).is_null());
        assert!(log.last().2.contains("fmuResourceLocation is NULL"));
    }
}

#[test]
fn unknown_value_references_and_types() {
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small3d.json", "vr");
    let i = Inst::new(&u);
    i.init(None);
    let mut x = [0.0; 2];
    let mut n = [0 as c_int; 2];
    let mut s = [null::<c_char>(); 1];
    unsafe {
        let bad = [u.vr("tip.uz"), 9999];
        i.expect_err(
            (a.fmi2GetReal)(i.c, bad.as_ptr(), 2, x.as_mut_ptr()),
            "unknown value reference 9999",
        );
        i.expect_err(
            (a.fmi2SetReal)(i.c, [9999].as_ptr(), 1, [1.0].as_ptr()),
            "unknown value reference 9999",
        );
        i.expect_err(
            (a.fmi2GetReal)(i.c, &u.vr("steps"), 1, x.as_mut_ptr()),
            "Integer variable, not Real",
        );
        i.expect_err(
            (a.fmi2GetInteger)(i.c, &u.vr("tip.uz"), 1, n.as_mut_ptr()),
            "Real variable, not Integer",
        );
        i.expect_err(
            (a.fmi2GetBoolean)(i.c, &0, 1, n.as_mut_ptr()),
            "no Boolean variables",
        );
        i.expect_err(
            (a.fmi2GetString)(i.c, &0, 1, s.as_mut_ptr()),
            "no String variables",
        );
        i.expect_err(
            (a.fmi2SetBoolean)(i.c, &0, 1, n.as_ptr()),
            "no Boolean variables",
        );
        i.expect_err(
            (a.fmi2SetString)(i.c, &0, 1, s.as_ptr()),
            "no String variables",
        );
        i.expect_err(
            (a.fmi2SetInteger)(i.c, &u.vr("steps"), 1, n.as_ptr()),
            "output and cannot be set",
        );
        i.expect_err(i.set(&[u.vr("tip.uz")], &[1.0]), "output and cannot be set");
    }
    assert_eq!(i.step(0.0, 0.01), OK);
}

#[test]
fn nan_and_infinite_inputs_are_rejected() {
    let _g = shared();
    let u = Unpacked::new("small3d.json", "nan");
    let i = Inst::new(&u);
    let (gz, fz, dz, rho) = (
        u.vr("gravity_z"),
        u.vr("tip_load.fz"),
        u.vr("clamp.dz"),
        u.vr("beam.density"),
    );
    i.expect_err(i.set(&[rho], &[f64::NAN]), "values must be finite");
    i.expect_err(
        i.set(&[rho], &[-1.0]),
        "material.density: must be in [0.001, 100000] kg/m3",
    );
    i.expect_err(
        i.set(&[u.vr("beam.poisson")], &[0.5]),
        "material.poisson: must be in [-0.999, 0.499]",
    );
    i.init(None);
    assert_eq!(i.real(&[rho])[0], 1000.0);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        // Nothing of a call with one bad value is applied.
        i.expect_err(i.set(&[fz, gz], &[5.0, bad]), "values must be finite");
        i.expect_err(i.set(&[dz], &[bad]), "values must be finite");
    }
    assert_eq!(i.real(&[gz, fz, dz]), vec![-9.81, 0.0, 0.0]);
    for k in 0..5 {
        assert_eq!(i.step(k as f64 * 0.002, 0.002), OK);
    }
    assert!(i.real(&real_outputs(&u)).iter().all(|x| x.is_finite()));
}

#[test]
fn instantiate_rejects_bad_guid_type_and_resources() {
    let _g = shared();
    let u = Unpacked::new("small3d.json", "inst");
    let fail = |guid: &str, uri: &str, needle: &str| {
        let log = Inst::with(&u, guid, uri, true)
            .err()
            .expect("instantiation must fail");
        let (s, cat, msg) = log.last();
        assert_eq!((s, cat.as_str()), (ERROR, "logStatusError"));
        assert!(msg.contains(needle), "'{msg}' does not contain '{needle}'");
    };
    fail(
        "{00000000-0000-0000-0000-000000000000}",
        &u.uri(),
        "GUID mismatch",
    );
    fail(
        &u.guid(),
        &format!("file://{}/nowhere", u.dir.display()),
        "cannot read the FMU's scene",
    );
    fail(
        &u.guid(),
        "http://example.com/resources",
        "not a local file URI",
    );
    fail(&u.guid(), "relative/resources", "not a local file URI");
    // The message is passed through "%s": a '%' in it arrives intact.
    fail(
        &u.guid(),
        "file:///tmp/%zz%s%n",
        "bad percent escape in 'file:///tmp/%zz%s%n'"
            .split(" in")
            .next()
            .unwrap(),
    );
    fail(&u.guid(), "file:///tmp/%zz%s%n", "file:///tmp/%zz%s%n");
    let bad = Unpacked::new("small3d.json", "malformed");
    std::fs::write(bad.dir.join("resources/scene.json"), "{ \"name\": ").unwrap();
    fail(&bad.guid(), &bad.uri(), "is invalid");
    // Model exchange is refused.
    unsafe {
        let log = Box::<Log>::default();
        let cb = Callbacks {
            logger: logger_ptr(),
            allocate: null(),
            free: null(),
            step_finished: null(),
            env: &*log as *const Log as *mut c_void,
        };
        let (name, g, uri) = (cstr("me"), cstr(&u.guid()), cstr(&u.uri()));
        assert!(
            (api().fmi2Instantiate)(name.as_ptr(), 0, g.as_ptr(), uri.as_ptr(), &cb, 0, 0)
                .is_null()
        );
        assert!(log.last().2.contains("Co-Simulation only"));
        assert_eq!(
            log.0.lock().unwrap().last().unwrap().3,
            "me",
            "the logger gets the instance name"
        );
    }
    // Percent-encoded paths, file:/ and file://localhost/ forms and a trailing '/' are read.
    let spaced = Unpacked::from_scene(u.scene.clone(), "a b%c");
    let enc = spaced
        .dir
        .display()
        .to_string()
        .replace('%', "%25")
        .replace(' ', "%20");
    for uri in [
        format!("file://{enc}/resources/"),
        format!("file:{enc}/resources"),
        format!("file://localhost{enc}/resources"),
    ] {
        let i = Inst::with(&spaced, &spaced.guid(), &uri, true)
            .unwrap_or_else(|l| panic!("{uri}: {}", l.all()));
        i.init(None);
    }
}

#[test]
fn fmu_state_roundtrip_is_bitwise() {
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small3d.json", "state");
    let outs = real_outputs(&u);
    let (fz, steps) = (u.vr("tip_load.fz"), u.vr("steps"));
    let i = Inst::new(&u);
    i.init(None);
    let h = 0.002;
    for k in 0..10 {
        assert_eq!(i.step(k as f64 * h, h), OK);
    }
    assert_eq!(i.set(&[fz], &[-3.0]), OK);
    let mut st: *mut c_void = null_mut();
    unsafe { assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK) };
    assert!(!st.is_null());
    let run = |inst: &Inst, from: usize| -> Vec<u64> {
        let mut v = Vec::new();
        for k in from..from + 10 {
            if k == from + 5 {
                assert_eq!(inst.set(&[fz], &[2.0]), OK);
            }
            assert_eq!(inst.step(k as f64 * h, h), OK);
            v.extend(inst.real(&outs).iter().map(|x| x.to_bits()));
            v.extend(inst.int(&[steps]).iter().map(|&x| x as u64));
        }
        v
    };
    let first = run(&i, 10);
    unsafe { assert_eq!((a.fmi2SetFMUstate)(i.c, st), OK) };
    assert_eq!(i.real(&[fz])[0], -3.0, "inputs are part of the state");
    let again = run(&i, 10);
    assert_eq!(first, again, "restored run differs");
    // Serialised, restored into a fresh instance: still bitwise the same.
    let mut size = 0usize;
    unsafe {
        assert_eq!((a.fmi2SerializedFMUstateSize)(i.c, st, &mut size), OK);
        let mut buf = vec![0 as c_char; size];
        i.expect_err(
            (a.fmi2SerializeFMUstate)(i.c, st, buf.as_mut_ptr(), size - 1),
            "needs",
        );
        assert_eq!(
            (a.fmi2SerializeFMUstate)(i.c, st, buf.as_mut_ptr(), size),
            OK
        );
        // Reusing an existing state handle is allowed (GetFMUstate overwrites it).
        assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK);
        assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
        assert!(st.is_null());
        let j = Inst::new(&u);
        j.init(None);
        let mut st2: *mut c_void = null_mut();
        assert_eq!(
            (a.fmi2DeSerializeFMUstate)(j.c, buf.as_ptr(), size, &mut st2),
            OK
        );
        assert_eq!((a.fmi2SetFMUstate)(j.c, st2), OK);
        assert_eq!((a.fmi2FreeFMUstate)(j.c, &mut st2), OK);
        assert_eq!(run(&j, 10), first, "deserialised run differs");
        // Corrupt or foreign data is refused with a message.
        let mut bad = buf.clone();
        bad[0] = b'X' as c_char;
        j.expect_err(
            (a.fmi2DeSerializeFMUstate)(j.c, bad.as_ptr(), size, &mut st2),
            "bad magic",
        );
        let mut bad = buf.clone();
        bad[8] = 99;
        j.expect_err(
            (a.fmi2DeSerializeFMUstate)(j.c, bad.as_ptr(), size, &mut st2),
            "format version",
        );
        j.expect_err(
            (a.fmi2DeSerializeFMUstate)(j.c, buf.as_ptr(), size / 2, &mut st2),
            "checksum mismatch",
        );
        let other = Unpacked::new("small2d.json", "state");
        let k = Inst::new(&other);
        k.init(None);
        k.expect_err(
            (a.fmi2DeSerializeFMUstate)(k.c, buf.as_ptr(), size, &mut st2),
            "another GUID",
        );
        assert!(st2.is_null());
    }
}

#[test]
fn solver_blow_up_is_an_error_with_finite_outputs() {
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small3d.json", "blowup");
    let outs = real_outputs(&u);
    let i = Inst::new(&u);
    unsafe { assert_eq!((a.fmi2EnterInitializationMode)(i.c), OK) };
    // A fixed step far above the stability limit.
    assert_eq!(i.set(&[u.vr("solver.dt")], &[0.005]), OK);
    unsafe { assert_eq!((a.fmi2ExitInitializationMode)(i.c), OK) };
    let mut st: *mut c_void = null_mut();
    unsafe { assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK) };
    let mut t = 0.0;
    let mut status = OK;
    while status == OK && t < 10.0 {
        status = i.step(t, 0.05);
        if status == OK {
            t += 0.05;
        }
    }
    i.expect_err(status, "blow-up");
    assert!(
        i.real(&outs).iter().all(|x| x.is_finite()),
        "outputs stay finite"
    );
    let mut last = -1.0;
    unsafe {
        assert_eq!((a.fmi2GetRealStatus)(i.c, 2, &mut last), OK);
        assert_eq!(last, t);
        i.expect_err((a.fmi2DoStep)(i.c, t, 0.05, 1), "illegal call sequence");
        // Restoring a state leaves the error state.
        assert_eq!((a.fmi2SetFMUstate)(i.c, st), OK);
        assert_eq!((a.fmi2DoStep)(i.c, 0.0, 0.001, 1), OK);
        assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
        assert_eq!((a.fmi2Reset)(i.c), OK);
    }
    i.init(None);
    assert_eq!(i.step(0.0, 0.05), OK);
}

#[test]
fn status_queries_and_unsupported_functions() {
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small3d.json", "status");
    let i = Inst::new(&u);
    i.init(None);
    let mut n: c_int = -1;
    let mut x = 0.0;
    let mut s: *const c_char = null();
    let vr: Vr = 0;
    unsafe {
        let discard = |st: c_int, needle: &str| {
            assert_eq!(st, DISCARD);
            let (ls, cat, msg) = i.log.last();
            assert_eq!((ls, cat.as_str()), (DISCARD, "logStatusWarning"));
            assert!(msg.contains(needle), "{msg}");
        };
        discard(
            (a.fmi2GetStatus)(i.c, 0, &mut n),
            "never returns fmi2Pending",
        );
        discard((a.fmi2GetIntegerStatus)(i.c, 0, &mut n), "not provided");
        discard((a.fmi2GetStringStatus)(i.c, 1, &mut s), "pending");
        discard(
            (a.fmi2GetRealStatus)(i.c, 0, &mut x),
            "only fmi2LastSuccessfulTime",
        );
        discard(
            (a.fmi2GetBooleanStatus)(i.c, 0, &mut n),
            "only fmi2Terminated",
        );
        i.expect_err((a.fmi2CancelStep)(i.c), "nothing to cancel");
        i.expect_err(
            (a.fmi2GetDirectionalDerivative)(i.c, &vr, 1, &vr, 1, &x, &mut x),
            "not supported",
        );
        i.expect_err(
            (a.fmi2SetRealInputDerivatives)(i.c, &vr, 1, &1, &x),
            "not an input",
        );
        i.expect_err(
            (a.fmi2GetRealOutputDerivatives)(i.c, &vr, 1, &1, &mut x),
            "not supported",
        );
        // Debug logging: categories from the model description; unknown ones refused.
        let ev = cstr("logEvents");
        let bad = cstr("logNothing");
        i.expect_err(
            (a.fmi2SetDebugLogging)(i.c, 1, 1, [bad.as_ptr()].as_ptr()),
            "unknown log category 'logNothing'",
        );
        assert_eq!(
            (a.fmi2SetDebugLogging)(i.c, 1, 1, [ev.as_ptr()].as_ptr()),
            OK
        );
        let before = i.log.len();
        let mut st: *mut c_void = null_mut();
        assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK);
        assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
        assert!(i.log.len() > before);
        let (ls, cat, _) = i.log.last();
        assert_eq!((ls, cat.as_str()), (OK, "logEvents"));
        assert_eq!((a.fmi2SetDebugLogging)(i.c, 0, 0, null()), OK);
        let before = i.log.len();
        assert_eq!((a.fmi2Reset)(i.c), OK);
        assert_eq!(i.log.len(), before, "logging off: no events");
    }
    let _ = FATAL;
}

/// Threads of this process named by FMU instances' pools ("fmu-<instance>-<k>").
fn fmu_threads() -> usize {
    std::fs::read_dir("/proc/self/task")
        .unwrap()
        .filter_map(|e| std::fs::read_to_string(e.ok()?.path().join("comm")).ok())
        .filter(|n| n.starts_with("fmu-"))
        .count()
}

/// Runs small3d for 20 steps with a tip load and returns every output's bits.
fn run_small3d(u: &Unpacked) -> Vec<u64> {
    let i = Inst::new(u);
    i.init(None);
    assert_eq!(i.set(&[u.vr("tip_load.fz")], &[-1.0]), OK);
    let outs = real_outputs(u);
    let mut v = Vec::new();
    for k in 0..20 {
        assert_eq!(i.step(k as f64 * 0.002, 0.002), OK);
        v.extend(i.real(&outs).iter().map(|x| x.to_bits()));
    }
    v
}

#[test]
fn instances_on_threads_and_no_thread_outlives_its_instance() {
    let _g = PROCESS.write().unwrap_or_else(|e| e.into_inner());
    let _ = (api(), logger_ptr());
    let u = Unpacked::new("small3d.json", "threads");
    // Only the instance's own (named) threads are counted: the process's total task count also
    // moves with the test harness's threads running other tests, so it cannot be compared.
    {
        let i = Inst::new(&u);
        // (a new thread takes its name once it runs)
        let mut named = 0;
        for _ in 0..200 {
            named = fmu_threads();
            if named >= 1 {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        assert!(
            named >= 1,
            "the worker threads are named fmu-<instance>-<k>"
        );
        i.init(None);
        assert_eq!(i.step(0.0, 0.01), OK);
    }
    assert_eq!(
        fmu_threads(),
        0,
        "fmi2FreeInstance joined every worker thread"
    );
    // Several instances in one process, one after the other and at the same time.
    let reference = run_small3d(&u);
    let a = Inst::new(&u);
    let b = Inst::new(&u);
    a.init(None);
    b.init(None);
    for k in 0..5 {
        assert_eq!(a.step(k as f64 * 0.01, 0.01), OK);
        assert_eq!(b.step(k as f64 * 0.01, 0.01), OK);
    }
    assert_eq!(a.real(&real_outputs(&u)), b.real(&real_outputs(&u)));
    drop((a, b));
    let results: Vec<Vec<u64>> = std::thread::scope(|s| {
        let hs: Vec<_> = (0..3).map(|_| s.spawn(|| run_small3d(&u))).collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for r in results {
        assert_eq!(
            r, reference,
            "concurrent instances give the sequential result"
        );
    }
    // A different scene at the same time as another.
    let u2 = Unpacked::new("small2d.json", "threads");
    std::thread::scope(|s| {
        let h = s.spawn(|| {
            let i = Inst::new(&u2);
            i.init(None);
            for k in 0..20 {
                assert_eq!(i.step(k as f64 * 0.002, 0.002), OK);
            }
        });
        assert_eq!(run_small3d(&u), reference);
        h.join().unwrap();
    });
    assert_eq!(fmu_threads(), 0, "no worker thread left");
}

#[test]
fn fmu_state_carries_its_parameters() {
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small3d.json", "stateparams");
    let (young, uz) = (u.vr("beam.young"), u.vr("tip.uz"));
    // Instance A: a stiffer beam, state captured after 10 steps, then 10 more.
    let stiff = Inst::new(&u);
    assert_eq!(stiff.set(&[young], &[3e6]), OK);
    stiff.init(None);
    for k in 0..10 {
        assert_eq!(stiff.step(k as f64 * 0.002, 0.002), OK);
    }
    let mut st: *mut c_void = null_mut();
    let mut size = 0usize;
    unsafe {
        assert_eq!((a.fmi2GetFMUstate)(stiff.c, &mut st), OK);
        assert_eq!((a.fmi2SerializedFMUstateSize)(stiff.c, st, &mut size), OK);
    }
    let mut buf = vec![0 as c_char; size];
    unsafe {
        assert_eq!(
            (a.fmi2SerializeFMUstate)(stiff.c, st, buf.as_mut_ptr(), size),
            OK
        )
    };
    for k in 10..20 {
        assert_eq!(stiff.step(k as f64 * 0.002, 0.002), OK);
    }
    let expected = stiff.real(&[uz])[0];
    // Instance B with the scene's parameters takes A's state: it is rebuilt with A's parameters.
    let other = Inst::new(&u);
    other.init(None);
    unsafe {
        let mut st2: *mut c_void = null_mut();
        assert_eq!(
            (a.fmi2DeSerializeFMUstate)(other.c, buf.as_ptr(), size, &mut st2),
            OK
        );
        assert_eq!((a.fmi2SetFMUstate)(other.c, st2), OK);
        assert_eq!((a.fmi2FreeFMUstate)(other.c, &mut st2), OK);
        assert_eq!((a.fmi2FreeFMUstate)(stiff.c, &mut st), OK);
    }
    assert_eq!(other.real(&[young])[0], 3e6);
    for k in 10..20 {
        assert_eq!(other.step(k as f64 * 0.002, 0.002), OK);
    }
    assert_eq!(other.real(&[uz])[0].to_bits(), expected.to_bits());
}

// ---------------------------------------------------------------------------------------------
// Hardening (issue 8): each test failed on the code before its fix.

/// Runs `f` on another thread and fails the test if it does not finish in `secs` (a deadlock
/// or an unbounded step would otherwise hang the whole suite).
fn within<T: Send + 'static>(secs: u64, what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(std::time::Duration::from_secs(secs))
        .unwrap_or_else(|_| panic!("{what} did not return within {secs} s"))
}

#[test]
fn logger_may_call_back_into_the_instance() {
    // Issue 8.5: the logger is called after the instance is released, so a host whose logger
    // reads a value of the same instance (here on every message) does not deadlock.
    let _g = shared();
    let u = Unpacked::new("small2d.json", "reenter");
    let i = Inst::new(&u);
    i.init(None);
    let ev = cstr("logEvents");
    unsafe {
        assert_eq!(
            (api().fmi2SetDebugLogging)(i.c, 1, 1, [ev.as_ptr()].as_ptr()),
            OK
        );
    }
    i.log.1.store(i.c, std::sync::atomic::Ordering::SeqCst);
    let i = within(20, "calls with a re-entrant logger", move || {
        let bad = i.step(0.0, -1.0);
        let good = i.step(0.0, 0.002);
        let mut st: *mut c_void = null_mut();
        let got = unsafe { (api().fmi2GetFMUstate)(i.c, &mut st) };
        unsafe { (api().fmi2FreeFMUstate)(i.c, &mut st) };
        assert_eq!((bad, good, got), (ERROR, OK, OK));
        i
    });
    i.log
        .1
        .store(null_mut(), std::sync::atomic::Ordering::SeqCst);
    let log = i.log.0.lock().unwrap().clone();
    let reentered: Vec<_> = log.iter().filter(|m| m.1 == "reentered").collect();
    assert!(reentered.len() >= 2, "{log:?}");
    assert!(reentered.iter().all(|m| m.0 == OK), "{log:?}");
    assert!(log.iter().any(|m| m.2.contains("communicationStepSize")));
}

#[test]
fn fmu_state_of_another_fmu_is_refused_and_changes_nothing() {
    // Issue 8.6 and 8.8: a state taken from another FMU (small3d into small2d) was accepted;
    // a refused state must leave time, inputs and particles as they were.
    let _g = shared();
    let a = api();
    let (u2, u3) = (
        Unpacked::new("small2d.json", "foreign"),
        Unpacked::new("small3d.json", "foreign"),
    );
    let (i2, i3) = (Inst::new(&u2), Inst::new(&u3));
    i2.init(None);
    i3.init(None);
    for k in 0..5 {
        assert_eq!(i3.step(k as f64 * 0.002, 0.002), OK);
    }
    assert_eq!(i2.step(0.0, 0.002), OK);
    let fy = u2.vr("tip_load.fy");
    assert_eq!(i2.set(&[fy], &[-1.0]), OK);
    let outs = real_outputs(&u2);
    let before = i2.real(&outs);
    let mut st: *mut c_void = null_mut();
    unsafe {
        assert_eq!((a.fmi2GetFMUstate)(i3.c, &mut st), OK);
        i2.expect_err((a.fmi2SetFMUstate)(i2.c, st), "another FMU");
        assert_eq!((a.fmi2FreeFMUstate)(i3.c, &mut st), OK);
        let mut t = 0.0;
        assert_eq!((a.fmi2GetRealStatus)(i2.c, 2, &mut t), OK);
        assert_eq!(t, 0.002, "time unchanged");
    }
    assert_eq!(i2.real(&outs), before, "outputs unchanged");
    assert_eq!(i2.real(&[fy]), vec![-1.0], "inputs unchanged");
    // And it steps on exactly like an instance that never saw the foreign state.
    let j = Inst::new(&u2);
    j.init(None);
    assert_eq!(j.step(0.0, 0.002), OK);
    assert_eq!(j.set(&[fy], &[-1.0]), OK);
    for k in 1..4 {
        assert_eq!(i2.step(k as f64 * 0.002, 0.002), OK);
        assert_eq!(j.step(k as f64 * 0.002, 0.002), OK);
    }
    assert_eq!(i2.real(&outs), j.real(&outs));
}

/// A serialised FMU state of small2d after a few steps.
fn serialized_state(u: &Unpacked, i: &Inst) -> Vec<c_char> {
    let a = api();
    for k in 0..3 {
        assert_eq!(i.step(k as f64 * 0.002, 0.002), OK);
    }
    let _ = u;
    let mut st: *mut c_void = null_mut();
    let mut size = 0usize;
    unsafe {
        assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK);
        assert_eq!((a.fmi2SerializedFMUstateSize)(i.c, st, &mut size), OK);
        let mut buf = vec![0 as c_char; size];
        assert_eq!(
            (a.fmi2SerializeFMUstate)(i.c, st, buf.as_mut_ptr(), size),
            OK
        );
        assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
        buf
    }
}

#[test]
fn corrupted_serialized_states_are_refused() {
    // Issue 8.7: 248 of 300 single-bit flips were accepted. With the CRC-32 every single-bit
    // flip (and any burst of up to 32 bits) is detected: all 300 must be refused.
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small2d.json", "flips");
    let i = Inst::new(&u);
    i.init(None);
    let buf = serialized_state(&u, &i);
    let bits = buf.len() * 8;
    let mut accepted = Vec::new();
    for k in 0..300 {
        let bit = (k * 7919 + 13) % bits;
        let mut bad = buf.clone();
        bad[bit / 8] ^= (1u8 << (bit % 8)) as c_char;
        let mut st: *mut c_void = null_mut();
        let s = unsafe { (a.fmi2DeSerializeFMUstate)(i.c, bad.as_ptr(), bad.len(), &mut st) };
        if s == OK {
            accepted.push(bit);
            unsafe { (a.fmi2FreeFMUstate)(i.c, &mut st) };
        } else {
            assert!(st.is_null());
        }
    }
    assert!(accepted.is_empty(), "accepted flips at bits {accepted:?}");
    // Trailing or missing bytes too.
    let mut st: *mut c_void = null_mut();
    let mut long = buf.clone();
    long.push(0);
    unsafe {
        i.expect_err(
            (a.fmi2DeSerializeFMUstate)(i.c, long.as_ptr(), long.len(), &mut st),
            "checksum",
        );
        i.expect_err(
            (a.fmi2DeSerializeFMUstate)(i.c, buf.as_ptr(), buf.len() - 1, &mut st),
            "checksum",
        );
        assert_eq!(
            (a.fmi2DeSerializeFMUstate)(i.c, buf.as_ptr(), buf.len(), &mut st),
            OK
        );
        assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
    }
}

#[test]
fn do_step_work_is_bounded() {
    // Issue 8.1: fmi2DoStep(h = 1e6) never returned. It is refused before any work, with the
    // step count in the message, and the instance steps on normally afterwards.
    let _g = shared();
    let u = Unpacked::new("small2d.json", "work");
    let i = Inst::new(&u);
    i.init(None);
    let i = within(20, "doStep(h = 1e6)", move || {
        let s = i.step(0.0, 1e6);
        i.expect_err(s, "solver steps");
        i
    });
    assert_eq!(i.step(0.0, 0.002), OK, "{}", i.log.all());
    assert!(i.int(&[u.vr("steps")])[0] > 0);
}

#[test]
fn input_derivatives_make_inputs_linear_over_the_step() {
    // Issue 8.12: canInterpolateInputs is declared, so fmi2SetRealInputDerivatives must work:
    // a load of 0 with derivative R over one step of h is the ramp R t. Reference: the same
    // ramp given as values held over 40 sub-intervals (error O(h / 40)). The held value 0 alone
    // would leave the tip unloaded.
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small2d.json", "derivatives");
    let (fy, uy) = (u.vr("tip_load.fy"), u.vr("tip.uy"));
    let gy = u.vr("gravity_y");
    let (h, rate) = (0.02, -500.0);
    let one = Inst::new(&u);
    one.init(None);
    assert_eq!(one.set(&[gy, fy], &[0.0, 0.0]), OK);
    unsafe {
        assert_eq!(
            (a.fmi2SetRealInputDerivatives)(one.c, &fy, 1, &1, &rate),
            OK,
            "{}",
            one.log.all()
        );
        one.expect_err(
            (a.fmi2SetRealInputDerivatives)(one.c, &fy, 1, &2, &rate),
            "only first derivatives",
        );
        one.expect_err(
            (a.fmi2SetRealInputDerivatives)(one.c, &uy, 1, &1, &rate),
            "not an input",
        );
    }
    assert_eq!(one.step(0.0, h), OK);
    let with_derivative = one.real(&[uy])[0];
    let fine = Inst::new(&u);
    fine.init(None);
    let n = 40;
    for k in 0..n {
        let t = k as f64 * h / n as f64;
        assert_eq!(
            fine.set(&[gy, fy], &[0.0, rate * (t + 0.5 * h / n as f64)]),
            OK
        );
        assert_eq!(fine.step(t, h / n as f64), OK);
    }
    let reference = fine.real(&[uy])[0];
    assert!(reference < -1e-6, "the ramp bends the strip: {reference}");
    assert!(
        (with_derivative - reference).abs() < 0.02 * reference.abs(),
        "derivative {with_derivative} vs fine hold {reference}"
    );
    // The derivative applies to one step: the next step holds the value set (0).
    let held = Inst::new(&u);
    held.init(None);
    assert_eq!(held.set(&[gy, fy], &[0.0, 0.0]), OK);
    assert_eq!(held.step(0.0, h), OK);
    let still = held.real(&[uy])[0];
    assert!(
        still.abs() < 1e-12,
        "no load, no gravity: no motion beyond round-off ({still})"
    );
}

#[test]
fn boundary_inputs_act_at_the_start_of_the_step_by_default() {
    // Issue 8.14: fmpy and fmusim set u(t) before doStep(t, h) and expect it to act from t.
    // Default (boundary_input_timing = 1): the value set is the displacement at t; with
    // derivatives it moves linearly over the step. Timing 2 reaches the value at t + h: with the
    // signal shifted one step ahead it gives the same motion as timing 1 with derivatives.
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small2d.json", "timing");
    let (dx, gy, ux, timing) = (
        u.vr("holder.dx"),
        u.vr("gravity_y"),
        u.vr("tip.ux"),
        u.vr("boundary_input_timing"),
    );
    let h = 0.002;
    let signal = |t: f64| 1e-3 * (t / 0.02).min(1.0);
    let run = |mode: c_int, shifted: bool, derivative: bool| -> Vec<f64> {
        let i = Inst::new(&u);
        unsafe { assert_eq!((a.fmi2SetInteger)(i.c, &timing, 1, &mode), OK) };
        i.init(None);
        let mut out = Vec::new();
        for k in 0..20 {
            let t = k as f64 * h;
            let v = if shifted { signal(t + h) } else { signal(t) };
            assert_eq!(i.set(&[gy, dx], &[0.0, v]), OK);
            if derivative {
                let d = (signal(t + h) - signal(t)) / h;
                unsafe { assert_eq!((a.fmi2SetRealInputDerivatives)(i.c, &dx, 1, &1, &d), OK) };
            }
            assert_eq!(i.step(t, h), OK);
            out.push(i.real(&[ux])[0]);
        }
        out
    };
    let start_held = run(1, false, false);
    let start_linear = run(1, false, true);
    let end_shifted = run(2, true, false);
    let end = run(2, false, false);
    for k in 0..20 {
        let scale = end_shifted.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(
            (start_linear[k] - end_shifted[k]).abs() <= 1e-9 * scale,
            "step {k}: {} vs {}",
            start_linear[k],
            end_shifted[k]
        );
    }
    // Held over each step, the group trails the linear motion by up to one step's change;
    // reached at the end of the step (the old behaviour) it trails by one more step.
    let sum = |v: &[f64]| v.iter().sum::<f64>();
    assert!(sum(&start_linear) > sum(&start_held), "linear leads held");
    assert!(sum(&start_held) > sum(&end), "reaching at the end lags");
}

#[test]
fn start_time_and_states_from_instantiation() {
    // Issue 8.13: a non-zero startTime was refused, and so were fmi2GetFMUstate /
    // fmi2SetFMUstate right after instantiation (fmusim's --initial-fmu-state-file restores a
    // state there and steps on without initialising).
    let _g = shared();
    let a = api();
    let u = Unpacked::new("small3d.json", "start");
    let outs = real_outputs(&u);
    let h = 0.002;
    let from_zero = Inst::new(&u);
    from_zero.init(None);
    let shifted = Inst::new(&u);
    unsafe {
        assert_eq!((a.fmi2SetupExperiment)(shifted.c, 0, 0.0, 10.0, 0, 0.0), OK);
        assert_eq!((a.fmi2EnterInitializationMode)(shifted.c), OK);
        assert_eq!((a.fmi2ExitInitializationMode)(shifted.c), OK);
    }
    for k in 0..5 {
        assert_eq!(from_zero.step(k as f64 * h, h), OK);
        assert_eq!(shifted.step(10.0 + k as f64 * h, h), OK);
    }
    // The scene's laws start at startTime: the same motion, shifted in time.
    // (Not bitwise: 10.002 - 10.0 is not 0.002, so the sub-steps differ by round-off.)
    let (x, y) = (from_zero.real(&outs), shifted.real(&outs));
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (p, q) in x.iter().zip(&y) {
        assert!((p - q).abs() <= 1e-6 * scale, "{p} vs {q} (scale {scale})");
    }
    unsafe {
        let mut t = 0.0;
        assert_eq!((a.fmi2GetRealStatus)(shifted.c, 2, &mut t), OK);
        assert!((t - 10.01).abs() < 1e-12);
    }
    // A state taken after 5 steps, serialised, restored into a fresh instance right after
    // fmi2Instantiate: it steps on from t = 0.01 like the original.
    let buf = unsafe {
        let mut st: *mut c_void = null_mut();
        let mut size = 0usize;
        assert_eq!((a.fmi2GetFMUstate)(from_zero.c, &mut st), OK);
        assert_eq!(
            (a.fmi2SerializedFMUstateSize)(from_zero.c, st, &mut size),
            OK
        );
        let mut buf = vec![0 as c_char; size];
        assert_eq!(
            (a.fmi2SerializeFMUstate)(from_zero.c, st, buf.as_mut_ptr(), size),
            OK
        );
        assert_eq!((a.fmi2FreeFMUstate)(from_zero.c, &mut st), OK);
        buf
    };
    let fresh = Inst::new(&u);
    unsafe {
        let mut st: *mut c_void = null_mut();
        assert_eq!(
            (a.fmi2DeSerializeFMUstate)(fresh.c, buf.as_ptr(), buf.len(), &mut st),
            OK,
            "{}",
            fresh.log.all()
        );
        assert_eq!((a.fmi2SetFMUstate)(fresh.c, st), OK, "{}", fresh.log.all());
        assert_eq!((a.fmi2FreeFMUstate)(fresh.c, &mut st), OK);
    }
    for k in 5..10 {
        assert_eq!(from_zero.step(k as f64 * h, h), OK);
        assert_eq!(fresh.step(k as f64 * h, h), OK, "{}", fresh.log.all());
    }
    assert_eq!(from_zero.real(&outs), fresh.real(&outs));
    // A state taken in Instantiated mode restores to Instantiated: the host initialises.
    let early = Inst::new(&u);
    unsafe {
        let mut st: *mut c_void = null_mut();
        assert_eq!((a.fmi2GetFMUstate)(early.c, &mut st), OK);
        assert_eq!((a.fmi2SetFMUstate)(fresh.c, st), OK);
        assert_eq!((a.fmi2FreeFMUstate)(early.c, &mut st), OK);
    }
    fresh.expect_err(fresh.step(0.02, h), "illegal call sequence");
    fresh.init(None);
    assert_eq!(fresh.step(0.0, h), OK);
}

/// Threads of this process (all of them, named or not).
fn process_threads() -> usize {
    std::fs::read_dir("/proc/self/task").unwrap().count()
}

#[test]
#[ignore = "run in a child process by no_thread_outlives_state_calls"]
fn child_state_calls_thread_count() {
    let u = Unpacked::new("small2d.json", "threads-child");
    let before = process_threads();
    {
        let i = Inst::new(&u);
        let a = api();
        let mut st: *mut c_void = null_mut();
        unsafe {
            assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK);
            assert_eq!((a.fmi2SetFMUstate)(i.c, st), OK);
            i.init(None);
            assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK);
            assert_eq!((a.fmi2SetFMUstate)(i.c, st), OK);
            assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
        }
        assert_eq!(i.step(0.0, 0.002), OK);
    }
    let after = process_threads();
    println!("THREADS before={before} after={after}");
}

#[test]
fn no_thread_outlives_state_calls() {
    // Issue 8.4: fmi2SetFMUstate ran on rayon's global pool, whose threads outlive the
    // instance. In a fresh process (no other test's threads), the thread count after
    // fmi2FreeInstance is the one before fmi2Instantiate.
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_state_calls_thread_count",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = text
        .lines()
        .find_map(|l| l.find("THREADS").map(|k| &l[k..]))
        .unwrap_or_else(|| panic!("no THREADS line in {text}"));
    let n: Vec<usize> = line
        .split_whitespace()
        .skip(1)
        .map(|kv| kv.split('=').nth(1).unwrap().parse().unwrap())
        .collect();
    assert_eq!(n[0], n[1], "{line}");
}

#[test]
fn coupling_outputs_velocity_is_the_rate_of_displacement() {
    // Issue 9: per probe velocities and, per load region, the mean displacement and velocity of
    // exactly the particles the force acts on. Check: each velocity output equals the central
    // difference of its displacement over +-h (h = 0.25 ms, about 1/1200 of the strip's first
    // period, so the difference quotient is within ~1e-5 of the derivative of the first mode;
    // 3 % of the peak velocity covers the higher modes the sudden load excites, whose
    // difference quotient errs by (omega h)^2 / 6 (2 % at 300 Hz), and symplectic Euler's
    // velocity being the mean over the last solver sub-step, half a sub-step (0.08 ms) behind),
    // and the load region's displacement lies between the displacement of the clamped end (0)
    // and a bit beyond the tip probe (same sign, same order).
    let _g = shared();
    let u = Unpacked::new("small2d.json", "coupling");
    let (fy, gy) = (u.vr("tip_load.fy"), u.vr("gravity_y"));
    let (puy, pvy) = (u.vr("tip.uy"), u.vr("tip.vy"));
    let (luy, lvy) = (u.vr("tip_load.uy"), u.vr("tip_load.vy"));
    let i = Inst::new(&u);
    i.init(None);
    assert_eq!(i.set(&[gy, fy], &[0.0, -2.0]), OK);
    let h = 0.00025;
    let mut series = Vec::new();
    for k in 0..240 {
        assert_eq!(i.step(k as f64 * h, h), OK);
        series.push(i.real(&[puy, pvy, luy, lvy]));
    }
    let mut worst: f64 = 0.0;
    let vmax = series.iter().fold(0.0f64, |m, s| m.max(s[1].abs()));
    for k in 1..series.len() - 1 {
        for (u_at, v_at) in [(0, 1), (2, 3)] {
            let fd = (series[k + 1][u_at] - series[k - 1][u_at]) / (2.0 * h);
            worst = worst.max((fd - series[k][v_at]).abs() / vmax);
        }
    }
    eprintln!("velocity vs difference quotient: worst {worst:.4} of the peak {vmax:.4e} m/s");
    assert!(
        vmax > 0.0 && worst < 0.03,
        "velocity vs difference quotient: {worst} of {vmax}"
    );
    let last = series.last().unwrap();
    assert!(
        last[2] < 0.0 && last[0] < 0.0,
        "the load bends the tip down: {last:?}"
    );
    assert!(
        (last[2] / last[0] - 1.0).abs() < 0.2,
        "load region mean {} vs tip probe {}",
        last[2],
        last[0]
    );
}

#[test]
fn instantiation_logs_under_resolved_geometry() {
    let _g = shared();
    let plate = Scene::from_json(
        &serde_json::json!({
            "name": "plate", "dimension": 3, "particle_spacing": 0.01,
            "bodies": [{ "name": "plate",
                         "material": { "density": 1000.0, "young": 1e6, "poisson": 0.3 },
                         "boxes": [{ "min": [0, 0, 0], "max": [0.2, 0.1, 0.01] }] }],
            "end_time": 0.01, "output_interval": 0.001
        })
        .to_string(),
    )
    .unwrap();
    let u = Unpacked::from_scene(plate, "warn");
    let i = Inst::new(&u);
    let warnings: Vec<_> = i
        .log
        .0
        .lock()
        .unwrap()
        .iter()
        .filter(|m| m.0 == 1)
        .cloned()
        .collect();
    assert_eq!(warnings.len(), 1, "{}", i.log.all());
    let (_, cat, msg, name) = &warnings[0];
    assert_eq!((cat.as_str(), name.as_str()), ("logStatusWarning", "inst"));
    assert!(
        msg.starts_with("scene warning in bodies[0] ('plate').boxes[0]:")
            && msg.contains("one particle thick along z")
            && msg.contains("refine particle_spacing"),
        "{msg}"
    );
    // Case 2 is resolved: nothing logged at instantiation but the (debug) events.
    let case2 = Scene::load(&root().join("scenes/case2_beam.json")).unwrap();
    let u = Unpacked::from_scene(case2, "warn");
    let i = Inst::new(&u);
    assert!(
        i.log.0.lock().unwrap().iter().all(|m| m.0 != 1),
        "{}",
        i.log.all()
    );
}

#[test]
fn fmu_state_of_a_scene_with_a_velocity_field_roundtrips() {
    // The scene is part of the state (bincode): the velocity field, whose JSON is an untagged
    // array-or-object, must encode and decode there too.
    let _g = shared();
    let a = api();
    let mut v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root().join("tests/data/small2d.json")).unwrap(),
    )
    .unwrap();
    v["bodies"][0]["velocity"] = serde_json::json!({
        "linear": [0.01, 0.0],
        "angular": { "omega": 0.5, "center": [0.2, 0.0] },
        "profiles": [
            { "mode_shape": { "shape": "clamped_free_1", "axis": "x", "component": "y",
                              "x0": 0.0, "length": 0.4, "amplitude": 0.05 } },
            { "table": { "axis": "y", "component": "x", "points": [[-0.05, 0.0], [0.05, 0.02]] } }
        ]
    });
    let u = Unpacked::from_scene(Scene::from_json(&v.to_string()).unwrap(), "vstate");
    let outs = real_outputs(&u);
    let i = Inst::new(&u);
    i.init(None);
    let h = 0.002;
    for k in 0..5 {
        assert_eq!(i.step(k as f64 * h, h), OK);
    }
    let run = |inst: &Inst| -> Vec<u64> {
        let mut r = Vec::new();
        for k in 5..10 {
            assert_eq!(inst.step(k as f64 * h, h), OK);
            r.extend(inst.real(&outs).iter().map(|x| x.to_bits()));
        }
        r
    };
    unsafe {
        let mut st: *mut c_void = null_mut();
        assert_eq!((a.fmi2GetFMUstate)(i.c, &mut st), OK);
        let mut size = 0usize;
        assert_eq!((a.fmi2SerializedFMUstateSize)(i.c, st, &mut size), OK);
        let mut buf = vec![0 as c_char; size];
        assert_eq!(
            (a.fmi2SerializeFMUstate)(i.c, st, buf.as_mut_ptr(), size),
            OK
        );
        let first = run(&i);
        assert_eq!((a.fmi2SetFMUstate)(i.c, st), OK, "{}", i.log.all());
        assert_eq!(run(&i), first, "restored run differs");
        assert_eq!((a.fmi2FreeFMUstate)(i.c, &mut st), OK);
        let j = Inst::new(&u);
        let mut st2: *mut c_void = null_mut();
        assert_eq!(
            (a.fmi2DeSerializeFMUstate)(j.c, buf.as_ptr(), size, &mut st2),
            OK,
            "{}",
            j.log.all()
        );
        assert_eq!((a.fmi2SetFMUstate)(j.c, st2), OK, "{}", j.log.all());
        assert_eq!((a.fmi2FreeFMUstate)(j.c, &mut st2), OK);
        assert_eq!(run(&j), first, "deserialised run differs");
    }
}

/// A component pointer moved to another thread (the host's own business there).
struct SendComp(Comp);
unsafe impl Send for SendComp {}

#[test]
fn fmi2_cancel_step_stops_a_long_closure_at_once() {
    // Issue 27.7: fmi2CancelStep was seen only between set-up stages, so a bulky clamped
    // body's closure (8 s for this cube, minutes for larger ones on a loaded machine) ran to its
    // end before fmi2EnterInitializationMode returned. Its iterations now poll the request.
    let _g = shared();
    let scene = Scene::load(&root().join("tests/data/clamped_cube.json")).unwrap();
    let u = Unpacked::from_scene(scene, "cancel_closure");
    let i = Inst::new(&u);
    let ev = cstr("logEvents");
    unsafe {
        assert_eq!(
            (api().fmi2SetDebugLogging)(i.c, 1, 1, [ev.as_ptr()].as_ptr()),
            OK
        );
        assert_eq!((api().fmi2SetupExperiment)(i.c, 0, 0.0, 0.0, 0, 0.0), OK);
    }
    let c = SendComp(i.c);
    let started = std::time::Instant::now();
    let setup = std::thread::spawn(move || {
        let c = c;
        let s = unsafe { (api().fmi2EnterInitializationMode)(c.0) };
        (s, std::time::Instant::now())
    });
    loop {
        if i.log.all().contains("set-up: operator fits took") {
            break;
        }
        assert!(
            started.elapsed().as_secs() < 120 && !setup.is_finished(),
            "the set-up ended before its closure:\n{}",
            i.log.all()
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    // Inside the closure.
    std::thread::sleep(std::time::Duration::from_millis(300));
    let t = std::time::Instant::now();
    assert_eq!(
        unsafe { (api().fmi2CancelStep)(i.c) },
        OK,
        "{}",
        i.log.all()
    );
    let (status, ended) = setup.join().unwrap();
    i.expect_err(status, "during the closure stage");
    let after = (ended - t).as_secs_f64();
    // An iteration is about 1 ms on an idle machine; a second allows for a loaded one.
    assert!(
        after < 1.0,
        "stopped {after:.2} s after the cancel:\n{}",
        i.log.all()
    );
    assert!(
        !i.log.all().contains("set-up: closure took"),
        "{}",
        i.log.all()
    );
}

#[test]
fn a_long_set_up_is_logged_as_it_happens_and_can_be_cancelled() {
    // Issue 27.7: fmi2EnterInitializationMode of a big scene logged nothing until it returned,
    // and fmi2CancelStep from another thread blocked until then. Now each stage is logged as it
    // ends, and fmi2CancelStep asks the set-up to stop at its next stage boundary, returning at
    // once; the set-up's call then fails, the instance is unchanged and can set up again.
    let _g = shared();
    // small3d at half its spacing: 2,368 particles, a set-up of about 2 s on 2 cores (the
    // stable step's measurement is most of it).
    let mut scene = Scene::load(&root().join("tests/data/small3d.json")).unwrap();
    scene.particle_spacing = 0.0125;
    let u = Unpacked::from_scene(scene, "cancel");
    let i = Inst::new(&u);
    let ev = cstr("logEvents");
    unsafe {
        assert_eq!(
            (api().fmi2SetDebugLogging)(i.c, 1, 1, [ev.as_ptr()].as_ptr()),
            OK
        );
        assert_eq!((api().fmi2SetupExperiment)(i.c, 0, 0.0, 0.0, 0, 0.0), OK);
    }
    let c = SendComp(i.c);
    let started = std::time::Instant::now();
    let setup = std::thread::spawn(move || {
        let c = c;
        let s = unsafe { (api().fmi2EnterInitializationMode)(c.0) };
        (s, std::time::Instant::now())
    });
    // The bonds stage is logged while the set-up runs.
    let seen = loop {
        let log = i.log.all();
        if log.contains("set-up: bonds took") {
            break std::time::Instant::now();
        }
        assert!(
            started.elapsed().as_secs() < 120 && !setup.is_finished(),
            "no stage was logged while the set-up ran:\n{log}"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    let t = std::time::Instant::now();
    let cancelled = unsafe { (api().fmi2CancelStep)(i.c) };
    let cancel_took = t.elapsed();
    let (status, ended) = setup.join().unwrap();
    assert_eq!(cancelled, OK, "{}", i.log.all());
    assert!(
        cancel_took.as_secs_f64() < 0.5,
        "fmi2CancelStep blocked for {cancel_took:?}"
    );
    i.expect_err(status, "fmi2CancelStep was called");
    assert!(ended > seen);
    println!(
        "set-up stopped {:.2} s after the cancel (bonds logged {:.2} s after the start)",
        (ended - t).as_secs_f64(),
        (seen - started).as_secs_f64()
    );
    // Nothing is left half-built: with no call running, fmi2CancelStep has nothing to stop,
    // and the instance can still be initialised (now without being stopped).
    i.expect_err(unsafe { (api().fmi2CancelStep)(i.c) }, "nothing to cancel");
    unsafe {
        assert_eq!(
            (api().fmi2EnterInitializationMode)(i.c),
            OK,
            "{}",
            i.log.all()
        );
    }
    let log = i.log.all();
    for stage in ["bonds", "operator fits", "closure", "stable step"] {
        assert!(
            log.contains(&format!("set-up: {stage} took")),
            "{stage}:\n{log}"
        );
    }
}

#[test]
fn results_do_not_depend_on_the_fmu_thread_count() {
    // Issue 27.5: the instance's own threads (not rayon) run the gather-form loops; the
    // outputs are bitwise the same with 1, 2 and 3 threads (MPS_FMI_THREADS, read at
    // fmi2Instantiate; the write lock keeps every other test of this process out meanwhile).
    let _g = PROCESS.write().unwrap_or_else(|e| e.into_inner());
    let _ = (api(), logger_ptr());
    let u = Unpacked::new("small3d.json", "thread-count");
    let runs: Vec<Vec<u64>> = [1, 2, 3]
        .iter()
        .map(|n| {
            std::env::set_var("MPS_FMI_THREADS", n.to_string());
            let r = run_small3d(&u);
            std::env::remove_var("MPS_FMI_THREADS");
            r
        })
        .collect();
    assert_eq!(runs[0], runs[1], "1 and 2 threads");
    assert_eq!(runs[0], runs[2], "1 and 3 threads");
}
