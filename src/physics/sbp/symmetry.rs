//! Axes of the closure's box that are alike (module `sbp`): an axis whose target is another's
//! under the swap of the two axes (a box alike along both, its faces and clamps too: the
//! cross-section axes of a square beam, two axes of a cube) takes that axis's corrections
//! swapped instead of a conjugate-gradient solve of its own; the caller checks them against
//! the axis's own constraints. The targets must agree to 1e-13 of their norm: a cube's x axis
//! differs from y and z by 1e-8 of its target (the corner fits' round-off), and is solved.
use std::collections::HashMap;

use crate::physics::bonds::Bonds;
use crate::physics::dim::{Dim, Space};

/// Largest difference of the two targets, relative to the first's norm, for which the axes
/// are taken as alike (their targets agree to a few 1e-16 when the box is alike along both).
const ALIKE: f64 = 1e-13;

/// The reduced box, as its axes' swaps see it.
pub(super) struct BoxAxes<'a, const D: usize> {
    /// The reduced box's particles per axis and the body's.
    pub small: &'a [usize; D],
    pub ext: &'a [usize; D],
    /// Each particle's lattice index in the reduced box, and the inverse map.
    pub sidx: &'a [[usize; D]],
    pub small_index: &'a HashMap<[usize; D], usize>,
    /// Fields per column (1 + D).
    pub nq: usize,
}

impl<const D: usize> BoxAxes<'_, D> {
    /// Per axis d2, the axis d1 < d2 (itself solved) whose corrections it takes and the
    /// particles' permutation that carries them; None: solved.
    pub(super) fn alike_axes(&self, targets: &[Vec<f64>]) -> Vec<Option<(usize, Vec<usize>)>> {
        let mut mapped: Vec<Option<(usize, Vec<usize>)>> = vec![None; D];
        for d2 in 1..D {
            for d1 in 0..d2 {
                if mapped[d1].is_none() && mapped[d2].is_none() {
                    if let Some(perm) = self.permutation(d1, d2, &targets[d1], &targets[d2]) {
                        mapped[d2] = Some((d1, perm));
                    }
                }
            }
        }
        mapped
    }

    /// The particles' permutation under the swap of axes d1 and d2, when the box has it and
    /// the targets t1 (of d1) and t2 (of d2) agree under it.
    fn permutation(&self, d1: usize, d2: usize, t1: &[f64], t2: &[f64]) -> Option<Vec<usize>> {
        let nq = self.nq;
        if self.small[d1] != self.small[d2] || self.ext[d1] != self.ext[d2] {
            return None;
        }
        let perm: Vec<usize> = self
            .sidx
            .iter()
            .map(|k| {
                let mut k2 = *k;
                k2.swap(d1, d2);
                self.small_index.get(&k2).copied()
            })
            .collect::<Option<_>>()?;
        // The linear fields' components swap with the axes.
        let swap_q = |q: usize| match q {
            _ if q == 1 + d1 => 1 + d2,
            _ if q == 1 + d2 => 1 + d1,
            _ => q,
        };
        let tnorm = t1.iter().map(|v| v * v).sum::<f64>().sqrt();
        let alike = perm.iter().enumerate().all(|(k, &p)| {
            (0..nq).all(|q| (t2[p * nq + swap_q(q)] - t1[k * nq + q]).abs() <= ALIKE * tnorm)
        });
        alike.then_some(perm)
    }
}

/// The corrections c1 (per bond of `vb`) carried by the particles' permutation: bond i -> j's
/// to the bond perm(i) -> perm(j); None when a bond has no image.
pub(super) fn swapped_corrections<const D: usize>(
    vb: &Bonds<D>,
    perm: &[usize],
    c1: &[f64],
) -> Option<Vec<f64>>
where
    Space: Dim<D>,
{
    let mut c2 = vec![0.0; vb.len()];
    for (i, &p) in perm.iter().enumerate() {
        for bnd in vb.of(i) {
            let pj = perm[vb.nbr[bnd] as usize] as u32;
            let b2 = vb.of(p).find(|&b2| vb.nbr[b2] == pj)?;
            c2[b2] = c1[bnd];
        }
    }
    Some(c2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::dim::Vect;

    /// The lattice indices, their inverse map and the positions.
    type Lattice = (Vec<[usize; 2]>, HashMap<[usize; 2], usize>, Vec<Vect<2>>);

    /// A 4 x 4 lattice box (2D), its particles in row-major order.
    fn lattice() -> Lattice {
        let sidx: Vec<[usize; 2]> = (0..16).map(|i| [i / 4, i % 4]).collect();
        let index = sidx.iter().enumerate().map(|(i, k)| (*k, i)).collect();
        let x = sidx
            .iter()
            .map(|k| Vect::<2>::new(k[0] as f64, k[1] as f64))
            .collect();
        (sidx, index, x)
    }

    #[test]
    fn swapped_targets_are_found_and_near_misses_are_not() {
        let (sidx, small_index, _) = lattice();
        let nq = 3;
        let t1: Vec<f64> = (0..16 * nq)
            .map(|v| ((v * 7919) % 101) as f64 - 50.0)
            .collect();
        // t2 = t1 under the swap: column (i, j) <- (j, i), fields 1 and 2 exchanged.
        let mut t2 = vec![0.0; t1.len()];
        for (k, idx) in sidx.iter().enumerate() {
            let p = small_index[&[idx[1], idx[0]]];
            t2[p * nq] = t1[k * nq];
            t2[p * nq + 2] = t1[k * nq + 1];
            t2[p * nq + 1] = t1[k * nq + 2];
        }
        let (square, long) = ([4, 4], [4, 20]);
        let axes = |ext| BoxAxes {
            small: &square,
            ext,
            sidx: &sidx,
            small_index: &small_index,
            nq,
        };
        let mapped = axes(&square).alike_axes(&[t1.clone(), t2.clone()]);
        let (d1, perm) = mapped[1].clone().expect("the swapped axis is found");
        assert_eq!(d1, 0);
        assert!(mapped[0].is_none(), "the first axis is solved");
        assert_eq!(perm[small_index[&[1, 3]]], small_index[&[3, 1]]);
        // A difference of 1e-8 of the target (a cube's x axis against y) is solved.
        let mut near = t2.clone();
        near[5] += 1e-8 * t1.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(axes(&square).alike_axes(&[t1.clone(), near])[1].is_none());
        // A body longer along one axis than the other is not swapped (its reduced box may be).
        assert!(axes(&long).alike_axes(&[t1, t2])[1].is_none());
    }

    #[test]
    fn corrections_follow_their_bonds_through_the_swap() {
        let (sidx, small_index, x) = lattice();
        let vb = Bonds::<2>::build(&x, &[0; 16], 1.5);
        let perm: Vec<usize> = sidx.iter().map(|k| small_index[&[k[1], k[0]]]).collect();
        let c1: Vec<f64> = (0..vb.len())
            .map(|b| {
                let i = vb.start.partition_point(|&s| s as usize <= b) - 1;
                (100 * i + vb.nbr[b] as usize) as f64
            })
            .collect();
        let c2 = swapped_corrections(&vb, &perm, &c1).expect("every bond has an image");
        for i in 0..16 {
            for b in vb.of(i) {
                let (p, pj) = (perm[i], perm[vb.nbr[b] as usize] as u32);
                let b2 = vb.of(p).find(|&b2| vb.nbr[b2] == pj).unwrap();
                assert_eq!(c2[b2], c1[b], "bond {i} -> {}", vb.nbr[b]);
            }
        }
        // A permutation that is not a symmetry of the bonds leaves a bond without an image.
        let mut wrong = perm.clone();
        wrong.swap(0, 5);
        assert!(swapped_corrections(&vb, &wrong, &c1).is_none());
    }
}
