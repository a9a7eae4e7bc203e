//! Diagnostic: a clamped bar under a body force along its axis (nu = 0): the exact
//! displacement u_x = (rho g / E)(L x - x^2 / 2) is quadratic, so a quadratic-consistent
//! operator must reproduce it to round-off. Prints the computed against the exact field.
use crate::physics::{ElasticModel, Vect};
use crate::scene::Model;
use crate::studies::bending::plate2d_scene;
use crate::studies::linear::{field_at, Linearised};

pub fn main(args: Vec<String>) {
    if std::env::var("CASE2").is_ok() {
        case2_clamps();
        return;
    }
    if std::env::var("COLUMNS_RESIDUAL").is_ok() {
        residual_by_column(
            args.clone()
                .into_iter()
                .nth(1)
                .and_then(|s| s.parse().ok())
                .unwrap_or(4),
        );
        return;
    }
    let n: usize = args
        .clone()
        .into_iter()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(4);
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
        println!(
            "x {x:.4}: u_x {:.6e} exact {:.6e} rel {:+.3e}  u_y {:.2e}",
            v[0],
            exact(x),
            v[0] / exact(x) - 1.0,
            v[1]
        );
    }
}

/// Residual K u_exact - f per column of particles (summed over the section), for the exact
/// quadratic field of the axial bar: which particles the operator is inconsistent at.
#[allow(dead_code)]
pub fn residual_by_column(n: usize) {
    let mut s = plate2d_scene(n, ElasticModel::SecondOrder);
    s.bodies[0].material.poisson = 0.0;
    let model = Model::<2>::build(&s).unwrap();
    let mat = &s.bodies[0].material;
    let l = s.bodies[0].boxes[0].max[0];
    let c = mat.density * 9.81 / mat.young;
    let w = &model.world;
    let u: Vec<Vect<2>> =
        w.p.x0
            .iter()
            .map(|x| {
                let xx = x[0].max(0.0);
                Vect::<2>::new(-c * (l * xx - 0.5 * xx * xx), 0.0)
            })
            .collect();
    let mut lin = Linearised::new(w).unwrap();
    let ku = lin.stiffness_times(&u);
    let dp = s.particle_spacing;
    let mut cols: std::collections::BTreeMap<i64, (f64, f64)> = Default::default();
    for ((x, k), m) in w.p.x0.iter().zip(&ku).zip(&w.p.mass) {
        let key = (x[0] / dp * 2.0).round() as i64;
        let e = cols.entry(key).or_default();
        e.0 += k[0] + m * 9.81;
        e.1 += m * 9.81;
    }
    for (k, (r, m)) in cols.iter().skip(3).take(7).chain(cols.iter().rev().take(3)) {
        println!(
            "column x = {:.2} dp: residual {:+.4e} N (weight {:.3e} N)",
            *k as f64 / 2.0,
            r,
            m
        );
    }
}

/// Case 2 (corrected and second_order) linearised, with its face-layer clamp on the cell
/// vertices (as shipped) and on the cell centres: f1 and static max deflection against the FEM.
#[allow(dead_code)]
pub fn case2_clamps() {
    use crate::studies::bending::linear_bending;
    use crate::studies::cases::{case2_scene, Support};
    let (f_ref, u_ref) = (10.55357, -0.00276809);
    for model in [ElasticModel::Corrected, ElasticModel::SecondOrder] {
        for vertex in [false, true] {
            let mut s = case2_scene(0.025, model, None, Support::Face);
            if !vertex {
                // the clamp rows on the cell centres: 9 x 9 at dp = 0.025
                let dp = s.particle_spacing;
                for a in 1..3 {
                    s.bodies[0].boxes[1].min[a] += 0.5 * dp;
                    s.bodies[0].boxes[1].max[a] -= 0.5 * dp;
                    s.boundaries[0].region.min[a] += 0.5 * dp;
                    s.boundaries[0].region.max[a] -= 0.5 * dp;
                }
            }
            let b = linear_bending(&s).unwrap();
            println!(
                "{model:?} vertex clamp {vertex}: f1 {:.5} Hz ({:+.2} %), static max {:.5e} m ({:+.2} %)",
                b.f1,
                100.0 * (b.f1 / f_ref - 1.0),
                b.tip,
                100.0 * (b.tip / u_ref - 1.0)
            );
        }
    }
}
