//! The material law of the energy operators (issue 7, docs/model.md "Material law"): the
//! neo-Hookean law's forces are the gradient of its energy and objective, it has the small-strain
//! limit of Saint Venant-Kirchhoff, a collapsed particle stops the run with an error naming it
//! (never NaN), the paper's operators refuse it, and a Saint Venant-Kirchhoff blow-up says when
//! the material had failed first.
use crate::common;
use common::block;
use mps_solid::physics::boundary::GravityLaw;
use mps_solid::physics::world::{GroupInit, WorldState};
use mps_solid::physics::{
    BodyInit, ElasticModel, InitialVelocity, Material, MaterialLaw, SimError, SolverOptions, Vect,
    World,
};
use mps_solid::studies::bending::{linear_bending, plate2d_scene};
use nalgebra::{Matrix3, Rotation3};

const ENERGY_MODELS: [ElasticModel; 2] = [ElasticModel::Corrected, ElasticModel::SecondOrder];
const LAWS: [MaterialLaw; 2] = [MaterialLaw::SaintVenantKirchhoff, MaterialLaw::NeoHookean];

fn material(law: MaterialLaw, poisson: f64) -> Material {
    Material {
        density: 1000.0,
        young: 1e7,
        poisson,
        law,
    }
}

/// A 6 x 5 x 4 block at l0 = 0.1 m, clamped on its x = 0 face when `clamp`.
fn block3(model: ElasticModel, law: MaterialLaw, clamp: bool) -> World<3> {
    let l0 = 0.1;
    let mut pts = vec![];
    for i in 0..6 {
        for j in 0..5 {
            for k in 0..4 {
                pts.push(Vect::<3>::new(i as f64, j as f64, k as f64) * l0);
            }
        }
    }
    let groups = if clamp {
        vec![GroupInit {
            name: "clamp".into(),
            members: (0..pts.len() as u32)
                .filter(|&i| pts[i as usize][0] < 0.5 * l0)
                .collect(),
            axes: [true; 3],
            fix_rotation: true,
            mirror: None,
        }]
    } else {
        vec![]
    };
    World::<3>::new(
        l0,
        SolverOptions {
            model,
            ..SolverOptions::default()
        },
        vec![BodyInit {
            name: "b".into(),
            material: material(law, -0.5),
            points: pts,
            velocity: Vect::<3>::zeros().into(),
            shape: None,
        }],
        groups,
        vec![],
        GravityLaw::Constant(Vect::<3>::zeros()),
    )
    .unwrap()
}

/// Breaks every bond of particle `victim` but those along x, leaving it a rank-1 span (the
/// degenerate neighbourhood fracture leaves; the second-order fit falls back to first order).
fn break_to_a_line(w: &mut World<3>, victim: usize) {
    let mut touched = vec![victim];
    let bonds: Vec<usize> = w.bonds.of(victim).collect();
    for b in bonds {
        let r0 = w.bonds.r0[b];
        if r0[1].abs() + r0[2].abs() > 1e-9 {
            let j = w.bonds.nbr[b] as usize;
            w.bonds.w0[b] = 0.0;
            let back = w
                .bonds
                .of(j)
                .find(|&k| w.bonds.nbr[k] as usize == victim)
                .unwrap();
            w.bonds.w0[back] = 0.0;
            touched.push(j);
        }
    }
    for &i in &touched {
        let n_ref = w.p.n_ref[i];
        w.op.refresh_particle(&w.bonds, i, n_ref);
    }
}

/// A large deformation about the block's centre: rotation by 0.6 rad about (1, 2, 3),
/// stretches (1.25, 0.8, 0.9), a bending u_z = 0.4 x^2 / m, and on the free particles a random
/// part of `noise` l0 (a clamp's particles move with the smooth field: the grip moved).
fn deformed(w: &World<3>, noise: f64) -> WorldState<3> {
    let mut rng = common::Rng(99);
    let r = Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vect::<3>::new(1.0, 2.0, 3.0)),
        0.6,
    );
    let f = r.matrix() * Matrix3::from_diagonal(&Vect::<3>::new(1.25, 0.8, 0.9));
    let c = Vect::<3>::new(0.25, 0.2, 0.15);
    let mut s = w.state();
    for i in 0..w.len() {
        let x = w.p.x0[i] - c;
        s.u[i] = f * (x + Vect::<3>::new(0.0, 0.0, 0.4 * x[0] * x[0])) - x;
        if w.p.fix[i] == 0 {
            s.u[i] += Vect::<3>::new(rng.next(), rng.next(), rng.next()) * (noise * w.l0);
        }
    }
    s
}

#[test]
fn forces_are_the_energy_gradient_at_large_strain() {
    // f . v = -dE/du . v by central differences, for a large deformation (stretches 0.8-1.25,
    // a 0.6 rad rotation, 2 % of l0 of random motion) of a clamped block whose particle 77 has
    // a rank-1 span, both operators, both laws, nu = -0.5 (lambda < 0). The difference
    // quotient's truncation at eps = 1e-6 l0 is ~1e-10 relative and the round-off of E ~1e-11:
    // 1e-6 is far below any error of a term (a missing geometric or span term is O(1)).
    for model in ENERGY_MODELS {
        for law in LAWS {
            let mut w = block3(model, law, true);
            break_to_a_line(&mut w, 77);
            let u = deformed(&w, 0.02);
            w.set_state(&u).unwrap();
            let mut rng = common::Rng(5);
            let v: Vec<Vect<3>> = (0..w.len())
                .map(|i| {
                    if w.p.fix[i] == 0 {
                        Vect::<3>::new(rng.next(), rng.next(), rng.next())
                    } else {
                        Vect::<3>::zeros()
                    }
                })
                .collect();
            common::assert_forces_are_minus_the_energy_gradient_along(
                &mut w,
                &u,
                &v,
                &format!("{model:?} {law:?}"),
            );
        }
    }
}

#[test]
fn energy_models_are_objective() {
    // A rigid rotation R (2.3 rad) of a deformed free body leaves its energy unchanged and
    // rotates its forces: E(R x) = E(x), f(R x) = R f(x), exact in the continuum. The deformation
    // is large (stretches 0.8-1.25, a quadratic bend) with 5 % of l0 of random motion, which the
    // second-order operator's stabilisation carries (it pairs each bond's residual with the
    // bond's current direction; with the reference direction the energy moved by 3e-5 of
    // itself). Both laws. The corrected operator forms F from relative vectors only, so its
    // bounds are round-off: 1e-12 of the energy and 1e-10 of the largest force (the forces are
    // differences of terms ~1e3 times larger). The second-order fits reproduce the rotation (a
    // linear field of size 1) only to ~3e-6 at this small block's corners, whose moment
    // matrices are conditioned ~1e10 (measured), which moves the energy by ~2e-7 of itself and
    // the forces by ~3e-6 of the largest: bounds 1e-6 and 1e-5.
    for (model, law, tol_e, tol_f) in [
        (
            ElasticModel::Corrected,
            MaterialLaw::NeoHookean,
            1e-12,
            1e-10,
        ),
        (
            ElasticModel::SecondOrder,
            MaterialLaw::NeoHookean,
            1e-6,
            1e-5,
        ),
        (
            ElasticModel::SecondOrder,
            MaterialLaw::SaintVenantKirchhoff,
            1e-6,
            1e-5,
        ),
    ] {
        let noise = 0.05;
        let mut w = block3(model, law, false);
        let u = deformed(&w, noise);
        w.set_state(&u).unwrap();
        let e0 = w.strain_energy();
        let f0: Vec<Vect<3>> = (0..w.len()).map(|i| w.internal_force(i)).collect();
        let fmax = f0.iter().map(|f| f.norm()).fold(0.0, f64::max);
        let r = Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vect::<3>::new(-2.0, 1.0, 0.5)),
            2.3,
        );
        let mut s = u.clone();
        for i in 0..w.len() {
            let x = w.p.x0[i] + u.u[i];
            s.u[i] = r * x - w.p.x0[i];
        }
        w.set_state(&s).unwrap();
        let e1 = w.strain_energy();
        let df = (0..w.len())
            .map(|i| (w.internal_force(i) - r * f0[i]).norm())
            .fold(0.0, f64::max);
        eprintln!(
            "{model:?} {law:?}: energy {:+.2e}, forces {:.2e} relative",
            e1 / e0 - 1.0,
            df / fmax
        );
        assert!(
            e0 > 0.0 && (e1 - e0).abs() < tol_e * e0,
            "{model:?} {law:?}: {e0} vs {e1}"
        );
        assert!(
            df < tol_f * fmax,
            "{model:?} {law:?}: forces off by {df:e} of {fmax:e}"
        );
    }
}

#[test]
#[ignore = "slow (12 s on a loaded 2-core machine): the full test command runs it"]
fn neo_hookean_has_the_small_strain_limit_of_saint_venant_kirchhoff() {
    // Both laws have the tangent 2 mu I + lambda I x I at zero strain, so the linearised first
    // frequency and static tip deflection of the GMS plate (4 across, nu = 0.3975) must agree.
    // The linearisation differences the forces at strains of ~1e-6, where the laws differ by
    // O(1e-6) relative in stress, cancelled to O(1e-12) by the central difference; the CG and
    // inverse iteration converge to 1e-10. Bound: 1e-6 relative, as the issue asks.
    for model in ENERGY_MODELS {
        let mut s = plate2d_scene(4, model);
        let svk = linear_bending(&s).unwrap();
        s.bodies[0].material.law = MaterialLaw::NeoHookean;
        let nh = linear_bending(&s).unwrap();
        let df = nh.f1 / svk.f1 - 1.0;
        let dt = nh.tip / svk.tip - 1.0;
        eprintln!("{model:?}: f1 {:+.3e}, tip {:+.3e} relative", df, dt);
        assert!(df.abs() < 1e-6, "{model:?}: f1 {} vs {}", nh.f1, svk.f1);
        assert!(dt.abs() < 1e-6, "{model:?}: tip {} vs {}", nh.tip, svk.tip);
    }
}

/// An 8 x 8 block (l0 = 0.01 m) moving towards its middle along x at `rate` (1/s):
/// v = -rate (X - X_c, 0), with a fixed step `dt`.
fn squeezed(model: ElasticModel, law: MaterialLaw, rate: f64, dt: f64) -> World<2> {
    let l0 = 0.01;
    let pts = block::<2>([8, 8, 1], l0);
    let v: Vec<Vect<2>> = pts
        .iter()
        .map(|x| Vect::<2>::new(-rate * x[0], 0.0))
        .collect();
    World::<2>::new(
        l0,
        SolverOptions {
            model,
            dt: Some(dt),
            ..SolverOptions::default()
        },
        vec![BodyInit {
            name: "block".into(),
            material: material(law, 0.3),
            points: pts,
            velocity: InitialVelocity::PerParticle {
                w: vec![0.0; v.len()],
                v,
            },
            shape: None,
        }],
        Vec::<GroupInit>::new(),
        vec![],
        GravityLaw::Constant(Vect::<2>::zeros()),
    )
    .unwrap()
}

#[test]
fn a_collapsed_neo_hookean_particle_is_an_error_naming_it() {
    // In one step of 1 ms at a squeeze rate of 1500 1/s every particle moves 1.5 times its
    // distance to the middle: F = diag(-0.5, 1), det F = -0.5, the body turned inside out along
    // x. The forces of the start state are zero, so the step itself is no blow-up; the state
    // it reaches has no neo-Hookean energy, and the run stops there with an error naming the
    // particle, its body and det F; every force stays finite.
    for model in ENERGY_MODELS {
        let mut w = squeezed(model, MaterialLaw::NeoHookean, 1500.0, 1e-3);
        let e = w.step(1e-3).unwrap_err();
        match &e {
            SimError::Collapsed {
                particle,
                body,
                det,
                ..
            } => {
                assert_eq!(body, "block");
                assert!(*particle < w.len());
                // The affine part is exact for the first-order fit: det F = -0.5 to round-off.
                assert!((det + 0.5).abs() < 1e-9, "{model:?}: det F {det}");
            }
            other => panic!("{model:?}: {other}"),
        }
        let text = e.to_string();
        assert!(
            text.contains("of body 'block' has det F = -5.0000e-1") && text.contains("neo-Hookean"),
            "{text}"
        );
        assert!((0..w.len()).all(|i| w.internal_force(i).iter().all(|c| c.is_finite())));
        assert!(w.strain_energy() == f64::INFINITY);
        // The same state restored is refused the same way.
        let s = w.state();
        let mut fresh = squeezed(model, MaterialLaw::NeoHookean, 1500.0, 1e-3);
        assert!(matches!(
            fresh.set_state(&s),
            Err(SimError::Collapsed { .. })
        ));
        // Saint Venant-Kirchhoff has an energy there (the mirror image's): no such error.
        let mut svk = squeezed(model, MaterialLaw::SaintVenantKirchhoff, 1500.0, 1e-3);
        svk.step(1e-3).unwrap();
    }
}

#[test]
fn paper_operators_refuse_the_neo_hookean_law() {
    for model in [ElasticModel::Paper, ElasticModel::PaperLocal] {
        let e = World::<2>::new(
            0.01,
            SolverOptions {
                model,
                ..SolverOptions::default()
            },
            vec![BodyInit {
                name: "strip".into(),
                material: material(MaterialLaw::NeoHookean, 0.3),
                points: block::<2>([4, 4, 1], 0.01),
                velocity: Vect::<2>::zeros().into(),
                shape: None,
            }],
            Vec::<GroupInit>::new(),
            vec![],
            GravityLaw::Constant(Vect::<2>::zeros()),
        )
        .err()
        .unwrap()
        .to_string();
        assert!(
            e.contains("body 'strip' (bodies[0]): material.law = neo_hookean needs an operator with a strain energy density"),
            "{e}"
        );
    }
}

/// An 8 x 8 block of Saint Venant-Kirchhoff material compressed along x to the stretch `s`
/// (uniform), stepped once with a step of 1 ms, 30 times its stable step: the surface
/// particles are kicked by more than half a spacing.
fn svk_blow_up(model: ElasticModel, s: f64) -> String {
    let mut w = squeezed(model, MaterialLaw::SaintVenantKirchhoff, 0.0, 1e-3);
    let mut st = w.state();
    for i in 0..w.len() {
        st.u[i] = Vect::<2>::new((s - 1.0) * w.p.x0[i][0], 0.0);
    }
    w.set_state(&st).unwrap();
    match w.step(1e-3) {
        Err(e @ SimError::BlowUp { .. }) => e.to_string(),
        other => panic!("{model:?} stretch {s}: {other:?}"),
    }
}

#[test]
fn saint_venant_kirchhoff_blow_up_says_when_the_material_had_failed() {
    // Compressed to a stretch of 0.5 < 1/sqrt(3) the whole block is beyond the law's stability
    // limit: the blow-up message says so, with the stretch of the failing particle, and points
    // to the neo-Hookean law. At 0.9 the same blow-up (a step far too long) is the scheme's and
    // the message says nothing of the material.
    for model in ENERGY_MODELS {
        let e = svk_blow_up(model, 0.5);
        assert!(
            e.contains("64 particle(s) of body 'block' (0 of them inverted) were compressed beyond a principal stretch of 1/sqrt(3)")
                && e.contains("is compressed to a principal stretch 0.500 < 1/sqrt(3) (det F 0.500)")
                && e.contains("material.law = \"neo_hookean\""),
            "{model:?}: {e}"
        );
        let e = svk_blow_up(model, 0.9);
        assert!(
            e.starts_with("numerical blow-up") && e.ends_with("reduce dt or check loads"),
            "{model:?}: {e}"
        );
    }
}
