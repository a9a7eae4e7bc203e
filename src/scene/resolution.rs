//! Warnings of under-resolved geometry, from the particles a scene creates (before any World is
//! built, so the FMU can report them at fmi2Instantiate):
//!
//! * a box of a body whose particles have all their neighbours within re in one plane or on
//!   one line: the body is a single layer (column) of particles there, with no stiffness
//!   across it (the shape tensor is singular and only its pseudo-inverse exists);
//! * a body in which no particle has the full neighbourhood of an interior particle: it is
//!   nowhere thicker than 2 m particles (m = the lattice layers within re, 2 at re = 2.1 l0),
//!   so every particle is near a surface and the operators' surface error governs the whole
//!   body.
use super::fill::body_fill;
use super::limits::num;
use super::{body_field, Scene};
use crate::physics::bonds::is_bond;
use crate::physics::dim::{sym_eigen, Mat};
use crate::physics::grid::CellGrid;
use crate::physics::{Dim, ElasticModel, Space, Vect};

/// A problem of a scene that does not stop it from running: which field and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct SceneWarning {
    pub field: String,
    pub message: String,
}

impl std::fmt::Display for SceneWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "scene warning in {}: {}", self.field, self.message)
    }
}

/// Lattice layers within re on each side of a particle: the largest m with w(m l0) > 0.
fn layers(re_factor: f64) -> usize {
    (1..)
        .take_while(|&m| is_bond(m as f64, re_factor))
        .last()
        .unwrap_or(0)
}

/// Bonds of a particle with a full neighbourhood on the lattice (counted as the bonds are:
/// positive weight).
fn full_neighbourhood<const D: usize>(re_factor: f64) -> usize {
    crate::physics::bonds::lattice_distances(D, 1.0, re_factor).len()
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// How many particles thick a body is where it is thickest, and along which axis: for each
/// particle on the lattice of the first one (its first box's; a grip block half a spacing off
/// is left out), the shortest of its runs of lattice neighbours along the axes (each counted up
/// to `cap`); the largest of those. A bounding extent would count a clamp block wider than the
/// beam it holds, and the most common run the short chords at a round body's rim.
fn thickness<const D: usize>(pts: &[Vect<D>], dp: f64, cap: usize) -> (usize, usize)
where
    Space: Dim<D>,
{
    let o = pts[0];
    let at = |p: &Vect<D>| -> Option<[i64; D]> {
        let f: [f64; D] = std::array::from_fn(|a| (p[a] - o[a]) / dp);
        f.iter()
            .all(|x| (x - x.round()).abs() < 1e-6)
            .then(|| std::array::from_fn(|a| f[a].round() as i64))
    };
    let cells: std::collections::HashSet<[i64; D]> = pts.iter().filter_map(at).collect();
    let mut thickest = (0, 1);
    for k in &cells {
        let run = |a: usize| {
            let mut n = 1;
            for dir in [-1i64, 1] {
                let mut q = *k;
                loop {
                    q[a] += dir;
                    if n >= cap || !cells.contains(&q) {
                        break;
                    }
                    n += 1;
                }
            }
            n
        };
        let (axis, n) = (0..D)
            .map(|a| (a, run(a)))
            .min_by_key(|&(_, n)| n)
            .expect("D >= 2");
        if n > thickest.1 {
            thickest = (axis, n);
        }
    }
    thickest
}

/// Bending errors of a cantilever only a few particles thick, where no particle has a full
/// neighbourhood (at re = 2.1 dp): (operator, dimension, particles through, static tip
/// deflection error %, first frequency error %) against the converged FEM references
/// (reference/cantilever3d_fem.json, reference/plate2d_fem.json), from `mps study bending 3d 2 3
/// 4` and `mps study bending 2d 2 3 4` (linearised; the corrected operator at its default
/// stabilisation 0.5); checked by `tests/suite/scene_validation.rs`. The default operator
/// closes the faces of a box 3 or more particles across (`sbp::MIN_ACROSS`): -0.15 % (3D) and
/// -0.45 % (2D) in static deflection at 3 through, within 0.11 % at 4, so it is not warned of.
pub const THIN_BENDING_ERRORS: [(ElasticModel, usize, usize, f64, f64); 8] = [
    (ElasticModel::SecondOrder, 3, 2, 94.4, -28.3),
    (ElasticModel::SecondOrder, 2, 2, 23.5, -10.1),
    (ElasticModel::Corrected, 3, 2, 12.7, -5.7),
    (ElasticModel::Corrected, 3, 3, 17.5, -7.7),
    (ElasticModel::Corrected, 3, 4, 10.7, -4.9),
    (ElasticModel::Corrected, 2, 2, -26.9, 17.0),
    (ElasticModel::Corrected, 2, 3, 11.3, -5.2),
    (ElasticModel::Corrected, 2, 4, 7.0, -3.3),
];

/// The warning on a body nowhere thicker than `needed - 1` particles (`n` along `axis` where
/// it is thickest, [`thickness`]), in the terms of the scene's operator: the measured effect on a cantilever of its
/// thickness where there is one (`THIN_BENDING_ERRORS`), and the remedy. None for the default
/// operator on a body it closes (`n` at least `sbp::MIN_ACROSS`): its faces are then second
/// order, and a body of several boxes it cannot close has its own warning after the build (a
/// body filled from shapes, one of its shapes).
fn thin_body_message(
    scene: &Scene,
    d: usize,
    n: usize,
    axis: &str,
    full: usize,
    needed: usize,
) -> Option<String> {
    let model = scene.solver.model;
    let closes = crate::physics::sbp::MIN_ACROSS;
    let second_order = model == ElasticModel::SecondOrder;
    if second_order && n >= closes {
        return None;
    }
    let dp = scene.particle_spacing;
    let rf = scene.solver.re_factor;
    let measured = (rf == 2.1 && (second_order || scene.solver.stabilisation == 0.5))
        .then(|| {
            THIN_BENDING_ERRORS
                .iter()
                .find(|e| e.0 == model && e.1 == d && e.2 == n)
        })
        .flatten();
    let effect = match measured {
        Some(&(_, _, _, tip, f1)) => format!(
            ": measured on a cantilever {n} particles thick ({d}D), its static deflection {:.1} % \
             too {} and its first frequency {:.1} % too {}",
            tip.abs(),
            if tip > 0.0 { "large" } else { "small" },
            f1.abs(),
            if f1 > 0.0 { "high" } else { "low" }
        ),
        None => String::new(),
    };
    // The thickness the remedy asks for: the closure's for the default operator, a full
    // neighbourhood for the others.
    let want = if second_order { closes } else { needed };
    // Six significant digits: the thickness over n is often a float hair below the round
    // number it means.
    let dp_max = num(format!("{:.5e}", n as f64 * dp / want as f64)
        .parse()
        .unwrap_or(dp));
    let (why, remedy) = if second_order {
        (
            format!(
                "too thin for the default operator to close its faces (it needs {closes} \
                 particles across), so every particle is near a surface, where it is least \
                 accurate"
            ),
            String::new(),
        )
    } else {
        (
            format!(
                "so every particle is near a surface, where the {} operator is least accurate",
                model.name()
            ),
            format!(
                ", or use the default operator (solver.model second_order), which closes the \
                 faces of a box at least {closes} particles across (a cantilever {closes} \
                 particles thick then within 0.5 %)"
            ),
        )
    };
    Some(format!(
        "no particle has the full neighbourhood of an interior particle ({full} neighbours \
         within re = {} dp): the body is nowhere more than {} particles thick (along {axis} it \
         spans {n} particles), {why}{effect}; refine particle_spacing (now {} m) so that at \
         least {want} particles span it (dp <= {dp_max} m){remedy}",
        num(rf),
        needed - 1,
        num(dp),
    ))
}

/// The warnings of body k whose particles are `pts`, `box_of` the box each comes from.
pub(crate) fn body_warnings<const D: usize>(
    scene: &Scene,
    k: usize,
    pts: &[Vect<D>],
    box_of: &[u32],
) -> Vec<SceneWarning>
where
    Space: Dim<D>,
{
    let body = &scene.bodies[k];
    let bf = body_field(k, body);
    let dp = scene.particle_spacing;
    let rf = scene.solver.re_factor;
    let re = rf * dp;
    let grid = CellGrid::build(pts, None, re);
    let full = full_neighbourhood::<D>(rf);
    let m = layers(rf);
    let needed = 2 * m + 1;
    // Per box (and the lattice of the shapes, last): particles with a singular neighbourhood,
    // and the directions it lacks.
    let shaped = !body.shapes.is_empty() || !body.cuts.is_empty();
    let nb = body.boxes.len() + usize::from(shaped);
    let mut flat = vec![0usize; nb];
    let mut isolated = vec![0usize; nb];
    let mut missing = vec![[false; 3]; nb];
    let mut oblique = vec![false; nb];
    let mut rank_of = vec![D; nb];
    let mut any_full = false;
    let mut any_flat = 0usize;
    // Per particle, in parallel: its bond count and the eigenpairs of its shape tensor where
    // that is singular (the directions it lacks); tallied per box in particle order.
    // A full neighbourhood is every lattice offset within re: neighbours off the particle's
    // lattice (a grip block half a spacing off the beam it holds) do not make one, however
    // many bonds they add.
    let on_lattice = |r: &Vect<D>| (0..D).all(|a| ((r[a] / dp) - (r[a] / dp).round()).abs() < 1e-6);
    let per_particle = crate::physics::par::map(pts, |p| {
        let mut count = 0usize;
        let mut lattice = 0usize;
        let mut shape = Mat::<D>::zeros();
        grid.for_each_near(pts, p, re, |j| {
            let r = pts[j as usize] - p;
            if is_bond(r.norm(), re) {
                count += 1;
                lattice += usize::from(on_lattice(&r));
                shape += r * r.transpose() / r.norm_squared();
            }
        });
        if count == 0 {
            return (count, lattice, None);
        }
        let (vals, vecs) = sym_eigen(&shape);
        let top = vals.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let weak: Vec<usize> = (0..D).filter(|&e| vals[e].abs() <= 1e-10 * top).collect();
        if weak.is_empty() {
            return (count, lattice, None);
        }
        // Per weak direction: the axis it lies along, if any.
        let dirs: Vec<Option<usize>> = weak
            .iter()
            .map(|&e| {
                let dir = vecs.column(e);
                (0..D).find(|&a| dir[a].abs() > 1.0 - 1e-6)
            })
            .collect();
        (count, lattice, Some(dirs))
    });
    for (i, (count, lattice, weak)) in per_particle.into_iter().enumerate() {
        any_full |= lattice >= full;
        let bx = box_of[i] as usize;
        if count == 0 {
            isolated[bx] += 1;
            any_flat += 1;
            continue;
        }
        let Some(dirs) = weak else {
            continue;
        };
        flat[bx] += 1;
        any_flat += 1;
        rank_of[bx] = rank_of[bx].min(D - dirs.len());
        for d in dirs {
            match d {
                Some(a) => missing[bx][a] = true,
                None => oblique[bx] = true,
            }
        }
    }
    let mut out = Vec::new();
    let advice = |thickness: Option<f64>| match thickness {
        Some(t) if t > 0.0 => format!(
            "refine particle_spacing (now {} m) so that at least {needed} particles span it \
             (dp <= {} m)",
            num(dp),
            // Six significant digits: the thickness over n is often a float hair below the
            // round number it means.
            num(format!("{:.5e}", t / needed as f64).parse().unwrap_or(t))
        ),
        _ => format!(
            "refine particle_spacing (now {} m) so that at least {needed} particles span the \
             thinnest part",
            num(dp)
        ),
    };
    for j in 0..nb {
        let in_box = box_of.iter().filter(|&&b| b as usize == j).count();
        let field = if j < body.boxes.len() {
            format!("{bf}.boxes[{j}]")
        } else {
            format!("{bf}.shapes")
        };
        let r = body.boxes.get(j);
        if flat[j] > 0 {
            let axes: Vec<usize> = (0..D).filter(|&a| missing[j][a]).collect();
            let names: Vec<&str> = axes.iter().map(|&a| AXES[a]).collect();
            let (lie, what) = if rank_of[j] == 2 {
                ("in one plane", "a single layer of particles")
            } else if D == 2 {
                ("on one line", "a single row of particles")
            } else {
                ("on one line", "a single column of particles")
            };
            let across = if names.is_empty() || oblique[j] {
                String::new()
            } else {
                format!(" (one particle thick along {})", names.join(" and "))
            };
            // The box's side across the layer (dp for a box one cell thick).
            let thickness = r.and_then(|r| {
                axes.iter()
                    .map(|&a| r.max[a] - r.min[a])
                    .fold(None, |t: Option<f64>, x| Some(t.map_or(x, |t| t.min(x))))
            });
            out.push(SceneWarning {
                field: field.clone(),
                message: format!(
                    "{} of its {in_box} particles have all their neighbours within re = {} dp \
                     {lie}: the body is {what}{across} there, whose shape tensor is singular, so \
                     the particle operators have no stiffness across it; {}",
                    flat[j],
                    num(rf),
                    advice(thickness)
                ),
            });
        }
        if isolated[j] > 0 {
            out.push(SceneWarning {
                field,
                message: format!(
                    "{} of its {in_box} particles have no neighbour within re = {} dp: they are \
                     bonded to nothing and move freely; refine particle_spacing (now {} m) or \
                     make the box touch the rest of the body",
                    isolated[j],
                    num(rf),
                    num(dp)
                ),
            });
        }
    }
    if !any_full && any_flat < pts.len() && !pts.is_empty() {
        let (axis, n) = thickness(pts, dp, needed);
        if let Some(message) = thin_body_message(scene, D, n, AXES[axis], full, needed) {
            out.push(SceneWarning { field: bf, message });
        }
    }
    out
}

/// The warnings of body k's shapes: meshes turned round, solid no particle took (`lost`, m^d),
/// and the reduced accuracy of the second-order operator at a solid's faces (`volumes`: the
/// particle volumes of a body filled from shapes).
pub(crate) fn shape_warnings(
    scene: &Scene,
    k: usize,
    volumes: Option<&[f64]>,
    one_box: bool,
    lost: f64,
) -> Vec<SceneWarning> {
    let b = &scene.bodies[k];
    let bf = body_field(k, b);
    let d = scene.dimension;
    let dp = scene.particle_spacing;
    let base = scene.base_dir.as_deref();
    let mut out = Vec::new();
    for (j, s) in b.shapes.iter().enumerate() {
        if let Ok(w) = super::shape::check(&format!("{bf}.shapes[{j}]"), s, d, dp, true, base) {
            out.extend(w);
        }
    }
    for (j, s) in b.cuts.iter().enumerate() {
        if let Ok(w) = super::shape::check(&format!("{bf}.cuts[{j}]"), s, d, dp, false, base) {
            out.extend(w);
        }
    }
    out.extend(region_face_warnings(scene, k));
    let Some(vol) = volumes else {
        return out;
    };
    let total: f64 = vol.iter().sum();
    if lost > 1e-6 * total {
        out.push(SceneWarning {
            field: format!("{bf}.shapes"),
            message: format!(
                "{} m^{d} of the solid ({:.2e} of it) lies more than two cells from every particle centre (slivers thinner than a particle) and is left out of the particles' volumes; refine particle_spacing (now {} m)",
                num(lost),
                lost / (total + lost),
                num(dp)
            ),
        });
    }
    // A solid that is one box (its sides any length) is closed like a body of boxes (module
    // `physics::sbp`); where its closure fails, the World's build says why.
    if scene.solver.model == crate::physics::ElasticModel::SecondOrder && !one_box {
        out.push(SceneWarning {
            field: bf.clone(),
            message: format!(
                "body '{}' is filled from shapes: next to its curved or cut faces its stresses are computed less accurately than in a body of boxes, so its stiffness may be off by up to about 1 % (measured on a round cantilever 4, 6 and 8 particles across: within 0.25 %; a plate with a round hole 6 particles across its ligament: end displacement 0.75 % too large); more particles across the body reduce it (particle_spacing is now {} m)",
                b.name,
                num(dp)
            ),
        });
    }
    out
}

/// Boundary groups of body k (a body with shapes, whose lattice is its own) whose region has a
/// face across the body that is not on the lattice's cell faces: the group holds the particles
/// whose centres are on its side, so its face is on the nearest cell face, up to half a spacing
/// from where the region puts it (a clamp there lengthens or shortens the body by that much).
fn region_face_warnings(scene: &Scene, k: usize) -> Vec<SceneWarning> {
    let b = &scene.bodies[k];
    let d = scene.dimension;
    let dp = scene.particle_spacing;
    let Ok(g) = scene.geometry(b) else {
        return Vec::new();
    };
    let (lo, hi) = g.bounds();
    let o = super::fill::lattice_origin(scene, b, &g, d);
    // Only a box solid's centred lattice puts its cell faces off whole spacings from the
    // body's ends, where a user writes region faces: along an axis it spans a whole number of
    // spacings of, the cell faces are at whole spacings from its ends as on a box body's
    // lattice (a region written with a margin inside a cell is the usual idiom there).
    if !(b.boxes.is_empty() && super::fill::one_box(&g, d).is_some()) {
        return Vec::new();
    }
    let mut out = Vec::new();
    for (gi, group) in scene.boundaries.iter().enumerate() {
        if group.body != b.name || group.shape.is_some() {
            continue;
        }
        let r = &group.region;
        let off = (0..d).find_map(|a| {
            let cells = (hi[a] - lo[a]) / dp;
            if (cells - cells.round()).abs() <= 1e-9 * cells.max(1.0) {
                return None;
            }
            [r.min[a], r.max[a]].into_iter().find_map(|c| {
                let inside = c > lo[a] + 0.5 * dp && c < hi[a] - 0.5 * dp;
                let t = (c - o[a]) / dp;
                let face = o[a] + t.round() * dp;
                (inside && (t - t.round()).abs() > 0.01).then_some((a, c, face))
            })
        });
        let Some((a, c, face)) = off else { continue };
        let ax = AXES[a];
        // Lengths to six decimals (m).
        let m = |x: f64| {
            let t = format!("{x:.6}");
            let t = t.trim_end_matches('0').trim_end_matches('.');
            if t == "-0" {
                "0".to_string()
            } else {
                t.to_string()
            }
        };
        out.push(SceneWarning {
            field: format!("boundaries[{gi}] ('{}')", group.name.escape_debug()),
            message: format!(
                "body '{}' spans {:.2} particle spacings along {ax}, not a whole number, so its particles sit centred in it and their cells' faces are not at whole spacings from its ends: the face {ax} = {} m of the region of '{}' lies inside a particle's cell, and the group holds the body from the cell face {ax} = {} m, {} m ({:.2} of a spacing) from the region's face; with whole numbers of spacings on both sides of the region's face (now {:.2} and {:.2}: choose particle_spacing, or the body's ends, so) a cell face falls on it",
                b.name,
                (hi[a] - lo[a]) / dp,
                m(c),
                group.name,
                m(face),
                m((face - c).abs()),
                (face - c).abs() / dp,
                (c - lo[a]) / dp,
                (hi[a] - c) / dp,
            ),
        });
    }
    out
}

impl Scene {
    /// Warnings of under-resolved geometry (see the module doc), in body order; empty for a
    /// scene that is not valid, whose memory estimate exceeds the memory available, or that is
    /// well resolved. Builds the particles but no World (cheap: one neighbour search).
    pub fn warnings(&self) -> Vec<SceneWarning> {
        if self.validate().is_err() || super::memory::check(self).is_err() {
            return Vec::new();
        }
        match self.dimension {
            2 => self.warnings_d::<2>(),
            _ => self.warnings_d::<3>(),
        }
    }

    fn warnings_d<const D: usize>(&self) -> Vec<SceneWarning>
    where
        Space: Dim<D>,
    {
        (0..self.bodies.len())
            .flat_map(|k| match body_fill::<D>(self, k) {
                Ok(f) => {
                    let mut w = body_warnings::<D>(self, k, &f.points, &f.box_of);
                    w.extend(shape_warnings(
                        self,
                        k,
                        f.shape.as_ref().map(|s| s.volumes.as_slice()),
                        f.shape.as_ref().is_some_and(|s| s.solid_box.is_some()),
                        f.lost_volume,
                    ));
                    w
                }
                Err(_) => Vec::new(),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_counts() {
        assert_eq!(layers(2.1), 2);
        assert_eq!(layers(2.0), 1);
        assert_eq!(layers(3.5), 3);
        assert_eq!(full_neighbourhood::<2>(2.1), 12);
        assert_eq!(full_neighbourhood::<3>(2.1), 32);
    }
}
