//! Summation-by-parts closure of the second-order operator at free faces (issue 7): particle
//! volumes that integrate cubic fields exactly over a box-shaped body, and the least correction
//! of the fits' gradient weights, inside their quadratic null spaces, for which the
//! volume-weighted transpose of the gradient of every linear field is minus its derivative plus
//! the exact face integral. With both, the particle (nodal) quadrature of the weak form passes
//! the integration constraint: a linear stress in equilibrium with its body force and free of
//! traction on the faces leaves no residual force (docs/model.md, "Free faces").
//!
//! In matrix form, per axis d, with G the fits' gradient matrix, H the diagonal of the volumes
//! and E = R^T B N_d R the face term (R: the fits' quadratic extrapolation of particle values to
//! the face points, B: the face quadrature, N_d: the normal's component), the closed gradient is
//! G + H^-1 D with D P2 = 0 (the fits stay exact for quadratic fields P2) and
//! (G + H^-1 D)^T H q = -H dq/dx_d + E q for the linear fields q. That system is solvable when
//! H integrates quadratic fields exactly and B integrates cubic ones over the faces; the
//! cell-centred midpoint rule does neither near a face, its end-corrected tensor product does
//! (weights 1 + 1/12, 1 - 1/8, 1 + 1/24 on the first three layers; by symmetry exact for cubics).
//! Mirror faces are interior to the body's mirrored extension, which is the box the closure is
//! built on. Bodies that are not a filled lattice box (after mirroring) keep the plain fits.
use std::collections::HashMap;

use super::bonds::Bonds;
use super::dim::{Dim, Mat, Space, Vect};
use super::second_order::{Ghost, SecondOrder};

/// End corrections of the cell-centred midpoint rule on the first three layers from a face:
/// with them the 1D rule integrates quadratics exactly (Euler-Maclaurin: the midpoint sum of a
/// cubic misses h^2 / 24 (f'(b) - f'(a))), and by symmetry cubics.
const END_CORRECTION: [f64; 3] = [1.0 / 12.0, -1.0 / 8.0, 1.0 / 24.0];

/// Relative residual at which the conjugate gradients stop.
const TOLERANCE: f64 = 1e-11;

/// The 1D weights (in units of l0) of n >= 3 cell-centred points.
fn weights_1d(n: usize) -> Vec<f64> {
    let mut w = vec![1.0; n];
    for (k, d) in END_CORRECTION.iter().enumerate() {
        w[k] += d;
        w[n - 1 - k] += d;
    }
    w
}

/// What the closure changes, in the world's indexing.
#[derive(Clone, Debug, Default)]
pub struct Closure<const D: usize> {
    /// Volume of each closed particle (m^D): its quadrature weight and, times the density, its
    /// mass. None: not closed (l0^D).
    pub vol: Vec<Option<f64>>,
    /// Correction of each bond's gradient weight (1/m).
    pub dg: Vec<Vect<D>>,
    /// One line per body: closed or why not, with the solve's figures.
    pub report: Vec<String>,
}

/// Number of monomials of degree 1 and 2 in D variables.
const fn quad_len(d: usize) -> usize {
    d + d * (d + 1) / 2
}

fn monomials<const D: usize>(s: &Vect<D>, out: &mut Vec<f64>) {
    out.clear();
    for a in 0..D {
        out.push(s[a]);
    }
    for a in 0..D {
        for c in a..D {
            out.push(s[a] * s[c]);
        }
    }
}

/// Closes the second-order operator of every body that is a filled lattice box once mirrored
/// across its mirror faces. `so` is the world's operator (its rigid flags and ghosts),
/// `bonds` the world's bonds.
pub fn close<const D: usize>(
    x0: &[Vect<D>],
    body: &[u32],
    bonds: &Bonds<D>,
    so: &SecondOrder<D>,
    l0: f64,
    re_factor: f64,
    n_bodies: usize,
) -> Closure<D>
where
    Space: Dim<D>,
{
    let n = x0.len();
    let mut out = Closure {
        vol: vec![None; n],
        dg: vec![Vect::<D>::zeros(); bonds.len()],
        report: Vec::new(),
    };
    let ghost_of: HashMap<u32, &Ghost<D>> = so.ghosts.iter().map(|g| (g.ghost, g)).collect();
    for b in 0..n_bodies {
        match close_body(x0, body, bonds, so, &ghost_of, l0, re_factor, b as u32, &mut out) {
            Ok(line) => out.report.push(format!("body {b}: {line}")),
            Err(why) => out.report.push(format!("body {b}: not closed: {why}")),
        }
    }
    out
}

#[allow(clippy::too_many_arguments)]
fn close_body<const D: usize>(
    x0: &[Vect<D>],
    body: &[u32],
    bonds: &Bonds<D>,
    so: &SecondOrder<D>,
    ghost_of: &HashMap<u32, &Ghost<D>>,
    l0: f64,
    re_factor: f64,
    b: u32,
    out: &mut Closure<D>,
) -> Result<String, String>
where
    Space: Dim<D>,
{
    let members: Vec<usize> = (0..x0.len()).filter(|&i| body[i] == b).collect();
    let real: Vec<usize> = members
        .iter()
        .copied()
        .filter(|i| !ghost_of.contains_key(&(*i as u32)))
        .collect();
    if real.iter().any(|&i| so.rigid[i]) {
        return Err("it has a rigid grip (a clamp without a mirror face)".into());
    }
    // Mirror planes (unit normal, offset n.x) from the ghost-master pairs of this body.
    let mut planes: Vec<(Vect<D>, f64)> = Vec::new();
    for &i in &members {
        if let Some(g) = ghost_of.get(&(i as u32)) {
            let (xg, xm) = (x0[g.ghost as usize], x0[g.master as usize]);
            let nrm = (xg - xm).normalize();
            let off = nrm.dot(&((xg + xm) * 0.5));
            if !planes
                .iter()
                .any(|(m, o)| (m - nrm).norm() < 1e-6 && (o - off).abs() < 1e-6 * l0)
            {
                planes.push((nrm, off));
            }
        }
    }
    // The virtual body: the real particles and their images across every mirror plane.
    let mut vx: Vec<Vect<D>> = real.iter().map(|&i| x0[i]).collect();
    for (nrm, off) in &planes {
        for &i in &real {
            let x = x0[i];
            vx.push(x - nrm * (2.0 * (nrm.dot(&x) - off)));
        }
    }
    let nv = vx.len();
    let mut lo = vx[0];
    for x in &vx {
        lo = lo.inf(x);
    }
    let mut idx: Vec<[usize; D]> = Vec::with_capacity(nv);
    let mut ext = [0usize; D];
    for x in &vx {
        let mut k = [0usize; D];
        for a in 0..D {
            let f = (x[a] - lo[a]) / l0;
            let r = f.round();
            if (f - r).abs() > 1e-6 {
                return Err("its particles are not on one lattice".into());
            }
            k[a] = r as usize;
            ext[a] = ext[a].max(k[a] + 1);
        }
        idx.push(k);
    }
    if ext.iter().product::<usize>() != nv
        || idx
            .iter()
            .collect::<std::collections::HashSet<_>>()
            .len()
            != nv
    {
        return Err("it is not a filled box (with its mirror images)".into());
    }
    if ext.iter().any(|&e| e < 3) {
        return Err("it is less than 3 particles across".into());
    }
    let w1: Vec<Vec<f64>> = ext.iter().map(|&e| weights_1d(e)).collect();
    let vol_unit = l0.powi(D as i32);
    let hv: Vec<f64> = idx
        .iter()
        .map(|k| vol_unit * (0..D).map(|a| w1[a][k[a]]).product::<f64>())
        .collect();
    // The virtual body's own fits (its particles see full stencils at the mirror planes).
    let vb = Bonds::build(&vx, &vec![0; nv], re_factor * l0);
    let vso = SecondOrder::<D>::new(&vb, l0, re_factor, nv, &vec![false; nv], &[]);
    if vso.quadratic.iter().any(|q| !q) || vso.full.iter().any(|f| !f) {
        return Err("a particle has no full quadratic fit".into());
    }
    // Linear fields q_0 = 1, q_a = (x_a - c_a) / half_a.
    let mut centre = Vect::<D>::zeros();
    let mut half = Vect::<D>::zeros();
    for a in 0..D {
        half[a] = 0.5 * ext[a] as f64 * l0;
        centre[a] = lo[a] - 0.5 * l0 + half[a];
    }
    let nq = D + 1;
    let q_at = |x: &Vect<D>, q: usize| -> f64 {
        if q == 0 {
            1.0
        } else {
            (x[q - 1] - centre[q - 1]) / half[q - 1]
        }
    };
    let qv: Vec<f64> = (0..nv)
        .flat_map(|i| (0..nq).map(move |q| (i, q)))
        .map(|(i, q)| q_at(&vx[i], q))
        .collect();
    // Row projectors on the quadratic null space: I - P^T (P P^T)^-1 P per row.
    let m = quad_len(D);
    let mut row_gram: Vec<nalgebra::DMatrix<f64>> = Vec::with_capacity(nv);
    let mut mono = Vec::with_capacity(m);
    let mono_of = |bnd: usize, mono: &mut Vec<f64>| monomials::<D>(&(vb.r0[bnd] / l0), mono);
    for i in 0..nv {
        let mut gram = nalgebra::DMatrix::<f64>::zeros(m, m);
        for bnd in vb.of(i) {
            mono_of(bnd, &mut mono);
            for r in 0..m {
                for c in 0..m {
                    gram[(r, c)] += mono[r] * mono[c];
                }
            }
        }
        let inv = gram
            .try_inverse()
            .ok_or("a fit's moment matrix is singular")?;
        row_gram.push(inv);
    }
    let depth: usize = std::env::var("MPS_SBP_DEPTH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(usize::MAX);
    let active: Vec<bool> = idx
        .iter()
        .map(|k| (0..D).any(|a| k[a].min(ext[a] - 1 - k[a]) < depth))
        .collect();
    let project = |c: &mut [f64]| {
        // c: per bond of the virtual body; project every row.
        let mut mono = Vec::with_capacity(m);
        for i in 0..nv {
            let r = vb.of(i);
            if !active[i] {
                for bnd in r {
                    c[bnd] = 0.0;
                }
                continue;
            }
            let mut pc = nalgebra::DVector::<f64>::zeros(m);
            for bnd in r.clone() {
                monomials::<D>(&(vb.r0[bnd] / l0), &mut mono);
                for k in 0..m {
                    pc[k] += mono[k] * c[bnd];
                }
            }
            let lam = &row_gram[i] * pc;
            for bnd in r {
                monomials::<D>(&(vb.r0[bnd] / l0), &mut mono);
                let mut s = 0.0;
                for k in 0..m {
                    s += mono[k] * lam[k];
                }
                c[bnd] -= s;
            }
        }
    };
    // The constraints of column k in local linear fields phi_0 = 1, phi_a = (x_a - x_k,a) / l0
    // (the same span as the global fields, but not nearly dependent far from the centre):
    // A c: sum_{b = i -> k} c_b phi(x_i - x_k) - phi(0) sum_{b of k} c_b, x_i - x_k = -r0_b.
    let apply_a = |c: &[f64], y: &mut [f64]| {
        y.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..nv {
            let mut row_sum = 0.0;
            for bnd in vb.of(i) {
                let k = vb.nbr[bnd] as usize;
                let r = vb.r0[bnd] / l0;
                y[k * nq] += c[bnd];
                for a in 0..D {
                    y[k * nq + 1 + a] -= c[bnd] * r[a];
                }
                row_sum += c[bnd];
            }
            y[i * nq] -= row_sum;
        }
    };
    // A^T y: bond b = i -> k: y_k0 - sum_a y_ka r0_a / l0 - y_i0.
    let apply_at = |y: &[f64], c: &mut [f64]| {
        for i in 0..nv {
            for bnd in vb.of(i) {
                let k = vb.nbr[bnd] as usize;
                let r = vb.r0[bnd] / l0;
                let mut s = y[k * nq] - y[i * nq];
                for a in 0..D {
                    s -= y[k * nq + 1 + a] * r[a];
                }
                c[bnd] = s;
            }
        }
    };
    let nb = vb.len();
    let mut corr: Vec<Vect<D>> = vec![Vect::<D>::zeros(); nb];
    let mut figures = Vec::new();
    for d in 0..D {
        // Target: t = -H dq/dx_d + E_d q - G_d^T H q.
        let mut t = vec![0.0; nv * nq];
        for i in 0..nv {
            for q in 1..nq {
                if q - 1 == d {
                    t[i * nq + q] -= hv[i] / half[d];
                }
            }
            for bnd in vb.of(i) {
                let k = vb.nbr[bnd] as usize;
                let gw = vso.g[bnd][d] * hv[i];
                for q in 0..nq {
                    let v = gw * qv[i * nq + q];
                    t[k * nq + q] -= v;
                    t[i * nq + q] += v;
                }
            }
            // Face points of particle i normal to axis d.
            let k = idx[i];
            for (side, at_face) in [(-1.0, k[d] == 0), (1.0, k[d] + 1 == ext[d])] {
                if !at_face {
                    continue;
                }
                let mut dd = Vect::<D>::zeros();
                dd[d] = side * 0.5 * l0;
                let y = vx[i] + dd;
                let area: f64 = l0.powi(D as i32 - 1)
                    * (0..D)
                        .filter(|&a| a != d)
                        .map(|a| w1[a][k[a]])
                        .product::<f64>();
                let mut rsum = 0.0;
                for bnd in vb.of(i) {
                    let j = vb.nbr[bnd] as usize;
                    let hb: Mat<D> = vso.h[bnd];
                    let rho = vso.g[bnd].dot(&dd) + 0.5 * dd.dot(&(hb * dd));
                    rsum += rho;
                    for q in 0..nq {
                        t[j * nq + q] += rho * side * area * q_at(&y, q);
                    }
                }
                for q in 0..nq {
                    t[i * nq + q] += (1.0 - rsum) * side * area * q_at(&y, q);
                }
            }
        }
        // To the local fields of each column.
        for k in 0..nv {
            let t0 = t[k * nq];
            for a in 0..D {
                t[k * nq + 1 + a] = (t[k * nq + 1 + a] - qv[k * nq + 1 + a] * t0) * half[a] / l0;
            }
        }
        let tnorm = t.iter().map(|v| v * v).sum::<f64>().sqrt();
        // CG on (A P A^T) y = t; c = P A^T y.
        let mut yv = vec![0.0; nv * nq];
        let mut r = t.clone();
        let mut p = r.clone();
        let mut rr: f64 = r.iter().map(|v| v * v).sum();
        let mut c = vec![0.0; nb];
        let mut ap = vec![0.0; nv * nq];
        let mut iters = 0;
        while rr.sqrt() > TOLERANCE * tnorm && iters < 3000 {
            apply_at(&p, &mut c);
            project(&mut c);
            apply_a(&c, &mut ap);
            let pap: f64 = p.iter().zip(&ap).map(|(a, b)| a * b).sum();
            if pap <= 0.0 {
                break;
            }
            let alpha = rr / pap;
            for k in 0..yv.len() {
                yv[k] += alpha * p[k];
                r[k] -= alpha * ap[k];
            }
            let rr_new: f64 = r.iter().map(|v| v * v).sum();
            let beta = rr_new / rr;
            rr = rr_new;
            for k in 0..p.len() {
                p[k] = r[k] + beta * p[k];
            }
            iters += 1;
            if iters % 500 == 0 && std::env::var_os("MPS_SBP_DEBUG").is_some() {
                eprintln!("sbp: axis {d}: {iters}: {:.2e}", rr.sqrt() / tnorm);
            }
        }
        apply_at(&yv, &mut c);
        project(&mut c);
        apply_a(&c, &mut ap);
        let res = ap
            .iter()
            .zip(&t)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        let gmax = vso.g.iter().map(|g| g.amax()).fold(0.0, f64::max);
        let mut cmax = 0.0f64;
        for i in 0..nv {
            for bnd in vb.of(i) {
                cmax = cmax.max((c[bnd] / hv[i]).abs());
            }
        }
        figures.push(format!(
            "axis {d}: {iters} CG iterations, residual {:.1e} of {:.1e}, largest correction {:.3} of the largest weight",
            res, tnorm, cmax / gmax
        ));
        for i in 0..nv {
            for bnd in vb.of(i) {
                corr[bnd][d] = c[bnd] / hv[i];
            }
        }
    }
    // Back to the world's bonds of the real particles (the first real.len() virtual ones).
    let key = |r: &Vect<D>| -> Vec<i64> { r.iter().map(|c| (c / l0 * 4.0).round() as i64).collect() };
    let mut lost = 0.0f64;
    let mut updates = Vec::new();
    for (vi, &i) in real.iter().enumerate() {
        let world: HashMap<Vec<i64>, usize> =
            bonds.of(i).map(|bnd| (key(&bonds.r0[bnd]), bnd)).collect();
        for bnd in vb.of(vi) {
            match world.get(&key(&vb.r0[bnd])) {
                Some(&wb) => updates.push((wb, corr[bnd])),
                None => lost = lost.max(corr[bnd].amax()),
            }
        }
    }
    if lost > 0.0 {
        return Err(format!("a correction of {lost:.2e} 1/m has no bond in the world"));
    }
    for (wb, c) in updates {
        out.dg[wb] = c;
    }
    for (vi, &i) in real.iter().enumerate() {
        out.vol[i] = Some(hv[vi]);
    }
    Ok(format!(
        "closed, {} particles ({} virtual, {:?} across); {}",
        real.len(),
        nv,
        ext,
        figures.join("; ")
    ))
}
