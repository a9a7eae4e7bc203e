//! Filling bodies with particles, shared by the World builder and the resolution warnings: the
//! lattice points of a body's boxes (cell centres at the particle spacing), or of a body with
//! shapes the lattice points inside its solid with the solid's volume, normal and area per
//! particle (module `shape`).
use super::shape::{to3, Geometry, Solid};
use super::{err, Scene, SceneError};
use crate::par_iter_mut;
#[allow(unused_imports)]
use crate::physics::par::*;
use crate::physics::world::ShapeFill;
use crate::physics::Vect;

/// The particles of body k of a validated scene: the cell centres of its boxes, a particle
/// closer than l0 / 4 to one of an earlier box dropped; and for each particle the index of the
/// box it comes from.
fn box_points<const D: usize>(
    scene: &Scene,
    k: usize,
) -> Result<(Vec<Vect<D>>, Vec<u32>), SceneError> {
    let dp = scene.particle_spacing;
    let b = &scene.bodies[k];
    let mut pts: Vec<Vect<D>> = Vec::new();
    let mut box_of: Vec<u32> = Vec::new();
    let cells: usize = b
        .boxes
        .iter()
        .filter_map(|r| scene.cell_counts(r, "").ok())
        .map(|n| n.iter().product::<usize>())
        .sum();
    let oom = |e: std::collections::TryReserveError| {
        err(
            format!("{}.boxes", super::body_field(k, b)),
            format!("cannot allocate the {cells} particles of the body: {e}"),
        )
    };
    pts.try_reserve_exact(cells).map_err(oom)?;
    box_of.try_reserve_exact(cells).map_err(oom)?;
    for (j, r) in b.boxes.iter().enumerate() {
        let n = scene.cell_counts(r, &format!("bodies[{k}].boxes[{j}]"))?;
        let first_new = pts.len();
        let grid = (j > 0).then(|| crate::physics::grid::CellGrid::build(&pts, None, dp));
        for code in 0..n.iter().product::<usize>() {
            let mut c = code;
            let mut p = Vect::<D>::zeros();
            for a in 0..D {
                p[a] = r.min[a] + ((c % n[a]) as f64 + 0.5) * dp;
                c /= n[a];
            }
            let mut taken = false;
            if let Some(g) = &grid {
                g.for_each_near(&pts[..first_new], &p, 0.25 * dp, |_| taken = true);
            }
            if !taken {
                pts.push(p);
                box_of.push(j as u32);
            }
        }
    }
    Ok((pts, box_of))
}

/// A body's particles with what a shaped body adds.
pub(crate) struct BodyFill<const D: usize> {
    /// Reference positions (m).
    pub points: Vec<Vect<D>>,
    /// Index of the box each particle comes from; `boxes.len()` for the lattice of a body with
    /// shapes.
    pub box_of: Vec<u32>,
    /// Of a body with shapes: per particle its volume (m^d), outward unit normal of the solid's
    /// surface it carries (zero inside) and that surface's area (m^(d-1), 0 inside).
    pub shape: Option<ShapeFill<D>>,
    /// Solid volume no particle took (m^d): slivers farther than two cells from every particle.
    pub lost_volume: f64,
}

/// Sub-cells per axis over which a cell cut by the surface is integrated (each with the
/// signed distance's linear ramp across it, exact for a plane along an axis and unbiased for
/// any plane): 8 in 2D, 6 in 3D.
fn subcells(d: usize) -> usize {
    if d == 2 {
        8
    } else {
        6
    }
}

/// The origin of the lattice of a body with shapes: `boxes[0].min`, so that a box fills
/// exactly as the box of a plain body. A solid that is one box given as shapes (`one_box`)
/// has its cells centred on it, per axis as many as come nearest to its extent: a side of a
/// whole number of spacings falls on the cell faces (it fills as the box body, and the
/// second-order operator's closure serves it), any other is cut alike at both ends, its faces
/// between a quarter and three quarters of a spacing beyond the outer particles (a symmetric
/// section stays symmetric; the closure takes the faces where they are). Other solids without
/// boxes: the origin. Cell centres are at origin + (i + 1/2) l0.
pub(crate) fn lattice_origin(scene: &Scene, b: &super::Body, g: &Geometry, d: usize) -> [f64; 3] {
    if let Some(r) = b.boxes.first() {
        return to3(&r.min);
    }
    let Some((lo, hi)) = one_box(g, d) else {
        return [0.0; 3];
    };
    let dp = scene.particle_spacing;
    let mut o = [0.0; 3];
    for k in 0..d {
        let cells = (hi[k] - lo[k]) / dp;
        let whole = cells.round();
        let left = if (cells - whole).abs() <= 1e-9 * cells.max(1.0) {
            0.0
        } else {
            cells - whole
        };
        o[k] = lo[k] + 0.5 * left * dp;
    }
    o
}

/// The lattice of a body with shapes: first cell index and cells per axis over the bounds of
/// its solid (one cell of margin), on the lattice of `lattice_origin`.
pub(crate) fn lattice_range(
    scene: &Scene,
    b: &super::Body,
    g: &Geometry,
    d: usize,
) -> Option<([i64; 3], [usize; 3])> {
    let dp = scene.particle_spacing;
    let o = lattice_origin(scene, b, g, d);
    let (lo, hi) = g.bounds();
    let mut first = [0i64; 3];
    let mut n = [1usize; 3];
    for k in 0..d {
        if !(lo[k].is_finite() && hi[k].is_finite()) {
            return None;
        }
        let a = ((lo[k] - o[k]) / dp).floor() - 1.0;
        let z = ((hi[k] - o[k]) / dp).ceil() + 1.0;
        if z - a > 1e7 {
            return None;
        }
        first[k] = a as i64;
        n[k] = (z - a) as usize;
    }
    Some((first, n))
}

/// A cell the surface may cross: the solid's volume fraction, its centroid (m), the vector
/// area of the surface in it (m^(d-1)) and the second moment of the solid in it about the
/// cell's centre, per unit cell volume (m^2).
type CutCell = (f64, [f64; 3], [f64; 3], [[f64; 3]; 3]);

/// Second moment of a whole cell about its centre per unit volume (m^2): l0^2 / 12 on the
/// diagonal.
fn whole_cell_moment(dp: f64, d: usize) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (a, row) in m.iter_mut().enumerate().take(d) {
        row[a] = dp * dp / 12.0;
    }
    m
}

/// Per boundary cell: the solid's volume in it (fraction of l0^d), its centroid and the vector
/// area of the solid's surface in it (-sum over the cell's faces of their outward normal times
/// the part of the face inside the solid: the divergence theorem on solid and cell).
fn cut_cell(g: &Geometry, c: [f64; 3], dp: f64, d: usize) -> CutCell {
    let k = subcells(d);
    let h = dp / k as f64;
    let ramp = |p: [f64; 3]| (0.5 - g.distance(p) / h).clamp(0.0, 1.0);
    let at = |idx: [usize; 3]| -> [f64; 3] {
        let mut p = c;
        for a in 0..d {
            p[a] = c[a] - 0.5 * dp + (idx[a] as f64 + 0.5) * h;
        }
        p
    };
    let total = k.pow(d as u32);
    let mut frac = 0.0;
    let mut cen = [0.0; 3];
    // About the cell's centre: each sub-cell's own h^2 / 12 and its centre's offset.
    let mut m2 = [[0.0; 3]; 3];
    for code in 0..total {
        let mut idx = [0usize; 3];
        let mut r = code;
        for slot in idx.iter_mut().take(d) {
            *slot = r % k;
            r /= k;
        }
        let p = at(idx);
        let f = ramp(p);
        frac += f;
        for a in 0..d {
            cen[a] += f * p[a];
            for b in 0..d {
                m2[a][b] += f * (p[a] - c[a]) * (p[b] - c[b]);
            }
            m2[a][a] += f * h * h / 12.0;
        }
    }
    if frac > 0.0 {
        for v in cen.iter_mut().take(d) {
            *v /= frac;
        }
    } else {
        cen = c;
    }
    let face_total = k.pow(d as u32 - 1);
    let mut area = [0.0; 3];
    for a in 0..d {
        for side in [-1.0f64, 1.0] {
            let mut inside = 0.0;
            for code in 0..face_total {
                let mut idx = [0usize; 3];
                let mut r = code;
                for (b, slot) in idx.iter_mut().enumerate().take(d) {
                    if b != a {
                        *slot = r % k;
                        r /= k;
                    }
                }
                let mut p = at(idx);
                p[a] = c[a] + side * 0.5 * dp;
                inside += ramp(p);
            }
            area[a] -= side * inside / face_total as f64 * dp.powi(d as i32 - 1);
        }
    }
    // Rounding of the sub-cell sums: a cell within 1e-9 of whole or empty is whole or empty, so
    // a face on the lattice's cell faces fills exactly as a box.
    let frac = match frac / total as f64 {
        f if f > 1.0 - 1e-9 => 1.0,
        f if f < 1e-9 => 0.0,
        f => f,
    };
    let m2 = if frac == 1.0 {
        cen = c;
        whole_cell_moment(dp, d)
    } else {
        m2.map(|row| row.map(|v| v / total as f64))
    };
    (frac, cen, area, m2)
}

/// The solid's bounds when it is one axis-aligned box: its parts are boxes, nothing is cut,
/// and they cover their bounds (every cell of the grid of their faces' coordinates lies in
/// one of them).
pub(crate) fn one_box(g: &Geometry, d: usize) -> Option<([f64; 3], [f64; 3])> {
    if !g.cuts.is_empty() {
        return None;
    }
    let boxes: Vec<([f64; 3], [f64; 3])> = g
        .parts
        .iter()
        .map(|s| match s {
            Solid::Box { min, max, .. } => Some((*min, *max)),
            _ => None,
        })
        .collect::<Option<_>>()?;
    if boxes.is_empty() || boxes.len() > 64 {
        return None;
    }
    let (lo, hi) = g.bounds();
    let cuts: Vec<Vec<f64>> = (0..d)
        .map(|a| {
            let mut c: Vec<f64> = boxes.iter().flat_map(|(l, h)| [l[a], h[a]]).collect();
            c.sort_by(f64::total_cmp);
            c.dedup();
            c
        })
        .collect();
    let cells: usize = cuts.iter().map(|c| c.len() - 1).product();
    for code in 0..cells {
        let mut c = code;
        let mut p = [0.0; 3];
        for a in 0..d {
            let n = cuts[a].len() - 1;
            let j = c % n;
            c /= n;
            p[a] = 0.5 * (cuts[a][j] + cuts[a][j + 1]);
        }
        if !boxes
            .iter()
            .any(|(l, h)| (0..d).all(|a| p[a] > l[a] && p[a] < h[a]))
        {
            return None;
        }
    }
    Some((lo, hi))
}

/// The particles of body k of a validated scene that has shapes or cuts (see `Body`).
fn shaped_points<const D: usize>(scene: &Scene, k: usize) -> Result<BodyFill<D>, SceneError> {
    let b = &scene.bodies[k];
    let bf = super::body_field(k, b);
    let dp = scene.particle_spacing;
    let g = scene.geometry(b)?;
    let (first, n) = lattice_range(scene, b, &g, D).ok_or_else(|| {
        err(
            format!("{bf}.shapes"),
            "the body's solid is unbounded or spans more than 1e7 particles along an axis",
        )
    })?;
    let o = lattice_origin(scene, b, &g, D);
    let cells: usize = n.iter().take(D).product();
    let centre = |code: usize| -> [f64; 3] {
        let mut p = [0.0; 3];
        let mut c = code;
        for a in 0..D {
            p[a] = o[a] + ((first[a] + (c % n[a]) as i64) as f64 + 0.5) * dp;
            c /= n[a];
        }
        p
    };
    let half_diagonal = 0.5 * dp * (D as f64).sqrt() * (1.0 + 1e-9);
    // Pass 1: classify the cells by the distance of their centres.
    let mut dist = Vec::new();
    dist.try_reserve_exact(cells).map_err(|e| {
        err(
            format!("{bf}.shapes"),
            format!("cannot allocate the {cells} lattice cells of the body: {e}"),
        )
    })?;
    dist.extend((0..cells).map(|c| g.distance(centre(c))));
    // Pass 2: integrate the cells the surface may cross (in parallel: each writes its own).
    let mut cut: Vec<(usize, CutCell)> = (0..cells)
        .filter(|&c| dist[c].abs() < half_diagonal)
        .map(|c| (c, (0.0, [0.0; 3], [0.0; 3], [[0.0; 3]; 3])))
        .collect();
    par_iter_mut!(cut).for_each(|(c, out)| *out = cut_cell(&g, centre(*c), dp, D));
    let full = dp.powi(D as i32);
    // Particles: the centres inside, in cell order.
    let mut slot = vec![u32::MAX; cells];
    let mut points = Vec::new();
    let mut volumes = Vec::new();
    let mut areas: Vec<[f64; 3]> = Vec::new();
    // Per particle the surface area of its cells: the sum of the lengths of their vector areas
    // (the length of the summed vector would lose the patch's curvature, ~2 % on a sphere of
    // 10 across).
    let mut scalar: Vec<f64> = Vec::new();
    let mut depths: Vec<f64> = Vec::new();
    // Per particle the first and second moments of its solid about its centre (m^(d+1),
    // m^(d+2)).
    let mut first_moments: Vec<[f64; 3]> = Vec::new();
    let mut second_moments: Vec<[[f64; 3]; 3]> = Vec::new();
    let whole = whole_cell_moment(dp, D).map(|row| row.map(|v| v * full));
    let len = |a: &[f64; 3]| (0..D).map(|k| a[k] * a[k]).sum::<f64>().sqrt();
    let mut cut_at = 0usize;
    let mut orphans = Vec::new();
    for c in 0..cells {
        let boundary = cut_at < cut.len() && cut[cut_at].0 == c;
        let cell = if boundary {
            cut_at += 1;
            Some(cut[cut_at - 1].1)
        } else {
            None
        };
        if dist[c] < 0.0 {
            slot[c] = points.len() as u32;
            let p = centre(c);
            points.push(Vect::<D>::from_fn(|a, _| p[a]));
            depths.push(-dist[c]);
            match cell {
                Some((f, cen, area, m2)) => {
                    volumes.push(f * full);
                    areas.push(area);
                    scalar.push(len(&area));
                    first_moments.push(std::array::from_fn(|a| f * full * (cen[a] - p[a])));
                    second_moments.push(m2.map(|row| row.map(|v| v * full)));
                }
                None => {
                    volumes.push(full);
                    areas.push([0.0; 3]);
                    scalar.push(0.0);
                    first_moments.push([0.0; 3]);
                    second_moments.push(whole);
                }
            }
        } else if let Some((f, cen, area, m2)) = cell {
            // A cell whose solid is below the sub-cells' resolution may still hold surface
            // (the solid touches its faces: half of a face on the lattice's cell faces, ~1.5 %
            // of a sphere's area at 10 across); it goes with the solid to the nearest particle.
            if f > 0.0 || len(&area) > 1e-9 * dp.powi(D as i32 - 1) {
                orphans.push((c, f, cen, area, m2));
            }
        }
    }
    // The solid in cells whose centres are outside goes to the nearest particle within two
    // cells of it, so that the particles' volumes add up to the solid's.
    let mut lost = 0.0;
    for (c, f, cen, area, m2) in orphans {
        let mut idx = [0i64; 3];
        let mut r = c;
        for a in 0..D {
            idx[a] = (r % n[a]) as i64;
            r /= n[a];
        }
        let mut best: Option<(f64, u32)> = None;
        let reach: i64 = 2;
        let span = (2 * reach + 1).pow(D as u32);
        for code in 0..span {
            let mut q = idx;
            let mut r = code;
            let mut ok = true;
            let mut lin = 0usize;
            let mut stride = 1usize;
            for a in 0..D {
                q[a] += r % (2 * reach + 1) - reach;
                r /= 2 * reach + 1;
                if q[a] < 0 || q[a] >= n[a] as i64 {
                    ok = false;
                    break;
                }
                lin += q[a] as usize * stride;
                stride *= n[a];
            }
            if !ok || slot[lin] == u32::MAX {
                continue;
            }
            let i = slot[lin];
            let p = &points[i as usize];
            let d2: f64 = (0..D).map(|a| (p[a] - cen[a]).powi(2)).sum();
            if best.is_none_or(|(bd, bi)| d2 < bd || (d2 == bd && i < bi)) {
                best = Some((d2, i));
            }
        }
        match best {
            Some((_, i)) => {
                // Its moments about the particle's centre x: the cell's about its own centre
                // o shifted by d = o - x (M1 += V (cen - x); M2 += M2_o + M1_o d^T + d M1_o^T
                // + V d d^T, M1_o = V (cen - o)).
                let o = centre(c);
                let x = &points[i as usize];
                let v = f * full;
                let dd: [f64; 3] = std::array::from_fn(|a| if a < D { o[a] - x[a] } else { 0.0 });
                let m1o: [f64; 3] = std::array::from_fn(|a| v * (cen[a] - o[a]));
                let k = i as usize;
                for a in 0..D {
                    first_moments[k][a] += v * (cen[a] - x[a]);
                    for b in 0..D {
                        second_moments[k][a][b] +=
                            m2[a][b] * full + m1o[a] * dd[b] + dd[a] * m1o[b] + v * dd[a] * dd[b];
                    }
                }
                volumes[i as usize] += f * full;
                for a in 0..D {
                    areas[i as usize][a] += area[a];
                }
                scalar[i as usize] += len(&area);
            }
            None => lost += f * full,
        }
    }
    if points.is_empty() {
        let what = if b.cuts.is_empty() {
            format!("{bf}.shapes")
        } else {
            format!("{bf}.cuts")
        };
        return Err(err(
            what,
            if b.cuts.is_empty() {
                format!(
                    "the body's solid holds no particle centre (particle_spacing = {} m): it is smaller than one particle, or thinner than one between lattice points",
                    super::limits::num(dp)
                )
            } else {
                "the cuts remove the whole body: no particle centre is left inside it".to_string()
            },
        ));
    }
    let normals = areas
        .iter()
        .map(|a| {
            let m = (0..D).map(|k| a[k] * a[k]).sum::<f64>().sqrt();
            if m > 1e-9 * dp.powi(D as i32 - 1) {
                Vect::<D>::from_fn(|k, _| a[k] / m)
            } else {
                Vect::<D>::zeros()
            }
        })
        .collect::<Vec<_>>();
    let area = scalar
        .iter()
        .zip(&normals)
        .map(|(a, nrm)| if nrm.norm() > 0.0 { *a } else { 0.0 })
        .collect();
    let count = points.len();
    let solid_box = one_box(&g, D).map(|(lo, hi)| {
        (
            Vect::<D>::from_fn(|a, _| lo[a]),
            Vect::<D>::from_fn(|a, _| hi[a]),
        )
    });
    Ok(BodyFill {
        points,
        box_of: vec![b.boxes.len() as u32; count],
        shape: Some(ShapeFill {
            solid_box,
            volumes,
            normals,
            areas: area,
            depths,
            moments: first_moments
                .iter()
                .zip(&second_moments)
                .map(|(m1, m2)| {
                    (
                        Vect::<D>::from_fn(|a, _| m1[a]),
                        crate::physics::Mat::<D>::from_fn(|a, b| m2[a][b]),
                    )
                })
                .collect(),
        }),
        lost_volume: lost,
    })
}

/// The particles of body k of a validated scene: boxes as `box_points`, shapes as
/// `shaped_points`.
pub(crate) fn body_fill<const D: usize>(
    scene: &Scene,
    k: usize,
) -> Result<BodyFill<D>, SceneError> {
    let b = &scene.bodies[k];
    if b.shapes.is_empty() && b.cuts.is_empty() {
        let (points, box_of) = box_points::<D>(scene, k)?;
        return Ok(BodyFill {
            points,
            box_of,
            shape: None,
            lost_volume: 0.0,
        });
    }
    shaped_points::<D>(scene, k)
}
