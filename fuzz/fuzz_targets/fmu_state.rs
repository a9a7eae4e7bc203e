//! Fuzz target: FMU-state deserialisation. The bytes are a serialised FMU state (the corpus
//! holds real ones of small2d and small3d, so mutations reach the decoder and the restore);
//! `deserialize_fmu_state` then `set_fmu_state` on a fresh initialised instance must fail
//! cleanly or restore a state that reads back unchanged, with finite outputs.
//! With MPS_FUZZ_SEEDS=DIR the binary writes the seeds of all targets and exits;
//! MPS_FUZZ_TRACE=1 prints the outcome of the restore.
#![no_main]
use libfuzzer_sys::fuzz_target;
use mps_fuzz::{all_inputs, fixtures, initialised, state_in_known_bounds, FIXTURES};
use mps_solid::fmi::instance::{FmuState, Instance};
use std::cell::RefCell;

fuzz_target!(init: {
    // scripts/fuzz.sh: MPS_FUZZ_SEEDS=DIR writes the seed inputs of every target and exits.
    if let Some(dir) = std::env::var_os("MPS_FUZZ_SEEDS") {
        mps_fuzz::seeds::write_seeds(std::path::Path::new(&dir));
        std::process::exit(0);
    }
}, |data: &[u8]| {
    // The GUID after the 16-byte header says which scene made the state (default small2d).
    let k = fixtures()
        .iter()
        .position(|f| data.get(16..16 + f.guid.len()) == Some(f.guid.as_bytes()))
        .unwrap_or(0);
    // States carry a CRC-32 of everything before it (tested in tests/fmi_host.rs): recompute
    // it so that mutations reach the decoder and the restore instead of stopping at the check.
    let mut data = data.to_vec();
    if data.len() >= 4 {
        let n = data.len() - 4;
        let crc = crc32fast::hash(&data[..n]);
        data[n..].copy_from_slice(&crc.to_le_bytes());
    }
    let data = &data[..];
    let (mut inst, pristine) = take(k);
    let Ok(state) = inst.deserialize_fmu_state(data) else {
        put(k, inst, pristine);
        return;
    };
    // What was decoded serialises to the same bytes and decodes to the same state.
    let bytes = inst.serialize_fmu_state(&state).expect("serialise a decoded state");
    let again = inst
        .deserialize_fmu_state(&bytes)
        .expect("a re-serialised state decodes");
    // Bytes, not PartialEq: a decoded state may hold NaNs.
    let bytes2 = inst.serialize_fmu_state(&again).expect("serialise");
    assert!(bytes2 == bytes, "serialise/deserialise round trip changes the state");

    if !all_inputs() && !state_in_known_bounds(&state) {
        put(k, inst, pristine);
        return;
    }
    let restored = inst.set_fmu_state(&state);
    if std::env::var_os("MPS_FUZZ_TRACE").is_some() {
        eprintln!("decoded; set_fmu_state: {restored:?}");
    }
    if restored.is_err() {
        // Not reused: a refused restore may have changed the instance (issue 8 item 8).
        return;
    }
    let n = inst.table().vars.len() as u32;
    let reals: Vec<u32> = (0..n)
        .filter(|&r| inst.get_real(&[r], &mut [0.0]).is_ok())
        .collect();
    let mut out = vec![0.0; reals.len()];
    if inst.get_real(&reals, &mut out).is_ok() {
        for (r, x) in reals.iter().zip(&out) {
            assert!(x.is_finite(), "fmi2GetReal returned {x} for vr {r} ('{}') with fmi2OK",
                inst.table().vars[*r as usize].name);
        }
    }
    let back = inst.get_fmu_state().expect("get a state just restored");
    let back_bytes = inst.serialize_fmu_state(&back).expect("serialise");
    if back_bytes != bytes && !mps_fuzz::same_state(&state, &back) {
        // The particles that follow a clamp (the layers behind a clamped face) are derived
        // from the particles they follow on restore: a state from elsewhere whose followers
        // disagree comes back with them re-derived, and nothing else may change. The state
        // read back is then restored as it is (a fixed point).
        let changed = mps_fuzz::differences(&state, &back);
        assert!(
            changed.iter().all(|p| mps_fuzz::is_particle_motion(p)),
            "get_fmu_state after set_fmu_state differs from the state set beyond re-derived \
             followers: {} ({})",
            mps_fuzz::first_difference(&state, &back),
            mps_fuzz::first_byte_difference(&bytes, &back_bytes)
        );
        inst.set_fmu_state(&back).expect("restore a state just read back");
        let again = inst.get_fmu_state().expect("get");
        let again_bytes = inst.serialize_fmu_state(&again).expect("serialise");
        assert!(
            again_bytes == back_bytes || mps_fuzz::same_state(&back, &again),
            "restoring a restored state changes it: {}",
            mps_fuzz::first_difference(&back, &again)
        );
    }
    if all_inputs() {
        // Needs a step-count limit: a mutated state can make the stable step tiny.
        let t = inst.time();
        let _ = inst.do_step(t, 1e-4);
    }
    put(k, inst, pristine);
});

thread_local! {
    /// An initialised instance per scene with its state at t = 0, reused across inputs (a
    /// build costs ~10 ms; a restore much less).
    static CACHE: RefCell<[Option<(Instance, FmuState)>; FIXTURES]> = const { RefCell::new([None, None, None, None]) };
}

/// The cached instance of scene k restored to t = 0 (bit for bit: checked by the target on
/// every restore), or a fresh one.
fn take(k: usize) -> (Instance, FmuState) {
    if let Some((mut inst, s)) = CACHE.with(|c| c.borrow_mut()[k].take()) {
        inst.set_fmu_state(&s).expect("restore the initial state");
        return (inst, s);
    }
    let mut inst = initialised(k);
    let s = inst.get_fmu_state().expect("initial state");
    (inst, s)
}

fn put(k: usize, inst: Instance, pristine: FmuState) {
    CACHE.with(|c| c.borrow_mut()[k] = Some((inst, pristine)));
}
