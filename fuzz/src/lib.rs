//! Shared pieces of the fuzz targets: the test scenes written once into resource directories,
//! a no-op logger, instance set-up, the particle-count estimate that bounds scene builds, and
//! the switch for inputs that trip known open defects.
use mps_solid::fmi::instance::{Instance, Logger, Status};
use mps_solid::fmi::model_description::guid;
use mps_solid::Scene;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

pub mod seeds;

/// The FMI layer's test scenes (tests/data), and cut-down versions of them (fuzz/scenes: a
/// model build of small2d/small3d takes ~10 ms, which would dominate every run) with a second
/// body (contact), fracture and a pinned group: the models the FMI targets run on.
pub const SMALL2D: &str = include_str!("../../tests/data/small2d.json");
pub const SMALL3D: &str = include_str!("../../tests/data/small3d.json");
pub const TINY2D: &str = include_str!("../scenes/tiny2d.json");
pub const TINY3D: &str = include_str!("../scenes/tiny3d.json");
const TEXTS: [&str; FIXTURES] = [SMALL2D, SMALL3D, TINY2D, TINY3D];
/// Number of fixtures.
pub const FIXTURES: usize = 4;

/// Largest particle count a fuzz input may build (a few ms per build; keeps every input fast
/// and bounded in memory).
pub const MAX_FUZZ_PARTICLES: f64 = 2000.0;

/// Logger that drops everything (the targets look for panics, not messages).
pub struct Quiet;
impl Logger for Quiet {
    fn log(&self, _: Status, _: &str, _: &str) {}
}

/// `MPS_FUZZ_ALL=1`: also feed inputs that trip known open defects, which the bounded CI run
/// would otherwise find again in its first seconds instead of new bugs:
/// - accepted parameter values that make a step run for hours (issue 8 item 1: tiny density
///   or solver step, huge Young's modulus or communication step);
/// - FMU states with positions beyond 1e15 m or not finite (overflow of the contact grid's
///   cell key in `physics::grid::CellGrid::for_each_near`), with non-finite inputs (restored
///   and read back with fmi2OK), or whose parameters build a huge model (issue 8 item 2);
///   reproducers in fuzz/regressions/open/.
///
/// Switch it on once those are fixed.
pub fn all_inputs() -> bool {
    static W: OnceLock<bool> = OnceLock::new();
    *W.get_or_init(|| std::env::var("MPS_FUZZ_ALL").is_ok_and(|v| v == "1"))
}

/// Whether an FMU state stays clear of the known open defects (see [`all_inputs`]): its
/// parameters build at most [`MAX_FUZZ_PARTICLES`] (a mutated box would otherwise allocate
/// gigabytes and run for long). Reads the state's serde form.
pub fn state_in_known_bounds<T: serde::Serialize>(state: &T) -> bool {
    let Ok(v) = serde_json::to_value(state) else {
        return false;
    };
    let Ok(params) = serde_json::from_value::<Scene>(v["params"].clone()) else {
        return false;
    };
    if particle_estimate(&params).is_none_or(|n| n > MAX_FUZZ_PARTICLES) {
        return false;
    }
    // Positions and inputs need no filter any more: states with huge or non-finite values are
    // handled by the restore (they were open defects; see fuzz/README.md).
    true
}

/// The first place where two serialisable values differ (JSON path and both values), for the
/// messages of failed round trips.
pub fn first_difference<T: serde::Serialize>(a: &T, b: &T) -> String {
    fn walk(a: &serde_json::Value, b: &serde_json::Value, path: String) -> Option<String> {
        use serde_json::Value::{Array, Object};
        match (a, b) {
            (Object(x), Object(y)) => x.iter().find_map(|(k, v)| {
                walk(
                    v,
                    y.get(k).unwrap_or(&serde_json::Value::Null),
                    format!("{path}.{k}"),
                )
            }),
            (Array(x), Array(y)) if x.len() == y.len() => x
                .iter()
                .zip(y)
                .enumerate()
                .find_map(|(i, (v, w))| walk(v, w, format!("{path}[{i}]"))),
            _ if a == b => None,
            _ => {
                let short =
                    |v: &serde_json::Value| v.to_string().chars().take(200).collect::<String>();
                Some(format!("{path}: {} vs {}", short(a), short(b)))
            }
        }
    }
    match (serde_json::to_value(a), serde_json::to_value(b)) {
        (Ok(x), Ok(y)) => walk(&x, &y, String::new())
            .unwrap_or_else(|| "no difference in the serde form (a NaN payload or -0.0?)".into()),
        _ => "not representable as JSON".into(),
    }
}

/// Every place where two serialisable values differ (JSON paths), in order.
pub fn differences<T: serde::Serialize>(a: &T, b: &T) -> Vec<String> {
    fn walk(a: &serde_json::Value, b: &serde_json::Value, path: String, out: &mut Vec<String>) {
        use serde_json::Value::{Array, Object};
        match (a, b) {
            (Object(x), Object(y)) if x.len() == y.len() => {
                for (k, v) in x {
                    walk(v, y.get(k).unwrap_or(&serde_json::Value::Null), format!("{path}.{k}"), out);
                }
            }
            (Array(x), Array(y)) if x.len() == y.len() => {
                for (i, (v, w)) in x.iter().zip(y).enumerate() {
                    walk(v, w, format!("{path}[{i}]"), out);
                }
            }
            _ if a == b => {}
            _ => out.push(path),
        }
    }
    let mut out = Vec::new();
    match (serde_json::to_value(a), serde_json::to_value(b)) {
        (Ok(x), Ok(y)) => walk(&x, &y, String::new(), &mut out),
        _ => out.push("(not representable as JSON)".into()),
    }
    out
}

/// Whether a JSON path of [`differences`] names a particle's displacement or velocity
/// (`.sim.D2.u[i]...`, `.sim.D3.v[i]...`): the entries a restore may re-derive, since the
/// particles that follow a clamp take them from the particles they follow.
pub fn is_particle_motion(path: &str) -> bool {
    ["2", "3"].iter().any(|d| {
        [".u[", ".v["]
            .iter()
            .any(|f| path.starts_with(&format!(".sim.D{d}{f}")))
    })
}

/// Whether two states are the same up to the sign of zeros and NaN payloads (what their serde
/// forms compare): a restored state may come back with +0.0 where it held -0.0, because the
/// instance compares parameters with `==` (harmless: -0.0 and 0.0 are the same parameter).
pub fn same_state<T: serde::Serialize>(a: &T, b: &T) -> bool {
    matches!((serde_json::to_value(a), serde_json::to_value(b)), (Ok(x), Ok(y)) if x == y)
}

/// Where two byte strings first differ, with 8 bytes of each from there.
pub fn first_byte_difference(a: &[u8], b: &[u8]) -> String {
    match a.iter().zip(b).position(|(x, y)| x != y) {
        Some(i) => format!(
            "byte {i} of {}/{}: {:02x?} vs {:02x?}",
            a.len(),
            b.len(),
            &a[i..(i + 8).min(a.len())],
            &b[i..(i + 8).min(b.len())]
        ),
        None => format!("lengths {} and {}", a.len(), b.len()),
    }
}

/// A set-up observer lending a memo (the closure a build takes: `mps pack` ships one).
pub struct KeepClosure(pub mps_solid::physics::world::SetupMemo);

impl mps_solid::physics::world::SetupObserver for KeepClosure {
    fn memo(&self) -> Option<&mps_solid::physics::world::SetupMemo> {
        Some(&self.0)
    }
}

/// One test scene with its resources directory (file:// URI) and GUID.
pub struct Fixture {
    pub scene: Scene,
    pub uri: String,
    pub guid: String,
}

fn fixture(name: &str, text: &str) -> Fixture {
    let scene = Scene::from_json(text).expect("test scene parses");
    // One directory per scene content, shared by all fuzz processes: written to a temporary
    // name and renamed, so concurrent runs never see a partial file.
    let hash = guid(&scene);
    let dir: PathBuf = std::env::temp_dir().join(format!("mps-solid-fuzz-{name}-{hash}"));
    let file = dir.join("scene.json");
    if std::fs::read_to_string(&file).ok().as_deref() != Some(text) {
        std::fs::create_dir_all(&dir).expect("create the resources directory");
        let tmp = dir.join(format!("scene.json.{}", std::process::id()));
        std::fs::write(&tmp, text).expect("write scene.json");
        std::fs::rename(&tmp, &file).expect("rename scene.json");
    }
    Fixture {
        guid: guid(&scene),
        uri: format!("file://{}", dir.display()),
        scene,
    }
}

/// small2d, small3d, tiny2d, tiny3d (indices 0 to 3).
pub fn fixtures() -> &'static [Fixture; FIXTURES] {
    static F: OnceLock<[Fixture; FIXTURES]> = OnceLock::new();
    F.get_or_init(|| {
        // One worker thread per instance (the serial build has none anyway).
        std::env::set_var("MPS_FMI_THREADS", "1");
        [
            fixture("small2d", SMALL2D),
            fixture("small3d", SMALL3D),
            fixture("tiny2d", TINY2D),
            fixture("tiny3d", TINY3D),
        ]
    })
}

/// A fresh instance of fixture `k`, instantiated (not initialised).
pub fn instantiate(k: usize) -> Instance {
    let f = &fixtures()[k];
    Instance::instantiate("fuzz", true, &f.guid, Some(&f.uri), Arc::new(Quiet), true)
        .expect("the test scene instantiates")
}

/// A fresh instance of fixture `k` in StepComplete at t = 0.
pub fn initialised(k: usize) -> Instance {
    let mut inst = instantiate(k);
    inst.setup_experiment(0.0, None).expect("setupExperiment");
    inst.enter_initialization_mode()
        .expect("enterInitializationMode");
    inst.exit_initialization_mode()
        .expect("exitInitializationMode");
    inst
}

/// Particles a scene would create before the overlap filter of later boxes (an upper bound
/// of what `Simulation::new` allocates), computed as `Scene::validate` counts them; None if a
/// box is malformed (validation rejects it).
pub fn particle_estimate(scene: &Scene) -> Option<f64> {
    let d = scene.dimension;
    let dp = scene.particle_spacing;
    let mut total = 0.0;
    for b in &scene.bodies {
        for r in &b.boxes {
            if r.min.len() < d || r.max.len() < d {
                return None;
            }
            let mut n = 1.0;
            for k in 0..d {
                n *= ((r.max[k] - r.min[k]) / dp).round().max(0.0);
            }
            total += n;
        }
    }
    total.is_finite().then_some(total)
}
