//! Benchmark of the FMU's worker threads (issue 27.5): the wall time of one solver step
//! (a doStep of one stable step) of a scene through the C ABI of the built library, whose
//! instances run their loops on threads of their own, against the same scene on a rayon pool
//! (the Rust API's `Instance`), and optionally against another build of the library (e.g. main's,
//! whose instances used a rayon pool): interleaved in blocks so that the machine's load hits all
//! alike. Prints the median step time of each and their ratios.
//!
//! ```text
//! cargo bench --bench fmu_pool -- [SCENE [BLOCKS [STEPS [OLD_LIB OLD_GUID]]]]
//! ```
//! The library measured is target/release/libmps_solid.so (`MPS_BENCH_LIB` overrides).
//! Defaults: scenes/case2_beam.json (3,645 particles), 15 blocks of 20 steps. OLD_GUID is the
//! GUID the other build gives the scene (its `mps pack --xml-only --write-xml DIR SCENE`).
use libloading::Library;
use mps_solid::fmi::instance::{Instance, NoLogger};
use mps_solid::fmi::model_description::guid;
use mps_solid::{Scene, Simulation};
use std::ffi::{c_char, c_int, c_void, CString};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

type Comp = *mut c_void;

#[repr(C)]
struct Callbacks {
    logger: *const c_void,
    allocate: *const c_void,
    free: *const c_void,
    step_finished: *const c_void,
    env: *mut c_void,
}

/// One instance of a library loaded through its C ABI.
struct CInstance {
    _lib: Library,
    c: Comp,
    do_step: unsafe extern "C" fn(Comp, f64, f64, c_int) -> c_int,
    free: unsafe extern "C" fn(Comp),
    t: f64,
}

impl CInstance {
    fn new(lib: &PathBuf, guid: &str, resources: &str) -> CInstance {
        unsafe {
            let lib = Library::new(lib).expect("load the library");
            let inst: unsafe extern "C" fn(
                *const c_char,
                c_int,
                *const c_char,
                *const c_char,
                *const Callbacks,
                c_int,
                c_int,
            ) -> Comp = *lib.get(b"fmi2Instantiate\0").unwrap();
            let setup: unsafe extern "C" fn(Comp, c_int, f64, f64, c_int, f64) -> c_int =
                *lib.get(b"fmi2SetupExperiment\0").unwrap();
            let enter: unsafe extern "C" fn(Comp) -> c_int =
                *lib.get(b"fmi2EnterInitializationMode\0").unwrap();
            let exit: unsafe extern "C" fn(Comp) -> c_int =
                *lib.get(b"fmi2ExitInitializationMode\0").unwrap();
            let do_step = *lib.get(b"fmi2DoStep\0").unwrap();
            let free = *lib.get(b"fmi2FreeInstance\0").unwrap();
            let cb = Callbacks {
                logger: std::ptr::null(),
                allocate: std::ptr::null(),
                free: std::ptr::null(),
                step_finished: std::ptr::null(),
                env: std::ptr::null_mut(),
            };
            let (name, g, uri) = (
                CString::new("bench").unwrap(),
                CString::new(guid).unwrap(),
                CString::new(resources).unwrap(),
            );
            let c = inst(name.as_ptr(), 1, g.as_ptr(), uri.as_ptr(), &cb, 0, 0);
            assert!(!c.is_null(), "fmi2Instantiate failed (GUID {guid})");
            assert_eq!(setup(c, 0, 0.0, 0.0, 0, 0.0), 0);
            assert_eq!(enter(c), 0);
            assert_eq!(exit(c), 0);
            CInstance {
                _lib: lib,
                c,
                do_step,
                free,
                t: 0.0,
            }
        }
    }
    fn step(&mut self, h: f64) {
        assert_eq!(unsafe { (self.do_step)(self.c, self.t, h, 1) }, 0);
        self.t += h;
    }
}

impl Drop for CInstance {
    fn drop(&mut self) {
        unsafe { (self.free)(self.c) }
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    // `cargo bench` appends `--bench` to the arguments of a bench without libtest's harness.
    let args: Vec<String> = std::env::args().filter(|a| a != "--bench").collect();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let path = args
        .get(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("scenes/case2_beam.json"));
    let blocks: usize = args.get(2).map_or(15, |s| s.parse().unwrap());
    let steps: usize = args.get(3).map_or(20, |s| s.parse().unwrap());
    let old = args.get(4).zip(args.get(5));
    let scene = Scene::load(&path).unwrap();
    let dir = std::env::temp_dir().join(format!("mps-fmu-pool-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("scene.json"), scene.to_json()).unwrap();
    let uri = format!("file://{}", dir.display());
    // One solver step per doStep.
    let h = Simulation::new(&scene).unwrap().max_dt();
    let lib = std::env::var_os("MPS_BENCH_LIB")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target/release/libmps_solid.so"));
    let mut own = CInstance::new(&lib, &guid(&scene), &uri);
    // The other build reads the scene file as written (it may not know newer fields).
    let old_dir = dir.join("old");
    std::fs::create_dir_all(&old_dir).unwrap();
    std::fs::copy(&path, old_dir.join("scene.json")).unwrap();
    let old_uri = format!("file://{}", old_dir.display());
    let mut before = old.map(|(l, g)| CInstance::new(&PathBuf::from(l), g, &old_uri));
    let mut rayon = Instance::instantiate(
        "bench",
        true,
        &guid(&scene),
        Some(&uri),
        Arc::new(NoLogger),
        false,
    )
    .unwrap();
    rayon.setup_experiment(0.0, None).unwrap();
    rayon.enter_initialization_mode().unwrap();
    rayon.exit_initialization_mode().unwrap();
    let mut t_rayon = 0.0;
    let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
    let threads = mps_solid::fmi::instance::instance_threads();
    println!(
        "{}: {} particles, {threads} threads, {blocks} blocks of {steps} steps of {h:.3e} s",
        scene.name,
        Simulation::new(&scene).unwrap().particles()
    );
    for k in 0..=blocks {
        // Block 0 warms up; the order alternates so that neither always runs first.
        let mut run_own = || {
            let t = Instant::now();
            (0..steps).for_each(|_| own.step(h));
            t.elapsed().as_secs_f64() / steps as f64
        };
        let mut run_rayon = || {
            let t = Instant::now();
            for _ in 0..steps {
                rayon.do_step(t_rayon, h).unwrap();
                t_rayon += h;
            }
            t.elapsed().as_secs_f64() / steps as f64
        };
        let (x, y) = if k % 2 == 0 {
            let x = run_own();
            (x, run_rayon())
        } else {
            let y = run_rayon();
            (run_own(), y)
        };
        let z = before.as_mut().map(|o| {
            let t = Instant::now();
            (0..steps).for_each(|_| o.step(h));
            t.elapsed().as_secs_f64() / steps as f64
        });
        if k > 0 {
            a.push(x);
            b.push(y);
            if let Some(z) = z {
                c.push(z);
            }
        }
    }
    let (ma, mb) = (median(&mut a), median(&mut b));
    println!("instance threads (C ABI): {:.3} ms per step", ma * 1e3);
    println!("rayon pool (Rust API):    {:.3} ms per step", mb * 1e3);
    println!("ratio instance threads / rayon: {:.3}", ma / mb);
    if !c.is_empty() {
        let mc = median(&mut c);
        println!("other library (C ABI):    {:.3} ms per step", mc * 1e3);
        println!("ratio instance threads / other library: {:.3}", ma / mc);
    }
    std::fs::remove_dir_all(&dir).ok();
}
