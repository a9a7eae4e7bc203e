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
pub(super) fn strained<const D: usize>(
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
pub(super) fn strain_limit2(eps_max: f64, measure: BondStrain) -> f64 {
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
