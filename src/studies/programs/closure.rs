//! Diagnostic (issue 7): the summation-by-parts closure of the second-order operator's free
//! faces (module `physics::sbp`) for the paper's cases 1 and 2 and the bending benchmarks: per
//! body the solve's iterations, residuals, largest correction and wall time, or why a body
//! keeps its plain fits. `cargo run --release -- study closure`; `-- cube N` reports a
//! free cube of N^3 particles instead (the bulky body whose build is the slowest), with
//! CLAMP=1 one face clamped by 3 wall layers behind it (no mirror field), with
//! CORRECTED=1 the corrected operator's build for comparison; `-- family N` reports the bodies
//! of issue 24's family (`studies::family`) at N particles across, `-- scene FILE` those of a
//! scene file.
use crate::physics::ElasticModel;
use crate::scene::{Model, Scene};
use crate::studies::bending::{cantilever3d_scene, plate2d_scene};
use crate::studies::cases::{case1_scene, case2_scene, Support};

fn report<const D: usize>(name: &str, s: &Scene)
where
    crate::physics::Space: crate::physics::Dim<D>,
{
    let m = Model::<D>::build(s).unwrap();
    for (k, r) in m.world.closure.iter().enumerate() {
        match r {
            Ok(line) => println!("{name}, body {k}: {line}"),
            Err(why) => println!("{name}, body {k}: not closed: {why}"),
        }
    }
}

/// A free cube of n^3 particles at dp 0.1 m, second_order (the default operator); `clamped`:
/// with 3 wall layers behind its face x = 0 in a clamped region (written as a user would).
fn cube_scene(n: usize, clamped: bool, model: ElasticModel) -> Scene {
    let side = 0.1 * n as f64;
    let mut boxes = vec![serde_json::json!({"min": [0.0, 0.0, 0.0], "max": [side, side, side]})];
    let mut boundaries = vec![];
    if clamped {
        boxes.push(serde_json::json!({"min": [-0.3, 0.0, 0.0], "max": [0.0, side, side]}));
        boundaries.push(
            serde_json::json!({"name": "clamp", "kind": "clamped", "body": "cube",
            "region": {"min": [-0.3, 0.0, 0.0], "max": [-0.01, side, side]}}),
        );
    }
    let mut s: Scene = serde_json::from_value(serde_json::json!({
        "name": format!("cube{n}"),
        "dimension": 3,
        "particle_spacing": 0.1,
        "bodies": [{
            "name": "cube",
            "material": {"density": 1000.0, "young": 1e6, "poisson": 0.3},
            "boxes": boxes
        }],
        "boundaries": boundaries,
        "end_time": 0.001,
        "output_interval": 0.001
    }))
    .expect("cube scene");
    s.solver.model = model;
    s
}

pub fn main(args: Vec<String>) {
    let args: Vec<String> = args.clone().into_iter().skip(1).collect();
    if args.first().map(String::as_str) == Some("cube") {
        let n = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(20);
        let t = std::time::Instant::now();
        let clamped = std::env::var("CLAMP").is_ok();
        let model = if std::env::var("CORRECTED").is_ok() {
            ElasticModel::Corrected
        } else {
            ElasticModel::SecondOrder
        };
        report::<3>(
            &format!("cube {n}^3{}", if clamped { ", clamped face" } else { "" }),
            &cube_scene(n, clamped, model),
        );
        println!("build {:.1} s", t.elapsed().as_secs_f64());
        return;
    }
    if args.first().map(String::as_str) == Some("scene") {
        let path = args.get(1).expect("study closure scene FILE");
        let s = Scene::load(std::path::Path::new(path)).unwrap_or_else(|e| panic!("{path}: {e}"));
        let t = std::time::Instant::now();
        if s.dimension == 3 {
            report::<3>(path, &s);
        } else {
            report::<2>(path, &s);
        }
        println!("  build {:.1} s", t.elapsed().as_secs_f64());
        return;
    }
    if args.first().map(String::as_str) == Some("family") {
        let n = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4);
        for case in crate::studies::family::family(n, true) {
            let t = std::time::Instant::now();
            if case.scene.dimension == 3 {
                report::<3>(&case.name, &case.scene);
            } else {
                report::<2>(&case.name, &case.scene);
            }
            println!("  build {:.1} s", t.elapsed().as_secs_f64());
        }
        return;
    }
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
