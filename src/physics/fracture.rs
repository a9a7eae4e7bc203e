//! Fracture, Eq. (42): a bond whose strain eps_ij = (|r_ij| - |r0_ij|) / |r0_ij| exceeds eps_max
//! breaks for good (its weight w0 is set to zero in both stored directions), and both particles
//! become surface particles (Eq. (41) and section 2.5). Also: fragments as connected components
//! over the intact bonds.
use super::bonds::Bonds;
use super::dim::Vect;
#[allow(unused_imports)]
use super::par::*;
use crate::par_iter_mut;

/// Finds the bonds to break at the current positions and breaks them. The test compares squared
/// lengths, |r_ij|^2 > (1 + eps_max)^2 |r0_ij|^2 with r_ij = r0_ij + (u_j - u_i) (displacements
/// `u`), which is the same in both stored directions to the last bit (r_ji = -r_ij exactly), so both directions of a bond break in the same step
/// whatever the thread count. `flag` is scratch (one byte per particle). Returns the particles
/// that lost bonds (ascending) and the number of pairs broken.
pub fn break_bonds<const D: usize>(
    u: &[Vect<D>],
    bonds: &mut Bonds<D>,
    eps_max: f64,
    flag: &mut Vec<u8>,
) -> (Vec<usize>, u64) {
    let n = u.len();
    flag.resize(n, 0);
    let limit = (1.0 + eps_max) * (1.0 + eps_max);
    {
        let b = &*bonds;
        // Gather pass: each particle tests its own bonds and writes only its own flag.
        par_iter_mut!(flag[..]).enumerate().for_each(|(i, f)| {
            let ui = u[i];
            let mut hit = 0u8;
            for k in b.of(i) {
                if b.w0[k] == 0.0 {
                    continue;
                }
                let r = b.r0[k] + (u[b.nbr[k] as usize] - ui);
                if r.norm_squared() > limit * b.r0[k].norm_squared() {
                    hit = 1;
                    break;
                }
            }
            *f = hit;
        });
    }
    let mut touched = Vec::new();
    let mut pairs = 0u64;
    for i in 0..n {
        if flag[i] == 0 {
            continue;
        }
        touched.push(i);
        let ui = u[i];
        for k in bonds.of(i) {
            if bonds.w0[k] == 0.0 {
                continue;
            }
            let j = bonds.nbr[k] as usize;
            let r = bonds.r0[k] + (u[j] - ui);
            if r.norm_squared() > limit * bonds.r0[k].norm_squared() {
                bonds.w0[k] = 0.0;
                // Each pair is counted once, from its lower index (the other direction is found
                // from the other particle, which is flagged too: the test is symmetric).
                if i < j {
                    pairs += 1;
                }
            }
        }
    }
    (touched, pairs)
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
