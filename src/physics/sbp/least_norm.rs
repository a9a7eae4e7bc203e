//! The least-norm weight corrections of the summation-by-parts closure (module `sbp`): the
//! constraints on them, solved matrix-free by conjugate gradients that a caller can stop.
use super::{monomials, quad_len};
use crate::par_iter_mut;
use crate::physics::bonds::Bonds;
use crate::physics::dim::{Dim, Space, Vect};
#[allow(unused_imports)]
use crate::physics::par::*;
use crate::physics::second_order;

/// Relative residual at which the conjugate gradients stop.
const TOLERANCE: f64 = 1e-9;

/// Total degree of the constant field's coarse polynomials (the linear fields': one less).
/// On a clamped 15^3 cube (axes 5,392 / 1,401 / 1,399 iterations without): degree 6
/// 1,630 / 769 / 772 (closure 7.7 -> 4.0 s), 8: 904 / 536 / 536 (4.4 s, its coarse
/// operator costs 525 operator products to build).
const COARSE_DEGREE: usize = 6;

/// Most conjugate-gradient iterations per axis.
pub(super) const MAX_ITERATIONS: usize = 20000;

/// The constraints on the corrections c_b (one per directed bond, for one axis): each row's
/// corrections orthogonal to the quadratic monomials of its bonds (the fit stays exact), and
/// each column's sums against the linear fields, in local coordinates phi_0 = 1,
/// phi_a = (x_a - x_k,a) / l0, equal to a target. The least-norm solution is c = P A^T y with
/// (A P A^T) y = t, solved by conjugate gradients (matrix-free, per row and per column in
/// parallel) preconditioned by the inverses of its diagonal blocks plus, on a box solved
/// whole (no tied rows), a coarse correction on its smooth polynomial fields
/// (`build_coarse`).
pub(super) struct NullSpaceConstraints<'a, const D: usize> {
    bonds: &'a Bonds<D>,
    mirror: Vec<u32>,
    /// Each row's stencil: rows whose bonds have the same lattice offsets in the same order
    /// share one (on a 15^3 box 343 stencils for 3,375 rows), so that what the solve reads per
    /// iteration besides the bonds' indices is a few hundred kB and stays in cache (per row,
    /// 10 MB: the whole box's solve took 1.3 times as long).
    stencil: Vec<u32>,
    /// Where each stencil's bonds start in `mono` (in bonds).
    stencil_start: Vec<usize>,
    /// Monomials of every stencil bond's r0 / l0 (quad_len(D) per bond).
    mono: Vec<f64>,
    /// Inverse Gram matrix of each stencil's monomials, column-major (quad_len(D)^2 per
    /// stencil, as nalgebra stores it): contiguous, so that the projection's loops have
    /// constant trip counts and no bounds checks (it is most of a closure's set-up).
    gram_inv: Vec<f64>,
    l0: f64,
    nq: usize,
    /// Diagonal of A P A^T.
    diag: Vec<f64>,
    /// Inverses of A P A^T's diagonal blocks, the preconditioner (nq x nq per column,
    /// row-major; a singular block takes the inverse of its diagonal). Against the diagonal
    /// alone: 8-11 % fewer iterations on a free 30^3 cube's axes, 23 % on a clamped 15^3 cube.
    block_inv: Vec<f64>,
    /// Rows of each class.
    members: Vec<Vec<u32>>,
    /// The corrections are kept once per class (the rows of a class share them): class g's
    /// at `class_start[g]..class_start[g + 1]`, bond b's at `cpos[b]`.
    class_start: Vec<usize>,
    cpos: Vec<u32>,
    /// Each row's class.
    class: Vec<u32>,
    /// Where the incoming bond's correction is kept: `cpos[mirror[b]]`.
    cpos_in: Vec<u32>,
    /// Every stencil bond's r0 / l0 (D per bond), the monomials' linear part, for the loops
    /// that read only it.
    lin: Vec<f64>,
    /// Coarse space of the two-level preconditioner (`build_coarse`): each column's flat
    /// index in the box, the box's dimensions, the Legendre tables per axis, the degrees per
    /// axis plus one, the fields (component, flat exponent index) and the pseudo-inverse of
    /// their Galerkin operator (empty: no coarse space).
    coarse_grid: Vec<usize>,
    coarse_dims: Vec<usize>,
    coarse_leg: Vec<Vec<f64>>,
    /// Their transposes (dims[a] x degrees), the prolongation's tables.
    coarse_leg_t: Vec<Vec<f64>>,
    coarse_ne: usize,
    coarse_fields: Vec<(usize, usize)>,
    coarse_inv: Vec<f64>,
}

impl<'a, const D: usize> NullSpaceConstraints<'a, D>
where
    Space: Dim<D>,
{
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        bonds: &'a Bonds<D>,
        gram_inv: Vec<nalgebra::DMatrix<f64>>,
        l0: f64,
        nq: usize,
        tie: Vec<u32>,
        positions: &[Vect<D>],
        clamped_axis: bool,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Self {
        let m = quad_len(D);
        // Rows with the same lattice offsets (r0 / l0 within 1e-9 of integers, in the same
        // order) share a stencil: its monomials and the inverse Gram matrix of its first row.
        // A row off the lattice has its own.
        let n = bonds.start.len() - 1;
        let mut stencil = Vec::with_capacity(n);
        let mut stencil_start = vec![0usize];
        let mut firsts: Vec<usize> = Vec::new();
        {
            let mut known: std::collections::HashMap<Vec<i64>, u32> = Default::default();
            let mut key = Vec::new();
            for i in 0..n {
                key.clear();
                let mut on_lattice = true;
                for b in bonds.of(i) {
                    for a in 0..D {
                        let x = bonds.r0[b][a] / l0;
                        on_lattice &= (x - x.round()).abs() <= 1e-9;
                        key.push(x.round() as i64);
                    }
                }
                if !on_lattice {
                    key.push(i64::MIN + i as i64);
                }
                let next = firsts.len() as u32;
                let s = *known.entry(key.clone()).or_insert(next);
                if s == next {
                    firsts.push(i);
                    stencil_start.push(stencil_start[s as usize] + bonds.of(i).len());
                }
                stencil.push(s);
            }
        }
        let mut gram_flat = Vec::with_capacity(firsts.len() * m * m);
        for &i in &firsts {
            gram_flat.extend_from_slice(gram_inv[i].as_slice());
        }
        drop(gram_inv);
        let mut mono = Vec::with_capacity(stencil_start[firsts.len()] * m);
        let mut lin = Vec::with_capacity(stencil_start[firsts.len()] * D);
        let mut tmp = Vec::with_capacity(m);
        for &i in &firsts {
            for b in bonds.of(i) {
                let r = bonds.r0[b] / l0;
                monomials::<D>(&r, &mut tmp);
                mono.extend_from_slice(&tmp);
                lin.extend(r.iter());
            }
        }
        let mut sys = NullSpaceConstraints {
            bonds,
            mirror: second_order::mirror_index(bonds),
            stencil,
            stencil_start,
            mono,
            gram_inv: gram_flat,
            l0,
            nq,
            diag: vec![0.0; n * nq],
            block_inv: Vec::new(),
            members: {
                let nc = tie.iter().map(|&t| t as usize + 1).max().unwrap_or(0);
                let mut m = vec![Vec::new(); nc];
                for (i, &t) in tie.iter().enumerate() {
                    m[t as usize].push(i as u32);
                }
                m
            },
            class_start: Vec::new(),
            cpos: Vec::new(),
            class: tie.clone(),
            cpos_in: Vec::new(),
            lin,
            coarse_grid: Vec::new(),
            coarse_dims: Vec::new(),
            coarse_leg: Vec::new(),
            coarse_leg_t: Vec::new(),
            coarse_ne: 0,
            coarse_fields: Vec::new(),
            coarse_inv: Vec::new(),
        };
        let mut class_start = vec![0usize];
        let mut cpos = vec![0u32; bonds.len()];
        for members in &sys.members {
            let at = *class_start.last().unwrap_or(&0);
            let len = members.first().map_or(0, |&i| bonds.of(i as usize).len());
            for &i in members {
                debug_assert_eq!(bonds.of(i as usize).len(), len, "a class's rows alike");
                for (k, b) in bonds.of(i as usize).enumerate() {
                    cpos[b] = (at + k) as u32;
                }
            }
            class_start.push(at + len);
        }
        sys.cpos_in = sys.mirror.iter().map(|&b| cpos[b as usize]).collect();
        sys.class_start = class_start;
        sys.cpos = cpos;
        // diag = |P A^T e_(k,a)|^2: the incoming bonds of k lie in other rows (one entry each:
        // |P e_b|^2 = 1 - mono_b^T Ginv mono_b), the constant field also has -1 on all of row
        // k's own bonds. The diagonal block of column k: the same sums of keep_b phi_q phi_q'
        // (an incoming bond's entries of the fields are multiples of one unit vector; the own
        // row's -1s lie in another row than every incoming bond). The ties are left out: a
        // preconditioner need not be exact.
        let keep = |b: usize, i: usize| -> f64 {
            let (mb, g) = sys.row_data(i);
            let k = b - bonds.start[i] as usize;
            let mb = &mb[k * m..(k + 1) * m];
            let mut s = 0.0;
            for r in 0..m {
                for c in 0..m {
                    s += mb[r] * g[c * m + r] * mb[c];
                }
            }
            1.0 - s
        };
        let mut diag = vec![0.0; n * nq];
        let mut block_inv = Vec::new();
        for k in 0..n {
            let mut blk = nalgebra::DMatrix::<f64>::zeros(nq, nq);
            for b in bonds.of(k) {
                let back = sys.mirror[b] as usize; // j -> k, in row j
                let j = bonds.nbr[b] as usize;
                let kb = keep(back, j);
                let r = bonds.r0[b] / l0; // x_j - x_k
                diag[k * nq] += kb;
                for a in 0..D {
                    diag[k * nq + 1 + a] += kb * r[a] * r[a];
                }
                let phi = |q: usize| if q == 0 { 1.0 } else { r[q - 1] };
                for q in 0..nq {
                    for q2 in 0..nq {
                        blk[(q, q2)] += kb * phi(q) * phi(q2);
                    }
                }
            }
            let mut ones = vec![-1.0; bonds.of(k).len()];
            sys.project_row(k, &mut ones);
            let own = ones.iter().map(|v| v * v).sum::<f64>();
            diag[k * nq] += own;
            blk[(0, 0)] += own;
            {
                match blk.try_inverse() {
                    Some(inv) => {
                        for q in 0..nq {
                            for q2 in 0..nq {
                                block_inv.push(inv[(q, q2)]);
                            }
                        }
                    }
                    None => {
                        for q in 0..nq {
                            for q2 in 0..nq {
                                let d = diag[k * nq + q];
                                block_inv.push(if q == q2 && d > 0.0 { 1.0 / d } else { 0.0 });
                            }
                        }
                    }
                }
            }
        }
        sys.diag = diag;
        sys.block_inv = block_inv;
        // On a reduced box (rows tied along a long axis) the polynomial fields of the box are
        // not the slow modes of the tied system, except along a clamped face's normal: there
        // they cut the iterations of a clamped 30^3 cube's axis 11,743 -> 7,525, on the free
        // axes only 3,249 -> 2,836, less than the coarse correction costs (with the tied rows
        // summed; with their mean, `tie`, the clamped axis 8,369 -> 5,231). So a reduced box
        // has the coarse space when an axis of it is clamped, and uses it on that axis
        // (`solve`'s `coarse`).
        if clamped_axis || sys.members.iter().all(|m| m.len() < 2) {
            sys.build_coarse(positions, stop);
        }
        sys
    }

    /// c -= (the part of c in the span of row i's monomials): c P_i, with P_i = I - M (M^T
    /// M)^-1 M^T over its bonds.
    fn project_row(&self, i: usize, c: &mut [f64]) {
        let (mono, g) = self.row_data(i);
        project::<D>(mono, g, c);
    }

    /// Row i's monomials (quad_len(D) per bond) and inverse Gram matrix, from its stencil.
    #[inline]
    fn row_data(&self, i: usize) -> (&[f64], &[f64]) {
        let m = quad_len(D);
        let s = self.stencil[i] as usize;
        let (a, b) = (self.stencil_start[s], self.stencil_start[s + 1]);
        (
            &self.mono[a * m..b * m],
            &self.gram_inv[s * m * m..(s + 1) * m * m],
        )
    }

    /// Row i's bonds' r0 / l0 (D per bond), from its stencil.
    #[inline]
    fn row_lin(&self, i: usize) -> &[f64] {
        let s = self.stencil[i] as usize;
        &self.lin[self.stencil_start[s] * D..self.stencil_start[s + 1] * D]
    }

    /// The coarse space of the two-level preconditioner: Legendre polynomial fields over the
    /// box (the constant field's component y_0 up to total degree COARSE_DEGREE, each linear
    /// field's up to one less), the smoothest fields and so the ones the sixth-order-like
    /// operator damps most, which the block-diagonal preconditioner cannot see; their
    /// Galerkin operator pseudo-inverted (its null space: the quadratic fields). Applied by
    /// tensor contractions along the box's axes, so a coarse correction costs a few passes
    /// over the unknowns, not one per coarse field. Needs the rows on a full lattice box.
    /// A stop request ends it at once without a coarse space (the solves then stop at their
    /// first iteration).
    fn build_coarse(&mut self, positions: &[Vect<D>], stop: &(dyn Fn() -> bool + Sync)) {
        let n = positions.len();
        let nq = self.nq;
        let deg = COARSE_DEGREE;
        let mut lo = Vect::<D>::repeat(f64::INFINITY);
        for x in positions {
            for a in 0..D {
                lo[a] = lo[a].min(x[a]);
            }
        }
        let idx: Vec<[usize; D]> = positions
            .iter()
            .map(|x| std::array::from_fn(|a| ((x[a] - lo[a]) / self.l0).round() as usize))
            .collect();
        let dims: [usize; D] =
            std::array::from_fn(|a| idx.iter().map(|k| k[a]).max().unwrap_or(0) + 1);
        if dims.iter().product::<usize>() != n || dims.iter().any(|&d| d < 2) {
            return;
        }
        let flat = |k: &[usize; D]| (0..D).fold(0, |f, a| f * dims[a] + k[a]);
        let grid: Vec<usize> = idx.iter().map(flat).collect();
        // Every lattice point of the box held by exactly one column.
        let mut seen = vec![false; n];
        for &g in &grid {
            if std::mem::replace(&mut seen[g], true) {
                return;
            }
        }
        let ne = deg + 1;
        // Legendre values per axis: leg[a][e * dims[a] + i].
        let leg: Vec<Vec<f64>> = (0..D)
            .map(|a| {
                let m = dims[a];
                let mut t = vec![0.0; ne * m];
                for i in 0..m {
                    let x = 2.0 * i as f64 / (m - 1) as f64 - 1.0;
                    let (mut p0, mut p1) = (1.0, x);
                    t[i] = 1.0;
                    if ne > 1 {
                        t[m + i] = x;
                    }
                    for e in 2..ne {
                        let p2 = ((2 * e - 1) as f64 * x * p1 - (e - 1) as f64 * p0) / e as f64;
                        t[e * m + i] = p2;
                        p0 = p1;
                        p1 = p2;
                    }
                }
                t
            })
            .collect();
        // The coarse fields: (component, exponents) of total degree within the component's.
        let mut fields = Vec::new();
        for q in 0..nq {
            let d = if q == 0 { deg } else { deg - 1 };
            for f in 0..ne.pow(D as u32) {
                let e: [usize; D] = std::array::from_fn(|a| f / ne.pow((D - 1 - a) as u32) % ne);
                if e.iter().sum::<usize>() <= d {
                    fields.push((q, f));
                }
            }
        }
        self.coarse_grid = grid;
        self.coarse_dims = dims.to_vec();
        self.coarse_leg_t = (0..D)
            .map(|a| {
                let m = dims[a];
                (0..m * ne)
                    .map(|ie| leg[a][(ie % ne) * m + ie / ne])
                    .collect()
            })
            .collect();
        self.coarse_leg = leg;
        self.coarse_ne = ne;
        self.coarse_fields = fields;
        let m = self.coarse_fields.len();
        let len = n * nq;
        let mut z = vec![0.0; len];
        let mut az = vec![0.0; len];
        let mut c = vec![0.0; self.class_len()];
        let mut coef = vec![0.0; m];
        let mut e = nalgebra::DMatrix::<f64>::zeros(m, m);
        for j in 0..m {
            if stop() {
                return;
            }
            coef.iter_mut().for_each(|v| *v = 0.0);
            coef[j] = 1.0;
            z.iter_mut().for_each(|v| *v = 0.0);
            self.prolong(&coef, &mut z);
            self.at_project(&z, &mut c);
            self.apply(&c, &mut az);
            self.restrict(&az, &mut coef);
            for i in 0..m {
                e[(i, j)] = coef[i];
            }
        }
        let e = (&e + e.transpose()) * 0.5;
        let eig = nalgebra::SymmetricEigen::new(e);
        let top = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
        let mut inv = nalgebra::DMatrix::<f64>::zeros(m, m);
        for (k, &l) in eig.eigenvalues.iter().enumerate() {
            if l > 1e-12 * top {
                let u = eig.eigenvectors.column(k);
                inv += u * u.transpose() / l;
            }
        }
        self.coarse_inv = inv.as_slice().to_vec();
    }

    /// Contracts a tensor (row-major, `shape`) along `axis` with the rows of `tab`
    /// (`rows` x shape[axis]): out[.., r, ..] = sum_i tab[r][i] t[.., i, ..].
    fn contract(t: &[f64], shape: &[usize], axis: usize, tab: &[f64], rows: usize) -> Vec<f64> {
        let outer: usize = shape[..axis].iter().product();
        let inner: usize = shape[axis + 1..].iter().product();
        let m = shape[axis];
        let mut out = vec![0.0; outer * rows * inner];
        if inner == 1 {
            // The last axis: one dot product per output, summed in the same order as below.
            for (src, dst) in t.chunks_exact(m).zip(out.chunks_exact_mut(rows)) {
                for (d, w) in dst.iter_mut().zip(tab.chunks_exact(m)) {
                    let mut s = 0.0;
                    for (w, x) in w.iter().zip(src) {
                        s += w * x;
                    }
                    *d = s;
                }
            }
            return out;
        }
        for o in 0..outer {
            for r in 0..rows {
                let dst = &mut out[(o * rows + r) * inner..(o * rows + r + 1) * inner];
                for i in 0..m {
                    let w = tab[r * m + i];
                    let src = &t[(o * m + i) * inner..(o * m + i + 1) * inner];
                    dst.iter_mut().zip(src).for_each(|(d, s)| *d += w * s);
                }
            }
        }
        out
    }

    /// Coarse coefficients of a fine vector: its moments against the coarse fields (the
    /// components in parallel: on a reduced box's clamped axis, the last to finish, the coarse
    /// correction was a third of an iteration on one thread).
    fn restrict(&self, r: &[f64], coef: &mut [f64]) {
        let nq = self.nq;
        let ne = self.coarse_ne;
        let qs: Vec<usize> = (0..nq).collect();
        let moments = crate::physics::par::map(&qs, |&q| {
            let mut t = vec![0.0; self.coarse_grid.len()];
            for (k, &g) in self.coarse_grid.iter().enumerate() {
                t[g] = r[k * nq + q];
            }
            let mut shape = self.coarse_dims.clone();
            for a in 0..D {
                t = Self::contract(&t, &shape, a, &self.coarse_leg[a], ne);
                shape[a] = ne;
            }
            t
        });
        for (j, &(q, f)) in self.coarse_fields.iter().enumerate() {
            coef[j] = moments[q][f];
        }
    }

    /// z += the coarse fields weighted by `coef` (the components in parallel).
    fn prolong(&self, coef: &[f64], z: &mut [f64]) {
        let nq = self.nq;
        let ne = self.coarse_ne;
        let qs: Vec<usize> = (0..nq).collect();
        let fields = crate::physics::par::map(&qs, |&q| {
            let mut t = vec![0.0; ne.pow(D as u32)];
            let mut any = false;
            for (j, &(fq, f)) in self.coarse_fields.iter().enumerate() {
                if fq == q {
                    t[f] = coef[j];
                    any |= coef[j] != 0.0;
                }
            }
            if !any {
                return None;
            }
            let mut shape = vec![ne; D];
            for a in 0..D {
                let m = self.coarse_dims[a];
                t = Self::contract(&t, &shape, a, &self.coarse_leg_t[a], m);
                shape[a] = m;
            }
            Some(t)
        });
        for (q, t) in fields.iter().enumerate() {
            let Some(t) = t else { continue };
            for (k, &g) in self.coarse_grid.iter().enumerate() {
                z[k * nq + q] += t[g];
            }
        }
    }

    /// z += Z E^+ Z^T r.
    fn coarse_correct(&self, r: &[f64], z: &mut [f64]) {
        if self.coarse_inv.is_empty() {
            return;
        }
        let m = self.coarse_fields.len();
        let mut zr = vec![0.0; m];
        self.restrict(r, &mut zr);
        let w: Vec<f64> = (0..m)
            .map(|j| (0..m).map(|i| self.coarse_inv[j * m + i] * zr[i]).sum())
            .collect();
        self.prolong(&w, z);
    }

    /// Length of the corrections kept once per class.
    fn class_len(&self) -> usize {
        *self.class_start.last().unwrap_or(&0)
    }

    /// c = P A^T y, per class of rows (`class_start`). The rows of a class get the mean over
    /// the class, the orthogonal projection on the tied corrections (T (T^T T)^-1 T^T), so
    /// that the corrections are the least-norm ones over the reduced box's rows, each tied row
    /// counted as the row it is. With the sum instead (T T^T, the norm of one correction per
    /// class) a class of 125 rows weighed like one row: the free 30^3 cube's axes took
    /// 3,840 / 3,249 / 3,245 iterations against 2,405 / 1,809 / 1,809 with the mean (closure
    /// 8.9 -> 4.3 s), the clamped one's 7,525 / 3,249 / 3,245 against 5,231 / 1,809 / 1,809;
    /// the other weights tried, (class size)^-1/2 and ^-3/2, took 2,488 / 1,967 / 1,969 and
    /// 3,807 / 2,793 / 2,778. The rows of a class have the same stencil, so the same
    /// projection, which commutes with the mean: a class is projected once, after its rows'
    /// values are averaged (on a reduced 15^3 box 1,331 projections instead of 3,375).
    fn at_project(&self, y: &[f64], c: &mut [f64]) {
        let nq = self.nq;
        let mut classes: Vec<&mut [f64]> = Vec::with_capacity(self.members.len());
        let mut rest: &mut [f64] = c;
        for g in 0..self.members.len() {
            let (head, tail) = rest.split_at_mut(self.class_start[g + 1] - self.class_start[g]);
            classes.push(head);
            rest = tail;
        }
        par_iter_mut!(classes).enumerate().for_each(|(g, row)| {
            let members = &self.members[g];
            let Some(&first) = members.first() else {
                return;
            };
            let first = first as usize;
            // The class's rows have the same stencil: their bonds' r0 at each position k
            // is the first row's, so A^T y summed over the class is, per k, the sums of
            // the neighbours' y and of the rows' own y_0 against the one r0.
            if members.len() == 1 {
                let yi = y[first * nq];
                let lin = self.row_lin(first);
                for ((v, b), r) in row
                    .iter_mut()
                    .zip(self.bonds.of(first))
                    .zip(lin.chunks_exact(D))
                {
                    let j = self.bonds.nbr[b] as usize;
                    let mut s = y[j * nq] - yi;
                    for a in 0..D {
                        s -= y[j * nq + 1 + a] * r[a];
                    }
                    *v = s;
                }
                self.project_row(first, row);
                return;
            }
            let own: f64 = members.iter().map(|&i| y[i as usize * nq]).sum();
            let mean = 1.0 / members.len() as f64;
            for (k, v) in row.iter_mut().enumerate() {
                let mut yj = [0.0; 4];
                for &i in members {
                    let j = self.bonds.nbr[self.bonds.start[i as usize] as usize + k] as usize;
                    for (q, s) in yj.iter_mut().enumerate().take(nq) {
                        *s += y[j * nq + q];
                    }
                }
                let r = &self.row_lin(first)[k * D..k * D + D];
                let mut s = yj[0] - own;
                for a in 0..D {
                    s -= yj[1 + a] * r[a];
                }
                *v = s * mean;
            }
            self.project_row(first, row);
        });
    }

    /// y = A c (c kept per class), per column: the incoming bonds (j -> k: phi(x_j - x_k) = r0 of k -> j) minus
    /// the constant field on row k's own bonds.
    fn apply(&self, c: &[f64], y: &mut [f64]) {
        let nq = self.nq;
        let mut cols: Vec<&mut [f64]> = y.chunks_mut(nq).collect();
        par_iter_mut!(cols).enumerate().for_each(|(k, yk)| {
            // Row k's own corrections, contiguous in its class's block.
            let g = self.class[k] as usize;
            let own: f64 = c[self.class_start[g]..self.class_start[g + 1]].iter().sum();
            let mut acc = [0.0; 4];
            for (b, r) in self.bonds.of(k).zip(self.row_lin(k).chunks_exact(D)) {
                let cin = c[self.cpos_in[b] as usize];
                acc[0] += cin;
                for a in 0..D {
                    acc[1 + a] += cin * r[a];
                }
            }
            acc[0] -= own;
            yk.copy_from_slice(&acc[..nq]);
        });
    }

    /// |A c - t| for corrections c given per bond, or None when the rows of a class do not
    /// hold the same corrections (c is then not of the tied form).
    pub(super) fn residual(&self, c: &[f64], t: &[f64]) -> Option<f64> {
        let mut cc = vec![0.0; self.class_len()];
        for (b, &v) in c.iter().enumerate() {
            cc[self.cpos[b] as usize] = v;
        }
        if c.iter()
            .enumerate()
            .any(|(b, &v)| cc[self.cpos[b] as usize] != v)
        {
            return None;
        }
        let mut ac = vec![0.0; t.len()];
        self.apply(&cc, &mut ac);
        Some(
            ac.iter()
                .zip(t)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt(),
        )
    }

    /// Least-norm corrections for target t, from the multipliers y0 (or zero); returns (c, y,
    /// iterations, |A c - t|) with y the multipliers (c = P A^T y), or Err(how far it had
    /// come) when `stop` says so (polled every iteration).
    pub(super) fn solve(
        &self,
        t: &[f64],
        coarse: bool,
        stop: &(dyn Fn() -> bool + Sync),
        y0: Option<&[f64]>,
    ) -> Result<(Vec<f64>, Vec<f64>, usize, f64), Unfinished> {
        let started = std::time::Instant::now();
        let n = t.len();
        let nb = self.bonds.len();
        let tnorm = t.iter().map(|v| v * v).sum::<f64>().sqrt();
        let nq = self.nq;
        let precond = |r: &[f64], z: &mut [f64]| {
            if !self.block_inv.is_empty() {
                for k in 0..n / nq {
                    let bi = &self.block_inv[k * nq * nq..(k + 1) * nq * nq];
                    for q in 0..nq {
                        let mut s = 0.0;
                        for q2 in 0..nq {
                            s += bi[q * nq + q2] * r[k * nq + q2];
                        }
                        z[k * nq + q] = s;
                    }
                }
                if coarse {
                    self.coarse_correct(r, z);
                }
                return;
            }
            for k in 0..n {
                z[k] = if self.diag[k] > 0.0 {
                    r[k] / self.diag[k]
                } else {
                    0.0
                };
            }
        };
        let mut yv = y0.map_or_else(|| vec![0.0; n], <[f64]>::to_vec);
        let mut c = vec![0.0; self.class_len()];
        let mut ap = vec![0.0; n];
        let mut z = vec![0.0; n];
        let mut iters = 0;
        // Conjugate gradients keeping the best iterate: the tied system is consistent only to
        // a floor (1e-8 to 1e-4 of the target on some axes), below which the iterates drift
        // and, in long runs, diverge; the run stops there or at the tolerance.
        let mut r = t.to_vec();
        if y0.is_some() {
            self.at_project(&yv, &mut c);
            self.apply(&c, &mut ap);
            r.iter_mut().zip(&ap).for_each(|(r, a)| *r -= a);
        }
        precond(&r, &mut z);
        let mut p = z.clone();
        let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let mut best = (f64::INFINITY, yv.clone());
        // The smallest residual so far after each iteration: its trend tells an interrupted
        // solve how far it has to go.
        let mut lowest = Vec::new();
        while iters < MAX_ITERATIONS {
            let rnorm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            if rnorm < 0.7 * best.0 {
                best = (rnorm, yv.clone());
            }
            if rnorm <= TOLERANCE * tnorm || rnorm > 1e3 * best.0 {
                break;
            }
            lowest.push(rnorm.min(lowest.last().copied().unwrap_or(f64::INFINITY)));
            if stop() {
                return Err(Unfinished::new(
                    &lowest,
                    TOLERANCE * tnorm,
                    started.elapsed().as_secs_f64(),
                ));
            }
            self.at_project(&p, &mut c);
            self.apply(&c, &mut ap);
            let pap: f64 = p.iter().zip(&ap).map(|(a, b)| a * b).sum();
            if pap <= 0.0 || rz <= 0.0 {
                break;
            }
            let alpha = rz / pap;
            for k in 0..n {
                yv[k] += alpha * p[k];
                r[k] -= alpha * ap[k];
            }
            iters += 1;
            precond(&r, &mut z);
            let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for k in 0..n {
                p[k] = z[k] + beta * p[k];
            }
        }
        let yv = best.1;
        self.at_project(&yv, &mut c);
        self.apply(&c, &mut ap);
        let res = ap
            .iter()
            .zip(t)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        // Per bond.
        let c = (0..nb).map(|b| c[self.cpos[b] as usize]).collect();
        Ok((c, yv, iters, res))
    }
}

/// How far an interrupted conjugate-gradient solve had come.
pub(super) struct Unfinished {
    pub(super) iterations: usize,
    /// Its residual relative to the one it stops at.
    pub(super) above_goal: f64,
    /// Seconds it would still need at its pace: its recent convergence rate (the smallest
    /// residual over the second half of its iterations) carried to the goal, at most to
    /// MAX_ITERATIONS.
    pub(super) more_seconds: f64,
}

impl Unfinished {
    /// `lowest`: the smallest residual after each iteration; `goal`: the residual it stops at.
    fn new(lowest: &[f64], goal: f64, seconds: f64) -> Self {
        let n = lowest.len();
        let now = lowest[n - 1];
        let half = lowest[n / 2];
        let per_iteration = seconds / n as f64;
        let rate = (now.ln() - half.ln()) / (n - n / 2) as f64;
        let left = (MAX_ITERATIONS - n) as f64;
        let more = if rate < 0.0 && now > goal {
            ((goal.ln() - now.ln()) / rate).min(left)
        } else if now <= goal {
            0.0
        } else {
            left
        };
        Unfinished {
            iterations: n,
            above_goal: now / goal,
            more_seconds: more * per_iteration,
        }
    }
}

crate::physics::cpu_versions! {
    /// The projection of a row (`NullSpaceConstraints::project_row`): c -= M lam with
    /// lam = G (M^T c), `mono` its bonds' monomials (quad_len(D) each), `g` the inverse of its
    /// Gram matrix (column-major). Loops of constant trip count, each sum in a fixed order and
    /// no fused operations, so that every compiled version (AVX2 and AVX-512 where the CPU has
    /// them: the closure's solve is mostly this) gives the same bits.
    fn project<const D: usize>(mono: &[f64], g: &[f64], c: &mut [f64]) {
        let m = quad_len(D);
        let mut pc = [0.0; 9];
        for (mb, v) in mono.chunks_exact(m).zip(c.iter()) {
            for r in 0..m {
                pc[r] += mb[r] * v;
            }
        }
        let mut lam = [0.0; 9];
        // lam_r = sum_c g_rc pc_c, c ascending for every r (the columns of g are contiguous).
        for (col, &p) in g.chunks_exact(m).zip(&pc) {
            for r in 0..m {
                lam[r] += col[r] * p;
            }
        }
        for (mb, v) in mono.chunks_exact(m).zip(c.iter_mut()) {
            let mut s = 0.0;
            for r in 0..m {
                s += mb[r] * lam[r];
            }
            *v -= s;
        }
    }
}
