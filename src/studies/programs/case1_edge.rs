//! Diagnostic (issue 7): case 1's lateral displacement u_x near the free end with the
//! second-order operator, linearised static solution under full gravity: the particle values and
//! the probe interpolation against the closed form. `cargo run --release -- study case1_edge`
use crate::physics::{ElasticModel, Vect};
use crate::scene::Model;
use crate::studies::cases::{case1_closed_form, case1_scene};
use crate::studies::linear::{field_at, Linearised};

pub fn main(_args: Vec<String>) {
    for model in [ElasticModel::SecondOrder, ElasticModel::Corrected] {
        let s = case1_scene(0.025, model, None);
        let mut m = Model::<3>::build(&s).unwrap();
        let u = Linearised::new(&m.world)
            .unwrap()
            .static_gravity(Vect::<3>::new(0.0, 0.0, -9.81), 1e-12)
            .unwrap();
        println!("{model:?}");
        for z in [-0.9875, -0.9625, -0.5125] {
            for x in [0.0875, 0.0625, 0.0125] {
                let p = Vect::<3>::new(x, 0.0125, z);
                let (i, _) = m.world.nearest_particle(&p, None).unwrap();
                let (cx, cz) = case1_closed_form(x, 0.0125, -z);
                println!(
                    "  particle ({x}, 0.0125, {z}): u_x {:+.4e} (closed {:+.4e}), u_z {:+.5e} (closed {:+.5e})",
                    u[i][0], cx, u[i][2], cz
                );
            }
        }
        for sdist in [0.9, 0.95, 1.0] {
            let p = Vect::<3>::new(0.1, 0.0, -sdist);
            let v = field_at(&mut m.world, &u, &p, None).unwrap();
            let (cx, _) = case1_closed_form(0.1, 0.0, sdist);
            println!("  probe s {sdist}: u_x {:+.4e} (closed {:+.4e})", v[0], cx);
        }
    }
}
