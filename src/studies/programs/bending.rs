//! Accuracy study of the elastic operators in bending (issue 7): linearised first frequency and
//! static tip deflection of the 2D GMS plate and the slender 3D cantilever against n particles
//! through the thickness. `cargo run --release -- study bending [2d|3d] [n...]`;
//! environment LAW sets the material law (`saint_venant_kirchhoff`, `neo_hookean`).
use crate::physics::ElasticModel;
use crate::studies::bending::{cantilever3d_scene, linear_bending, plate2d_scene};

pub fn main(args: Vec<String>) {
    let args: Vec<String> = args.clone().into_iter().skip(1).collect();
    let dim = args.first().map(|s| s.as_str()).unwrap_or("2d").to_string();
    let ns: Vec<usize> = args.iter().skip(1).filter_map(|s| s.parse().ok()).collect();
    let ns = if ns.is_empty() { vec![4, 8, 16] } else { ns };
    let models: Vec<(&str, ElasticModel, f64)> = vec![
        ("second_order", ElasticModel::SecondOrder, 0.5),
        ("corrected 0.5", ElasticModel::Corrected, 0.5),
        ("corrected 0.25", ElasticModel::Corrected, 0.25),
        ("corrected 1.0", ElasticModel::Corrected, 1.0),
    ];
    if std::env::var("TIME").is_ok() {
        time_forces(ns[0]);
        return;
    }
    if std::env::var("FREE").is_ok() {
        for &n in &ns {
            for (name, model) in [
                ("second_order", ElasticModel::SecondOrder),
                ("corrected", ElasticModel::Corrected),
            ] {
                println!(
                    "free-free plate {name} n = {n}: f1 = {:.6} Hz",
                    crate::studies::bending::free_free_plate_f1(n, model).unwrap()
                );
            }
        }
        return;
    }
    let only = std::env::var("MODELS").ok();
    let models: Vec<_> = models
        .into_iter()
        .filter(|(n, _, _)| {
            only.as_ref()
                .is_none_or(|o| o.split(',').any(|x| n.starts_with(x)))
        })
        .collect();
    println!("| model | n | particles | f1 (Hz) | tip static (m) | products | wall (s) |");
    println!("|---|---|---|---|---|---|---|");
    for (name, model, stab) in &models {
        for &n in &ns {
            let mut s = if dim == "3d" {
                cantilever3d_scene(n, *model)
            } else {
                plate2d_scene(n, *model)
            };
            s.solver.stabilisation = *stab;
            if let Ok(len) = std::env::var("LEN") {
                // beam length beyond the clamp (m): the clamp's share of the error scales as 1/L
                let len: f64 = len.parse().unwrap();
                s.bodies[0].boxes[0].max[0] = len;
                s.probes[0].point[0] = len;
            }
            if let Ok(re) = std::env::var("RE") {
                // re / l0 (the wall layers behind the face enter no second-order fit)
                s.solver.re_factor = re.parse().unwrap();
                if s.boundaries[0].mirror.is_some() {
                    // a mirror clamp needs ceil(re / l0) layers of images to fill the stencil
                    let far = -s.solver.re_factor.ceil() * s.particle_spacing;
                    s.bodies[0].boxes[1].min[0] = far;
                    s.boundaries[0].region.min[0] = far;
                }
            }
            if let Ok(nu) = std::env::var("NU") {
                s.bodies[0].material.poisson = nu.parse().unwrap();
            }
            if let Ok(law) = std::env::var("LAW") {
                // material.law: saint_venant_kirchhoff (default) or neo_hookean
                s.bodies[0].material.law =
                    serde_json::from_value(serde_json::Value::String(law)).unwrap();
            }
            match linear_bending(&s) {
                Ok(r) => println!(
                    "| {name} | {n} | {} | {:.5} | {:.6e} | {} | {:.2} |",
                    r.particles, r.f1, r.tip, r.products, r.wall
                ),
                Err(e) => println!("| {name} | {n} | error: {e} |"),
            }
        }
    }
}

/// Cost of one force evaluation per model (TIME=1): cantilever3d with n across.
#[allow(dead_code)]
pub fn time_forces(n: usize) {
    use crate::scene::Model;
    for model in [
        ElasticModel::SecondOrder,
        ElasticModel::Corrected,
        ElasticModel::Paper,
    ] {
        let mut s = cantilever3d_scene(n, model);
        if let Ok(law) = std::env::var("LAW") {
            s.bodies[0].material.law =
                serde_json::from_value(serde_json::Value::String(law)).unwrap();
        }
        let Ok(mut m) = Model::<3>::build(&s) else {
            continue; // the paper operator takes only the default law
        };
        let bonds = m.world.bonds.len();
        let dt = m.world.max_dt();
        let t0 = std::time::Instant::now();
        let steps = 200;
        for _ in 0..steps {
            m.world.step(dt).unwrap();
        }
        let el = t0.elapsed().as_secs_f64();
        println!(
            "{model:?}: {} particles, {bonds} bonds, {:.3} ms/step, {:.3e} bond-evaluations/s, critical dt {:.3e} s",
            m.world.len(),
            el / steps as f64 * 1e3,
            bonds as f64 * steps as f64 / el,
            m.world.critical_dt()
        );
    }
}
