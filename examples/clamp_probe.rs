//! Diagnostic: a clamped bar under a body force along its axis (nu = 0): the exact
//! displacement u_x = (rho g / E)(L x - x^2 / 2) is quadratic, so a quadratic-consistent
//! operator must reproduce it to round-off. Prints the computed against the exact field.
use mps_solid::bending::plate2d_scene;
use mps_solid::linear::{field_at, Linearised};
use mps_solid::physics::{ElasticModel, Vect};
use mps_solid::scene::Model;

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(4);
    let mut s = plate2d_scene(n, ElasticModel::SecondOrder);
    s.bodies[0].material.poisson = 0.0;
    let mut model = Model::<2>::build(&s).unwrap();
    let g = Vect::<2>::new(-9.81, 0.0);
    let mut lin = Linearised::new(&model.world).unwrap();
    let u = lin.static_gravity(g, 1e-12).unwrap();
    drop(lin);
    let mat = &s.bodies[0].material;
    let l = s.bodies[0].boxes[0].max[0];
    let exact = |x: f64| -(mat.density * 9.81 / mat.young) * (l * x - 0.5 * x * x);
    for x in [0.25 * l, 0.5 * l, l] {
        let p = Vect::<2>::new(x, 0.0);
        let v = field_at(&mut model.world, &u, &p, None).unwrap();
        println!("x {x:.4}: u_x {:.6e} exact {:.6e} rel {:+.3e}  u_y {:.2e}", v[0], exact(x), v[0] / exact(x) - 1.0, v[1]);
    }
}
