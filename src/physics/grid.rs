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

/// Points binned into cubic cells of side `cell`, kept as compressed rows (cell c's points at
/// `items[start[c]..start[c + 1]]`, in the order given). The cells of the points' bounding box
/// are indexed directly when the box has at most a few cells per point (every body the
/// solver builds); otherwise (points spread far apart, e.g. a corrupted state) the occupied
/// cells are hashed, so unbounded domains work. Against a hashed list per cell: no allocation
/// per cell and no hashing per lookup (the contact search's grid and its hash lookups were 7 %
/// of case 3).
pub struct CellGrid<const D: usize> {
    cell: f64,
    start: Vec<u32>,
    items: Vec<u32>,
    index: CellIndex<D>,
}

/// Where a cell's row is: directly in the bounding box of the cells (`lo`, `dims` per axis,
/// cell index sum_a (k_a - lo_a) stride_a with axis 0 fastest), or hashed.
enum CellIndex<const D: usize> {
    Dense { lo: [i64; D], dims: [i64; D] },
    Hashed(FxHashMap<[i64; D], u32>),
}

/// Most cells per point of a directly indexed grid (and a floor for a few points).
const DENSE_CELLS_PER_POINT: u64 = 8;
const DENSE_CELLS_MIN: u64 = 4096;

impl<const D: usize> CellGrid<D> {
    /// Bins the points `pts[i]` for `i` in `ids` (all points when `ids` is None).
    pub fn build(pts: &[Vect<D>], ids: Option<&[u32]>, cell: f64) -> Self {
        let order: Vec<u32> = match ids {
            Some(ids) => ids.to_vec(),
            None => (0..pts.len() as u32).collect(),
        };
        let keys: Vec<[i64; D]> = order
            .iter()
            .map(|&i| Self::key_of(&pts[i as usize], cell))
            .collect();
        let mut lo = [i64::MAX; D];
        let mut hi = [i64::MIN; D];
        for k in &keys {
            for a in 0..D {
                lo[a] = lo[a].min(k[a]);
                hi[a] = hi[a].max(k[a]);
            }
        }
        // The bounding box's cells, if few enough to index directly (None on overflow).
        let limit = (keys.len() as u64)
            .saturating_mul(DENSE_CELLS_PER_POINT)
            .max(DENSE_CELLS_MIN);
        let mut dims = [0i64; D];
        let mut total: Option<u64> = (!keys.is_empty()).then_some(1);
        for a in 0..D {
            let span = hi[a].checked_sub(lo[a]).and_then(|s| s.checked_add(1));
            total = match (total, span) {
                (Some(t), Some(s)) => t
                    .checked_mul(s as u64)
                    .filter(|&t| t <= limit && t < u32::MAX as u64),
                _ => None,
            };
            dims[a] = span.unwrap_or(0);
        }
        let (index, cell_of): (CellIndex<D>, Vec<u32>) = match total {
            Some(_) => {
                let idx = CellIndex::Dense { lo, dims };
                let cell_of = keys
                    .iter()
                    .map(|k| idx.find(k).expect("inside the bounding box"))
                    .collect();
                (idx, cell_of)
            }
            None => {
                let mut map: FxHashMap<[i64; D], u32> = FxHashMap::default();
                let cell_of = keys
                    .iter()
                    .map(|k| {
                        let next = map.len() as u32;
                        *map.entry(*k).or_insert(next)
                    })
                    .collect();
                (CellIndex::Hashed(map), cell_of)
            }
        };
        let cells = match &index {
            CellIndex::Dense { .. } => total.unwrap_or(0) as usize,
            CellIndex::Hashed(map) => map.len(),
        };
        let (start, items) = rows_by_cell(&cell_of, cells, &order);
        CellGrid {
            cell,
            start,
            items,
            index,
        }
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
            if let Some(c) = self.index.find(&key) {
                let row = &self.items
                    [self.start[c as usize] as usize..self.start[c as usize + 1] as usize];
                for &j in row {
                    if (pts[j as usize] - p).norm_squared() <= r2 {
                        f(j);
                    }
                }
            }
        }
    }
}

/// Compressed rows of `items` by their cells (`cell_of[k]` is the cell of `items[k]`, below
/// `cells`): cell c's at `rows[start[c]..start[c + 1]]`, in the order given (a stable counting
/// sort). Returns (start, rows).
pub(crate) fn rows_by_cell(cell_of: &[u32], cells: usize, items: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; cells + 1];
    for &c in cell_of {
        start[c as usize + 1] += 1;
    }
    for c in 0..cells {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut rows = vec![0u32; items.len()];
    for (&i, &c) in items.iter().zip(cell_of) {
        rows[fill[c as usize] as usize] = i;
        fill[c as usize] += 1;
    }
    (start, rows)
}

impl<const D: usize> CellIndex<D> {
    /// The cell of key k, if it has a row.
    #[inline(always)]
    fn find(&self, k: &[i64; D]) -> Option<u32> {
        match self {
            CellIndex::Dense { lo, dims } => {
                let mut at = 0i64;
                let mut stride = 1i64;
                for a in 0..D {
                    let off = k[a].checked_sub(lo[a])?;
                    if off < 0 || off >= dims[a] {
                        return None;
                    }
                    at += off * stride;
                    stride *= dims[a];
                }
                Some(at as u32)
            }
            CellIndex::Hashed(map) => map.get(k).copied(),
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
    fn direct_and_hashed_cells_find_the_same_points_in_the_same_order() {
        // A cloud in a box (its cells indexed directly), then the same cloud with a point far
        // away (the box would have 10^15 cells: hashed). Both find, for every point, exactly
        // the points within the radius (against all pairs), in the same order.
        let mut z = 12345u64;
        let mut rnd = || {
            z = z
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (z >> 11) as f64 / (1u64 << 53) as f64
        };
        let cloud: Vec<Vect<3>> = (0..600)
            .map(|_| Vect::<3>::new(rnd(), 0.5 * rnd(), 2.0 * rnd() - 1.0))
            .collect();
        let mut far = cloud.clone();
        far.push(Vect::<3>::new(1e5, -1e5, 1e5));
        let r = 0.11;
        let direct = CellGrid::build(&cloud, None, r);
        let hashed = CellGrid::build(&far, None, r);
        assert!(matches!(direct.index, CellIndex::Dense { .. }));
        assert!(matches!(hashed.index, CellIndex::Hashed(_)));
        for (i, p) in cloud.iter().enumerate() {
            let (mut a, mut b) = (vec![], vec![]);
            direct.for_each_near(&cloud, p, r, |j| a.push(j));
            hashed.for_each_near(&far, p, r, |j| b.push(j));
            assert_eq!(a, b, "point {i}");
            let mut want: Vec<u32> = (0..cloud.len() as u32)
                .filter(|&j| (cloud[j as usize] - p).norm_squared() <= r * r)
                .collect();
            a.sort();
            want.sort();
            assert_eq!(a, want, "point {i}");
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
