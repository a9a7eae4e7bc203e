//! Mirror faces against the grip (issue 7): the second-order operator on the axial bar (exact
//! quadratic field), the GMS plate, the slender cantilever and case 2, with its builders'
//! clamp (mirror faces) and with the earlier grip (a face layer on the face, walls behind it,
//! `GRIP=1`). `cargo run --release -- study ghost [bar|plate|cant|case2] n...`
//! (case2: dp = 0.1 / n).
use crate::physics::{ElasticModel, Vect};
use crate::scene::{Model, Scene};
use crate::studies::bending::{
    cantilever3d_scene, cantilever_reference, linear_bending, plate2d_scene, plate_reference,
};
use crate::studies::cases::{case2_scene, Support};
use crate::studies::linear::{field_at, Linearised};

/// The face-layer grip of the other operators, with the second-order model.
fn with_model(grip: bool, build: impl Fn(ElasticModel) -> Scene) -> Scene {
    if !grip {
        return build(ElasticModel::SecondOrder);
    }
    let mut s = build(ElasticModel::Corrected);
    s.solver.model = ElasticModel::SecondOrder;
    s
}

pub fn main(args: Vec<String>) {
    let args: Vec<String> = args.clone().into_iter().skip(1).collect();
    let what = args.first().cloned().unwrap_or("plate".into());
    let ns: Vec<usize> = args.iter().skip(1).filter_map(|s| s.parse().ok()).collect();
    let ns = if ns.is_empty() { vec![4, 8] } else { ns };
    let grip = std::env::var("GRIP").is_ok();
    let label = if grip { "grip" } else { "mirror" };
    for n in ns {
        match what.as_str() {
            "bar" => {
                // nu = 0, gravity along the axis: u_x = -(rho g / E)(L x - x^2 / 2).
                let mut s = with_model(grip, |m| plate2d_scene(n, m));
                s.bodies[0].material.poisson = 0.0;
                let mat = s.bodies[0].material;
                let l = s.bodies[0].boxes[0].max[0];
                let exact = -(mat.density * 9.81 / mat.young) * (0.5 * l * l);
                let mut model = Model::<2>::build(&s).unwrap();
                let mut lin = Linearised::new(&model.world).unwrap();
                let u = lin
                    .static_gravity(Vect::<2>::new(-9.81, 0.0), 1e-12)
                    .unwrap();
                drop(lin);
                let v = field_at(&mut model.world, &u, &Vect::<2>::new(l, 0.0), None).unwrap();
                println!(
                    "bar n {n} ({label}): tip u_x relative error {:+.3e}",
                    v[0] / exact - 1.0
                );
            }
            "case2" => {
                let (f_ref, u_ref) = (10.55357, -0.00276809);
                let dp = 0.1 / n as f64;
                let s = with_model(grip, |m| case2_scene(dp, m, None, Support::Face));
                let b = linear_bending(&s).unwrap();
                println!(
                    "case2 dp {dp} ({label}): f1 {:.5} Hz ({:+.3} %), static {:.5e} m ({:+.3} %), {:.0} s",
                    b.f1,
                    100.0 * (b.f1 / f_ref - 1.0),
                    b.tip,
                    100.0 * (b.tip / u_ref - 1.0),
                    b.wall
                );
            }
            _ => {
                let (s, r) = if what == "plate" {
                    (with_model(grip, |m| plate2d_scene(n, m)), plate_reference())
                } else {
                    (
                        with_model(grip, |m| cantilever3d_scene(n, m)),
                        cantilever_reference(),
                    )
                };
                let b = linear_bending(&s).unwrap();
                println!(
                    "{what} n {n} ({label}): f1 {:.6} Hz ({:+.3} %), tip {:.6e} m ({:+.3} %), {:.0} s",
                    b.f1,
                    100.0 * (b.f1 / r.f1 - 1.0),
                    b.tip,
                    100.0 * (b.tip / r.tip - 1.0),
                    b.wall
                );
            }
        }
    }
}
