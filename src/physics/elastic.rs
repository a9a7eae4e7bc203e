//! Internal forces and moments of the elastic particle model: the paper's Eqs. (13)-(36) and the
//! corrected (per-particle normalised) operator. Both are written in gather form: every particle
//! sums over its own bonds and writes only its own force, so results do not depend on threads.
use super::bonds::Bonds;
use super::dim::{Dim, Mat, Space, Vect};
use super::ghosts::{Follower, Ghost};
use super::law;
#[allow(unused_imports)]
use super::par::*;
use super::params::{ElasticModel, Material, MaterialLaw};
use super::particles::Particles;
use super::second_order::{Cells, SecondOrder, SecondOrderScratch};
pub use super::shape::{shape_pinv, shape_tensor, SHAPE_MIN_CONDITION};
use crate::par_iter_mut;
use crate::physics::cpu_versions;

/// Precomputed constants of the elastic operator.
#[derive(Clone, Debug)]
pub struct ElasticOperator<const D: usize> {
    pub model: ElasticModel,
    /// Particle volume l0^d (m^d).
    pub volume: f64,
    /// Interior reference number density n0, Eq. (12).
    pub n0: f64,
    /// Stabilisation factor (corrected model).
    pub stabilisation: f64,
    /// Per-body (mu, lambda) (Pa).
    pub lame: Vec<(f64, f64)>,
    /// Per-body strain energy law of the energy operators (the paper's ignore it).
    pub laws: Vec<MaterialLaw>,
    /// Corrected model: inverse shape tensor K_i^-1 with K_i = sum_j w0/|r0|^2 r0 r0^T.
    pub k_inv: Vec<Mat<D>>,
    /// Corrected and paper models: 1 / |r0|^2 of each directed bond (1/m^2), fixed as the
    /// reference vectors are, so that the force passes divide by nothing per bond (issue 25:
    /// two divisions per bond were about a third of the corrected operator's step). Empty for
    /// the second-order model, whose stencils carry their own.
    pub inv_r02: Vec<f64>,
    /// Corrected model: projector K_i^+ K_i on the span of the intact bonds of particle i; exactly
    /// the identity for a full neighbourhood. The Green strain is measured in this span only,
    /// (F^T F - P) / 2, so a particle left with bonds along one line or plane after fracture
    /// (or none) feels no spurious stress from the missing directions.
    pub span: Vec<Mat<D>>,
    /// Corrected model: volume carried by the stress of particle i (m^d): l0^d, scaled by
    /// n_i / n_i(reference) once particle i has lost bonds, Eq. (42). A particle hanging on a
    /// few bonds then carries a share of its stress in proportion to what it still holds,
    /// instead of concentrating its whole volume's stiffness on them (which would make it
    /// far stiffer than the stable step allows).
    pub vol: Vec<f64>,
    /// Volume of particle i with all its bonds (m^d): l0^d, or the summation-by-parts
    /// volume of a closed second-order body (module `sbp`).
    pub base_vol: Vec<f64>,
    /// Particle spacing l0 (m).
    pub l0: f64,
    /// Second-order model: first and second moments per unit volume (m, m^2) of the solid each
    /// particle stands for, about its centre (bodies filled from solids, issue 26); empty when
    /// every particle is a whole lattice cell (0 and l0^2 / 12 I). Its cell energy integrates
    /// the energy density's Taylor expansion with them, exactly for a quadratic density.
    pub cell_moments: Vec<(Vect<D>, Mat<D>)>,
    /// Second-order model: its bond weights (empty for the other models).
    pub second: SecondOrder<D>,
    /// Energy operators: the share of particle i's energy it keeps, 1 until a break. At a
    /// break the particle is re-fitted without the broken bonds, and nothing bounds the
    /// re-fitted energy at the same positions by the energy held before (a fit over fewer
    /// bonds can see more strain); where it would be higher, the share drops so that the
    /// energy is unchanged ([`ElasticOperator::limit_at_break`]): a break releases energy and
    /// never creates it (issue 7, tests/energy_fracture.rs). A share never grows back
    /// (damage is irreversible).
    pub retained: Vec<f64>,
}

/// Scratch arrays of the two passes.
#[derive(Clone, Debug, Default)]
pub struct ElasticScratch<const D: usize> {
    /// Corrected: deformation gradient F_i.
    pub defgrad: Vec<Mat<D>>,
    /// Corrected: B_i = V P_i K_i^-1 - kappa V F_i.
    pub bmat: Vec<Mat<D>>,
    /// Paper: pressure p_i, Eq. (29) (Pa).
    pub pressure: Vec<f64>,
    /// Second-order model: gradients, Hessians and their conjugates.
    pub second: SecondOrderScratch<D>,
    /// Energy operators: 1 where the particle's law has no energy at its state (a neo-Hookean
    /// particle collapsed or inverted, det F <= 0); its stress is then taken as zero.
    pub collapsed: Vec<u8>,
}

impl<const D: usize> ElasticOperator<D>
where
    Space: Dim<D>,
{
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        model: ElasticModel,
        l0: f64,
        re_factor: f64,
        n0: f64,
        stabilisation: f64,
        materials: &[Material],
        bonds: &Bonds<D>,
        n_particles: usize,
        rigid: &[bool],
        ghosts: &[Ghost<D>],
        followers: &[Follower],
        walls: &[bool],
    ) -> Self {
        let mut op = ElasticOperator {
            model,
            volume: l0.powi(D as i32),
            n0,
            stabilisation,
            lame: materials.iter().map(|m| (m.mu(), m.lambda())).collect(),
            laws: materials.iter().map(|m| m.law).collect(),
            k_inv: Vec::new(),
            inv_r02: Vec::new(),
            span: Vec::new(),
            vol: vec![l0.powi(D as i32); n_particles],
            base_vol: vec![l0.powi(D as i32); n_particles],
            l0,
            cell_moments: Vec::new(),
            second: SecondOrder::default(),
            retained: vec![1.0; n_particles],
        };
        if model == ElasticModel::SecondOrder {
            op.second = SecondOrder::new_packed(
                bonds,
                l0,
                re_factor,
                n_particles,
                rigid,
                ghosts,
                followers,
                walls,
            );
        } else {
            op.inv_r02 = bonds.r0.iter().map(|r| 1.0 / r.norm_squared()).collect();
            (op.k_inv, op.span) = (0..n_particles)
                .map(|i| op.shape_inverse_span(bonds, i))
                .unzip();
        }
        op
    }

    /// The per-particle data of the second-order operator's cells.
    fn cells(&self) -> Cells<'_, D> {
        Cells {
            lame: &self.lame,
            laws: &self.laws,
            vol: &self.vol,
            moments: &self.cell_moments,
            retained: &self.retained,
            volume: self.volume,
            l0: self.l0,
        }
    }

    /// K_i^-1 (pseudo-inverse when degenerate, [`shape_pinv`]) and the projector on the span of
    /// the intact bonds (exactly the identity when the neighbourhood has full rank).
    pub fn shape_inverse_span(&self, bonds: &Bonds<D>, i: usize) -> (Mat<D>, Mat<D>) {
        let k = shape_tensor(bonds, i);
        let k_inv = shape_pinv(&k);
        let p = k_inv * k;
        let span = if (p - Mat::<D>::identity()).amax() < 1e-8 {
            Mat::<D>::identity()
        } else {
            (p + p.transpose()) * 0.5
        };
        (k_inv, span)
    }

    /// Particle i's bonds as the corrected and paper passes read them: neighbour, reference
    /// vector, weight w0 and 1 / |r0|^2.
    #[inline(always)]
    fn bond_terms<'a>(
        &'a self,
        bonds: &'a Bonds<D>,
        i: usize,
    ) -> impl Iterator<Item = (usize, &'a Vect<D>, f64, f64)> + 'a {
        let r = bonds.of(i);
        bonds.nbr[r.clone()]
            .iter()
            .zip(&bonds.r0[r.clone()])
            .zip(&bonds.w0[r.clone()])
            .zip(&self.inv_r02[r])
            .map(|(((&j, r0), &w0), &inv)| (j as usize, r0, w0, inv))
    }

    /// Refreshes the operator of particle i after some of its bonds broke, Eq. (42): K_i^-1,
    /// the span projector and the stress volume l0^d n_i / n_i(reference).
    pub fn refresh_particle(&mut self, bonds: &Bonds<D>, i: usize, n_ref: f64) {
        if self.model == ElasticModel::SecondOrder {
            self.second.refresh(bonds, self.l0, i);
        } else {
            let (k_inv, span) = self.shape_inverse_span(bonds, i);
            self.k_inv[i] = k_inv;
            self.span[i] = span;
        }
        let n_now: f64 = bonds.of(i).map(|b| bonds.w0[b]).sum();
        self.vol[i] = if n_ref > 0.0 && n_now < n_ref {
            self.base_vol[i] * n_now / n_ref
        } else {
            self.base_vol[i]
        };
    }

    /// K_i^-1 for the current (unbroken) bonds of particle i; pseudo-inverse when the
    /// neighbourhood is degenerate (e.g. a single layer of particles), [`shape_pinv`].
    pub fn shape_inverse(&self, bonds: &Bonds<D>, i: usize) -> Mat<D> {
        shape_pinv(&shape_tensor(bonds, i))
    }

    /// Stiffness kappa of the stabilisation springs: `stabilisation` times the paper's
    /// spring constant 2 d 2 mu / n0 per unit volume, Eqs. (27)-(31).
    fn kappa(&self, mu: f64) -> f64 {
        self.stabilisation * 2.0 * D as f64 * mu / self.n0
    }

    /// Computes the internal force and moment of every particle at the current state. Returns
    /// the first particle whose material law has no energy at its state (a collapsed or inverted
    /// neo-Hookean particle, see [`ElasticScratch::collapsed`]), if any; the forces are then
    /// finite but not those of the model.
    pub fn forces(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        s: &mut ElasticScratch<D>,
        force: &mut [Vect<D>],
        torque: &mut [<Space as Dim<D>>::Ang],
    ) -> Option<usize> {
        s.collapsed.resize(p.len(), 0);
        match self.model {
            ElasticModel::Corrected => self.corrected_forces(p, bonds, s, force, torque),
            ElasticModel::SecondOrder => {
                self.second.forces(
                    p,
                    bonds,
                    &self.cells(),
                    &mut s.second,
                    &mut s.collapsed,
                    force,
                );
                torque
                    .iter_mut()
                    .for_each(|t| *t = <Space as Dim<D>>::ang_zero());
            }
            ElasticModel::Paper | ElasticModel::PaperLocal => {
                self.paper_forces(p, bonds, s, force, torque)
            }
        }
        if self
            .laws
            .iter()
            .all(|&l| l == MaterialLaw::SaintVenantKirchhoff)
        {
            return None;
        }
        s.collapsed.iter().position(|&c| c != 0)
    }

    /// det F of particle i at the last force evaluation (its area or volume ratio), for the
    /// energy operators; after fracture left its bonds in a line or plane, the ratio in their
    /// span, `det(I + 2E)^(1/2)`. None for the paper's operators.
    pub fn jacobian(&self, s: &ElasticScratch<D>, i: usize) -> Option<f64> {
        let (f, e) = self.strain_of(s, i)?;
        let full = match self.model {
            ElasticModel::SecondOrder => self.second.full[i],
            _ => self.span[i] == Mat::<D>::identity(),
        };
        Some(if full {
            law::det(&f)
        } else {
            (1.0 + law::det_c_minus_one(&e)).max(0.0).sqrt()
        })
    }

    /// Deformation gradient F and Green strain E = (F^T F - P) / 2 (in the span P of the
    /// bonds) of particle i at the last force evaluation, for the energy operators; None for
    /// the paper's operators (no deformation gradient) or before the first evaluation.
    pub fn strain_of(&self, s: &ElasticScratch<D>, i: usize) -> Option<(Mat<D>, Mat<D>)> {
        match self.model {
            ElasticModel::Corrected => {
                let f = *s.defgrad.get(i)?;
                Some((f, (f.transpose() * f - self.span[i]) * 0.5))
            }
            ElasticModel::SecondOrder => {
                let h = s.second.grad.get(i)?;
                Some(self.second.strain_of(h, i))
            }
            ElasticModel::Paper | ElasticModel::PaperLocal => None,
        }
    }

    fn corrected_forces(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        s: &mut ElasticScratch<D>,
        force: &mut [Vect<D>],
        torque: &mut [<Space as Dim<D>>::Ang],
    ) {
        let n = p.len();
        s.defgrad.resize(n, Mat::<D>::identity());
        s.bmat.resize(n, Mat::<D>::zeros());
        // Pass 1: F_i = (sum_j w r_ij r0_ij^T / |r0|^2) K_i^-1 (exact for affine motion), Green
        // strain E = (F^T F - I) / 2, the law's second Piola-Kirchhoff stress S (Saint
        // Venant-Kirchhoff S = 2 mu E + lambda tr(E) I, Eqs. (6)-(7) in the small-strain limit,
        // or neo-Hookean, module `law`), first Piola-Kirchhoff P = F S.
        par_iter_mut!(s.defgrad)
            .zip(par_iter_mut!(s.bmat))
            .zip(par_iter_mut!(s.collapsed))
            .enumerate()
            .for_each(|(i, ((f_out, b_out), c_out))| {
                corrected_pass1_particle(self, p, bonds, i, f_out, b_out, c_out)
            });
        let bm = &s.bmat;
        // Pass 2: f_i = -dE/dx_i (`corrected_pass2_particle`).
        par_iter_mut!(force)
            .enumerate()
            .for_each(|(i, f_out)| *f_out = corrected_pass2_particle(self, p, bonds, bm, i));
        torque
            .iter_mut()
            .for_each(|t| *t = <Space as Dim<D>>::ang_zero());
    }

    fn paper_forces(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        s: &mut ElasticScratch<D>,
        force: &mut [Vect<D>],
        torque: &mut [<Space as Dim<D>>::Ang],
    ) {
        s.pressure.resize(p.len(), 0.0);
        // Pass 1: volumetric strain from the bond stretches, Eq. (26), and pressure, Eq. (29).
        par_iter_mut!(s.pressure)
            .enumerate()
            .for_each(|(i, p_out)| *p_out = paper_pass1_particle(self, p, bonds, i));
        let pr = &s.pressure;
        // Pass 2: Eqs. (13)-(14) relative displacement with the pair rotation, (27)-(28) spring
        // stress, (30)-(31) translation, (32)-(33) pressure (with the sign of -grad p), (34)-(35)
        // moments.
        par_iter_mut!(force)
            .zip(par_iter_mut!(torque))
            .enumerate()
            .for_each(|(i, (f_out, t_out))| {
                (*f_out, *t_out) = paper_pass2_particle(self, p, bonds, pr, i)
            });
    }

    /// Corrected model: energy of particle i (J) with deformation gradient `f`, without its
    /// retained share: V_i W(E) and the stabilisation springs of its bonds. `collapsed`: the
    /// law has no energy at the state (a collapsed neo-Hookean particle: the energy grows
    /// without bound as J -> 0, and the step that made it stops the run).
    fn corrected_energy(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        i: usize,
        f: &Mat<D>,
        collapsed: bool,
    ) -> f64 {
        let (mu, lambda) = self.lame[p.body[i] as usize];
        let e = (f.transpose() * f - self.span[i]) * 0.5;
        let w = if collapsed {
            None
        } else {
            self.laws[p.body[i] as usize].energy(&e, mu, lambda)
        };
        let mut total = self.vol[i] * w.unwrap_or(f64::INFINITY);
        let kv = self.kappa(mu) * self.volume;
        let ui = p.u[i];
        for b in bonds.of(i) {
            let r0 = bonds.r0[b];
            let om = bonds.w0[b] * self.inv_r02[b];
            let res = (r0 + (p.u[bonds.nbr[b] as usize] - ui)) - f * r0;
            total += 0.5 * kv * om * res.norm_squared();
        }
        total
    }

    /// Corrected model: deformation gradient F_i = (sum_j w r_ij r0_ij^T / |r0|^2) K_i^-1 at
    /// the current positions (exact for affine motion).
    #[inline(always)]
    fn corrected_defgrad(&self, p: &Particles<D>, bonds: &Bonds<D>, i: usize) -> Mat<D> {
        // F = (K + sum_j w/|r0|^2 (u_j - u_i) r0^T) K^-1 = P + H K^-1 with P the span
        // projector: the identity at rest exactly, and F - P free of the cancellation of
        // K K^-1 against I. A broken bond (w0 = 0) adds zeros.
        let ui = p.u[i];
        let mut h = Mat::<D>::zeros();
        for (j, r0, w0, inv) in self.bond_terms(bonds, i) {
            let du = p.u[j] - ui;
            h += (du * (w0 * inv)) * r0.transpose();
        }
        self.span[i] + h * self.k_inv[i]
    }

    /// Energy of particle i (J) at the current positions with its current weights and
    /// retained share, evaluated from scratch (at a break, between force passes); None for
    /// the paper's operators, whose springs are the bonds themselves.
    pub fn particle_energy(&self, p: &Particles<D>, bonds: &Bonds<D>, i: usize) -> Option<f64> {
        let e = match self.model {
            ElasticModel::Corrected => {
                let f = self.corrected_defgrad(p, bonds, i);
                let law = self.laws[p.body[i] as usize];
                let collapsed = law != MaterialLaw::SaintVenantKirchhoff
                    && self.span[i] == Mat::<D>::identity()
                    && law::det(&f) <= 0.0;
                self.corrected_energy(p, bonds, i, &f, collapsed)
            }
            ElasticModel::SecondOrder => self.second.particle_energy(p, bonds, &self.cells(), i),
            ElasticModel::Paper | ElasticModel::PaperLocal => return None,
        };
        Some(self.retained[i] * e)
    }

    /// At a break: particle i held `before` (J) just before its bonds broke and holds `now`
    /// after its re-fit (both with its share as it was). Where `now` is higher, its share
    /// drops so that its energy stays `before`. Returns the energy the break released at the
    /// particle (J, >= 0).
    pub fn limit_at_break(&mut self, i: usize, before: f64, now: f64) -> f64 {
        if !(before.is_finite() && now.is_finite()) {
            return 0.0;
        }
        if now > before {
            self.retained[i] *= before.max(0.0) / now;
            return 0.0;
        }
        before - now
    }

    /// Elastic strain energy of the current state (J); evaluated for output, not in the step.
    pub fn strain_energy(&self, p: &Particles<D>, bonds: &Bonds<D>, s: &ElasticScratch<D>) -> f64 {
        if self.model == ElasticModel::SecondOrder {
            return self
                .second
                .strain_energy(p, bonds, &self.cells(), &s.second);
        }
        let v = self.volume;
        let d = D as f64;
        // In parallel, per fixed chunk of particles (the same bits on any number of threads).
        crate::physics::par::sum(p.len(), |i| {
            let mut total = 0.0;
            let (mu, lambda) = self.lame[p.body[i] as usize];
            let ui = p.u[i];
            match self.model {
                ElasticModel::SecondOrder => unreachable!("handled above"),
                ElasticModel::Corrected => {
                    let f = s.defgrad.get(i).copied().unwrap_or_else(Mat::<D>::identity);
                    let collapsed = s.collapsed.get(i) == Some(&1);
                    total += self.retained[i] * self.corrected_energy(p, bonds, i, &f, collapsed);
                }
                ElasticModel::Paper | ElasticModel::PaperLocal => {
                    let nd = if self.model == ElasticModel::PaperLocal {
                        p.n_ref[i]
                    } else {
                        self.n0
                    };
                    let c = 2.0 * d / nd * v;
                    for b in bonds.of(i) {
                        if bonds.w0[b] == 0.0 {
                            continue;
                        }
                        let j = bonds.nbr[b] as usize;
                        let r0 = bonds.r0[b];
                        let u = (r0 + (p.u[j] - ui))
                            - <Space as Dim<D>>::rotate_midpoint(&p.q[i], &p.q[j], &r0);
                        total += 0.25 * c * 2.0 * mu * bonds.w0[b] / r0.norm_squared()
                            * u.norm_squared();
                    }
                    let pi = s.pressure.get(i).copied().unwrap_or(0.0);
                    if lambda > 0.0 {
                        total += 0.5 * v * pi * pi / lambda;
                    }
                }
            }
            total
        })
    }
}

/// Pass 1 of the corrected operator for particle i: F_i, the stress and B_i. Baseline code
/// only: compiled also for AVX2 (multiversion, as the paper's passes) it ran 4 % slower
/// (`study throughput` 2.00-2.02e8 against 2.10-2.11e8 pair-updates/s, BENCHMARKS.md).
fn corrected_pass1_particle<const D: usize>(
    op: &ElasticOperator<D>,
    p: &Particles<D>,
    bonds: &Bonds<D>,
    i: usize,
    f_out: &mut Mat<D>,
    b_out: &mut Mat<D>,
    c_out: &mut u8,
) where
    Space: Dim<D>,
{
    let v = op.volume;
    let f = op.corrected_defgrad(p, bonds, i);
    let body = p.body[i] as usize;
    let (mu, lambda) = op.lame[body];
    let law = op.laws[body];
    let e = (f.transpose() * f - op.span[i]) * 0.5;
    let stress = match law.stress(&e, mu, lambda) {
        // An inverted particle (det F <= 0) of a full neighbourhood has the same C
        // as a mirrored one: only F sees it.
        Some(s)
            if law == MaterialLaw::SaintVenantKirchhoff
                || op.span[i] != Mat::<D>::identity()
                || law::det(&f) > 0.0 =>
        {
            *c_out = 0;
            s
        }
        _ => {
            *c_out = 1;
            Mat::<D>::zeros()
        }
    };
    *b_out = ((f * stress * op.k_inv[i]) * op.vol[i] - f * (op.kappa(mu) * v)) * op.retained[i];
    *f_out = f;
}

/// Pass 2 of the corrected operator for particle i: f_i = -dE/dx_i = sum_j w/|r0|^2 [(B_i +
/// B_j) r0_ij + (s_i + s_j) kappa V r_ij] with s the retained shares (B carries its particle's
/// share). B_i's part is B_i sum_j w/|r0|^2 r0_ij, added once after the loop (zero for a
/// symmetric neighbourhood); a broken bond has w0 = 0 and adds zeros, without a branch.
/// Baseline code, as pass 1.
fn corrected_pass2_particle<const D: usize>(
    op: &ElasticOperator<D>,
    p: &Particles<D>,
    bonds: &Bonds<D>,
    bm: &[Mat<D>],
    i: usize,
) -> Vect<D>
where
    Space: Dim<D>,
{
    let share = &op.retained;
    let ui = p.u[i];
    let si = share[i];
    let kv = op.kappa(op.lame[p.body[i] as usize].0) * op.volume;
    let mut acc = Vect::<D>::zeros();
    let mut moment = Vect::<D>::zeros();
    for (j, r0, w0, inv) in op.bond_terms(bonds, i) {
        let om = w0 * inv;
        let g = r0 * om;
        moment += g;
        acc += bm[j] * g + (r0 + (p.u[j] - ui)) * ((si + share[j]) * kv * om);
    }
    acc + bm[i] * moment
}

/// The paper's reference number density of particle i: n0, or its own at the start (the local
/// variant).
#[inline(always)]
fn paper_density<const D: usize>(op: &ElasticOperator<D>, p: &Particles<D>, i: usize) -> f64
where
    Space: Dim<D>,
{
    if op.model == ElasticModel::PaperLocal {
        p.n_ref[i]
    } else {
        op.n0
    }
}

cpu_versions! {
    /// Pass 1 of the paper's operators for particle i: its pressure, Eqs. (26) and (29) (compiled
    /// also for AVX-512 and AVX2 and chosen at run time, as the second-order passes: +10 % on the
    /// paper's passes; no fused operations, so every version gives the same bits).
    fn paper_pass1_particle<const D: usize>(
        op: &ElasticOperator<D>,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        i: usize,
    ) -> f64
    where
        Space: Dim<D>,
    {
        let ui = p.u[i];
        let mut sum = 0.0;
        for (j, r0, w0, inv) in op.bond_terms(bonds, i) {
            if w0 == 0.0 {
                continue;
            }
            // (|r| - l0) / l0 with one square root.
            let r2 = (r0 + (p.u[j] - ui)).norm_squared();
            sum += w0 * ((r2 * inv).sqrt() - 1.0);
        }
        // A particle without bonds (n_i = 0 in the local model) has no volumetric strain: sum = 0,
        // and 0 / 0 must not make its pressure NaN.
        if sum == 0.0 {
            0.0
        } else {
            -op.lame[p.body[i] as usize].1 * D as f64 / paper_density(op, p, i) * sum
        }
    }
}

cpu_versions! {
    /// Pass 2 of the paper's operators for particle i: its force and moment (compiled as pass 1).
    fn paper_pass2_particle<const D: usize>(
        op: &ElasticOperator<D>,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        pr: &[f64],
        i: usize,
    ) -> (Vect<D>, <Space as Dim<D>>::Ang)
    where
        Space: Dim<D>,
    {
        let ui = p.u[i];
        let qi = p.q[i];
        let c = 2.0 * D as f64 / paper_density(op, p, i) * op.volume;
        let mu2 = 2.0 * op.lame[p.body[i] as usize].0;
        let mut acc = Vect::<D>::zeros();
        let mut mom = <Space as Dim<D>>::ang_zero();
        for (j, r0, w0, inv) in op.bond_terms(bonds, i) {
            if w0 == 0.0 {
                continue;
            }
            let rij = r0 + (p.u[j] - ui);
            let u = rij - <Space as Dim<D>>::rotate_midpoint(&qi, &p.q[j], r0);
            let fs = u * (c * mu2 * w0 * inv);
            let rn = (r0.norm_squared() * rij.norm_squared()).sqrt();
            acc += fs + rij * (-c * 0.5 * (pr[i] + pr[j]) * w0 / rn);
            mom = <Space as Dim<D>>::ang_add(mom, <Space as Dim<D>>::cross(&(rij * 0.5), &fs));
        }
        (acc, mom)
    }
}
