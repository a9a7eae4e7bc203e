//! Interned per-particle weight sets ("stencil classes") of the second-order operator (issue
//! 25): the fit weights (g_b, h_b) of a particle, in its bond order, are stored once per
//! distinct set, and each particle holds the index of its set. On a lattice every interior
//! particle has the same neighbour pattern and so bitwise the same weights (translation
//! invariance of the fit, with the reference vectors quantised): a body of N particles has a
//! few hundred sets instead of N, the force loop reads its weights from the cache instead of
//! 96 bytes per bond from memory, and the memory per particle drops accordingly. Sets are
//! compared bit for bit, so interning changes no result.
use std::collections::HashMap;

use super::dim::{Dim, Mat, Space, Vect};

/// Values per bond of a set: the gradient weight g (D values, 1/m), then the upper triangle of
/// the symmetric Hessian weight h, row by row (D (D + 1) / 2 values, 1/m^2).
pub const fn stride(d: usize) -> usize {
    d + d * (d + 1) / 2
}

/// The weight sets and the set of each particle.
#[derive(Clone, Debug, Default)]
pub struct Stencils<const D: usize> {
    /// Set of each particle.
    pub class: Vec<u32>,
    /// Start of each set in `w` (in values); one more entry than sets.
    start: Vec<u32>,
    /// The sets' values, `stride(D)` per bond.
    w: Vec<f64>,
    /// Hash of a set's bits -> the sets with that hash.
    index: HashMap<u64, Vec<u32>>,
}

/// FNV-1a over the bits of the values (fast, and the sets are compared in full anyway).
fn hash(values: &[f64]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for v in values {
        h ^= v.to_bits();
        h = h.wrapping_mul(0x0000_0100_0000_01B3);
        h ^= h >> 29;
    }
    h ^ values.len() as u64
}

impl<const D: usize> Stencils<D>
where
    Space: Dim<D>,
{
    /// Room for `n` particles, none assigned.
    pub fn with_particles(n: usize) -> Self {
        Stencils {
            class: vec![u32::MAX; n],
            start: vec![0],
            w: Vec::new(),
            index: HashMap::new(),
        }
    }

    /// Packs the weights of one particle (in its bond order) into `out`.
    pub fn pack(g: &[Vect<D>], h: &[Mat<D>], out: &mut Vec<f64>) {
        out.clear();
        for (g, h) in g.iter().zip(h) {
            out.extend(g.iter());
            for a in 0..D {
                for c in a..D {
                    out.push(h[(a, c)]);
                }
            }
        }
    }

    /// The set with these values (bitwise), added if new; returns its index.
    pub fn intern(&mut self, values: &[f64]) -> u32 {
        let key = hash(values);
        if let Some(cands) = self.index.get(&key) {
            for &c in cands {
                let s = self.values(c);
                if s.len() == values.len()
                    && s.iter()
                        .zip(values)
                        .all(|(a, b)| a.to_bits() == b.to_bits())
                {
                    return c;
                }
            }
        }
        let c = (self.start.len() - 1) as u32;
        self.w.extend_from_slice(values);
        self.start.push(self.w.len() as u32);
        self.index.entry(key).or_default().push(c);
        c
    }

    /// Assigns particle i the set with these values.
    pub fn set(&mut self, i: usize, values: &[f64]) {
        self.class[i] = self.intern(values);
    }

    /// The values of set c.
    #[inline(always)]
    pub fn values(&self, c: u32) -> &[f64] {
        &self.w[self.start[c as usize] as usize..self.start[c as usize + 1] as usize]
    }

    /// The values of particle i's set (`stride(D)` per bond, in its bond order).
    #[inline(always)]
    pub fn of(&self, i: usize) -> &[f64] {
        self.values(self.class[i])
    }

    /// The values of particle i's set, None if it has none (or there are no sets).
    pub fn get(&self, i: usize) -> Option<&[f64]> {
        match self.class.get(i) {
            Some(&c) if c != u32::MAX => Some(self.values(c)),
            _ => None,
        }
    }

    /// Gradient weight of bond k (in particle i's order) (1/m).
    #[inline(always)]
    pub fn g(w: &[f64], k: usize) -> Vect<D> {
        let s = stride(D);
        let w = &w[k * s..k * s + D];
        Vect::<D>::from_fn(|a, _| w[a])
    }

    /// Hessian weight of bond k (symmetric, 1/m^2).
    #[inline(always)]
    pub fn h(w: &[f64], k: usize) -> Mat<D> {
        let s = stride(D);
        let w = &w[k * s + D..(k + 1) * s];
        let mut m = Mat::<D>::zeros();
        let mut o = 0;
        for a in 0..D {
            for c in a..D {
                m[(a, c)] = w[o];
                m[(c, a)] = w[o];
                o += 1;
            }
        }
        m
    }

    /// Number of distinct sets.
    pub fn classes(&self) -> usize {
        self.start.len() - 1
    }

    /// Bytes held (values, offsets, classes, index).
    pub fn bytes(&self) -> usize {
        8 * self.w.capacity()
            + 4 * (self.start.capacity() + self.class.capacity())
            + self.index.capacity() * 48
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_sets_share_one_class_and_unpack_bit_for_bit() {
        let g = [
            Vect::<3>::new(1.0, -2.0, 0.5),
            Vect::<3>::new(0.25, 0.0, -0.0),
        ];
        let mut h0 = Mat::<3>::zeros();
        h0[(0, 1)] = 3.0;
        h0[(1, 0)] = 3.0;
        h0[(2, 2)] = -1.5;
        let h = [h0, Mat::<3>::identity()];
        let mut s = Stencils::<3>::with_particles(3);
        let mut buf = Vec::new();
        Stencils::<3>::pack(&g, &h, &mut buf);
        assert_eq!(buf.len(), 2 * stride(3));
        s.set(0, &buf);
        s.set(2, &buf);
        // -0.0 and 0.0 are different bits: a different set (the second bond's g_z is -0.0).
        let mut other = buf.clone();
        assert_eq!(other[stride(3) + 2].to_bits(), (-0.0f64).to_bits());
        other[stride(3) + 2] = 0.0;
        s.set(1, &other);
        assert_eq!(s.classes(), 2);
        assert_eq!(s.class, vec![0, 1, 0]);
        let w = s.of(2);
        for k in 0..2 {
            assert_eq!(Stencils::<3>::g(w, k), g[k]);
            assert_eq!(Stencils::<3>::h(w, k), h[k]);
        }
    }
}
