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
//! built on, in the lattice's own frame (a turned body gets the same closure, volumes and stable
//! step). A clamped face is a face of that box whose extrapolation R is the followers'
//! constraint along its normal (`ghosts::Follower`), so that its face term vanishes for
//! every motion the clamp admits. Bodies that are not a filled lattice box (after mirroring)
//! keep the plain fits.
//!
//! The least-norm corrections solve (A P A^T) y = t (A: the column sums, P: the projection on
//! each row's quadratic null space), a sixth-order-like operator whose condition grows as the
//! sixth power of the body's length in layers. Layers further than REACH from both ends of a
//! long axis are alike, so the system is solved on a box of 2 REACH + 1 layers along such an
//! axis with the rows beyond TIE layers from its ends tied to one correction (the translation
//! invariant solution, which exists: the tied system is consistent to round-off), and copied
//! back by layer. The corrections are the least-norm ones over the reduced box's rows (a tied
//! class counts as its rows: (A P T (T^T T)^-1 T^T A^T) y = t, T the ties). The reduced box
//! needs some thousand conjugate-gradient iterations at most.
use std::collections::HashMap;

use super::bonds::Bonds;
use super::dim::{Dim, Mat, Space, Vect};
use super::ghosts::{Ghost, FACE_EXTRAPOLATION};
use super::grid::round;
#[allow(unused_imports)]
use super::par::*;
use super::second_order::SecondOrder;
use super::stencils::Stencils;

mod least_norm;
pub mod memo;
mod symmetry;
use least_norm::{NullSpaceConstraints, MAX_ITERATIONS};

/// Fewest particles across a box, along every axis, whose faces the closure serves (with the
/// mirror images of its clamped faces); a thinner body keeps the plain fits.
pub const MIN_ACROSS: usize = 3;

/// End corrections of the cell-centred midpoint rule on the first three layers from a face:
/// with them the 1D rule integrates quadratics exactly (Euler-Maclaurin: the midpoint sum of a
/// cubic misses h^2 / 24 (f'(b) - f'(a))), and by symmetry cubics.
const END_CORRECTION: [f64; 3] = [1.0 / 12.0, -1.0 / 8.0, 1.0 / 24.0];

/// Layers from the ends of a long axis within which columns differ: TIE plus the fits' reach
/// (2 layers). The column REACH layers from an end is the first whose rows are all tied, so
/// the reduced box of 2 REACH + 1 layers holds one interior column and its constraint; with
/// one layer fewer the reduced system still solves but no column of it stands for the
/// interior's. (It was TIE + 3: 17 layers instead of 15, the same closure to the printed
/// digits of every accuracy figure and 20 % more set-up.)
const REACH: usize = 7;

/// Layers from the ends of a long axis whose rows have their own corrections; the rows beyond
/// are tied (translation invariance). With 3 the tied system is inconsistent (the rows 3 and 4
/// from an end need their own corrections).
const TIE: usize = 5;

/// Largest relative residual of the constraints for which the closure is taken (the reduced
/// system is consistent to round-off; a failed solve leaves the body's plain fits).
const ACCEPT: f64 = 1e-3;

/// Layers from a face over which the sliver of a face that cuts cells is spread: fewer than
/// TIE, so that the tied rows keep the interior's weight 1.
const SLIVER_LAYERS: usize = 5;

/// Least weight (in l0) a closed particle may have: a face that cuts its cells more deeply
/// than the layers can take keeps the plain fits.
const LEAST_WEIGHT: f64 = 0.25;

/// The 1D weights (in units of l0) of n >= 3 cell-centred points 0, 1, ..., n - 1 over the
/// interval from `delta[0]` before the first to `delta[1]` beyond the last (a face on the
/// cell faces is 1/2 out; one that cuts cells is further or nearer, by the sliver of cell the
/// outer particle carries or lacks). At 1/2 the end-corrected midpoint rule; a sliver adds to
/// the first layers from its face the least-norm weights that integrate its (signed) moments
/// 1, x, x^2 (and x^3 when the two ends differ): the rule then integrates cubics exactly over
/// the interval, with equal ends by symmetry. None where a weight would fall below
/// LEAST_WEIGHT or the layers are too few.
fn weights_1d(n: usize, delta: [f64; 2]) -> Option<Vec<f64>> {
    let mut w = vec![1.0; n];
    for (k, d) in END_CORRECTION.iter().enumerate() {
        w[k] += d;
        w[n - 1 - k] += d;
    }
    let equal = (delta[0] - delta[1]).abs() <= 1e-12;
    let conditions = if equal { 3 } else { 4 };
    let layers = SLIVER_LAYERS.min(n);
    for (end, &dl) in delta.iter().enumerate() {
        if dl.is_nan() || dl <= 0.0 {
            return None;
        }
        if (dl - 0.5).abs() <= 1e-12 {
            continue;
        }
        if layers < conditions {
            return None;
        }
        // The sliver [-dl, -1/2] in the layers' coordinate (layer k at k).
        let moment = |p: i32| ((-0.5f64).powi(p + 1) - (-dl).powi(p + 1)) / (p + 1) as f64;
        let v =
            nalgebra::DMatrix::<f64>::from_fn(conditions, layers, |p, k| (k as f64).powi(p as i32));
        let t = nalgebra::DVector::<f64>::from_fn(conditions, |p, _| moment(p as i32));
        let lam = (&v * v.transpose()).lu().solve(&t)?;
        let inc = v.transpose() * lam;
        for k in 0..layers {
            let at = if end == 0 { k } else { n - 1 - k };
            w[at] += inc[k];
        }
    }
    w.iter().all(|&x| x >= LEAST_WEIGHT).then_some(w)
}

/// Where a body's faces are, for the closure.
#[derive(Clone, Copy, Debug)]
pub enum BodyFaces<const D: usize> {
    /// A body of boxes: its faces are half a spacing beyond its outer particles.
    Lattice,
    /// A body filled from a solid that is this axis-aligned box (least and greatest corners,
    /// m): its faces may cut the outer particles' cells.
    Box(Vect<D>, Vect<D>),
    /// A body filled from another solid: its faces are not a box's.
    Other,
}

/// What the closure changes, in the world's indexing.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Closure<const D: usize> {
    /// Volume of each closed particle (m^D): its quadrature weight and, times the density, its
    /// mass. None: not closed (l0^D).
    pub vol: Vec<Option<f64>>,
    /// Correction of each bond's gradient weight (1/m): per closed particle, D values per bond
    /// in its bond order, interned by set (module `stencils`: the particles of one layer class
    /// share their row bit for bit), 4 B per particle where a list per bond held 24 B per bond
    /// during the build (issue 25).
    pub dg: Stencils<D>,
    /// Per body: closed (with the solve's figures) or why not.
    pub report: Vec<Result<String, String>>,
    /// Set when the caller's stop check ended a solve: how far it had come (the bodies after
    /// it were not tried, and the volumes and corrections are incomplete).
    pub interrupted: Option<String>,
}

/// Orthonormal lattice axes (as columns) from particle i's bonds of length l0: the first bond
/// direction, then each next one orthogonal to those taken.
fn lattice_frame<const D: usize>(bonds: &Bonds<D>, i: usize, l0: f64) -> Option<Mat<D>> {
    let mut axes: Vec<Vect<D>> = Vec::with_capacity(D);
    for b in bonds.of(i) {
        let r = bonds.r0[b];
        if (r.norm() - l0).abs() > 1e-6 * l0 {
            continue;
        }
        let e = r / r.norm();
        if axes.iter().all(|a| a.dot(&e).abs() < 1e-6) {
            axes.push(e);
            if axes.len() == D {
                break;
            }
        }
    }
    (axes.len() == D).then(|| Mat::<D>::from_columns(&axes))
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

/// What the closure is computed from: the reference positions and bodies, each body's faces
/// (`faces`) and name, the world's bonds, its second-order operator after the fits (rigid
/// flags, walls, ghosts, followers), the spacing l0 (m) and the stencil radius over l0.
pub struct ClosureInputs<'a, const D: usize>
where
    Space: Dim<D>,
{
    pub x0: &'a [Vect<D>],
    pub faces: &'a [BodyFaces<D>],
    pub body: &'a [u32],
    pub bonds: &'a Bonds<D>,
    pub so: &'a SecondOrder<D>,
    pub l0: f64,
    pub re_factor: f64,
    pub names: &'a [&'a str],
}

/// Closes the second-order operator of every body that is a filled lattice box once mirrored
/// across its mirror faces, with its faces where `faces` says (per body). `stop` is polled in
/// the solves (from any thread): when it says so, the closure ends at once with `interrupted`
/// set.
pub fn close<const D: usize>(
    input: &ClosureInputs<'_, D>,
    stop: &(dyn Fn() -> bool + Sync),
) -> Closure<D>
where
    Space: Dim<D>,
{
    let ClosureInputs {
        x0,
        faces,
        body,
        bonds,
        so,
        l0,
        re_factor,
        names,
    } = *input;
    let n = x0.len();
    let mut out = Closure {
        vol: vec![None; n],
        dg: Stencils::with_particles(n),
        report: Vec::new(),
        interrupted: None,
    };
    let ghost_of: HashMap<u32, &Ghost<D>> = so.ghosts.iter().map(|g| (g.ghost, g)).collect();
    for (b, name) in names.iter().enumerate() {
        let r = close_body(
            x0, faces[b], body, bonds, so, &ghost_of, l0, re_factor, b as u32, name, stop, &mut out,
        );
        out.report.push(r);
        if out.interrupted.is_some() {
            break;
        }
    }
    out
}

#[allow(clippy::too_many_arguments)]
fn close_body<const D: usize>(
    x0: &[Vect<D>],
    faces: BodyFaces<D>,
    body: &[u32],
    bonds: &Bonds<D>,
    so: &SecondOrder<D>,
    ghost_of: &HashMap<u32, &Ghost<D>>,
    l0: f64,
    re_factor: f64,
    b: u32,
    name: &str,
    stop: &(dyn Fn() -> bool + Sync),
    out: &mut Closure<D>,
) -> Result<String, String>
where
    Space: Dim<D>,
{
    let clock = std::time::Instant::now();
    let members: Vec<usize> = (0..x0.len()).filter(|&i| body[i] == b).collect();
    let real: Vec<usize> = members
        .iter()
        .copied()
        .filter(|i| {
            !ghost_of.contains_key(&(*i as u32)) && !so.walls.get(*i).copied().unwrap_or(false)
        })
        .collect();
    if real.is_empty() {
        return Err("it has no particles of its own".into());
    }
    if matches!(faces, BodyFaces::Other) {
        return Err(
            "it is filled from a solid that is not a box, whose faces cut the lattice's cells"
                .into(),
        );
    }
    if real.iter().any(|&i| so.rigid[i]) {
        return Err("it has a rigid grip: a clamped or fully prescribed group without a mirror face; a clamp on a plane face takes boundaries[k].mirror".into());
    }
    // The lattice's own frame (its axes from the first particle's bonds of length l0) and
    // positions relative to that particle in it: the closure of a turned or moved body is the
    // same to round-off, and so are its volumes, masses and stable step.
    let frame = lattice_frame(bonds, real[0], l0).ok_or("its particles are not on a lattice")?;
    let xref = x0[real[0]];
    let loc = |i: usize| -> Vect<D> { frame.transpose() * (x0[i] - xref) };
    // Mirror planes (unit normal, a point on the plane) from the ghost-master pairs of this
    // body. The closure needs a lattice box, so the planes are normal to a lattice axis: the
    // normal is snapped to it.
    let mut planes: Vec<(Vect<D>, Vect<D>)> = Vec::new();
    for &i in &members {
        if let Some(g) = ghost_of.get(&(i as u32)) {
            let (xg, xm) = (loc(g.ghost as usize), loc(g.master as usize));
            let d = xg - xm;
            let a = d.iamax();
            if (d.norm() - d[a].abs()) > 1e-6 * d.norm() {
                return Err("a mirror face is not normal to an axis".into());
            }
            let mut nrm = Vect::<D>::zeros();
            nrm[a] = d[a].signum();
            let point = (xg + xm) * 0.5;
            if !planes
                .iter()
                .any(|(m, p)| *m == nrm && (p - point).dot(&nrm).abs() < 1e-6 * l0)
            {
                planes.push((nrm, point));
            }
        }
    }
    // The virtual body: the real particles and their images across every mirror plane.
    let mut vx: Vec<Vect<D>> = real.iter().map(|&i| loc(i)).collect();
    for (nrm, point) in &planes {
        for &i in &real {
            let x = loc(i);
            vx.push(x - nrm * (2.0 * nrm.dot(&(x - point))));
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
        || idx.iter().collect::<std::collections::HashSet<_>>().len() != nv
    {
        return Err("it is not a filled box (with its mirror images)".into());
    }
    if ext.iter().any(|&e| e < MIN_ACROSS) {
        return Err(format!("it is less than {MIN_ACROSS} particles across"));
    }
    // Where the virtual box's faces are (spacings beyond its outer particles, per axis and
    // side): half a spacing for a body of boxes; for a box solid, where its faces are, except
    // on a side beyond which the solid holds wall layers (a clamp: its face is half a spacing
    // out, where the followers hold it); across a mirror plane, where the mirrored face is.
    let mut delta = [[0.5f64; 2]; D];
    if let BodyFaces::Box(blo, bhi) = faces {
        let corner = |x: &Vect<D>| frame.transpose() * (x - xref);
        let (a0, a1) = (corner(&blo), corner(&bhi));
        let (slo, shi) = (a0.inf(&a1), a0.sup(&a1));
        let mut rlo = loc(real[0]);
        let mut rhi = rlo;
        for &i in &real {
            rlo = rlo.inf(&loc(i));
            rhi = rhi.sup(&loc(i));
        }
        let mut real_delta = [[0.5f64; 2]; D];
        for a in 0..D {
            for (side, dl) in [(rlo[a] - slo[a]) / l0, (shi[a] - rhi[a]) / l0]
                .into_iter()
                .enumerate()
            {
                if dl <= 0.0 {
                    return Err("a particle lies outside its solid's box (internal)".into());
                }
                // Beyond the next cell's centre the solid holds walls: a clamped face.
                real_delta[a][side] = if dl > 1.0 + 1e-6 { 0.5 } else { dl };
            }
        }
        for a in 0..D {
            let mirrored = |side: usize| {
                planes
                    .iter()
                    .any(|(n, _)| n[a] != 0.0 && (n[a] > 0.0) == (side == 1))
            };
            for side in 0..2 {
                delta[a][side] = match (mirrored(side), mirrored(1 - side)) {
                    (false, _) => real_delta[a][side],
                    (true, false) => real_delta[a][1 - side],
                    (true, true) => 0.5,
                };
            }
        }
    }
    let w1: Vec<Vec<f64>> = ext
        .iter()
        .zip(&delta)
        .map(|(&e, &dl)| weights_1d(e, dl))
        .collect::<Option<_>>()
        .ok_or("its faces cut its outer particles' cells more deeply than its layers can take")?;
    // The reduced box: along an axis longer than 2 REACH + 1 layers, the layers between the
    // first REACH and the last REACH are all alike (the same stencils, weights and targets),
    // so the problem is solved on a box of 2 REACH + 1 layers there, with the rows between
    // the first and last TIE layers tied to one correction (translation invariance), and the
    // result is copied back by layer class. Its conditioning no longer grows with the length.
    let small: [usize; D] = std::array::from_fn(|a| ext[a].min(2 * REACH + 1));
    let big_of = |a: usize, j: usize| -> usize {
        if small[a] == ext[a] || j < REACH {
            j
        } else if j + 1 + REACH > small[a] {
            ext[a] - (small[a] - j)
        } else {
            REACH
        }
    };
    let small_of = |a: usize, j: usize| -> usize {
        if small[a] == ext[a] || j < REACH {
            j
        } else if j + 1 + REACH > ext[a] {
            small[a] - (ext[a] - j)
        } else {
            REACH
        }
    };
    let full_idx = idx;
    let full_nv = nv;
    let mut idx: Vec<[usize; D]> = Vec::new();
    let mut sidx: Vec<[usize; D]> = Vec::new();
    {
        let mut k = [0usize; D];
        'cells: loop {
            sidx.push(k);
            idx.push(std::array::from_fn(|a| big_of(a, k[a])));
            let mut a = D;
            loop {
                if a == 0 {
                    break 'cells;
                }
                a -= 1;
                k[a] += 1;
                if k[a] < small[a] {
                    break;
                }
                k[a] = 0;
            }
        }
    }
    let nv = idx.len();
    // Positions relative to the box's first particle: the closure is translation invariant,
    // and the bonds' reference vectors then carry no round-off of a far-away origin.
    let vx: Vec<Vect<D>> = sidx
        .iter()
        .map(|k| Vect::<D>::from_fn(|a, _| k[a] as f64 * l0))
        .collect();
    // Rows tied by class: along the long axes the rows TIE..small-TIE share one class.
    let tie_key = |k: &[usize; D]| -> [usize; D] {
        std::array::from_fn(|a| {
            if small[a] < ext[a] && k[a] >= TIE && k[a] + TIE < small[a] {
                usize::MAX
            } else {
                k[a]
            }
        })
    };
    let mut classes: HashMap<[usize; D], u32> = HashMap::new();
    let tie: Vec<u32> = sidx
        .iter()
        .map(|k| {
            let key = tie_key(k);
            let nc = classes.len() as u32;
            *classes.entry(key).or_insert(nc)
        })
        .collect();
    let vol_unit = l0.powi(D as i32);
    let hv: Vec<f64> = idx
        .iter()
        .map(|k| vol_unit * (0..D).map(|a| w1[a][k[a]]).product::<f64>())
        .collect();
    // The virtual body's own fits (its particles see full stencils at the mirror planes).
    let vb = Bonds::build(&vx, &vec![0; nv], re_factor * l0);
    let mut vso = SecondOrder::<D>::new(&vb, l0, re_factor, nv, &vec![false; nv], &[], &[], &[]);
    if vso.quadratic.iter().any(|q| !q) {
        return Err("a particle's neighbourhood has no quadratic fit".into());
    }
    // Linear fields q_0 = 1, q_a = (x_a - c_a) / half_a.
    let mut centre = Vect::<D>::zeros();
    let mut half = Vect::<D>::zeros();
    for a in 0..D {
        half[a] = 0.5 * small[a] as f64 * l0;
        centre[a] = -0.5 * l0 + half[a];
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
    // The fits' exactness for quadratic fields to round-off: the pseudo-inverse of a corner's
    // moment matrix leaves ~1e-7 of a weight, enough to make the constraints of one axis
    // inconsistent at that level (the solve then stalls at a few 1e-6 of its target). One
    // least-norm correction per row inside its bonds' span fixes it.
    for (i, gram_inv) in row_gram.iter().enumerate() {
        for d in 0..D {
            let mut e = nalgebra::DVector::<f64>::zeros(m);
            for bnd in vb.of(i) {
                mono_of(bnd, &mut mono);
                for r in 0..m {
                    e[r] += vso.g[bnd][d] * l0 * mono[r];
                }
            }
            e[d] -= 1.0;
            let lam = gram_inv * e;
            for bnd in vb.of(i) {
                mono_of(bnd, &mut mono);
                let mut dv = 0.0;
                for r in 0..m {
                    dv += mono[r] * lam[r];
                }
                vso.g[bnd][d] -= dv / l0;
            }
        }
    }
    // Rows of one class must have the same bonds in the same order.
    {
        let mut first: HashMap<u32, usize> = HashMap::new();
        for (i, &t) in tie.iter().enumerate() {
            let f = *first.entry(t).or_insert(i);
            let (a, b) = (vb.of(f), vb.of(i));
            if a.len() != b.len()
                || a.zip(b)
                    .any(|(x, y)| (vb.r0[x] - vb.r0[y]).norm() > 1e-9 * l0)
            {
                return Err("rows of one class differ (internal)".into());
            }
        }
    }
    // Face points on clamped faces (particle of the reduced box, axis, side): their
    // extrapolation is the followers' constraint along the normal (FACE_EXTRAPOLATION on the
    // first three layers), so that the face term vanishes for every motion the clamp allows.
    let small_index: HashMap<[usize; D], usize> =
        sidx.iter().enumerate().map(|(i, k)| (*k, i)).collect();
    let mut clamped: std::collections::HashSet<(usize, usize, i8)> = Default::default();
    {
        let vi_of: HashMap<usize, usize> = real.iter().enumerate().map(|(v, &i)| (i, v)).collect();
        for fl in &so.followers {
            let Some(&vi) = vi_of.get(&(fl.particle as usize)) else {
                continue;
            };
            let out = loc(fl.particle as usize) - loc(fl.inner[0] as usize);
            let a = out.iamax();
            let k = full_idx[vi];
            let Some(&si) = small_index.get(&std::array::from_fn(|c| small_of(c, k[c]))) else {
                return Err("a follower has no layer class (internal)".into());
            };
            clamped.insert((si, a, out[a].signum() as i8));
        }
    }
    // The axes normal to a clamped face: their targets reach the operator's smoothest fields
    // (the clamp breaks the box's symmetry along them), which the coarse space serves.
    let clamped_axes: Vec<bool> = (0..D)
        .map(|d| clamped.iter().any(|&(_, a, _)| a == d))
        .collect();
    let tied = classes.len() < tie.len();
    let sys = NullSpaceConstraints::new(
        &vb,
        row_gram,
        l0,
        D + 1,
        tie,
        &vx,
        clamped_axes.iter().any(|&c| c),
        stop,
    );
    let nb = vb.len();
    let mut figures = Vec::new();
    let mut targets = Vec::with_capacity(D);
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
                dd[d] = side * delta[d][usize::from(side > 0.0)] * l0;
                let y = vx[i] + dd;
                let area: f64 = l0.powi(D as i32 - 1)
                    * (0..D)
                        .filter(|&a| a != d)
                        .map(|a| w1[a][k[a]])
                        .product::<f64>();
                if clamped.contains(&(i, d, side as i8)) {
                    let mut k1 = sidx[i];
                    for (step, r) in FACE_EXTRAPOLATION.iter().enumerate() {
                        k1[d] = if side < 0.0 {
                            sidx[i][d] + step
                        } else {
                            sidx[i][d] - step
                        };
                        let &j = small_index
                            .get(&k1)
                            .ok_or("a clamped face's column is short (internal)")?;
                        for q in 0..nq {
                            t[j * nq + q] += r * side * area * q_at(&y, q);
                        }
                    }
                    continue;
                }
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
        targets.push(t);
    }
    // The axes' solves are independent: side by side (each is a few thousand iterations of
    // small parallel passes, which keep fewer than two cores busy).
    // The Hessian weights of the virtual body served the targets only: freed before the
    // solves, the peak of the closure (issue 25).
    vso.h = Vec::new();
    // An axis whose target is another's under the swap of the two axes takes that axis's
    // corrections swapped (module `symmetry`), checked against its own constraints.
    // On a box solved whole every axis takes the coarse correction; on a reduced one the
    // clamped axes only. Axes alike under a swap share their work (module `symmetry`).
    let (solved, mapped) = symmetry::BoxAxes {
        small: &small,
        ext: &ext,
        sidx: &sidx,
        small_index: &small_index,
        nq,
    }
    .solve_axes(&sys, &vb, &targets, &|d| !tied || clamped_axes[d], stop);
    if solved.iter().any(|s| s.is_err()) {
        // The slowest axis says how long the closure still needs (they run side by side).
        let (d, u) = solved
            .iter()
            .enumerate()
            .filter_map(|(d, s)| s.as_ref().err().map(|u| (d, u)))
            .max_by(|a, b| a.1.more_seconds.total_cmp(&b.1.more_seconds))
            .expect("an interrupted axis");
        let why = format!(
            "the closure of body '{name}' was solving its constraints on a box of {small:?} \
             particles: axis {d} at conjugate-gradient iteration {} of at most {MAX_ITERATIONS}, \
             its residual {:.1e} times the one it stops at; at its pace it needed about {:.0} s \
             more",
            u.iterations, u.above_goal, u.more_seconds
        );
        out.interrupted = Some(why.clone());
        return Err(why);
    }
    let solved: Vec<_> = solved.into_iter().flatten().collect();
    let mut corr: Vec<Vect<D>> = vec![Vect::<D>::zeros(); nb];
    for (d, (t, (c, _, iters, res))) in targets.iter().zip(solved).enumerate() {
        let tnorm = t.iter().map(|v| v * v).sum::<f64>().sqrt();
        // (NaN fails it too.)
        if res.partial_cmp(&(ACCEPT * tnorm)) != Some(std::cmp::Ordering::Less) {
            return Err(format!(
                "the closure's constraints on axis {d} were not met (residual {:.1e} of {:.1e} after {iters} iterations)",
                res, tnorm
            ));
        }
        let gmax = vso.g.iter().map(|g| g.amax()).fold(0.0, f64::max);
        let mut cmax = 0.0f64;
        for (i, h) in hv.iter().enumerate() {
            for bnd in vb.of(i) {
                cmax = cmax.max((c[bnd] / h).abs());
            }
        }
        let how = match mapped[d] {
            Some(d1) => format!("axis {d1}'s corrections, its axes swapped"),
            None => format!("{iters} CG iterations"),
        };
        figures.push(format!(
            "axis {d}: {how}, residual {:.1e} of {:.1e}, largest correction {:.3} of the largest weight",
            res, tnorm, cmax / gmax
        ));
        for (i, h) in hv.iter().enumerate() {
            for bnd in vb.of(i) {
                corr[bnd][d] = c[bnd] / h;
            }
        }
    }
    // The solves' arrays are not needed for the copy-back: freed before its rows are made.
    drop(sys);
    // Back to the world's bonds of the real particles, by layer class: each particle's world
    // bonds looked up by lattice offset (a key on a quarter-spacing grid) among its class's
    // row, sorted for the particle at hand (a hash map of heap-allocated keys per particle
    // took 2.4 s of a 10^6-particle cube's set-up; maps kept per class raised the closure's
    // memory peak of a 15^3 cube, where every particle is a class of its own, by 1.2 %).
    let key = |r: &Vect<D>| -> [i64; D] { std::array::from_fn(|a| round(r[a] / l0 * 4.0) as i64) };
    // Each particle's row (with the largest correction of its class that has no bond of the
    // particle), computed in parallel a chunk at a time and interned in particle order: serially
    // this was 1.9 s of a 10^6-particle cube's set-up; a chunk's rows are under 1 MB.
    let row_of = |vi: usize, i: usize| -> Result<(Vec<f64>, f64), String> {
        let k = full_idx[vi];
        let Some(&si) = small_index.get(&std::array::from_fn(|a| small_of(a, k[a]))) else {
            return Err("a particle has no layer class (internal)".into());
        };
        let first = bonds.of(i).start;
        let mut row = vec![0.0; bonds.of(i).len() * D];
        let mut class_bonds: Vec<([i64; D], usize)> =
            vb.of(si).map(|bnd| (key(&vb.r0[bnd]), bnd)).collect();
        class_bonds.sort_unstable();
        let mut matched = vec![false; class_bonds.len()];
        for wb in bonds.of(i) {
            // The world's plain weight becomes the refined fit's plus the correction.
            let kw = key(&(frame.transpose() * bonds.r0[wb]));
            if let Ok(at) = class_bonds.binary_search_by(|(k, _)| k.cmp(&kw)) {
                matched[at] = true;
                let bnd = class_bonds[at].1;
                let c = frame * (vso.g[bnd] + corr[bnd]) - so.grad_weight(bonds, i, wb);
                row[(wb - first) * D..(wb - first + 1) * D].copy_from_slice(c.as_slice());
            }
        }
        // A correction of the class whose bond the particle does not have.
        let mut lost = 0.0f64;
        for (&(_, bnd), _) in class_bonds.iter().zip(&matched).filter(|(_, m)| !**m) {
            lost = lost.max(corr[bnd].amax());
        }
        Ok((row, lost))
    };
    // Each particle's row straight into `out.dg` (a list of the updates first would hold 32 B
    // per bond of the body, issue 25), and cleared again if a correction has no bond.
    const CHUNK: usize = 1024;
    let mut lost = 0.0f64;
    let order: Vec<(usize, usize)> = real.iter().copied().enumerate().collect();
    for chunk in order.chunks(CHUNK) {
        let rows = crate::physics::par::map(chunk, |&(vi, i)| row_of(vi, i));
        for (&(_, i), r) in chunk.iter().zip(rows) {
            let (row, l) = r?;
            lost = lost.max(l);
            out.dg.set(i, &row);
        }
    }
    if lost > 0.0 {
        for &i in &real {
            out.dg.class[i] = u32::MAX;
        }
        return Err(format!(
            "a correction of {lost:.2e} 1/m has no bond in the world"
        ));
    }
    for (vi, &i) in real.iter().enumerate() {
        let k = full_idx[vi];
        out.vol[i] = Some(vol_unit * (0..D).map(|a| w1[a][k[a]]).product::<f64>());
    }
    Ok(format!(
        "closed in {:.2} s, {} particles ({} with the mirror images, {:?} across, solved on {:?}); {}",
        clock.elapsed().as_secs_f64(),
        real.len(),
        full_nv,
        ext,
        small,
        figures.join("; ")
    ))
}

#[cfg(test)]
mod tests {
    use super::weights_1d;

    /// The end-corrected midpoint weights integrate x^0..x^3 exactly over [0, n] for every
    /// n >= 3 (the closure's compatibility needs quadratics in the volume and cubics on the
    /// faces); the plain midpoint rule misses x^2 by n / 12.
    #[test]
    fn end_corrected_weights_integrate_cubics() {
        for n in 3..20usize {
            let w = weights_1d(n, [0.5, 0.5]).unwrap();
            assert!(w.iter().all(|&v| v > 0.5), "n = {n}: {w:?}");
            for k in 0..4 {
                let sum: f64 = (0..n).map(|i| w[i] * (i as f64 + 0.5).powi(k)).sum();
                let exact = (n as f64).powi(k + 1) / (k + 1) as f64;
                assert!(
                    (sum - exact).abs() < 1e-12 * exact.max(1.0),
                    "n = {n}, x^{k}: {sum} vs {exact}"
                );
            }
        }
    }

    /// With faces that cut the outer cells (a box solid whose sides are not whole numbers of
    /// spacings: the face `delta` spacings beyond the outer particle, a quarter to three
    /// quarters on the lattice the fill centres), the weights still integrate x^0..x^3 exactly
    /// over the solid's interval, equal ends or not, and stay positive; at one half they are
    /// the end-corrected rule bit for bit.
    #[test]
    fn weights_with_cut_faces_integrate_cubics_over_the_solid() {
        for n in 4..20usize {
            for d0 in [0.25, 0.4, 0.5, 0.6, 0.75] {
                for d1 in [0.25, 0.5, 0.7, 0.75] {
                    let Some(w) = weights_1d(n, [d0, d1]) else {
                        // Only unequal ends on few layers may be refused (four moments on a
                        // side's layers).
                        assert!(n < 5 && d0 != d1, "n = {n}, {d0}, {d1} refused");
                        continue;
                    };
                    assert!(w.iter().all(|&v| v >= 0.25), "n = {n}, {d0}, {d1}: {w:?}");
                    let (a, b) = (-d0, n as f64 - 1.0 + d1);
                    for k in 0..4 {
                        let sum: f64 = (0..n).map(|i| w[i] * (i as f64).powi(k)).sum();
                        let exact = (b.powi(k + 1) - a.powi(k + 1)) / (k + 1) as f64;
                        assert!(
                            (sum - exact).abs() < 1e-11 * (n as f64).powi(k + 1),
                            "n = {n}, faces {d0} / {d1}, x^{k}: {sum} vs {exact}"
                        );
                    }
                }
            }
            assert_eq!(weights_1d(n, [0.5, 0.5]), {
                let mut w = vec![1.0; n];
                for (k, d) in super::END_CORRECTION.iter().enumerate() {
                    w[k] += d;
                    w[n - 1 - k] += d;
                }
                Some(w)
            });
        }
    }
}
