//! The paper's cases 1 and 2 at the paper's particle spacing dp = 0.025 m against their
//! references, and the scene files under scenes/ against the builders.
use mps_solid::physics::ElasticModel;
use mps_solid::studies::cases::{paper_scenes, CASE1_STATIONS};
use mps_solid::studies::report;

#[test]
#[ignore = "slow (52 s on a loaded 2-core machine): the full test command runs it"]
fn case1_column_matches_closed_form_within_3_percent() {
    // Lateral and axial displacement along the paper's line x = 0.1 m, y = 0: the relative
    // max-norm error over s >= 0.2 m (max |u - u_cf| / max |u_cf| on the line) must be <= 3 %
    // (the accuracy target at dp = 0.025; measured ~0.9 % and ~1.1 %). Closer to the
    // support the clamped face stops the lateral contraction the closed form assumes (Saint-Venant).
    let r = report::case1(0.025, ElasticModel::Corrected, None, |_| {}).unwrap();
    assert_eq!(r.stations.len(), CASE1_STATIONS.len());
    assert!(r.error_ux <= 0.03, "u_x error {}", r.error_ux);
    assert!(r.error_uz <= 0.03, "u_z error {}", r.error_uz);
    // Statics: the support carries the whole weight once the motion has settled (damping
    // 20 1/s over 0.8 s leaves e^-8 of the ramp's residual oscillation): 0.1 %.
    assert!(
        (r.reaction_z / r.weight - 1.0).abs() < 1e-3,
        "reaction {} vs weight {}",
        r.reaction_z,
        r.weight
    );
}

#[test]
#[ignore = "slow (48 s on a loaded 2-core machine): the full test command runs it"]
fn case2_beam_first_frequency_within_3_percent_of_3d_fem() {
    // First bending frequency from the least-squares sinusoid fit of the deflection at
    // x = 0.56 m, against the converged 3D FEM reference (reference/case2_fem.json): 3 %.
    // Peak deflection under suddenly applied gravity against the FEM modal-superposition peak:
    // 5 % (it also contains the higher modes' contribution, which the particle model resolves
    // less well; measured ~1.4 %).
    let r = report::case2(0.025, ElasticModel::Corrected, None, |_| {}).unwrap();
    assert!(
        r.frequency_error.abs() <= 0.03,
        "frequency {} Hz vs FEM {} Hz",
        r.frequency_hz,
        r.fem.f1_hz
    );
    assert!(
        r.peak_error.abs() <= 0.05,
        "peak {} m vs FEM {} m",
        r.peak_deflection_m,
        r.fem.peak_dynamic_uz_m
    );
    // Shear deformation and rotary inertia: a 3D solid must come out below Euler-Bernoulli.
    assert!(r.frequency_hz < r.euler_bernoulli_hz * 0.9);
}

#[test]
fn scene_files_match_the_case_builders() {
    // scenes/*.json are the builders' output (regenerate with `mps scenes scenes`).
    for sc in paper_scenes()
        .into_iter()
        .chain(mps_solid::studies::bending::benchmark_scenes())
    {
        let path = format!("{}/scenes/{}.json", env!("CARGO_MANIFEST_DIR"), sc.name);
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let file = mps_solid::Scene::from_json(&text).unwrap();
        assert_eq!(
            file, sc,
            "{path} is stale: run `cargo run --release -- scenes scenes`"
        );
    }
}

#[test]
fn case2_written_as_a_box_shape_is_within_one_percent_at_5_particles_across() {
    // Case 2 as a user who draws solids writes it (studies::cases::case2_shape_scene: one box
    // shape from the clamp's 3 layers to the support's, regions for both, the default
    // operator) at dp = 1/21 m: whole spacings along the 1 m span, 4.725 across the 0.225 m
    // section (5 particles, the faces 0.36 of a spacing beyond the outer ones). The first
    // frequency and the peak under sudden gravity against the 3D FEM within 1 %, issue 25's
    // bound for its real-time figure (measured +0.33 % and -0.80 %; at the paper's dp = 0.025,
    // 9 across, the box scene's -0.08 / +0.11 %). Before the closure took box solids' faces
    // where they are, this scene was closed as the particles' own box (the section 0.19 m
    // deep) or, at dp = 0.025, lost the half cells beyond its lattice: peak +19 %.
    let scene = mps_solid::studies::cases::case2_shape_scene(1.0 / 21.0);
    let r = report::case2_of(&scene, |_| {}).unwrap();
    assert!(
        r.frequency_error.abs() <= 0.01 && r.peak_error.abs() <= 0.01,
        "f1 {:+.4}, peak {:+.4}",
        r.frequency_error,
        r.peak_error
    );
}

#[test]
fn case1_written_as_a_box_shape_is_within_one_percent_at_4_particles_across() {
    // Case 1 as a user who draws solids writes it (studies::cases::case1_shape_scene: the
    // column and 3 layers above its support as one box shape, a `clamped` region over them,
    // the default operator) at dp = 1/21 m: 4.2 spacings across the 0.2 m section (4
    // particles, the faces 0.6 of a spacing beyond the outer ones). u_x and u_z along the
    // paper's line against the clamped column's 3D FEM within 1 %, issue 25's bound for its
    // real-time figure (measured +0.70 % and +0.11 %; at dp = 1/20, 4 across on the cell
    // faces, u_x +1.01 %).
    let scene = mps_solid::studies::cases::case1_shape_scene(1.0 / 21.0);
    let r = report::case1_of(&scene, |_| {}).unwrap();
    assert!(
        r.error_ux_fem.abs() <= 0.01 && r.error_uz_fem.abs() <= 0.01,
        "u_x {:+.4}, u_z {:+.4}",
        r.error_ux_fem,
        r.error_uz_fem
    );
}
