//! Fracture, Eq. (42): a bond whose strain eps_ij (by default the stretch
//! (|r_ij| - |r0_ij|) / |r0_ij|; see [`BondStrain`]) exceeds eps_max breaks for good (its weight w0 is set to zero in both stored directions), and both particles
//! become surface particles (Eq. (41) and section 2.5). Also: fragments as connected components
//! over the intact bonds.
use super::bonds::Bonds;
use super::dim::{Dim, Space, Vect};
#[allow(unused_imports)]
use super::par::*;
use super::params::BondStrain;
use crate::par_iter_mut;

/// Whether the bond from particle `i` to `j` (reference vector `r0`) is strained beyond eps_max
/// by the measure `m`, Eq. (42). Evaluated in one canonical direction (from the lower index),
/// so both stored directions of a bond give the same answer to the last bit whatever the thread
/// count, and both break in the same step. `limit2` is (1 + eps_max)^2 for the stretch and
/// eps_max^2 otherwise.
#[allow(clippy::too_many_arguments)]
fn strained<const D: usize>(
    m: BondStrain,
    limit2: f64,
    i: usize,
    j: usize,
    r0: Vect<D>,
    u: &[Vect<D>],
    q: &[<Space as Dim<D>>::Rotation],
) -> bool
where
    Space: Dim<D>,
{
    let (a, b, r0) = if i < j { (i, j, r0) } else { (j, i, -r0) };
    let du = u[b] - u[a];
    let l02 = r0.norm_squared();
    match m {
        BondStrain::Stretch => (r0 + du).norm_squared() > limit2 * l02,
        BondStrain::RelativeDisplacement => du.norm_squared() > limit2 * l02,
        BondStrain::RotationCorrected => {
            let rigid = <Space as Dim<D>>::rotate_midpoint(&q[a], &q[b], &r0) - r0;
            (du - rigid).norm_squared() > limit2 * l02
        }
    }
}

/// Finds the bonds to break at the current displacements `u` (and orientations `q`, for the
/// rotation-corrected measure) and breaks them. `flag` is scratch (one byte per particle).
/// Returns the particles that lost bonds (ascending) and the number of pairs broken.
pub fn break_bonds<const D: usize>(
    u: &[Vect<D>],
    q: &[<Space as Dim<D>>::Rotation],
    bonds: &mut Bonds<D>,
    eps_max: f64,
    measure: BondStrain,
    flag: &mut Vec<u8>,
) -> (Vec<usize>, u64)
where
    Space: Dim<D>,
{
    let touched = strained_particles(u, q, bonds, eps_max, measure, flag);
    let pairs = break_strained(u, q, bonds, eps_max, measure, &touched);
    (touched, pairs)
}

/// `limit2` of [`strained`] for eps_max and the measure.
fn strain_limit2(eps_max: f64, measure: BondStrain) -> f64 {
    match measure {
        BondStrain::Stretch => (1.0 + eps_max) * (1.0 + eps_max),
        _ => eps_max * eps_max,
    }
}

/// The particles (ascending) with a bond strained beyond eps_max, which [`break_strained`]
/// then breaks. `flag` is scratch (one byte per particle).
pub fn strained_particles<const D: usize>(
    u: &[Vect<D>],
    q: &[<Space as Dim<D>>::Rotation],
    bonds: &Bonds<D>,
    eps_max: f64,
    measure: BondStrain,
    flag: &mut Vec<u8>,
) -> Vec<usize>
where
    Space: Dim<D>,
{
    flag.resize(u.len(), 0);
    let limit2 = strain_limit2(eps_max, measure);
    // Gather pass: each particle tests its own bonds and writes only its own flag.
    par_iter_mut!(flag[..]).enumerate().for_each(|(i, f)| {
        let hit = bonds.of(i).any(|k| {
            bonds.w0[k] != 0.0
                && strained(measure, limit2, i, bonds.nbr[k] as usize, bonds.r0[k], u, q)
        });
        *f = u8::from(hit);
    });
    (0..u.len()).filter(|&i| flag[i] != 0).collect()
}

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

/// A screen in front of the bond-strain test (issue 25). At a full test it records the
/// displacements and, per particle, a lower bound of how far the two ends of any of its intact
/// bonds must move relative to each other before the bond can reach eps_max (its slack). At
/// the next checks a pass over the particles (not the bonds) takes each particle's
/// displacement change since the record, less its body's translation (d_i), and the largest
/// of its body (d_max): a bond i-j has moved by at most d_i + d_j <= d_i + d_max, so only the particles
/// whose slack is below that are tested, with the same test; a bond that breaks is found from
/// both its ends (the slack and the bound are symmetric). When more than an eighth of the
/// particles would be tested, all are, and the record is taken again. So the screen only
/// skips tests that would find nothing: the bonds break at the same steps as without it, bit
/// for bit. The stretch and the relative-displacement measures are screened; the
/// rotation-corrected one (which also reads the orientations) tests every bond at every check.
#[derive(Clone, Debug, Default)]
pub struct StrainScreen<const D: usize> {
    /// Displacements at the last full test (empty: no valid record).
    u_ref: Vec<Vect<D>>,
    /// Per body, the particle whose displacement change is taken as the body's translation
    /// (its lowest index).
    anchor: Vec<u32>,
    /// Per particle, the lower bound of the relative motion of the ends of any of its intact
    /// bonds that could break it, at the last full test (m).
    slack: Vec<f64>,
    /// Per particle scratch: its displacement change since the record (m).
    moved: Vec<f64>,
    /// Per body scratch: the largest of its particles' `moved` (m).
    moved_max: Vec<f64>,
    /// Shortest reference bond length of the set-up (m): bonds only break, so it bounds every
    /// intact bond's from below for good.
    l0_min: f64,
    /// Checks that tested every bond, and the particles tested by the others.
    pub full_tests: u64,
    pub particles_tested: u64,
}

impl<const D: usize> StrainScreen<D> {
    /// Forgets the record (the state was restored: its bonds may differ).
    pub fn invalidate(&mut self) {
        self.u_ref.clear();
    }

    /// The particles (ascending) with a bond strained beyond eps_max, as
    /// [`strained_particles`] finds them, testing only the bonds that may have reached the
    /// limit since the record. `flag` is scratch (one byte per particle).
    #[allow(clippy::too_many_arguments)]
    pub fn strained(
        &mut self,
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
        if self.u_ref.len() != n {
            return self.record(u, body, bonds, eps_max, measure, flag);
        }
        let (u_ref, anchor) = (&self.u_ref, &self.anchor);
        self.moved.resize(n, 0.0);
        par_iter_mut!(self.moved[..])
            .enumerate()
            .for_each(|(i, d)| {
                let a = anchor[body[i] as usize] as usize;
                *d = ((u[i] - u_ref[i]) - (u[a] - u_ref[a])).norm();
            });
        // Per body the largest change (bonds join particles of one body). NaN (a blown-up
        // state) makes its max NaN and every comparison false below: then all its particles
        // are candidates and the full test runs.
        self.moved_max.clear();
        self.moved_max.resize(self.anchor.len(), 0.0);
        for (&d, &b) in self.moved.iter().zip(body) {
            let m = &mut self.moved_max[b as usize];
            if d > *m || d.is_nan() {
                *m = d;
            }
        }
        flag.resize(n, 0);
        let (slack, moved, moved_max) = (&self.slack, &self.moved, &self.moved_max);
        let tol = SCREEN_ROUND_OFF * self.l0_min;
        par_iter_mut!(flag[..]).enumerate().for_each(|(i, f)| {
            let reach = moved[i] + moved_max[body[i] as usize] + tol;
            // Skipped only when the reach is surely within the slack (NaN: tested).
            let clear = reach < SCREEN_USE * slack[i];
            *f = u8::from(!clear);
        });
        let candidates = flag.iter().filter(|&&f| f != 0).count();
        if candidates as f64 > SCREEN_RECORD_SHARE * n as f64 {
            return self.record(u, body, bonds, eps_max, measure, flag);
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
    fn record(
        &mut self,
        u: &[Vect<D>],
        body: &[u32],
        bonds: &Bonds<D>,
        eps_max: f64,
        measure: BondStrain,
        flag: &mut Vec<u8>,
    ) -> Vec<usize> {
        let n = u.len();
        self.full_tests += 1;
        if self.anchor.is_empty() {
            let bodies = body.iter().map(|&b| b as usize + 1).max().unwrap_or(0);
            self.anchor = vec![0; bodies];
            for (i, &b) in body.iter().enumerate().rev() {
                self.anchor[b as usize] = i as u32;
            }
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

/// Breaks the bonds of the `touched` particles (from [`strained_particles`] at the same state)
/// strained beyond eps_max. Returns the number of pairs broken.
pub fn break_strained<const D: usize>(
    u: &[Vect<D>],
    q: &[<Space as Dim<D>>::Rotation],
    bonds: &mut Bonds<D>,
    eps_max: f64,
    measure: BondStrain,
    touched: &[usize],
) -> u64
where
    Space: Dim<D>,
{
    let limit2 = strain_limit2(eps_max, measure);
    let mut pairs = 0u64;
    for &i in touched {
        for k in bonds.of(i) {
            if bonds.w0[k] == 0.0 {
                continue;
            }
            let j = bonds.nbr[k] as usize;
            if strained(measure, limit2, i, j, bonds.r0[k], u, q) {
                bonds.w0[k] = 0.0;
                // Each pair is counted once, from its lower index (the other direction is found
                // from the other particle, which is flagged too: the test is symmetric).
                if i < j {
                    pairs += 1;
                }
            }
        }
    }
    pairs
}

/// Number of broken (directed) bonds of particle i.
pub fn broken_of<const D: usize>(bonds: &Bonds<D>, i: usize) -> u32 {
    bonds.of(i).filter(|&k| bonds.w0[k] == 0.0).count() as u32
}

/// Number of separate fragments: connected components of the particles over the intact bonds
/// (a body that never broke is one fragment; a particle that lost all its bonds is one).
pub fn fragments<const D: usize>(bonds: &Bonds<D>, n: usize) -> usize {
    let root = components(bonds, n);
    (0..n).filter(|&i| root[i] == i as u32).count()
}

/// Component label of every particle over the intact bonds: the lowest particle index of its
/// component.
pub fn components<const D: usize>(bonds: &Bonds<D>, n: usize) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            let g = parent[parent[a as usize] as usize];
            parent[a as usize] = g;
            a = g;
        }
        a
    }
    for i in 0..n {
        for k in bonds.of(i) {
            if bonds.w0[k] == 0.0 {
                continue;
            }
            let (a, b) = (find(&mut parent, i as u32), find(&mut parent, bonds.nbr[k]));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    (0..n as u32).map(|i| find(&mut parent, i)).collect()
}

/// Largest strain (|r_ij| - |r0_ij|) / |r0_ij| over the intact bonds, and the particle that has
/// it; `u` are the displacements.
pub fn max_bond_strain<const D: usize>(u: &[Vect<D>], bonds: &Bonds<D>) -> (f64, usize) {
    let mut best = (f64::NEG_INFINITY, 0);
    for i in 0..u.len() {
        for k in bonds.of(i) {
            if bonds.w0[k] == 0.0 {
                continue;
            }
            let l = bonds.r0[k].norm();
            let e = ((bonds.r0[k] + (u[bonds.nbr[k] as usize] - u[i])).norm() - l) / l;
            if e > best.0 {
                best = (e, i);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two particles 1 apart whose pair turns rigidly by `theta`, the particles' orientations
    /// turned with it: which measures break the bond at eps_max = 0.2?
    fn breaks(measure: BondStrain, theta: f64) -> bool {
        let x0 = [Vect::<2>::new(0.0, 0.0), Vect::<2>::new(1.0, 0.0)];
        let mut bonds = Bonds::build(&x0, &[0, 0], 2.1);
        let u = [
            Vect::<2>::zeros(),
            Vect::<2>::new(theta.cos() - 1.0, theta.sin()),
        ];
        let q = [theta, theta];
        let (touched, pairs) = break_bonds(&u, &q, &mut bonds, 0.2, measure, &mut vec![]);
        assert_eq!(touched.len(), 2 * pairs as usize, "both ends or none");
        pairs == 1
    }

    #[test]
    fn bond_strain_measures_of_a_rigid_turn() {
        // A rigid turn by 30 degrees: no stretch; a relative displacement of 2 sin(15 deg) =
        // 0.518 of the length (> 0.2: the non-objective measure breaks it); nothing left once
        // the particles' own rotation is taken out.
        let t = 30f64.to_radians();
        assert!(!breaks(BondStrain::Stretch, t));
        assert!(breaks(BondStrain::RelativeDisplacement, t));
        assert!(!breaks(BondStrain::RotationCorrected, t));
        // A turn by 10 degrees (2 sin 5 deg = 0.174 < 0.2) breaks nothing.
        assert!(!breaks(
            BondStrain::RelativeDisplacement,
            10f64.to_radians()
        ));
    }
}
