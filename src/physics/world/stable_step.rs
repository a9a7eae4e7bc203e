//! The stable step: omega_max measured by the Lanczos process (set-up) and power iteration
//! (its refresh in the current configuration) as the body deforms, and the step it allows.
use super::World;
use crate::par_iter_mut;
use crate::physics::dim::{Dim, Space, Vect};
use crate::physics::elastic::ElasticScratch;
use crate::physics::integrate::critical_step;
use crate::physics::par::Producer;
use crate::physics::params::ElasticModel;
use crate::physics::particles::{Particles, FIX_AXIS, FIX_ROT};
use serde::{Deserialize, Serialize};

/// Relative margin added to the measured largest angular frequency (-): the measurement
/// under-estimates it (up to 0.35 % in 3D after 20 Lanczos steps; 80 power iterations, before:
/// up to 0.77 %) and a deflected configuration is stiffer than the reference one by 1-2 % (issue 7).
pub const OMEGA_MARGIN: f64 = 0.03;

/// Most force evaluations of the Lanczos measurement of the reference state's omega_max.
pub const LANCZOS_ITERATIONS: usize = 20;

/// Fewest force evaluations of the set-up's Lanczos measurement: it stops earlier than
/// LANCZOS_ITERATIONS once its largest Ritz value has settled, grown by less than
/// LANCZOS_SETTLED (relative) over the last LANCZOS_SETTLE_WINDOW evaluations. Measured on 15
/// scenes (BENCHMARKS.md, "The stable step's Lanczos measurement stops when settled"): against
/// 20 evaluations it lost at most 0.004 % of omega_max (the margin OMEGA_MARGIN is 3 %), and a
/// 10^6-particle cube stopped at 14. Scenes whose value still creeps (the paper's case 2,
/// plateaus before a jump: the cylinder cantilever's rises 0.04 % per evaluation at 13, then
/// 0.9 % by 17) take all 20.
pub const LANCZOS_LEAST: usize = 12;
pub const LANCZOS_SETTLE_WINDOW: usize = 3;
pub const LANCZOS_SETTLED: f64 = 1e-4;

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
    /// Largest angular frequency of the linearised particle model (rad/s), contact included
    /// while some repelling pair is in contact.
    pub fn omega_max(&self) -> f64 {
        self.omega_max
    }

    /// Sets omega_max from the elastic model's and contact's bound on the stiffness it adds
    /// at the last force evaluation (`Contact::omega2_now`: Gershgorin over the repelling pairs
    /// within their contact distance; 0 with none, when the elastic model alone sets the
    /// step). The step that follows a force evaluation is then stable for the stiffness at
    /// the state it starts from: a pair that comes into contact during a step shortens the
    /// next one (an advance re-divides its remaining time, `advance_to_with`), and the force
    /// law's onset (`contact::ONSET`) makes a pair's first touch soft. The steps' change of
    /// length is what the integrator's kick over half of each step takes care of
    /// (`StepInputs::kick_dt`).
    pub(super) fn set_omega_max(&mut self) {
        let c2 = if self.contact.active {
            self.contact.omega2_now.min(self.omega2_contact)
        } else {
            0.0
        };
        self.omega_max = (self.omega_elastic.powi(2) + c2).sqrt();
    }

    /// Largest angular frequency of the elastic model alone, measured on its own forces (rad/s).
    pub fn omega_elastic(&self) -> f64 {
        self.omega_elastic
    }

    /// Stability limit of symplectic Euler for this model with its damping (s): 2 / omega_max
    /// without damping, less with it (see [`critical_step`]).
    pub fn critical_dt(&self) -> f64 {
        critical_step(self.omega_max, self.options.damping)
    }

    /// The step the solver takes at most: the scene's fixed dt, or safety * critical_dt, and
    /// no longer than contact's approach step (`Contact::approach_step`: a pair closing fast
    /// gets at most `contact::APPROACH_DEPTH` of its contact distance deep per step) (s).
    pub fn max_dt(&self) -> f64 {
        self.options.dt.unwrap_or_else(|| {
            let stable = self.options.safety * self.critical_dt();
            if self.contact.active {
                stable.min(self.contact.approach_step)
            } else {
                stable
            }
        })
    }

    /// Deterministic pseudo-random start vector of the eigenvalue measurements, which moves
    /// with the body: per particle a pseudo-random combination of its bond directions
    /// (coefficients hashed from the pair indices), so a translated or rotated scene starts
    /// from the translated or rotated vector and measures the same omega_max to round-off.
    /// Rotations only for the paper models (the others carry none).
    #[allow(clippy::type_complexity)]
    pub fn start_vector(&self) -> (Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) {
        let n = self.len();
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
        let rotational = self.rotational();
        let mut t = vec![Vect::<D>::zeros(); n];
        let mut r = vec![<Space as Dim<D>>::ang_zero(); n];
        par_iter_mut!(t)
            .zip(par_iter_mut!(r))
            .enumerate()
            .for_each(|(i, (t, r))| {
                *t = bond_mix(i, 1);
                if rotational {
                    let a = <Space as Dim<D>>::cross(&bond_mix(i, 2), &bond_mix(i, 3));
                    *r = <Space as Dim<D>>::ang_scale(a, 1.0 / self.l0);
                }
            });
        (t, r)
    }

    /// Whether the elastic model has rotational degrees of freedom (the paper models).
    fn rotational(&self) -> bool {
        matches!(
            self.op.model,
            ElasticModel::Paper | ElasticModel::PaperLocal
        )
    }

    /// Largest eigenvalue of M^-1 K about the reference state (translations and, in the paper
    /// model, rotations), as omega_max (rad/s), by the Lanczos process in the mass inner product
    /// on the model's own force function, `iterations` force evaluations from the deterministic
    /// start vector. The largest Ritz value approaches omega_max^2 from below, like the power
    /// iteration's Rayleigh quotient, but from the whole Krylov space of its iterates, so in
    /// far fewer evaluations (the top of a particle model's spectrum is dense: 80 power
    /// iterations left omega 0.5 % short in 3D). Constrained degrees of freedom are excluded.
    /// The forces are evaluated on the buffers `scratch`, returned after (the set-up hands over
    /// the world's own, so that the initial forces find them allocated: at 10^6 particles their
    /// first touch costs about as much as a force evaluation).
    /// At most `iterations` evaluations, fewer once the value has settled (LANCZOS_SETTLED);
    /// returns omega_max, the evaluations taken and the buffers.
    pub(super) fn lanczos_omega_max_in(
        &self,
        iterations: usize,
        scratch: ElasticScratch<D>,
    ) -> (f64, usize, ElasticScratch<D>) {
        let mut op = LinearProbe::new(self, false, scratch);
        let (omega, k) = self.lanczos_run(iterations, self.start_vector(), &mut op, true);
        (omega, k, op.scratch)
    }

    /// [`World::lanczos_omega_max_in`] from the start vector `start` (translations, rotations),
    /// on buffers of its own.
    #[allow(clippy::type_complexity)]
    pub fn lanczos_omega_max_from(
        &self,
        iterations: usize,
        start: (Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>),
    ) -> f64 {
        let mut op = LinearProbe::new(self, false, ElasticScratch::default());
        self.lanczos_run(iterations, start, &mut op, false).0
    }

    /// The Lanczos process of [`World::lanczos_omega_max_in`] on the probe `op`: omega_max and
    /// the force evaluations taken (all `iterations`, unless `settle` and the value settled).
    #[allow(clippy::type_complexity)]
    fn lanczos_run(
        &self,
        iterations: usize,
        start: (Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>),
        op: &mut LinearProbe<D>,
        settle: bool,
    ) -> (f64, usize) {
        let n = self.len();
        let (mut vt, mut vr) = start;
        op.mask(&self.p, &mut vt, &mut vr);
        let nv = op.norm_m(&self.p, &vt, &vr);
        if nv == 0.0 {
            return (0.0, 0);
        }
        op.scale(&mut vt, &mut vr, 1.0 / nv);
        let mut pt = vec![Vect::<D>::zeros(); n];
        let mut pr = vec![<Space as Dim<D>>::ang_zero(); n];
        let (mut wt, mut wr) = (pt.clone(), pr.clone());
        let (mut alpha, mut beta) = (Vec::new(), Vec::new());
        // The largest Ritz value after each evaluation (`settle`).
        let mut tops = Vec::new();
        let mut beta_prev = 0.0;
        for _ in 0..iterations {
            op.apply(self, &vt, &vr, &mut wt, &mut wr);
            let a = op.dot_m(&self.p, &vt, &vr, &wt, &wr);
            // w -= a v + beta_prev v_prev, and once more against v (local reorthogonalisation:
            // the finite-difference operator is symmetric only to about 1e-9).
            par_iter_mut!(wt)
                .zip(par_iter_mut!(wr))
                .enumerate()
                .for_each(|(i, (wt, wr))| {
                    *wt -= vt[i] * a + pt[i] * beta_prev;
                    *wr = <Space as Dim<D>>::ang_add(
                        *wr,
                        <Space as Dim<D>>::ang_add(
                            <Space as Dim<D>>::ang_scale(vr[i], -a),
                            <Space as Dim<D>>::ang_scale(pr[i], -beta_prev),
                        ),
                    );
                });
            let c = op.dot_m(&self.p, &vt, &vr, &wt, &wr);
            par_iter_mut!(wt)
                .zip(par_iter_mut!(wr))
                .enumerate()
                .for_each(|(i, (wt, wr))| {
                    *wt -= vt[i] * c;
                    *wr = <Space as Dim<D>>::ang_add(*wr, <Space as Dim<D>>::ang_scale(vr[i], -c));
                });
            if !(a + c).is_finite() {
                // Non-finite forces (the power iteration's Rayleigh quotient came out as 0
                // then too): no measurement.
                return (0.0, alpha.len() + 1);
            }
            alpha.push(a + c);
            if settle {
                tops.push(top_ritz(&alpha, &beta));
                let k = tops.len();
                if k >= LANCZOS_LEAST
                    && tops[k - 1] - tops[k - 1 - LANCZOS_SETTLE_WINDOW]
                        < LANCZOS_SETTLED * tops[k - 1]
                {
                    break;
                }
            }
            let b = op.norm_m(&self.p, &wt, &wr);
            // An invariant subspace (a body of a few particles): T's spectrum is exact.
            if b.is_nan() || b <= 1e-12 * (a + c).abs() {
                break;
            }
            beta.push(b);
            beta_prev = b;
            op.scale(&mut wt, &mut wr, 1.0 / b);
            std::mem::swap(&mut pt, &mut vt);
            std::mem::swap(&mut pr, &mut vr);
            std::mem::swap(&mut vt, &mut wt);
            std::mem::swap(&mut vr, &mut wr);
        }
        (top_ritz(&alpha, &beta).sqrt(), alpha.len())
    }

    /// The stiffest mode of the reference state (diagnostics: where the stable step is set):
    /// omega (rad/s) and the translations of `iterations` power iterations from the
    /// deterministic start vector, normalised in the mass norm.
    pub fn stiffest_mode(&self, iterations: usize) -> (f64, Vec<Vect<D>>) {
        let n = self.len();
        let (omega, t, _) = self.measure_omega_max(
            iterations,
            (
                &vec![Vect::<D>::zeros(); n],
                &vec![<Space as Dim<D>>::ang_zero(); n],
            ),
        );
        (omega, t)
    }

    /// Largest eigenvalue of M^-1 K about the current state (its tangent stiffness: geometric
    /// and material) by power iteration on the model's own force function, with the mass inner
    /// product (so the operator is self-adjoint), from `warm` (the last iterate of the previous
    /// measurement) plus as much of the deterministic start vector. Constrained degrees of
    /// freedom are excluded. Returns omega_max (rad/s) and the last iterate.
    #[allow(clippy::type_complexity)]
    pub(super) fn measure_omega_max(
        &self,
        iterations: usize,
        warm: (&[Vect<D>], &[<Space as Dim<D>>::Ang]),
    ) -> (f64, Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) {
        let n = self.len();
        let mut op = LinearProbe::new(self, true, ElasticScratch::default());
        // The previous eigenvector plus as much of the deterministic start vector (in the
        // mass norm): a mode that has become the stiffest elsewhere in the body (a fold
        // forming) still has weight in the start.
        let (mut zt, mut zr) = {
            let (t0, r0) = warm;
            let (ft, fr) = self.start_vector();
            let (a, b) = (op.norm_m(&self.p, t0, r0), op.norm_m(&self.p, &ft, &fr));
            let (a, b) = (
                if a > 0.0 { 1.0 / a } else { 0.0 },
                if b > 0.0 { 1.0 / b } else { 0.0 },
            );
            (
                (0..n).map(|i| t0[i] * a + ft[i] * b).collect::<Vec<_>>(),
                (0..n)
                    .map(|i| {
                        <Space as Dim<D>>::ang_add(
                            <Space as Dim<D>>::ang_scale(r0[i], a),
                            <Space as Dim<D>>::ang_scale(fr[i], b),
                        )
                    })
                    .collect::<Vec<_>>(),
            )
        };
        let mut f = vec![Vect::<D>::zeros(); n];
        let mut t = vec![<Space as Dim<D>>::ang_zero(); n];
        op.mask(&self.p, &mut zt, &mut zr);
        let mut lambda = 0.0;
        for _ in 0..iterations {
            let nz = op.norm_m(&self.p, &zt, &zr);
            if nz == 0.0 {
                return (0.0, zt, zr);
            }
            op.scale(&mut zt, &mut zr, 1.0 / nz);
            // The next iterate A z, in place of the forces, then swapped with z.
            op.apply(self, &zt, &zr, &mut f, &mut t);
            // Rayleigh quotient <z, A z>_M with |z|_M = 1.
            lambda = op.dot_m(&self.p, &zt, &zr, &f, &t);
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
                Some(w) => self.measure_omega_max(REFRESH_ITERATIONS, w),
                // No previous eigenvector (the first refresh: the reference state's
                // measurement keeps none): a full measurement from the deterministic start.
                None => {
                    let (t0, r0) = self.start_vector();
                    self.measure_omega_max(FULL_POWER_ITERATIONS, (&t0, &r0))
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
            self.set_omega_max();
            self.step_refreshes += 1;
        }
        self.step_refresh_seconds += clock.elapsed().as_secs_f64();
        deformed
    }
}

/// Power iterations of a refresh that has no previous eigenvector to start from.
const FULL_POWER_ITERATIONS: usize = 80;

/// The linearised operator A z = -M^-1 (f(u + eps z) - f(u)) / eps of a world's elastic
/// forces (translations and, for the paper models, rotations with their inertia; constrained
/// degrees of freedom masked), about the reference state or the current one. Its probe state
/// holds what the elastic operators read (displacements, orientations, bodies, number
/// densities), not the integrator's arrays (issue 25: about 110 B per particle less at the
/// peak of the set-up).
struct LinearProbe<const D: usize>
where
    Space: Dim<D>,
{
    probe: Particles<D>,
    scratch: ElasticScratch<D>,
    /// The forces of the current state (None: about the reference state, where they are zero
    /// to round-off and not subtracted).
    base: Option<(Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>)>,
    rotational: bool,
}

impl<const D: usize> LinearProbe<D>
where
    Space: Dim<D>,
{
    fn new(world: &World<D>, about_current: bool, mut scratch: ElasticScratch<D>) -> Self {
        let n = world.len();
        let base = about_current.then(|| {
            let mut f0 = vec![Vect::<D>::zeros(); n];
            let mut t0 = vec![<Space as Dim<D>>::ang_zero(); n];
            world
                .op
                .forces(&world.p, &world.bonds, &mut scratch, &mut f0, &mut t0);
            (f0, t0)
        });
        LinearProbe {
            probe: Particles::<D> {
                x0: Vec::new(),
                u: world.p.u.clone(),
                x: Vec::new(),
                v: Vec::new(),
                q: world.p.q.clone(),
                w: Vec::new(),
                body: world.p.body.clone(),
                mass: Vec::new(),
                inertia: Vec::new(),
                fix: Vec::new(),
                n_ref: world.p.n_ref.clone(),
            },
            scratch,
            base,
            rotational: world.rotational(),
        }
    }

    fn mask(&self, p: &Particles<D>, zt: &mut [Vect<D>], zr: &mut [<Space as Dim<D>>::Ang]) {
        for i in 0..zt.len() {
            for k in 0..D {
                if p.fix[i] & FIX_AXIS[k] != 0 {
                    zt[i][k] = 0.0;
                }
            }
            if p.fix[i] & FIX_ROT != 0 {
                zr[i] = <Space as Dim<D>>::ang_zero();
            }
        }
    }

    fn dot_m(
        &self,
        p: &Particles<D>,
        at: &[Vect<D>],
        ar: &[<Space as Dim<D>>::Ang],
        bt: &[Vect<D>],
        br: &[<Space as Dim<D>>::Ang],
    ) -> f64 {
        crate::physics::par::sum(at.len(), |i| {
            p.mass[i] * at[i].dot(&bt[i]) + p.inertia[i] * <Space as Dim<D>>::ang_dot(ar[i], br[i])
        })
    }

    fn norm_m(&self, p: &Particles<D>, zt: &[Vect<D>], zr: &[<Space as Dim<D>>::Ang]) -> f64 {
        self.dot_m(p, zt, zr, zt, zr).sqrt()
    }

    fn scale(&self, zt: &mut [Vect<D>], zr: &mut [<Space as Dim<D>>::Ang], s: f64) {
        par_iter_mut!(zt)
            .zip(par_iter_mut!(zr))
            .for_each(|(zt, zr)| {
                *zt *= s;
                *zr = <Space as Dim<D>>::ang_scale(*zr, s);
            });
    }

    /// out = A z.
    fn apply(
        &mut self,
        world: &World<D>,
        zt: &[Vect<D>],
        zr: &[<Space as Dim<D>>::Ang],
        out_t: &mut [Vect<D>],
        out_r: &mut [<Space as Dim<D>>::Ang],
    ) {
        let p = &world.p;
        let eps = 1e-7 * world.l0;
        let about_current = self.base.is_some();
        par_iter_mut!(self.probe.u)
            .zip(par_iter_mut!(self.probe.q))
            .enumerate()
            .for_each(|(i, (u, q))| {
                if about_current {
                    *u = p.u[i] + zt[i] * eps;
                    *q = <Space as Dim<D>>::advance(&p.q[i], &zr[i], eps);
                } else {
                    *u = zt[i] * eps;
                    *q = <Space as Dim<D>>::advance(&<Space as Dim<D>>::identity(), &zr[i], eps);
                }
            });
        world
            .op
            .forces(&self.probe, &world.bonds, &mut self.scratch, out_t, out_r);
        let base = self.base.as_ref();
        let rotational = self.rotational;
        par_iter_mut!(out_t)
            .zip(par_iter_mut!(out_r))
            .enumerate()
            .for_each(|(i, (ft, fr))| {
                if let Some((f0, t0)) = base {
                    *ft -= f0[i];
                    *fr =
                        <Space as Dim<D>>::ang_add(*fr, <Space as Dim<D>>::ang_scale(t0[i], -1.0));
                }
                *ft *= -1.0 / (eps * p.mass[i]);
                *fr = if rotational {
                    <Space as Dim<D>>::ang_scale(*fr, -1.0 / (eps * p.inertia[i]))
                } else {
                    <Space as Dim<D>>::ang_zero()
                };
                for k in 0..D {
                    if p.fix[i] & FIX_AXIS[k] != 0 {
                        ft[k] = 0.0;
                    }
                }
                if p.fix[i] & FIX_ROT != 0 {
                    *fr = <Space as Dim<D>>::ang_zero();
                }
            });
    }
}

/// The largest eigenvalue of the Lanczos process's tridiagonal matrix T_k (`alpha` its k
/// diagonal entries, `beta` at least k - 1 off-diagonal ones), at least 0 (0 for k = 0).
fn top_ritz(alpha: &[f64], beta: &[f64]) -> f64 {
    let k = alpha.len();
    if k == 0 {
        return 0.0;
    }
    let t = nalgebra::DMatrix::<f64>::from_fn(k, k, |r, c| {
        if r == c {
            alpha[r]
        } else if r + 1 == c {
            beta[r]
        } else if c + 1 == r {
            beta[c]
        } else {
            0.0
        }
    });
    nalgebra::SymmetricEigen::new(t)
        .eigenvalues
        .iter()
        .fold(0.0f64, |m, &v| m.max(v))
}
