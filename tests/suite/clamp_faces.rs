//! Clamps written without a `mirror` field (issue 24): the second-order operator finds the
//! clamped face from the geometry (`physics::world::faces`) and builds the same followers as a
//! mirror clamp, whether the region holds wall layers behind the face, the body's own end
//! layers or a layer on the face; where it cannot (a clamp wrapping an edge, a body too thin
//! behind the face) it keeps the rigid grip and warns, naming the clamp, the estimated effect and
//! the remedy in the scene's terms.
use mps_solid::physics::{ElasticModel, Vect};
use mps_solid::scene::{Model, Region};
use mps_solid::studies::bending::{linear_bending, plate2d_scene, plate_reference};
use mps_solid::studies::family::{single_box, ClampStyle};
use mps_solid::studies::linear::{field_at, Linearised};

/// The GMS plate (plane strain, 4 particles through its thickness) with its clamp written the
/// three natural ways gives what the mirror clamp gives: walls behind the face and the body's
/// own end layers are the mirror's particles exactly (so the same to the linear solves'
/// round-off, 1e-9), a layer on the face (the benchmark's corrected-operator clamp) builds the
/// same followers with the clamp's motion taken from the face layer. All within the issue's
/// 0.3 % of the FEM at 4 across. Before (the rigid grip these scenes kept): walls behind the
/// face -1.09 % / +2.20 % (f1 / static tip), the face layer -0.31 % / +0.61 %.
#[test]
fn natural_clamps_match_the_mirror_clamp() {
    let r = plate_reference();
    let mirror = linear_bending(&single_box(2, 4, ClampStyle::Mirror).scene).unwrap();
    for style in [
        ClampStyle::Walls,
        ClampStyle::EndLayers,
        ClampStyle::FaceLayer,
    ] {
        let case = single_box(2, 4, style);
        let b = linear_bending(&case.scene).unwrap();
        // No warning of reduced accuracy.
        assert!(b.warnings.is_empty(), "{}: {:?}", case.name, b.warnings);
        let (ef, et) = (b.f1 / r.f1 - 1.0, b.tip / r.tip - 1.0);
        assert!(
            ef.abs() < 3e-3 && et.abs() < 3e-3,
            "{}: f1 {:+.3} %, tip {:+.3} %",
            case.name,
            100.0 * ef,
            100.0 * et
        );
        if style != ClampStyle::FaceLayer {
            assert!(
                (b.f1 / mirror.f1 - 1.0).abs() < 1e-9 && (b.tip / mirror.tip - 1.0).abs() < 1e-9,
                "{}: f1 {} / tip {} against the mirror's {} / {}",
                case.name,
                b.f1,
                b.tip,
                mirror.f1,
                mirror.tip
            );
        }
    }
}

/// The axial bar (nu = 0, gravity along the axis: its exact field is quadratic) clamped by a
/// layer on the face and walls, written without a mirror: exact to round-off (below 1e-9) at 4
/// and 8 across, as with the mirror. The same bar whose clamp also holds the first two columns'
/// top and bottom particles (a clamp that wraps the end's edges) cannot have followers: it
/// keeps the grip, slips (tip error above 1e-3, the test's power to tell them apart) and the
/// scene warns, naming the clamp, the effect and the remedy without the solver's vocabulary.
#[test]
fn natural_clamp_is_exact_on_an_axial_bar_and_a_wrapping_clamp_warns() {
    let tip_error = |n: usize, wrap: bool| -> (f64, Vec<String>) {
        let mut s = plate2d_scene(n, ElasticModel::Corrected);
        s.solver.model = ElasticModel::SecondOrder;
        s.bodies[0].material.poisson = 0.0;
        let dp = s.particle_spacing;
        if wrap {
            // Two more clamped regions over the first two columns' outer rows.
            for (name, y0) in [("sleeve", -0.01), ("sleeve_top", 0.01 - dp)] {
                let mut b = s.boundaries[0].clone();
                b.name = name.into();
                b.region = Region {
                    min: vec![0.0, y0],
                    max: vec![2.0 * dp, y0 + dp],
                };
                s.boundaries.push(b);
            }
        }
        let mat = s.bodies[0].material;
        let l = s.bodies[0].boxes[0].max[0];
        let exact = -(mat.density * 9.81 / mat.young) * (0.5 * l * l);
        let mut model = Model::<2>::build(&s).unwrap();
        let warnings = model
            .warnings
            .iter()
            .map(|w| format!("{}: {}", w.field, w.message))
            .collect();
        let u = Linearised::new(&model.world)
            .unwrap()
            .static_gravity(Vect::<2>::new(-9.81, 0.0), 1e-12)
            .unwrap();
        let tip = field_at(&mut model.world, &u, &Vect::<2>::new(l, 0.0), None).unwrap();
        (tip[0] / exact - 1.0, warnings)
    };
    for n in [4, 8] {
        let (e, w) = tip_error(n, false);
        assert!(e.abs() < 1e-9, "tip error {e:e} at {n} across");
        assert!(
            w.iter()
                .all(|m| !m.starts_with("boundaries") && !m.contains("first order")),
            "{w:?}"
        );
    }
    let (e, w) = tip_error(4, true);
    assert!(e.abs() > 1e-3, "wrapping clamp: tip error {e:e}");
    warning_with(
        &w,
        "boundaries[1] ('sleeve')",
        &[
            "held as a rigid block",
            "too large",
            "at 4 particles through 'beam'",
            "to fix it",
        ],
    );
    no_jargon(&w);
}

/// Forces stay minus the gradient of the energy with a clamp found from the geometry on part of
/// a face: a 3D block whose wall layers (no mirror field) cover only the lower half of its face
/// x = 0 and have moved by a common translation. The first layer there follows (2 rows x 4 = 8
/// followers), the rest of the face is free, the closure serves the block with the face partly
/// clamped; f . v = -dE/du . v by central differences to 1e-6 relative for a random v on the
/// free particles (the same check as the mirror faces', `bending_accuracy`).
#[test]
fn forces_are_the_energy_gradient_with_a_clamp_on_part_of_a_face() {
    use mps_solid::physics::boundary::GravityLaw;
    use mps_solid::physics::world::GroupInit;
    use mps_solid::physics::{BodyInit, Material, MaterialLaw, SolverOptions, World};
    let l0 = 0.1;
    let mut pts = vec![];
    for i in -3..7 {
        for j in 0..5 {
            for k in 0..4 {
                if i < 0 && j >= 2 {
                    continue;
                }
                pts.push(Vect::<3>::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * l0);
            }
        }
    }
    let clamp: Vec<u32> = (0..pts.len() as u32)
        .filter(|&i| pts[i as usize][0] < 0.0)
        .collect();
    let w = World::<3>::new(
        l0,
        SolverOptions {
            model: ElasticModel::SecondOrder,
            ..SolverOptions::default()
        },
        vec![BodyInit {
            name: "b".into(),
            material: Material {
                density: 1000.0,
                young: 1e7,
                poisson: 0.3,
                law: MaterialLaw::SaintVenantKirchhoff,
            },
            points: pts.clone(),
            velocity: Vect::<3>::zeros().into(),
            shape: None,
        }],
        vec![GroupInit {
            name: "clamp".into(),
            members: clamp.clone(),
            axes: [true; 3],
            fix_rotation: true,
            mirror: None,
        }],
        vec![],
        GravityLaw::Constant(Vect::<3>::zeros()),
    );
    let mut w = w.unwrap();
    assert_eq!(w.op.second.followers.len(), 8);
    assert!(matches!(w.clamp_faces.as_slice(), [(0, Ok(()))]));
    assert!(w.closure[0].is_ok(), "{:?}", w.closure[0]);
    let shift = Vect::<3>::new(1e-4, -2e-4, 3e-4);
    crate::bending_accuracy::assert_forces_are_the_energy_gradient(
        &mut w, l0, 24681357, &clamp, shift,
    );
}

/// A clamp's followers pass their weight and loads to the layers they follow, spread into the
/// forces at the end of each step. A co-simulation host that changes gravity between steps
/// (here: the scene's -9.81 m/s^2 at the build, then 0 before the first step) must see the
/// body stay at rest: before the spread was redone with the inputs of the step, the build's
/// weight of the followers stayed in the first step's forces and the strip's tip moved by
/// 9e-8 m in 0.02 s (tests/fmi_host.rs `input_derivatives_make_inputs_linear_over_the_step`
/// caught it). At rest with no input every force is zero exactly, so below 1e-15 m.
#[test]
fn followers_see_the_gravity_set_between_steps() {
    use mps_solid::Simulation;
    let scene = mps_solid::scene::Scene::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/small2d.json"
    )))
    .unwrap();
    let mut sim = Simulation::new(&scene).unwrap();
    sim.set_gravity_linear([0.0; 3], [0.0; 3], 0.0);
    sim.advance_to(0.02).unwrap();
    for k in 0..2 {
        let u = sim.probe_displacement(k);
        assert!(u.iter().all(|c| c.abs() < 1e-15), "probe {k}: {u:?}");
    }
    // And the weight set back acts at once: the tip falls as in a run that had it throughout.
    let mut a = Simulation::new(&scene).unwrap();
    a.set_gravity_linear([0.0; 3], [0.0; 3], 0.0);
    a.advance_to(0.002).unwrap();
    a.set_gravity_linear([0.0, -9.81, 0.0], [0.0; 3], 0.002);
    a.advance_to(0.004).unwrap();
    let mut b = Simulation::new(&scene).unwrap();
    b.advance_to(0.002).unwrap();
    let tip_b = b.probe_displacement(0)[1];
    assert!(tip_b < 0.0);
    let tip_a = a.probe_displacement(0)[1];
    assert!(
        (tip_a - tip_b).abs() < 1e-12 * tip_b.abs().max(1e-12) + 1e-18,
        "gravity from t = 0.002 s: {tip_a} after 0.002 s of it; from t = 0: {tip_b}"
    );
}

/// A support written as a layer of particles on the body's face (the corrected operator's scene
/// of the paper's case 2, run with the default operator) is named in its own warning with the
/// measured effect and the remedy in the scene's terms. Before, the body's warning called it a
/// body of several boxes and estimated 0.3 % where the beam is 1.47 % too flexible (linearised
/// against the FEM; with mirror faces +0.14 %). The estimate at 9 across is the power law
/// through the measurements at 9 and 18 across (1.47 / 0.459 % static, 0.82 / 0.28 % in f1).
#[test]
fn a_support_on_the_face_is_named_with_its_effect_and_remedy() {
    use mps_solid::studies::family::case2_clamps;
    let mut cases = case2_clamps();
    let natural = cases.remove(0).scene;
    let w: Vec<String> = Model::<3>::build(&natural)
        .unwrap()
        .warnings
        .iter()
        .map(|w| w.to_string())
        .collect();
    warning_with(
        &w,
        "scene warning in boundaries[1] ('support'): ",
        &[
            "a layer of particles on the face of body 'beam'",
            "holding y, z",
            "static deflection about 1.43 % too large",
            "first frequency about 0.83 % too low at 9 particles through 'beam'",
            "two or three layers of particles beyond the face",
        ],
    );
    assert!(
        w.iter().all(|m| !m.contains("not a single box")),
        "the body is one box: {w:?}"
    );
    no_jargon(&w);
    // The builder's scene (mirror faces at both ends) has no such warning.
    let mirrored = cases.remove(0).scene;
    let w = Model::<3>::build(&mirrored).unwrap().warnings;
    assert!(
        w.iter()
            .all(|m| !m.to_string().contains("layer of particles on the face")),
        "{w:?}"
    );
}

/// The warning of `warnings` that starts with `prefix`; it must contain every one of `parts`.
fn warning_with<'a>(warnings: &'a [String], prefix: &str, parts: &[&str]) -> &'a str {
    let found = warnings
        .iter()
        .find(|m| m.starts_with(prefix))
        .unwrap_or_else(|| panic!("no warning starting {prefix:?}: {warnings:?}"));
    for part in parts {
        assert!(found.contains(part), "{part:?} not in {found}");
    }
    found
}

/// A user's warnings speak the scene's language: no solver internals, no file of the sources.
fn no_jargon(warnings: &[String]) {
    for m in warnings {
        for jargon in [
            "summation-by-parts",
            "plain fits",
            "rigid grip",
            "docs/",
            ".md",
        ] {
            assert!(!m.contains(jargon), "{jargon:?} in {m}");
        }
    }
}

/// The GMS plate (4 particles through it) clamped at x = 0 and resting at its far end on a
/// support that holds y (a propped cantilever), the support written as a user writes it, with
/// no `mirror` field: wall layers behind the end face (a second box), or the body's own last
/// three layers (one box, the region holding them). Both are the mirror support's particles
/// exactly, so the second-order operator mirrors the plate across the end face as if the
/// field were given: the same first frequency and static deflection to the linear solves'
/// round-off (1e-9), and no warning of reduced accuracy. Before (issue 24) such a support was
/// three layers of material with y held, which also resist the end's turning: f1 +26.5 % and
/// mid-span deflection -35 % off the mirror support's (measured on the code before).
/// A support on part of the end face (its lower half) is not a mirror: it keeps its meaning
/// (material with y held).
#[test]
fn natural_supports_match_the_mirror_support() {
    use mps_solid::scene::{Boundary, BoundaryKind, MirrorSpec, Scene};
    let n = 4;
    let base = plate2d_scene(n, ElasticModel::SecondOrder);
    let (l, dp) = (0.2, base.particle_spacing);
    let h = base.bodies[0].boxes[0].max[1];
    let tol = 1e-6 * dp;
    // `walls`: a box beyond the face; else the body's own box made longer. `part`: the
    // support's region covers the lower half of the section only.
    let propped = |walls: bool, mirror: bool, part: bool, layers: f64| -> Scene {
        let mut s = base.clone();
        let beam = &mut s.bodies[0].boxes[0];
        assert!((beam.max[0] - l).abs() < tol, "the plate ends at x = L");
        if walls {
            let mut b = beam.clone();
            b.min[0] = l;
            b.max[0] = l + layers * dp;
            s.bodies[0].boxes.push(b);
        } else {
            beam.max[0] = l + layers * dp;
        }
        s.boundaries.push(Boundary {
            name: "support".into(),
            kind: BoundaryKind::Pinned,
            body: s.bodies[0].name.clone(),
            region: Region {
                min: vec![l + tol, -h - tol],
                max: vec![l + layers * dp + tol, if part { 0.0 } else { h + tol }],
            },
            shape: None,
            axes: Some(vec!["y".into()]),
            mirror: mirror.then(|| MirrorSpec {
                point: vec![l, 0.0],
                normal: vec![1.0, 0.0],
            }),
        });
        s.probes[0].point = vec![0.5 * l, 0.0];
        s
    };
    let quiet = |w: &[String]| {
        w.iter()
            .all(|w| !w.starts_with("boundaries") && !w.contains("first order"))
    };
    let mirror = linear_bending(&propped(true, true, false, 3.0)).unwrap();
    assert!(quiet(&mirror.warnings), "{:?}", mirror.warnings);
    for (walls, name) in [
        (true, "walls behind the face"),
        (false, "the body's end layers"),
    ] {
        let b = linear_bending(&propped(walls, false, false, 3.0)).unwrap();
        assert!(quiet(&b.warnings), "{name}: {:?}", b.warnings);
        assert!(
            (b.f1 / mirror.f1 - 1.0).abs() < 1e-9 && (b.tip / mirror.tip - 1.0).abs() < 1e-9,
            "{name}: f1 {} / mid-span {} against the mirror's {} / {}",
            b.f1,
            b.tip,
            mirror.f1,
            mirror.tip
        );
    }
    // Two layers are as deep as the stencil (re = 2.1 dp) reaches, so are four.
    for layers in [2.0, 4.0] {
        let b = linear_bending(&propped(true, false, false, layers)).unwrap();
        assert!(quiet(&b.warnings), "{layers} layers: {:?}", b.warnings);
        assert!(
            (b.f1 / mirror.f1 - 1.0).abs() < 1e-9 && (b.tip / mirror.tip - 1.0).abs() < 1e-9,
            "{layers} layers: f1 {} / mid-span {}",
            b.f1,
            b.tip
        );
    }
    // One layer is not: the support is held as part of the body (measured f1 -2.34 %,
    // mid-span +4.16 % off the mirror's), and the scene says so, naming the support, its
    // layers, the face and the remedy.
    let one = linear_bending(&propped(true, false, false, 1.0)).unwrap();
    let w = warning_with(
        &one.warnings,
        "boundaries[1] ('support')",
        &[
            "1 layer(s)",
            "x = 0.2 m",
            "fewer than the 2",
            "hold 2 layers beyond the face",
        ],
    );
    assert!(!w.contains("first order"), "{w}");
    no_jargon(&one.warnings);
    assert!(
        one.tip / mirror.tip - 1.0 > 0.01,
        "one layer, mid-span {} against the mirror's {}",
        one.tip,
        mirror.tip
    );
    let part = linear_bending(&propped(true, false, true, 3.0)).unwrap();
    eprintln!(
        "propped plate: mirror f1 {} mid {}; half-face support f1 {:+.3} % mid {:+.3} %",
        mirror.f1,
        mirror.tip,
        100.0 * (part.f1 / mirror.f1 - 1.0),
        100.0 * (part.tip / mirror.tip - 1.0)
    );
    // Pinned at the face's lower half only, the end is free to turn about a lower point: a
    // different (softer) support, so not the mirror's figures.
    assert!(
        (part.tip / mirror.tip - 1.0).abs() > 1e-3,
        "{} vs {}",
        part.tip,
        mirror.tip
    );
}
