//! First torsion frequency of the slender 3D cantilever (issue 7: near incompressibility),
//! from the linearised model by inverse iteration in the class of fields antisymmetric under
//! both mirrors of the section (`bending::torsion_frequency`), against the FEM of
//! reference/cantilever3d_fem.json.
use mps_solid::physics::{ElasticModel, Vect};
use mps_solid::scene::Model;
use mps_solid::studies::bending::{
    cantilever3d_scene, cantilever_torsion_reference, mirror_maps, project_torsion_class,
    torsion_frequency,
};

/// The projector onto the torsion class is a projector (P P v = P v for an arbitrary field)
/// and keeps a pure twist u = theta(x) (0, -z, y) and a warping u_x = yz whole, and removes
/// the bending and axial fields (symmetric under at least one mirror).
#[test]
fn torsion_class_projector() {
    let s = cantilever3d_scene(4, ElasticModel::SecondOrder);
    let m = Model::<3>::build(&s).unwrap();
    let x0 = &m.world.p.x0;
    let maps = mirror_maps(x0, s.particle_spacing).unwrap();
    let norm = |v: &[Vect<3>]| v.iter().map(|a| a.norm_squared()).sum::<f64>().sqrt();
    let diff = |a: &[Vect<3>], b: &[Vect<3>]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).norm_squared())
            .sum::<f64>()
            .sqrt()
    };
    // an arbitrary (deterministic, non-symmetric) field
    let v: Vec<Vect<3>> = x0
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let a = (i as f64 * 0.618).sin();
            Vect::<3>::new(a + p[1], (3.0 * a).cos() * p[2] + p[0], a * p[1] - 0.3)
        })
        .collect();
    let pv = project_torsion_class(&maps, &v);
    let ppv = project_torsion_class(&maps, &pv);
    assert!(diff(&pv, &ppv) <= 1e-14 * norm(&pv));
    assert!(norm(&pv) > 0.05 * norm(&v));
    let keep: Vec<Vect<3>> = x0
        .iter()
        .map(|p| Vect::<3>::new(p[1] * p[2] * p[0], -p[2] * p[0], p[1] * p[0]))
        .collect();
    assert!(diff(&project_torsion_class(&maps, &keep), &keep) <= 1e-14 * norm(&keep));
    for drop in [
        x0.iter()
            .map(|p| Vect::<3>::new(-p[2], 0.0, p[0] * p[0]))
            .collect::<Vec<_>>(),
        x0.iter()
            .map(|p| Vect::<3>::new(-p[1], p[0] * p[0], 0.0))
            .collect(),
        x0.iter()
            .map(|p| Vect::<3>::new(p[0], 0.3 * p[1], 0.3 * p[2]))
            .collect(),
    ] {
        assert!(norm(&project_torsion_class(&maps, &drop)) <= 1e-14 * norm(&drop));
    }
}

/// Second-order operator, nu = 0.3, 4 particles across: measured 43.945 Hz, -2.57 % against
/// the FEM 45.104 Hz with the summation-by-parts closure of the free faces (module
/// `physics::sbp`); with the plain fits it was 43.452 Hz, -3.66 % (and -2.22 / -1.18 / -0.76 %
/// at 5 / 8 / 10 across, not re-measured with the closure: the discretisation error, too soft,
/// falling as dp^1.3-2.2). The window -3.32 % .. -1.82 % is the measured error +- 0.75 points:
/// wide enough for changes of summation order (the result is converged to 1e-9 in the Rayleigh
/// quotient), narrow enough to catch a lost term of the operator (corrected gives +1.13 %) or
/// a lost closure. The mode must be torsion: more than 99.9 % of its kinetic energy
/// in a rigid rotation of each section (measured 1 - 4.9e-5; the rest is warping), and the
/// discrete operator must respect the mirror symmetry the projection relies on (measured 1e-12).
#[test]
#[ignore = "slow (9 s on a loaded 2-core machine): the full test command runs it"]
fn second_order_torsion_at_4_across() {
    let (fem, _) = cantilever_torsion_reference();
    let (f, info) = torsion_frequency(&cantilever3d_scene(4, ElasticModel::SecondOrder)).unwrap();
    let err = f / fem - 1.0;
    assert!(
        (-0.0332..-0.0182).contains(&err),
        "f = {f} Hz vs FEM {fem} ({:+.2} %)",
        100.0 * err
    );
    assert!(info.rotation_fraction > 0.999, "{info:?}");
    assert!(info.symmetry_defect < 1e-6, "{info:?}");
}

/// Near incompressibility, the case: corrected operator (the default), nu = 0.499
/// (lambda / mu = 499), 4 across: measured 42.536 Hz, +1.24 % against the mixed Q2-P1disc FEM
/// 42.015 Hz (+1.13 % at nu = 0.3): no volumetric locking in torsion, which is isochoric in
/// the continuum. The window +0.5 % .. +2.0 % is that error +- 0.75 points; a locking
/// operator would be several per cent stiff and grow with lambda.
#[test]
#[ignore = "slow (17 s on a loaded 2-core machine): the full test command runs it"]
fn corrected_torsion_near_incompressible_at_4_across() {
    let (_, fem) = cantilever_torsion_reference();
    let mut s = cantilever3d_scene(4, ElasticModel::Corrected);
    s.bodies[0].material.poisson = 0.499;
    let (f, info) = torsion_frequency(&s).unwrap();
    let err = f / fem - 1.0;
    assert!(
        (0.005..0.020).contains(&err),
        "f = {f} Hz vs FEM {fem} ({:+.2} %)",
        100.0 * err
    );
    assert!(info.rotation_fraction > 0.999, "{info:?}");
}
