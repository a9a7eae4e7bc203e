//! Boundary groups (clamped, pinned, prescribed motion), their displacement laws and reactions;
//! external load regions; the gravity law including the paper's ramp, Eq. (46).
use super::dim::Vect;
use serde::{Deserialize, Serialize};

/// A set of particles whose translation is prescribed along some axes (and optionally whose
/// rotation is held). Clamped: all axes and the rotation; pinned: some axes, rotation free;
/// prescribed: some axes follow a displacement set from outside, rotation held.
#[derive(Clone, Debug)]
pub struct BoundaryGroup<const D: usize> {
    pub name: String,
    pub members: Vec<u32>,
    /// Axes whose translation is prescribed.
    pub axes: [bool; 3],
    /// Whether the rotation is held at its initial value.
    pub fix_rotation: bool,
    pub motion: GroupMotion<D>,
    /// Force the group exerts on the rest of the body through the bonds, with the sign of a
    /// support reaction: minus the internal force on the members, along the prescribed axes (N).
    pub reaction: Vect<D>,
}

/// Displacement of a group: linear in time from `from` at `t_from` to `to` at `t_to`, constant
/// afterwards. The FMI layer sets `to` for the end of each communication step, so a host's
/// piecewise-constant input becomes a continuous motion.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct GroupMotion<const D: usize> {
    pub from: Vect<D>,
    pub to: Vect<D>,
    pub t_from: f64,
    pub t_to: f64,
}

impl<const D: usize> Default for GroupMotion<D> {
    fn default() -> Self {
        GroupMotion {
            from: Vect::<D>::zeros(),
            to: Vect::<D>::zeros(),
            t_from: 0.0,
            t_to: 0.0,
        }
    }
}

impl<const D: usize> GroupMotion<D> {
    /// Displacement at time t (m).
    pub fn at(&self, t: f64) -> Vect<D> {
        if t >= self.t_to || self.t_to <= self.t_from {
            return self.to;
        }
        let s = ((t - self.t_from) / (self.t_to - self.t_from)).clamp(0.0, 1.0);
        self.from + (self.to - self.from) * s
    }
}

/// A region of particles that shares an external force set from outside.
#[derive(Clone, Debug)]
pub struct LoadRegion<const D: usize> {
    pub name: String,
    pub members: Vec<u32>,
    /// Total force on the region at time `t_ref` (N), spread evenly over its particles.
    pub force: Vect<D>,
    /// Rate of change of the total force (N/s): the force is `force + rate (t - t_ref)`, so that
    /// an FMU input with a derivative (fmi2SetRealInputDerivatives) varies over a step.
    pub rate: Vect<D>,
    /// Time at which the force equals `force` (s).
    pub t_ref: f64,
}

impl<const D: usize> LoadRegion<D> {
    /// Total force at time t (N).
    pub fn force_at(&self, t: f64) -> Vect<D> {
        if self.rate == Vect::<D>::zeros() {
            self.force
        } else {
            self.force + self.rate * (t - self.t_ref)
        }
    }
}

/// Gravity as a function of time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(bound = "")]
pub enum GravityLaw<const D: usize> {
    /// A constant acceleration (m/s^2), e.g. set by an FMU host every communication step.
    Constant(Vect<D>),
    /// The paper's ramp, Eq. (46): g(t) = G (0.5 - 0.5 cos(5 pi t / T)) for t <= 0.2 T, G after.
    PaperRamp { full: Vect<D>, period: f64 },
    /// Linear in time: `start + rate (t - t0)` (m/s^2, m/s^3, s); an FMU host's gravity input
    /// with its derivative over one communication step.
    Linear {
        start: Vect<D>,
        rate: Vect<D>,
        t0: f64,
    },
}

impl<const D: usize> GravityLaw<D> {
    /// Gravity at time t (m/s^2).
    pub fn at(&self, t: f64) -> Vect<D> {
        match *self {
            GravityLaw::Constant(g) => g,
            GravityLaw::PaperRamp { full, period } => full * paper_ramp(t, period),
            GravityLaw::Linear { start, rate, t0 } => start + rate * (t - t0),
        }
    }
}

/// The factor of Eq. (46).
pub fn paper_ramp(t: f64, period: f64) -> f64 {
    if t <= 0.2 * period {
        0.5 - 0.5 * (5.0 * std::f64::consts::PI * t / period).cos()
    } else {
        1.0
    }
}
