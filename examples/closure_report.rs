//! Diagnostic (issue 7): the summation-by-parts closure of the second-order operator's free
//! faces (module `physics::sbp`) for the paper's cases 1 and 2 and the bending benchmarks: per
//! body the solve's iterations, residuals, largest correction and wall time, or why a body
//! keeps its plain fits. `cargo run --release --example closure_report`
use mps_solid::bending::{cantilever3d_scene, plate2d_scene};
use mps_solid::cases::{case1_scene, case2_scene, Support};
use mps_solid::physics::ElasticModel;
use mps_solid::scene::{Model, Scene};

fn report<const D: usize>(name: &str, s: &Scene)
where
    mps_solid::physics::Space: mps_solid::physics::Dim<D>,
{
    let m = Model::<D>::build(s).unwrap();
    for (k, r) in m.world.closure.iter().enumerate() {
        match r {
            Ok(line) => println!("{name}, body {k}: {line}"),
            Err(why) => println!("{name}, body {k}: not closed: {why}"),
        }
    }
}

fn main() {
    let so = ElasticModel::SecondOrder;
    report::<3>("case 1 (dp 0.025)", &case1_scene(0.025, so, None));
    report::<3>(
        "case 2 (dp 0.025)",
        &case2_scene(0.025, so, None, Support::Face),
    );
    for n in [4, 8, 16] {
        report::<2>(&format!("GMS plate, {n} across"), &plate2d_scene(n, so));
    }
    for n in [4, 8] {
        report::<3>(
            &format!("cantilever, {n} across"),
            &cantilever3d_scene(n, so),
        );
    }
}
