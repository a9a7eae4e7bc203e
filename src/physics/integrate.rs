//! Symplectic Euler, Eqs. (37)-(40), and the stable time step of the particle model, measured by
//! the Lanczos process on its own stiffness (springs, pressure and rotational degrees of freedom).
use super::dim::{Dim, Space, Vect};
#[allow(unused_imports)]
use super::par::*;
use super::particles::{Particles, FIX_AXIS, FIX_ROT};
use crate::par_iter_mut;

/// Per-step inputs of the integrator that are the same for all particles.
pub struct StepInputs<'a, const D: usize> {
    /// Length of this step (s): the drift, Eqs. (38) and (40).
    pub dt: f64,
    /// Time over which this step's forces change the velocities (s), Eqs. (37) and (39): the
    /// velocities are those of the step that led here, so with steps of unequal length the
    /// forces at t_n act over half of each, (dt_previous + dt) / 2 (Stormer-Verlet with
    /// variable steps); with equal steps it is dt. See `World::previous_step`.
    pub kick_dt: f64,
    pub gravity: Vect<D>,
    /// Mass-proportional damping (1/s).
    pub damping: f64,
    /// Per particle: boundary group index or u32::MAX.
    pub group_of: &'a [u32],
    /// Per group: displacement at the start and at the end of the step.
    pub group_disp: &'a [(Vect<D>, Vect<D>)],
    /// Per particle: load region index or u32::MAX.
    pub load_of: &'a [u32],
    /// Per load region: force per particle (N).
    pub load_per_particle: &'a [Vect<D>],
    /// A step whose forces move a particle farther than this (dt times the change of velocity,
    /// i.e. the part of the motion not carried over from the previous step) is a numerical
    /// blow-up (m). A rigid motion, however fast, is not.
    pub max_move: f64,
}

/// Advances velocities and positions by one step, Eqs. (37)-(40), given the internal forces and
/// moments at the current state. Returns the index of the first particle whose new state is not
/// finite or moved more than `max_move` (a blow-up), if any.
pub fn symplectic_euler<const D: usize>(
    p: &mut Particles<D>,
    force: &[Vect<D>],
    torque: &[<Space as Dim<D>>::Ang],
    inp: &StepInputs<'_, D>,
    bad: &mut [u8],
) -> Option<usize>
where
    Space: Dim<D>,
{
    let (dt, kick) = (inp.dt, inp.kick_dt);
    let Particles {
        x0,
        u,
        x,
        v,
        q,
        w,
        mass,
        inertia,
        fix,
        ..
    } = p;
    par_iter_mut!(u)
        .zip(par_iter_mut!(x))
        .zip(par_iter_mut!(v))
        .zip(par_iter_mut!(q))
        .zip(par_iter_mut!(w))
        .zip(par_iter_mut!(bad))
        .enumerate()
        .for_each(|(i, (((((ui, xi), vi), qi), wi), bi))| {
            let m = mass[i];
            let mut f = force[i] + inp.gravity * m - *vi * (inp.damping * m);
            let l = inp.load_of[i];
            if l != u32::MAX {
                f += inp.load_per_particle[l as usize];
            }
            // Eq. (37) and (38), on the displacement u = x - X (full precision far from the
            // origin; x is derived).
            let mut vn = *vi + f * (kick / m);
            let mut un = *ui + vn * dt;
            let flags = fix[i];
            if flags != 0 {
                let g = inp.group_of[i];
                let (d_start, d_end) = if g == u32::MAX {
                    (Vect::<D>::zeros(), Vect::<D>::zeros())
                } else {
                    inp.group_disp[g as usize]
                };
                for k in 0..D {
                    if flags & FIX_AXIS[k] != 0 {
                        un[k] = d_end[k];
                        vn[k] = (d_end[k] - d_start[k]) / dt;
                    }
                }
            }
            // Eq. (39) and (40)
            if flags & FIX_ROT == 0 {
                *wi = <Space as Dim<D>>::ang_add(
                    *wi,
                    <Space as Dim<D>>::ang_scale(torque[i], kick / inertia[i]),
                );
                // Without an angular velocity the orientation stays as it is (the energy
                // operators have no moments: their particles never turn), and the quaternion
                // exponential is skipped.
                if *wi != <Space as Dim<D>>::ang_zero() {
                    *qi = <Space as Dim<D>>::advance(qi, wi, dt);
                }
            }
            // Motion due to this step's internal, contact and damping forces: an unstable mode
            // grows by a factor > 1 per step in acceleration, while a rigid translation has
            // none. Gravity and loads are given accelerations that cannot make a mode grow (a
            // strong gravity moves a particle far in a step without any instability), and held
            // axes follow their prescribed motion (a body thrown at its support is stopped
            // there in one step): neither is counted.
            let mut dv = (force[i] - *vi * (inp.damping * m)) * (dt / m);
            for k in 0..D {
                if flags & FIX_AXIS[k] != 0 {
                    dv[k] = 0.0;
                }
            }
            let moved = (dv * dt).norm();
            *bi = u8::from(
                moved.is_nan()
                    || moved > inp.max_move
                    || !vn.iter().all(|c| c.is_finite())
                    || !<Space as Dim<D>>::ang_finite(wi),
            );
            *ui = un;
            *xi = x0[i] + un;
            *vi = vn;
        });
    bad.iter().position(|&b| b != 0)
}

/// Critical step of symplectic Euler for the largest angular frequency of the linearised model
/// with mass-proportional damping c (1/s), -c m v evaluated explicitly with the velocity at the
/// start of the step. The amplification matrix of one mode has determinant 1 - c dt and trace
/// 2 - c dt - omega^2 dt^2; both eigenvalues lie in the unit circle (Jury) when c dt <= 2 and
/// omega^2 dt^2 + 2 c dt <= 4, i.e.
///
///   dt <= (2 / omega) (sqrt(1 + zeta^2) - zeta),   zeta = c / (2 omega),
///
/// which is 2 / omega without damping and tends to 2 / c for omega -> 0 (the rigid modes are
/// damped too). The bound decreases with omega, so omega_max sets it.
pub fn critical_step(omega_max: f64, damping: f64) -> f64 {
    let c = damping.max(0.0);
    if omega_max > 0.0 {
        let zeta = c / (2.0 * omega_max);
        // (sqrt(1 + z^2) - z) written as 1 / (sqrt(1 + z^2) + z): no cancellation at large z.
        2.0 / omega_max / ((1.0 + zeta * zeta).sqrt() + zeta)
    } else if c > 0.0 {
        2.0 / c
    } else {
        f64::INFINITY
    }
}
