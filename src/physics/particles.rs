//! Per-particle state as parallel arrays: reference and current position, velocity, orientation,
//! angular velocity, body, mass, inertia, constraint flags.
use super::dim::{Dim, Space, Vect};

/// Translation along axis k is prescribed when bit k is set.
pub const FIX_AXIS: [u8; 3] = [1, 2, 4];
/// Rotation is held at its initial value.
pub const FIX_ROT: u8 = 8;

/// Parallel arrays over all particles of all bodies.
#[derive(Clone, Debug)]
pub struct Particles<const D: usize>
where
    Space: Dim<D>,
{
    /// Reference (initial) positions X (m).
    pub x0: Vec<Vect<D>>,
    /// Current positions x (m).
    pub x: Vec<Vect<D>>,
    /// Velocities (m/s).
    pub v: Vec<Vect<D>>,
    /// Orientations (paper model).
    pub q: Vec<<Space as Dim<D>>::Rotation>,
    /// Angular velocities (rad/s).
    pub w: Vec<<Space as Dim<D>>::Ang>,
    /// Index of the body each particle belongs to.
    pub body: Vec<u32>,
    /// Mass rho l0^d (kg).
    pub mass: Vec<f64>,
    /// Moment of inertia (kg m^2).
    pub inertia: Vec<f64>,
    /// Constraint bits (FIX_AXIS, FIX_ROT).
    pub fix: Vec<u8>,
    /// Particle number density in the reference configuration, Eq. (12) (-).
    pub n_ref: Vec<f64>,
}

impl<const D: usize> Particles<D>
where
    Space: Dim<D>,
{
    pub fn len(&self) -> usize {
        self.x.len()
    }
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
    /// Displacement x - X of particle i (m).
    pub fn displacement(&self, i: usize) -> Vect<D> {
        self.x[i] - self.x0[i]
    }
}
