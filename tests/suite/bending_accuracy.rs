//! Accuracy of the elastic operators in bending (issue 7), from the linearised model
//! (src/studies/linear.rs: static deflection by conjugate gradients, first mode by inverse iteration),
//! against the converged FEM references of tools/fem_bending.py.
use crate::common;
use mps_solid::physics::{ElasticModel, Vect};
use mps_solid::scene::Model;
use mps_solid::studies::bending::{
    free_free_plate_f1, linear_bending, plate2d_scene, plate_reference,
};
use mps_solid::studies::cases::{case1_closed_field, case1_scene};
use mps_solid::studies::linear::{field_at, Linearised};

/// Tip displacement error of the plate turned into an axial bar (nu = 0, gravity along the
/// axis), whose exact displacement u_x = -(rho g / E)(L x - x^2 / 2) is quadratic.
fn axial_bar_tip_error(n: usize, model: ElasticModel) -> f64 {
    let mut s = plate2d_scene(n, model);
    s.solver.model = ElasticModel::SecondOrder;
    s.bodies[0].material.poisson = 0.0;
    let mat = s.bodies[0].material;
    let l = s.bodies[0].boxes[0].max[0];
    let exact = -(mat.density * 9.81 / mat.young) * (0.5 * l * l);
    let mut model = Model::<2>::build(&s).unwrap();
    let u = Linearised::new(&model.world)
        .unwrap()
        .static_gravity(Vect::<2>::new(-9.81, 0.0), 1e-12)
        .unwrap();
    let tip = field_at(&mut model.world, &u, &Vect::<2>::new(l, 0.0), None).unwrap();
    tip[0] / exact - 1.0
}

/// The clamp of the second-order operator must not slip: on an axial bar whose exact field is
/// quadratic (so the operator's fits are exact away from the clamp) the clamp is the only error
/// source. The first layer follows the quadratic extrapolation to the clamped face
/// (docs/model.md, "Clamped faces"), which is exact for that field, and the closure makes the
/// particle quadrature exact for it too, so the tip is exact to round-off: measured 2.2e-13 /
/// 6.6e-14 at 4 / 8 particles across (relative); required below 1e-9 (round-off of the CG solve
/// at its 1e-12 tolerance). The odd mirror of the clamp (the previous treatment) was off by
/// 4.97e-4 / 1.08e-4 at 4 / 8 (its closure: the same); the face-layer grip by 1.15e-2 / 5.7e-3.
/// The same bar clamped by a layer on the face without a mirror (the corrected operator's
/// scene) is exact too since the clamp's face is found from the geometry (issue 24); the grip
/// that a clamp wrapping the end's edges keeps shows the slip, which guards the test's power to
/// tell them apart (`clamp_faces::natural_clamp_is_exact_on_an_axial_bar_and_a_wrapping_clamp_warns`).
#[test]
fn clamp_is_exact_on_an_axial_bar() {
    for n in [4, 8] {
        let e = axial_bar_tip_error(n, ElasticModel::SecondOrder);
        assert!(e.abs() < 1e-9, "tip error {e:e} at {n} across");
    }
}

/// The free-free plate has no singular corner, so it shows the operator's own order: the
/// second-order operator is exact for quadratic fields (pure bending), so its error must fall
/// at least as dp^2, and there must be no zero-energy mode below the flexural one (an hourglass
/// mode would make f1 near zero). With the summation-by-parts closure of the free faces
/// (module `physics::sbp`) the observed order is 3.8 and the error at 4 across 0.097 % from
/// the Richardson limit; required order >= 3 and below 0.15 %. Without the closure (plain fits,
/// cell-centred volumes and the cell term) it was order 2.16 and 0.28 %, which fails both.
#[test]
#[ignore = "slow (75 s on a loaded 2-core machine): the full test command runs it"]
fn second_order_converges_at_second_order_on_the_free_free_plate() {
    let f: Vec<f64> = [4, 8, 16]
        .iter()
        .map(|&n| free_free_plate_f1(n, ElasticModel::SecondOrder).unwrap())
        .collect();
    let order = ((f[1] - f[0]) / (f[2] - f[1])).log2();
    let limit = f[2] + (f[2] - f[1]) / (2f64.powf(order) - 1.0);
    let err4 = (f[0] - limit).abs() / limit;
    assert!(order >= 3.0, "observed order {order:.2} (f = {f:?})");
    assert!(
        err4 < 1.5e-3,
        "error at 4 across {:.3} % (f = {f:?})",
        100.0 * err4
    );
    // Thin-plate value of the free-free first mode, (4.730^2 / 2 pi L^2) sqrt(E' I / rho A) =
    // 25.05 Hz: at L/H = 10 shear and rotary inertia lower it by about 4.6 % (first-order
    // Timoshenko correction (beta L)^2 (H/L)^2 / 24 (1 + E' / (kappa G))); the limit must be
    // 2-7 % below the thin-plate value.
    let drop = 1.0 - limit / 25.05;
    assert!(
        (0.02..0.07).contains(&drop),
        "limit {limit} Hz, {:.2} % below thin-plate",
        100.0 * drop
    );
}

/// The clamped GMS plate against the converged FEM (targets of issue 7: within 2 % at 4 and
/// 1 % at 8 particles through the thickness). The second-order operator closes the plate's free
/// faces and its clamped face (module `physics::sbp`); the first layer at the clamp follows the
/// quadratic extrapolation to the face (src/studies/bending.rs, docs/model.md "Clamped faces").
/// Measured: f1 -0.009 % / -0.009 % and static tip deflection +0.003 % / +0.016 % at 4 / 8
/// (and within 0.002 % at 16 and 32 across). Required within 0.03 %, about twice the largest: the odd
/// mirror of the clamp (the previous treatment, whose odd extension has a kink in the curvature
/// at the face) gave -0.19 % / +0.36 % and -0.13 % / +0.26 %, the face-layer grip -0.31 % /
/// +0.61 % and -0.37 % / +0.73 %, so the test tells the clamps apart.
#[test]
#[ignore = "slow (15 s on a loaded 2-core machine): the full test command runs it"]
fn clamped_plate_against_the_fem() {
    let r = plate_reference();
    for (n, tol_f, tol_tip) in [(4, 3e-4, 3e-4), (8, 3e-4, 3e-4)] {
        let b = linear_bending(&plate2d_scene(n, ElasticModel::SecondOrder)).unwrap();
        let ef = b.f1 / r.f1 - 1.0;
        let et = b.tip / r.tip - 1.0;
        assert!(
            ef.abs() < tol_f,
            "n = {n}: f1 {} Hz vs FEM {} ({:+.2} %)",
            b.f1,
            r.f1,
            100.0 * ef
        );
        assert!(
            et.abs() < tol_tip,
            "n = {n}: tip {} m vs FEM {} ({:+.2} %)",
            b.tip,
            r.tip,
            100.0 * et
        );
    }
}

/// The clamp's reaction is the body's weight: the first layer at a clamped face follows the
/// clamp's constraint and has no inertia of its own (its mass is lumped on the layers it
/// follows), so its weight must reach the clamp through the constraint and not be counted twice
/// or lost. The GMS plate (second_order, 4 across) in its static state under a small gravity
/// (1e-6 g, so that the linear solution is the nonlinear one to ~1e-7): the clamp's reaction
/// equals rho g L H: measured 1.6e-12 relative, required 1e-8 (the balance holds by momentum
/// conservation to round-off once the free particles are in equilibrium); a lost follower layer
/// would be off by 1/40 (one layer of 40), the lumped shares counted twice by about 1/80. No axial
/// reaction under the transverse load: measured 5e-7 of the weight, which is the
/// finite-difference linearisation's error (1e-10 of the stress-level bond forces); required
/// 1e-5.
#[test]
fn clamp_reaction_is_the_weight() {
    use mps_solid::physics::boundary::GravityLaw;
    let s = plate2d_scene(4, ElasticModel::SecondOrder);
    let mat = s.bodies[0].material;
    let beam = &s.bodies[0].boxes[0];
    let (l, h) = (beam.max[0] - beam.min[0], beam.max[1] - beam.min[1]);
    let mut model = Model::<2>::build(&s).unwrap();
    let w = &mut model.world;
    assert!(!w.op.second.followers.is_empty());
    let g = Vect::<2>::new(0.0, -9.81e-6);
    w.set_gravity(GravityLaw::Constant(g));
    let u = Linearised::new(w)
        .unwrap()
        .static_gravity(g, 1e-13)
        .unwrap();
    let mut st = w.state();
    st.u = u;
    w.set_state(&st).unwrap();
    let weight = mat.density * l * h * 9.81e-6;
    let r = w.groups[0].reaction;
    assert!(
        (r[1] / weight - 1.0).abs() < 1e-8 && r[0].abs() < 1e-5 * weight,
        "reaction {r:?} vs weight {weight}"
    );
}

/// The second-order forces are minus the gradient of its strain energy: for a random
/// deformation (strain ~ 1e-3, large enough for the geometric terms) of a 3D block in which one
/// particle lost most of its bonds (first-order fallback, degenerate span) and with a clamped
/// grip on one face, f . v = -dE/du . v by central differences to 1e-6 relative (the difference
/// quotient's truncation at eps = 1e-6 is ~1e-10; round-off of E ~1e-12).
#[test]
fn second_order_forces_are_the_energy_gradient() {
    use mps_solid::physics::boundary::GravityLaw;
    use mps_solid::physics::world::GroupInit;
    use mps_solid::physics::{BodyInit, Material, MaterialLaw, SolverOptions, Vect, World};
    let l0 = 0.1;
    let mut pts = vec![];
    for i in 0..6 {
        for j in 0..5 {
            for k in 0..4 {
                pts.push(Vect::<3>::new(i as f64, j as f64, k as f64) * l0);
            }
        }
    }
    let clamp: Vec<u32> = (0..pts.len() as u32)
        .filter(|&i| pts[i as usize][0] < 0.5 * l0)
        .collect();
    let mut w = World::<3>::new(
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
            members: clamp,
            axes: [true; 3],
            fix_rotation: true,
            mirror: None,
        }],
        vec![],
        GravityLaw::Constant(Vect::<3>::zeros()),
    )
    .unwrap();
    // Break all bonds of particle 77 but those along x (a line: rank-1 span).
    let victim = 77usize;
    let mut touched = vec![victim];
    for b in w.bonds.of(victim) {
        let r0 = w.bonds.r0[b];
        if r0[1].abs() + r0[2].abs() > 1e-9 {
            let j = w.bonds.nbr[b] as usize;
            w.bonds.w0[b] = 0.0;
            let bm = mps_solid::physics::second_order::mirror_index(&w.bonds)[b] as usize;
            w.bonds.w0[bm] = 0.0;
            touched.push(j);
        }
    }
    for &i in &touched {
        let n_ref = w.p.n_ref[i];
        w.op.refresh_particle(&w.bonds, i, n_ref);
    }
    assert!(!w.op.second.quadratic[victim] && !w.op.second.full[victim]);
    assert_forces_are_the_energy_gradient(&mut w, l0, 12345, &[], Vect::<3>::zeros());
}

/// The same energy-gradient check with two mirror faces: a clamp (all axes odd) whose group
/// has moved by a common translation, and a face support holding y and z (x even). The ghosts'
/// displacements are their masters' reflected, so the chain rule through them must be in the
/// forces: f . v = -dE/du . v to 1e-6 relative for a random v on the free particles.
#[test]
fn forces_are_the_energy_gradient_with_mirror_faces() {
    use mps_solid::physics::boundary::GravityLaw;
    use mps_solid::physics::world::{GroupInit, MirrorFace};
    use mps_solid::physics::{BodyInit, Material, MaterialLaw, SolverOptions, World};
    let l0 = 0.1;
    let mut pts = vec![];
    // Body cells x in [0, 6 l0]; clamp images at x < 0, support images at x > 6 l0.
    for i in -3..9 {
        for j in 0..5 {
            for k in 0..4 {
                pts.push(Vect::<3>::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * l0);
            }
        }
    }
    let select = |f: &dyn Fn(f64) -> bool| -> Vec<u32> {
        (0..pts.len() as u32)
            .filter(|&i| f(pts[i as usize][0] / l0))
            .collect()
    };
    let clamp = select(&|x| x < 0.0);
    let support = select(&|x| x > 6.0);
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
        vec![
            GroupInit {
                name: "clamp".into(),
                members: clamp.clone(),
                axes: [true; 3],
                fix_rotation: true,
                mirror: Some(MirrorFace {
                    point: [0.0; 3],
                    normal: [-1.0, 0.0, 0.0],
                }),
            },
            GroupInit {
                name: "support".into(),
                members: support.clone(),
                axes: [false, true, true],
                fix_rotation: false,
                mirror: Some(MirrorFace {
                    point: [6.0 * l0, 0.0, 0.0],
                    normal: [1.0, 0.0, 0.0],
                }),
            },
        ],
        vec![],
        GravityLaw::Constant(Vect::<3>::zeros()),
    );
    let mut w = w.unwrap();
    // The face support mirrors (ghosts); the clamp's first body layer (5 x 4) follows.
    assert_eq!(w.op.second.ghosts.len(), support.len());
    assert_eq!(w.op.second.followers.len(), 20);
    let shift = Vect::<3>::new(1e-4, -2e-4, 3e-4);
    assert_forces_are_the_energy_gradient(&mut w, l0, 987654321, &clamp, shift);
}

/// Checks f . v = -dE/du . v by central differences (eps = 1e-6 l0) to 1e-6 relative, for a
/// random displacement (~2e-3 l0) and direction v of the free particles; the members of `moved`
/// are first displaced by `shift` (a group's motion). The difference quotient's truncation is
/// ~1e-10 and the round-off of E ~1e-12.
#[allow(clippy::needless_range_loop)]
pub(crate) fn assert_forces_are_the_energy_gradient(
    w: &mut mps_solid::physics::World<3>,
    l0: f64,
    mut seed: u64,
    moved: &[u32],
    shift: Vect<3>,
) {
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut u = w.state();
    let mut v: Vec<Vect<3>> = vec![Vect::<3>::zeros(); w.len()];
    for i in 0..w.len() {
        if w.p.fix[i] == 0 {
            u.u[i] = Vect::<3>::new(rnd(), rnd(), rnd()) * (2e-3 * l0);
            v[i] = Vect::<3>::new(rnd(), rnd(), rnd());
        } else if moved.contains(&(i as u32)) {
            u.u[i] = shift;
        }
    }
    common::assert_forces_are_minus_the_energy_gradient_along(w, &u, &v, "second_order");
}

/// A mirror face finds the same ghosts and gives the same answer wherever the scene sits: the
/// GMS plate (second_order, mirror clamp, 4 across) moved by (1e6, -1e6) m has the same
/// linearised f1 and tip deflection to 1e-6 relative (round-off of positions near 1e6 m is
/// ~1e-10 m = 2e-8 l0, and the fit's reference vectors are snapped to 1e-9 l0).
#[test]
fn mirror_clamp_gives_the_same_answer_far_from_the_origin() {
    let base = plate2d_scene(4, ElasticModel::SecondOrder);
    let mut far = base.clone();
    let off = [1e6, -1e6];
    let shift = |v: &mut Vec<f64>| v.iter_mut().zip(off).for_each(|(c, o)| *c += o);
    for b in &mut far.bodies {
        for r in &mut b.boxes {
            shift(&mut r.min);
            shift(&mut r.max);
        }
    }
    for g in &mut far.boundaries {
        shift(&mut g.region.min);
        shift(&mut g.region.max);
        if let Some(m) = &mut g.mirror {
            shift(&mut m.point);
        }
    }
    for p in &mut far.probes {
        shift(&mut p.point);
    }
    let (a, b) = (
        linear_bending(&base).unwrap(),
        linear_bending(&far).unwrap(),
    );
    assert!((b.f1 / a.f1 - 1.0).abs() < 1e-6, "f1 {} vs {}", b.f1, a.f1);
    assert!(
        (b.tip / a.tip - 1.0).abs() < 1e-6,
        "tip {} vs {}",
        b.tip,
        a.tip
    );
}

/// The closure of the free faces (module `physics::sbp`) makes the particle quadrature of the
/// weak form consistent: case 1's closed form u* (the hanging column: quadratic, traction-free
/// side faces and free end) is reproduced exactly by the fits, so K u* - f_gravity must vanish
/// at every particle that does not see the clamp (whose closed form is not exact: it leaves the
/// lateral contraction free there, and the first layer follows the clamp's constraint instead of
/// u*, which the forces see up to two stencil radii, 4.2 dp = 0.105 m, from it). Measured: at
/// most 2.0e-8 of a particle's weight over the particles more than 0.12 m from the clamp
/// (0.2 m g in the layer 4 dp from the first, inside that reach); required below 1e-6 (the constraint solve stops at
/// a relative residual of 1e-9). With the plain fits the free end's layers carry
/// -0.35 / +0.53 / -0.18 and the side faces 0.16 of a particle's weight, and the end layer's
/// lateral contraction comes out at a sixth of the closed form's (docs/model.md, "Free faces").
#[test]
#[ignore = "slow (11 s on a loaded 2-core machine): the full test command runs it"]
fn closed_free_faces_pass_the_integration_constraint() {
    let s = case1_scene(0.025, ElasticModel::SecondOrder, None);
    let m = Model::<3>::build(&s).unwrap();
    let w = &m.world;
    assert!(
        w.closure.iter().all(|r| r.is_ok()),
        "closure: {:?}",
        w.closure
    );
    let ustar = case1_closed_field(&w.p.x0);
    let ku = Linearised::new(w).unwrap().stiffness_times(&ustar);
    let mut worst: f64 = 0.0;
    let mut checked = 0;
    for (i, k) in ku.iter().enumerate() {
        let x = w.p.x0[i];
        if x[2] > -0.12 {
            continue;
        }
        let mg = w.p.mass[i] * 9.81;
        let r = (k + Vect::<3>::new(0.0, 0.0, mg)) / mg;
        worst = worst.max(r.amax());
        checked += 1;
    }
    assert!(checked > 2000, "{checked} particles checked");
    assert!(worst < 1e-6, "largest residual {worst:.3e} m g");
}

/// Case 1 (the hanging column, second_order, dp = 0.025 m) in its linearised static state
/// against the clamped column's converged 3D FEM (reference/case1_fem.json) on the paper's line
/// x = 0.1 m, y = 0, with the metric of `mps cases` (max over s >= 0.2 m of |u - u_FEM| / max
/// |u_FEM|). The clamp's treatment decides this: the closed form, which leaves the support free
/// to contract laterally, is 0.95 % (u_x) and 1.00 % (u_z) from the FEM. Measured: u_x 0.043 %,
/// u_z 0.038 % (the followers at the clamped face); required 0.2 %, where the Saint-Venant
/// boundary layer at the clamp, the only error source besides the free end's, is resolved to
/// within a fifth of its size (the corrected operator's grip is 0.8 % off in u_x).
#[test]
#[ignore = "slow (20 s on a loaded 2-core machine): the full test command runs it"]
fn case1_static_against_the_clamped_column_fem() {
    use mps_solid::studies::cases::{CASE1_HALF, CASE1_STATIONS};
    let s = case1_scene(0.025, ElasticModel::SecondOrder, None);
    let mut m = Model::<3>::build(&s).unwrap();
    let u = Linearised::new(&m.world)
        .unwrap()
        .static_gravity(Vect::<3>::new(0.0, 0.0, -9.81), 1e-10)
        .unwrap();
    let fem = mps_solid::studies::report::case1_fem_line();
    let (mut ex, mut ez, mut sx, mut sz) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (&st, &(ux_fem, uz_fem)) in CASE1_STATIONS.iter().zip(&fem) {
        if st < 0.2 - 1e-9 {
            continue;
        }
        let p = Vect::<3>::new(CASE1_HALF, 0.0, -st);
        let v = field_at(&mut m.world, &u, &p, None).unwrap();
        ex = ex.max((v[0] - ux_fem).abs());
        ez = ez.max((v[2] - uz_fem).abs());
        sx = sx.max(ux_fem.abs());
        sz = sz.max(uz_fem.abs());
    }
    let (ex, ez) = (ex / sx, ez / sz);
    assert!(
        ex < 2e-3 && ez < 2e-3,
        "u_x {:.3} %, u_z {:.3} % from the FEM",
        100.0 * ex,
        100.0 * ez
    );
}

/// The warning on a body too thin for any particle to have a full neighbourhood quotes
/// measured figures (`scene::THIN_BENDING_ERRORS`, `mps study bending 2d|3d 2 3 4`): each entry
/// against the linearised cantilever of its operator, dimension and thickness (the GMS plate in
/// 2D, the slender cantilever in 3D) must agree within 0.06 percentage points, the table's
/// rounding to 0.1 plus the linear solves' round-off (1e-9), and the warning on that scene must
/// quote them. The default operator closes the faces of a box `sbp::MIN_ACROSS` = 3 particles
/// across, which is why it is not warned of there: at 3 and 4 particles through it is within
/// the 0.5 % the corrected operator's warning promises for it (measured -0.15 / +0.11 % in 3D,
/// -0.45 / +0.003 % in 2D, static deflection), against 7-17 % for the corrected operator at the
/// same thickness; the scene then has no warning at all.
#[test]
#[ignore = "slow (8 s on a 2-core machine): the full test command runs it"]
fn thin_bodies_are_warned_of_with_measured_errors() {
    use mps_solid::physics::sbp::MIN_ACROSS;
    use mps_solid::scene::THIN_BENDING_ERRORS;
    use mps_solid::studies::bending::{cantilever3d_scene, cantilever_reference};
    let run = |model: ElasticModel, d: usize, n: usize| {
        let (scene, r) = if d == 2 {
            (plate2d_scene(n, model), plate_reference())
        } else {
            (cantilever3d_scene(n, model), cantilever_reference())
        };
        let b = linear_bending(&scene).unwrap();
        (
            100.0 * (b.tip / r.tip - 1.0),
            100.0 * (b.f1 / r.f1 - 1.0),
            b.warnings,
        )
    };
    for &(model, d, n, tip, f1) in &THIN_BENDING_ERRORS {
        let (et, ef, warnings) = run(model, d, n);
        assert!(
            (et - tip).abs() < 0.06 && (ef - f1).abs() < 0.06,
            "{model:?} {d}D {n} through: static {et:+.3} %, f1 {ef:+.3} % against the \
             warning's {tip:+.1} / {f1:+.1} %"
        );
        let quoted = format!(
            "measured on a cantilever {n} particles thick ({d}D), its static deflection {:.1} %",
            tip.abs()
        );
        assert!(
            warnings.iter().any(|w| w.contains(&quoted)),
            "{model:?} {d}D {n}: {warnings:?}"
        );
    }
    for d in [2, 3] {
        for n in [MIN_ACROSS, MIN_ACROSS + 1] {
            let (et, ef, warnings) = run(ElasticModel::SecondOrder, d, n);
            assert!(
                et.abs() < 0.5 && ef.abs() < 0.5,
                "second_order {d}D {n} through: static {et:+.3} %, f1 {ef:+.3} %"
            );
            assert!(warnings.is_empty(), "{d}D {n}: {warnings:?}");
        }
    }
}
