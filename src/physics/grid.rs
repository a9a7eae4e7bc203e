//! A uniform cell grid over points: O(N) neighbour search within a radius (bond search in the
//! reference configuration, contact search among surface particles).
use super::dim::Vect;
use rustc_hash::FxHashMap;

/// `x.round()` (to the nearest integer, halves away from zero) without a call into the math
/// library: the baseline x86-64 build has no rounding instruction (SSE4.1), and the set-up's
/// lattice keys round a few values per bond (a 10^6-particle body: about 10^9 calls). The same
/// bits as `round` for every input: |x| < 2^52 through the exact truncation and fraction,
/// beyond that (already an integer), infinities and NaN as given.
#[inline(always)]
pub fn round(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64 as f64;
        let f = x - t;
        let r = if f >= 0.5 {
            t + 1.0
        } else if f <= -0.5 {
            t - 1.0
        } else {
            t
        };
        r.copysign(x)
    } else {
        x
    }
}

/// Points binned into cubic cells of side `cell`; cells are hashed so unbounded domains work.
pub struct CellGrid<const D: usize> {
    cell: f64,
    cells: FxHashMap<[i64; D], Vec<u32>>,
}

impl<const D: usize> CellGrid<D> {
    /// Bins the points `pts[i]` for `i` in `ids` (all points when `ids` is None).
    pub fn build(pts: &[Vect<D>], ids: Option<&[u32]>, cell: f64) -> Self {
        let mut cells: FxHashMap<[i64; D], Vec<u32>> = FxHashMap::default();
        let mut push = |i: u32| {
            cells
                .entry(Self::key_of(&pts[i as usize], cell))
                .or_default()
                .push(i);
        };
        match ids {
            Some(ids) => ids.iter().for_each(|&i| push(i)),
            None => (0..pts.len() as u32).for_each(&mut push),
        }
        CellGrid { cell, cells }
    }

    fn key_of(p: &Vect<D>, cell: f64) -> [i64; D] {
        let mut k = [0i64; D];
        for (d, kd) in k.iter_mut().enumerate() {
            *kd = (p[d] / cell).floor() as i64;
        }
        k
    }

    /// Calls `f(j)` for every binned point j with |pts[j] - p| <= radius (radius <= cell size).
    pub fn for_each_near(&self, pts: &[Vect<D>], p: &Vect<D>, radius: f64, mut f: impl FnMut(u32)) {
        debug_assert!(radius <= self.cell * (1.0 + 1e-12));
        let base = Self::key_of(p, self.cell);
        let r2 = radius * radius;
        let n = 3usize.pow(D as u32);
        'cells: for code in 0..n {
            let mut key = base;
            let mut c = code;
            for kd in key.iter_mut() {
                // A point far outside any sane domain (|x| / cell beyond i64, e.g. a corrupted
                // state) sits in the edge cell, which has no neighbour beyond it.
                match kd.checked_add((c % 3) as i64 - 1) {
                    Some(k) => *kd = k,
                    None => continue 'cells,
                }
                c /= 3;
            }
            if let Some(list) = self.cells.get(&key) {
                for &j in list {
                    if (pts[j as usize] - p).norm_squared() <= r2 {
                        f(j);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_gives_the_bits_of_the_math_library() {
        // Halves, the values next to them, signed zeros, both sides of 2^52, huge values,
        // infinities, NaN and a sweep of ordinary values: bit for bit what f64::round gives.
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            4503599627370495.5,
            -4503599627370495.5,
            4503599627370496.0,
            4503599627370497.0,
            9007199254740993.0,
            1e300,
            -1e300,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e-320,
            -1e-320,
        ];
        for k in -2000..2000 {
            let x = k as f64 * 0.25 + k as f64 * 1e-17;
            xs.extend([x, f64::from_bits(x.to_bits() + 1), x * 1.07e9, -x * 3.3]);
        }
        for x in xs {
            let (ours, theirs) = (round(x), x.round());
            assert!(
                ours.to_bits() == theirs.to_bits() || (ours.is_nan() && theirs.is_nan()),
                "{x:e}: {ours:e} against {theirs:e}"
            );
        }
    }

    #[test]
    fn points_beyond_the_key_range_do_not_overflow() {
        // Found by the fmu_state fuzz target: a state with a displacement of ~1e300 m put a
        // particle in cell i64::MAX, and the neighbour-cell offset overflowed (a panic with
        // overflow checks, wrong cells without).
        let pts = vec![
            Vect::<2>::new(1e300, -1e300),
            Vect::<2>::new(1e300, -1e300),
            Vect::<2>::new(0.0, 0.0),
        ];
        let g = CellGrid::build(&pts, None, 0.1);
        let mut near = vec![];
        g.for_each_near(&pts, &pts[0], 0.1, |j| near.push(j));
        near.sort();
        assert_eq!(near, vec![0, 1]);
    }
}
