//! Diagnostic (issues 24 and 25): where the stiffest mode of a scene sits, which sets its stable
//! step. Power iteration on the model's own forces about the reference state; prints omega_max
//! (Lanczos, as the solver measures it, and the power iterate), the mode's mass-weighted energy
//! by how many of the bodies' bounding faces a particle lies within 1.5 spacings of (interior,
//! face, edge, corner) and the particles that carry most of it; the Lanczos estimate by
//! iterations from the solver's hashed start and from it weighted by (n0 / n_i)^p towards the
//! particles short of neighbours; and the stiffest mode again with the corners held, then the
//! edges too (how far the stable step would move if they were no stiffer than the faces).
//!
//! `cargo run --release -- study stiffest [case1|case2|cant|SCENE.json] [model] [iterations]`
use crate::physics::{Dim, ElasticModel, Space, Vect, World};
use crate::scene::Model;
use crate::studies::cases::{case1_scene, case2_scene, Support};
use crate::studies::family::{single_box, ClampStyle};

fn report<const D: usize>(w: &mut World<D>, iterations: usize)
where
    Space: Dim<D>,
{
    let boxes = bounds(w);
    report_once(w, iterations, &boxes);
    // Lanczos from the hashed start and from it weighted towards the particles short of
    // neighbours, by iterations.
    let n0 = w.p.n_ref.iter().cloned().fold(0.0, f64::max);
    let reference = w.lanczos_omega_max_from(80, w.start_vector());
    println!("Lanczos 80 from the hashed start: {reference:.6e}");
    for pw in [0.0, 2.0, 4.0, 8.0] {
        let mut line = format!("weight (n0/n)^{pw}:");
        for k in [6usize, 8, 10, 12, 16, 20] {
            let (mut t, r) = w.start_vector();
            for (i, ti) in t.iter_mut().enumerate() {
                *ti *= (n0 / w.p.n_ref[i].max(1e-3 * n0)).powf(pw);
            }
            let o = w.lanczos_omega_max_from(k, (t, r));
            line += &format!("  {k}: {:+.3} %", (o / reference - 1.0) * 100.0);
        }
        println!("{line}");
    }
    // The same with the corner particles held, then the edges too: how far the stable step
    // would move if the corners were no stiffer than the rest.
    for keep_below in [3usize, 2] {
        let n = w.len();
        let all: u8 = (0..D).map(|a| crate::physics::particles::FIX_AXIS[a]).sum();
        for i in 0..n {
            if w.p.fix[i] == 0 && class_of(w, &boxes, i) >= keep_below {
                w.p.fix[i] = all;
            }
        }
        println!("--- particles within 1.5 spacings of {keep_below} or more bounding faces held:");
        report_once(w, iterations, &boxes);
    }
}

/// Each body's bounding box over its free particles.
fn bounds<const D: usize>(w: &World<D>) -> Vec<(Vect<D>, Vect<D>)>
where
    Space: Dim<D>,
{
    let bodies = w.p.body.iter().map(|&b| b as usize + 1).max().unwrap_or(0);
    let mut out = vec![
        (
            Vect::<D>::repeat(f64::INFINITY),
            Vect::<D>::repeat(f64::NEG_INFINITY)
        );
        bodies
    ];
    for i in 0..w.len() {
        if w.p.fix[i] == 0 {
            let (lo, hi) = &mut out[w.p.body[i] as usize];
            *lo = lo.inf(&w.p.x0[i]);
            *hi = hi.sup(&w.p.x0[i]);
        }
    }
    out
}

/// How many of its body's bounding faces particle i lies within 1.5 spacings of.
fn class_of<const D: usize>(w: &World<D>, boxes: &[(Vect<D>, Vect<D>)], i: usize) -> usize
where
    Space: Dim<D>,
{
    let (lo, hi) = &boxes[w.p.body[i] as usize];
    (0..D)
        .filter(|&a| {
            let x = w.p.x0[i][a];
            x - lo[a] < 1.5 * w.l0 || hi[a] - x < 1.5 * w.l0
        })
        .count()
}

fn report_once<const D: usize>(w: &World<D>, iterations: usize, boxes: &[(Vect<D>, Vect<D>)])
where
    Space: Dim<D>,
{
    let (omega, v) = w.stiffest_mode(iterations);
    let n = w.len();
    let free: Vec<usize> = (0..n).filter(|&i| w.p.fix[i] == 0).collect();
    let e: Vec<f64> = (0..n).map(|i| w.p.mass[i] * v[i].norm_squared()).collect();
    let total: f64 = free.iter().map(|&i| e[i]).sum();
    let class = |i: usize| class_of(w, boxes, i);
    let mut by = [0.0; 4];
    for &i in &free {
        by[class(i)] += e[i] / total;
    }
    println!(
        "omega_max: Lanczos {:.6e} rad/s (with margin as the solver uses it: {:.6e}), power iterate after {iterations}: {:.6e}",
        w.omega_elastic() / (1.0 + crate::physics::world::OMEGA_MARGIN),
        w.omega_elastic(),
        omega
    );
    println!(
        "mode energy by place (within 1.5 spacings of 0/1/2/3 bounding faces of its body): interior {:.3}, face {:.3}, edge {:.3}, corner {:.3}",
        by[0], by[1], by[2], by[3]
    );
    let mut order = free.clone();
    order.sort_by(|&a, &b| e[b].total_cmp(&e[a]));
    for &i in order.iter().take(12) {
        let rel: Vec<String> = (0..D)
            .map(|a| {
                format!(
                    "{:+.2}",
                    (w.p.x0[i][a] - boxes[w.p.body[i] as usize].0[a]) / w.l0
                )
            })
            .collect();
        println!(
            "  particle {i:6}  (x0 - body min)/dp = [{}]  share {:.4}  class {}",
            rel.join(", "),
            e[i] / total,
            class(i)
        );
    }
}

pub fn main(args: Vec<String>) {
    let which = args.get(1).map(String::as_str).unwrap_or("case1");
    let model = match args.get(2).map(String::as_str) {
        Some("corrected") => ElasticModel::Corrected,
        Some("paper") => ElasticModel::Paper,
        Some("paper_local") => ElasticModel::PaperLocal,
        _ => ElasticModel::SecondOrder,
    };
    let iterations: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(400);
    let scene = match which {
        "case2" => case2_scene(0.025, model, None, Support::Face),
        "cant" => {
            let mut s = single_box(3, 4, ClampStyle::Walls).scene;
            s.solver.model = model;
            s
        }
        "case1" => case1_scene(0.025, model, None),
        path => {
            let mut s = crate::Scene::from_json(&std::fs::read_to_string(path).unwrap()).unwrap();
            if args.get(2).is_some() {
                s.solver.model = model;
            }
            s
        }
    };
    if scene.dimension == 2 {
        report(&mut Model::<2>::build(&scene).unwrap().world, iterations);
    } else {
        report(&mut Model::<3>::build(&scene).unwrap().world, iterations);
    }
}
