//! Seed inputs of the fuzz targets, written into DIR/<target>/: the test and paper scenes
//! (JSON and TOML) for `scene`, and real serialised FMU states of small2d and small3d (at
//! t = 0, after steps, with inputs and parameters set) for `fmu_state`, and their closures for
//! `closure`. scripts/fuzz.sh writes
//! them on each run (through the fmu_state binary with MPS_FUZZ_SEEDS=DIR: a fuzz crate builds
//! only libFuzzer binaries), so the state seeds always match the current state format.
use crate::{fixtures, initialised};
use mps_solid::fmi::instance::Instance;
use mps_solid::fmi::variables::Quantity;
use std::path::Path;

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::create_dir_all(dir).expect("create the seed directory");
    std::fs::write(dir.join(name), bytes).expect("write a seed");
}

fn state(inst: &mut Instance) -> Vec<u8> {
    let s = inst.get_fmu_state().expect("get state");
    // The targets' filter reads the state's serde form: if the state's layout changes, it
    // must still pass real states, or the fmu_state target would skip every restore.
    assert!(
        crate::state_in_known_bounds(&s),
        "state_in_known_bounds (fuzz/src/lib.rs) rejects a real FMU state: update it to the \
         state's current serde layout (params, inputs, sim.D2/D3.u)"
    );
    inst.serialize_fmu_state(&s).expect("serialise state")
}

/// Writes the seeds into `out`/scene, `out`/fmu_state and `out`/closure.
pub fn write_seeds(out: &Path) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");

    // The closures small2d's and small3d's builds compute (what `mps pack` ships).
    for f in &fixtures()[..2] {
        let keep = crate::KeepClosure(Default::default());
        mps_solid::Simulation::new_observed(&f.scene, &keep).expect("the test scene builds");
        let bytes = keep.0.closure_bytes().expect("the test scene has a closure");
        write(&out.join("closure"), &format!("{}.bin", f.scene.name), &bytes);
    }

    let scenes = out.join("scene");
    for (f, text) in fixtures().iter().zip(crate::TEXTS) {
        write(&scenes, &format!("{}.json", f.scene.name), text.as_bytes());
        let toml = toml_of(&f.scene);
        write(&scenes, &format!("{}.toml", f.scene.name), toml.as_bytes());
    }
    // The paper scenes as they are (parsed, not built: the target builds small ones only).
    if let Ok(dir) = std::fs::read_dir(root.join("scenes")) {
        for e in dir.flatten() {
            let p = e.path();
            if p.extension().is_some_and(|x| x == "json") {
                let text = std::fs::read(&p).expect("read a scene");
                write(&scenes, &p.file_name().unwrap().to_string_lossy(), &text);
            }
        }
    }

    let states = out.join("fmu_state");
    for (k, f) in fixtures().iter().enumerate() {
        let name = &f.scene.name;
        let mut inst = initialised(k);
        write(&states, &format!("{name}-t0.bin"), &state(&mut inst));
        for _ in 0..3 {
            inst.do_step(inst.time(), 1e-3).expect("doStep");
        }
        write(&states, &format!("{name}-3ms.bin"), &state(&mut inst));
        // Inputs set (gravity, the group displacement, the load), then more steps.
        let vars = inst.table().vars.clone();
        for v in &vars {
            if matches!(
                v.quantity,
                Quantity::Gravity(_) | Quantity::GroupDisplacement(..) | Quantity::Load(..)
            ) {
                inst.set_real(&[v.value_reference], &[1e-4])
                    .expect("set an input");
            }
        }
        inst.do_step(inst.time(), 1e-3).expect("doStep");
        write(&states, &format!("{name}-inputs.bin"), &state(&mut inst));
        // A parameter changed before initialisation (the state carries other params).
        let mut inst = crate::instantiate(k);
        inst.setup_experiment(0.0, Some(1.0))
            .expect("setupExperiment");
        if let Some(v) = vars
            .iter()
            .find(|v| matches!(v.quantity, Quantity::Young(_)))
        {
            inst.set_real(&[v.value_reference], &[2e6])
                .expect("set young");
        }
        inst.enter_initialization_mode().expect("enter");
        write(
            &states,
            &format!("{name}-init-young.bin"),
            &state(&mut inst),
        );
    }
    println!("seeds written to {}", out.display());
}

/// TOML of a scene (through serde_json's value, without the nulls TOML cannot hold).
fn toml_of(scene: &mps_solid::Scene) -> String {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.retain(|_, x| !x.is_null());
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_str(&scene.to_json()).expect("json");
    strip(&mut v);
    toml::to_string(&v).expect("a scene as TOML")
}
