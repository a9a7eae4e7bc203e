//! Shapes of bodies (issue 26): boxes, cylinders (discs in 2D), spheres, half-space cuts and
//! closed triangle meshes read from STL files, combined per body as a union less the cuts; as
//! serde data and as a signed distance (negative inside) for filling, selection and output.
//!
//! Meshes are read with `stl_io` (binary and ASCII) and queried with parry's `TriMesh` (the
//! angle-weighted pseudo-normals of Baerentzen & Aanaes give the inside test, its projection the
//! distance). A mesh must be closed and manifold with outward normals; inward normals are
//! turned round with a warning. The signed distance of a union is the least of its members',
//! that of a cut max(d_body, -d_cut): exact outside a union and a bound (never larger than the
//! distance) elsewhere, which is what the filling's classification of cells needs.
use super::limits::num;
use super::{err, SceneError, SceneWarning};
use parry3d_f64::math::Point;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::{TriMesh, TriMeshFlags};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A shape of a body, a cut, or a selection. Coordinates in m, `dimension` components.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// An axis-aligned box (m); its sides need not be whole numbers of particle spacings.
    Box(super::Region),
    /// A circular cylinder; in 2D a disc (then `axis` and `length` are left out).
    Cylinder(Cylinder),
    /// A ball; in 2D a disc.
    Sphere(Sphere),
    /// The half-space (x - point) . normal <= 0: the normal points out of the solid side. Only
    /// as a cut (it is unbounded; the normal then points into what remains) or as a selection.
    HalfSpace(HalfSpace),
    /// A closed triangle mesh read from an STL file (3D only).
    Mesh(MeshSpec),
}

/// A circular cylinder (3D) or a disc (2D).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Cylinder {
    /// Centre of the axis (the middle of its length) (m), `dimension` components.
    pub center: Vec<f64>,
    /// Radius (m).
    pub radius: f64,
    /// Direction of the axis (-; any length, not zero; 3 components). 3D only.
    #[serde(default)]
    pub axis: Option<Vec<f64>>,
    /// Length along the axis (m). 3D only.
    #[serde(default)]
    pub length: Option<f64>,
}

/// A ball (3D) or a disc (2D).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Sphere {
    /// Centre (m), `dimension` components.
    pub center: Vec<f64>,
    /// Radius (m).
    pub radius: f64,
}

/// A half-space: the points x with (x - point) . normal <= 0. As a cut it removes those points:
/// its normal points into what remains of the body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HalfSpace {
    /// A point of the bounding plane (m), `dimension` components.
    pub point: Vec<f64>,
    /// Outward normal of the solid side (-; any length, not zero), `dimension` components.
    pub normal: Vec<f64>,
}

/// A closed triangle mesh from an STL file, placed by x = R (scale X) + translate, where R turns
/// by `rotate_deg[0]` about x, then `rotate_deg[1]` about y, then `rotate_deg[2]` about z (fixed
/// axes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// The STL file (binary or ASCII), relative to the scene file's folder (in an FMU: to its
    /// resources folder, where `mps pack` puts it).
    pub file: String,
    /// Factor from the file's units to m (-): 0.001 for a file in millimetres. Default 1.
    #[serde(default = "one")]
    pub scale: f64,
    /// Translation after scaling and rotation (m), 3 components. Default none.
    #[serde(default)]
    pub translate: Option<Vec<f64>>,
    /// Rotation angles about x, y, z (deg), applied in that order about fixed axes.
    /// Default none.
    #[serde(default)]
    pub rotate_deg: Option<Vec<f64>>,
}

fn one() -> f64 {
    1.0
}

/// A mesh read, checked and placed: parry's TriMesh with its pseudo-normals.
pub struct LoadedMesh {
    pub mesh: TriMesh,
    /// Enclosed volume (m^3).
    pub volume: f64,
    /// Whether the file's triangles faced inward (they were turned round).
    pub inverted: bool,
}

impl std::fmt::Debug for LoadedMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "LoadedMesh({} triangles, {} m^3)",
            self.mesh.num_triangles(),
            self.volume
        )
    }
}

/// A shape ready to query, in 3D coordinates (z = 0 in 2D).
#[derive(Clone, Debug)]
pub enum Solid {
    /// `dims`: the scene's dimension (a 2D box has no extent along z).
    Box {
        min: [f64; 3],
        max: [f64; 3],
        dims: usize,
    },
    Sphere {
        c: [f64; 3],
        r: f64,
    },
    Cylinder {
        c: [f64; 3],
        a: [f64; 3],
        r: f64,
        half: f64,
    },
    Disc {
        c: [f64; 3],
        r: f64,
    },
    HalfSpace {
        p: [f64; 3],
        n: [f64; 3],
    },
    Mesh(Arc<LoadedMesh>),
}

/// The first three components of a vector (0 for those missing: z of a 2D point).
pub fn to3(v: &[f64]) -> [f64; 3] {
    [
        v.first().copied().unwrap_or(0.0),
        v.get(1).copied().unwrap_or(0.0),
        v.get(2).copied().unwrap_or(0.0),
    ]
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    [a[0] / n, a[1] / n, a[2] / n]
}

impl Solid {
    /// Signed distance of p (m): negative inside, positive outside (a bound for meshes only
    /// where noted: exact here for every primitive and mesh).
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        match self {
            Solid::Box { min, max, dims } => {
                let mut out = 0.0f64;
                let mut inside = f64::NEG_INFINITY;
                for k in 0..*dims {
                    let c = 0.5 * (min[k] + max[k]);
                    let h = 0.5 * (max[k] - min[k]);
                    let q = (p[k] - c).abs() - h;
                    out += q.max(0.0).powi(2);
                    inside = inside.max(q);
                }
                out.sqrt() + inside.min(0.0)
            }
            Solid::Sphere { c, r } | Solid::Disc { c, r } => norm(sub(p, *c)) - r,
            Solid::Cylinder { c, a, r, half } => {
                let d = sub(p, *c);
                let t = dot(d, *a);
                let radial = norm([d[0] - t * a[0], d[1] - t * a[1], d[2] - t * a[2]]);
                let dx = radial - r;
                let dy = t.abs() - half;
                dx.max(dy).min(0.0) + (dx.max(0.0).powi(2) + dy.max(0.0).powi(2)).sqrt()
            }
            Solid::HalfSpace { p: q, n } => dot(sub(p, *q), *n),
            Solid::Mesh(m) => {
                let pt = Point::new(p[0], p[1], p[2]);
                let (proj, _) = m.mesh.project_local_point_and_get_location(&pt, false);
                let d = (pt - proj.point).norm();
                if proj.is_inside {
                    -d
                } else {
                    d
                }
            }
        }
    }

    /// Axis-aligned bounds (m); None for a half-space.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        match self {
            Solid::Box { min, max, .. } => Some((*min, *max)),
            Solid::Sphere { c, r } => Some((
                [c[0] - r, c[1] - r, c[2] - r],
                [c[0] + r, c[1] + r, c[2] + r],
            )),
            Solid::Disc { c, r } => Some(([c[0] - r, c[1] - r, 0.0], [c[0] + r, c[1] + r, 0.0])),
            Solid::Cylinder { c, a, r, half } => {
                // The bounds of the two end discs.
                let mut lo = [0.0; 3];
                let mut hi = [0.0; 3];
                for k in 0..3 {
                    let ext = half * a[k].abs() + r * (1.0 - a[k] * a[k]).max(0.0).sqrt();
                    lo[k] = c[k] - ext;
                    hi[k] = c[k] + ext;
                }
                Some((lo, hi))
            }
            Solid::HalfSpace { .. } => None,
            Solid::Mesh(m) => {
                let b = m.mesh.local_aabb();
                Some((
                    [b.mins.x, b.mins.y, b.mins.z],
                    [b.maxs.x, b.maxs.y, b.maxs.z],
                ))
            }
        }
    }
}

/// A body's geometry: the union of `parts` less the union of `cuts`.
#[derive(Clone, Debug)]
pub struct Geometry {
    pub parts: Vec<Solid>,
    pub cuts: Vec<Solid>,
}

impl Geometry {
    /// Signed distance (m), negative inside: min over the parts, then max(d, -d_cut).
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        let mut d = self
            .parts
            .iter()
            .map(|s| s.distance(p))
            .fold(f64::INFINITY, f64::min);
        for c in &self.cuts {
            d = d.max(-c.distance(p));
        }
        d
    }

    /// Bounds of the union of the parts (m).
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for s in &self.parts {
            if let Some((a, b)) = s.bounds() {
                for k in 0..3 {
                    lo[k] = lo[k].min(a[k]);
                    hi[k] = hi[k].max(b[k]);
                }
            }
        }
        (lo, hi)
    }
}

/// The rotation matrix of `rotate_deg` (about x, then y, then z; fixed axes).
fn rotation(deg: &[f64]) -> [[f64; 3]; 3] {
    let [ax, ay, az] = to3(deg).map(f64::to_radians);
    let rx = [
        [1.0, 0.0, 0.0],
        [0.0, ax.cos(), -ax.sin()],
        [0.0, ax.sin(), ax.cos()],
    ];
    let ry = [
        [ay.cos(), 0.0, ay.sin()],
        [0.0, 1.0, 0.0],
        [-ay.sin(), 0.0, ay.cos()],
    ];
    let rz = [
        [az.cos(), -az.sin(), 0.0],
        [az.sin(), az.cos(), 0.0],
        [0.0, 0.0, 1.0],
    ];
    let mul = |a: [[f64; 3]; 3], b: [[f64; 3]; 3]| {
        let mut c = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
            }
        }
        c
    };
    mul(rz, mul(ry, rx))
}

/// Resolves a mesh file against the scene's folder.
pub fn mesh_path(base: Option<&Path>, file: &str) -> PathBuf {
    let p = Path::new(file);
    match base {
        Some(b) if p.is_relative() => b.join(p),
        _ => p.to_path_buf(),
    }
}

/// Largest STL file read (bytes): a part of a few hundred thousand triangles.
const MAX_MESH_BYTES: u64 = 256 << 20;

/// Reads, checks and places a mesh. `field` names the mesh in messages. Refused: a file that
/// is missing or not STL, no triangles, a surface that is not closed or not manifold (an edge
/// not shared by exactly two triangles of opposite senses), a non-finite vertex, and a zero
/// enclosed volume. Inward-facing triangles are turned round (`LoadedMesh::inverted`).
pub fn load_mesh(
    field: &str,
    spec: &MeshSpec,
    base: Option<&Path>,
) -> Result<LoadedMesh, SceneError> {
    let ff = format!("{field}.file");
    let path = mesh_path(base, &spec.file);
    let size = std::fs::metadata(&path)
        .map_err(|e| err(&ff, format!("cannot read the mesh {}: {e}", path.display())))?
        .len();
    if size > MAX_MESH_BYTES {
        return Err(err(
            &ff,
            format!(
                "{} is {size} bytes long, more than a mesh file may be ({MAX_MESH_BYTES})",
                path.display()
            ),
        ));
    }
    let bytes = std::fs::read(&path)
        .map_err(|e| err(&ff, format!("cannot read the mesh {}: {e}", path.display())))?;
    let stl = stl_io::read_stl(&mut std::io::Cursor::new(&bytes)).map_err(|e| {
        err(
            &ff,
            format!(
                "{} is not a readable STL file (binary or ASCII): {e}",
                path.display()
            ),
        )
    })?;
    let rot = rotation(spec.rotate_deg.as_deref().unwrap_or(&[]));
    let t = to3(spec.translate.as_deref().unwrap_or(&[]));
    let s = spec.scale;
    let mut vertices = Vec::with_capacity(stl.vertices.len());
    for (k, v) in stl.vertices.iter().enumerate() {
        let x = v.0.map(|c| c as f64 * s);
        if !x.iter().all(|c| c.is_finite()) {
            return Err(err(
                &ff,
                format!("{}: vertex {k} is not finite ({:?})", path.display(), v.0),
            ));
        }
        let y: [f64; 3] = std::array::from_fn(|i| dot(rot[i], x) + t[i]);
        vertices.push(Point::new(y[0], y[1], y[2]));
    }
    // Triangles with a repeated vertex (slivers of CAD exports) have no area: dropped.
    let mut indices: Vec<[u32; 3]> = stl
        .faces
        .iter()
        .map(|f| f.vertices.map(|i| i as u32))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect();
    if indices.is_empty() {
        return Err(err(
            &ff,
            format!(
                "{} holds no triangle with three distinct vertices",
                path.display()
            ),
        ));
    }
    let mut volume = signed_volume(&vertices, &indices);
    let inverted = volume < 0.0;
    if inverted {
        for t in &mut indices {
            t.swap(1, 2);
        }
        volume = -volume;
    }
    // Closed and manifold: each directed edge once, with its twin.
    let mut edges = std::collections::HashMap::with_capacity(indices.len() * 3);
    for (f, t) in indices.iter().enumerate() {
        for k in 0..3 {
            let e = (t[k], t[(k + 1) % 3]);
            if let Some(g) = edges.insert(e, f) {
                let (a, b) = (vertices[e.0 as usize], vertices[e.1 as usize]);
                return Err(err(
                    &ff,
                    format!(
                        "{}: the surface is not manifold: the edge from ({}, {}, {}) to ({}, {}, {}) m is used in the same sense by triangles {g} and {f} (an edge of more than two triangles, or neighbours of opposite orientation); export a closed, consistently oriented solid",
                        path.display(), num(a.x), num(a.y), num(a.z), num(b.x), num(b.y), num(b.z)
                    ),
                ));
            }
        }
    }
    let open: Vec<&(u32, u32)> = edges
        .keys()
        .filter(|e| !edges.contains_key(&(e.1, e.0)))
        .collect();
    if let Some(e) = open.first() {
        let (a, b) = (vertices[e.0 as usize], vertices[e.1 as usize]);
        return Err(err(
            &ff,
            format!(
                "{}: the surface is not closed: {} edges belong to one triangle only (a hole), e.g. from ({}, {}, {}) to ({}, {}, {}) m; a body needs a watertight solid",
                path.display(), open.len(), num(a.x), num(a.y), num(a.z), num(b.x), num(b.y), num(b.z)
            ),
        ));
    }
    let lo = vertices.iter().fold([f64::INFINITY; 3], |l, p| {
        [l[0].min(p.x), l[1].min(p.y), l[2].min(p.z)]
    });
    let hi = vertices.iter().fold([f64::NEG_INFINITY; 3], |h, p| {
        [h[0].max(p.x), h[1].max(p.y), h[2].max(p.z)]
    });
    let bbox = (0..3).map(|k| hi[k] - lo[k]).product::<f64>();
    if volume.is_nan() || volume <= 1e-9 * bbox || volume == 0.0 {
        return Err(err(
            &ff,
            format!(
                "{}: the mesh encloses no volume ({} m^3 in a bounding box of {} m^3): a flat or self-cancelling surface",
                path.display(), num(volume), num(bbox)
            ),
        ));
    }
    let mesh = TriMesh::with_flags(vertices, indices, TriMeshFlags::ORIENTED);
    Ok(LoadedMesh {
        mesh,
        volume,
        inverted,
    })
}

/// The volume enclosed by a triangle mesh, positive for outward-facing triangles (m^3).
fn signed_volume(v: &[Point<f64>], t: &[[u32; 3]]) -> f64 {
    // About the first vertex, so that a part far from the origin keeps its digits.
    let o = v[t[0][0] as usize];
    t.iter()
        .map(|t| {
            let a = v[t[0] as usize] - o;
            let b = v[t[1] as usize] - o;
            let c = v[t[2] as usize] - o;
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

/// Checks a shape's numbers (`field` names it) for a scene of dimension d and spacing dp;
/// `as_part`: a shape of a body's union (a half-space is refused there), else a cut or a
/// selection. Meshes are read (`base`: the scene's folder) and their warnings returned.
pub fn check(
    field: &str,
    s: &Shape,
    d: usize,
    dp: f64,
    as_part: bool,
    base: Option<&Path>,
) -> Result<Vec<SceneWarning>, SceneError> {
    let vector = |f: &str, v: &[f64], n: usize| super::vector(&format!("{field}.{f}"), v, n);
    let small = |f: &str, what: &str, v: f64| -> Result<(), SceneError> {
        if !(v.is_finite() && v > 0.0) {
            return Err(err(
                format!("{field}.{f}"),
                format!("must be a positive finite number, got {}", num(v)),
            ));
        }
        if as_part && v < 0.5 * dp {
            return Err(err(
                format!("{field}.{f}"),
                format!(
                    "{what} of {} m is smaller than one particle (particle_spacing = {} m): the shape would hold no particle or a single one",
                    num(v),
                    num(dp)
                ),
            ));
        }
        Ok(())
    };
    match s {
        Shape::Box(r) => {
            super::region(field, r, d)?;
            if as_part {
                for k in 0..d {
                    small("max", "a side", r.max[k] - r.min[k])?;
                }
            }
        }
        Shape::Sphere(sp) => {
            vector("center", &sp.center, d)?;
            small("radius", "a radius", sp.radius)?;
        }
        Shape::Cylinder(c) => {
            vector("center", &c.center, d)?;
            small("radius", "a radius", c.radius)?;
            if d == 2 {
                if c.axis.is_some() || c.length.is_some() {
                    return Err(err(
                        field,
                        "a 2D cylinder is a disc (center and radius): leave out axis and length",
                    ));
                }
            } else {
                let a = c.axis.as_ref().ok_or_else(|| {
                    err(
                        format!("{field}.axis"),
                        "a 3D cylinder needs its axis direction",
                    )
                })?;
                vector("axis", a, 3)?;
                if a.iter().all(|x| *x == 0.0) {
                    return Err(err(format!("{field}.axis"), "must not be zero"));
                }
                let l = c.length.ok_or_else(|| {
                    err(
                        format!("{field}.length"),
                        "a 3D cylinder needs its length (m)",
                    )
                })?;
                small("length", "a length", l)?;
            }
        }
        Shape::HalfSpace(h) => {
            if as_part {
                return Err(err(
                    field,
                    "a half_space is unbounded: it can only cut a body (bodies[].cuts) or select particles, not be one of a body's shapes",
                ));
            }
            vector("point", &h.point, d)?;
            vector("normal", &h.normal, d)?;
            if h.normal.iter().all(|x| *x == 0.0) {
                return Err(err(format!("{field}.normal"), "must not be zero"));
            }
        }
        Shape::Mesh(m) => {
            if d != 3 {
                return Err(err(field, "an STL mesh is a 3D shape; this scene is 2D"));
            }
            if !(m.scale.is_finite() && m.scale > 0.0) {
                return Err(err(
                    format!("{field}.scale"),
                    format!("must be a positive finite number, got {}", num(m.scale)),
                ));
            }
            if let Some(t) = &m.translate {
                vector("translate", t, 3)?;
            }
            if let Some(r) = &m.rotate_deg {
                vector("rotate_deg", r, 3)?;
            }
            let loaded = load_mesh(&format!("{field}.mesh"), m, base)?;
            let b = loaded.mesh.local_aabb();
            let ext: Vec<f64> = (0..3).map(|k| b.maxs[k] - b.mins[k]).collect();
            let big = ext.iter().fold(0.0f64, |a, &b| a.max(b));
            let thin = ext.iter().fold(f64::INFINITY, |a, &b| a.min(b));
            if as_part && thin < dp {
                return Err(err(
                    format!("{field}.mesh.scale"),
                    format!(
                        "the mesh is {} m thin (extents {} x {} x {} m after scale = {}), less than one particle (particle_spacing = {} m); if the file is in m but the scale assumes mm, or the part is meant larger, fix the scale",
                        num(thin), num(ext[0]), num(ext[1]), num(ext[2]), num(m.scale), num(dp)
                    ),
                ));
            }
            let cells = ext.iter().map(|e| (e / dp).max(1.0)).product::<f64>();
            if as_part && (big > 1000.0 || cells > 1e9) {
                return Err(err(
                    format!("{field}.mesh.scale"),
                    format!(
                        "the mesh spans {} x {} x {} m after scale = {} ({} particle cells at particle_spacing = {} m): a part of {} m is not what an STL of a machine part means; if the file is in millimetres set scale to 0.001",
                        num(ext[0]), num(ext[1]), num(ext[2]), num(m.scale), num(cells.round()), num(dp), num(big)
                    ),
                ));
            }
            let mut w = Vec::new();
            if loaded.inverted {
                w.push(SceneWarning {
                    field: format!("{field}.mesh.file"),
                    message: format!(
                        "the triangles of {} face inward (their enclosed volume is negative); they were turned round, the solid is the inside of the surface",
                        m.file
                    ),
                });
            }
            return Ok(w);
        }
    }
    Ok(Vec::new())
}

/// The queryable solid of a validated shape (meshes read from `base`).
pub fn solid(field: &str, s: &Shape, d: usize, base: Option<&Path>) -> Result<Solid, SceneError> {
    Ok(match s {
        Shape::Box(r) => Solid::Box {
            min: to3(&r.min),
            max: to3(&r.max),
            dims: d,
        },
        Shape::Sphere(sp) if d == 2 => Solid::Disc {
            c: to3(&sp.center),
            r: sp.radius,
        },
        Shape::Sphere(sp) => Solid::Sphere {
            c: to3(&sp.center),
            r: sp.radius,
        },
        Shape::Cylinder(c) if d == 2 => Solid::Disc {
            c: to3(&c.center),
            r: c.radius,
        },
        Shape::Cylinder(c) => Solid::Cylinder {
            c: to3(&c.center),
            a: unit(to3(c.axis.as_deref().unwrap_or(&[1.0, 0.0, 0.0]))),
            r: c.radius,
            half: 0.5 * c.length.unwrap_or(0.0),
        },
        Shape::HalfSpace(h) => Solid::HalfSpace {
            p: to3(&h.point),
            n: unit(to3(&h.normal)),
        },
        Shape::Mesh(m) => Solid::Mesh(Arc::new(load_mesh(&format!("{field}.mesh"), m, base)?)),
    })
}

/// Two unit vectors that complete unit `a` to an orthonormal frame.
fn frame(a: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let t = if a[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let cross = |u: [f64; 3], v: [f64; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let e1 = unit(cross(a, t));
    (e1, cross(a, e1))
}

/// A point c + s e1 + t e2.
fn at2(c: [f64; 3], e1: [f64; 3], e2: [f64; 3], s: f64, t: f64) -> [f64; 3] {
    std::array::from_fn(|k| c[k] + s * e1[k] + t * e2[k])
}

/// A parallelogram c + s e1 + t e2, s in [0, a], t in [0, b], as triangles no larger than
/// `h`, facing e1 x e2.
fn patch(
    out: &mut Vec<Vec<[f64; 3]>>,
    c: [f64; 3],
    e1: [f64; 3],
    e2: [f64; 3],
    a: f64,
    b: f64,
    h: f64,
) {
    let n = ((a / h).ceil() as usize).clamp(1, 4096);
    let m = ((b / h).ceil() as usize).clamp(1, 4096);
    for i in 0..n {
        for j in 0..m {
            let (s0, s1) = (a * i as f64 / n as f64, a * (i + 1) as f64 / n as f64);
            let (t0, t1) = (b * j as f64 / m as f64, b * (j + 1) as f64 / m as f64);
            let p00 = at2(c, e1, e2, s0, t0);
            let p10 = at2(c, e1, e2, s1, t0);
            let p11 = at2(c, e1, e2, s1, t1);
            let p01 = at2(c, e1, e2, s0, t1);
            out.push(vec![p00, p10, p11]);
            out.push(vec![p00, p11, p01]);
        }
    }
}

impl Solid {
    /// The shape's boundary as outward-facing triangles (3D) or segments (2D, `d` = 2) no
    /// larger than about `h` (m); a half-space as the part of its plane over `bounds`.
    fn surface(&self, d: usize, h: f64, bounds: ([f64; 3], [f64; 3])) -> Vec<Vec<[f64; 3]>> {
        let mut out = Vec::new();
        let tau = std::f64::consts::TAU;
        let circle = |out: &mut Vec<Vec<[f64; 3]>>, c: [f64; 3], r: f64| {
            let n = ((tau * r / h).ceil() as usize).clamp(8, 1 << 16);
            for i in 0..n {
                let a0 = tau * i as f64 / n as f64;
                let a1 = tau * (i + 1) as f64 / n as f64;
                out.push(vec![
                    [c[0] + r * a0.cos(), c[1] + r * a0.sin(), 0.0],
                    [c[0] + r * a1.cos(), c[1] + r * a1.sin(), 0.0],
                ]);
            }
        };
        match self {
            Solid::Box { min, max, .. } if d == 2 => {
                let c = [
                    [min[0], min[1]],
                    [max[0], min[1]],
                    [max[0], max[1]],
                    [min[0], max[1]],
                ];
                for k in 0..4 {
                    let (a, b) = (c[k], c[(k + 1) % 4]);
                    let len = ((b[0] - a[0]).abs() + (b[1] - a[1]).abs()).max(1e-300);
                    let n = ((len / h).ceil() as usize).clamp(1, 1 << 16);
                    for i in 0..n {
                        let (s0, s1) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
                        out.push(vec![
                            [a[0] + s0 * (b[0] - a[0]), a[1] + s0 * (b[1] - a[1]), 0.0],
                            [a[0] + s1 * (b[0] - a[0]), a[1] + s1 * (b[1] - a[1]), 0.0],
                        ]);
                    }
                }
            }
            Solid::Box { min, max, .. } => {
                let e = |k: usize| -> [f64; 3] {
                    std::array::from_fn(|i| if i == k { 1.0 } else { 0.0 })
                };
                for k in 0..3 {
                    let (u, v) = ((k + 1) % 3, (k + 2) % 3);
                    let (a, b) = (max[u] - min[u], max[v] - min[v]);
                    // Face at max[k], facing +k: e_u x e_v = e_k.
                    let mut c = *min;
                    c[k] = max[k];
                    patch(&mut out, c, e(u), e(v), a, b, h);
                    // Face at min[k], facing -k: e_v x e_u.
                    patch(&mut out, *min, e(v), e(u), b, a, h);
                }
            }
            Solid::Sphere { c, r } => {
                let nt = ((std::f64::consts::PI * r / h).ceil() as usize).clamp(4, 1 << 12);
                let np = ((tau * r / h).ceil() as usize).clamp(8, 1 << 13);
                let p = |t: usize, f: usize| {
                    let th = std::f64::consts::PI * t as f64 / nt as f64;
                    let ph = tau * f as f64 / np as f64;
                    [
                        c[0] + r * th.sin() * ph.cos(),
                        c[1] + r * th.sin() * ph.sin(),
                        c[2] + r * th.cos(),
                    ]
                };
                for t in 0..nt {
                    for f in 0..np {
                        let (a, b, cc, dd) = (p(t, f), p(t + 1, f), p(t + 1, f + 1), p(t, f + 1));
                        if t > 0 {
                            out.push(vec![a, b, dd]);
                        }
                        if t + 1 < nt {
                            out.push(vec![b, cc, dd]);
                        }
                    }
                }
            }
            Solid::Disc { c, r } => circle(&mut out, *c, *r),
            Solid::Cylinder { c, a, r, half } => {
                let (e1, e2) = frame(*a);
                let n = ((tau * r / h).ceil() as usize).clamp(8, 1 << 13);
                let m = ((2.0 * half / h).ceil() as usize).clamp(1, 1 << 13);
                let rings = ((r / h).ceil() as usize).clamp(1, 1 << 12);
                let p = |i: usize, z: f64, rad: f64| {
                    let ang = tau * i as f64 / n as f64;
                    let s = rad * ang.cos();
                    let t = rad * ang.sin();
                    std::array::from_fn(|k| c[k] + s * e1[k] + t * e2[k] + z * a[k])
                };
                for i in 0..n {
                    for j in 0..m {
                        let z0 = -half + 2.0 * half * j as f64 / m as f64;
                        let z1 = -half + 2.0 * half * (j + 1) as f64 / m as f64;
                        let (p00, p10, p11, p01) = (
                            p(i, z0, *r),
                            p(i + 1, z0, *r),
                            p(i + 1, z1, *r),
                            p(i, z1, *r),
                        );
                        out.push(vec![p00, p10, p11]);
                        out.push(vec![p00, p11, p01]);
                    }
                    for (z, up) in [(*half, true), (-half, false)] {
                        for k in 0..rings {
                            let (r0, r1) = (
                                r * k as f64 / rings as f64,
                                r * (k + 1) as f64 / rings as f64,
                            );
                            let (q00, q10, q11, q01) =
                                (p(i, z, r0), p(i, z, r1), p(i + 1, z, r1), p(i + 1, z, r0));
                            let mut tri = |x: [f64; 3], y: [f64; 3], w: [f64; 3]| {
                                if up {
                                    out.push(vec![x, y, w]);
                                } else {
                                    out.push(vec![x, w, y]);
                                }
                            };
                            if k > 0 {
                                tri(q00, q10, q11);
                                tri(q00, q11, q01);
                            } else {
                                tri(q00, q10, q11);
                            }
                        }
                    }
                }
            }
            Solid::HalfSpace { p, n } => {
                let (lo, hi) = bounds;
                let span = (0..d).map(|k| hi[k] - lo[k]).fold(0.0f64, f64::max);
                let mid: [f64; 3] =
                    std::array::from_fn(|k| if k < d { 0.5 * (lo[k] + hi[k]) } else { 0.0 });
                // The foot of the middle of the bounds on the plane.
                let off = dot(sub(mid, *p), *n);
                let foot: [f64; 3] = std::array::from_fn(|k| mid[k] - off * n[k]);
                if d == 2 {
                    let t = [-n[1], n[0], 0.0];
                    let m = ((2.0 * span / h).ceil() as usize).clamp(1, 1 << 16);
                    for i in 0..m {
                        let s0 = -span + 2.0 * span * i as f64 / m as f64;
                        let s1 = -span + 2.0 * span * (i + 1) as f64 / m as f64;
                        out.push(vec![
                            [foot[0] + s0 * t[0], foot[1] + s0 * t[1], 0.0],
                            [foot[0] + s1 * t[0], foot[1] + s1 * t[1], 0.0],
                        ]);
                    }
                } else {
                    let (e1, e2) = frame(*n);
                    let c0 = at2(foot, e1, e2, -span, -span);
                    patch(&mut out, c0, e1, e2, 2.0 * span, 2.0 * span, h);
                }
            }
            Solid::Mesh(m) => {
                for t in m.mesh.triangles() {
                    out.push([t.a, t.b, t.c].iter().map(|q| [q.x, q.y, q.z]).collect());
                }
            }
        }
        out
    }
}

impl Geometry {
    /// The solid's boundary as outward-facing triangles (3D) or segments (2D), no larger than
    /// about `h` (m): each part's and each cut's own boundary, kept where it bounds the solid
    /// (its centroid within h / 4 of the solid's surface, not inside it); the cuts' faces turned
    /// to face out of the solid. Seams where shapes meet are jagged at the scale of h.
    pub fn surface(&self, d: usize, h: f64) -> Vec<Vec<[f64; 3]>> {
        let bounds = self.bounds();
        let tol = 0.25 * h;
        let mut out = Vec::new();
        let centroid = |c: &[[f64; 3]]| -> [f64; 3] {
            std::array::from_fn(|k| c.iter().map(|p| p[k]).sum::<f64>() / c.len() as f64)
        };
        for s in &self.parts {
            for c in s.surface(d, h, bounds) {
                if self.distance(centroid(&c)).abs() <= tol {
                    out.push(c);
                }
            }
        }
        for s in &self.cuts {
            for mut c in s.surface(d, h, bounds) {
                if self.distance(centroid(&c)).abs() <= tol {
                    c.reverse();
                    out.push(c);
                }
            }
        }
        out
    }
}
