//! Translation and rotation invariance of the particle model: an undeformed body feels no force
//! wherever it sits and however it is turned, its measured stable step does not depend on that,
//! and a dynamic run gives the same motion relative to the body. Also: a scene far from the
//! origin runs like the same scene at the origin, coordinates too large to resolve the particle
//! spacing are a scene error, and a particle without neighbours has finite (zero) strain energy.
use crate::common;
use common::*;
use mps_solid::physics::boundary::GravityLaw;
use mps_solid::physics::world::GroupInit;
use mps_solid::physics::{BodyInit, Dim, ElasticModel, Mat, SolverOptions, Space, Vect, World};
use mps_solid::scene::{Model, Scene};
use nalgebra::{Rotation2, Rotation3, Vector3};

const STRAIN: f64 = 1e-3;

/// A lattice block of n particles per axis at spacing l0 with its first corner cell at the
/// origin (cell centres at (k + 1/2) l0), before any offset or rotation.
fn lattice<const D: usize>(n: [usize; 3], l0: f64) -> Vec<Vect<D>> {
    let total: usize = n[..D].iter().product();
    (0..total)
        .map(|code| {
            let mut c = code;
            Vect::<D>::from_fn(|a, _| {
                let k = c % n[a];
                c /= n[a];
                (k as f64 + 0.5) * l0
            })
        })
        .collect()
}

/// A world of one body at the given points; `clamped` particles are held (all axes, rotation).
fn world<const D: usize>(
    model: ElasticModel,
    l0: f64,
    points: Vec<Vect<D>>,
    clamped: Vec<u32>,
    gravity: Vect<D>,
) -> World<D>
where
    Space: Dim<D>,
{
    let groups = if clamped.is_empty() {
        vec![]
    } else {
        vec![GroupInit {
            name: "clamp".into(),
            members: clamped,
            axes: [true; 3],
            fix_rotation: true,
            mirror: None,
        }]
    };
    World::new(
        l0,
        SolverOptions {
            model,
            ..SolverOptions::default()
        },
        vec![BodyInit {
            name: "block".into(),
            material: STEEL_LIKE,
            points,
            velocity: Vect::<D>::zeros().into(),
            shape: None,
        }],
        groups,
        vec![],
        GravityLaw::Constant(gravity),
    )
    .unwrap()
}

/// Force on one particle of a uniform strain of 1e-3: E eps l0^(d-1) (N).
fn force_scale<const D: usize>(l0: f64) -> f64 {
    STEEL_LIKE.young * STRAIN * l0.powi(D as i32 - 1)
}

/// Strain energy of a uniform strain of 1e-3 in a body of n particles: E eps^2 / 2 n l0^d (J).
fn energy_scale<const D: usize>(n: usize, l0: f64) -> f64 {
    0.5 * STEEL_LIKE.young * STRAIN * STRAIN * n as f64 * l0.powi(D as i32)
}

/// Checks that the undeformed world feels no force and stores no energy, and returns its
/// critical step. Round-off: the corrected operator evaluates F = P + H K^-1 with H = 0 at rest
/// (the identity bit for bit, so its strain, residuals and energy are exactly zero), the paper's
/// r - R r0 = 0, |r| - |r0| = 0 exactly, and the second-order fits are zero, so what remains in
/// the forces is the round-off of sums of opposite bond terms, about 1e-16 of the stress; 1e-9
/// of the force and 1e-12 of the energy of a 1e-3 strain leave a margin of 1e3-1e4 above it
/// while catching the defect (forces of 0.7 kN, 7 times the 1e-3 strain force, and energies of
/// 16 J). The corrected operator's energy must be zero exactly (before F was written P + H K^-1
/// it was K K^-1, 1e-16 from the identity).
fn rest_check<const D: usize>(w: &World<D>, what: &str) -> f64
where
    Space: Dim<D>,
{
    let fmax = (0..w.len())
        .map(|i| w.internal_force(i).norm())
        .fold(0.0, f64::max);
    let fs = force_scale::<D>(w.l0);
    assert!(
        fmax <= 1e-9 * fs,
        "{what}: largest force at rest {fmax:.3e} N, more than 1e-9 of the 1e-3 strain force {fs:.3e} N"
    );
    let e = w.strain_energy();
    let es = energy_scale::<D>(w.len(), w.l0);
    assert!(
        e.abs() <= 1e-12 * es,
        "{what}: strain energy at rest {e:.3e} J (1e-3 strain: {es:.3e} J)"
    );
    if w.op.model == ElasticModel::Corrected {
        assert_eq!(
            e, 0.0,
            "{what}: the corrected operator's energy at rest is not exactly zero"
        );
    }
    w.critical_dt()
}

fn same_dt(dt: f64, base: f64, what: &str) {
    assert!(
        ((dt - base) / base).abs() <= 1e-6,
        "{what}: critical step {dt:.9e} s differs from {base:.9e} s at the origin by more than 1e-6"
    );
}

/// Offsets of the translation tests: 0 to 10 m in steps of `step` m along x and along the
/// diagonal, and 1e6 m.
fn offsets<const D: usize>(step: f64) -> Vec<Vect<D>> {
    let mut out = Vec::new();
    for k in 0..=(10.0 / step).round() as usize {
        let s = step * k as f64;
        out.push(Vect::<D>::from_fn(|a, _| if a == 0 { s } else { 0.0 }));
        out.push(Vect::<D>::from_fn(|a, _| s * (1.0 + 0.37 * a as f64)));
    }
    out.push(Vect::<D>::from_fn(|a, _| if a == 0 { 1e6 } else { 0.0 }));
    out.push(Vect::<D>::from_element(-1e6));
    out
}

fn rest_under_translation<const D: usize>(n: [usize; 3], l0: f64, step: f64)
where
    Space: Dim<D>,
{
    for model in MODELS {
        let base_pts = lattice::<D>(n, l0);
        let base = rest_check(
            &world(model, l0, base_pts.clone(), vec![], Vect::<D>::zeros()),
            &format!("{D}D {model:?} at the origin"),
        );
        for off in offsets::<D>(step) {
            let pts = base_pts.iter().map(|p| p + off).collect();
            let what = format!("{D}D {model:?} at offset {:?}", off.as_slice());
            let dt = rest_check(&world(model, l0, pts, vec![], Vect::<D>::zeros()), &what);
            same_dt(dt, base, &what);
        }
    }
}

#[test]
#[ignore = "slow (110 s on a loaded 2-core machine): the full test command runs it"]
fn undeformed_body_has_no_force_at_any_offset_3d() {
    // A 1 m cube at dp 0.1: on the old code, offsets 3.5-7 m gave 16 J at rest, forces up to
    // 0.8 kN and a critical step 160 times too small. Steps of 1.25 m put three offsets in
    // that range along each direction (each build costs a stable-step estimate; the 2D test
    // samples every 0.5 m).
    rest_under_translation::<3>([10, 10, 10], 0.1, 1.25);
}

#[test]
#[ignore = "slow (26 s on a loaded 2-core machine): the full test command runs it"]
fn undeformed_body_has_no_force_at_any_offset_2d() {
    rest_under_translation::<2>([20, 13, 1], 0.05, 0.5);
}

/// Rotations of the rotation tests (3D: axis-angle vectors).
fn rotations3() -> Vec<Rotation3<f64>> {
    [
        Vector3::new(0.0, 0.0, 0.3),
        Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        Vector3::new(0.7, 0.0, 0.0),
        Vector3::new(0.3, -0.5, 0.4),
        Vector3::new(-1.1, 2.0, 0.9),
        Vector3::new(0.0, std::f64::consts::PI, 0.0),
    ]
    .iter()
    .map(|v| Rotation3::new(*v))
    .collect()
}

fn angles2() -> Vec<f64> {
    vec![0.1, 0.5, std::f64::consts::FRAC_PI_4, 1.0, 2.5, -2.0]
}

#[test]
#[ignore = "slow (40 s on a loaded 2-core machine): the full test command runs it"]
fn undeformed_body_has_no_force_at_any_orientation() {
    for model in MODELS {
        let l0 = 0.1;
        let pts = lattice::<3>([9, 7, 5], l0);
        let base = rest_check(
            &world(model, l0, pts.clone(), vec![], Vect::<3>::zeros()),
            "3D",
        );
        for r in rotations3() {
            for off in [
                Vector3::zeros(),
                Vector3::new(5.0, -4.0, 3.0),
                Vector3::new(1e6, 0.0, 0.0),
            ] {
                let p: Vec<_> = pts.iter().map(|x| r * x + off).collect();
                let what = format!(
                    "3D {model:?} rotated {:?} at {:?}",
                    r.scaled_axis().as_slice(),
                    off.as_slice()
                );
                let dt = rest_check(&world(model, l0, p, vec![], Vect::<3>::zeros()), &what);
                same_dt(dt, base, &what);
            }
        }
        let l0 = 0.05;
        let pts = lattice::<2>([17, 11, 1], l0);
        let base = rest_check(
            &world(model, l0, pts.clone(), vec![], Vect::<2>::zeros()),
            "2D",
        );
        for a in angles2() {
            let r = Rotation2::new(a);
            for off in [
                Vect::<2>::zeros(),
                Vect::<2>::new(4.5, 6.5),
                Vect::<2>::new(-1e6, 1e6),
            ] {
                let p: Vec<_> = pts.iter().map(|x| r * x + off).collect();
                let what = format!("2D {model:?} rotated {a} at {:?}", off.as_slice());
                let dt = rest_check(&world(model, l0, p, vec![], Vect::<2>::zeros()), &what);
                same_dt(dt, base, &what);
            }
        }
    }
}

/// A placement of a 2D scene (or its inverse rotation).
type Map2 = Box<dyn Fn(&Vect<2>) -> Vect<2>>;

/// A cantilever clamped at its x = min end, under sudden gravity -y (rotated with the scene),
/// moved by `place`; returns the tip displacement, rotated back by `back`, after `steps`
/// steps of the given dt, and the critical step.
fn cantilever_run<const D: usize>(
    model: ElasticModel,
    n: [usize; 3],
    l0: f64,
    place: impl Fn(&Vect<D>) -> Vect<D>,
    back: impl Fn(&Vect<D>) -> Vect<D>,
    dt: Option<f64>,
    steps: usize,
) -> (Vect<D>, f64)
where
    Space: Dim<D>,
{
    let pts = lattice::<D>(n, l0);
    let clamped: Vec<u32> = (0..pts.len() as u32)
        .filter(|&i| pts[i as usize][0] < 2.0 * l0)
        .collect();
    let tip = (0..pts.len())
        .max_by(|&a, &b| (pts[a][0] - 1e-3 * pts[a][1]).total_cmp(&(pts[b][0] - 1e-3 * pts[b][1])))
        .unwrap();
    let origin = place(&Vect::<D>::zeros());
    let g = Vect::<D>::from_fn(|a, _| if a == 1 { -9.81 } else { 0.0 });
    let g = place(&g) - origin;
    let placed: Vec<Vect<D>> = pts.iter().map(&place).collect();
    let mut w = world(model, l0, placed, clamped, g);
    let crit = w.critical_dt();
    let dt = dt.unwrap_or(0.5 * crit);
    for _ in 0..steps {
        w.step(dt).unwrap();
    }
    (back(&w.p.displacement(tip)), crit)
}

/// Same motion relative to the body: translated by offsets up to 10 m and rotated, the tip
/// displacement agrees to 1e-9 of itself (the reference lattice differs by the round-off of
/// the placed coordinates, 1e-15 of l0, and the run is linear in it); translated by 1e6 m, to
/// 1e-6 (coordinates there are rounded to 1.2e-10 m, 2e-9 of l0 = 0.05 m).
#[test]
#[ignore = "slow (12 s on a loaded 2-core machine): the full test command runs it"]
fn dynamic_run_moves_alike_wherever_the_body_sits() {
    let steps = 300;
    for model in MODELS {
        // 2D
        let (n, l0) = ([16, 4, 1], 0.05);
        let (base, crit) = cantilever_run::<2>(model, n, l0, |x| *x, |x| *x, None, steps);
        let dt = Some(0.5 * crit);
        assert!(
            base.norm() > 1e-4 * l0,
            "{model:?}: the tip must move ({base:?})"
        );
        let mut cases: Vec<(String, Map2, Map2, f64)> = Vec::new();
        for k in 1..=20 {
            let off = Vect::<2>::new(0.5 * k as f64, 0.25 * k as f64);
            cases.push((
                format!("offset {off:?}"),
                Box::new(move |x| x + off),
                Box::new(|x| *x),
                1e-9,
            ));
        }
        let far = Vect::<2>::new(1e6, -1e6);
        cases.push((
            "offset 1e6".into(),
            Box::new(move |x| x + far),
            Box::new(|x| *x),
            1e-6,
        ));
        for a in angles2() {
            let r = Rotation2::new(a);
            cases.push((
                format!("rotated {a}"),
                Box::new(move |x| r * x + Vect::<2>::new(3.0, 7.0)),
                Box::new(move |x| r.inverse() * x),
                1e-9,
            ));
        }
        for (what, place, back, tol) in cases {
            let (u, c) = cantilever_run::<2>(model, n, l0, place, back, dt, steps);
            same_dt(c, crit, &format!("2D {model:?} {what}"));
            assert!(
                (u - base).norm() <= tol * base.norm(),
                "2D {model:?} {what}: tip displacement {u:?} vs {base:?} at the origin"
            );
        }
        // 3D
        let (n, l0) = ([10, 3, 3], 0.05);
        let (base, crit) = cantilever_run::<3>(model, n, l0, |x| *x, |x| *x, None, steps / 2);
        let dt = Some(0.5 * crit);
        for r in rotations3() {
            let off = Vect::<3>::new(2.5, -6.0, 9.5);
            let what = format!("3D {model:?} rotated {:?}", r.scaled_axis().as_slice());
            let (u, c) = cantilever_run::<3>(
                model,
                n,
                l0,
                move |x| r * x + off,
                move |x| r.inverse() * x,
                dt,
                steps / 2,
            );
            same_dt(c, crit, &what);
            assert!(
                (u - base).norm() <= 1e-9 * base.norm(),
                "{what}: tip displacement {u:?} vs {base:?}"
            );
        }
        let far = Vect::<3>::new(1e6, 1e6, -1e6);
        let (u, c) = cantilever_run::<3>(model, n, l0, move |x| x + far, |x| *x, dt, steps / 2);
        same_dt(c, crit, &format!("3D {model:?} at 1e6"));
        assert!(
            (u - base).norm() <= 1e-6 * base.norm(),
            "3D {model:?} at 1e6: tip displacement {u:?} vs {base:?}"
        );
    }
}

fn small2d() -> Scene {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/small2d.json");
    Scene::load(std::path::Path::new(path)).unwrap()
}

/// Moves every coordinate of a scene by `d`.
fn shifted(mut s: Scene, d: [f64; 2]) -> Scene {
    let mv = |v: &mut Vec<f64>| v.iter_mut().zip(d).for_each(|(c, o)| *c += o);
    for b in &mut s.bodies {
        for r in &mut b.boxes {
            mv(&mut r.min);
            mv(&mut r.max);
        }
    }
    for g in &mut s.boundaries {
        mv(&mut g.region.min);
        mv(&mut g.region.max);
    }
    for l in &mut s.loads {
        mv(&mut l.region.min);
        mv(&mut l.region.max);
    }
    for p in &mut s.probes {
        mv(&mut p.point);
    }
    s
}

/// small2d shifted by 1e7 m: on the old code the measured step was wrong (positions there are
/// rounded to 1.9e-9 m, more than the 1.25e-9 m probe of the power iteration) and the run blew
/// up at step 8. Now the step agrees to 1e-6 (measured 7e-8) and the tip deflection after
/// 0.05 s (about 200 steps) to 1e-7 of itself (measured 2-4e-9): the reference lattice at 1e7 m
/// is rounded to 1.5e-7 of l0, which perturbs bond stiffnesses at that level and the deflection
/// less (the perturbations are random and average out), while displacements keep full precision.
#[test]
fn small2d_far_from_the_origin_runs_like_at_the_origin() {
    let base = small2d();
    for model in MODELS {
        let mut s0 = base.clone();
        s0.solver.model = model;
        let mut m0 = Model::<2>::build(&s0).unwrap();
        let mut m1 = Model::<2>::build(&shifted(s0.clone(), [1e7, -1e7])).unwrap();
        same_dt(
            m1.world.critical_dt(),
            m0.world.critical_dt(),
            &format!("small2d {model:?} at 1e7"),
        );
        m0.world
            .set_load(0, Vect::<2>::new(0.0, -2.0), Vect::<2>::zeros(), 0.0);
        m1.world
            .set_load(0, Vect::<2>::new(0.0, -2.0), Vect::<2>::zeros(), 0.0);
        m0.world.advance_to(0.05).unwrap();
        m1.world.advance_to(0.05).unwrap();
        assert_eq!(m0.world.steps, m1.world.steps);
        let (a, b) = (m0.probe_displacement(0), m1.probe_displacement(0));
        assert!(a.norm() > 1e-4, "{model:?}: the tip must deflect ({a:?})");
        assert!(
            (a - b).norm() <= 1e-7 * a.norm(),
            "small2d {model:?}: tip {b:?} at 1e7 m vs {a:?} at the origin"
        );
        let (e0, e1) = (m0.world.strain_energy(), m1.world.strain_energy());
        assert!((e0 - e1).abs() <= 1e-6 * e0, "strain energy {e1} vs {e0}");
    }
}

/// Particles near 1e15 m cannot resolve a spacing of 0.0125 m (doubles there are 0.125 m
/// apart): a scene error naming the body and the coordinate, not a blow-up at run time.
#[test]
fn coordinates_that_cannot_resolve_the_spacing_are_a_scene_error() {
    // small2d moved there: its boxes lose their lengths (the scene validation says so).
    let e = Model::<2>::build(&shifted(small2d(), [1e15, 0.0]))
        .err()
        .expect("small2d at 1e15 m must be refused")
        .to_string();
    assert!(e.contains("scene error") && !e.contains("blow-up"), "{e}");
    // Boxes whose sides stay whole numbers of spacings there, but whose particles coincide.
    for (x, dp) in [(1e15, 0.01), (-1e15, 0.01), (1e10, 0.0625)] {
        let text = format!(
            r#"{{"name": "far", "dimension": 2, "particle_spacing": {dp},
            "bodies": [{{"name": "plate", "material": {{"density": 1000, "young": 1e6, "poisson": 0.3}},
                "boxes": [{{"min": [{x}, 0.0], "max": [{}, {}]}}]}}],
            "end_time": 0.01, "output_interval": 0.001}}"#,
            x + 1.0,
            8.0 * dp
        );
        let scene = Scene::from_json(&text).unwrap();
        let e = Model::<2>::build(&scene)
            .err()
            .unwrap_or_else(|| panic!("a body at {x} m with dp {dp} m must be refused"))
            .to_string();
        assert!(
            e.contains("body 'plate' (bodies[0])")
                && e.contains("significant bits")
                && e.contains("nearer the origin"),
            "{e}"
        );
        assert!(!e.contains("blow-up"), "{e}");
    }
    // The bound: 1e7 m at 0.0125 m keeps 22 bits and is accepted (see above).
    assert!(Model::<2>::build(&shifted(small2d(), [1e7, 1e7])).is_ok());
}

/// A particle with no neighbours (a body of one particle, or one placed beyond re from the
/// rest of its body) has no elastic energy or force, in every model: n_i = 0 in the paper_local
/// normalisation made its pressure 0/0 = NaN. Energies stay finite through a run.
#[test]
fn particle_without_neighbours_has_finite_zero_energy() {
    for model in MODELS {
        let l0 = 0.05;
        let mut pts = lattice::<2>([6, 4, 1], l0);
        pts.push(Vect::<2>::new(1.0, 1.0));
        let lone = pts.len() - 1;
        let mut w = world(model, l0, pts, vec![], Vect::<2>::new(0.0, -9.81));
        assert_eq!(w.bonds.of(lone).len(), 0);
        rest_check(&w, &format!("{model:?} with a lone particle"));
        assert_eq!(w.internal_force(lone), Vect::<2>::zeros());
        let mut s = w.state();
        for (i, u) in s.u.iter_mut().enumerate() {
            *u = Vect::<2>::new(1e-4 * l0 * (i % 3) as f64, 0.0);
        }
        w.set_state(&s).unwrap();
        let e = w.strain_energy();
        assert!(e.is_finite() && e > 0.0, "{model:?}: strain energy {e}");
        for _ in 0..50 {
            w.step(0.5 * w.critical_dt()).unwrap();
            assert!(w.strain_energy().is_finite() && w.kinetic_energy().is_finite());
        }
        assert_eq!(w.internal_force(lone), Vect::<2>::zeros());
        // A body of a single particle.
        let w1 = world(
            model,
            l0,
            vec![Vect::<2>::new(0.3, 0.2)],
            vec![],
            Vect::<2>::zeros(),
        );
        assert_eq!(w1.strain_energy(), 0.0);
        assert_eq!(w1.kinetic_energy(), 0.0);
        let w3 = world(
            model,
            l0,
            vec![Vect::<3>::new(0.3, 0.2, 0.1)],
            vec![],
            Vect::<3>::zeros(),
        );
        assert_eq!(w3.strain_energy(), 0.0);
    }
}

/// Uniform strain at 1e6 m: displacements are relative, so the force pattern of a strained
/// body is the same as at the origin to 1e-6 (the rounding of the reference lattice there).
#[test]
fn strained_body_far_away_feels_the_same_forces() {
    for model in MODELS {
        let l0 = 0.1;
        let pts = lattice::<3>([6, 5, 4], l0);
        let eps = Mat::<3>::new(1.0, 0.3, 0.0, 0.3, -0.5, 0.2, 0.0, 0.2, 0.7) * STRAIN;
        let run = |off: Vect<3>| {
            let mut w = world(
                model,
                l0,
                pts.iter().map(|p| p + off).collect(),
                vec![],
                Vect::<3>::zeros(),
            );
            let mut s = w.state();
            for (u, p) in s.u.iter_mut().zip(&pts) {
                *u = eps * p;
            }
            w.set_state(&s).unwrap();
            (0..w.len())
                .map(|i| w.internal_force(i))
                .collect::<Vec<_>>()
        };
        let (f0, f1) = (run(Vect::<3>::zeros()), run(Vect::<3>::new(1e6, -1e6, 3e5)));
        let fs = force_scale::<3>(l0);
        let worst = f0
            .iter()
            .zip(&f1)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(
            worst <= 1e-6 * fs,
            "{model:?}: forces differ by {worst:.3e} N"
        );
    }
}

/// The issue's example as a scene: a 1.3 x 1 x 1 m block at dp = 0.1 at x = 5 m. On the old code
/// 59 of its 1300 particles carried up to 2 kN at rest and, left alone, it gained kinetic energy.
/// Now it is at rest like the same block at the origin: forces and strain energy at round-off and
/// kinetic energy below 1e-20 of the 1e-3 strain energy after 200 steps.
#[test]
#[ignore = "slow (7 s on a loaded 2-core machine): the full test command runs it"]
fn scene_block_at_five_metres_stays_at_rest() {
    for model in ["corrected", "paper", "paper_local"] {
        for x in [0.0, 5.0] {
            let text = format!(
                r#"{{"name": "block", "dimension": 3, "particle_spacing": 0.1,
                "solver": {{"model": "{model}"}},
                "bodies": [{{"name": "b", "material": {{"density": 1000, "young": 1e7, "poisson": 0.3}},
                    "boxes": [{{"min": [{x}, 0.0, 0.0], "max": [{}, 1.0, 1.0]}}]}}],
                "end_time": 0.1, "output_interval": 0.01}}"#,
                x + 1.3
            );
            let mut m = Model::<3>::build(&Scene::from_json(&text).unwrap()).unwrap();
            assert_eq!(m.world.len(), 1300);
            let what = format!("{model} block at x = {x} m");
            rest_check(&m.world, &what);
            let dt = 0.8 * m.world.critical_dt();
            for _ in 0..200 {
                m.world.step(dt).unwrap();
            }
            let ek = m.world.kinetic_energy();
            assert!(
                ek <= 1e-20 * energy_scale::<3>(1300, 0.1),
                "{what}: kinetic energy {ek:.3e} J after 200 steps at rest"
            );
        }
    }
}
