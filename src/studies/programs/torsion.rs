//! First torsion frequency of the slender 3D cantilever (issue 7: near incompressibility) for
//! the operators without particle rotations, at nu = 0.3 and 0.499, against the FEM
//! (reference/cantilever3d_fem.json; at nu = 0.499 the mixed Q2-P1disc element).
//! `cargo run --release -- study torsion [n...]`; environment: MODELS=second_order,
//! corrected (paper on request, time domain only); NU=0.3,0.499; METHODS=linear,time (default linear; time: release from a twist
//! rate, timed over PERIODS periods, default 3).
use crate::physics::ElasticModel;
use crate::studies::bending::{
    cantilever3d_scene, cantilever_torsion_reference, torsion_frequency, torsion_frequency_time,
    torsion_frequency_with,
};

pub fn main(args: Vec<String>) {
    let ns: Vec<usize> = args
        .clone()
        .into_iter()
        .skip(1)
        .filter_map(|s| s.parse().ok())
        .collect();
    let ns = if ns.is_empty() { vec![4, 5] } else { ns };
    let only = std::env::var("MODELS").ok();
    let models: Vec<(&str, ElasticModel)> = [
        ("second_order", ElasticModel::SecondOrder),
        ("corrected", ElasticModel::Corrected),
    ]
    .into_iter()
    // the paper operator only on request and only in the time domain (its particle rotations
    // are degrees of freedom the linearisation does not cover)
    .chain(
        only.as_ref()
            .filter(|o| o.split(',').any(|x| x == "paper"))
            .map(|_| ("paper", ElasticModel::Paper)),
    )
    .filter(|(n, _)| only.as_ref().is_none_or(|o| o.split(',').any(|x| x == *n)))
    .collect();
    let nus: Vec<f64> = std::env::var("NU")
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or_else(|_| vec![0.3, 0.499]);
    let methods = std::env::var("METHODS").unwrap_or_else(|_| "linear".into());
    let linear = methods.split(',').any(|m| m == "linear");
    let time = methods.split(',').any(|m| m == "time");
    let periods: usize = std::env::var("PERIODS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let (f03, f0499) = cantilever_torsion_reference();
    println!("| operator | nu | n | method | particles | torsion f (Hz) | FEM (Hz) | error | products / steps | iterations | 1 - rotation share | residual | symmetry defect | wall (s) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, model) in &models {
        for &nu in &nus {
            let fem = if nu > 0.4 { f0499 } else { f03 };
            for &n in &ns {
                let mut s = cantilever3d_scene(n, *model);
                s.bodies[0].material.poisson = nu;
                let mut runs = vec![];
                if linear {
                    runs.push(match std::env::var("CG_TOL") {
                        Ok(t) => torsion_frequency_with(&s, t.parse().unwrap()),
                        Err(_) => torsion_frequency(&s),
                    });
                }
                if time {
                    runs.push(torsion_frequency_time(&s, periods));
                }
                for r in runs {
                    match r {
                        Ok((f, i)) => {
                            if std::env::var("CG").is_ok() {
                                eprintln!("{name} {nu} {n}: CG iterations {:?}", i.cg_iterations);
                            }
                            println!(
                            "| {name} | {nu} | {n} | {} | {} | {f:.4} | {fem:.3} | {:+.2} % | {} | {} | {:.1e} | {:.1e} | {:.1e} | {:.1} |",
                            i.method,
                            i.particles,
                            100.0 * (f / fem - 1.0),
                            i.work,
                            i.iterations,
                            1.0 - i.rotation_fraction,
                            i.residual,
                            i.symmetry_defect,
                            i.wall
                        )
                        }
                        Err(e) => println!("| {name} | {nu} | {n} | error: {e} |"),
                    }
                }
            }
        }
    }
}
