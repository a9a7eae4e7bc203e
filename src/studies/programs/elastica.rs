//! Large deflection of the slender 3D cantilever (issue 7): the nonlinear static tip under
//! gravity at the three load levels of the elastica reference (tip deflection 30 / 45 / 60 % of
//! L), found by dynamic relaxation (`crate::studies::bending::elastica_static`), against the
//! elastica scaled by the linear 3D FEM / Euler-Bernoulli ratio, the plain elastica, and the
//! finite-strain 3D FEM with the same material law (reference/cantilever3d_nonlinear_fem.json,
//! the one without the elastica's simplifications). Prints a markdown table.
//!
//! `cargo run --release -- study elastica [ops] [ns] [levels]`, e.g.
//! `-- second_order,corrected 4,8 1,2,3` (levels 1-based; level 0 is a check of the relaxation:
//! g = 9.81 against the linear 3D FEM tip, where the nonlinear and the linearised static
//! solutions agree, so its error is the linear one of BENCHMARKS.md). Environment: ZETA, RAMP (periods),
//! TOL (in L f1), MAXP (periods) override the relaxation settings; LAW the material law
//! (`saint_venant_kirchhoff`, `neo_hookean`).
use crate::physics::ElasticModel;
use crate::studies::bending::{
    cantilever_reference, elastica_reference, elastica_static, nonlinear_fem_reference,
    ElasticaLevel, RelaxOptions, CANTILEVER_LENGTH, G,
};

fn env(k: &str) -> Option<f64> {
    std::env::var(k).ok().and_then(|s| s.parse().ok())
}

pub fn main(args: Vec<String>) {
    let args: Vec<String> = args.clone().into_iter().skip(1).collect();
    let ops: Vec<&str> = args
        .first()
        .map(|s| s.split(',').collect())
        .unwrap_or(vec!["second_order", "corrected"]);
    let list = |i: usize, d: Vec<usize>| -> Vec<usize> {
        args.get(i)
            .map(|s| s.split(',').filter_map(|x| x.parse().ok()).collect())
            .unwrap_or(d)
    };
    let ns = list(1, vec![4, 8]);
    let levels = list(2, vec![1, 2, 3]);
    let mut opt = RelaxOptions::default();
    if let Some(v) = env("ZETA") {
        opt.zeta = v;
    }
    if let Some(v) = env("RAMP") {
        opt.ramp_periods = v;
    }
    if let Some(v) = env("TOL") {
        opt.tol = v;
    }
    if let Some(v) = env("MAXP") {
        opt.max_periods = v;
    }
    if let Ok(law) = std::env::var("LAW") {
        // material.law: saint_venant_kirchhoff (default) or neo_hookean
        opt.law = serde_json::from_value(serde_json::Value::String(law)).unwrap();
    }
    let fem = nonlinear_fem_reference(opt.law);
    let mut refs = elastica_reference();
    let lin = cantilever_reference();
    // level 0: small load, against the linear FEM (u_x is second order there: no reference)
    refs.insert(
        0,
        ElasticaLevel {
            target: lin.tip.abs() / CANTILEVER_LENGTH,
            g: G,
            uz: lin.tip,
            ux: f64::NAN,
            uz_fem: lin.tip,
            ux_fem: f64::NAN,
        },
    );
    println!(
        "Dynamic relaxation: damping c = 2 x {} x 2 pi f1 (f1 = {} Hz), gravity ramp {} periods, \
        converged at tip and RMS speed < {:e} L f1.\n",
        opt.zeta, opt.f1, opt.ramp_periods, opt.tol
    );
    println!("| operator | n | particles | level | g (m/s^2) | tip u_z (m) | tip u_x (m) | u_z err (FEM-scaled) | u_x err (FEM-scaled) | u_z err (elastica) | u_x err (elastica) | u_z err (nonlinear FEM) | u_x err (nonlinear FEM) | steps | sim time (s) | wall (s) | ms/step | status |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for op in &ops {
        let model = match *op {
            "second_order" => ElasticModel::SecondOrder,
            "corrected" => ElasticModel::Corrected,
            o => panic!("unknown operator {o}"),
        };
        for &n in &ns {
            for &l in &levels {
                let r = &refs[l];
                let nl = fem
                    .iter()
                    .find(|t| (t.g - r.g).abs() < 1e-9)
                    .expect("the nonlinear FEM reference has every level");
                let res = match elastica_static(n, model, r.g, &opt) {
                    Ok(x) => x,
                    Err(e) => {
                        println!(
                            "| {op} | {n} | | {:.0} % | {} | scene error: {e} |",
                            100.0 * r.target,
                            r.g
                        );
                        continue;
                    }
                };
                let pc = |a: f64, b: f64| {
                    if b.is_finite() {
                        format!("{:+.2} %", 100.0 * (a / b - 1.0))
                    } else {
                        "-".to_string()
                    }
                };
                let status = match (&res.failure, res.converged) {
                    (Some(f), _) => format!("FAILED: {f}"),
                    (None, true) => "converged".into(),
                    (None, false) => format!(
                        "not converged (tip {:.1e}, rms {:.1e} m/s)",
                        res.tip_speed, res.rms_speed
                    ),
                };
                println!(
                    "| {op} | {n} | {} | {:.1} % | {} | {:.5} | {:.5} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {:.1} | {:.3} | {status} |",
                    res.particles,
                    100.0 * r.target,
                    r.g,
                    res.uz,
                    res.ux,
                    pc(res.uz, r.uz_fem),
                    pc(res.ux, r.ux_fem),
                    pc(res.uz, r.uz),
                    pc(res.ux, r.ux),
                    pc(res.uz, nl.uz),
                    pc(res.ux, nl.ux),
                    res.steps,
                    res.time,
                    res.wall,
                    1e3 * res.wall / res.steps.max(1) as f64,
                );
            }
        }
    }
}
