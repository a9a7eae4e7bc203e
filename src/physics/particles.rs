//! Per-particle state as parallel arrays: reference position, displacement (the state), current
//! position, velocity, orientation, angular velocity, body, mass, inertia, constraint flags.
//!
//! The displacement u = x - X is what evolves; the current position x = X + u is derived from it
//! (output, cell grids). Relative vectors are formed as (X_j - X_i) + (u_j - u_i), never as
//! x_j - x_i: an offset of the whole scene cancels exactly in X_j - X_i, and u keeps full
//! precision however far from the origin the body sits (see docs/model.md).
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
    /// Displacements u = x - X (m): the evolving state.
    pub u: Vec<Vect<D>>,
    /// Current positions x = X + u (m), derived from `u` (output and cell grids only).
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
    /// Number of particles: the length of the state `u` (a probe state of the power iteration
    /// holds only what the elastic operators read).
    pub fn len(&self) -> usize {
        self.u.len()
    }
    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }
    /// Displacement x - X of particle i (m).
    pub fn displacement(&self, i: usize) -> Vect<D> {
        self.u[i]
    }
    /// Recomputes the current positions x = X + u from the displacements.
    pub fn sync_positions(&mut self) {
        for ((x, x0), u) in self.x.iter_mut().zip(&self.x0).zip(&self.u) {
            *x = x0 + u;
        }
    }
}

/// The vector from particle i to particle j in the current configuration, formed as
/// (X_j - X_i) + (u_j - u_i) so that it does not depend on where the scene sits. Exactly
/// antisymmetric: rel(j, i) = -rel(i, j) bit for bit.
#[inline(always)]
pub fn rel<const D: usize>(x0: &[Vect<D>], u: &[Vect<D>], i: usize, j: usize) -> Vect<D> {
    (x0[j] - x0[i]) + (u[j] - u[i])
}
