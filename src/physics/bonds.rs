//! Reference-configuration bonds: for each particle its neighbours within re (same body), with
//! the reference vector r0_ij and the weight w(|r0_ij|) of Eq. (8), stored per particle (CSR).
use super::dim::Vect;
use super::grid::CellGrid;

/// Whether two particles of one body at reference distance `r` are bonded: the one
/// neighbourhood rule (weight > 0, i.e. 0 < r < re). A pair at exactly re (or coinciding) has
/// zero weight and is no bond, since a zero weight marks a broken bond; |r0| = re to round-off
/// would otherwise make the bond count, and so the surface flags, depend on where the body sits.
#[inline]
pub fn is_bond(r: f64, re: f64) -> bool {
    weight(r, re) > 0.0
}

/// Weight function, Eq. (8).
#[inline]
pub fn weight(r: f64, re: f64) -> f64 {
    if r <= re && r > 0.0 {
        re / r - 1.0
    } else {
        0.0
    }
}

/// Bonds in compressed-row form: the bonds of particle i are `start[i]..start[i+1]`.
/// Every bond is stored twice (i->j and j->i), so the gather loops need no scatter.
#[derive(Clone, Debug, Default)]
pub struct Bonds<const D: usize> {
    pub start: Vec<u32>,
    /// Neighbour index j.
    pub nbr: Vec<u32>,
    /// Reference vector r0_ij = X_j - X_i (m).
    pub r0: Vec<Vect<D>>,
    /// Reference weight w(|r0_ij|), Eq. (8); set to 0 when the bond breaks, Eq. (42).
    pub w0: Vec<f64>,
}

impl<const D: usize> Bonds<D> {
    /// Finds all pairs of the same body within `re` (positive weight) with a cell grid (O(N)).
    /// Symmetric: r0_ji = -r0_ij exactly and the weights of both directions are equal.
    pub fn build(x0: &[Vect<D>], body: &[u32], re: f64) -> Self {
        let mut b = Bonds::<D> {
            start: Vec::with_capacity(x0.len() + 1),
            ..Default::default()
        };
        b.fill(x0, body, re);
        b
    }

    /// As `build`, with the arrays reserved fallibly for `per_particle` bonds per particle
    /// first (more grow the arrays as usual): running out of memory is an error, not an abort.
    pub fn try_build(
        x0: &[Vect<D>],
        body: &[u32],
        re: f64,
        per_particle: usize,
    ) -> Result<Self, std::collections::TryReserveError> {
        let cap = x0.len().saturating_mul(per_particle);
        let mut b = Bonds::<D>::default();
        b.start.try_reserve_exact(x0.len() + 1)?;
        b.nbr.try_reserve_exact(cap)?;
        b.r0.try_reserve_exact(cap)?;
        b.w0.try_reserve_exact(cap)?;
        b.fill(x0, body, re);
        Ok(b)
    }

    fn fill(&mut self, x0: &[Vect<D>], body: &[u32], re: f64) {
        let grid = CellGrid::build(x0, None, re);
        let b = self;
        b.start.push(0);
        let mut near = Vec::new();
        for i in 0..x0.len() {
            near.clear();
            grid.for_each_near(x0, &x0[i], re, |j| {
                if j as usize != i && body[j as usize] == body[i] {
                    near.push(j)
                }
            });
            near.sort_unstable();
            for &j in &near {
                let r0 = x0[j as usize] - x0[i];
                let r = r0.norm();
                if is_bond(r, re) {
                    b.nbr.push(j);
                    b.w0.push(weight(r, re));
                    b.r0.push(r0);
                }
            }
            b.start.push(b.nbr.len() as u32);
        }
    }

    /// Range of bond indices of particle i.
    #[inline(always)]
    pub fn of(&self, i: usize) -> std::ops::Range<usize> {
        self.start[i] as usize..self.start[i + 1] as usize
    }

    /// Number of stored (directed) bonds.
    pub fn len(&self) -> usize {
        self.nbr.len()
    }
    pub fn is_empty(&self) -> bool {
        self.nbr.is_empty()
    }
}

/// Distances of the points of the square/cubic lattice of spacing l0 (in `dimension` = 2 or 3
/// dimensions) that a particle at the origin is bonded to ([`is_bond`]): the one enumeration
/// behind the full-neighbourhood counts of the bond builder, the number density n0, the memory
/// estimate and the resolution warnings.
pub fn lattice_distances(dimension: usize, l0: f64, re: f64) -> Vec<f64> {
    let m = (re / l0).ceil() as i64;
    let side = (2 * m + 1) as usize;
    (0..side.pow(dimension as u32))
        .filter_map(|code| {
            let mut c = code;
            let mut r2 = 0.0;
            for _ in 0..dimension {
                let k = (c % side) as i64 - m;
                c /= side;
                r2 += (k as f64 * l0).powi(2);
            }
            let r = r2.sqrt();
            is_bond(r, re).then_some(r)
        })
        .collect()
}

/// The bonds of a particle with a full neighbourhood on the lattice of spacing l0: the lattice
/// points other than itself within re (12 in 2D and 32 in 3D for re = 2.1 l0).
pub fn lattice_neighbours<const D: usize>(l0: f64, re: f64) -> usize {
    lattice_distances(D, l0, re).len()
}

/// At most the bonds of a particle on the lattice of spacing l0 (for reservations and the memory
/// estimate): [`lattice_neighbours`] plus the lattice points at exactly re, since such a pair's
/// distance is re only to round-off and one a few ulps short of re is bonded.
pub fn max_lattice_neighbours(dimension: usize, l0: f64, re: f64) -> usize {
    lattice_distances(dimension, l0, re * (1.0 + 1e-9)).len()
}

/// The number density n0 of a particle with a full neighbourhood on the square/cubic lattice of
/// spacing l0, Eq. (12).
pub fn lattice_number_density<const D: usize>(l0: f64, re: f64) -> f64 {
    lattice_distances(D, l0, re)
        .into_iter()
        .map(|r| weight(r, re))
        .sum()
}
