//! The stable step: omega_max measured by power iteration on the model's own forces, its
//! refresh in the current configuration as the body deforms, and the step it allows.
use super::World;
use crate::physics::dim::{Dim, Space, Vect};
use crate::physics::elastic::ElasticScratch;
use crate::physics::integrate::critical_step;
use crate::physics::params::ElasticModel;
use crate::physics::particles::{Particles, FIX_AXIS, FIX_ROT};
use serde::{Deserialize, Serialize};

/// Relative margin added to the measured largest angular frequency (-): the power iteration
/// under-estimates it (0.5 % in 3D after 80 iterations) and a deflected configuration is
/// stiffer than the reference one by 1-2 % (issue 7).
pub const OMEGA_MARGIN: f64 = 0.03;

/// Steps between two checks of whether the stable step must be measured again in the current
/// configuration (the check is one pass over the bonds, about 1/20 of a force evaluation).
pub const REFRESH_CHECK_EVERY: u64 = 20;

/// The stable step is measured again in the current configuration when some intact bond's
/// relative displacement has changed by more than this fraction of its reference length since
/// the last measurement (a strain or a rotation of 10 %; a rigid translation does not count) (-).
pub const REFRESH_DEFORMATION: f64 = 0.1;

/// Power iterations of a refresh, warm-started from the previous eigenvector.
pub const REFRESH_ITERATIONS: usize = 6;

/// Fewest steps between two refreshes: a refresh costs REFRESH_ITERATIONS + 1 force
/// evaluations, so this bounds its cost to 14 % of the steps' (reached only by bodies that
/// deform all the time: a soft strip collapsing under 100 g, 80 refreshes in 4800 steps; a
/// cantilever bent to half its length: 1-3 % of the run time). 200 was too slow to follow a
/// soft strip collapsing under 100 g (blow-up at safety 0.8, step 876); 20 costs 35 %.
pub const REFRESH_MIN_STEPS: u64 = 50;

/// What the stable step's refresh carries from step to step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct StableStepState<const D: usize>
where
    Space: Dim<D>,
{
    /// omega_max of the elastic model the step uses (rad/s): the last measurement with the
    /// margin, extrapolated over the next interval when it grew (see `maybe_refresh_step`).
    pub omega_elastic: f64,
    /// The last measurement with the margin, not extrapolated (rad/s).
    pub omega_measured: f64,
    /// Displacements at the last measurement (empty: the reference state).
    pub u_measured: Vec<Vect<D>>,
    /// Step count at the last measurement.
    pub step_measured: u64,
    /// Last iterate of the power iteration (translations, rotations), the warm start of the
    /// next refresh (empty: none).
    pub eig_t: Vec<Vect<D>>,
    pub eig_r: Vec<<Space as Dim<D>>::Ang>,
}

impl<const D: usize> World<D>
where
    Space: Dim<D>,
{
    /// Largest angular frequency of the linearised particle model (rad/s), contact included.
    pub fn omega_max(&self) -> f64 {
        self.omega_max
    }

    /// Largest angular frequency of the elastic model alone, measured by power iteration (rad/s).
    pub fn omega_elastic(&self) -> f64 {
        self.omega_elastic
    }

    /// Stability limit of symplectic Euler for this model with its damping (s): 2 / omega_max
    /// without damping, less with it (see [`critical_step`]).
    pub fn critical_dt(&self) -> f64 {
        critical_step(self.omega_max, self.options.damping)
    }

    /// The step the solver takes at most: the scene's fixed dt, or safety * critical_dt (s).
    pub fn max_dt(&self) -> f64 {
        self.options
            .dt
            .unwrap_or(self.options.safety * self.critical_dt())
    }

    /// Largest eigenvalue of M^-1 K (translations and, in the paper model, rotations) by power
    /// iteration on the model's own force function, with the mass inner product (so the
    /// operator is self-adjoint). Constrained degrees of freedom are excluded. `warm`: None
    /// linearises about the reference state from the deterministic start vector; Some(start)
    /// linearises about the current state (its tangent stiffness: geometric and material)
    /// from `start` (the last iterate of the previous measurement). Returns omega_max (rad/s)
    /// and the last iterate.
    #[allow(clippy::type_complexity)]
    pub(super) fn measure_omega_max(
        &self,
        iterations: usize,
        warm: Option<(&[Vect<D>], &[<Space as Dim<D>>::Ang])>,
    ) -> (f64, Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) {
        let n = self.len();
        // The probe state holds what the elastic operators read (displacements, orientations,
        // bodies, number densities), not the integrator's arrays (issue 25: about 110 B per
        // particle less at the peak of the set-up).
        let mut probe = Particles::<D> {
            x0: Vec::new(),
            u: self.p.u.clone(),
            x: Vec::new(),
            v: Vec::new(),
            q: self.p.q.clone(),
            w: Vec::new(),
            body: self.p.body.clone(),
            mass: Vec::new(),
            inertia: Vec::new(),
            fix: Vec::new(),
            n_ref: self.p.n_ref.clone(),
        };
        let mut scratch = ElasticScratch::default();
        let mut f = vec![Vect::<D>::zeros(); n];
        let mut t = vec![<Space as Dim<D>>::ang_zero(); n];
        let rotational = matches!(
            self.op.model,
            ElasticModel::Paper | ElasticModel::PaperLocal
        );
        // Deterministic pseudo-random start vector that moves with the body: per particle a
        // pseudo-random combination of its bond directions (coefficients hashed from the pair
        // indices), so a translated or rotated scene starts from the translated or rotated
        // vector and measures the same omega_max to round-off.
        let coef = |i: usize, j: u32, salt: u64| -> f64 {
            let mut z = ((i as u64) << 32 | j as u64) ^ salt;
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let bond_mix = |i: usize, salt: u64| -> Vect<D> {
            let mut acc = Vect::<D>::zeros();
            for b in self.bonds.of(i) {
                let r0 = self.bonds.r0[b];
                acc += r0 * (coef(i, self.bonds.nbr[b], salt) / r0.norm());
            }
            acc
        };
        let fresh = || -> (Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) {
            (
                (0..n).map(|i| bond_mix(i, 1)).collect(),
                (0..n)
                    .map(|i| {
                        if rotational {
                            let a = <Space as Dim<D>>::cross(&bond_mix(i, 2), &bond_mix(i, 3));
                            <Space as Dim<D>>::ang_scale(a, 1.0 / self.l0)
                        } else {
                            <Space as Dim<D>>::ang_zero()
                        }
                    })
                    .collect(),
            )
        };
        let (mut zt, mut zr): (Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) = match warm {
            // The previous eigenvector plus as much of the deterministic start vector (in the
            // mass norm): a mode that has become the stiffest elsewhere in the body (a fold
            // forming) still has weight in the start.
            Some((t0, r0)) => {
                let (ft, fr) = fresh();
                let nm = |zt: &[Vect<D>], zr: &[<Space as Dim<D>>::Ang]| -> f64 {
                    (0..n)
                        .map(|i| {
                            self.p.mass[i] * zt[i].norm_squared()
                                + self.p.inertia[i] * <Space as Dim<D>>::ang_dot(zr[i], zr[i])
                        })
                        .sum::<f64>()
                        .sqrt()
                };
                let (a, b) = (nm(t0, r0), nm(&ft, &fr));
                let (a, b) = (
                    if a > 0.0 { 1.0 / a } else { 0.0 },
                    if b > 0.0 { 1.0 / b } else { 0.0 },
                );
                (
                    (0..n).map(|i| t0[i] * a + ft[i] * b).collect(),
                    (0..n)
                        .map(|i| {
                            <Space as Dim<D>>::ang_add(
                                <Space as Dim<D>>::ang_scale(r0[i], a),
                                <Space as Dim<D>>::ang_scale(fr[i], b),
                            )
                        })
                        .collect(),
                )
            }
            None => (
                (0..n).map(|i| bond_mix(i, 1)).collect(),
                (0..n)
                    .map(|i| {
                        if rotational {
                            let a = <Space as Dim<D>>::cross(&bond_mix(i, 2), &bond_mix(i, 3));
                            <Space as Dim<D>>::ang_scale(a, 1.0 / self.l0)
                        } else {
                            <Space as Dim<D>>::ang_zero()
                        }
                    })
                    .collect(),
            ),
        };
        // About the current state: the forces there, subtracted from the probe's.
        let base = warm.map(|_| {
            let mut f0 = vec![Vect::<D>::zeros(); n];
            let mut t0 = vec![<Space as Dim<D>>::ang_zero(); n];
            self.op
                .forces(&self.p, &self.bonds, &mut scratch, &mut f0, &mut t0);
            (f0, t0)
        });
        let mask = |p: &Particles<D>, zt: &mut [Vect<D>], zr: &mut [<Space as Dim<D>>::Ang]| {
            for i in 0..n {
                for k in 0..D {
                    if p.fix[i] & FIX_AXIS[k] != 0 {
                        zt[i][k] = 0.0;
                    }
                }
                if p.fix[i] & FIX_ROT != 0 {
                    zr[i] = <Space as Dim<D>>::ang_zero();
                }
            }
        };
        let norm_m = |zt: &[Vect<D>], zr: &[<Space as Dim<D>>::Ang]| -> f64 {
            (0..n)
                .map(|i| {
                    self.p.mass[i] * zt[i].norm_squared()
                        + self.p.inertia[i] * <Space as Dim<D>>::ang_dot(zr[i], zr[i])
                })
                .sum::<f64>()
                .sqrt()
        };
        mask(&self.p, &mut zt, &mut zr);
        let mut lambda = 0.0;
        for _ in 0..iterations {
            let nz = norm_m(&zt, &zr);
            if nz == 0.0 {
                return (0.0, zt, zr);
            }
            let eps = 1e-7 * self.l0;
            for i in 0..n {
                zt[i] /= nz;
                zr[i] = <Space as Dim<D>>::ang_scale(zr[i], 1.0 / nz);
                if base.is_some() {
                    probe.u[i] = self.p.u[i] + zt[i] * eps;
                    probe.q[i] = <Space as Dim<D>>::advance(&self.p.q[i], &zr[i], eps);
                } else {
                    probe.u[i] = zt[i] * eps;
                    probe.q[i] =
                        <Space as Dim<D>>::advance(&<Space as Dim<D>>::identity(), &zr[i], eps);
                }
            }
            self.op
                .forces(&probe, &self.bonds, &mut scratch, &mut f, &mut t);
            if let Some((f0, t0)) = &base {
                for i in 0..n {
                    f[i] -= f0[i];
                    t[i] =
                        <Space as Dim<D>>::ang_add(t[i], <Space as Dim<D>>::ang_scale(t0[i], -1.0));
                }
            }
            // The next iterate A z = -M^-1 (f(z eps) - f0) / eps, in place of the forces
            // (which the next pass overwrites), then swapped with z.
            for i in 0..n {
                f[i] *= -1.0 / (eps * self.p.mass[i]);
                t[i] = if rotational {
                    <Space as Dim<D>>::ang_scale(t[i], -1.0 / (eps * self.p.inertia[i]))
                } else {
                    <Space as Dim<D>>::ang_zero()
                };
            }
            mask(&self.p, &mut f, &mut t);
            // Rayleigh quotient <z, A z>_M with |z|_M = 1.
            lambda = (0..n)
                .map(|i| {
                    self.p.mass[i] * zt[i].dot(&f[i])
                        + self.p.inertia[i] * <Space as Dim<D>>::ang_dot(zr[i], t[i])
                })
                .sum::<f64>();
            std::mem::swap(&mut zt, &mut f);
            std::mem::swap(&mut zr, &mut t);
        }
        (lambda.max(0.0).sqrt(), zt, zr)
    }

    /// Every `REFRESH_CHECK_EVERY` steps (automatic step only), at least `REFRESH_MIN_STEPS`
    /// after the last refresh: if some intact bond's relative
    /// displacement has changed by more than `REFRESH_DEFORMATION` of its length since the
    /// last measurement, measures omega_max again about the current state
    /// (`REFRESH_ITERATIONS` power iterations from the previous eigenvector) and takes the
    /// larger of it (with the margin) and the reference value. Returns whether it measured.
    pub(super) fn maybe_refresh_step(&mut self) -> bool {
        if self.options.dt.is_some()
            || !self.steps.is_multiple_of(REFRESH_CHECK_EVERY)
            || (self.stable.step_measured > 0
                && self.steps < self.stable.step_measured + REFRESH_MIN_STEPS)
        {
            return false;
        }
        let clock = std::time::Instant::now();
        let n = self.len();
        let u = &self.p.u;
        let um = &self.stable.u_measured;
        let lim2 = REFRESH_DEFORMATION * REFRESH_DEFORMATION;
        let moved = |i: usize, j: usize| -> Vect<D> {
            if um.is_empty() {
                u[j] - u[i]
            } else {
                (u[j] - um[j]) - (u[i] - um[i])
            }
        };
        let deformed = (0..n).any(|i| {
            self.bonds.of(i).any(|b| {
                self.bonds.w0[b] != 0.0
                    && moved(i, self.bonds.nbr[b] as usize).norm_squared()
                        > lim2 * self.bonds.r0[b].norm_squared()
            })
        });
        if deformed {
            let start = (
                std::mem::take(&mut self.stable.eig_t),
                std::mem::take(&mut self.stable.eig_r),
            );
            let warm = if start.0.len() == n && start.1.len() == n {
                Some((&start.0[..], &start.1[..]))
            } else {
                None
            };
            let (omega, eig_t, eig_r) = match warm {
                Some(w) => self.measure_omega_max(REFRESH_ITERATIONS, Some(w)),
                // No previous eigenvector: a full measurement from the deterministic start.
                None => {
                    let (_, t0, r0) = self.measure_omega_max(0, None);
                    self.measure_omega_max(80, Some((&t0, &r0)))
                }
            };
            // A body that stiffens as it deforms (a soft strip folding under its load) stiffens
            // on until the next measurement: the growth since the last one is assumed again
            // for the next interval (at most x1.5).
            // Never below the last measurement: a few warm iterations from the mixed start can
            // fall short of a value an earlier refresh converged to, and a bound that drops
            // back lets the step grow past the limit (seen: small2d through the FMU, blow-up at
            // step 671). A body that softens again keeps the shorter step.
            let measured = (omega * (1.0 + OMEGA_MARGIN)).max(self.stable.omega_measured);
            let growth =
                (omega * (1.0 + OMEGA_MARGIN) / self.stable.omega_measured).clamp(1.0, 1.5);
            self.stable = StableStepState {
                omega_elastic: (measured * growth).max(self.omega_reference),
                omega_measured: measured,
                u_measured: self.p.u.clone(),
                step_measured: self.steps,
                eig_t,
                eig_r,
            };
            self.omega_elastic = self.stable.omega_elastic;
            self.omega_max = (self.omega_elastic.powi(2) + self.omega2_contact).sqrt();
            self.step_refreshes += 1;
        }
        self.step_refresh_seconds += clock.elapsed().as_secs_f64();
        deformed
    }
}
