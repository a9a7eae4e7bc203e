//! The screen in front of the bond-strain test of Eq. (42) (issue 25): which particles' bonds
//! may have reached eps_max since the last full test, from a pass over the particles and the
//! cells of the reference lattice instead of over the bonds.
use super::bonds::Bonds;
use super::dim::{Dim, Space, Vect};
use super::fracture::{strain_limit2, strained, strained_particles};
#[allow(unused_imports)]
use super::par::*;
use super::params::BondStrain;
use crate::par_iter_mut;
use rustc_hash::FxHashMap;

/// Fraction of a particle's slack that its bonds' ends may move before its bonds are tested
/// again (-), and the motion taken as round-off, as a fraction of the shortest bond (-): the
/// slack is a lower bound already (by a factor up to 2: the bound's sqrt(L2) + sqrt(x2) <=
/// 2 sqrt(L2), and the shortest bond's length for each bond's); these keep the round-off of
/// the squared lengths and of the displacement changes (1e-16 of them) from deciding a break.
const SCREEN_USE: f64 = 0.999;
const SCREEN_ROUND_OFF: f64 = 1e-9;

/// Share of the particles above which a check tests every bond and takes a new record (-):
/// the record has grown stale (the bodies have moved too far since).
const SCREEN_RECORD_SHARE: f64 = 0.125;

/// A screen in front of the bond-strain test. At a full test it records the displacements and,
/// per particle, a lower bound of how far the two ends of any of its intact bonds must move
/// relative to each other before the bond can reach eps_max (its slack). At the next checks
/// it bounds how far the ends of each particle's bonds have moved relative to each other since
/// the record, by cells of the reference lattice (per body, a side at least the longest bond,
/// so that a bond's two ends lie in one cell or in neighbouring cells): with d_i the
/// displacement change of particle i, m_c the mean of d over cell c and rho_c the largest
/// |d_i - m_c| in it, a bond i-j from cell a to cell b has moved by
/// |d_j - d_i| <= |d_i - m_a| + |m_a - m_b| + rho_b, so only the particles whose slack is below
/// |d_i - m_a| + max over a's neighbours b of (|m_a - m_b| + rho_b) are tested, with the same
/// test. The bound follows the local motion: a body that moves, turns or vibrates as a whole
/// moves neighbouring cells alike. A bond that breaks is found from both its ends (the slack
/// and the bound are symmetric). When more than an eighth of the particles would be tested,
/// all are, and the record is taken again. So the screen only skips tests that would find
/// nothing: the bonds break at the same steps as without it, bit for bit. The stretch and the
/// relative-displacement measures are screened; the rotation-corrected one (which also reads
/// the orientations) tests every bond at every check.
#[derive(Clone, Debug, Default)]
pub struct StrainScreen<const D: usize> {
    /// Displacements at the last full test (empty: no valid record).
    u_ref: Vec<Vect<D>>,
    /// The cells of the reference lattice (empty until the first record).
    cells: RestCells,
    /// Per particle, the lower bound of the relative motion of the ends of any of its intact
    /// bonds that could break it, at the last full test (m).
    slack: Vec<f64>,
    /// Per cell scratch: the mean displacement change since the record (m).
    cell_mean: Vec<Vect<D>>,
    /// Per cell scratch: the largest distance of a member's change from the mean (m).
    cell_radius: Vec<f64>,
    /// Per cell scratch: the largest |m_a - m_b| + rho_b over its neighbours b (m).
    cell_reach: Vec<f64>,
    /// Shortest reference bond length of the set-up (m): bonds only break, so it bounds every
    /// intact bond's from below for good.
    l0_min: f64,
    /// Checks that tested every bond, and the particles tested by the others.
    pub full_tests: u64,
    pub particles_tested: u64,
}

/// The cells of the reference positions, per body: compressed rows of their members and of
/// their neighbouring cells (each cell's own included).
#[derive(Clone, Debug, Default)]
struct RestCells {
    /// Per particle, its cell.
    cell_of: Vec<u32>,
    member_start: Vec<u32>,
    members: Vec<u32>,
    near_start: Vec<u32>,
    near: Vec<u32>,
}

/// The larger of a and b, NaN if either is (a blown-up state then reaches every bound).
#[inline(always)]
fn max_nan(a: f64, b: f64) -> f64 {
    if b > a || b.is_nan() {
        b
    } else {
        a
    }
}

impl RestCells {
    /// Cells of side the longest bond (and a little more, for the round-off of the cell
    /// index) over the reference positions `x0`, separate per body. Every bond is checked to
    /// join a cell to one of its neighbours; should one not (a bond not between reference
    /// positions), each body is one cell, which bounds as the body's largest motion does.
    fn build<const D: usize>(x0: &[Vect<D>], body: &[u32], bonds: &Bonds<D>) -> Self {
        let longest = bonds.r0.iter().map(|r| r.norm()).fold(0.0, f64::max);
        let side = if longest > 0.0 && longest.is_finite() {
            longest * (1.0 + 1e-9)
        } else {
            1.0
        };
        let cells = Self::with_side(x0, body, Some(side));
        let joined = (0..x0.len()).all(|i| {
            bonds.of(i).all(|k| {
                let j = bonds.nbr[k] as usize;
                cells.near_of(cells.cell_of[i]).contains(&cells.cell_of[j])
            })
        });
        if joined {
            cells
        } else {
            Self::with_side(x0, body, None)
        }
    }

    /// The cells of side `side` (None: one per body).
    fn with_side<const D: usize>(x0: &[Vect<D>], body: &[u32], side: Option<f64>) -> Self {
        let n = x0.len();
        let mut lo = Vect::<D>::repeat(f64::INFINITY);
        for x in x0 {
            lo = lo.inf(x);
        }
        let key = |i: usize| -> (u32, [i64; D]) {
            let mut k = [0i64; D];
            if let Some(h) = side {
                for (d, kd) in k.iter_mut().enumerate() {
                    let c = ((x0[i][d] - lo[d]) / h).floor();
                    // A non-finite position falls in cell 0 (the bonds' check then fails).
                    *kd = if c.is_finite() { c as i64 } else { 0 };
                }
            }
            (body[i], k)
        };
        let mut index: FxHashMap<(u32, [i64; D]), u32> = FxHashMap::default();
        let mut cell_of = Vec::with_capacity(n);
        for i in 0..n {
            let next = index.len() as u32;
            cell_of.push(*index.entry(key(i)).or_insert(next));
        }
        let m = index.len();
        let all: Vec<u32> = (0..n as u32).collect();
        let (member_start, members) = super::grid::rows_by_cell(&cell_of, m, &all);
        let mut keys = vec![(0u32, [0i64; D]); m];
        for (k, &c) in &index {
            keys[c as usize] = *k;
        }
        let mut near_start = Vec::with_capacity(m + 1);
        let mut near = Vec::new();
        near_start.push(0u32);
        let offsets = 3usize.pow(D as u32);
        for (b, k) in &keys {
            for o in 0..offsets {
                let mut nk = *k;
                let mut r = o;
                for kd in nk.iter_mut() {
                    *kd += (r % 3) as i64 - 1;
                    r /= 3;
                }
                if let Some(&c) = index.get(&(*b, nk)) {
                    near.push(c);
                }
            }
            near_start.push(near.len() as u32);
        }
        RestCells {
            cell_of,
            member_start,
            members,
            near_start,
            near,
        }
    }

    fn near_of(&self, c: u32) -> &[u32] {
        &self.near[self.near_start[c as usize] as usize..self.near_start[c as usize + 1] as usize]
    }

    fn members_of(&self, c: usize) -> &[u32] {
        &self.members[self.member_start[c] as usize..self.member_start[c + 1] as usize]
    }

    fn len(&self) -> usize {
        self.member_start.len().saturating_sub(1)
    }
}

impl<const D: usize> StrainScreen<D> {
    /// Forgets the record (the state was restored: its bonds may differ).
    pub fn invalidate(&mut self) {
        self.u_ref.clear();
    }

    /// The particles (ascending) with a bond strained beyond eps_max, as
    /// [`strained_particles`] finds them, testing only the bonds that may have reached the
    /// limit since the record. `x0` are the reference positions the bonds were built from;
    /// `flag` is scratch (one byte per particle).
    #[allow(clippy::too_many_arguments)]
    pub fn strained(
        &mut self,
        x0: &[Vect<D>],
        u: &[Vect<D>],
        q: &[<Space as Dim<D>>::Rotation],
        body: &[u32],
        bonds: &Bonds<D>,
        eps_max: f64,
        measure: BondStrain,
        flag: &mut Vec<u8>,
    ) -> Vec<usize>
    where
        Space: Dim<D>,
    {
        let n = u.len();
        if measure == BondStrain::RotationCorrected {
            self.full_tests += 1;
            return strained_particles(u, q, bonds, eps_max, measure, flag);
        }
        if self.u_ref.len() != n || self.cells.cell_of.len() != n {
            return self.record(x0, u, body, bonds, eps_max, measure, flag);
        }
        let (u_ref, cells) = (&self.u_ref, &self.cells);
        let m = cells.len();
        self.cell_mean.resize(m, Vect::<D>::zeros());
        self.cell_radius.resize(m, 0.0);
        self.cell_reach.resize(m, 0.0);
        par_iter_mut!(self.cell_mean[..])
            .zip(par_iter_mut!(self.cell_radius[..]))
            .enumerate()
            .for_each(|(c, (mean, radius))| {
                let members = cells.members_of(c);
                let mut sum = Vect::<D>::zeros();
                for &i in members {
                    sum += u[i as usize] - u_ref[i as usize];
                }
                *mean = sum / members.len().max(1) as f64;
                let mut r = 0.0;
                for &i in members {
                    r = max_nan(r, ((u[i as usize] - u_ref[i as usize]) - *mean).norm());
                }
                *radius = r;
            });
        let (mean, radius) = (&self.cell_mean, &self.cell_radius);
        par_iter_mut!(self.cell_reach[..])
            .enumerate()
            .for_each(|(c, reach)| {
                *reach = cells.near_of(c as u32).iter().fold(0.0, |r, &b| {
                    let b = b as usize;
                    max_nan(r, (mean[c] - mean[b]).norm() + radius[b])
                });
            });
        flag.resize(n, 0);
        let (slack, reach) = (&self.slack, &self.cell_reach);
        let tol = SCREEN_ROUND_OFF * self.l0_min;
        par_iter_mut!(flag[..]).enumerate().for_each(|(i, f)| {
            let c = cells.cell_of[i] as usize;
            let own = ((u[i] - u_ref[i]) - mean[c]).norm();
            // Skipped only when the reach is surely within the slack (NaN: tested).
            let clear = own + reach[c] + tol < SCREEN_USE * slack[i];
            *f = u8::from(!clear);
        });
        let candidates = flag.iter().filter(|&&f| f != 0).count();
        if candidates as f64 > SCREEN_RECORD_SHARE * n as f64 {
            return self.record(x0, u, body, bonds, eps_max, measure, flag);
        }
        self.particles_tested += candidates as u64;
        if candidates == 0 {
            return Vec::new();
        }
        let limit2 = strain_limit2(eps_max, measure);
        par_iter_mut!(flag[..]).enumerate().for_each(|(i, f)| {
            if *f != 0 {
                let hit = bonds.of(i).any(|k| {
                    bonds.w0[k] != 0.0
                        && strained(measure, limit2, i, bonds.nbr[k] as usize, bonds.r0[k], u, q)
                });
                *f = u8::from(hit);
            }
        });
        (0..n).filter(|&i| flag[i] != 0).collect()
    }

    /// Full test, recording the displacements and each particle's slack over the bonds that
    /// stay intact.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        x0: &[Vect<D>],
        u: &[Vect<D>],
        body: &[u32],
        bonds: &Bonds<D>,
        eps_max: f64,
        measure: BondStrain,
        flag: &mut Vec<u8>,
    ) -> Vec<usize> {
        let n = u.len();
        self.full_tests += 1;
        if self.cells.cell_of.len() != n {
            self.cells = RestCells::build(&x0[..n.min(x0.len())], body, bonds);
            self.l0_min = bonds
                .r0
                .iter()
                .map(|r| r.norm())
                .fold(f64::INFINITY, f64::min);
        }
        flag.resize(n, 0);
        self.slack.resize(n, 0.0);
        let limit2 = strain_limit2(eps_max, measure);
        // Per bond, with x2 its measured squared length (the stretched bond's, or its relative
        // displacement's) and L2 = limit2 |r0|^2: strained when x2 > L2 (the test of
        // `strained`, in the same canonical direction), else its ends must move by at least
        // sqrt(L2) - sqrt(x2) = (L2 - x2) / (sqrt(L2) + sqrt(x2)) >= m l0 / (2 sqrt(limit2))
        // relative to each other, with m = (L2 - x2) / |r0|^2.
        let scale = self.l0_min / (2.0 * limit2.sqrt());
        par_iter_mut!(flag[..])
            .zip(par_iter_mut!(self.slack[..]))
            .enumerate()
            .for_each(|(i, (f, slack))| {
                let mut hit = false;
                let mut m = f64::INFINITY;
                let ui = u[i];
                for k in bonds.of(i) {
                    if bonds.w0[k] == 0.0 {
                        continue;
                    }
                    // From i to j, not in `strained`'s canonical direction: the two differ by
                    // the sign of r0 and of du (exactly, as r0_ji = -r0_ij and u_i - u_j =
                    // -(u_j - u_i) in floating point), which the squared lengths do not see.
                    let r0 = bonds.r0[k];
                    let du = u[bonds.nbr[k] as usize] - ui;
                    let l02 = r0.norm_squared();
                    let x2 = match measure {
                        BondStrain::Stretch => (r0 + du).norm_squared(),
                        _ => du.norm_squared(),
                    };
                    let room = limit2 * l02 - x2;
                    if room < 0.0 {
                        hit = true;
                    } else if room < m * l02 {
                        m = room / l02;
                    }
                }
                *f = u8::from(hit);
                // A NaN room leaves m as it was: a non-finite state is caught by the step.
                *slack = m * scale;
            });
        self.u_ref.clear();
        self.u_ref.extend_from_slice(u);
        (0..n).filter(|&i| flag[i] != 0).collect()
    }
}
