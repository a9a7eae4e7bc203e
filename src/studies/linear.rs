//! Linearised statics and lowest modes of a world about its reference state, matrix-free: the
//! stiffness K v is the central difference of the model's own internal forces, K^-1 by
//! conjugate gradients, the lowest mode by inverse iteration with the lumped masses. Used by the
//! bending benchmarks and the accuracy tests (a static deflection and a frequency without time
//! stepping), for the models without particle rotations (second-order and corrected).
use crate::physics::dim::{Dim, Space, Vect};
use crate::physics::elastic::ElasticScratch;
use crate::physics::particles::FIX_AXIS;
use crate::physics::{ElasticModel, SimError, World};

/// Matrix-free linearisation of a world's elastic forces about the reference state.
pub struct Linearised<'a, const D: usize>
where
    Space: Dim<D>,
{
    world: &'a World<D>,
    probe: crate::physics::particles::Particles<D>,
    scratch: ElasticScratch<D>,
    fp: Vec<Vect<D>>,
    fm: Vec<Vect<D>>,
    torque: Vec<<Space as Dim<D>>::Ang>,
    /// Number of stiffness products so far.
    pub products: u64,
    /// Shift sigma (1/s^2): the products are (K + sigma M) v, for free bodies.
    pub shift: f64,
    /// Modes projected out of the inverse iteration (M-orthonormal), e.g. a free body's rigid
    /// motions.
    pub deflate: Vec<Vec<Vect<D>>>,
}

impl<'a, const D: usize> Linearised<'a, D>
where
    Space: Dim<D>,
{
    /// Refuses the paper models, whose rotations are degrees of freedom of their own.
    pub fn new(world: &'a World<D>) -> Result<Self, SimError> {
        if matches!(
            world.op.model,
            ElasticModel::Paper | ElasticModel::PaperLocal
        ) {
            return Err(SimError::Invalid(
                "the linear analysis covers the models without particle rotations (second_order, corrected)".into(),
            ));
        }
        let n = world.len();
        let mut probe = world.p.clone();
        probe.u.iter_mut().for_each(|u| *u = Vect::<D>::zeros());
        Ok(Linearised {
            world,
            probe,
            scratch: ElasticScratch::default(),
            fp: vec![Vect::<D>::zeros(); n],
            fm: vec![Vect::<D>::zeros(); n],
            torque: vec![<Space as Dim<D>>::ang_zero(); n],
            products: 0,
            shift: 0.0,
            deflate: Vec::new(),
        })
    }

    fn mask(&self, v: &mut [Vect<D>]) {
        for (i, vi) in v.iter_mut().enumerate() {
            for k in 0..D {
                if self.world.p.fix[i] & FIX_AXIS[k] != 0 {
                    vi[k] = 0.0;
                }
            }
        }
    }

    /// K v on the free degrees of freedom (N/m times the units of v).
    #[allow(clippy::needless_range_loop)]
    pub fn stiffness_times(&mut self, v: &[Vect<D>]) -> Vec<Vect<D>> {
        let vmax = v.iter().map(|x| x.amax()).fold(0.0, f64::max);
        let n = v.len();
        if vmax == 0.0 {
            return vec![Vect::<D>::zeros(); n];
        }
        // Central difference: the quadratic (geometric) part cancels; the cubic one is
        // O(eps^2) = 1e-12 relative.
        let eps = 1e-6 * self.world.l0 / vmax;
        let w = self.world;
        for s in [1.0, -1.0] {
            for i in 0..n {
                self.probe.u[i] = v[i] * (s * eps);
                self.probe.x[i] = self.probe.x0[i] + self.probe.u[i];
            }
            let f = if s > 0.0 { &mut self.fp } else { &mut self.fm };
            w.op.forces(
                &self.probe,
                &w.bonds,
                &mut self.scratch,
                f,
                &mut self.torque,
            );
        }
        self.products += 1;
        let m = &self.world.p.mass;
        let mut out: Vec<Vect<D>> = (0..n)
            .map(|i| (self.fp[i] - self.fm[i]) * (-0.5 / eps) + v[i] * (self.shift * m[i]))
            .collect();
        self.mask(&mut out);
        out
    }

    /// Solves K x = rhs on the free degrees of freedom by conjugate gradients (Jacobi-free: the
    /// masses are uniform per body). Returns x and the iterations taken; an error when the
    /// relative residual does not fall below `tol` in `max_iter` iterations.
    pub fn solve(
        &mut self,
        rhs: &[Vect<D>],
        tol: f64,
        max_iter: usize,
    ) -> Result<(Vec<Vect<D>>, usize), SimError> {
        self.solve_from(rhs, None, tol, max_iter)
    }

    /// [`Linearised::solve`] from the initial guess `x0` (None: zero, which is `solve`; a
    /// guess costs one product more). The tolerance stays relative to |rhs|, so a good guess
    /// saves iterations.
    pub fn solve_from(
        &mut self,
        rhs: &[Vect<D>],
        x0: Option<&[Vect<D>]>,
        tol: f64,
        max_iter: usize,
    ) -> Result<(Vec<Vect<D>>, usize), SimError> {
        let n = rhs.len();
        let dot =
            |a: &[Vect<D>], b: &[Vect<D>]| -> f64 { a.iter().zip(b).map(|(x, y)| x.dot(y)).sum() };
        let mut b = rhs.to_vec();
        self.mask(&mut b);
        let bn = dot(&b, &b).sqrt();
        let mut x = vec![Vect::<D>::zeros(); n];
        if bn == 0.0 {
            return Ok((x, 0));
        }
        let mut r = b.clone();
        if let Some(x0) = x0 {
            x.copy_from_slice(x0);
            self.mask(&mut x);
            let kx = self.stiffness_times(&x);
            for i in 0..n {
                r[i] -= kx[i];
            }
            if dot(&r, &r).sqrt() <= tol * bn {
                return Ok((x, 0));
            }
        }
        let mut p = r.clone();
        let mut rr = dot(&r, &r);
        for it in 1..=max_iter {
            let kp = self.stiffness_times(&p);
            let pkp = dot(&p, &kp);
            if pkp.is_nan() || pkp <= 0.0 {
                return Err(SimError::Invalid(format!(
                    "the stiffness is not positive definite on the free degrees of freedom (p^T K p = {pkp:.3e} at CG iteration {it}): a free rigid motion or a zero-energy mode"
                )));
            }
            let alpha = rr / pkp;
            for i in 0..n {
                x[i] += p[i] * alpha;
                r[i] -= kp[i] * alpha;
            }
            let rr_new = dot(&r, &r);
            if rr_new.sqrt() <= tol * bn {
                return Ok((x, it));
            }
            let beta = rr_new / rr;
            rr = rr_new;
            for i in 0..n {
                p[i] = r[i] + p[i] * beta;
            }
        }
        Err(SimError::Invalid(format!(
            "conjugate gradients did not reach the relative residual {tol:.1e} in {max_iter} iterations (reached {:.1e})",
            rr.sqrt() / bn
        )))
    }

    /// Static displacement under the body force `g` (m/s^2) on every free particle (m).
    pub fn static_gravity(&mut self, g: Vect<D>, tol: f64) -> Result<Vec<Vect<D>>, SimError> {
        let mut rhs: Vec<Vect<D>> = self.world.p.mass.iter().map(|&m| g * m).collect();
        // The followers' weight acts through their constraint.
        self.world.op.second.spread_to_followed(
            &self.world.p.mass,
            g,
            |_| Vect::<D>::zeros(),
            &mut rhs,
        );
        self.mask(&mut rhs);
        let max_iter = 40 * rhs.len() + 1000;
        Ok(self.solve(&rhs, tol, max_iter)?.0)
    }

    /// Lowest angular frequency (rad/s) and its mode by inverse iteration x <- K^-1 M x from
    /// `start`, until the Rayleigh quotient changes by less than `tol` (relative).
    pub fn lowest_mode(
        &mut self,
        start: &[Vect<D>],
        tol: f64,
    ) -> Result<(f64, Vec<Vect<D>>), SimError> {
        let n = start.len();
        let m = &self.world.p.mass;
        let mut x = start.to_vec();
        self.mask(&mut x);
        let mut last = f64::INFINITY;
        for _ in 0..50 {
            for z in &self.deflate {
                let c: f64 = (0..n).map(|i| m[i] * z[i].dot(&x[i])).sum();
                for i in 0..n {
                    x[i] -= z[i] * c;
                }
            }
            let mx: Vec<Vect<D>> = (0..n).map(|i| x[i] * m[i]).collect();
            let (y, _) = self.solve(&mx, 1e-10, 40 * n + 1000)?;
            // Rayleigh quotient y^T K y / y^T M y with K y = M x.
            let num: f64 = (0..n).map(|i| y[i].dot(&mx[i])).sum();
            let den: f64 = (0..n).map(|i| m[i] * y[i].norm_squared()).sum();
            let w2 = num / den - self.shift;
            let norm = den.sqrt();
            x = y.iter().map(|v| v / norm).collect();
            if ((w2 - last) / w2).abs() < tol {
                return Ok((w2.sqrt(), x));
            }
            last = w2;
        }
        Ok((last.sqrt(), x))
    }
}

/// Displacement of a field `u` at a reference point, interpolated from the nearest particle of
/// `body` with the operator's gradient (and Hessian), as the probes do. Sets the world's state.
pub fn field_at<const D: usize>(
    world: &mut World<D>,
    u: &[Vect<D>],
    point: &Vect<D>,
    body: Option<u32>,
) -> Result<Vect<D>, SimError>
where
    Space: Dim<D>,
{
    let mut s = world.state();
    s.u = u.to_vec();
    s.v.iter_mut().for_each(|v| *v = Vect::<D>::zeros());
    world.set_state(&s)?;
    let (i, _) = world
        .nearest_particle(point, body)
        .ok_or_else(|| SimError::Invalid("no particle".into()))?;
    Ok(world.displacement_at(i, point))
}
