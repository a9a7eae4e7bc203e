//! The second-order elastic operator (selectable, `model = second_order`): displacement gradients and Hessians from a
//! quadratic-consistent weighted least-squares fit over each particle's bonds, a strain energy
//! integrated over each particle's cell to second order, and a stabilisation of the motion
//! that no quadratic field explains, with the shear modulus as its stiffness (no tuned factor).
//!
//! Why (issue 7, docs/model.md): the first-order corrected operator is exact for linear fields
//! only, so at a free surface, where bending strains are largest and the neighbourhood is one
//! sided, its gradient of a bending field is wrong to O(l0); its energy samples the strain
//! energy density at the cell centre (midpoint rule), which under-counts a bending energy by
//! (l0/h)^2; and its zero-energy modes need a stabilisation whose hand-set factor moves results.
//! Here every term is exact for a quadratic displacement field, which is what pure bending is:
//!
//! * gradient H_i = sum_j (u_j - u_i) g_ij^T and Hessian G_i^(a) = sum_j (u_j - u_i) h_ij^(a)T,
//!   with (g_ij, h_ij) the rows of the inverse moment matrix of the basis (xi, xi xi^T) weighted
//!   by w0_ij / |r0_ij|^2 (Eq. (8)); in a full symmetric neighbourhood g_ij equals the
//!   first-order corrected weight K_i^-1 r0_ij w0 / |r0|^2 (odd and even moments decouple);
//! * cell energy V [W(E) + l0^2 / 12 sum_a w(sym(F^T G^(a)))]: the Taylor expansion of the
//!   energy density over the cell, int_cell W = V [W + l0^2 / 24 sum_a d_a^2 W], exact for a
//!   cubic density; W is the body's law in the Green strain E (Saint Venant-Kirchhoff, Eqs.
//!   (6)-(7) at small strain, or neo-Hookean, module `law`), w(e) = mu e:e + lambda / 2 tr(e)^2,
//!   and F^T G^(a) = d_a E to first order (objective: unchanged by a rigid rotation). The cell
//!   term keeps the small-strain moduli for every law: it is the O(l0^2) correction of the
//!   quadrature, d_a^2 W ~ d_aE : C : d_aE with the tangent C taken at zero strain;
//! * residual energy V sum_j (w0_ij / n_i) mu |sym(d_ij n_ij^T)|^2 with d_ij the part of the
//!   bond's motion that the local quadratic field does not explain,
//!   d_ij = [u_j - u_i - H_i r0 - 1/2 G_i : r0 r0] / |r0|, n_ij = (x_j - x_i) / |x_j - x_i|
//!   the bond's current direction: zero for every quadratic field, positive for the sub-cell
//!   (hourglass) modes; mu, not lambda, so that it does not lock near incompressibility. A
//!   rigid rotation R turns d into R d and n into R n, so the term is objective; at the
//!   reference state n = r0 / |r0| and d = 0, so its linearisation is that of the reference
//!   direction.
//!
//! Forces are -dE/dx of that one energy, in gather form over the stored (directed) bonds with the
//! mirror index of each bond, so they conserve momentum and do not depend on threads.
use nalgebra::DMatrix;

use super::bonds::Bonds;
use super::cell_term;
use super::dim::{Dim, Mat, Space, Vect};
pub use super::ghosts::{Follower, Ghost, FACE_EXTRAPOLATION, FOLLOW, LUMP};
use super::grid::round;
use super::law;
#[allow(unused_imports)]
use super::par::*;
use super::params::MaterialLaw;
use super::particles::Particles;
use super::shape::{shape_pinv, shape_tensor};
use super::stencils::{padded, Stencils, LANES};

mod forces;
mod lanes;

/// Index of the symmetric pair (a, c) among the D (D + 1) / 2 quadratic terms, in the
/// stencils' order (a <= c row by row: (0,0), (0,1), (0,2), (1,1), (1,2), (2,2) in 3D).
#[inline(always)]
const fn pair<const D: usize>(a: usize, c: usize) -> usize {
    let (a, c) = if a <= c { (a, c) } else { (c, a) };
    // The rows before a hold D + (D - 1) + ... + (D - a + 1) pairs.
    a * D - a * (a.saturating_sub(1)) / 2 + (c - a)
}

/// Smallest ratio of the smallest to the largest singular value of the (scaled) moment matrix
/// for which the quadratic fit is used; below it the particle falls back to the first-order
/// corrected gradient (e.g. a particle left with bonds in one plane after fracture).
pub const QUADRATIC_MIN_CONDITION: f64 = 1e-9;

/// Per-bond weights and per-particle state of the second-order operator.
#[derive(Clone, Debug, Default)]
pub struct SecondOrder<const D: usize> {
    /// Construction form only ([`SecondOrder::new`], the closure's virtual body): gradient
    /// weight g_b of each directed bond (1/m). Empty in the packed form the world uses
    /// ([`SecondOrder::new_packed`]), whose weights are in `stencils`.
    pub g: Vec<Vect<D>>,
    /// Construction form only: Hessian weights h_b (symmetric, 1/m^2):
    /// d_a d_c u = sum_b (u_j - u_i) h_b[a][c].
    pub h: Vec<Mat<D>>,
    /// Packed form: the weights of each particle, interned by set (module `stencils`).
    pub stencils: Stencils<D>,
    /// Packed form: the geometry of each particle's bonds (snapped reference vectors, 1 / their
    /// lengths, whether each enters the fits), interned by set; fixed once built.
    pub geometry: Stencils<D>,
    /// Packed form: each particle's set with all its bonds intact, as built (the closure
    /// included): what a particle whose bonds come back (a restored state) takes again.
    pub initial_class: Vec<u32>,
    /// Whether the weights are in `stencils` (else in `g` and `h`).
    pub packed: bool,
    /// Start of each particle's block in the per-bond output of the force pass (`dbond`, in
    /// values: its bonds padded to whole groups, D rows of `LANES` per group); one more entry
    /// than particles.
    pub pad_start: Vec<u32>,
    /// Position in `dbond` of the reverse bond j -> i of each bond i -> j (its first
    /// component; the others follow `LANES` apart).
    pub mirror_pos: Vec<u32>,
    /// Whether particle i has the quadratic fit (else: first-order fallback, h = 0).
    pub quadratic: Vec<bool>,
    /// Reference number density n_i of the residual weights (sum of w0 over the original bonds).
    pub n_ref: Vec<f64>,
    /// Span projector P_i = sum_b r0_b g_b^T: exactly the identity for a full-rank
    /// neighbourhood (then `full[i]`), the projector on the bonds' span otherwise.
    pub span: Vec<Mat<D>>,
    /// Whether P_i is the identity.
    pub full: Vec<bool>,
    /// Particles of a clamped group (all axes held): a rigid grip that carries no strain
    /// energy of its own; its particles still enter their neighbours' fits with u prescribed.
    /// So a clamp face with a particle layer on it is where the displacement is zero, and the
    /// material ends there (the wall layers behind it are the grip, not material).
    pub rigid: Vec<bool>,
    /// Rigid particles with no free particle within 1.01 l0: the wall layers behind a clamped
    /// face. They enter no fit: the displacement field has a kink at the face (the shear strain
    /// of the root is not zero), and a fit across it would be wrong to O(1) in the gradient.
    pub behind: Vec<bool>,
    /// re / l0, for the fit weights w(|s|) of the quantised reference vectors.
    pub re_factor: f64,
    /// Ghosts of mirror faces, sorted by ghost index (`world::MirrorFace`).
    pub ghosts: Vec<Ghost<D>>,
    /// Followers of clamped mirror faces (all axes held): the first layer of the body at the
    /// face, whose displacement is the one for which the quadratic extrapolation along the
    /// face's normal to the face equals the clamp's motion.
    pub followers: Vec<Follower>,
    /// Members of clamped mirror faces: they enter no fit (the clamp is the followers'
    /// constraint, the face a free face of the closure).
    pub walls: Vec<bool>,
    /// Whether particle i is a follower.
    pub following: Vec<bool>,
    /// Summation-by-parts closure (module `sbp`): the correction of each bond's gradient
    /// weight (1/m), D values per bond of a closed particle, interned by set (`sbp::Closure`;
    /// empty without a closure, and in the packed form once taken into the particles' sets).
    pub closure_dg: Stencils<D>,
    /// Whether particle i belongs to a closed body.
    pub closable: Vec<bool>,
    /// Whether particle i's weights carry the closure now (closable and none of its bonds
    /// broken). Its volume then integrates the energy exactly, so it has no cell term.
    pub closed: Vec<bool>,
}

/// Scratch of the force passes.
#[derive(Clone, Debug, Default)]
pub struct SecondOrderScratch<const D: usize> {
    /// Displacement gradient H_i (for det F and the strain of the outputs). The Hessians
    /// G_i^(a) are not kept (issue 25: D^3 values per particle, 216 B in 3D, used only by the
    /// energy queries): [`SecondOrder::strain_energy`] fits them again from the same
    /// displacements, which gives them bit for bit.
    pub grad: Vec<Mat<D>>,
    /// dE/d(u_j - u_i) of each directed bond (N), by particle in groups of `LANES` bonds, D rows
    /// of `LANES` values per group (`SecondOrder::pad_start`).
    pub dbond: Vec<f64>,
    /// Displacements with the ghosts of a mirror clamp reflected (empty without ghosts).
    pub ueff: Vec<Vect<D>>,
}

pub use super::cell_term::Cells;

/// Number of basis functions of the quadratic fit: D linear + D (D + 1) / 2 quadratic.
const fn basis_len(d: usize) -> usize {
    d + d * (d + 1) / 2
}

/// The quadratic basis at s = xi / l0: (s_a, then s_a s_c for a <= c).
fn basis<const D: usize>(s: &Vect<D>, out: &mut [f64]) {
    let mut k = 0;
    for a in 0..D {
        out[k] = s[a];
        k += 1;
    }
    for a in 0..D {
        for c in a..D {
            out[k] = s[a] * s[c];
            k += 1;
        }
    }
}

impl<const D: usize> SecondOrder<D>
where
    Space: Dim<D>,
{
    /// Weights of all particles from their current (intact) bonds, in the construction form
    /// (per bond in `g` and `h`); `rigid` marks the particles of clamped groups, `ghosts` the
    /// mirror faces' members, `followers` and `walls` the clamped mirror faces' first layers
    /// and members.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        bonds: &Bonds<D>,
        l0: f64,
        re_factor: f64,
        n: usize,
        rigid: &[bool],
        ghosts: &[Ghost<D>],
        followers: &[Follower],
        walls: &[bool],
    ) -> Self {
        let mut s = Self::flags(bonds, l0, re_factor, n, rigid, ghosts, followers, walls);
        s.g = vec![Vect::<D>::zeros(); bonds.len()];
        s.h = vec![Mat::<D>::zeros(); bonds.len()];
        for i in 0..n {
            s.refresh(bonds, l0, i);
        }
        s
    }

    /// Everything but the weights.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn flags(
        bonds: &Bonds<D>,
        l0: f64,
        re_factor: f64,
        n: usize,
        rigid: &[bool],
        ghosts: &[Ghost<D>],
        followers: &[Follower],
        walls: &[bool],
    ) -> Self {
        let mut s = SecondOrder {
            g: Vec::new(),
            h: Vec::new(),
            stencils: Stencils::default(),
            geometry: Stencils::default(),
            initial_class: Vec::new(),
            packed: false,
            pad_start: Vec::new(),
            mirror_pos: Vec::new(),
            quadratic: vec![false; n],
            span: vec![Mat::<D>::identity(); n],
            full: vec![true; n],
            rigid: rigid.to_vec(),
            behind: vec![false; n],
            re_factor,
            ghosts: ghosts.to_vec(),
            followers: followers.to_vec(),
            following: {
                let mut f = vec![false; n];
                for fl in followers {
                    f[fl.particle as usize] = true;
                }
                f
            },
            walls: if walls.is_empty() {
                vec![false; n]
            } else {
                walls.to_vec()
            },
            closure_dg: Stencils::default(),
            closable: Vec::new(),
            closed: Vec::new(),
            n_ref: (0..n)
                .map(|i| bonds.of(i).map(|b| bonds.w0[b]).sum())
                .collect(),
        };
        (s.pad_start, s.mirror_pos) = padded_layout(bonds, D);
        let near = 1.01 * l0;
        for i in 0..n {
            s.behind[i] = s.rigid[i]
                && bonds
                    .of(i)
                    .all(|b| s.rigid[bonds.nbr[b] as usize] || bonds.r0[b].norm() > near);
        }
        // Ghosts enter the fits wherever they are: they carry the reflected field.
        for g in ghosts {
            s.behind[g.ghost as usize] = false;
        }
        for i in 0..n {
            s.behind[i] |= s.walls[i];
        }
        s
    }

    /// Adds the followers' external forces to what they follow, by the chain rule of their
    /// constraint: their weight `mass[i] g` and `ext(i)` (loads, contact). The clamp's wall
    /// particle gets its share as part of the reaction. The followed layers carry the
    /// followers' lumped inertia (`LUMP`), whose weight the integrator applies with theirs: it
    /// is taken off here, so that the weight acts as the constraint distributes it.
    pub fn spread_to_followed(
        &self,
        mass: &[f64],
        g: Vect<D>,
        ext: impl Fn(usize) -> Vect<D>,
        force: &mut [Vect<D>],
    ) {
        for fl in &self.followers {
            let i = fl.particle as usize;
            let w = g * mass[i];
            let e = w + ext(i);
            force[fl.wall as usize] += e * FOLLOW[0];
            force[fl.inner[0] as usize] += e * FOLLOW[1] - w * LUMP[0];
            force[fl.inner[1] as usize] += e * FOLLOW[2] - w * LUMP[1];
        }
    }

    /// The ghost record of particle i, if it is one.
    pub fn ghost_of(&self, i: usize) -> Option<&Ghost<D>> {
        self.ghosts
            .binary_search_by_key(&(i as u32), |g| g.ghost)
            .ok()
            .map(|k| &self.ghosts[k])
    }

    /// Takes the summation-by-parts closure of module `sbp`: `dg` per closed particle's bond,
    /// `closable` per particle; refreshes the closable particles.
    pub fn set_closure(&mut self, bonds: &Bonds<D>, l0: f64, dg: Stencils<D>, closable: Vec<bool>) {
        self.closed = vec![false; closable.len()];
        self.closure_dg = dg;
        self.closable = closable;
        // A particle's refreshed weights depend only on its bonds' snapped reference vectors
        // and weights (in its bond order) and on its correction row, so particles alike share
        // one refresh (in the packed form): a 10^6-particle cube has a few thousand kinds, and
        // refreshing each particle (a 9 x 9 SVD) took 10 s of its set-up, one particle at a
        // time.
        // The kinds are found by a hash of that key, each kind's first particle standing for it
        // (its key compared in full, so a collision only costs a refresh).
        let q = 2f64.powi(QUANTUM_BITS);
        let kind_key = |so: &Self, i: usize, key: &mut Vec<i64>| {
            key.clear();
            for b in bonds.of(i) {
                key.extend((0..D).map(|a| round(bonds.r0[b][a] / l0 * q) as i64));
                // Whether the bond has a weight, not its value: a quadratic fit's refresh reads
                // the weights only as zero or not (the snapped r0 gives the rest), and the
                // weights' bits vary with the particles' absolute positions (a 60^3 cube:
                // 53,433 kinds with the bits, 3,155 without).
                key.push((so.weight(bonds, b) != 0.0) as i64);
                key.push((bonds.w0[b] != 0.0) as i64);
            }
            key.push(so.closure_dg.class.get(i).copied().unwrap_or(u32::MAX) as i64);
        };
        let hash_of = |key: &[i64]| {
            use std::hash::{Hash, Hasher};
            let mut hs = rustc_hash::FxHasher::default();
            key.hash(&mut hs);
            hs.finish()
        };
        // Each closable particle's kind: the first particle with the same hash of its key
        // stands for it when their keys are equal in full (else it is refreshed on its own).
        // The keys are built and compared in parallel (serially they were 2.7 s of a
        // 10^6-particle cube's set-up); the refreshes run in particle order as before, so the
        // sets are interned in the same order.
        let same_kind: Vec<Option<u32>> = if self.packed {
            let all: Vec<usize> = (0..self.closable.len()).collect();
            let this = &*self;
            let hashes: Vec<Option<u64>> = crate::physics::par::map(&all, |&i| {
                this.closable[i].then(|| {
                    let mut key = Vec::new();
                    kind_key(this, i, &mut key);
                    hash_of(&key)
                })
            });
            let mut kinds: rustc_hash::FxHashMap<u64, u32> = Default::default();
            let first: Vec<Option<u32>> = hashes
                .iter()
                .enumerate()
                .map(|(i, h)| h.map(|h| *kinds.entry(h).or_insert(i as u32)))
                .collect();
            crate::physics::par::map(&all, |&i| {
                let r = first[i]? as usize;
                if r == i {
                    return None;
                }
                let (mut key, mut other) = (Vec::new(), Vec::new());
                kind_key(this, i, &mut key);
                kind_key(this, r, &mut other);
                (key == other).then_some(r as u32)
            })
        } else {
            Vec::new()
        };
        for i in 0..self.closable.len() {
            if !self.closable[i] {
                continue;
            }
            // A representative that took the first-order fallback (which reads the weights'
            // values and the exact r0) stands for no one.
            match same_kind
                .get(i)
                .copied()
                .flatten()
                .filter(|&r| self.quadratic[r as usize])
            {
                Some(r) => {
                    let r = r as usize;
                    self.quadratic[i] = self.quadratic[r];
                    self.closed[i] = self.closed[r];
                    self.full[i] = self.full[r];
                    self.span[i] = self.span[r];
                    self.stencils.class[i] = self.stencils.class[r];
                }
                None => self.refresh(bonds, l0, i),
            }
        }
        if self.packed {
            // The closed particles' sets hold their corrections; a particle whose bonds come
            // back takes its set as built (`initial_class`).
            self.initial_class = self.stencils.class.clone();
            self.closure_dg = Stencils::default();
        }
    }

    /// Weight of bond b in the fits and the residuals: w0, or 0 for a bond to a wall particle
    /// behind a clamped face (and for a broken bond).
    #[inline(always)]
    pub fn weight(&self, bonds: &Bonds<D>, b: usize) -> f64 {
        if self.behind[bonds.nbr[b] as usize] {
            0.0
        } else {
            bonds.w0[b]
        }
    }

    /// The geometry set of particle i's bonds (module `stencils`): their snapped reference
    /// vectors and whether each enters the fits.
    pub(crate) fn pack_geometry(&self, bonds: &Bonds<D>, l0: f64, i: usize, out: &mut Vec<f64>) {
        let range = bonds.of(i);
        let r0: Vec<Vect<D>> = range
            .clone()
            .map(|b| quantised(&bonds.r0[b], l0) * l0)
            .collect();
        let keep: Vec<bool> = range.map(|b| !self.behind[bonds.nbr[b] as usize]).collect();
        Stencils::<D>::pack_geometry(&r0, &keep, out);
    }

    /// Recomputes the weights of particle i from its intact bonds (after fracture) and its span
    /// projector.
    pub fn refresh(&mut self, bonds: &Bonds<D>, l0: f64, i: usize) {
        let m = basis_len(D);
        let range = bonds.of(i);
        let first = range.start;
        // This particle's weights, in its bond order.
        let mut gw = vec![Vect::<D>::zeros(); range.len()];
        let mut hw = vec![Mat::<D>::zeros(); range.len()];
        let mut mom = DMatrix::<f64>::zeros(m, m);
        let mut p = vec![0.0; m];
        for b in range.clone() {
            let w0 = self.weight(bonds, b);
            if w0 == 0.0 {
                continue;
            }
            let s = quantised(&bonds.r0[b], l0);
            let om = super::bonds::weight(s.norm(), self.re_factor) / s.norm_squared();
            basis::<D>(&s, &mut p);
            for r in 0..m {
                for c in 0..m {
                    mom[(r, c)] += om * p[r] * p[c];
                }
            }
        }
        // A particle that lost a bond takes the first-order fit: the quadratic fit of a cut
        // neighbourhood can be arbitrarily ill-conditioned, and with it the re-fit at a break
        // raised the strain energy (small2d impact: +46 % total energy and an overlap stop at
        // the automatic step; tests/energy_fracture.rs).
        let cut = bonds.of(i).any(|b| bonds.w0[b] == 0.0);
        let inv = if cut { None } else { quadratic_inverse(&mom) };
        self.quadratic[i] = inv.is_some();
        match inv {
            Some(inv) => {
                for b in range {
                    let w0 = self.weight(bonds, b);
                    if w0 == 0.0 {
                        gw[b - first] = Vect::<D>::zeros();
                        hw[b - first] = Mat::<D>::zeros();
                        continue;
                    }
                    let s = quantised(&bonds.r0[b], l0);
                    let om = super::bonds::weight(s.norm(), self.re_factor) / s.norm_squared();
                    basis::<D>(&s, &mut p);
                    let coef: Vec<f64> = (0..m)
                        .map(|r| om * (0..m).map(|c| inv[(r, c)] * p[c]).sum::<f64>())
                        .collect();
                    let mut g = Vect::<D>::zeros();
                    for a in 0..D {
                        g[a] = coef[a] / l0;
                    }
                    // u = ... + 1/2 sum_ac d_ac u xi_a xi_c: the coefficient of s_a s_c is
                    // d_ac u l0^2 for a < c and 1/2 d_aa u l0^2 on the diagonal.
                    let mut h = Mat::<D>::zeros();
                    let mut k = D;
                    for a in 0..D {
                        for c in a..D {
                            let v = coef[k] / (l0 * l0);
                            if a == c {
                                h[(a, a)] = 2.0 * v;
                            } else {
                                h[(a, c)] = v;
                                h[(c, a)] = v;
                            }
                            k += 1;
                        }
                    }
                    gw[b - first] = g;
                    hw[b - first] = h;
                }
            }
            None => {
                // First-order corrected gradient (pseudo-inverse of the shape tensor) and no
                // Hessian: exact for linear fields in the span of the remaining bonds.
                let k = shape_tensor(bonds, i);
                let k_inv = shape_pinv(&k);
                for b in range {
                    let w0 = self.weight(bonds, b);
                    let r0 = bonds.r0[b];
                    gw[b - first] = if w0 == 0.0 {
                        Vect::<D>::zeros()
                    } else {
                        k_inv * r0 * (w0 / r0.norm_squared())
                    };
                    hw[b - first] = Mat::<D>::zeros();
                }
            }
        }
        let mut span = Mat::<D>::zeros();
        for b in bonds.of(i) {
            if self.weight(bonds, b) != 0.0 {
                span += quantised(&bonds.r0[b], l0) * l0 * gw[b - first].transpose();
            }
        }
        // A closed particle of the packed form whose corrections were taken at set-up
        // (`closure_dg` dropped) has its set as built.
        let mut as_built = false;
        if let Some(&true) = self.closable.get(i) {
            let intact = bonds.of(i).all(|b| bonds.w0[b] > 0.0);
            self.closed[i] = intact;
            if intact {
                if self.closure_dg.class.is_empty() {
                    as_built = true;
                } else {
                    let row = self.closure_dg.get(i);
                    for (k, gk) in gw.iter_mut().enumerate() {
                        *gk += row.map_or(Vect::<D>::zeros(), |r| {
                            Vect::<D>::from_fn(|a, _| r[k * D + a])
                        });
                    }
                }
            }
        }
        // A full-rank fit reproduces linear fields: sum r0 g^T = I to round-off.
        self.full[i] = (span - Mat::<D>::identity()).amax() < 1e-8;
        self.span[i] = if self.full[i] {
            Mat::<D>::identity()
        } else {
            (span + span.transpose()) * 0.5
        };
        if !self.packed {
            let range = bonds.of(i);
            self.g[range.clone()].copy_from_slice(&gw);
            self.h[range].copy_from_slice(&hw);
        } else if as_built {
            self.stencils.class[i] = self.initial_class[i];
        } else {
            let mut values = Vec::new();
            Stencils::<D>::pack(&gw, &hw, &mut values);
            self.stencils.set(i, &values);
        }
    }
}

/// Bits of l0 kept in the reference vectors of the fit.
const QUANTUM_BITS: i32 = 30;

/// r0 / l0 rounded to 2^-QUANTUM_BITS (1e-9 of l0). The fit's weights are ~40 times as
/// sensitive to the reference geometry as the first-order operator's (a corner particle's
/// moment matrix), so the round-off of r0 of a body placed away from the origin (1e-16 relative
/// near it, 2e-9 l0 at 1e6 m) is first snapped to the same values, with the weights w(|s|)
/// evaluated on the snapped vectors: invariance tests (tests/invariance.rs) hold to 1e-9.
pub(super) fn quantised<const D: usize>(r0: &Vect<D>, l0: f64) -> Vect<D> {
    let q = 2f64.powi(QUANTUM_BITS);
    (r0 / l0).map(|c| round(c * q) / q)
}

/// Inverse of the moment matrix when it is well conditioned (SVD, relative threshold).
fn quadratic_inverse(mom: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let svd = mom.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if smax.is_nan() || smax <= 0.0 || smin < QUADRATIC_MIN_CONDITION * smax {
        return None;
    }
    svd.pseudo_inverse(0.0).ok()
}

/// For each directed bond i -> j the index of j -> i (bonds are stored in both directions with
/// the neighbours of each particle sorted).
pub fn mirror_index<const D: usize>(bonds: &Bonds<D>) -> Vec<u32> {
    const CHUNK: usize = 4096;
    let n = bonds.start.len() - 1;
    let mut m = vec![u32::MAX; bonds.len()];
    // In parallel, per chunk of particles, each writing its own bonds' entries.
    let mut parts = Vec::with_capacity(n.div_ceil(CHUNK));
    let mut rest = &mut m[..];
    for first in (0..n).step_by(CHUNK) {
        let last = (first + CHUNK).min(n);
        let len = (bonds.start[last] - bonds.start[first]) as usize;
        let (part, tail) = std::mem::take(&mut rest).split_at_mut(len);
        rest = tail;
        parts.push((first..last, part));
    }
    crate::par_iter_mut!(parts).for_each(|(range, out)| {
        let base = bonds.start[range.start] as usize;
        for i in range.clone() {
            for b in bonds.of(i) {
                let j = bonds.nbr[b] as usize;
                let r = bonds.of(j);
                let slice = &bonds.nbr[r.clone()];
                let k = slice
                    .binary_search(&(i as u32))
                    .expect("bonds are symmetric: j -> i exists for every i -> j");
                out[b - base] = (r.start + k) as u32;
            }
        }
    });
    m
}

/// The force pass's per-bond output layout (`SecondOrder::pad_start`, `mirror_pos`): each
/// particle's bonds padded to whole groups of `LANES`, `d` rows of `LANES` values per group.
fn padded_layout<const D: usize>(bonds: &Bonds<D>, d: usize) -> (Vec<u32>, Vec<u32>) {
    let n = bonds.start.len() - 1;
    let mut start = Vec::with_capacity(n + 1);
    let mut at = 0usize;
    start.push(0);
    for i in 0..n {
        at += padded(bonds.of(i).len()) * d;
        start.push(u32::try_from(at).expect("fewer than 2^32 values of per-bond output"));
    }
    let mirror = mirror_index(bonds);
    let mut pos = vec![0u32; bonds.len()];
    for i in 0..n {
        for b in bonds.of(i) {
            let back = mirror[b] as usize;
            let j = bonds.nbr[b] as usize;
            let k = back - bonds.of(j).start;
            pos[b] = start[j] + ((k / LANES) * LANES * d + k % LANES) as u32;
        }
    }
    (start, pos)
}

impl<const D: usize> SecondOrder<D>
where
    Space: Dim<D>,
{
    /// Displacement gradient H_i and Hessian G_i of particle i from the displacements `uu` of
    /// the fits (ghosts reflected, followers following): the weighted sums over its bonds.
    #[inline(always)]
    fn fit(
        &self,
        bonds: &Bonds<D>,
        i: usize,
        uu: impl Fn(usize) -> Vect<D>,
    ) -> (Mat<D>, [Mat<D>; D]) {
        debug_assert!(self.packed, "the force loop reads the packed form");
        let m = lanes::with_groups(self, bonds, i, uu, |groups| lanes::fit(self, i, groups));
        let h = Mat::<D>::from_fn(|r, c| m[r][c]);
        let g: [Mat<D>; D] = if self.quadratic[i] {
            std::array::from_fn(|a| Mat::<D>::from_fn(|r, c| m[r][D + pair::<D>(a, c)]))
        } else {
            [Mat::<D>::zeros(); D]
        };
        (h, g)
    }

    /// Displacement of particle k as the fits see it: a ghost's reflected field, a follower's
    /// constrained value, else its own.
    pub fn effective_displacement(&self, u: &[Vect<D>], k: usize) -> Vect<D> {
        if let Some(g) = self.ghost_of(k) {
            return g.reflect(&u[k], &u[g.master as usize]);
        }
        if self.following[k] {
            if let Some(fl) = self.followers.iter().find(|f| f.particle as usize == k) {
                return fl.follow(|j| u[j]);
            }
        }
        u[k]
    }

    /// Energy of particle i's cell at the current displacements (J) with its current fit,
    /// without its retained share: its term of [`SecondOrder::strain_energy`], evaluated from
    /// scratch (at a break, between force passes).
    pub fn particle_energy(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        c: &Cells<D>,
        i: usize,
    ) -> f64 {
        if self.rigid[i] {
            return 0.0;
        }
        let uu = |k: usize| self.effective_displacement(&p.u, k);
        let (h, g) = self.fit(bonds, i, uu);
        self.cell_energy(p, bonds, c, i, &h, &g, uu)
    }

    /// Green strain of F = P + H: (H + H^T + H^T H) / 2 for a full neighbourhood (P = I, exact
    /// zero at rest), (P H + H^T P + H^T H) / 2 in the span P otherwise.
    #[inline(always)]
    fn green(h: &Mat<D>, span: &Mat<D>, full: bool) -> Mat<D> {
        if full {
            (h + h.transpose() + h.transpose() * h) * 0.5
        } else {
            (span * h + h.transpose() * span + h.transpose() * h) * 0.5
        }
    }

    /// Deformation gradient F = P + H and Green strain of particle i with displacement gradient
    /// `h`.
    pub fn strain_of(&self, h: &Mat<D>, i: usize) -> (Mat<D>, Mat<D>) {
        (
            self.span[i] + h,
            Self::green(h, &self.span[i], self.full[i]),
        )
    }

    /// Residual d_ij |r0| of bond b of particle i with displacement difference du.
    #[inline(always)]
    fn residual(du: &Vect<D>, r0: &Vect<D>, grad: &Mat<D>, hess: &[Mat<D>; D]) -> Vect<D> {
        let mut q = Vect::<D>::zeros();
        for a in 0..D {
            q += hess[a] * r0 * r0[a];
        }
        du - grad * r0 - q * 0.5
    }

    /// Current unit direction n of a bond (reference vector `r0`, displacement difference `du`):
    /// the stabilisation pairs the residual with it, so that a rigid rotation, which rotates
    /// the residual, leaves the energy unchanged. Falls back to the reference direction for
    /// coincident particles. Returns (n, |r0 + du|).
    #[inline(always)]
    fn bond_direction(r0: &Vect<D>, du: &Vect<D>) -> (Vect<D>, f64) {
        let r = r0 + du;
        let len = r.norm();
        if len > 1e-9 * r0.norm() {
            (r / len, len)
        } else {
            (r0 / r0.norm(), 0.0)
        }
    }

    /// Residual energy of one bond and its two partial derivatives: E_b = c/2 (|res|^2 +
    /// (res.n)^2) with c = V w0 / n_i mu / |r0|^2 (mu |sym(d n^T)|^2 = mu/2 (|d|^2 + (d.n)^2),
    /// d = res / |r0|) and n the bond's current direction. Returns (E_b, dE_b/d res, the direct
    /// dE_b/d du through n: c (res.n) (I - n n^T) res / |r0 + du|).
    #[inline(always)]
    fn residual_terms(
        res: &Vect<D>,
        r0: &Vect<D>,
        du: &Vect<D>,
        c: f64,
    ) -> (f64, Vect<D>, Vect<D>) {
        let (n, len) = Self::bond_direction(r0, du);
        let rn = res.dot(&n);
        let energy = 0.5 * c * (res.norm_squared() + rn * rn);
        let conj = (res + n * rn) * c;
        let direct = if len > 0.0 {
            (res - n * rn) * (c * rn / len)
        } else {
            Vect::<D>::zeros()
        };
        (energy, conj, direct)
    }

    /// Strain energy of the current state (J), the same energy whose gradient `forces` is.
    pub fn strain_energy(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        c: &Cells<D>,
        s: &SecondOrderScratch<D>,
    ) -> f64 {
        let uu: &[Vect<D>] = if self.ghosts.is_empty() && self.followers.is_empty() {
            &p.u
        } else {
            &s.ueff
        };
        // Before the first force pass the scratch is empty: nothing is strained yet. Each
        // particle's gradient and Hessian are fitted again from the displacements of the last
        // force pass (`ueff` or `p.u`, unchanged since): the same sums in the same order as
        // there, so the same bits as the force pass saw, without keeping the Hessians.
        // In parallel, per fixed chunk of particles (the same bits on any number of threads).
        crate::physics::par::sum(s.grad.len(), |i| {
            if self.rigid[i] {
                0.0
            } else {
                c.retained[i] * fitted_cell_energy(self, p, bonds, c, uu, i)
            }
        })
    }

    /// Energy of particle i's cell (J) without its retained share, from its gradient `h`,
    /// Hessian `g` and the fits' displacements `uu`: V W(E) + the cell term + the residuals of
    /// its bonds.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn cell_energy(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        c: &Cells<D>,
        i: usize,
        h: &Mat<D>,
        g: &[Mat<D>; D],
        uu: impl Fn(usize) -> Vect<D>,
    ) -> f64 {
        let Cells {
            lame,
            laws,
            vol,
            moments,
            volume,
            l0,
            ..
        } = *c;
        let body = p.body[i] as usize;
        let (mu, lambda) = lame[body];
        let f = self.span[i] + h;
        let e = Self::green(h, &self.span[i], self.full[i]);
        // A collapsed neo-Hookean particle: the energy grows without bound as J -> 0.
        let inverted =
            laws[body] != MaterialLaw::SaintVenantKirchhoff && self.full[i] && law::det(&f) <= 0.0;
        let mut total = vol[i]
            * laws[body]
                .energy(&e, mu, lambda)
                .filter(|_| !inverted)
                .unwrap_or(f64::INFINITY);
        if self.quadratic[i] && !self.closed.get(i).copied().unwrap_or(false) {
            cell_term::energy(
                &f,
                g,
                &e,
                (mu, lambda),
                vol[i],
                moments.get(i),
                l0,
                &mut total,
            );
        }
        let cres = volume * mu / self.n_ref[i].max(f64::MIN_POSITIVE);
        let ui = uu(i);
        let geometry = self.geometry.of(i);
        for (k, b) in bonds.of(i).enumerate() {
            let w0 = self.weight(bonds, b);
            if w0 == 0.0 {
                continue;
            }
            // The reference vector as the fits see it, as in the force pass (module `lanes`).
            let (r0, inv) = Stencils::<D>::r0(geometry, k);
            let du = uu(bonds.nbr[b] as usize) - ui;
            let res = Self::residual(&du, &r0, h, g);
            total += Self::residual_terms(&res, &r0, &du, cres * w0 * (inv * inv)).0;
        }
        total
    }
}

crate::physics::cpu_versions! {
    /// Energy of particle i's cell without its retained share (J), fitted again from the
    /// displacements `uu` of the last force pass (compiled also for AVX2 and AVX-512 as the
    /// force pass, whose fused multiply-adds would otherwise be library calls in the baseline
    /// build: the same bits in every version).
    fn fitted_cell_energy<const D: usize>(
        op: &SecondOrder<D>,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        c: &Cells<D>,
        uu: &[Vect<D>],
        i: usize,
    ) -> f64
    where
        Space: Dim<D>,
    {
        let (h, g) = op.fit(bonds, i, |k| uu[k]);
        op.cell_energy(p, bonds, c, i, &h, &g, |k| uu[k])
    }
}
