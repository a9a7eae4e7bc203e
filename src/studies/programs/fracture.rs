//! Diagnostic (issue 7): why case 3 breaks its first bond at 0.128 s with the second-order
//! operator and at 0.3425 s with the corrected one. Prints, every 10 ms, the largest bond strain
//! and where it sits (position, surface flag, body), and the kinetic and strain energy, for both
//! operators. `cargo run --release -- study fracture [end_time]`
use crate::physics::ElasticModel;
use crate::scene::Model;
use crate::studies::case3::case3_scene;

pub fn main(args: Vec<String>) {
    let end: f64 = args
        .clone()
        .into_iter()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.16);
    for model in [ElasticModel::SecondOrder, ElasticModel::Corrected] {
        let s = case3_scene(0.05, true, model);
        let mut m = Model::<3>::build(&s).unwrap();
        println!("{model:?}");
        let mut t = 0.0;
        while t < end - 1e-12 {
            t += 0.01;
            if let Err(e) = m.world.advance_to(t) {
                println!("  {t:.2} s: {e}");
                break;
            }
            let (eps, i) = m.world.max_bond_strain();
            let x = m.world.p.x0[i];
            println!(
                "  {t:.2} s: max bond strain {eps:.4} at particle {i} x0 ({:+.3}, {:+.3}, {:+.3}) body {} surface {}, broken {}, kinetic {:.1} J, strain {:.1} J",
                x[0],
                x[1],
                x[2],
                m.world.p.body[i],
                m.world.is_surface(i),
                m.world.broken_bonds_of(i),
                m.world.kinetic_energy(),
                m.world.strain_energy()
            );
        }
    }
}
