//! Inputs: the values of the inputs as the host set them, their derivatives for the next step,
//! and the FMU-level settings ([`GravitySource`], [`BoundaryTiming`]).
use crate::fmi::variables::{GRAVITY_FROM_INPUTS, GRAVITY_FROM_SCENE};
use crate::scene::Scene;
use serde::{Deserialize, Serialize};

/// Where the gravity vector comes from (Integer parameter `gravity_source`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum GravitySource {
    /// The scene's gravity law (constant, or the Eq. (46) ramp); the gravity inputs are ignored.
    Scene = GRAVITY_FROM_SCENE as isize,
    /// The inputs gravity_x/y/z, held over each step (or linear with input derivatives).
    Inputs = GRAVITY_FROM_INPUTS as isize,
}

impl GravitySource {
    /// The default of a scene: its own law when it has a time law (the ramp), else the inputs
    /// (whose start values are the scene's constant vector, so both agree until a host sets them).
    pub fn default_for(scene: &Scene) -> Self {
        if scene.gravity.paper_ramp_period.is_some() {
            GravitySource::Scene
        } else {
            GravitySource::Inputs
        }
    }
    pub fn from_int(v: i32) -> Option<Self> {
        match v {
            GRAVITY_FROM_SCENE => Some(GravitySource::Scene),
            GRAVITY_FROM_INPUTS => Some(GravitySource::Inputs),
            _ => None,
        }
    }
}

/// When a boundary displacement input takes effect (Integer parameter `boundary_input_timing`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum BoundaryTiming {
    /// FMI 2.0 semantics, what generic masters (fmpy, fmusim, libcosim) expect: the value set
    /// before doStep(t, h) is the displacement at t, held over the step, or extrapolated linearly
    /// with the derivative of fmi2SetRealInputDerivatives.
    AtStepStart = 1,
    /// The value set before doStep(t, h) is reached at t + h, moving linearly from where the
    /// group is: a smooth motion that lags the master's signal by one communication step.
    AtStepEnd = 2,
}

impl BoundaryTiming {
    pub fn from_int(v: i32) -> Option<Self> {
        match v {
            1 => Some(BoundaryTiming::AtStepStart),
            2 => Some(BoundaryTiming::AtStepEnd),
            _ => None,
        }
    }
}

/// Values of the inputs as the host set them (start values until then), their first
/// derivatives for the next step, and the FMU-level settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(super) struct Inputs {
    pub(super) gravity: [f64; 3],
    pub(super) displacement: Vec<[f64; 3]>,
    pub(super) load: Vec<[f64; 3]>,
    /// d/dt of the inputs, set by fmi2SetRealInputDerivatives for the next doStep only.
    pub(super) gravity_rate: [f64; 3],
    pub(super) displacement_rate: Vec<[f64; 3]>,
    pub(super) load_rate: Vec<[f64; 3]>,
    pub(super) gravity_source: GravitySource,
    pub(super) boundary_timing: BoundaryTiming,
}

impl Inputs {
    pub(super) fn start(scene: &Scene) -> Self {
        let mut gravity = [0.0; 3];
        for (k, g) in scene.gravity.vector.iter().take(3).enumerate() {
            gravity[k] = *g;
        }
        Inputs {
            gravity,
            displacement: vec![[0.0; 3]; scene.boundaries.len()],
            load: vec![[0.0; 3]; scene.loads.len()],
            gravity_rate: [0.0; 3],
            displacement_rate: vec![[0.0; 3]; scene.boundaries.len()],
            load_rate: vec![[0.0; 3]; scene.loads.len()],
            gravity_source: GravitySource::default_for(scene),
            boundary_timing: BoundaryTiming::AtStepStart,
        }
    }
    pub(super) fn clear_rates(&mut self) {
        self.gravity_rate = [0.0; 3];
        self.displacement_rate
            .iter_mut()
            .for_each(|r| *r = [0.0; 3]);
        self.load_rate.iter_mut().for_each(|r| *r = [0.0; 3]);
    }
    pub(super) fn fits(&self, scene: &Scene) -> bool {
        self.displacement.len() == scene.boundaries.len()
            && self.displacement_rate.len() == scene.boundaries.len()
            && self.load.len() == scene.loads.len()
            && self.load_rate.len() == scene.loads.len()
    }
}
