//! Interned per-particle weight sets ("stencil classes") of the second-order operator (issue
//! 25): the fit weights (g_b, h_b) of a particle, in its bond order, are stored once per
//! distinct set, and each particle holds the index of its set; so are the geometry of its bonds
//! (snapped reference vectors, whether each enters the fits), in sets of their own. On a lattice every interior
//! particle has the same neighbour pattern and so bitwise the same weights (translation
//! invariance of the fit, with the reference vectors quantised): a body of N particles has a
//! few hundred sets instead of N, the force loop reads its weights from the cache instead of
//! 96 bytes per bond from memory, and the memory per particle drops accordingly. Sets are
//! compared bit for bit, so interning changes no result.
use rustc_hash::FxHashMap;

use super::dim::{Dim, Mat, Space, Vect};

/// Bonds per group of the force loop (one AVX2 register of doubles).
pub const LANES: usize = 4;

/// `nb` bonds rounded up to whole groups.
pub const fn padded(nb: usize) -> usize {
    nb.div_ceil(LANES) * LANES
}

/// Fit weights per bond: the gradient weight g (D values, 1/m), then the upper triangle of the
/// symmetric Hessian weight h, row by row (D (D + 1) / 2 values, 1/m^2).
pub const fn stride(d: usize) -> usize {
    d + d * (d + 1) / 2
}

/// Values per bond of a geometry set: the bond's reference vector as the fits see it (snapped
/// to 1e-9 l0, D values, m), 1 / its length (1/m), and 1 if the bond enters the fits and
/// residuals of its particle (0 for a bond to a wall particle behind a clamped face). Kept
/// apart from the weights, which the closure and fracture make differ between particles of
/// the same neighbourhood: a body has as many geometry sets as kinds of neighbourhood.
pub const fn geometry_rows(d: usize) -> usize {
    d + 2
}

/// Row of the reference vectors' first component in a geometry set.
pub const R0_ROW: usize = 0;

/// Row of 1 / |r0| in a geometry set.
pub const fn inv_len_row(d: usize) -> usize {
    d
}

/// Row of the fits' 0/1 flags in a geometry set.
pub const fn keep_row(d: usize) -> usize {
    d + 1
}

/// Sets store their values by group of [`LANES`] bonds and in a group by value (value j of bond
/// k at `(k / LANES) * rows * LANES + j * LANES + k % LANES`, `rows` values per bond, the bond
/// count padded to whole groups: zero weights, a unit reference vector along the first axis),
/// so that the force loop reads each value of a group as one vector and a group's values in
/// one stretch.
#[inline(always)]
pub const fn at(rows: usize, j: usize, k: usize) -> usize {
    (k / LANES) * rows * LANES + j * LANES + k % LANES
}

/// The weight sets and the set of each particle (serde: a closure shipped in an FMU,
/// `world::SetupMemo`).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Stencils<const D: usize> {
    /// Set of each particle.
    pub class: Vec<u32>,
    /// Start of each set in `w` (in values); one more entry than sets.
    start: Vec<u32>,
    /// The sets' values, `stride(D)` per bond, by value (see [`stride`]).
    w: Vec<f64>,
    /// Hash of a set's bits -> the sets with that hash.
    index: FxHashMap<u64, Vec<u32>>,
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
            index: FxHashMap::default(),
        }
    }

    /// Packs the fit weights of one particle (in its bond order) into `out` ([`at`], [`stride`]
    /// rows).
    pub fn pack(g: &[Vect<D>], h: &[Mat<D>], out: &mut Vec<f64>) {
        out.clear();
        out.resize(padded(g.len()) * stride(D), 0.0);
        for (k, (g, h)) in g.iter().zip(h).enumerate() {
            for a in 0..D {
                out[at(stride(D), a, k)] = g[a];
            }
            let mut j = D;
            for a in 0..D {
                for c in a..D {
                    out[at(stride(D), j, k)] = h[(a, c)];
                    j += 1;
                }
            }
        }
    }

    /// Packs the geometry of one particle's bonds (in its bond order) into `out` ([`at`],
    /// [`geometry_rows`]): the snapped reference vectors `r0` and the flags `keep`.
    pub fn pack_geometry(r0: &[Vect<D>], keep: &[bool], out: &mut Vec<f64>) {
        let rows = geometry_rows(D);
        out.clear();
        out.resize(padded(r0.len()) * rows, 0.0);
        for k in 0..padded(r0.len()) {
            let Some(r) = r0.get(k) else {
                out[at(rows, R0_ROW, k)] = 1.0;
                out[at(rows, inv_len_row(D), k)] = 1.0;
                continue;
            };
            for a in 0..D {
                out[at(rows, R0_ROW + a, k)] = r[a];
            }
            out[at(rows, inv_len_row(D), k)] = 1.0 / r.norm();
            out[at(rows, keep_row(D), k)] = if keep[k] { 1.0 } else { 0.0 };
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

    /// The values of particle i's set (by groups of bonds: [`at`]).
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

    /// Gradient weight of bond k (in particle i's order) of a weight set (1/m).
    #[inline(always)]
    pub fn g(w: &[f64], k: usize) -> Vect<D> {
        Vect::<D>::from_fn(|a, _| w[at(stride(D), a, k)])
    }

    /// Hessian weight of bond k of a weight set (symmetric, 1/m^2).
    #[inline(always)]
    pub fn h(w: &[f64], k: usize) -> Mat<D> {
        let mut m = Mat::<D>::zeros();
        let mut o = D;
        for a in 0..D {
            for c in a..D {
                m[(a, c)] = w[at(stride(D), o, k)];
                m[(c, a)] = m[(a, c)];
                o += 1;
            }
        }
        m
    }

    /// Reference vector of bond k of a geometry set as the fits see it (snapped, m) and 1 / its
    /// length (1/m).
    #[inline(always)]
    pub fn r0(w: &[f64], k: usize) -> (Vect<D>, f64) {
        let rows = geometry_rows(D);
        (
            Vect::<D>::from_fn(|a, _| w[at(rows, R0_ROW + a, k)]),
            w[at(rows, inv_len_row(D), k)],
        )
    }

    /// Number of distinct sets.
    pub fn classes(&self) -> usize {
        self.start.len() - 1
    }

    /// Whether the sets are consistent (offsets from 0, increasing, ending at the values' end;
    /// every particle's set one of them or none): what a set-up checks of sets read from a
    /// file before it indexes them.
    pub fn well_formed(&self) -> bool {
        self.start.first() == Some(&0)
            && self.start.windows(2).all(|s| s[0] <= s[1])
            && self.start.last().map(|&e| e as usize) == Some(self.w.len())
            && self
                .class
                .iter()
                .all(|&c| c == u32::MAX || (c as usize) < self.classes())
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
        assert_eq!(buf.len(), LANES * stride(3));
        s.set(0, &buf);
        s.set(2, &buf);
        // -0.0 and 0.0 are different bits: a different set (the second bond's g_z is -0.0).
        let mut other = buf.clone();
        assert_eq!(other[2 * LANES + 1].to_bits(), (-0.0f64).to_bits());
        other[2 * LANES + 1] = 0.0;
        s.set(1, &other);
        assert_eq!(s.classes(), 2);
        assert_eq!(s.class, vec![0, 1, 0]);
        let w = s.of(2);
        for k in 0..2 {
            assert_eq!(Stencils::<3>::g(w, k), g[k]);
            assert_eq!(Stencils::<3>::h(w, k), h[k]);
        }
        // The padding: no weight.
        assert_eq!(Stencils::<3>::g(w, 2), Vect::<3>::zeros());
        // A geometry set, its padding a unit vector along x, not in the fits.
        let r0 = [
            Vect::<3>::new(0.0, 3.0, 4.0),
            Vect::<3>::new(-1.0, 0.0, 0.0),
        ];
        Stencils::<3>::pack_geometry(&r0, &[true, false], &mut buf);
        assert_eq!(buf.len(), LANES * geometry_rows(3));
        assert_eq!(Stencils::<3>::r0(&buf, 0), (r0[0], 0.2));
        assert_eq!(Stencils::<3>::r0(&buf, 1), (r0[1], 1.0));
        assert_eq!(Stencils::<3>::r0(&buf, LANES - 1), (Vect::<3>::x(), 1.0));
        let keep = |k: usize| buf[at(geometry_rows(3), keep_row(3), k)];
        assert_eq!((keep(0), keep(1), keep(2)), (1.0, 0.0, 0.0));
    }
}
