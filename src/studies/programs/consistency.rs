//! Diagnostic (issue 7): how far case 1's exact field is from the discrete equilibrium. The
//! hanging bar's closed form u* is quadratic, so both fits reproduce its strains exactly; the
//! residual K u* - f_gravity per particle, in units of the particle's weight m g, is then the
//! error of the particle quadrature of the weak form (nodal integration). The corrected
//! operator's free end and side faces do not satisfy it (0.4-1 m g); the second-order operator's
//! summation-by-parts closure (module `physics::sbp`) does, to ~1e-8 m g (its plain fits left
//! -0.35 / +0.53 / -0.18 m g on the free end's layers). Printed by layer from the free end for
//! the second-order and corrected operators. `cargo run --release -- study consistency`
use crate::physics::{ElasticModel, Vect};
use crate::scene::Model;
use crate::studies::cases::{case1_closed_field, case1_scene};
use crate::studies::linear::Linearised;

const G: f64 = 9.81;

pub fn main(_args: Vec<String>) {
    for model in [ElasticModel::SecondOrder, ElasticModel::Corrected] {
        let s = case1_scene(0.025, model, None);
        let m = Model::<3>::build(&s).unwrap();
        let w = &m.world;
        let ustar = case1_closed_field(&w.p.x0);
        let ku = Linearised::new(w).unwrap().stiffness_times(&ustar);
        println!("{model:?}: (K u* - f_gravity) / (m g), rows z, columns x (y = 0.0125 m)");
        println!("  z (m)      x=0.0875               x=0.0625               x=0.0125");
        for zc in [-0.9875, -0.9625, -0.9375, -0.9125, -0.5125] {
            let mut line = format!("  {zc:+.4}");
            for xc in [0.0875, 0.0625, 0.0125] {
                let (i, _) = w
                    .nearest_particle(&Vect::<3>::new(xc, 0.0125, zc), None)
                    .unwrap();
                let mg = w.p.mass[i] * G;
                // Gravity is -z: the residual is K u* + m g e_z.
                let r = (ku[i] + Vect::<3>::new(0.0, 0.0, mg)) / mg;
                line += &format!("  ({:+.2e}, {:+.2e})", r[0], r[2]);
            }
            println!("{line}");
        }
    }
}
