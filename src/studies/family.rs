//! The accuracy family of issue 24: bodies written the way a user writes them (no `solver.model`,
//! clamps as a `clamped` region without a `mirror` field) against converged FEM references
//! (reference/*_fem.json, tools/fem_bending.py and tools/fem_shapes.py, whose "problem" blocks
//! give the geometry): single-box cantilevers in 2D and 3D with the clamp written several ways,
//! stepped cantilevers in 2D and 3D, an L-bracket and a plate with a rectangular hole, both under
//! their own weight. `mps study family` prints the linearised first frequency and static
//! deflection of each against its reference.
use crate::physics::{ElasticModel, Material, MaterialLaw, SolverOptions};
use crate::scene::{Body, Boundary, BoundaryKind, Gravity, MirrorSpec, Probe, Region, Scene};
use crate::studies::bending::{cantilever3d_scene, plate2d_scene};

/// How a scene writes its clamp at the face x = 0 (y = 0 for the L-bracket).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClampStyle {
    /// A box of 3 wall layers behind the face, on the body's lattice, over its section, in a
    /// `clamped` region: the natural way.
    Walls,
    /// The body's own end layers: one box that starts 2 layers before the face, with the
    /// `clamped` region over those layers.
    EndLayers,
    /// A layer of particles on the face (on the cell vertices across the section) and 2 wall
    /// layers behind it: how the benchmark scenes clamp for the corrected operator.
    FaceLayer,
    /// The `mirror` field: 3 layers at the images of the body's first three, with the face
    /// named (the benchmark scenes of the second-order operator).
    Mirror,
}

impl ClampStyle {
    pub const ALL: [ClampStyle; 4] = [
        ClampStyle::Walls,
        ClampStyle::EndLayers,
        ClampStyle::FaceLayer,
        ClampStyle::Mirror,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ClampStyle::Walls => "walls behind the face",
            ClampStyle::EndLayers => "the body's own end layers",
            ClampStyle::FaceLayer => "a layer on the face + walls",
            ClampStyle::Mirror => "mirror field",
        }
    }
}

/// Material of the issue-24 shapes (tools/fem_shapes.py): rho 1000, E 100 MPa, nu 0.3.
pub const SHAPE_MATERIAL: Material = Material {
    density: 1000.0,
    young: 1e8,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};

/// A reference: what it is, its value and the probe component it is read from.
#[derive(Clone, Copy, Debug)]
pub struct FamilyReference {
    pub f1: f64,
    pub static_u: f64,
    pub peak_u: f64,
}

fn converged(json: &str, f: &str, s: &str, p: &str) -> FamilyReference {
    let v: serde_json::Value = serde_json::from_str(json).expect("reference JSON");
    let c = &v["converged"];
    let q = if c["quantities"].is_object() {
        &c["quantities"]
    } else {
        c
    };
    let get = |k: &str| -> f64 {
        let x = &q[k];
        x["value"]
            .as_f64()
            .or_else(|| x.as_f64())
            .unwrap_or_else(|| panic!("reference lacks {k}"))
    };
    FamilyReference {
        f1: get(f),
        static_u: get(s),
        peak_u: get(p),
    }
}

/// One member of the family: a scene and its reference.
pub struct FamilyCase {
    pub name: String,
    pub scene: Scene,
    pub reference: FamilyReference,
}

fn v(dim: usize, x: f64, y: f64, z: f64) -> Vec<f64> {
    if dim == 3 {
        vec![x, y, z]
    } else {
        vec![x, y]
    }
}

fn bx(dim: usize, lo: [f64; 3], hi: [f64; 3]) -> Region {
    Region {
        min: v(dim, lo[0], lo[1], lo[2]),
        max: v(dim, hi[0], hi[1], hi[2]),
    }
}

/// A scene of one body of boxes with a clamp at the face x = x_face (normal -x) over the
/// section [y0, y1] x [z0, z1], under gravity along the last axis, with one probe.
#[allow(clippy::too_many_arguments)]
fn clamped_scene(
    name: &str,
    description: String,
    dim: usize,
    dp: f64,
    boxes: Vec<Region>,
    section: ([f64; 2], [f64; 2]),
    style: ClampStyle,
    probe: Vec<f64>,
) -> Scene {
    let ([y0, y1], [z0, z1]) = section;
    let mut boxes = boxes;
    let walls = 3.0;
    let (clamp_box, region, mirror) = match style {
        ClampStyle::Walls | ClampStyle::Mirror => (
            Some(bx(dim, [-walls * dp, y0, z0], [0.0, y1, z1])),
            bx(dim, [-walls * dp, y0, z0], [-0.25 * dp, y1, z1]),
            (style == ClampStyle::Mirror).then(|| MirrorSpec {
                point: vec![0.0; dim],
                normal: v(dim, -1.0, 0.0, 0.0),
            }),
        ),
        ClampStyle::EndLayers => {
            // The first box starts two layers before the face.
            boxes[0].min[0] -= 2.0 * dp;
            (
                None,
                bx(dim, [-2.0 * dp, y0, z0], [-0.25 * dp, y1, z1]),
                None,
            )
        }
        ClampStyle::FaceLayer => {
            let e = 0.5 * dp;
            let (zl, zh) = if dim == 3 { (z0 - e, z1 + e) } else { (z0, z1) };
            (
                Some(bx(dim, [-2.5 * dp, y0 - e, zl], [0.5 * dp, y1 + e, zh])),
                bx(dim, [-2.5 * dp, y0 - e, zl], [0.25 * dp, y1 + e, zh]),
                None,
            )
        }
    };
    if let Some(c) = clamp_box {
        boxes.push(c);
    }
    let g = if dim == 3 {
        vec![0.0, 0.0, -9.81]
    } else {
        vec![0.0, -9.81]
    };
    Scene {
        name: name.into(),
        description,
        dimension: dim,
        particle_spacing: dp,
        solver: SolverOptions::default(),
        gravity: Gravity {
            vector: g,
            paper_ramp_period: None,
        },
        bodies: vec![Body {
            name: "beam".into(),
            material: SHAPE_MATERIAL,
            boxes,
            shapes: vec![],
            cuts: vec![],
            velocity: None,
        }],
        boundaries: vec![Boundary {
            name: "clamp".into(),
            kind: BoundaryKind::Clamped,
            body: "beam".into(),
            region,
            shape: None,
            axes: None,
            mirror,
        }],
        loads: vec![],
        probes: vec![Probe {
            name: "tip".into(),
            point: probe,
            body: None,
        }],
        end_time: 1.0,
        output_interval: 1e-3,
        analysis: Some(crate::scene::Analysis {
            probe: "tip".into(),
            component: if dim == 3 { "z".into() } else { "y".into() },
        }),
        base_dir: None,
    }
}

/// The slender cantilever (3D) or the GMS plate (2D, plane strain) of the benchmark with the
/// clamp written as `style`, `n` particles across.
pub fn single_box(dim: usize, n: usize, style: ClampStyle) -> FamilyCase {
    let (base, reference) = if dim == 3 {
        let r = crate::studies::bending::cantilever_reference();
        let v: serde_json::Value =
            serde_json::from_str(crate::studies::bending::CANTILEVER_FEM_JSON).unwrap();
        let peak = v["converged"]["peak_dynamic_tip_uz_axis_m"]
            .as_f64()
            .unwrap();
        (
            cantilever3d_scene(n, ElasticModel::SecondOrder),
            FamilyReference {
                f1: r.f1,
                static_u: r.tip,
                peak_u: peak,
            },
        )
    } else {
        let r = crate::studies::bending::plate_reference();
        let v: serde_json::Value =
            serde_json::from_str(crate::studies::bending::PLATE_FEM_JSON).unwrap();
        let peak = v["converged"]["peak_dynamic_tip_uy_m"].as_f64().unwrap();
        (
            plate2d_scene(n, ElasticModel::SecondOrder),
            FamilyReference {
                f1: r.f1,
                static_u: r.tip,
                peak_u: peak,
            },
        )
    };
    let dp = base.particle_spacing;
    let beam = base.bodies[0].boxes[0].clone();
    let h = beam.max[1];
    let mut s = clamped_scene(
        &base.name,
        String::new(),
        dim,
        dp,
        vec![beam],
        ([-h, h], [-h, h]),
        style,
        base.probes[0].point.clone(),
    );
    s.bodies[0].material = base.bodies[0].material;
    s.description = format!(
        "{} ({n} across), clamp written as {}; the solver's defaults (second_order)",
        if dim == 3 {
            "slender 3D cantilever"
        } else {
            "GMS plate, plane strain"
        },
        style.name()
    );
    FamilyCase {
        name: format!(
            "{} {n} across, {}",
            if dim == 3 {
                "cantilever 3D"
            } else {
                "plate 2D"
            },
            style.name()
        ),
        scene: s,
        reference,
    }
}

/// reference/stepped_cantilever{2d,3d}_fem.json.
pub const STEPPED2D_FEM_JSON: &str = include_str!("../../reference/stepped_cantilever2d_fem.json");
pub const STEPPED3D_FEM_JSON: &str = include_str!("../../reference/stepped_cantilever3d_fem.json");
/// reference/l_bracket2d_fem.json.
pub const L_BRACKET_FEM_JSON: &str = include_str!("../../reference/l_bracket2d_fem.json");
/// reference/plate_rect_hole2d_fem.json.
pub const RECT_HOLE_FEM_JSON: &str = include_str!("../../reference/plate_rect_hole2d_fem.json");

/// The stepped cantilever (root 0.1 deep over x in [0, 0.5], tip 0.05 deep over [0.5, 1]),
/// `n` particles across the thinnest section (0.05 m), clamp written as `style`.
pub fn stepped(dim: usize, n: usize, style: ClampStyle) -> FamilyCase {
    let dp = 0.05 / n as f64;
    let boxes = vec![
        bx(dim, [0.0, -0.05, -0.05], [0.5, 0.05, 0.05]),
        bx(dim, [0.5, -0.025, -0.025], [1.0, 0.025, 0.025]),
    ];
    let s = clamped_scene(
        &format!("stepped{dim}d"),
        format!(
            "stepped cantilever ({dim}D, {n} across the tip section), clamp written as {}",
            style.name()
        ),
        dim,
        dp,
        boxes,
        ([-0.05, 0.05], [-0.05, 0.05]),
        style,
        v(dim, 1.0, 0.0, 0.0),
    );
    let reference = if dim == 3 {
        converged(
            STEPPED3D_FEM_JSON,
            "f1_hz",
            "static_tip_uz_m",
            "peak_first_tip_uz_m",
        )
    } else {
        converged(
            STEPPED2D_FEM_JSON,
            "f1_hz",
            "static_tip_uy_m",
            "peak_first_tip_uy_m",
        )
    };
    FamilyCase {
        name: format!("stepped {dim}D {n} across, {}", style.name()),
        scene: s,
        reference,
    }
}

/// The L-bracket (plane strain): leg 1 x in [0, 0.05], y in [0, 0.4] clamped at y = 0, leg 2
/// x in [0, 0.4], y in [0.35, 0.4]; under its own weight (-y), probe at the end box's centre.
/// `n` particles across the legs (0.05 m). The clamp: 3 wall layers below y = 0.
pub fn l_bracket(n: usize) -> FamilyCase {
    let dp = 0.05 / n as f64;
    let boxes = vec![
        bx(2, [0.0, 0.0, 0.0], [0.05, 0.4, 0.0]),
        bx(2, [0.05, 0.35, 0.0], [0.4, 0.4, 0.0]),
        bx(2, [0.0, -3.0 * dp, 0.0], [0.05, 0.0, 0.0]),
    ];
    let mut s = clamped_scene(
        "l_bracket2d",
        format!("L-bracket, plane strain, {n} across the legs, under its own weight, clamped by 3 wall layers below y = 0"),
        2,
        dp,
        boxes,
        ([0.0, 0.0], [0.0, 0.0]),
        ClampStyle::Walls,
        vec![0.375, 0.375],
    );
    // The generic clamp box is at x < 0: replace it by the layers below y = 0.
    s.bodies[0].boxes.pop();
    s.boundaries[0].region = bx(2, [0.0, -3.0 * dp, 0.0], [0.05, -0.25 * dp, 0.0]);
    FamilyCase {
        name: format!("L-bracket 2D {n} across"),
        scene: s,
        reference: converged(
            L_BRACKET_FEM_JSON,
            "f1_hz",
            "gravity_static_uy_m",
            "gravity_peak_first_uy_m",
        ),
    }
}

/// The plate [0, 0.4] x [-0.1, 0.1] with the hole [0.15, 0.25] x [-0.05, 0.05] (plane strain,
/// four boxes), clamped at x = 0 by 3 wall layers, under its own weight; `n` particles across
/// the ligaments (0.05 m).
pub fn rect_hole(n: usize) -> FamilyCase {
    let dp = 0.05 / n as f64;
    let boxes = vec![
        bx(2, [0.0, -0.1, 0.0], [0.15, 0.1, 0.0]),
        bx(2, [0.25, -0.1, 0.0], [0.4, 0.1, 0.0]),
        bx(2, [0.15, 0.05, 0.0], [0.25, 0.1, 0.0]),
        bx(2, [0.15, -0.1, 0.0], [0.25, -0.05, 0.0]),
    ];
    let s = clamped_scene(
        "rect_hole2d",
        format!("plate with a rectangular hole, plane strain, {n} across the ligaments, under its own weight"),
        2,
        dp,
        boxes,
        ([-0.1, 0.1], [0.0, 0.0]),
        ClampStyle::Walls,
        vec![0.4, 0.0],
    );
    FamilyCase {
        name: format!("plate with a hole 2D {n} across"),
        scene: s,
        reference: converged(
            RECT_HOLE_FEM_JSON,
            "f1_hz",
            "static_end_uy_m",
            "peak_first_end_uy_m",
        ),
    }
}

/// The single-box cantilever of `single_box` (walls behind the face) written as a user who
/// draws solids writes it: the beam and its 3 wall layers as one `box` shape (`shapes`, no
/// `boxes`: the lattice is the body's own) at `across` particle spacings through the section
/// (a whole number: the faces fall on the lattice's cell faces; else they cut the outer
/// cells), the whole scene moved by `offset` spacings across the beam (y, and z in 3D; the
/// probe with it). A body written this way must not depend on where it sits.
pub fn shape_written(dim: usize, across: f64, offset: f64) -> FamilyCase {
    let mut case = single_box(dim, 4, ClampStyle::Walls);
    let s = &mut case.scene;
    let h = s.bodies[0].boxes[0].max[1];
    let length = s.bodies[0].boxes[0].max[0];
    let dp = 2.0 * h / across;
    s.particle_spacing = dp;
    let at = |x: f64, y: f64| v(dim, x, y + offset * dp, y + offset * dp);
    s.bodies[0].boxes.clear();
    s.bodies[0].shapes = vec![crate::scene::shape::Shape::Box(Region {
        min: at(-3.0 * dp, -h),
        max: at(length, h),
    })];
    s.boundaries[0].region = Region {
        min: at(-3.0 * dp, -h),
        max: at(-0.25 * dp, h),
    };
    s.probes[0].point = at(length, 0.0);
    s.description = format!("{} written as a box shape", s.description);
    case.name = format!(
        "{} {across} across, written as a box shape moved by {offset} dp",
        if dim == 3 {
            "cantilever 3D"
        } else {
            "plate 2D"
        }
    );
    case
}

/// The rows of the single box written as a box shape: (spacings added to `n` through the
/// section, offset of the scene in spacings). By default the box moved by 0.3 spacings, and
/// the box half a spacing thicker (faces cutting the outer cells); `SHAPE_EXTRA=0.2,0.5,...`
/// (a study's knob) gives other thicknesses, unmoved.
fn shape_rows() -> Vec<(f64, f64)> {
    std::env::var("SHAPE_EXTRA")
        .ok()
        .map(|e| {
            e.split(',')
                .filter_map(|x| x.trim().parse::<f64>().ok())
                .map(|x| (x, 0.0))
                .collect()
        })
        .unwrap_or_else(|| vec![(0.0, 0.3), (0.5, 0.0)])
}

/// The family at `n` particles through the thinnest section: the single-box cantilevers with
/// every clamp style, then the multi-box shapes (walls behind the face).
pub fn family(n: usize, three_d: bool) -> Vec<FamilyCase> {
    let mut out = Vec::new();
    for style in ClampStyle::ALL {
        out.push(single_box(2, n, style));
    }
    if three_d {
        for style in ClampStyle::ALL {
            out.push(single_box(3, n, style));
        }
    }
    out.push(stepped(2, n, ClampStyle::Walls));
    if three_d {
        out.push(stepped(3, n, ClampStyle::Walls));
    }
    out.push(l_bracket(n));
    out.push(rect_hole(n));
    for (extra, offset) in shape_rows() {
        out.push(shape_written(2, n as f64 + extra, offset));
        if three_d {
            out.push(shape_written(3, n as f64 + extra, offset));
        }
    }
    if three_d && n == 4 {
        out.extend(case2_clamps());
    }
    out
}

/// The paper's case 2 at its spacing (dp = 0.025, 9 across) with the default operator: the
/// scene written as for the corrected operator (a face layer on the cell vertices and walls at
/// the clamp, a face-layer support holding y and z at the other end), and as the builder
/// writes it for second_order (both ends with `mirror`), and the latter without its `mirror`
/// fields. Against reference/case2_fem.json
/// (probe at x = 0.56 m, near the largest static deflection).
pub fn case2_clamps() -> Vec<FamilyCase> {
    use crate::studies::cases::{case2_scene, Support};
    let v: serde_json::Value =
        serde_json::from_str(crate::studies::report::CASE2_FEM_JSON).expect("case 2 JSON");
    let c = &v["converged"];
    let reference = FamilyReference {
        f1: c["f1_richardson_hz"].as_f64().unwrap(),
        static_u: c["static_max_uz_richardson_m"].as_f64().unwrap(),
        peak_u: c["peak_dynamic_uz_m"].as_f64().unwrap(),
    };
    let mut natural = case2_scene(0.025, ElasticModel::Corrected, None, Support::Face);
    natural.solver.model = ElasticModel::SecondOrder;
    let mirror = case2_scene(0.025, ElasticModel::SecondOrder, None, Support::Face);
    // The builder's layers (walls behind both end faces) without the mirror fields: what a
    // user writes who puts the clamp and the support beyond the beam's ends.
    let mut walls = mirror.clone();
    for b in &mut walls.boundaries {
        b.mirror = None;
    }
    vec![
        FamilyCase {
            name: "case 2, dp 0.025, written for corrected (face layers, no mirror)".into(),
            scene: natural,
            reference,
        },
        FamilyCase {
            name: "case 2, dp 0.025, mirror fields (the builder's)".into(),
            scene: mirror,
            reference,
        },
        FamilyCase {
            name: "case 2, dp 0.025, walls behind both faces (no mirror)".into(),
            scene: walls,
            reference,
        },
    ]
}

/// The family's linearised figures as a Markdown table (`mps bench --family`, `mps study
/// family`): per case the particles, the first frequency's and the static deflection's error
/// against the FEM, the wall time of build and solves, and the scene's accuracy warnings.
/// `only`: keep the cases whose name contains it.
pub fn family_markdown(ns: &[usize], three_d: bool, peaks: bool, only: Option<&str>) -> String {
    use crate::studies::bending::linear_bending;
    let mut md = String::from(
        "| case | particles | f1 error | static error | first peak error | build + solves (s) |\n|---|---|---|---|---|---|\n",
    );
    for &n in ns {
        for case in family(n, three_d) {
            if only.is_some_and(|o| !case.name.contains(o)) {
                continue;
            }
            match linear_bending(&case.scene) {
                Ok(b) => {
                    let peak = if peaks {
                        match first_peak(&case.scene, case.reference.f1) {
                            Ok(p) => format!("{:+.3} %", 100.0 * (p / case.reference.peak_u - 1.0)),
                            Err(e) => format!("error: {e}"),
                        }
                    } else {
                        "-".into()
                    };
                    md += &format!(
                        "| {} | {} | {:+.3} % | {:+.3} % | {peak} | {:.1} |\n",
                        case.name,
                        b.particles,
                        100.0 * (b.f1 / case.reference.f1 - 1.0),
                        100.0 * (b.tip / case.reference.static_u - 1.0),
                        b.wall
                    );
                    for w in &b.warnings {
                        if w.starts_with("boundaries") || w.contains("first order") {
                            md += &format!("|   warning: {w} | | | | | |\n");
                        }
                    }
                }
                Err(e) => md += &format!("| {} | error: {e} | | | | |\n", case.name),
            }
            eprint!(".");
        }
    }
    eprintln!();
    md
}

/// The first peak of the probe's displacement (along the scene's analysis component) under the
/// scene's gravity applied suddenly at t = 0 from rest, in the time domain with the solver's own
/// step: sampled every 1/400 of the reference period up to 0.7 of it, the extreme refined by the
/// parabola through its neighbours (m).
pub fn first_peak(scene: &Scene, f1_ref: f64) -> Result<f64, String> {
    let mut sim = crate::Simulation::new(scene).map_err(|e| e.to_string())?;
    let comp = crate::scene::axis_index(
        &scene
            .analysis
            .as_ref()
            .ok_or("the scene has no analysis")?
            .component,
    )
    .ok_or("bad analysis component")?;
    let period = 1.0 / f1_ref;
    let h = period / 400.0;
    let mut series = vec![0.0];
    let mut k = 0usize;
    while (k as f64) * h < 0.7 * period {
        k += 1;
        sim.advance_to(k as f64 * h).map_err(|e| e.to_string())?;
        series.push(sim.probe_displacement(0)[comp]);
    }
    // The first extreme: the largest |u| before it turns back.
    let sign = series
        .iter()
        .copied()
        .fold(0.0f64, |a, v| if v.abs() > a.abs() { v } else { a })
        .signum();
    let (i, _) = series
        .iter()
        .enumerate()
        .max_by(|a, b| (a.1 * sign).total_cmp(&(b.1 * sign)))
        .ok_or("no samples")?;
    if i == 0 || i + 1 >= series.len() {
        return Err("the first peak is not inside 0.7 of the reference period".into());
    }
    let (a, b, c) = (series[i - 1], series[i], series[i + 1]);
    let denom = a - 2.0 * b + c;
    Ok(if denom == 0.0 {
        b
    } else {
        b - 0.125 * (c - a) * (c - a) / denom
    })
}
