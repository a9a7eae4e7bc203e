//! Using mps-solid as a Rust library: a plane-strain cantilever written as a scene in code,
//! clamped the natural way (a `clamped` region over wall particles behind its root), stepped
//! under sudden gravity while the program reads its tip probe, then its energies.
//!
//! ```text
//! cargo run --release --example library
//! ```
use mps_solid::{Scene, Simulation};

fn main() -> Result<(), String> {
    // A 0.4 m x 0.04 m strip, 8 particles through its depth, and a 3-layer wall behind x = 0;
    // the clamp holds those three wall layers. Units: m, kg/m^3, Pa, s.
    let scene = Scene::from_json(
        r#"{
        "name": "cantilever", "dimension": 2, "particle_spacing": 0.005,
        "gravity": { "vector": [0.0, -9.81] },
        "bodies": [ { "name": "strip",
                      "material": { "density": 1000.0, "young": 2.0e6, "poisson": 0.3 },
                      "boxes": [ { "min": [-0.015, -0.02], "max": [0.4, 0.02] } ] } ],
        "boundaries": [ { "name": "clamp", "kind": "clamped", "body": "strip",
                          "region": { "min": [-0.02, -0.03], "max": [0.0, 0.03] } } ],
        "probes": [ { "name": "tip", "point": [0.4, 0.0] } ],
        "end_time": 0.2, "output_interval": 0.01
    }"#,
    )
    .map_err(|e| e.to_string())?;
    let mut sim = Simulation::new(&scene).map_err(|e| e.to_string())?;
    for w in sim.warnings() {
        eprintln!("warning: {w}");
    }
    println!(
        "{} particles, {} bonds, stable step {:.3e} s",
        sim.particles(),
        sim.bonds(),
        sim.critical_dt()
    );
    println!("t (s)      tip u_y (m)");
    for k in 1..=20 {
        let t = 0.01 * k as f64;
        sim.advance_to(t).map_err(|e| e.to_string())?;
        println!("{t:.3}    {:+.6e}", sim.probe_displacement(0)[1]);
    }
    println!(
        "kinetic {:.4e} J/m, strain {:.4e} J/m, clamp reaction y {:.4} N/m",
        sim.kinetic_energy(),
        sim.strain_energy(),
        sim.group_reaction(0)[1]
    );
    Ok(())
}
