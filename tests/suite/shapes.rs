//! Bodies of any shape (issue 26): the scene format's shapes, the filling with particle volumes,
//! normals and areas, STL meshes and their bad input, selection by shape and the output.
use mps_solid::physics::World;
use mps_solid::scene::Model;
use mps_solid::{Scene, Simulation};
use serde_json::{json, Value};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

fn material() -> Value {
    json!({"density": 1000.0, "young": 1e6, "poisson": 0.3})
}

/// A scene of one body with the given fields (`boxes`, `shapes`, `cuts`).
fn one_body(d: usize, dp: f64, body: Value) -> Value {
    let mut b = json!({"name": "part", "material": material()});
    for (k, v) in body.as_object().unwrap() {
        b[k] = v.clone();
    }
    json!({
        "name": "shape_test", "dimension": d, "particle_spacing": dp,
        "bodies": [b], "end_time": 0.01, "output_interval": 0.001,
        "solver": {"model": "corrected"}
    })
}

fn scene_in(v: &Value, dir: Option<&Path>) -> Result<Scene, mps_solid::scene::SceneError> {
    Scene::from_json_in(&v.to_string(), dir)
}

fn world3(s: &Scene) -> World<3> {
    Model::<3>::build(s).unwrap().world
}

fn world2(s: &Scene) -> World<2> {
    Model::<2>::build(s).unwrap().world
}

/// A scratch folder removed when dropped.
struct TempDir(PathBuf);
impl TempDir {
    fn new(tag: &str) -> Self {
        let p = std::env::temp_dir().join(format!("mps_shapes_{tag}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}
impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

type Tri = [[f64; 3]; 3];

/// The 12 outward triangles of the box [0, a]^3.
fn cube_triangles(a: f64) -> Vec<Tri> {
    let v = |i: usize| -> [f64; 3] {
        [
            a * (i & 1) as f64,
            a * ((i >> 1) & 1) as f64,
            a * ((i >> 2) & 1) as f64,
        ]
    };
    // Faces as outward quads (corner codes, counter-clockwise seen from outside).
    let quads = [
        [0, 2, 3, 1], // z = 0
        [4, 5, 7, 6], // z = a
        [0, 1, 5, 4], // y = 0
        [2, 6, 7, 3], // y = a
        [0, 4, 6, 2], // x = 0
        [1, 3, 7, 5], // x = a
    ];
    let mut t = Vec::new();
    for q in quads {
        t.push([v(q[0]), v(q[1]), v(q[2])]);
        t.push([v(q[0]), v(q[2]), v(q[3])]);
    }
    t
}

fn write_binary_stl(path: &Path, tris: &[Tri]) {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        b.extend_from_slice(&[0u8; 12]);
        for p in t {
            for c in p {
                b.extend_from_slice(&(*c as f32).to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    std::fs::write(path, b).unwrap();
}

fn write_ascii_stl(path: &Path, tris: &[Tri]) {
    let mut s = String::from("solid cube\n");
    for t in tris {
        s.push_str("facet normal 0 0 0\n outer loop\n");
        for p in t {
            s.push_str(&format!("  vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        s.push_str(" endloop\nendfacet\n");
    }
    s.push_str("endsolid cube\n");
    std::fs::write(path, s).unwrap();
}

fn volume3(w: &World<3>) -> f64 {
    w.op.base_vol.iter().sum()
}

#[test]
fn a_box_shape_fills_bit_for_bit_as_the_box_body() {
    // The lattice of a body with shapes is anchored at boxes[0].min (else the origin), so a box
    // given as a shape on that lattice is the box body: same particles, volumes l0^3, and the
    // same run to the bit.
    let dp: f64 = 0.02;
    let r = json!({"min": [0.0, 0.0, 0.0], "max": [0.2, 0.08, 0.06]});
    let with_gravity = |mut v: Value| {
        v["gravity"] = json!({"vector": [0.0, 0.0, -9.81]});
        scene_in(&v, None).unwrap()
    };
    let plain = with_gravity(one_body(3, dp, json!({"boxes": [r.clone()]})));
    let shaped = with_gravity(one_body(3, dp, json!({"shapes": [{"box": r}]})));
    let (a, b) = (world3(&plain), world3(&shaped));
    assert_eq!(a.p.x0, b.p.x0);
    assert_eq!(a.p.mass, b.p.mass);
    assert_eq!(a.op.base_vol, b.op.base_vol);
    let mut sa = Simulation::new(&plain).unwrap();
    let mut sb = Simulation::new(&shaped).unwrap();
    for s in [&mut sa, &mut sb] {
        s.advance_to(0.005).unwrap();
    }
    assert_eq!(
        sa.particle_snapshot().position,
        sb.particle_snapshot().position
    );
}

#[test]
fn sphere_cylinder_and_disc_volumes_are_within_half_a_percent_at_10_across() {
    // The target: the solid's volume (and mass) to 0.5 % at 10 particles across, where
    // the staircase (l0^3 per lattice point inside) is off by up to 1.9 % here (cylinder along
    // x; it depends on where the lattice falls) and is not bounded in general. The cells the surface cuts
    // are integrated on 6^3 sub-cells (8^2 in 2D) with the signed distance's ramp, whose
    // error is second order in the sub-cell (1e-4 here), so 0.5 % holds with margin.
    let dp: f64 = 0.01;
    let r: f64 = 0.05;
    let rho = 1000.0;
    let cases: Vec<(&str, Value, f64)> = vec![
        (
            "sphere",
            json!({"sphere": {"center": [0.0013, -0.0021, 0.0007], "radius": r}}),
            4.0 / 3.0 * PI * r.powi(3),
        ),
        (
            "cylinder along x",
            json!({"cylinder": {"center": [0.0, 0.0, 0.0], "axis": [1.0, 0.0, 0.0], "radius": r, "length": 0.3}}),
            PI * r * r * 0.3,
        ),
        (
            "oblique cylinder",
            json!({"cylinder": {"center": [0.0, 0.0, 0.0], "axis": [1.0, 0.7, 0.3], "radius": r, "length": 0.2}}),
            PI * r * r * 0.2,
        ),
    ];
    for (what, shape, exact) in cases {
        let s = scene_in(&one_body(3, dp, json!({"shapes": [shape]})), None).unwrap();
        let w = world3(&s);
        let v = volume3(&w);
        let m: f64 = w.p.mass.iter().sum();
        let staircase = w.len() as f64 * dp.powi(3);
        eprintln!(
            "{what}: volume {:+.4} %, staircase {:+.3} %, {} particles",
            100.0 * (v / exact - 1.0),
            100.0 * (staircase / exact - 1.0),
            w.len()
        );
        assert!((v / exact - 1.0).abs() < 5e-3, "{what}: {v} vs {exact}");
        assert!((m / (rho * exact) - 1.0).abs() < 5e-3, "{what}: mass {m}");
    }
    // 2D: a disc of 10 across (area per m of depth).
    let s = scene_in(
        &one_body(
            2,
            dp,
            json!({"shapes": [{"sphere": {"center": [0.0, 0.0], "radius": r}}]}),
        ),
        None,
    )
    .unwrap();
    let w = world2(&s);
    let a: f64 = w.op.base_vol.iter().sum();
    assert!((a / (PI * r * r) - 1.0).abs() < 5e-3, "disc area {a}");
}

#[test]
fn surface_particles_carry_the_solids_normal_and_area() {
    // The sphere's surface area from the particles' shares (the divergence theorem on each cell:
    // exact for a plane, so the error is the sub-cell sampling of the cell faces, ~1e-3) and
    // normals along the radius (the share of a surface patch of a particle's cells: its mean
    // normal is radial to O(dp / R)^2 over the patch, 0.99 here).
    let dp: f64 = 0.01;
    let r: f64 = 0.05;
    let s = scene_in(
        &one_body(
            3,
            dp,
            json!({"shapes": [{"sphere": {"center": [0.0, 0.0, 0.0], "radius": r}}]}),
        ),
        None,
    )
    .unwrap();
    let w = world3(&s);
    let area: f64 = w.surface.iter().map(|(_, a)| a).sum();
    let exact = 4.0 * PI * r * r;
    eprintln!("sphere area {:+.3} %", 100.0 * (area / exact - 1.0));
    assert!((area / exact - 1.0).abs() < 0.01, "area {area} vs {exact}");
    let mut carriers = 0;
    for (i, (n, a)) in w.surface.iter().enumerate() {
        if *a > 0.0 {
            carriers += 1;
            let radial = w.p.x0[i].normalize();
            assert!(
                n.dot(&radial) > 0.95,
                "particle {i}: normal {n:?} at {:?}",
                w.p.x0[i]
            );
        }
    }
    assert!(carriers > 100, "{carriers} surface particles");
}

#[test]
fn cuts_make_holes_and_half_spaces_cut() {
    // A plate with a round hole: volume within 0.5 % of (W L - pi a^2) t. A cut removes its
    // solid; a half-space is the side its normal points away from, so the cut that keeps
    // x < 0.35 has its normal along -x (out of the removed side, into what stays).
    let dp: f64 = 0.01;
    let v = one_body(
        3,
        dp,
        json!({
            "boxes": [{"min": [0.0, 0.0, 0.0], "max": [0.4, 0.2, 0.04]}],
            "cuts": [
                {"cylinder": {"center": [0.2, 0.1, 0.02], "axis": [0.0, 0.0, 1.0], "radius": 0.04, "length": 1.0}},
                {"half_space": {"point": [0.35, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0]}}
            ]
        }),
    );
    let w = world3(&scene_in(&v, None).unwrap());
    let exact = (0.35 * 0.2 - PI * 0.04 * 0.04) * 0.04;
    let vol = volume3(&w);
    assert!((vol / exact - 1.0).abs() < 5e-3, "{vol} vs {exact}");
    assert!(w.p.x0.iter().all(|p| p.x < 0.35));
    assert!(w
        .p
        .x0
        .iter()
        .all(|p| ((p.x - 0.2).powi(2) + (p.y - 0.1).powi(2)).sqrt() > 0.04));
}

#[test]
fn boundaries_loads_and_probes_select_by_shape() {
    let dp: f64 = 0.01;
    let mut v = one_body(
        3,
        dp,
        json!({"shapes": [{"cylinder": {"center": [0.15, 0.0, 0.0], "axis": [1.0, 0.0, 0.0], "radius": 0.03, "length": 0.3}}]}),
    );
    v["boundaries"] = json!([{
        "name": "root", "kind": "clamped", "body": "part",
        "shape": {"half_space": {"point": [0.02, 0.0, 0.0], "normal": [1.0, 0.0, 0.0]}}
    }]);
    v["loads"] = json!([{
        "name": "tip", "body": "part",
        "shape": {"sphere": {"center": [0.3, 0.0, 0.0], "radius": 0.02}}
    }]);
    // On the curved surface, not in any box: found through the body's solid.
    v["probes"] = json!([{"name": "side", "point": [0.15, 0.0, 0.03]}]);
    let s = scene_in(&v, None).unwrap();
    let sim = Simulation::new(&s).unwrap();
    // The section of radius 3 l0 on the lattice (centres at odd multiples of l0 / 2): per
    // quadrant the 3 x 3 centres but the corner (0.025, 0.025), 8, so 32 per layer; the
    // half-space x <= 0.02 holds the layers at x = 0.005 and 0.015.
    assert_eq!(
        sim.group_size(0),
        2 * 32,
        "two layers of the 32-particle section"
    );
    assert!(sim.load_size(0) > 0);
    let at = sim.probe_particle_position(0);
    assert!((at[2] - 0.025).abs() < 1e-9, "{at:?}");
    // A selection that holds no particle names the shape.
    v["loads"][0]["shape"]["sphere"]["center"] = json!([1.0, 1.0, 1.0]);
    let e = Simulation::new(&scene_in(&v, None).unwrap())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("loads[0] ('tip').shape") && e.contains("no particle"),
        "{e}"
    );
}

#[test]
fn stl_meshes_binary_and_ascii_fill_to_their_volume() {
    let dir = TempDir::new("stl");
    // A 50 mm cube in millimetres at 0.001 and 2 mm particles, turned and moved: 25 across.
    write_binary_stl(&dir.0.join("cube.stl"), &cube_triangles(50.0));
    write_ascii_stl(&dir.0.join("cube_ascii.stl"), &cube_triangles(0.05));
    for (file, scale) in [("cube.stl", 0.001), ("cube_ascii.stl", 1.0)] {
        let v = one_body(
            3,
            0.002,
            json!({"shapes": [{"mesh": {"file": file, "scale": scale, "rotate_deg": [0.0, 0.0, 30.0], "translate": [0.1, 0.0, 0.0]}}]}),
        );
        let s = scene_in(&v, Some(&dir.0)).unwrap();
        let w = world3(&s);
        let vol = volume3(&w);
        assert!((vol / 1.25e-4 - 1.0).abs() < 2e-3, "{file}: {vol}");
        // Turned by 30 degrees about z and moved by 0.1 m along x.
        let xmax = w.p.x0.iter().map(|p| p.x).fold(f64::MIN, f64::max);
        let expect = 0.1 + 0.05 * 30f64.to_radians().cos();
        assert!(
            (xmax - expect).abs() < 0.002,
            "{file}: x max {xmax} vs {expect}"
        );
    }
}

/// The error of a one-body scene whose shape is an STL mesh of these triangles.
fn mesh_error(tag: &str, tris: &[Tri], scale: f64) -> String {
    let dir = TempDir::new(tag);
    write_binary_stl(&dir.0.join("m.stl"), tris);
    let v = one_body(
        3,
        0.01,
        json!({"shapes": [{"mesh": {"file": "m.stl", "scale": scale}}]}),
    );
    scene_in(&v, Some(&dir.0)).unwrap_err().to_string()
}

#[test]
fn bad_meshes_are_errors_naming_the_field_and_reason() {
    let f = "bodies[0] ('part').shapes[0].mesh";
    let cube = cube_triangles(0.1);
    // Not closed: one triangle missing.
    let e = mesh_error("open", &cube[1..], 1.0);
    assert!(
        e.contains(f) && e.contains("not closed") && e.contains("hole"),
        "{e}"
    );
    // Not manifold: two cubes sharing an edge (four triangles on it).
    let mut two = cube.clone();
    two.extend(
        cube.iter()
            .map(|t| t.map(|p| [p[0] + 0.1, p[1] + 0.1, p[2]])),
    );
    let e = mesh_error("nonmanifold", &two, 1.0);
    assert!(e.contains(f) && e.contains("not manifold"), "{e}");
    // Zero volume: a triangle and its reverse, back to back (closed and consistently
    // oriented: every edge once each way).
    let (a, b, c) = ([0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]);
    let flat = vec![[a, b, c], [a, c, b]];
    let e = mesh_error("flat", &flat, 1.0);
    assert!(e.contains(f) && e.contains("encloses no volume"), "{e}");
    // Units off by 1000: a 2000 mm part read as metres.
    let e = mesh_error("units", &cube_triangles(2000.0), 1.0);
    assert!(
        e.contains(&format!("{f}.scale")) && e.contains("2000") && e.contains("0.001"),
        "{e}"
    );
    // Smaller than one particle.
    let e = mesh_error("tiny", &cube_triangles(0.004), 1.0);
    assert!(
        e.contains(&format!("{f}.scale")) && e.contains("less than one particle"),
        "{e}"
    );
    // Missing file, and a file that is not STL.
    let v = one_body(
        3,
        0.01,
        json!({"shapes": [{"mesh": {"file": "nowhere.stl"}}]}),
    );
    let e = scene_in(&v, None).unwrap_err().to_string();
    assert!(
        e.contains(&format!("{f}.file")) && e.contains("nowhere.stl"),
        "{e}"
    );
    let dir = TempDir::new("garbage");
    std::fs::write(dir.0.join("g.stl"), b"solid x\nthis is not an stl\n").unwrap();
    let v = one_body(3, 0.01, json!({"shapes": [{"mesh": {"file": "g.stl"}}]}));
    let e = scene_in(&v, Some(&dir.0)).unwrap_err().to_string();
    assert!(e.contains(&format!("{f}.file")), "{e}");
    // A mesh in a 2D scene.
    let v = one_body(2, 0.01, json!({"shapes": [{"mesh": {"file": "g.stl"}}]}));
    let e = scene_in(&v, Some(&dir.0)).unwrap_err().to_string();
    assert!(
        e.contains("bodies[0] ('part').shapes[0]") && e.contains("3D"),
        "{e}"
    );
}

#[test]
fn inverted_meshes_are_turned_round_with_a_warning() {
    let dir = TempDir::new("inverted");
    let inv: Vec<Tri> = cube_triangles(0.05)
        .iter()
        .map(|t| [t[0], t[2], t[1]])
        .collect();
    write_binary_stl(&dir.0.join("inv.stl"), &inv);
    let v = one_body(3, 0.005, json!({"shapes": [{"mesh": {"file": "inv.stl"}}]}));
    let s = scene_in(&v, Some(&dir.0)).unwrap();
    let w = s.warnings();
    assert!(
        w.iter()
            .any(|w| w.field == "bodies[0] ('part').shapes[0].mesh.file"
                && w.message.contains("face inward")),
        "{w:?}"
    );
    let vol = volume3(&world3(&s));
    assert!((vol / 1.25e-4 - 1.0).abs() < 2e-3, "{vol}");
}

/// The warning of a body filled from shapes is for a user who knows the scene format, not the
/// solver: it names the body, the size of the effect and the remedy in scene terms, and points to
/// no file (an FMU user has only the FMU). Issue 24/27: the old text said "summation-by-parts
/// closure", "plain fits" and "docs/model.md".
#[test]
fn the_shape_accuracy_warning_speaks_the_scene_format() {
    let mut v = one_body(
        3,
        0.01,
        json!({"shapes": [{"cylinder": {"axis": [1.0, 0.0, 0.0], "center": [0.15, 0.0, 0.0],
                                        "radius": 0.05, "length": 0.3}}]}),
    );
    v["solver"] = json!({});
    let s = scene_in(&v, None).unwrap();
    let w = s.warnings();
    let shape_warning = w
        .iter()
        .find(|w| w.field == "bodies[0] ('part')" && w.message.contains("filled from shapes"))
        .unwrap_or_else(|| panic!("no shape accuracy warning: {w:?}"));
    let m = &shape_warning.message;
    for jargon in [
        "closure",
        "fits",
        "summation",
        "quadrature",
        "docs/",
        ".md",
        "second_order",
    ] {
        assert!(!m.contains(jargon), "'{jargon}' in: {m}");
    }
    for wanted in ["'part'", "%", "particle_spacing", "0.01 m"] {
        assert!(m.contains(wanted), "'{wanted}' missing from: {m}");
    }
}

#[test]
fn bad_shapes_are_errors_naming_the_field_and_reason() {
    let err = |body: Value, d: usize| {
        scene_in(&one_body(d, 0.01, body), None)
            .unwrap_err()
            .to_string()
    };
    // Smaller than one particle.
    let e = err(
        json!({"shapes": [{"sphere": {"center": [0.0, 0.0, 0.0], "radius": 0.003}}]}),
        3,
    );
    assert!(
        e.contains("shapes[0].radius") && e.contains("smaller than one particle"),
        "{e}"
    );
    // A cut that removes the whole body.
    let s = scene_in(
        &one_body(
            3,
            0.01,
            json!({
                "shapes": [{"sphere": {"center": [0.0, 0.0, 0.0], "radius": 0.05}}],
                "cuts": [{"half_space": {"point": [0.0, 0.0, 0.06], "normal": [0.0, 0.0, 1.0]}}]
            }),
        ),
        None,
    )
    .unwrap();
    let e = Simulation::new(&s).err().expect("refused").to_string();
    assert!(
        e.contains("bodies[0] ('part').cuts") && e.contains("remove the whole body"),
        "{e}"
    );
    // A half-space as a body's shape (unbounded).
    let e = err(
        json!({"shapes": [{"half_space": {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}}]}),
        3,
    );
    assert!(e.contains("shapes[0]") && e.contains("unbounded"), "{e}");
    // A 3D cylinder without its axis; a 2D one with an axis.
    let e = err(
        json!({"shapes": [{"cylinder": {"center": [0.0, 0.0, 0.0], "radius": 0.05, "length": 0.2}}]}),
        3,
    );
    assert!(e.contains("shapes[0].axis"), "{e}");
    let e = err(
        json!({"shapes": [{"cylinder": {"center": [0.0, 0.0], "radius": 0.05, "axis": [1.0, 0.0, 0.0]}}]}),
        2,
    );
    assert!(e.contains("shapes[0]") && e.contains("disc"), "{e}");
    // No box and no shape.
    let e = err(json!({}), 3);
    assert!(
        e.contains("bodies[0] ('part').boxes") && e.contains("box or shape"),
        "{e}"
    );
    // An unknown shape kind is a parse error naming the path.
    let e = err(json!({"shapes": [{"torus": {}}]}), 3);
    assert!(e.contains("bodies[0].shapes[0]"), "{e}");
}

#[test]
fn existing_scene_files_read_unchanged() {
    // `boxes` stays, the new fields are optional: every committed scene reads, and its
    // bodies have no shapes.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for f in [
        "tests/data/small2d.json",
        "tests/data/small3d.json",
        "scenes/case1_column.json",
    ] {
        let s = Scene::load(&root.join(f)).unwrap();
        assert!(
            s.bodies
                .iter()
                .all(|b| b.shapes.is_empty() && b.cuts.is_empty()),
            "{f}"
        );
    }
}

/// The converged value of a quantity of a FEM reference file.
fn fem(file: &str, q: &str) -> f64 {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("reference")
        .join(file);
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    v["converged"]["quantities"][q]["value"].as_f64().unwrap()
}

#[test]
#[ignore = "slow (linearised statics and first mode of 1,800 particles in 3D): the full test command runs it"]
fn cylinder_cantilever_against_the_fem() {
    // scenes/cylinder_cantilever.json: R = 0.05 m, L = 1 m at 6 particles across, mirrored
    // clamp, second_order with the particles' volumes of the cylinder. Linearised static tip
    // deflection under gravity and first frequency against the Hex27 FEM (+-0.004 %).
    use mps_solid::physics::Vect;
    use mps_solid::studies::linear::{field_at, Linearised};
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = Scene::load(&root.join("scenes/cylinder_cantilever.json")).unwrap();
    let mut w = world3(&s);
    let (u, f1) = {
        let mut lin = Linearised::new(&w).unwrap();
        let u = lin
            .static_gravity(Vect::<3>::new(0.0, 0.0, -9.81), 1e-8)
            .unwrap();
        let (omega, _) = lin.lowest_mode(&u, 1e-8).unwrap();
        (u, omega / (2.0 * PI))
    };
    let tip = field_at(&mut w, &u, &Vect::<3>::new(1.0, 0.0, 0.0), Some(0)).unwrap();
    let (f_ref, u_ref) = (
        fem("cylinder3d_fem.json", "f1_hz"),
        fem("cylinder3d_fem.json", "static_tip_uz_m"),
    );
    let (ef, eu) = (f1 / f_ref - 1.0, tip.z / u_ref - 1.0);
    eprintln!(
        "cylinder 6 across: f1 {f1:.5} Hz ({:+.3} %), tip {:.6e} m ({:+.3} %), {} particles",
        100.0 * ef,
        tip.z,
        100.0 * eu,
        w.len()
    );
    // The 1 %. Measured -0.127 % / +0.242 % (4 across -> 0.024 / -0.056 %, 8 across
    // -0.076 / +0.149 %): the cell energy integrates over each particle's solid with its
    // moments. Before (l0^2 / 12 at every particle): +2.32 % / -4.51 %, the section 5.3 % too
    // stiff in bending.
    assert!(
        ef.abs() < 0.01 && eu.abs() < 0.01,
        "f1 {ef:+.4}, tip {eu:+.4}"
    );
}

#[test]
#[ignore = "slow (linearised statics and first mode of 1,500 particles): the full test command runs it"]
fn plate_with_a_round_hole_against_the_fem() {
    // scenes/plate_round_hole.json without gravity: f1 of the plate and the end's u_x under a
    // traction of 1e5 Pa on x = 0.8 m (as the FEM: 2e4 N per m of depth over the end layer),
    // 6 particles across each ligament.
    use mps_solid::physics::Vect;
    use mps_solid::studies::linear::{field_at, Linearised};
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = Scene::load(&root.join("scenes/plate_round_hole.json")).unwrap();
    let model = Model::<2>::build(&s).unwrap();
    let mut w = model.world;
    let end: Vec<usize> = (0..w.len()).filter(|&i| w.p.x0[i].x > 0.79).collect();
    let mut rhs = vec![Vect::<2>::zeros(); w.len()];
    for &i in &end {
        rhs[i] = Vect::<2>::new(2e4 / end.len() as f64, 0.0);
    }
    let (u, f1) = {
        let mut lin = Linearised::new(&w).unwrap();
        let n = rhs.len();
        let (u, _) = lin.solve(&rhs, 1e-10, 40 * n + 1000).unwrap();
        let start: Vec<Vect<2>> =
            w.p.x0
                .iter()
                .map(|p| Vect::<2>::new(0.0, p.x * p.x))
                .collect();
        let (omega, _) = lin.lowest_mode(&start, 1e-10).unwrap();
        (u, omega / (2.0 * PI))
    };
    let ux = field_at(&mut w, &u, &Vect::<2>::new(0.8, 0.0), Some(0))
        .unwrap()
        .x;
    let (f_ref, u_ref) = (
        fem("plate_round_hole2d_fem.json", "f1_hz"),
        fem("plate_round_hole2d_fem.json", "end_ux_centre_m"),
    );
    let (ef, eu) = (f1 / f_ref - 1.0, ux / u_ref - 1.0);
    eprintln!(
        "plate with a round hole, 6 across the ligament: f1 {f1:.5} Hz ({:+.3} %), end u_x {ux:.6e} m ({:+.3} %), {} particles",
        100.0 * ef,
        100.0 * eu,
        w.len()
    );
    // The 1 %. Measured -0.239 % / +0.746 % (before the cell moments: -0.27 / +1.00 %).
    assert!(
        ef.abs() < 0.01 && eu.abs() < 0.01,
        "f1 {ef:+.4}, u_x {eu:+.4}"
    );
}

#[test]
#[ignore = "slow (two 3D impacts of 4,500 particles, 20 s): the full test command runs it"]
fn ball_on_a_thick_plate_conserves_energy_and_lasts_as_hertz_says() {
    // A ball of radius R = 0.05 m (10 particles across, filled from a sphere) at v = 1 m/s onto
    // a block 0.2 x 0.2 x 0.1 m whose base is held, both E = 1 MPa, nu = 0.3, rho = 1000, both
    // operators at the default safety. Energy: the staggered energy (as
    // energy_drift::contact_impact_returns_its_energy) after the ball has left, against before
    // the impact: the box tests' bound of 0.2 % at safety 0.8. Contact time: Hertz's
    // t = 2.87 (m^2 / (R E*^2 v))^(1/5) for a ball on a half-space (E* = E / (2 (1 - nu^2)),
    // both bodies deforming) is 20.4 ms; the target is 10 % at 10 particles across.
    for model in ["corrected", "second_order"] {
        ball_on_a_thick_plate(model);
    }
}

fn ball_on_a_thick_plate(model: &str) {
    let r: f64 = 0.05;
    let dp: f64 = 0.01;
    let (e, nu, rho, v) = (1e6, 0.3, 1000.0, 1.0);
    let mut s = one_body(
        3,
        dp,
        json!({"shapes": [{"sphere": {"center": [0.0, 0.0, r + 0.5 * dp], "radius": r}}], "velocity": [0.0, 0.0, -v]}),
    );
    s["name"] = json!("ball_on_plate");
    s["solver"]["model"] = json!(model);
    s["bodies"][0]["name"] = json!("ball");
    s["bodies"][0]["material"] = json!({"density": rho, "young": e, "poisson": nu});
    s["bodies"].as_array_mut().unwrap().push(json!({
        "name": "block", "material": {"density": rho, "young": e, "poisson": nu},
        "boxes": [{"min": [-0.1, -0.1, -0.1], "max": [0.1, 0.1, 0.0]}]
    }));
    s["boundaries"] = json!([{"name": "base", "kind": "clamped", "body": "block",
        "region": {"min": [-0.1, -0.1, -0.1], "max": [0.1, 0.1, -0.09]}}]);
    s["end_time"] = json!(1.0);
    let scene = scene_in(&s, None).unwrap();
    let mut w = world3(&scene);
    let mass: f64 = (0..w.len())
        .filter(|&i| w.p.body[i] == 0)
        .map(|i| w.p.mass[i])
        .sum();
    let dt = w.max_dt();
    let stag = |w: &World<3>| {
        let k: f64 = (0..w.len())
            .map(|i| {
                let m = w.p.mass[i];
                let vi = w.p.v[i];
                0.5 * m * vi.dot(&(vi + w.internal_force(i) * (dt / m)))
            })
            .sum();
        k + w.strain_energy() + w.contact_energy()
    };
    let e0 = stag(&w);
    let (mut t_on, mut t_off) = (None, None);
    let mut steps = 0u64;
    while t_off.is_none() {
        w.step(dt).unwrap();
        steps += 1;
        let c = w.contact_pairs();
        if c > 0 && t_on.is_none() {
            t_on = Some(w.time);
        }
        if c == 0 && t_on.is_some() {
            t_off = Some(w.time);
        }
        assert!(steps < 100_000, "the ball never left");
    }
    let mut sum = 0.0;
    let n = 1000;
    for _ in 0..n {
        w.step(dt).unwrap();
        sum += stag(&w);
    }
    let drift = sum / n as f64 / e0 - 1.0;
    let estar = e / (2.0 * (1.0 - nu * nu));
    let hertz = 2.87 * (mass * mass / (r * estar * estar * v)).powf(0.2);
    let tc = t_off.unwrap() - t_on.unwrap();
    eprintln!(
        "ball on plate, {model}: mass {mass:.4} kg ({:+.3} % of the sphere's), contact {:.3} ms vs Hertz {:.3} ms ({:+.1} %), energy after {:+.4} %, dt {dt:.3e} s, {} particles",
        100.0 * (mass / (rho * 4.0 / 3.0 * PI * r.powi(3)) - 1.0),
        1e3 * tc,
        1e3 * hertz,
        100.0 * (tc / hertz - 1.0),
        100.0 * drift,
        w.len()
    );
    assert!(drift.abs() < 2e-3, "{model}: energy changed by {drift}");
    // The 10 %. Measured -8.1 % (18.74 ms) with corrected, -0.6 % (20.28 ms) with
    // second_order: the particles meet where the solids do (each stands for the ball inside
    // the solid about its centre). corrected: -4.9 % at 20 across, -5.0 % on a block 0.2 m
    // thick (a block held at its base is stiffer than Hertz's half-space), -6.6 to -9.5 % for
    // other placements of the ball on the lattice and speeds of 0.5 to 2 m/s. Before, every
    // pair met at l0 and the ball's flat bottom layer, a spacing above the sphere's lowest
    // point, hit as a flat punch: 12.3 ms (-40 %) with corrected.
    assert!(
        (tc / hertz - 1.0).abs() < 0.10,
        "{model}: contact {tc} s vs Hertz {hertz} s"
    );
}

#[test]
fn the_stl_bracket_fills_to_its_solid() {
    // scenes/bracket_stl.json: the STL L-bracket (mm, scale 0.001) less the half-space bevel,
    // 4 particles through its 20 mm legs. Its solid: the profile of tools/make_bracket_stl.py
    // (area 3998.569 mm^2) clipped by the bevel z <= x + 90 mm (a 10 x 10 mm triangle: 50
    // mm^2) times the 60 mm width: 2.369141e-4 m^3. The particles' volumes add up to it within
    // the 0.5 % (measured +0.003 %; the lattice's staircase, l0^3 per particle, is
    // -1.44 % off: the fillet's and the bevel's cut cells).
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = Scene::load(&root.join("scenes/bracket_stl.json")).unwrap();
    let w = world3(&s);
    let exact = 3948.5691474067917 * 60.0 * 1e-9;
    let vol = volume3(&w);
    let staircase = w.len() as f64 * s.particle_spacing.powi(3);
    eprintln!(
        "STL bracket: volume {:+.3} %, staircase {:+.3} %, {} particles",
        100.0 * (vol / exact - 1.0),
        100.0 * (staircase / exact - 1.0),
        w.len()
    );
    assert!(
        (vol / exact - 1.0).abs() < 5e-3,
        "{vol} m^3 against {exact}"
    );
}

#[test]
fn cell_moments_integrate_quadratics_over_the_solid() {
    // The second-order operator's cell energy integrates a quadratic density over each
    // particle's solid with the particle's volume V and moments (c1, c2) per unit volume about
    // its centre x: int p = sum_i V (p(x) + c1 . grad p + 1/2 c2 : grad grad p). For p = x_a x_b
    // over a ball (R = 0.05 m at 10 across, centre off the lattice) that is
    // sum_i V (x_a x_b + c1_a x_b + c1_b x_a + c2_ab) against 4/15 pi R^5 delta_ab about the
    // centre. The sub-cell integration of the cut cells (6^3 sub-cells, a linear ramp of the
    // distance across each) bounds it: measured 0.16 % at most (the volume itself: 0.03 %),
    // held to 0.5 % and to a third of the whole-cell rule's error (c1 = 0, c2 = l0^2 / 12 I at
    // every particle: 0.86 % here; 5.3 % in the bending of the 6-across round cantilever's
    // section, where l0 / R is larger).
    let (r, dp) = (0.05f64, 0.01f64);
    let c = [0.0031, -0.0017, 0.0043];
    let mut v = one_body(
        3,
        dp,
        json!({"shapes": [{"sphere": {"center": c, "radius": r}}]}),
    );
    v["solver"] = json!({"model": "second_order"});
    let w = world3(&scene_in(&v, None).unwrap());
    let exact = 4.0 / 15.0 * PI * r.powi(5);
    let mut with = [[0.0f64; 3]; 3];
    let mut whole = [[0.0f64; 3]; 3];
    for i in 0..w.len() {
        let vol = w.op.vol[i];
        let (c1, c2) = &w.op.cell_moments[i];
        let x: [f64; 3] = std::array::from_fn(|a| w.p.x0[i][a] - c[a]);
        for a in 0..3 {
            for b in 0..3 {
                with[a][b] += vol * (x[a] * x[b] + c1[a] * x[b] + c1[b] * x[a] + c2[(a, b)]);
                let cell = if a == b { dp * dp / 12.0 } else { 0.0 };
                whole[a][b] += vol * (x[a] * x[b] + cell);
            }
        }
    }
    let (mut worst, mut worst_whole) = (0.0f64, 0.0f64);
    for a in 0..3 {
        for b in 0..3 {
            let want = if a == b { exact } else { 0.0 };
            worst = worst.max((with[a][b] - want).abs() / exact);
            worst_whole = worst_whole.max((whole[a][b] - want).abs() / exact);
        }
    }
    eprintln!(
        "ball at 10 across, int x_a x_b: moments {:.3} %, whole cells {:.3} %",
        100.0 * worst,
        100.0 * worst_whole
    );
    assert!(worst < 5e-3, "with the moments: {with:?} against {exact:e}");
    assert!(
        worst < worst_whole / 3.0,
        "moments {worst}, whole cells {worst_whole}"
    );
}

#[test]
fn forces_of_a_body_filled_from_a_solid_are_its_energy_gradient() {
    // The cell moments' terms (first moments included, which a whole cell has not) enter the
    // forces as the gradient of the same energy: a free cylinder with cuts, second_order, at a
    // random displacement (module bending_accuracy's check: central differences, 1e-6).
    let dp = 0.01;
    let mut v = one_body(
        3,
        dp,
        json!({"shapes": [{"cylinder": {"axis": [1.0, 0.0, 0.0], "center": [0.0, 0.0, 0.0],
                                        "radius": 0.035, "length": 0.1}}],
               "cuts": [{"sphere": {"center": [0.05, 0.0, 0.03], "radius": 0.02}}]}),
    );
    v["solver"] = json!({"model": "second_order"});
    let mut w = world3(&scene_in(&v, None).unwrap());
    assert!(w
        .op
        .cell_moments
        .iter()
        .any(|(c1, _)| c1.norm() > 1e-3 * dp));
    crate::bending_accuracy::assert_forces_are_the_energy_gradient(
        &mut w,
        dp,
        2718281828,
        &[],
        mps_solid::physics::Vect::<3>::zeros(),
    );
}

#[test]
fn a_ball_touches_a_plate_where_its_solid_does() {
    // Contact starts where the solids meet, not where the lattice's staircase does: a ball of
    // 10 particles across a tenth of a spacing above a plate has no contact pair and no contact
    // energy; a tenth of a spacing into it, it has. (With every pair meeting at l0 the ball's
    // bottom layer, up to a spacing above the sphere's lowest point, touched only when the
    // solids overlapped by up to a spacing.) Several placements of the ball on the lattice.
    let (r, dp) = (0.05f64, 0.01f64);
    for (k, off) in [[0.0, 0.0], [0.003, 0.001], [0.005, 0.005], [0.0071, 0.0023]]
        .iter()
        .enumerate()
    {
        for (gap, touching) in [(0.1, false), (-0.1, true)] {
            let mut s = one_body(
                3,
                dp,
                json!({"shapes": [{"sphere": {"center": [off[0], off[1], r + gap * dp], "radius": r}}]}),
            );
            s["bodies"][0]["name"] = json!("ball");
            s["bodies"].as_array_mut().unwrap().push(json!({
                "name": "plate", "material": material(),
                "boxes": [{"min": [-0.08, -0.08, -0.03], "max": [0.08, 0.08, 0.0]}]
            }));
            let w = world3(&scene_in(&s, None).unwrap());
            let (pairs, energy) = (w.contact_pairs(), w.contact_energy());
            assert_eq!(
                (pairs > 0, energy > 0.0),
                (touching, touching),
                "placement {k}, ball {gap} spacings above the plate: {pairs} pairs, contact energy {energy} J"
            );
        }
    }
}

#[test]
fn snapshots_and_surface_meshes_show_the_shapes() {
    // The VTU snapshot carries each particle's volume, normal and area; the surface mesh lies
    // on the solid (within a spacing where the cut meets the sphere), faces out, and its
    // vertices follow the particles.
    let dp: f64 = 0.01;
    let r: f64 = 0.05;
    let mut v = one_body(
        3,
        dp,
        json!({
            "shapes": [{"sphere": {"center": [0.0, 0.0, 0.0], "radius": r}}],
            "cuts": [{"half_space": {"point": [0.0, 0.0, 0.03], "normal": [0.0, 0.0, -1.0]}}],
            "velocity": [0.0, 0.0, -1.0]
        }),
    );
    v["end_time"] = json!(0.002);
    let s = scene_in(&v, None).unwrap();
    let mut sim = Simulation::new(&s).unwrap();
    let snap = sim.particle_snapshot();
    let n = snap.position.len();
    assert_eq!(
        (snap.volume.len(), snap.normal.len(), snap.area.len()),
        (n, n, n)
    );
    let dir = TempDir::new("surface");
    let vtu = dir.0.join("s.vtu");
    mps_solid::output::write_vtu(&vtu, &snap).unwrap();
    let text = std::fs::read_to_string(&vtu).unwrap();
    for name in ["\"volume\"", "\"normal\"", "\"area\""] {
        assert!(text.contains(name), "{name} missing");
    }
    let mesh = sim.surface_mesh(&s).unwrap();
    assert!(mesh.cells.len() > 200, "{} triangles", mesh.cells.len());
    let mut outward = 0;
    for c in &mesh.cells {
        let p: Vec<[f64; 3]> = c.iter().map(|&i| mesh.points[i as usize]).collect();
        let cen: [f64; 3] = std::array::from_fn(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
        let e1: [f64; 3] = std::array::from_fn(|k| p[1][k] - p[0][k]);
        let e2: [f64; 3] = std::array::from_fn(|k| p[2][k] - p[0][k]);
        let nrm = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        // Out of the cut ball: along +z on the flat face, along the radius elsewhere.
        let dir = if cen[2] > 0.03 - 1e-9 {
            [0.0, 0.0, 1.0]
        } else {
            cen
        };
        if nrm[0] * dir[0] + nrm[1] * dir[1] + nrm[2] * dir[2] > 0.0 {
            outward += 1;
        }
        for q in &p {
            let rad = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            // Seams where the cut meets the sphere are jagged at the scale of l0.
            assert!(
                rad <= r + dp && q[2] <= 0.03 + dp,
                "vertex {q:?} off the solid"
            );
        }
    }
    assert!(
        outward as f64 > 0.98 * mesh.cells.len() as f64,
        "{outward} of {} face out",
        mesh.cells.len()
    );
    sim.advance_to(0.002).unwrap();
    let u = sim.surface_displacement(&mesh);
    assert!(
        u.iter().all(|d| (d[2] + 0.002).abs() < 1e-4),
        "a free ball moves as one"
    );
    mps_solid::output::write_surface_vtu(&dir.0.join("surface.vtu"), &mesh, &u, sim.time())
        .unwrap();
}

/// Asserts the linearised first frequency and static tip deflection of a family case within
/// `f1` and `tip` (relative) of its FEM reference, printing both.
fn assert_family_within(case: &mps_solid::studies::family::FamilyCase, f1: f64, tip: f64) {
    let b = mps_solid::studies::bending::linear_bending(&case.scene).unwrap();
    let (ef, eu) = (
        b.f1 / case.reference.f1 - 1.0,
        b.tip / case.reference.static_u - 1.0,
    );
    eprintln!(
        "{}: f1 {:+.3} %, static {:+.3} %",
        case.name,
        100.0 * ef,
        100.0 * eu
    );
    assert!(
        ef.abs() < f1 && eu.abs() < tip,
        "{}: f1 {ef:+.5}, static {eu:+.5}",
        case.name
    );
}

#[test]
fn a_box_given_as_a_shape_bends_as_the_box_wherever_it_sits() {
    // The GMS plate (plane strain) and its 3 clamp wall layers written as one `box` shape, as
    // a user who draws solids writes it. Its lattice is its own: centred on the solid, so a
    // side of a whole number of spacings falls on the cell faces wherever the body sits, and
    // the second-order operator's closure serves it as it serves the box body. Before, the
    // lattice was anchored at the origin: 5 across, the faces cut the outer cells in half,
    // the closure took the 4 particles inside for a box of 4 across and dropped the rest of
    // the section (static deflection +55.8 %, f1 -19.8 %).
    use mps_solid::studies::family::shape_written;
    for (across, offset) in [(5.0, 0.0), (4.0, 0.3)] {
        // The box body's own figures (-0.017 / +0.030 % at 5 across, -0.008 / +0.003 % at 4)
        // and at most 0.1 %: the closure's accuracy on one box (docs/model.md).
        assert_family_within(&shape_written(2, across, offset), 1e-3, 1e-3);
    }
}

#[test]
fn a_box_shape_whose_sides_cut_cells_is_closed_at_its_faces() {
    // The same plate 8.5 and 8.4 particle spacings thick: the lattice centred on it leaves 9
    // particles with the faces a quarter spacing beyond the outer ones, and 8 with the faces
    // 0.7 spacings beyond. The closure takes the faces where they are (volumes integrating
    // cubics over the solid, face points on the faces). Before, the closure threw the cut
    // cells' volumes away and closed the particles' own box (8.5 across: f1 -5.8 %, static
    // +12.8 %); with the plain fits and the cut cells' volumes instead, the faces were first
    // order: -0.30 / +0.61 % at 8.5 across, -0.47 / +0.97 % at 4.5, -0.15 / +0.30 % at 16.5.
    use mps_solid::studies::family::shape_written;
    for across in [8.5, 8.4] {
        let case = shape_written(2, across, 0.0);
        let w = Model::<2>::build(&case.scene).unwrap();
        assert!(
            w.world.closure.iter().all(|r| r.is_ok()),
            "{}: {:?}",
            case.name,
            w.world.closure
        );
        // Measured +0.105 / -0.209 % (faces a quarter spacing out) and -0.010 / +0.015 %
        // (0.7 out): the discretisation error of 8 to 9 particles through a bent section with
        // its faces off the cell faces, within issue 24's 0.15 % in f1 at 8 across and, in the
        // deflection, twice it (the quarter-spacing faces converge at first order: 0.42, 0.21,
        // 0.09 % at 4.5, 8.5, 16.5 across).
        assert_family_within(&case, 1.5e-3, 3e-3);
    }
}

#[test]
fn a_region_face_inside_a_cut_box_cell_is_warned_of_with_the_spacings_either_side() {
    // Case 2 written as a box shape at dp = 0.045 m: the solid spans 28.22 spacings along x,
    // so its centred lattice puts no cell face at x = 0 or x = 1 m where the regions of the
    // clamp and the support end; each group then holds the body from the nearest cell face,
    // 0.005 m away (the beam 0.01 m shorter: f1 +1.4 %, peak -3.1 % against the FEM, where
    // dp = 1/22 m gives -0.20 / +0.24 %). Each group is warned of with
    // the spacings on either side of its face, the remedy in the scene's terms. At dp = 1/21 m
    // (whole spacings along x) no such warning; nor for any scene of scenes/ (boxes, or
    // solids other than one box, whose lattice is not centred).
    use mps_solid::studies::cases::case2_shape_scene;
    let off = case2_shape_scene(0.045).warnings();
    for (k, name, sides) in [
        (0, "clamp", "3.00 and 25.22"),
        (1, "support", "25.22 and 3.00"),
    ] {
        let w = off
            .iter()
            .find(|w| w.field.starts_with(&format!("boundaries[{k}] ('{name}')")))
            .unwrap_or_else(|| panic!("no warning on {name}: {off:?}"));
        for part in [
            "28.22 particle spacings along x",
            "0.005 m",
            sides,
            "particle_spacing",
        ] {
            assert!(w.message.contains(part), "{part} not in: {}", w.message);
        }
    }
    assert!(
        !case2_shape_scene(1.0 / 21.0)
            .warnings()
            .iter()
            .any(|w| w.field.starts_with("boundaries")),
        "warned at whole spacings"
    );
}
