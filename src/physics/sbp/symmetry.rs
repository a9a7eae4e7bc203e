//! The closure's axes solved (module `sbp`), the alike ones once: an axis whose target is
//! another's under the swap of the two axes (a box alike along both, its faces and clamps too:
//! the cross-section axes of a square beam, two axes of a cube) takes that axis's corrections
//! swapped instead of a conjugate-gradient solve of its own, checked against its own
//! constraints. The targets must agree to 1e-13 of their norm: a cube's x axis differs from y
//! and z by 1e-8 of its target (the corner fits' round-off), and is solved, from the other's
//! multipliers swapped.
use std::collections::HashMap;

use super::least_norm::{NullSpaceConstraints, Unfinished};
use crate::physics::bonds::Bonds;
use crate::physics::dim::{Dim, Space};

/// Largest difference of the two targets, relative to the first's norm, for which the axes
/// are taken as alike (their targets agree to a few 1e-16 when the box is alike along both).
const ALIKE: f64 = 1e-13;

/// Largest difference of two targets for which one axis's solve starts from the other's
/// multipliers (any start is correct; a near one saves the iterations).
const NEAR: f64 = 1e-4;

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
        self.axes_within(targets, ALIKE)
    }

    /// As `alike_axes`, with the targets' agreement `tol` (relative to their norm).
    pub(super) fn axes_within(
        &self,
        targets: &[Vec<f64>],
        tol: f64,
    ) -> Vec<Option<(usize, Vec<usize>)>> {
        let mut mapped: Vec<Option<(usize, Vec<usize>)>> = vec![None; D];
        for d2 in 1..D {
            for d1 in 0..d2 {
                if mapped[d1].is_none() && mapped[d2].is_none() {
                    if let Some(perm) = self.permutation(d1, d2, &targets[d1], &targets[d2], tol) {
                        mapped[d2] = Some((d1, perm));
                    }
                }
            }
        }
        mapped
    }

    /// Solves the axes' least-norm problems (their targets `targets`, the coarse correction on
    /// the axes `coarse_on` says): the alike ones once, carried to their partners and checked
    /// against the partners' constraints; an axis alike another but for its targets'
    /// round-off (a cube's x against y, 1e-8) from that one's multipliers swapped (free 30^3
    /// cube: 2,405 -> 839 iterations; case 1's column 809 -> 346). Returns each axis's result
    /// and, per axis, the axis whose corrections it took.
    #[allow(clippy::type_complexity)]
    pub(super) fn solve_axes(
        &self,
        sys: &NullSpaceConstraints<D>,
        vb: &Bonds<D>,
        targets: &[Vec<f64>],
        coarse_on: &(dyn Fn(usize) -> bool + Sync),
        stop: &(dyn Fn() -> bool + Sync),
    ) -> (
        Vec<Result<(Vec<f64>, Vec<f64>, usize, f64), Unfinished>>,
        Vec<Option<usize>>,
    )
    where
        Space: Dim<D>,
    {
        let nq = self.nq;
        let mut mapped = self.alike_axes(targets);
        // Axes alike but for round-off of their targets (a cube's x against y: 1e-8): the lower
        // one starts from the other's multipliers swapped.
        let near = self.axes_within(targets, NEAR);
        let mut warm: Vec<Option<(usize, Vec<usize>)>> = vec![None; D];
        for (d2, m) in near.into_iter().enumerate() {
            if let Some((d1, perm)) = m {
                if mapped[d1].is_none() && mapped[d2].is_none() && warm[d2].is_none() {
                    warm[d1] = Some((d2, perm));
                }
            }
        }
        let first: Vec<usize> = (0..D)
            .filter(|&d| mapped[d].is_none() && warm[d].is_none())
            .collect();
        let solve = |&d: &usize| sys.solve(&targets[d], coarse_on(d), stop, None);
        let mut by_axis: Vec<Option<_>> = (0..D).map(|_| None).collect();
        for (&d, r) in first.iter().zip(crate::physics::par::map(&first, solve)) {
            by_axis[d] = Some(r);
        }
        let second: Vec<usize> = (0..D).filter(|&d| warm[d].is_some()).collect();
        let solve_warm = |&d: &usize| {
            let (d2, perm) = warm[d].as_ref().expect("a warm axis");
            let y0 = match by_axis[*d2].as_ref() {
                Some(Ok((_, y2, _, _))) => Some(swapped_multipliers(perm, y2, nq, *d2, d)),
                _ => None,
            };
            sys.solve(&targets[d], coarse_on(d), stop, y0.as_deref())
        };
        for (&d, r) in second
            .iter()
            .zip(crate::physics::par::map(&second, solve_warm))
        {
            by_axis[d] = Some(r);
        }
        for d in 0..D {
            let Some((d1, perm)) = &mapped[d] else {
                continue;
            };
            let Some(Ok((c1, _, _, res1))) = by_axis[*d1].as_ref() else {
                by_axis[d] = Some(sys.solve(&targets[d], coarse_on(d), stop, None));
                mapped[d] = None;
                continue;
            };
            let c2 = swapped_corrections(vb, perm, c1);
            let t = &targets[d];
            let tnorm = t.iter().map(|v| v * v).sum::<f64>().sqrt();
            by_axis[d] = match c2.and_then(|c2| Some((sys.residual(&c2, t)?, c2))) {
                Some((res, c2)) if res <= (2.0 * res1).max(1e-9 * tnorm) => {
                    Some(Ok((c2, Vec::new(), 0, res)))
                }
                _ => {
                    mapped[d] = None;
                    Some(sys.solve(t, coarse_on(d), stop, None))
                }
            };
        }
        let solved = by_axis.into_iter().flatten().collect();
        (
            solved,
            mapped
                .iter()
                .map(|m| m.as_ref().map(|(d1, _)| *d1))
                .collect(),
        )
    }

    /// The particles' permutation under the swap of axes d1 and d2, when the box has it and
    /// the targets t1 (of d1) and t2 (of d2) agree under it.
    fn permutation(
        &self,
        d1: usize,
        d2: usize,
        t1: &[f64],
        t2: &[f64],
        tol: f64,
    ) -> Option<Vec<usize>> {
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
            (0..nq).all(|q| (t2[p * nq + swap_q(q)] - t1[k * nq + q]).abs() <= tol * tnorm)
        });
        alike.then_some(perm)
    }
}

/// The multipliers y1 of axis d1 (nq per column) carried to axis d2 by the particles'
/// permutation under the swap of the two axes.
pub(super) fn swapped_multipliers(
    perm: &[usize],
    y1: &[f64],
    nq: usize,
    d1: usize,
    d2: usize,
) -> Vec<f64> {
    let mut y2 = vec![0.0; y1.len()];
    for (k, &p) in perm.iter().enumerate() {
        for q in 0..nq {
            let q2 = match q {
                _ if q == 1 + d1 => 1 + d2,
                _ if q == 1 + d2 => 1 + d1,
                _ => q,
            };
            y2[p * nq + q2] = y1[k * nq + q];
        }
    }
    y2
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
