//! Diagnostic (issue 7): does fracture create energy at time steps below the automatic one?
//! The small2d cantilever of tests/energy_fracture.rs (no gravity, fracture_strain 0.01,
//! fractured-surface contact) thrown at its holder, run for 5 ms at `factor` x the automatic
//! step; prints the energy (kinetic + strain + contact) change summed over the steps in which
//! bonds broke and over the others, the largest rise, the energy the breaks released and the
//! particles whose re-fit at a break was limited, per model and velocity.
//! `cargo run --release -- study fracture_energy_dt [factor...]` (default 1 0.5 0.25).
use crate::physics::World;
use crate::scene::{Model, Scene};
use serde_json::Value;

fn small2d(velocity: [f64; 2], model: &str) -> Result<World<2>, String> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let text =
        std::fs::read_to_string(root.join("tests/data/small2d.json")).map_err(|e| e.to_string())?;
    let mut v: Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    v["gravity"] = serde_json::json!({ "vector": [0.0, 0.0] });
    v["bodies"][0]["velocity"] = serde_json::json!(velocity);
    v["solver"] = serde_json::json!({
        "model": model,
        "fracture_strain": 0.01,
        "contact": { "fractured_surfaces": true }
    });
    let scene = Scene::from_json(&v.to_string()).map_err(|e| e.to_string())?;
    Ok(Model::<2>::build(&scene).map_err(|e| e.to_string())?.world)
}

fn total(w: &World<2>) -> f64 {
    w.kinetic_energy() + w.strain_energy() + w.contact_energy()
}

pub fn main(args: Vec<String>) {
    let factors: Vec<f64> = args
        .clone()
        .into_iter()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let factors = if factors.is_empty() {
        vec![1.0, 0.5, 0.25]
    } else {
        factors
    };
    for model in ["second_order", "corrected"] {
        for vel in [[0.0, -5.0], [5.0, 0.0], [-5.0, 0.0]] {
            for &f in &factors {
                let mut w = match small2d(vel, model) {
                    Ok(w) => w,
                    Err(e) => {
                        println!("{model} v {vel:?}: {e}");
                        continue;
                    }
                };
                let dt = w.max_dt() * f;
                // The first step stops the held particles: the reference is the energy after it.
                let first = w.step(dt);
                let e0 = total(&w);
                let (mut on_break, mut other, mut emax) = (0.0, 0.0, e0);
                let (mut prev, mut prev_broken) = (e0, w.broken_pairs);
                let mut outcome = first.err().map(|e| e.to_string());
                while outcome.is_none() && w.time < 5e-3 {
                    if let Err(e) = w.step(dt) {
                        outcome = Some(e.to_string());
                        break;
                    }
                    let e = total(&w);
                    if w.broken_pairs != prev_broken {
                        on_break += e - prev;
                    } else {
                        other += e - prev;
                    }
                    emax = emax.max(e);
                    prev = e;
                    prev_broken = w.broken_pairs;
                }
                let limited: Vec<f64> =
                    w.op.retained.iter().copied().filter(|&r| r < 1.0).collect();
                let least = limited.iter().copied().fold(1.0, f64::min);
                println!(
                    "{model} v {vel:?} dt {f} x auto: E0 {e0:.2} J, largest {:+.2} %, change in steps with breaks {on_break:+.2} J, in the others {other:+.2} J, {} broken pairs, released {:.2} J, {} of {} particles limited (least share {least:.3}){}",
                    100.0 * (emax / e0 - 1.0),
                    w.broken_pairs,
                    w.fracture_release,
                    limited.len(),
                    w.len(),
                    outcome.map(|e| format!(", stopped at {:.5} s: {e}", w.time)).unwrap_or_default()
                );
            }
        }
    }
}
