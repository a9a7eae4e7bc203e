//! Large deflection of the slender 3D cantilever (issue 7): the nonlinear static tip under a
//! dead gravity load against the elastica (reference/cantilever3d_fem.json, key "elastica") and
//! the finite-strain 3D FEM with the same material law (reference/cantilever3d_nonlinear_fem.json),
//! found by dynamic relaxation (`bending::elastica_static`). The cheapest meaningful case:
//! `second_order` at 4 particles across, the 30 % level (g = 216 m/s^2), 13-20 s in release on
//! one loaded core, for each of the two material laws.
use mps_solid::physics::{ElasticModel, MaterialLaw};
use mps_solid::studies::bending::{
    cantilever_reference, elastica_reference, elastica_static, nonlinear_fem_reference,
    ElasticaResult, RelaxOptions, G,
};

/// Stable (no blow-up, the velocity tolerance reached) and within the tolerance of the
/// shear-corrected elastica (the elastica times the linear 3D FEM / Euler-Bernoulli ratio).
///
/// Measured: u_z +0.36 %, u_x +0.46 % (with the closure of the free faces and the clamp's
/// followers; +1.41 % and +2.22 % before the closure, with the odd mirror of the clamp). The error
/// is the operator's resolution error at 4 across, not the nonlinearity: at g = 9.81 the model's
/// linear tip is +0.11 % from the linear FEM. Bounds: u_z within 2.0 %, u_x within 3.0 % (the
/// issue's 3 %; u_x is a second-order quantity, about the mean square of the rotation, so its
/// relative error is about twice that of the rotation); both must be too soft (positive error),
/// as the resolution makes it. And the answer must be geometrically nonlinear: the linear
/// solution at this load, the model's own small-load tip scaled by g / 9.81, is about 8 % larger
/// than the one found; the test requires at least 5 % (a small-strain operator would give about
/// 0).
///
/// Against the finite-strain FEM with the same law (Saint Venant-Kirchhoff, Hex27, Richardson over
/// 3 / 4 / 6 elements across; its finest mesh is 0.02 % from its limit here), which has none of
/// the elastica's simplifications (linear moment-curvature, inextensible and shear-free axis), the
/// error is the model's resolution error alone. Measured: u_z +0.09 %, u_x +0.15 %, the same as
/// the linear tip's +0.11 % at this resolution. Bounds: both too soft, u_z within 0.25 % and u_x
/// within 0.4 % (about twice the linear resolution error, and for u_x twice that again, as
/// above). A model that reproduced the FEM-scaled elastica instead of the solid (0.27 % stiffer
/// than the solid at this level) would fail it.
#[test]
#[ignore = "slow (89 s on a loaded 2-core machine): the full test command runs it"]
fn second_order_4_across_30_percent_matches_elastica() {
    let level = elastica_reference()[0];
    assert_eq!(level.target, 0.3);
    let r = elastica_static(
        4,
        ElasticModel::SecondOrder,
        level.g,
        &RelaxOptions::default(),
    )
    .unwrap();
    assert!(r.failure.is_none(), "step failed: {:?}", r.failure);
    assert!(
        r.converged,
        "not settled after {} steps: tip {:e}, rms {:e} m/s",
        r.steps, r.tip_speed, r.rms_speed
    );
    let ez = r.uz / level.uz_fem - 1.0;
    let ex = r.ux / level.ux_fem - 1.0;
    println!(
        "u_z {:.5} m ({:+.2} %), u_x {:.5} m ({:+.2} %), {} steps, {:.1} s",
        r.uz,
        100.0 * ez,
        r.ux,
        100.0 * ex,
        r.steps,
        r.wall
    );
    assert!(ez > 0.0 && ez < 0.020, "u_z error {:+.2} %", 100.0 * ez);
    assert!(ex > 0.0 && ex < 0.030, "u_x error {:+.2} %", 100.0 * ex);
    // geometric nonlinearity: well below the linear extrapolation (-1.4753e-2 m at 9.81, the
    // model's own linear tip, is 0.11 % above the FEM's; use the FEM's scaled by that)
    let linear = cantilever_reference().tip * 1.0011 * level.g / G;
    assert!(
        r.uz / linear < 0.95,
        "u_z {:.5} m is within 5 % of the linear {:.5} m",
        r.uz,
        linear
    );
    assert_matches_finite_strain_fem(&r, MaterialLaw::SaintVenantKirchhoff, level.g);
}

/// The relaxed tip against the finite-strain FEM of the same law at gravity `g`: too soft
/// (positive error, as the resolution makes it), u_z within 0.25 % and u_x within 0.4 % (the
/// bounds and their reasons: see the test above).
fn assert_matches_finite_strain_fem(r: &ElasticaResult, law: MaterialLaw, g: f64) {
    let fem = nonlinear_fem_reference(law)
        .into_iter()
        .find(|t| t.g == g)
        .expect("the nonlinear FEM reference has the level");
    let (nz, nx) = (r.uz / fem.uz - 1.0, r.ux / fem.ux - 1.0);
    println!(
        "{}: against the finite-strain FEM u_z {:+.3} %, u_x {:+.3} %",
        law.name(),
        100.0 * nz,
        100.0 * nx
    );
    assert!(nz > 0.0 && nz < 0.0025, "u_z error {:+.3} %", 100.0 * nz);
    assert!(nx > 0.0 && nx < 0.004, "u_x error {:+.3} %", 100.0 * nx);
}

/// The neo-Hookean law at finite strain, through the whole operator, against the FEM of the same
/// law (an independent implementation of docs/model.md Eq. (NH1) in tools/fem_large_deflection.py;
/// at 30 % deflection the two laws' tips differ by 0.04 % in u_z and 1.2 % in u_x, so u_x tells
/// them apart). Measured: u_z +0.13 %, u_x +0.22 %.
#[test]
#[ignore = "slow (97 s on a loaded 2-core machine): the full test command runs it"]
fn neo_hookean_4_across_30_percent_matches_finite_strain_fem() {
    let level = elastica_reference()[0];
    let opt = RelaxOptions {
        law: MaterialLaw::NeoHookean,
        ..RelaxOptions::default()
    };
    let r = elastica_static(4, ElasticModel::SecondOrder, level.g, &opt).unwrap();
    assert!(r.failure.is_none(), "step failed: {:?}", r.failure);
    assert!(r.converged, "not settled after {} steps", r.steps);
    assert_matches_finite_strain_fem(&r, MaterialLaw::NeoHookean, level.g);
}
