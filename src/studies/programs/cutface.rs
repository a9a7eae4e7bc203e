//! Diagnostic (issue 24): why a box written as a shape whose faces cut the outer cells a quarter
//! spacing out converges at first order (docs/model.md, "A box given as shapes"). The GMS plate
//! (plane strain) written as a box shape `n + extra` spacings thick, and the end-loaded
//! cantilever's exact field (Timoshenko and Goodier's, plane-strain constants): a cubic
//! displacement whose stress is quadratic (the shear parabola, traction-free on the faces) with
//! no body force, so the residual K u* per particle is the particle quadrature's error for a
//! quadratic stress (the closure is exact for linear ones). Printed in units of the largest shear
//! stress times the cell (tau_max l0 per unit depth), summed over columns of particles along the
//! plate (the columns next to the clamp and the loaded end also carry those boundaries' terms).
//!
//! `cargo run --release -- study cutface [n] [extra...]` (default 8, extras 0, 0.25, 0.5, 0.7);
//! `-- free [n...]`: the free-free plate's f1, aligned (n across) against n + 1/2 across;
//! `-- walls`: the clamped plate with 3 or 5 wall layers; `-- nu NU`: the clamped plate at
//! Poisson's ratio NU, aligned against n + 1/2 (self-convergence).
use crate::physics::Vect;
use crate::scene::Model;
use crate::studies::family::shape_written;
use crate::studies::linear::Linearised;

/// The GMS plate written as a box shape `across` spacings thick, free (no clamp, no walls).
fn free_plate(across: f64) -> crate::Scene {
    let mut s = shape_written(2, across, 0.0).scene;
    s.boundaries.clear();
    if let crate::scene::shape::Shape::Box(r) = &mut s.bodies[0].shapes[0] {
        r.min[0] = 0.0;
    }
    s
}

/// Free-free first flexural frequency of the plate by thickness, aligned (n across) and cut
/// (n + 1/2 across: faces a quarter spacing out): both converge to the same plate's.
fn free_free(ns: &[f64]) {
    println!("free-free plate, f1 (Hz) by spacings across: aligned n, and n + 1/2 (faces 1/4 out)");
    for &n in ns {
        let a = crate::studies::bending::free_free_f1(&free_plate(n)).unwrap();
        let c = crate::studies::bending::free_free_f1(&free_plate(n + 0.5)).unwrap();
        println!("  n = {n:4}: aligned {a:.9}, n + 1/2 {c:.9}");
    }
}

/// The clamped plate written as a box shape `across` thick with `walls` wall layers in the
/// solid behind the clamped face: f1 and static tip errors against the FEM.
fn clamped(walls: f64, across: f64) {
    let case = shape_written(2, across, 0.0);
    let mut s = case.scene;
    let dp = s.particle_spacing;
    if let crate::scene::shape::Shape::Box(r) = &mut s.bodies[0].shapes[0] {
        r.min[0] = -walls * dp;
    }
    s.boundaries[0].region.min[0] = -walls * dp;
    let b = crate::studies::bending::linear_bending(&s).unwrap();
    println!(
        "  {across} across, {walls} wall layers: f1 {:+.4} %, static {:+.4} %",
        100.0 * (b.f1 / case.reference.f1 - 1.0),
        100.0 * (b.tip / case.reference.static_u - 1.0)
    );
}

/// The clamped plate at Poisson's ratio `nu`, aligned (n across) and cut (n + 1/2): f1 (Hz)
/// and static tip (m), for self-convergence where no reference exists.
fn clamped_nu(nu: f64, ns: &[f64]) {
    println!("clamped plate at nu = {nu}: f1 (Hz), static tip (m); aligned n | n + 1/2");
    for &n in ns {
        let mut line = format!("  n = {n:4}:");
        for across in [n, n + 0.5] {
            let mut s = shape_written(2, across, 0.0).scene;
            s.bodies[0].material.poisson = nu;
            let b = crate::studies::bending::linear_bending(&s).unwrap();
            line += &format!("  {:.9} {:.9e}", b.f1, b.tip);
        }
        println!("{line}");
    }
}

pub fn main(args: Vec<String>) {
    if args.get(1).map(String::as_str) == Some("nu") {
        let nu: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.0);
        clamped_nu(nu, &[4.0, 8.0, 16.0]);
        return;
    }
    if args.get(1).map(String::as_str) == Some("walls") {
        for across in [4.5, 8.5, 4.0, 8.0] {
            for walls in [3.0, 5.0] {
                clamped(walls, across);
            }
        }
        return;
    }
    if args.get(1).map(String::as_str) == Some("free") {
        let ns: Vec<f64> = args[2..].iter().filter_map(|s| s.parse().ok()).collect();
        free_free(if ns.is_empty() {
            &[4.0, 8.0, 16.0, 32.0]
        } else {
            &ns
        });
        return;
    }
    let n: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(8.0);
    let extras: Vec<f64> = if args.len() > 2 {
        args[2..].iter().filter_map(|s| s.parse().ok()).collect()
    } else {
        vec![0.0, 0.25, 0.5, 0.7]
    };
    for extra in extras {
        let case = shape_written(2, n + extra, 0.0);
        let s = &case.scene;
        let crate::scene::shape::Shape::Box(solid) = &s.bodies[0].shapes[0] else {
            unreachable!("shape_written gives a box")
        };
        let (h, length) = (solid.max[1], solid.max[0]);
        let mat = s.bodies[0].material;
        // Plane strain: Timoshenko's plane-stress field with E / (1 - nu^2), nu / (1 - nu).
        let e = mat.young / (1.0 - mat.poisson * mat.poisson);
        let nu = mat.poisson / (1.0 - mat.poisson);
        let g = mat.young / (2.0 * (1.0 + mat.poisson));
        let inertia = 2.0 * h * h * h / 3.0;
        let p = 1.0;
        let field = |x: &Vect<2>| -> Vect<2> {
            let (x, y) = (x[0], x[1]);
            let l = length;
            let u = -p * x * x * y / (2.0 * e * inertia) - nu * p * y.powi(3) / (6.0 * e * inertia)
                + p * y.powi(3) / (6.0 * inertia * g)
                + (p * l * l / (2.0 * e * inertia) - p * h * h / (2.0 * inertia * g)) * y;
            let v = nu * p * x * y * y / (2.0 * e * inertia) + p * x.powi(3) / (6.0 * e * inertia)
                - p * l * l * x / (2.0 * e * inertia)
                + p * l.powi(3) / (3.0 * e * inertia);
            Vect::<2>::new(u, v)
        };
        let m = Model::<2>::build(s).unwrap();
        let w = &m.world;
        let ustar: Vec<Vect<2>> = w.p.x0.iter().map(field).collect();
        let ku = Linearised::new(w).unwrap().stiffness_times(&ustar);
        let tau_max = p * h * h / (2.0 * inertia);
        let scale = tau_max * w.l0;
        println!(
            "{} across: K u* / (tau_max l0) by column (x in spacings from the clamp face), the top half's net x force and the column's x moment / h",
            n + extra
        );
        let dp = w.l0;
        for at in [
            0.5,
            1.5,
            2.5,
            3.5,
            0.5 * length / dp,
            length / dp - 2.5,
            length / dp - 0.5,
        ] {
            let (i0, _) = w
                .nearest_particle(&Vect::<2>::new(at * dp, 0.0), None)
                .unwrap();
            let xm = w.p.x0[i0][0];
            let column: Vec<usize> = (0..w.len())
                .filter(|&i| w.p.fix[i] == 0 && (w.p.x0[i][0] - xm).abs() < 1e-9 * dp)
                .collect();
            let net: f64 = column
                .iter()
                .filter(|&&i| w.p.x0[i][1] > 1e-9 * dp)
                .map(|&i| ku[i][0] / scale)
                .sum();
            let moment: f64 = column
                .iter()
                .map(|&i| ku[i][0] / scale * w.p.x0[i][1] / h)
                .sum();
            let shear: f64 = column.iter().map(|&i| ku[i][1] / scale).sum();
            println!(
                "  x = {:6.2} dp: net x (top half) {net:+.3e}, moment {moment:+.3e}, net y {shear:+.3e}",
                xm / dp
            );
        }
    }
}
