//! Fracture never creates energy (issue 7): the small2d cantilever thrown against its own holder
//! at 5 m/s with fracture_strain 0.01 and fractured-surface contact on. A broken bond releases its
//! stored energy; the contact across it must not push at the moment it breaks. Before the fix the
//! held layer sits half a spacing from the first free layer, so a broken bond of that pair started
//! at 0.5 l0 inside the contact range and the contact spring added ~60 J per broken pair
//! (547 J -> 884 J kinetic + strain in 0.5 ms).
use crate::common;
use mps_solid::physics::World;
use mps_solid::scene::{Model, Scene};
use serde_json::Value;

fn small2d_with(velocity: [f64; 2], fractured_surfaces: bool, model: &str) -> World<2> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v: Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("tests/data/small2d.json")).unwrap(),
    )
    .unwrap();
    // No gravity: kinetic + strain + contact is then the whole energy.
    v["gravity"] = serde_json::json!({ "vector": [0.0, 0.0] });
    v["bodies"][0]["velocity"] = serde_json::json!(velocity);
    v["solver"] = serde_json::json!({
        "model": model,
        "fracture_strain": 0.01,
        "contact": { "fractured_surfaces": fractured_surfaces }
    });
    let scene = Scene::from_json(&v.to_string()).unwrap();
    Model::<2>::build(&scene).unwrap().world
}

fn total(w: &World<2>) -> f64 {
    w.kinetic_energy() + w.strain_energy() + w.contact_energy()
}

/// Runs `t_end` seconds step by step at `factor` times the automatic step; returns (energy
/// after the first step, largest energy after it, largest mean over the time of 10 automatic
/// steps (10 / factor steps) after it, broken pairs). The first step stops the held particles
/// (their kinetic energy is taken out by the holder), so the reference is the energy after it.
fn run_at(mut w: World<2>, t_end: f64, factor: f64) -> (f64, f64, f64, u64) {
    let dt = w.max_dt() * factor;
    let window = (10.0 / factor).round() as usize;
    w.step(dt).unwrap();
    let e0 = total(&w);
    let mut e = vec![];
    while w.time < t_end {
        w.step(dt).unwrap();
        e.push(total(&w));
    }
    let emax = e.iter().fold(e0, |a, &b| a.max(b));
    let mean10 = e
        .windows(window)
        .map(|x| x.iter().sum::<f64>() / window as f64)
        .fold(f64::MIN, f64::max);
    (e0, emax, mean10, w.broken_pairs)
}

/// Runs the impact at `vel` with `model` at `factor` x the automatic step and checks that the
/// energy after the first step is never exceeded. Symplectic Euler's energy measured at the
/// step ends oscillates from step to step by O(dt omega) of the energy in the highest modes
/// (period ~4 steps at the default safety) around a conserved shadow energy; created energy
/// (the contact defect: +60 % in 5 ms) persists. So: the mean over 10 automatic steps within
/// 0.1 % and single steps within 0.5 % (measured at most +0.28 %, below).
fn assert_creates_no_energy(model: &str, factor: f64, vel: [f64; 2]) {
    let (e0, emax, mean10, broken) = run_at(small2d_with(vel, true, model), 5e-3, factor);
    eprintln!(
        "{model}, {factor} x dt, v = {vel:?}: E0 {e0:.2} J, max {:+.3} %, 10-step mean {:+.3} %, {broken} pairs",
        100.0 * (emax / e0 - 1.0),
        100.0 * (mean10 / e0 - 1.0)
    );
    assert!(broken > 0, "the scenario must break bonds");
    assert!(
        mean10 <= e0 * 1.001,
        "{model}, {factor} x the automatic step, v = {vel:?}: energy rose from {e0} J to {mean10} J (10-step mean)"
    );
    assert!(
        emax <= e0 * 1.005,
        "{model}, {factor} x the automatic step, v = {vel:?}: energy rose from {e0} J to {emax} J"
    );
}

/// The three impacts at the automatic step (corrected). Measured with the C1 contact onset:
/// single steps up to +1.2 % (v = -y), the 10-step mean never above -0.13 %; with the retained
/// share at breaks no single step above the energy after the first and the mean at most
/// -0.002 % (v = +x, which breaks 78 pairs and releases little).
#[test]
fn fracture_on_impact_creates_no_energy() {
    for vel in [[0.0, -5.0], [5.0, 0.0], [-5.0, 0.0]] {
        assert_creates_no_energy("corrected", 1.0, vel);
    }
}

/// Fracture creates no energy at any time step, with either operator that re-fits its
/// particles at a break. The re-fit of a particle that lost bonds has no bound by the energy it
/// held before: a fit over fewer bonds can see more strain at the same positions. Before
/// `SHAPE_MIN_CONDITION` and the first-order fit of second_order's cut particles, the re-fit
/// raised the strain energy at fixed positions by up to 45 J on two broken pairs, and the
/// impact at v = -y gained, as the largest total after the first step: corrected +1.2 % /
/// +15.9 % / +20.9 % at 1 / 0.5 / 0.25 x the automatic step, second_order +46 % and an overlap
/// stop at the automatic step. With those and before the retained share
/// (`ElasticOperator::retained`: a particle whose re-fit would hold more than it held just
/// before the break keeps only the share that holds the same), corrected at most +0.97 % in a
/// step, second_order +0.68 % in a step and +0.38 % in the 10-step mean at 0.25 x (v = -y).
/// With the share (`mps study fracture_energy_dt`): the largest single step +0.24 %
/// (corrected, v = -x, 0.25 x), second_order at most +0.24 %. Bounds as in the test above.
#[test]
fn fracture_creates_no_energy_at_any_step() {
    for model in ["corrected", "second_order"] {
        for factor in [1.0, 0.5, 0.25] {
            for vel in [[0.0, -5.0], [-5.0, 0.0]] {
                assert_creates_no_energy(model, factor, vel);
            }
        }
    }
}

/// The breaks release energy and the share limits only particles whose re-fit would have
/// raised it: after the second_order impact at v = -y, the released energy is positive and
/// below the energy in the body, and every share lies in (0, 1].
#[test]
fn breaks_release_energy_and_shares_stay_in_range() {
    let mut w = small2d_with([0.0, -5.0], true, "second_order");
    let dt = w.max_dt();
    let e_start = w.kinetic_energy();
    while w.time < 5e-3 {
        w.step(dt).unwrap();
    }
    let limited = w.op.retained.iter().filter(|&&r| r < 1.0).count();
    eprintln!(
        "{} broken pairs, {:.2} J released of {e_start:.1} J, {limited} particles limited",
        w.broken_pairs, w.fracture_release
    );
    assert!(w.broken_pairs > 0);
    assert!(w.fracture_release > 0.0 && w.fracture_release < e_start);
    assert!(w.op.retained.iter().all(|&r| r > 0.0 && r <= 1.0));
}

/// Every particle of an intact lattice block keeps its full span under `SHAPE_MIN_CONDITION`:
/// the smallest eigenvalue ratio of the shape tensors of a block (faces, edges, corners) and of
/// a plate two particles thick, 2D and 3D, is well above it (measured minima in the message).
#[test]
fn intact_neighbourhoods_keep_their_full_span() {
    use mps_solid::physics::dim::sym_eigen;
    use mps_solid::physics::elastic::{shape_tensor, SHAPE_MIN_CONDITION};
    fn min_ratio<const D: usize>(w: &World<D>) -> f64
    where
        mps_solid::physics::Space: mps_solid::physics::Dim<D>,
    {
        (0..w.len())
            .map(|i| {
                let (vals, _) = sym_eigen(&shape_tensor(&w.bonds, i));
                let top = vals.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                vals.iter().fold(f64::INFINITY, |a, v| a.min(v.abs())) / top
            })
            .fold(f64::INFINITY, f64::min)
    }
    let cases = [
        (
            "2D block 6 x 5",
            min_ratio(&common::free_world::<2>(
                [6, 5, 1],
                mps_solid::physics::ElasticModel::Corrected,
            )),
        ),
        (
            "2D strip 8 x 2",
            min_ratio(&common::free_world::<2>(
                [8, 2, 1],
                mps_solid::physics::ElasticModel::Corrected,
            )),
        ),
        (
            "3D block 5 x 4 x 3",
            min_ratio(&common::free_world::<3>(
                [5, 4, 3],
                mps_solid::physics::ElasticModel::Corrected,
            )),
        ),
        (
            "3D plate 6 x 5 x 2",
            min_ratio(&common::free_world::<3>(
                [6, 5, 2],
                mps_solid::physics::ElasticModel::Corrected,
            )),
        ),
    ];
    for (what, r) in cases {
        eprintln!("{what}: smallest eigenvalue ratio {r:.3}");
        assert!(
            r > 2.0 * SHAPE_MIN_CONDITION,
            "{what}: an intact particle's shape tensor has an eigenvalue ratio {r:.3}, within a factor 2 of the cut-off {SHAPE_MIN_CONDITION}"
        );
    }
}
