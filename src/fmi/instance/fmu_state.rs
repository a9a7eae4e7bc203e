//! FMU state: the complete state of an instance as plain data ([`FmuState`]),
//! fmi2Get/Set/FreeFMUstate, and its serialised form with the checks of a state handed in.
use super::inputs::Inputs;
use super::lifecycle::{Built, Instance, Mode, SetupControl, SetupLog};
use super::status::{FmiError, FmiResult};
use crate::scene::Scene;
use crate::sim::{SimState, Simulation};
use serde::{Deserialize, Serialize};

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
/// Version 6: the state's scene carries `solver.max_setup_seconds`, a body its shapes and cuts,
/// a boundary group and a load region their selecting shape (issue 26). Version 7: the world's
/// state carries the length of the step that led to it (`WorldState::previous_step`).
const STATE_MAGIC: &[u8; 8] = b"MPSFMUST";
const STATE_VERSION: u32 = 7;
/// Largest serialised state accepted (bytes): bounds the allocations of a decoded state.
const MAX_STATE_BYTES: u64 = 1 << 34;

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
        self.log
            .event(&format!("FMU state captured at t = {}", self.time));
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
        // The model in hand serves a state of the parameters it was built with (also after
        // fmi2Reset or parameters set in between); another state's parameters need a build.
        let rebuild =
            self.sim.is_none() || !self.built.as_ref().is_some_and(|b| b.params == s.params);
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
            let started = std::time::Instant::now();
            // (Not cancellable, as before: fmi2CancelStep stops initialisation builds.)
            let control = SetupControl::default();
            let observer = SetupLog {
                logger: self.log.immediate("logEvents"),
                control: &control,
                memo: &self.memo,
            };
            let mut sim = self
                .pool
                .install(|| Simulation::new_observed(params, &observer))
                .map_err(|e| {
                    FmiError::Invalid(format!("cannot build the FMU state's model: {e}"))
                })?;
            let initial = self.pool.install(|| sim.state());
            let seconds = started.elapsed().as_secs_f64();
            self.pool.install(|| restore(&mut sim))?;
            let outputs = self.cheap_outputs(&sim)?;
            self.sim = Some(sim);
            self.built = Some(Built {
                params: s.params.clone(),
                initial,
                seconds,
            });
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
                Ok(o) => {
                    self.store_outputs(o);
                    self.params = s.params.clone();
                    self.stale = false;
                }
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
        self.log
            .event(&format!("FMU state restored at t = {}", self.time));
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
        let mut s: FmuState = Self::bincode()
            .deserialize(payload)
            .map_err(|e| bad(&format!("cannot decode: {e}")))?;
        // The folder of the scene's mesh files is not part of the data: it is this instance's
        // resources folder.
        s.params.base_dir = self.scene.base_dir.clone();
        self.check_state(&s)?;
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::small2d;
    use super::*;

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
}
