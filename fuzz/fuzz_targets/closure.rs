//! Fuzz target: the closure file an FMU ships (`resources/mps-closure.bin`, read by every
//! instance's first build). The bytes are a closure's (the seeds: small2d's and small3d's); the
//! header's length and CRC-32 are recomputed so that mutations reach the decoder. A decoded
//! closure is offered to the fixture's build of its dimension (it is taken when the mutation
//! spared the key and the sizes, so mutated sets and volumes reach the build's checks and the
//! force loops): the build must take it or compute its own, and the model step or fail with
//! an error, never panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use mps_fuzz::{fixtures, KeepClosure};
use mps_solid::physics::world::SetupMemo;
use mps_solid::Simulation;

fuzz_target!(|data: &[u8]| {
    let mut data = data.to_vec();
    if data.len() >= 40 {
        let n = (data.len() - 40) as u64;
        data[28..36].copy_from_slice(&n.to_le_bytes());
        let crc = crc32fast::hash(&data[40..]);
        data[36..40].copy_from_slice(&crc.to_le_bytes());
    }
    let Ok(memo) = SetupMemo::from_closure_bytes(&data) else {
        return;
    };
    // The dimension field picks small3d or small2d.
    let k = if data.get(16) == Some(&3) { 1 } else { 0 };
    let scene = &fixtures()[k].scene;
    let Ok(mut sim) = Simulation::new_observed(scene, &KeepClosure(memo)) else {
        return;
    };
    // Three steps (the fuzz build's forces are slow: software fused multiply-adds).
    let t = 3.0 * sim.max_dt();
    if t.is_finite() && sim.check_work(t).is_ok() {
        let _ = sim.advance_to(t);
    }
});
