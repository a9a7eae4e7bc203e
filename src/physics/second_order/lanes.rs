//! Pass 1 of the second-order operator across bonds (issue 25): a particle's bonds taken in
//! groups of `LANES`, each per-bond quantity of a group held as one array of `LANES` values
//! (structure of arrays), so that the compiler keeps a group in one vector register (AVX-512:
//! 8 doubles) where the per-bond form worked on 2-wide pieces of 3 x 9 rows and divided one
//! bond at a time. What is constant per bond (the fit weights; the snapped reference vectors,
//! 1 / their length, whether the bond enters the fits) comes the same way from the particle's
//! interned sets (module `stencils`), and dE/d du goes out the same way (`dbond`), so that only
//! the displacements are gathered bond by bond. Sums over bonds are kept per lane and added in
//! a fixed order at the end; products are summed with fused multiply-adds (`f64::mul_add`,
//! exactly rounded), and the sums of the rows interleaved so that their chains of additions
//! overlap: the same bits in every compiled version and on every thread count.
use arrayvec::ArrayVec;

use super::{pair, SecondOrder};
use crate::physics::bonds::Bonds;
use crate::physics::dim::{Dim, Space, Vect};
pub use crate::physics::stencils::LANES;
use crate::physics::stencils::{geometry_rows, inv_len_row, keep_row, stride, R0_ROW};

/// One value per bond of a group.
pub type Lane = [f64; LANES];

/// The packed fit or conjugates of a particle: row r = [gradient part (D) | Hessian pairs].
pub type Packed<const D: usize> = [[f64; 9]; D];

/// The state of a group of a particle's bonds: du = u_j - u_i (m) and the bond's weight in the
/// residuals (0 for a broken bond, a bond behind a clamp, and the lanes past the last bond).
/// Aligned to a cache line, so that no lane straddles two.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
pub struct Group<const D: usize> {
    du: [Lane; D],
    w0: Lane,
}

/// Groups kept on the stack (128 bonds; more go to the heap).
const STACK_GROUPS: usize = 16;

/// Sum of a lane's values in a fixed order (the halves, then their two lanes).
#[inline(always)]
fn total(v: &Lane) -> f64 {
    (v[0] + v[2]) + (v[1] + v[3])
}

/// The sums of the lanes of `acc` (row r, values 0..nq).
#[inline(always)]
fn sums<const D: usize>(acc: &[[Lane; 9]; D], nq: usize) -> Packed<D> {
    let mut m = [[0.0f64; 9]; D];
    for (row, a) in m.iter_mut().zip(acc) {
        for j in 0..nq {
            row[j] = total(&a[j]);
        }
    }
    m
}

/// Row `row` of a group's block of its particle's set.
#[inline(always)]
fn lane(block: &[Lane], row: usize) -> &Lane {
    &block[row]
}

/// The blocks of a set with `rows` values per bond, one per group, each `rows` lanes.
#[inline(always)]
fn blocks(ws: &[f64], rows: usize) -> std::slice::ChunksExact<'_, Lane> {
    let (lanes, rest) = ws.as_chunks::<LANES>();
    debug_assert!(rest.is_empty(), "a set holds whole groups");
    lanes.chunks_exact(rows)
}

/// Sum of a particle's block of `dbond` (D rows of `LANES` per group): its bonds' dE/d du.
#[inline(always)]
pub fn block_sum<const D: usize>(block: &[f64]) -> Vect<D>
where
    Space: Dim<D>,
{
    let mut sum = [[0.0f64; LANES]; D];
    for group in block.chunks_exact(D * LANES) {
        for (r, s) in sum.iter_mut().enumerate() {
            for l in 0..LANES {
                s[l] += group[r * LANES + l];
            }
        }
    }
    Vect::<D>::from_fn(|r, _| total(&sum[r]))
}

/// Gathers the state of particle i's bonds into groups, then runs `f` on them. `uu` gives the
/// displacements of the fits.
#[inline(always)]
pub fn with_groups<const D: usize, R>(
    op: &SecondOrder<D>,
    bonds: &Bonds<D>,
    i: usize,
    uu: impl Fn(usize) -> Vect<D>,
    f: impl FnOnce(&[Group<D>]) -> R,
) -> R
where
    Space: Dim<D>,
{
    let range = bonds.of(i);
    let nb = range.len();
    let ng = nb.div_ceil(LANES);
    let empty = Group {
        du: [[0.0; LANES]; D],
        w0: [0.0; LANES],
    };
    let mut stack = ArrayVec::<Group<D>, STACK_GROUPS>::new();
    let mut heap = Vec::new();
    let groups: &mut [Group<D>] = if ng <= STACK_GROUPS {
        stack.extend(std::iter::repeat_n(empty, ng));
        &mut stack
    } else {
        heap.resize(ng, empty);
        &mut heap
    };
    let geometry = op.geometry.of(i);
    let ui = uu(i);
    let nbr = &bonds.nbr[range.clone()];
    let w0 = &bonds.w0[range];
    for (gi, (g, block)) in groups
        .iter_mut()
        .zip(blocks(geometry, geometry_rows(D)))
        .enumerate()
    {
        let start = gi * LANES;
        let n = (nb - start).min(LANES);
        let keep = lane(block, keep_row(D));
        for l in 0..n {
            g.w0[l] = w0[start + l] * keep[l];
        }
        // A bond without a weight enters neither the fit nor the residuals.
        for l in 0..n {
            if g.w0[l] != 0.0 {
                let d = uu(nbr[start + l] as usize) - ui;
                for a in 0..D {
                    g.du[a][l] = d[a];
                }
            }
        }
    }
    f(groups)
}

/// a b + c lane by lane, fused, written out lane by lane (the form the vectoriser takes as one
/// vector operation whatever the loops around it).
#[inline(always)]
fn fma(a: &Lane, b: &Lane, c: &Lane) -> Lane {
    const { assert!(LANES == 4) };
    [
        a[0].mul_add(b[0], c[0]),
        a[1].mul_add(b[1], c[1]),
        a[2].mul_add(b[2], c[2]),
        a[3].mul_add(b[3], c[3]),
    ]
}

/// One group's share of the fit: acc[r][j] += du[r] w[j] lane by lane.
#[inline(always)]
fn fit_group<const D: usize>(acc: &mut [[Lane; 9]; D], du: &[Lane; D], block: &[Lane])
where
    Space: Dim<D>,
{
    // A constant trip count (not the block's length), so that the loop is unrolled and its
    // lanes vectorised whatever the inlining around it.
    for j in 0..SecondOrder::<D>::NQ {
        let w = &block[j];
        for (row, du) in acc.iter_mut().zip(du) {
            row[j] = fma(du, w, &row[j]);
        }
    }
}

/// The fit of particle i in packed form, m = [H | G] (G's symmetric pairs in the stencils'
/// order): m_r = sum_b du_b[r] w_b over its bonds. Both the force pass and the energy fit with
/// this (the same bits).
#[inline(always)]
pub fn fit<const D: usize>(op: &SecondOrder<D>, i: usize, groups: &[Group<D>]) -> Packed<D>
where
    Space: Dim<D>,
{
    let nq = SecondOrder::<D>::NQ;
    let ws = op.stencils.of(i);
    let mut acc = [[[0.0f64; LANES]; 9]; D];
    for (g, block) in groups.iter().zip(blocks(ws, stride(D))) {
        fit_group(&mut acc, &g.du, block);
    }
    sums(&acc, nq)
}

/// dE/d du of particle i's bonds into `out` (its block of `dbond`: per group D rows of
/// `LANES`). For each bond with a weight, the residual res = du - m phi
/// with phi = (r0, r0_a r0_c / (1 + [a = c])), its energy's conjugate rho and direct part
/// (`SecondOrder::residual_terms`, a group at a time); the conjugates `cj` take -rho phi^T
/// (the residual's share), then dE/d du_b = rho + direct + cj w_b, times `share` (the
/// particle's retained share of its energy). `cres` is V mu / n_i; a bond's stiffness is
/// cres w0 / |r0|^2.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn bond_forces<const D: usize>(
    op: &SecondOrder<D>,
    i: usize,
    groups: &[Group<D>],
    m: &Packed<D>,
    cres: f64,
    mut cj: Packed<D>,
    share: f64,
    out: &mut [f64],
) where
    Space: Dim<D>,
{
    let nq = SecondOrder::<D>::NQ;
    let ws = op.stencils.of(i);
    let geometry = op.geometry.of(i);
    debug_assert_eq!(ws.len(), groups.len() * LANES * stride(D));
    debug_assert_eq!(out.len(), groups.len() * LANES * D);
    let mut acc = [[[0.0f64; LANES]; 9]; D];
    for ((g, o), block) in groups
        .iter()
        .zip(out.chunks_exact_mut(D * LANES))
        .zip(blocks(geometry, geometry_rows(D)))
    {
        let du = &g.du;
        let r0: [Lane; D] = std::array::from_fn(|a| *lane(block, R0_ROW + a));
        let inv_r0 = lane(block, inv_len_row(D));
        let mut phi = [[0.0f64; LANES]; 9];
        for a in 0..D {
            phi[a] = r0[a];
            for c in a..D {
                let p = &mut phi[D + pair::<D>(a, c)];
                for l in 0..LANES {
                    p[l] = if a == c {
                        0.5 * r0[a][l] * r0[a][l]
                    } else {
                        r0[a][l] * r0[c][l]
                    };
                }
            }
        }
        // The rows' sums interleaved (three independent chains of fused multiply-adds).
        let mut q = [[0.0f64; LANES]; D];
        for j in 0..nq {
            for (r, q) in q.iter_mut().enumerate() {
                *q = fma(&[m[r][j]; LANES], &phi[j], q);
            }
        }
        let mut res = *du;
        for (res, q) in res.iter_mut().zip(&q) {
            for l in 0..LANES {
                res[l] -= q[l];
            }
        }
        // The bond's current direction n and length (`bond_direction`): the reference
        // direction for coincident particles. One square root and one division per bond.
        let mut len2 = [0.0f64; LANES];
        for a in 0..D {
            for l in 0..LANES {
                let x = r0[a][l] + du[a][l];
                len2[l] = x.mul_add(x, len2[l]);
            }
        }
        let mut dir = [[0.0f64; LANES]; D];
        let mut inv_len = [0.0f64; LANES];
        let mut c = [0.0f64; LANES];
        for l in 0..LANES {
            let s = len2[l].sqrt();
            let moving = s * inv_r0[l] > 1e-9;
            let inv = if moving { 1.0 / s } else { inv_r0[l] };
            let shift = if moving { 1.0 } else { 0.0 };
            for a in 0..D {
                dir[a][l] = (r0[a][l] + shift * du[a][l]) * inv;
            }
            inv_len[l] = if moving { inv } else { 0.0 };
            c[l] = cres * g.w0[l] * (inv_r0[l] * inv_r0[l]);
        }
        let mut rn = [0.0f64; LANES];
        for a in 0..D {
            for l in 0..LANES {
                rn[l] = res[a][l].mul_add(dir[a][l], rn[l]);
            }
        }
        // rho = c (res + n (res.n)); direct = c (res.n) / |r0 + du| (res - n (res.n)), none
        // for coincident particles.
        let mut rho = [[0.0f64; LANES]; D];
        for a in 0..D {
            let o = &mut o[a * LANES..(a + 1) * LANES];
            for l in 0..LANES {
                rho[a][l] = (res[a][l] + dir[a][l] * rn[l]) * c[l];
                o[l] = rho[a][l] + (res[a][l] - dir[a][l] * rn[l]) * (c[l] * rn[l] * inv_len[l]);
            }
        }
        for (r, row) in acc.iter_mut().enumerate() {
            for j in 0..nq {
                row[j] = fma(&rho[r], &phi[j], &row[j]);
            }
        }
    }
    let back = sums(&acc, nq);
    for (row, b) in cj.iter_mut().zip(&back) {
        for j in 0..nq {
            row[j] -= b[j];
        }
    }
    // dE/d du_b += cj w_b; zero for the bonds without a weight.
    for ((g, o), block) in groups
        .iter()
        .zip(out.chunks_exact_mut(D * LANES))
        .zip(blocks(ws, stride(D)))
    {
        let (o, _) = o.as_chunks_mut::<LANES>();
        // An opaque value per group keeps LLVM's loop vectoriser off this loop: across groups
        // it gathered every weight from four groups and transposed every output (23 % of
        // pass 1), where the group's own lanes are one vector each.
        conjugates_group::<D>(o, &cj, block, &g.w0, std::hint::black_box(share));
    }
}

/// One group's dE/d du: o[r] += cj[r] w lane by lane (the rows' chains interleaved), times the
/// share, zero where the bond has no weight (w0 = 0).
#[inline(always)]
fn conjugates_group<const D: usize>(
    o: &mut [Lane],
    cj: &Packed<D>,
    block: &[Lane],
    w0: &Lane,
    share: f64,
) where
    Space: Dim<D>,
{
    let mut d: [Lane; D] = std::array::from_fn(|r| o[r]);
    for j in 0..SecondOrder::<D>::NQ {
        let w = &block[j];
        for (r, d) in d.iter_mut().enumerate() {
            *d = fma(&[cj[r][j]; LANES], w, d);
        }
    }
    let scale: Lane = std::array::from_fn(|l| if w0[l] == 0.0 { 0.0 } else { share });
    for (o, d) in o.iter_mut().zip(&d) {
        for l in 0..LANES {
            o[l] = d[l] * scale[l];
        }
    }
}
