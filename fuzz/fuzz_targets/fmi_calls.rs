//! Fuzz target: FMI call sequences on the safe instance API, as a hostile host would make them:
//! any order, random value references, NaN/inf/-0.0 and extreme values, steps at wrong times,
//! FMU states taken, serialised (with bit flips), restored, freed; reset and terminate.
//! Any panic is a bug. Oracles besides "no panic": a Real read with fmi2OK is finite, a
//! state restored reads back bit for bit, serialise/deserialise is the identity.
//! MPS_FUZZ_TRACE=1 prints each call and the instance's mode after it.
#![no_main]
use arbitrary::Arbitrary;
use libfuzzer_sys::fuzz_target;
use mps_fuzz::{all_inputs, fixtures, instantiate, state_in_known_bounds, FIXTURES};
use mps_solid::fmi::instance::{FmuState, Instance};
use mps_solid::fmi::model_description::LOG_CATEGORIES;
use mps_solid::fmi::variables::{Quantity, VariableTable};
use std::cell::RefCell;

/// A value of a call argument.
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Real {
    /// One of NaN, +-inf, -0.0, 0.0, +-1, MIN_POSITIVE, MAX, 1e-30, 1e30, -1e300...
    Special(u8),
    /// The start value of the variable times 2^(k/32) (k in -128..127): accepted values.
    Scaled(i8),
    /// Any bit pattern.
    Bits(u64),
}

const SPECIAL: [f64; 16] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    -0.0,
    0.0,
    1.0,
    -1.0,
    f64::MIN_POSITIVE,
    f64::MAX,
    -f64::MAX,
    1e-30,
    1e30,
    -1e300,
    5e-324,
    0.49999999999999994,
    -9.809999999999999,
];

/// A value reference: mostly one of the FMU's, sometimes any.
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Vr {
    Known(u8),
    Any(u32),
}

/// Time argument of fmi2DoStep.
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Time {
    /// The instance's time (the correct call).
    Now,
    /// The instance's time plus k 1e-11 (relative): inside the tolerance 1e-9 or just outside.
    Near(i8),
    Other(Real),
}

/// Step size of fmi2DoStep: bounded to 1 ms unless MPS_FUZZ_ALL=1 (a longer step of a stiff
/// model runs for minutes: issue 8 item 1).
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Step {
    /// (k + 1) / 256 ms.
    Small(u8),
    Other(Real),
}

#[derive(Arbitrary, Debug)]
enum Call {
    SetDebugLogging {
        on: bool,
        categories: Vec<u8>,
    },
    SetupExperiment {
        start: Real,
        stop: Option<Real>,
    },
    EnterInit,
    ExitInit,
    SetReal {
        vr: Vec<Vr>,
        values: Vec<Real>,
    },
    GetReal {
        vr: Vec<Vr>,
    },
    GetInteger {
        vr: Vec<Vr>,
    },
    SetInteger {
        vr: Vec<Vr>,
        values: Vec<i32>,
    },
    GetBoolean {
        vr: Vec<Vr>,
    },
    SetString {
        vr: Vec<Vr>,
    },
    DoStep {
        t: Time,
        h: Step,
    },
    /// The usual call: doStep(t, (k + 1) / 256 ms) at the instance's time.
    StepNow(u8),
    CancelStep,
    Status {
        kind: i32,
    },
    GetState {
        slot: u8,
    },
    SetState {
        slot: u8,
    },
    FreeState {
        slot: u8,
    },
    Serialize {
        slot: u8,
    },
    /// Deserialise buffer `slot`, optionally with one bit flipped, into state `slot`.
    Deserialize {
        slot: u8,
        flip: Option<u32>,
    },
    Reset,
    Terminate,
}

/// Where the sequence starts: the usual calls a host makes first, so that most inputs reach
/// stepping (the fuzzer would otherwise spend most runs finding that prefix).
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Start {
    Instantiated,
    InitializationMode,
    StepComplete,
}

#[derive(Arbitrary, Debug)]
struct Input {
    /// The scene: fixtures()[scene % FIXTURES] (tiny2d/tiny3d half of the time).
    scene: u8,
    start: Start,
    calls: Vec<Call>,
}

const SLOTS: usize = 4;
/// doSteps per input: bounds the time an input takes (each is up to ~10 solver steps).
const MAX_STEPS: usize = 24;

struct Harness {
    inst: Instance,
    /// Index of the scene in `fixtures()`.
    fixture: usize,
    states: [Option<FmuState>; SLOTS],
    buffers: [Option<Vec<u8>>; SLOTS],
    steps: usize,
}

impl Harness {
    fn vr(&self, v: Vr) -> u32 {
        let n = self.inst.table().vars.len() as u32;
        match v {
            Vr::Known(k) => k as u32 % n,
            Vr::Any(r) => r,
        }
    }

    /// The value of a Real argument for value reference `vr`.
    fn value(&self, vr: u32, x: Real) -> f64 {
        match x {
            Real::Special(k) => {
                let v = SPECIAL[k as usize % SPECIAL.len()];
                // A parameter with an accepted extreme value makes a step take hours.
                if !all_inputs() && v.is_finite() && v != 0.0 && self.is_parameter(vr) {
                    return self.scaled(vr, 0);
                }
                v
            }
            Real::Scaled(k) => self.scaled(vr, k),
            Real::Bits(b) => {
                let v = f64::from_bits(b);
                if !all_inputs() && v.is_finite() && self.is_parameter(vr) {
                    return self.scaled(vr, (b % 64) as i8 - 32);
                }
                v
            }
        }
    }

    fn is_parameter(&self, vr: u32) -> bool {
        self.inst.table().get(vr).is_some_and(|v| {
            matches!(
                v.quantity,
                Quantity::Density(_)
                    | Quantity::Young(_)
                    | Quantity::Poisson(_)
                    | Quantity::SolverDt
                    | Quantity::Damping
                    | Quantity::FractureStrain
            )
        })
    }

    /// Start value times 2^(k/32), kept in a range where a 1 ms step takes at most ~1000
    /// solver steps of the small scenes unless MPS_FUZZ_ALL=1.
    fn scaled(&self, vr: u32, k: i8) -> f64 {
        let f = 2f64.powf(k as f64 / 32.0);
        let Some(v) = self.inst.table().get(vr) else {
            return f;
        };
        let scene = &fixtures()[self.fixture].scene;
        let start = VariableTable::parameter_value(scene, v.quantity).unwrap_or(0.0);
        match v.quantity {
            Quantity::Density(_) | Quantity::Young(_) => start * f.clamp(0.25, 4.0),
            Quantity::Poisson(_) => (k as f64 / 128.0 * 0.9).clamp(-0.9, 0.45),
            // 0 = automatic; else 1 us .. 16 us (blows up above the stable step: fine).
            Quantity::SolverDt => {
                if k < 0 {
                    0.0
                } else {
                    1e-6 * f
                }
            }
            Quantity::Damping => (k as f64).abs(),
            Quantity::FractureStrain => (k as f64).max(0.0) * 1e-3,
            Quantity::Gravity(k) => match scene.gravity.vector.get(k) {
                Some(&g) if g != 0.0 => g * f,
                _ => (f - 1.0) * 10.0,
            },
            // Inputs a model follows without blowing up in 1 ms: mm and tens of newtons.
            Quantity::GroupDisplacement(..) => (f - 1.0) * 1e-3,
            Quantity::Load(..) => (f - 1.0) * 10.0,
            _ => f - 1.0,
        }
    }

    fn call(&mut self, c: Call) {
        match c {
            Call::SetDebugLogging { on, categories } => {
                let cats: Vec<String> = categories
                    .iter()
                    .take(6)
                    .map(|&k| match LOG_CATEGORIES.get(k as usize % 5) {
                        Some((n, _)) => n.to_string(),
                        None => format!("bad{k}"),
                    })
                    .collect();
                let _ = self.inst.set_debug_logging(on, &cats);
            }
            Call::SetupExperiment { start, stop } => {
                let start = self.value(u32::MAX, start);
                let stop = stop.map(|s| self.value(u32::MAX, s));
                let _ = self.inst.setup_experiment(start, stop);
            }
            Call::EnterInit => {
                let _ = self.inst.enter_initialization_mode();
            }
            Call::ExitInit => {
                let _ = self.inst.exit_initialization_mode();
            }
            Call::SetReal { vr, values } => {
                let vr: Vec<u32> = vr.iter().take(8).map(|&v| self.vr(v)).collect();
                let values: Vec<f64> = vr
                    .iter()
                    .zip(values.iter().chain(std::iter::repeat(&Real::Scaled(0))))
                    .map(|(&r, &x)| self.value(r, x))
                    .collect();
                let _ = self.inst.set_real(&vr, &values);
            }
            Call::GetReal { vr } => {
                let vr: Vec<u32> = vr.iter().take(32).map(|&v| self.vr(v)).collect();
                let mut out = vec![0.0; vr.len()];
                if self.inst.get_real(&vr, &mut out).is_ok() {
                    for (r, x) in vr.iter().zip(&out) {
                        assert!(
                            x.is_finite(),
                            "fmi2GetReal returned {x} for vr {r} ('{}') with fmi2OK",
                            self.inst.table().vars[*r as usize].name
                        );
                    }
                }
            }
            Call::GetInteger { vr } => {
                let vr: Vec<u32> = vr.iter().take(8).map(|&v| self.vr(v)).collect();
                let mut out = vec![0; vr.len()];
                let _ = self.inst.get_integer(&vr, &mut out);
            }
            Call::SetInteger { vr, values } => {
                let vr: Vec<u32> = vr.iter().take(8).map(|&v| self.vr(v)).collect();
                let n = vr.len().min(values.len());
                let _ = self.inst.set_integer(&vr[..n], &values[..n]);
            }
            Call::GetBoolean { vr } => {
                let vr: Vec<u32> = vr.iter().take(8).map(|&v| self.vr(v)).collect();
                let _ = self.inst.get_none("fmi2GetBoolean", "Boolean", &vr);
            }
            Call::SetString { vr } => {
                let vr: Vec<u32> = vr.iter().take(8).map(|&v| self.vr(v)).collect();
                let _ = self.inst.set_none("fmi2SetString", "String", &vr);
            }
            Call::StepNow(k) => self.call(Call::DoStep {
                t: Time::Now,
                h: Step::Small(k),
            }),
            Call::DoStep { t, h } => {
                if self.steps >= MAX_STEPS {
                    return;
                }
                self.steps += 1;
                let now = self.inst.time();
                let t = match t {
                    Time::Now => now,
                    Time::Near(k) => now + k as f64 * 1e-11 * now.abs().max(1.0),
                    Time::Other(x) => self.value(u32::MAX, x),
                };
                let h = match h {
                    Step::Small(k) => 1e-3 * (k as f64 + 1.0) / 256.0,
                    Step::Other(x) => {
                        let h = self.value(u32::MAX, x);
                        if !all_inputs() && h.is_finite() && h > 1e-3 {
                            1e-3
                        } else {
                            h
                        }
                    }
                };
                let _ = self.inst.do_step(t, h);
            }
            Call::CancelStep => {
                let _ = self.inst.cancel_step();
            }
            Call::Status { kind } => {
                let _ = self.inst.get_status(kind);
                let _ = self.inst.get_real_status(kind);
                let _ = self.inst.get_integer_status(kind);
                let _ = self.inst.get_boolean_status(kind);
                let _ = self.inst.get_string_status(kind);
            }
            Call::GetState { slot } => {
                if let Ok(s) = self.inst.get_fmu_state() {
                    self.states[slot as usize % SLOTS] = Some(s);
                }
            }
            Call::SetState { slot } => {
                let Some(s) = self.states[slot as usize % SLOTS].clone() else {
                    return;
                };
                if self.inst.set_fmu_state(&s).is_ok() {
                    let back = self
                        .inst
                        .get_fmu_state()
                        .expect("get a state just restored");
                    let a = self.inst.serialize_fmu_state(&s).expect("serialise");
                    let b = self.inst.serialize_fmu_state(&back).expect("serialise");
                    assert!(
                        a == b || mps_fuzz::same_state(&s, &back),
                        "get_fmu_state after set_fmu_state differs: {}",
                        mps_fuzz::first_difference(&s, &back)
                    );
                }
            }
            Call::FreeState { slot } => {
                if self.inst.free_fmu_state().is_ok() {
                    self.states[slot as usize % SLOTS] = None;
                }
            }
            Call::Serialize { slot } => {
                let i = slot as usize % SLOTS;
                if let Some(s) = &self.states[i] {
                    if let Ok(b) = self.inst.serialize_fmu_state(s) {
                        let back = self
                            .inst
                            .deserialize_fmu_state(&b)
                            .expect("a state just serialised decodes");
                        let b2 = self.inst.serialize_fmu_state(&back).expect("serialise");
                        assert!(
                            b == b2,
                            "serialise/deserialise round trip changes the state"
                        );
                        self.buffers[i] = Some(b);
                    }
                }
            }
            Call::Deserialize { slot, flip } => {
                let i = slot as usize % SLOTS;
                let Some(mut b) = self.buffers[i].clone() else {
                    return;
                };
                if let Some(bit) = flip {
                    let bit = bit as usize % (8 * b.len());
                    b[bit / 8] ^= 1 << (bit % 8);
                }
                if let Ok(s) = self.inst.deserialize_fmu_state(&b) {
                    // A flipped bit in a parameter can make the next step run for hours or
                    // build a huge model (issue 8 items 1, 2): unless MPS_FUZZ_ALL=1, keep
                    // only states with the parameters of the original and in known bounds.
                    let same_params = |a: &FmuState, b: &FmuState| {
                        let p = |s: &FmuState| {
                            serde_json::to_value(s).ok().map(|v| v["params"].clone())
                        };
                        p(a).is_some_and(|x| Some(x) == p(b))
                    };
                    let original = self
                        .inst
                        .deserialize_fmu_state(&self.buffers[i].clone().unwrap_or_default());
                    let keep = all_inputs()
                        || (state_in_known_bounds(&s)
                            && original.is_ok_and(|o| same_params(&o, &s)));
                    if keep {
                        self.states[i] = Some(s);
                    }
                }
            }
            Call::Reset => {
                let _ = self.inst.reset();
            }
            Call::Terminate => {
                let _ = self.inst.terminate();
            }
        }
    }
}

thread_local! {
    /// An instance per scene in StepComplete with its state at t = 0, reused by the inputs that
    /// start there (a model build costs ~10 ms, a restore far less).
    static CACHE: RefCell<[Option<(Instance, FmuState)>; FIXTURES]> = const { RefCell::new([None, None, None, None]) };
}

/// An instance of scene k in StepComplete at t = 0: the cached one restored to its initial
/// state (logging as instantiated), or a fresh one.
fn step_complete(k: usize) -> (Instance, FmuState) {
    if let Some((mut inst, s)) = CACHE.with(|c| c.borrow_mut()[k].take()) {
        if inst.set_debug_logging(true, &[]).is_ok() && inst.set_fmu_state(&s).is_ok() {
            return (inst, s);
        }
    }
    let mut inst = instantiate(k);
    inst.setup_experiment(0.0, None).expect("setupExperiment");
    inst.enter_initialization_mode()
        .expect("enterInitializationMode");
    inst.exit_initialization_mode()
        .expect("exitInitializationMode");
    let s = inst.get_fmu_state().expect("initial state");
    (inst, s)
}

fuzz_target!(|input: Input| {
    let k = [2, 3, 2, 3, 0, 1, 2, 3][input.scene as usize % 8];
    let (inst, pristine) = match input.start {
        Start::StepComplete => {
            let (i, s) = step_complete(k);
            (i, Some(s))
        }
        Start::InitializationMode => {
            let mut i = instantiate(k);
            i.setup_experiment(0.0, None).expect("setupExperiment");
            i.enter_initialization_mode()
                .expect("enterInitializationMode");
            (i, None)
        }
        Start::Instantiated => (instantiate(k), None),
    };
    let mut h = Harness {
        inst,
        fixture: k,
        states: Default::default(),
        buffers: Default::default(),
        steps: 0,
    };
    let trace = std::env::var_os("MPS_FUZZ_TRACE").is_some();
    for c in input.calls.into_iter().take(256) {
        if trace {
            eprintln!("{c:?}");
        }
        h.call(c);
        if trace {
            eprintln!("  -> mode {:?}, t = {}", h.inst.mode(), h.inst.time());
        }
    }
    let _ = h.inst.terminate();
    if let Some(s) = pristine {
        CACHE.with(|c| c.borrow_mut()[k] = Some((h.inst, s)));
    }
});
