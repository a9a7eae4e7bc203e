//! Surface particles, Eq. (41), and contact between them (section 2.5): particles of different
//! bodies, and particles of one body with no intact bond between them once fracture is on, repel
//! when closer than l0. The force law is the paper's normal spring, Eqs. (27) and (30), with the
//! range of influence re = l0 and the number density n_i of Eq. (30) taken over the contact
//! neighbourhood (derivation in docs/contact-fracture.md): for one partner the weight cancels and
//!
//!   f_i = -k_c (l0 - r) r_hat_ij,   k_c = 2 d (2 mu_ij) l0^d / l0^2,   r < l0,
//!
//! with r_hat_ij = (x_j - x_i) / r and mu_ij the series (harmonic) mean of the two bodies' shear
//! moduli. Several partners add (symmetric pair forces: momentum is conserved to round-off). The
//! law is conservative, U(r) = k_c (l0 - r)^2 / 2, frictionless (Eq. (31) has no reference
//! vector across a contact) and has no pressure part (no volumetric strain across a contact).
//!
//! Contact distance of a pair: the sum of the two particles' contact radii between bodies and
//! between particles of one body that were never bonded (farther than re > l0 apart in the
//! reference state); the smaller of that and |r0_ij| across a broken bond. A particle's contact
//! radius is l0 / 2 (a box body's face is half a spacing out from its particles), so the
//! distance is l0 for boxes. A particle of a body filled from a solid (scene shapes) stands for
//! the largest ball about its centre inside the solid: its radius is the centre's distance to
//! the solid's surface (at most [`max_radius`]), so the particles' balls follow a curved
//! face instead of the lattice's staircase. Why (issue 26): a ball of 10 particles across has
//! a flat bottom layer 0.03 m wide, a whole spacing above the sphere's lowest point; with l0
//! for every pair it hit a plate as a flat punch and its contact lasted 12.3 ms against
//! Hertz's 20.4 ms. A bond breaks only in tension, longer than |r0_ij|, so the contact across it
//! never starts inside its range: breaking releases the bond's energy and adds none (issue 7:
//! a face layer half a spacing from the next, as the holder of tests/data/small2d.json, got
//! k_c (l0/2)^2 / 2 of contact energy per broken pair, 547 J -> 985 J). The overlap limit of a
//! pair is overlap_fraction times its contact distance.
//!
//! Contact search: a Verlet list over surface particles only, built with a cell grid of side
//! (1 + skin) l0 and rebuilt when a surface particle has moved more than skin l0 / 2 since the
//! last build, or when the set of surface particles or bonds changed (fracture). Forces are
//! gathered per particle over its own sorted list, so results do not depend on the threads.
use super::bonds::Bonds;
use super::dim::Vect;
use super::grid::CellGrid;
#[allow(unused_imports)]
use super::par::*;
use super::params::ContactOptions;
use super::particles::rel;
use crate::par_iter_mut;

/// Width of the smooth onset of the contact force, as a fraction of the pair's contact
/// distance c (-). Over the first `ONSET` c of penetration p = c - r the stiffness rises
/// linearly from 0 to k_c (force k_c p^2 / (2 ONSET c)); beyond, the force is the paper's
/// spring shifted by half the band, k_c (p - ONSET c / 2). The force is C1 (no kink at first
/// touch), never stiffer than k_c (the stable-step bound is unchanged) and zero from r = c on
/// (a bond broken in tension still starts outside its contact range, no energy is created).
///
/// Why (issue 7, docs/model.md "Energy"; two 8 x 8 blocks closing at 2 m/s, 8 phases of the
/// touch within a step): with the kink at r = c symplectic Euler's energy error of an impact is
/// second order in dt, the same at any speed (the linear law is scale-free) and of random sign
/// with the phase of the touch: mean -0.77 %, rms 1.34 %, max 1.94 % at safety 0.8. With the
/// onset it is of one sign and phase-free, still second order: -0.137 % at safety 0.8 (0.1 c:
/// -0.32 %, 0.5 c: -0.09 %); what remains is the face layer being stopped within a few steps
/// (it grows with the speed: -0.39 % at 8 m/s closing). At the overlap limit (0.5 c) the force
/// is 70 % of the paper spring's.
pub const ONSET: f64 = 0.3;

/// Deepest a pair may get within its contact distance in one step as it closes, as a fraction
/// of the distance c (-): half the onset band, so that a pair's first evaluated touch lies on
/// the law's soft ramp however fast it comes (`Contact::approach_step`). At case 3's 5 m/s it
/// allows steps of 1.5e-3 s, four times the stable step; a pair closing at 50 m/s on the same
/// spacing is held to 1.5e-4 s once it is within reach.
pub const APPROACH_DEPTH: f64 = 0.5 * ONSET;

/// Largest contact radius of a particle filled from a solid (m): l0, as a particle deeper below
/// the surface is not what a partner meets first (its shallower neighbours are), and below
/// 0.45 re, so that two particles of one body that were never bonded (farther apart than re)
/// are never in contact at rest. The pair search reaches twice it plus the skin.
pub fn max_radius(l0: f64, re: f64) -> f64 {
    l0.min(0.45 * re)
}

/// Magnitude of the repulsive contact force at distance r (N) for the pair stiffness k_c and the
/// pair's contact distance `c` (the spacing l0, or a shorter reference length of a broken
/// bond): C1, with the smooth onset of [`ONSET`].
#[inline(always)]
pub fn force_magnitude(kc: f64, c: f64, r: f64) -> f64 {
    let p = c - r;
    let band = ONSET * c;
    if p <= 0.0 {
        0.0
    } else if p < band {
        kc * p * p / (2.0 * band)
    } else {
        kc * (p - 0.5 * band)
    }
}

/// Contact potential at distance r (J): the integral of `force_magnitude` from r to c.
pub fn potential(kc: f64, c: f64, r: f64) -> f64 {
    let p = c - r;
    let band = ONSET * c;
    if p <= 0.0 {
        0.0
    } else if p < band {
        kc * p * p * p / (6.0 * band)
    } else {
        0.5 * kc * (p - 0.5 * band).powi(2) + kc * band * band / 24.0
    }
}

/// Largest eigenvalue of the pair stiffness (Hessian of U): the radial stiffness, at most k_c
/// (the transverse part, -|f| / r, is negative) (N/m).
pub fn max_tangent_stiffness(kc: f64) -> f64 {
    kc
}

/// A pair closer than the overlap distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Overlap {
    pub i: usize,
    pub j: usize,
    pub distance: f64,
    /// The pair's overlap limit: overlap_fraction times its contact distance (m).
    pub limit: f64,
}

/// Bits of a surface particle's touch flags in a force evaluation (`Contact::touch`).
const TOUCH_SAME_BODY: u8 = 1;
const TOUCH_REPELLING: u8 = 2;

/// Contact state: surface flags, number densities and the Verlet pair list.
#[derive(Clone, Debug)]
pub struct Contact<const D: usize> {
    pub opts: ContactOptions,
    /// Whether any contact search is needed at all: contact enabled and either two or more
    /// bodies or fracture on.
    pub active: bool,
    /// Whether pairs of the same body without an intact bond are candidates (fracture on).
    pub same_body: bool,
    /// Pair stiffness k_c per body pair (row-major, n_bodies^2) (N/m).
    pub k0: Vec<f64>,
    pub n_bodies: usize,
    pub l0: f64,
    /// Current number density n_i over the intact bonds, Eq. (12) (-).
    pub number_density: Vec<f64>,
    /// n_max of Eq. (41) per body: the largest of the interior lattice value n0 and the
    /// body's largest reference number density (-).
    pub n_max: Vec<f64>,
    /// Surface flag, Eq. (41), or lost a bond, Eq. (42).
    pub surface: Vec<bool>,
    /// Indices of the surface particles (ascending).
    pub surface_ids: Vec<u32>,
    /// Displacements of the surface particles at the last build.
    u_build: Vec<Vect<D>>,
    /// Pair list per surface particle (CSR over `surface_ids`): neighbour and whether the pair
    /// repels (false: checked for overlap only).
    start: Vec<u32>,
    nbr: Vec<u32>,
    repel: Vec<bool>,
    /// Contact distance per list entry (m): the sum of the contact radii between bodies; the
    /// smaller of that and |X_j - X_i| within a body, so a pair whose bond breaks is never
    /// inside its contact range at the moment of breaking (a bond broken in tension is longer
    /// than its reference length).
    reach: Vec<f64>,
    /// Contact radius per particle (m); empty: l0 / 2 for every particle (box bodies).
    radius: Vec<f64>,
    /// Largest contact radius (m).
    max_radius: f64,
    /// Contact force per surface particle (scratch).
    f_s: Vec<Vect<D>>,
    /// First overlap found per surface particle (scratch).
    hit: Vec<Option<(u32, f64, f64)>>,
    /// Per surface particle (scratch): bit `TOUCH_SAME_BODY`, a pair of one body came within
    /// its contact distance; bit `TOUCH_REPELLING`, a repelling pair did.
    touch: Vec<u8>,
    /// Per surface particle (scratch): its row of Gershgorin's bound on M^-1/2 K_c M^-1/2 over
    /// the repelling pairs within their contact distance (rad^2/s^2, see `omega2_now`).
    row_bound: Vec<f64>,
    /// Upper bound of omega^2 that contact adds at the last force evaluation (rad^2/s^2; 0:
    /// no repelling pair within its contact distance, contact adds no stiffness): Gershgorin
    /// on M^-1/2 K_c M^-1/2 over the pairs in contact, each of stiffness at most k_ij (the
    /// pair Hessian's radial eigenvalue; its transverse one is negative), with at most
    /// `max_partners` partners counted per particle,
    ///   omega_c^2 <= max_i min(n_i, max_partners) max_j k_ij (1/m_i + 1/sqrt(m_i m_j)),
    /// n_i the particle's partners in contact. At most [`Contact::omega2_bound`]. It depends on
    /// the positions only (every pair within its contact distance is in any valid pair list),
    /// so a restored state gives the same value.
    pub omega2_now: f64,
    /// Per surface particle (scratch): its pairs' longest step by `APPROACH_DEPTH` (s).
    row_step: Vec<f64>,
    /// Longest step after which no repelling pair of the list that is closing now gets deeper
    /// than `APPROACH_DEPTH` c within its contact distance, at the velocities of the last force
    /// evaluation (s; infinite when none closes): min over them of (max(r - c, 0) +
    /// APPROACH_DEPTH c) / w, w the closing speed. The stable step bounds a contact's stiffness;
    /// this bounds how far a fast pair moves into it per step (before, the scene-wide stiffness
    /// bound halved every step of a scene with contact and with it that distance).
    pub approach_step: f64,
    pub needs_rebuild: bool,
    /// Pair-list builds so far.
    pub searches: u64,
    /// Force evaluations in which some pair of one body (across a broken bond, or never
    /// bonded) was within its contact distance: the only pairs whose forces depend on
    /// `fractured_surfaces`, so two runs that differ only in it are the same to the bit while
    /// this stays 0.
    pub same_body_touches: u64,
}

impl<const D: usize> Contact<D> {
    /// Sets up contact for the particles' bodies; `mu` per body, `n0` of the elastic operator.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        opts: ContactOptions,
        l0: f64,
        n0: f64,
        mu: &[f64],
        body: &[u32],
        bonds: &Bonds<D>,
        fracture: bool,
        radius: Vec<f64>,
    ) -> Self {
        let nb = mu.len();
        let d = D as f64;
        let mut k0 = vec![0.0; nb * nb];
        for a in 0..nb {
            for b in 0..nb {
                let mu_ab = 2.0 * mu[a] * mu[b] / (mu[a] + mu[b]);
                // Eqs. (27), (30) times the particle volume l0^d, with |r0| = l0 and one partner
                // (see module doc).
                k0[a * nb + b] =
                    opts.stiffness * 2.0 * d * 2.0 * mu_ab * l0.powi(D as i32) / (l0 * l0);
            }
        }
        let n = body.len();
        let number_density: Vec<f64> = (0..n)
            .map(|i| bonds.of(i).map(|k| bonds.w0[k]).sum())
            .collect();
        // n_max of Eq. (41): the interior value n0 of the lattice (or more, for denser bodies),
        // so the faces of a body too thin to have interior particles are still surface.
        let mut n_max = vec![n0; nb];
        for i in 0..n {
            let b = body[i] as usize;
            n_max[b] = n_max[b].max(number_density[i]);
        }
        let active = opts.enabled && (nb >= 2 || fracture);
        let mut c = Contact {
            active,
            same_body: fracture,
            k0,
            n_bodies: nb,
            l0,
            number_density,
            n_max,
            surface: vec![false; n],
            surface_ids: Vec::new(),
            u_build: Vec::new(),
            start: vec![0],
            nbr: Vec::new(),
            repel: Vec::new(),
            reach: Vec::new(),
            max_radius: radius.iter().fold(0.5 * l0, |a, &r| a.max(r)),
            radius,
            f_s: Vec::new(),
            hit: Vec::new(),
            touch: Vec::new(),
            row_bound: Vec::new(),
            omega2_now: 0.0,
            row_step: Vec::new(),
            approach_step: f64::INFINITY,
            same_body_touches: 0,
            needs_rebuild: true,
            searches: 0,
            opts,
        };
        for i in 0..n {
            c.surface[i] = c.is_surface(bonds, body, i);
        }
        c.collect_surface();
        c
    }

    /// Eq. (41): n_i < n_max - n_c; or particle i lost a bond (Eq. (42) makes it a surface
    /// particle even when the lost weight is below n_c).
    fn is_surface(&self, bonds: &Bonds<D>, body: &[u32], i: usize) -> bool {
        self.number_density[i] < self.n_max[body[i] as usize] - self.opts.surface_threshold
            || bonds.of(i).any(|k| bonds.w0[k] == 0.0)
    }

    fn collect_surface(&mut self) {
        self.surface_ids = (0..self.surface.len() as u32)
            .filter(|&i| self.surface[i as usize])
            .collect();
        self.needs_rebuild = true;
    }

    /// Updates number densities and surface flags of the particles that lost bonds.
    pub fn bonds_broken(&mut self, bonds: &Bonds<D>, body: &[u32], touched: &[usize]) {
        for &i in touched {
            self.number_density[i] = bonds.of(i).map(|k| bonds.w0[k]).sum();
            self.surface[i] = self.is_surface(bonds, body, i);
        }
        self.collect_surface();
    }

    /// Recomputes everything derived from the bonds (after a state restore).
    pub fn refresh_all(&mut self, bonds: &Bonds<D>, body: &[u32]) {
        for i in 0..self.surface.len() {
            self.number_density[i] = bonds.of(i).map(|k| bonds.w0[k]).sum();
            self.surface[i] = self.is_surface(bonds, body, i);
        }
        self.collect_surface();
    }

    /// Rebuilds the pair list if motion (or a change of the surface) requires it. `x` are the
    /// current positions (binning only), `u` the displacements.
    pub fn update_list(&mut self, x: &[Vect<D>], u: &[Vect<D>], body: &[u32], bonds: &Bonds<D>) {
        if !self.needs_rebuild {
            let lim = 0.5 * self.opts.skin * self.l0;
            let lim2 = lim * lim;
            let moved = self
                .surface_ids
                .iter()
                .zip(&self.u_build)
                .any(|(&i, ub)| (u[i as usize] - ub).norm_squared() > lim2);
            if !moved {
                return;
            }
        }
        self.rebuild(x, u, body, bonds);
    }

    /// Contact distance of particles i and j of different bodies, or of one body without a bond
    /// between them (m): the sum of their contact radii.
    #[inline(always)]
    fn pair_distance(&self, i: usize, j: usize) -> f64 {
        if self.radius.is_empty() {
            self.l0
        } else {
            self.radius[i] + self.radius[j]
        }
    }

    fn rebuild(&mut self, x: &[Vect<D>], u: &[Vect<D>], body: &[u32], bonds: &Bonds<D>) {
        self.searches += 1;
        self.needs_rebuild = false;
        let reach = if self.radius.is_empty() {
            (1.0 + self.opts.skin) * self.l0
        } else {
            2.0 * self.max_radius + self.opts.skin * self.l0
        };
        // Binned by the current positions x = X + u: far from the origin their differences are
        // rounded, which only moves pairs at the edge of the skin, never one within l0.
        let grid = CellGrid::build(x, Some(&self.surface_ids), reach);
        let ids = &self.surface_ids;
        let same_body = self.same_body;
        let repel_same = self.opts.fractured_surfaces;
        let this = &*self;
        let mut lists: Vec<Vec<(u32, bool, f64)>> = vec![Vec::new(); ids.len()];
        par_iter_mut!(lists).enumerate().for_each(|(s, out)| {
            let i = ids[s] as usize;
            grid.for_each_near(x, &x[i], reach, |j| {
                let ju = j as usize;
                if ju == i {
                    return;
                }
                let c = this.pair_distance(i, ju);
                if body[ju] != body[i] {
                    out.push((j, true, c));
                } else if same_body {
                    match bond_of(bonds, i, j) {
                        // Intact bond: no contact.
                        Some(k) if bonds.w0[k] != 0.0 => {}
                        // Broken bond: contact from its reference length on (the same to the
                        // bit in both directions, r0_ji = -r0_ij).
                        Some(k) => out.push((j, repel_same, c.min(bonds.r0[k].norm()))),
                        // Never bonded: farther than re > 2 max_radius in the reference state.
                        None => out.push((j, repel_same, c)),
                    }
                }
            });
            out.sort_unstable_by_key(|e| e.0);
        });
        self.start.clear();
        self.start.push(0);
        self.nbr.clear();
        self.repel.clear();
        self.reach.clear();
        for l in &lists {
            for &(j, r, c) in l {
                self.nbr.push(j);
                self.repel.push(r);
                self.reach.push(c);
            }
            self.start.push(self.nbr.len() as u32);
        }
        self.u_build = ids.iter().map(|&i| u[i as usize]).collect();
    }

    /// Adds the contact forces to `force` and checks for overlaps (pairs closer than
    /// overlap_fraction l0). Returns the overlap of the lowest particle index, if any; the forces
    /// are then incomplete.
    pub fn add_forces(
        &mut self,
        x0: &[Vect<D>],
        u: &[Vect<D>],
        v: &[Vect<D>],
        body: &[u32],
        mass: &[f64],
        force: &mut [Vect<D>],
    ) -> Option<Overlap> {
        let ns = self.surface_ids.len();
        self.f_s.resize(ns, Vect::<D>::zeros());
        self.hit.resize(ns, None);
        self.touch.resize(ns, 0);
        self.row_bound.resize(ns, 0.0);
        self.row_step.resize(ns, f64::INFINITY);
        let max_partners = self.opts.max_partners;
        let frac = self.opts.overlap_fraction;
        let nb = self.n_bodies;
        let (ids, start, nbr, repel, reach, k0) = (
            &self.surface_ids,
            &self.start,
            &self.nbr,
            &self.repel,
            &self.reach,
            &self.k0,
        );
        par_iter_mut!(self.f_s)
            .zip(par_iter_mut!(self.hit))
            .zip(par_iter_mut!(self.touch))
            .zip(par_iter_mut!(self.row_bound))
            .zip(par_iter_mut!(self.row_step))
            .enumerate()
            .for_each(|(s, ((((f_out, h_out), t_out), b_out), dt_out))| {
                let i = ids[s] as usize;
                let bi = body[i] as usize;
                let mut acc = Vect::<D>::zeros();
                let mut hit = None;
                let mut touch = 0u8;
                let (mut partners, mut stiffest) = (0.0f64, 0.0f64);
                let mut longest = f64::INFINITY;
                for e in start[s] as usize..start[s + 1] as usize {
                    let j = nbr[e] as usize;
                    let r = rel(x0, u, i, j);
                    let r2 = r.norm_squared();
                    let c = reach[e];
                    if repel[e] {
                        // Closing at w = -r . (v_j - v_i) / |r| > 0: the step that takes it
                        // APPROACH_DEPTH c within its contact distance.
                        let closing = -r.dot(&(v[j] - v[i]));
                        if closing > 0.0 {
                            let d = r2.sqrt();
                            let reach_in = (d - c).max(0.0) + APPROACH_DEPTH * c;
                            longest = longest.min(reach_in * d / closing);
                        }
                    }
                    if r2 >= c * c {
                        continue;
                    }
                    if body[j] as usize == bi {
                        touch |= TOUCH_SAME_BODY;
                    }
                    let d = r2.sqrt();
                    // Overlap: closer than the fraction of the pair's contact distance.
                    if d < frac * c {
                        if hit.is_none() {
                            hit = Some((j as u32, d, frac * c));
                        }
                        continue;
                    }
                    if repel[e] {
                        touch |= TOUCH_REPELLING;
                        let k = k0[bi * nb + body[j] as usize];
                        partners += 1.0;
                        stiffest = stiffest.max(
                            max_tangent_stiffness(k)
                                * (1.0 / mass[i] + 1.0 / (mass[i] * mass[j]).sqrt()),
                        );
                        // f_i = -f(r) r_ij / r
                        acc -= r * (force_magnitude(k, c, d) / d);
                    }
                }
                *f_out = acc;
                *h_out = hit;
                *t_out = touch;
                *b_out = partners.min(max_partners) * stiffest;
                *dt_out = longest;
            });
        let touched = self.touch.iter().fold(0u8, |a, &t| a | t);
        if touched & TOUCH_SAME_BODY != 0 {
            self.same_body_touches += 1;
        }
        self.omega2_now = self.row_bound.iter().fold(0.0, |a, &b| a.max(b));
        self.approach_step = self.row_step.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        for (s, &i) in self.surface_ids.iter().enumerate() {
            force[i as usize] += self.f_s[s];
        }
        self.hit.iter().enumerate().find_map(|(s, h)| {
            h.map(|(j, d, limit)| Overlap {
                i: self.surface_ids[s] as usize,
                j: j as usize,
                distance: d,
                limit,
            })
        })
    }

    /// Contact potential energy of the current state (J), each pair once.
    pub fn energy(&self, x0: &[Vect<D>], u: &[Vect<D>], body: &[u32]) -> f64 {
        let mut total = 0.0;
        for (s, &i) in self.surface_ids.iter().enumerate() {
            let i = i as usize;
            for e in self.start[s] as usize..self.start[s + 1] as usize {
                let j = self.nbr[e] as usize;
                if j <= i || !self.repel[e] {
                    continue;
                }
                let k = self.k0[body[i] as usize * self.n_bodies + body[j] as usize];
                total += potential(k, self.reach[e], rel(x0, u, i, j).norm());
            }
        }
        total
    }

    /// Pairs in contact (closer than l0, repelling) now, each pair once.
    pub fn pairs_in_contact(&self, x0: &[Vect<D>], u: &[Vect<D>]) -> usize {
        let mut count = 0;
        for (s, &i) in self.surface_ids.iter().enumerate() {
            let i = i as usize;
            for e in self.start[s] as usize..self.start[s + 1] as usize {
                let j = self.nbr[e] as usize;
                let c = self.reach[e];
                if j > i && self.repel[e] && rel(x0, u, i, j).norm_squared() < c * c {
                    count += 1;
                }
            }
        }
        count
    }

    /// Pairs closer than their contact radii's sum now (l0 for boxes), each pair once:
    /// (different bodies, same body across a broken bond), the latter whether they repel or
    /// not.
    pub fn pairs_by_kind(&self, x0: &[Vect<D>], u: &[Vect<D>], body: &[u32]) -> (usize, usize) {
        let (mut inter, mut same) = (0, 0);
        for (s, &i) in self.surface_ids.iter().enumerate() {
            let i = i as usize;
            for e in self.start[s] as usize..self.start[s + 1] as usize {
                let j = self.nbr[e] as usize;
                let c = self.pair_distance(i, j);
                if j > i && rel(x0, u, i, j).norm_squared() < c * c {
                    if body[i] == body[j] {
                        same += 1;
                    } else {
                        inter += 1;
                    }
                }
            }
        }
        (inter, same)
    }

    /// Upper bound of omega^2 that contact adds to the particle model (rad^2/s^2), by
    /// Gershgorin on M^-1/2 K_c M^-1/2: each particle has at most `max_partners` partners of
    /// stiffness k_c, so omega_c^2 <= max_partners k_c (1/m_i + 1/sqrt(m_i m_j))
    /// <= 2 max_partners k_c / m_min.
    pub fn omega2_bound(&self, mass: &[f64]) -> f64 {
        if !self.active {
            return 0.0;
        }
        let kmax = self.k0.iter().fold(0.0f64, |a, &k| a.max(k));
        let m_min = mass.iter().fold(f64::INFINITY, |a, &m| a.min(m));
        2.0 * self.opts.max_partners * max_tangent_stiffness(kmax) / m_min
    }
}

/// The bond of particle i to particle j (intact or broken), if any (the bonds of i are sorted
/// by j).
fn bond_of<const D: usize>(bonds: &Bonds<D>, i: usize, j: u32) -> Option<usize> {
    let r = bonds.of(i);
    bonds.nbr[r.clone()]
        .binary_search(&j)
        .ok()
        .map(|k| r.start + k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_law_is_c1_conservative_and_no_stiffer_than_kc() {
        let (kc, c) = (3.0e7, 0.01);
        let h = 1e-9 * c;
        // Zero force and energy from the contact distance on.
        assert_eq!(force_magnitude(kc, c, c), 0.0);
        assert_eq!(potential(kc, c, c), 0.0);
        assert_eq!(force_magnitude(kc, c, 1.5 * c), 0.0);
        let mut prev_k: f64 = 0.0;
        for k in 1..1000 {
            let r = c * (1.0 - 0.6 * k as f64 / 1000.0);
            // f = -dU/dr (central difference).
            let du = (potential(kc, c, r - h) - potential(kc, c, r + h)) / (2.0 * h);
            let f = force_magnitude(kc, c, r);
            assert!(
                (du - f).abs() <= 1e-5 * f.max(kc * c * 1e-6),
                "r {r}: {du} vs {f}"
            );
            // Stiffness df/dp rises continuously from 0 to k_c and never exceeds it.
            let stiff = (force_magnitude(kc, c, r - h) - force_magnitude(kc, c, r + h)) / (2.0 * h);
            assert!(
                stiff <= kc * (1.0 + 1e-6) && stiff >= prev_k - 1e-6 * kc,
                "r {r}: {stiff}"
            );
            prev_k = stiff;
        }
        // C1 at first touch: the stiffness just inside is ~0, not k_c.
        let p = 1e-4 * c;
        let s0 = (force_magnitude(kc, c, c - 2.0 * p) - force_magnitude(kc, c, c - p)) / p;
        assert!(s0 < 1e-3 * kc, "{s0}");
        // Beyond the band: the paper spring shifted by half the band.
        let r = 0.5 * c;
        assert!(
            (force_magnitude(kc, c, r) - kc * (0.5 * c - 0.5 * ONSET * c)).abs() < 1e-9 * kc * c
        );
    }
}
