//! Diagnostic (issue 7): the small2d strip with E = 1e6 Pa, nu = -0.5, gravity x100, thrown down
//! at 1 m/s, which blew up at the default safety 0.8 when it folds. Records the deformation
//! gradient of the corrected operator at the failing particle and its neighbours, its principal
//! stretches, det F and the definiteness of the Saint Venant-Kirchhoff tangent over the last
//! steps, and the spectrum of the assembled tangent stiffness.
//!
//! `cargo run --release -- study fold [safety] [t_end]`
use crate::physics::{Mat, MaterialLaw, Vect, World};
use crate::scene::Model;
use nalgebra::{DMatrix, Matrix2, Matrix4};

fn scene(safety: f64, law: Option<&str>) -> crate::Scene {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("tests/data/small2d.json")).unwrap(),
    )
    .unwrap();
    v["bodies"][0]["material"]["young"] = 1e6.into();
    v["bodies"][0]["material"]["poisson"] = (-0.5).into();
    if let Some(l) = law {
        v["bodies"][0]["material"]["law"] = l.into();
    }
    v["bodies"][0]["velocity"] = serde_json::json!([0.0, -1.0]);
    v["gravity"]["vector"] = serde_json::json!([0.0, -981.0]);
    v["solver"] = serde_json::json!({ "model": "corrected", "safety": safety });
    crate::Scene::from_json(&v.to_string()).unwrap()
}

/// F_i of the corrected operator at displacements u.
fn defgrad(w: &World<2>, u: &[Vect<2>], i: usize) -> Mat<2> {
    let mut g = Mat::<2>::zeros();
    for b in w.bonds.of(i) {
        let w0 = w.bonds.w0[b];
        if w0 == 0.0 {
            continue;
        }
        let r0 = w.bonds.r0[b];
        let r = r0 + (u[w.bonds.nbr[b] as usize] - u[i]);
        g += (r * (w0 / r0.norm_squared())) * r0.transpose();
    }
    g * w.op.k_inv[i]
}

/// Tangent A = d^2 W / dF dF of the law (4x4 on the entries F_aA, index 2a + A) by central
/// differences of P = F S(E(F)).
fn law_tangent(law: MaterialLaw, f: &Mat<2>, mu: f64, lambda: f64) -> Matrix4<f64> {
    let piola = |f: &Mat<2>| {
        let e = (f.transpose() * f - Mat::<2>::identity()) * 0.5;
        f * law
            .stress(&e, mu, lambda)
            .unwrap_or(Mat::<2>::zeros() * f64::NAN)
    };
    let h = 1e-6;
    let mut t = Matrix4::<f64>::zeros();
    for b in 0..2 {
        for bb in 0..2 {
            let mut d = Mat::<2>::zeros();
            d[(b, bb)] = h;
            let dp = (piola(&(f + d)) - piola(&(f - d))) / (2.0 * h);
            for a in 0..2 {
                for aa in 0..2 {
                    t[(2 * a + aa, 2 * b + bb)] = dp[(a, aa)];
                }
            }
        }
    }
    (t + t.transpose()) * 0.5
}

/// Smallest eigenvalue of the acoustic tensor Q(n)_ab = A_aAbB n_A n_B over directions n.
fn acoustic_min(t: &Matrix4<f64>) -> (f64, f64) {
    let mut best = (f64::INFINITY, 0.0);
    for k in 0..360 {
        let th = k as f64 * std::f64::consts::PI / 360.0;
        let n = [th.cos(), th.sin()];
        let mut q = Matrix2::<f64>::zeros();
        for a in 0..2 {
            for b in 0..2 {
                for aa in 0..2 {
                    for bb in 0..2 {
                        q[(a, b)] += t[(2 * a + aa, 2 * b + bb)] * n[aa] * n[bb];
                    }
                }
            }
        }
        let e = q.symmetric_eigenvalues().min();
        if e < best.0 {
            best = (e, th.to_degrees());
        }
    }
    best
}

/// Assembled tangent stiffness (free dofs) by central differences of the operator's forces,
/// divided by the mass: its eigenvalues are omega^2 (negative: growth rate^2).
fn tangent_spectrum(w: &World<2>, u: &[Vect<2>]) -> (Vec<f64>, DMatrix<f64>, Vec<(usize, usize)>) {
    let dofs: Vec<(usize, usize)> = (0..w.len())
        .flat_map(|i| (0..2).map(move |k| (i, k)))
        .filter(|&(i, k)| w.p.fix[i] & [1u8, 2][k] == 0)
        .collect();
    let n = dofs.len();
    let mut kmat = DMatrix::<f64>::zeros(n, n);
    let mut p = w.p.clone();
    let mut scratch = Default::default();
    let mut fp = vec![Vect::<2>::zeros(); w.len()];
    let mut fm = fp.clone();
    let mut tq = vec![0.0; w.len()];
    let eps = 1e-7 * w.l0;
    for (c, &(i, k)) in dofs.iter().enumerate() {
        for (s, f) in [(1.0, &mut fp), (-1.0, &mut fm)] {
            p.u.copy_from_slice(u);
            p.u[i][k] += s * eps;
            w.op.forces(&p, &w.bonds, &mut scratch, f, &mut tq);
        }
        for (r, &(j, l)) in dofs.iter().enumerate() {
            kmat[(r, c)] = -(fp[j][l] - fm[j][l]) / (2.0 * eps) / w.p.mass[j];
        }
    }
    let sym = (&kmat + kmat.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let mut ev: Vec<(f64, usize)> = eig.eigenvalues.iter().copied().zip(0..).collect();
    ev.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
    let vecs = DMatrix::from_fn(n, n, |r, c| eig.eigenvectors[(r, ev[c].1)]);
    (ev.iter().map(|e| e.0).collect(), vecs, dofs)
}

pub fn main(args: Vec<String>) {
    let args: Vec<String> = args.clone().into_iter().collect();
    if let Ok(t) = std::env::var("ADVANCE") {
        advance_once(args[1].parse().unwrap(), t.parse().unwrap());
        return;
    }
    let safety: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(0.8);
    let t_end: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.2);
    let law = std::env::var("LAW").ok();
    let sc = scene(safety, law.as_deref());
    let mut m = Model::<2>::build(&sc).unwrap();
    let w = &mut m.world;
    let (mu, lambda) = w.op.lame[0];
    let mlaw = w.op.laws[0];
    println!(
        "mu {mu:.4e} lambda {lambda:.4e} dt {:.4e} n {}",
        w.max_dt(),
        w.len()
    );
    let mut hist: std::collections::VecDeque<crate::physics::world::WorldState<2>> =
        Default::default();
    let mut minj = (f64::INFINITY, 0usize, 0.0);
    let mut minstretch = (f64::INFINITY, 0usize, 0.0);
    let mut minac = (f64::INFINITY, 0usize, 0.0);
    let mut first_elliptic_loss: Option<(f64, usize, f64, f64)> = None;
    let mut first_inversion: Option<f64> = None;
    // The step sequence of World::advance_to(t_end): equal sub-steps, re-split when the
    // measured bound shortens.
    let (mut t0, mut h) = (w.time, t_end - w.time);
    let mut n = ((h / w.max_dt()) * (1.0 - 1e-12)).ceil().max(1.0) as u64;
    let mut k = 0u64;
    let report_every: f64 = std::env::var("REPORT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.01);
    let mut next_report = report_every;
    let mut window = (
        f64::INFINITY,
        f64::INFINITY,
        0.0f64,
        0usize,
        0usize,
        (0.0f64, 0usize),
    );
    let res = loop {
        if k == n {
            break Ok(());
        }
        hist.push_back(w.state());
        if hist.len() > 60 {
            hist.pop_front();
        }
        let max_dt = w.max_dt();
        k += 1;
        let t_new = if k == n {
            t_end
        } else {
            t0 + k as f64 * (h / n as f64)
        };
        if let Err(e) = w.step(t_new - w.time) {
            break Err(e);
        }
        if k < n && w.max_dt() < max_dt {
            t0 = w.time;
            h = t_end - t0;
            n = ((h / w.max_dt()) * (1.0 - 1e-12)).ceil().max(1.0) as u64;
            k = 0;
        }
        let prev = hist.back().unwrap();
        let dt = w.time - prev.time;
        let g = Vect::<2>::new(0.0, -981.0);
        let kick = (0..w.len())
            .filter(|&i| w.p.fix[i] == 0)
            .map(|i| ((w.p.v[i] - prev.v[i] - g * dt).norm() * dt / w.l0, i))
            .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
        let (mut jmin, mut smin, mut smax, mut inverted, mut beyond) =
            (f64::INFINITY, f64::INFINITY, 0.0f64, 0, 0);
        for i in 0..w.len() {
            if w.p.fix[i] != 0 {
                continue;
            }
            let f = defgrad(w, &w.p.u, i);
            let sv = f.singular_values();
            jmin = jmin.min(f.determinant());
            smin = smin.min(sv.min());
            smax = smax.max(sv.max());
            inverted += usize::from(f.determinant() <= 0.0);
            beyond += usize::from(sv.min() < 1.0 / 3f64.sqrt());
        }
        window.0 = window.0.min(jmin);
        window.1 = window.1.min(smin);
        window.2 = window.2.max(smax);
        window.3 = window.3.max(inverted);
        window.4 = window.4.max(beyond);
        if kick.0 > window.5 .0 {
            window.5 = kick;
        }
        if w.time >= next_report || w.time >= t_end {
            println!(
                "t {:.4}: min det F {:+.3}, stretches {:.3}..{:.3}, most inverted {}, most below 1/sqrt(3) {}, largest dt|dv| {:.3} l0 (particle {}), dt {:.3e}",
                w.time, window.0, window.1, window.2, window.3, window.4, window.5 .0, window.5 .1, dt
            );
            window = (f64::INFINITY, f64::INFINITY, 0.0, 0, 0, (0.0, 0));
            next_report += report_every;
        }
        for i in 0..w.len() {
            if w.p.fix[i] != 0 {
                continue;
            }
            let f = defgrad(w, &w.p.u, i);
            let j = f.determinant();
            let sv = f.singular_values().min();
            if j < minj.0 {
                minj = (j, i, w.time);
            }
            if sv < minstretch.0 {
                minstretch = (sv, i, w.time);
            }
            let ac = acoustic_min(&law_tangent(mlaw, &f, mu, lambda)).0 / mu;
            if ac < minac.0 {
                minac = (ac, i, w.time);
            }
            if ac < 0.0 && first_elliptic_loss.is_none() {
                first_elliptic_loss = Some((w.time, i, f.singular_values().min(), f.determinant()));
                println!(
                    "first loss of ellipticity: t {:.4} particle {i} stretch {:.3} det {:.3}",
                    w.time,
                    f.singular_values().min(),
                    f.determinant()
                );
            }
            if f.determinant() <= 0.0 && first_inversion.is_none() {
                first_inversion = Some(w.time);
                println!("first inversion: t {:.4} particle {i}", w.time);
            }
        }
    };
    println!(
        "end t {:.5} steps {} result {:?}\nover the run: min det F {:.4} (particle {}, t {:.4}); min stretch {:.4} (particle {}, t {:.4}); min acoustic eig / mu {:.4} (particle {}, t {:.4})",
        w.time, w.steps, res.as_ref().err().map(|e| e.to_string()), minj.0, minj.1, minj.2,
        minstretch.0, minstretch.1, minstretch.2, minac.0, minac.1, minac.2
    );
    let bad = match &res {
        Err(crate::physics::SimError::BlowUp { particle, .. }) => *particle,
        _ => std::env::var("WATCH")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(31),
    };
    let mut nb: Vec<usize> = w.bonds.of(bad).map(|b| w.bonds.nbr[b] as usize).collect();
    nb.retain(|&j| (w.p.x0[j] - w.p.x0[bad]).norm() < 1.01 * w.l0);
    nb.insert(0, bad);
    println!(
        "particle {bad} at X {:?}, fix {}, nearest neighbours {:?}",
        w.p.x0[bad],
        w.p.fix[bad],
        &nb[1..]
    );
    let every: usize = std::env::var("EVERY")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    for (k, s) in hist.iter().enumerate() {
        if k % every != 0 && k + 1 != hist.len() {
            continue;
        }
        println!("-- t {:.6} step {}", s.time, s.steps);
        for &i in &nb {
            let f = defgrad(w, &s.u, i);
            let svd = f.svd(false, false);
            let t = law_tangent(mlaw, &f, mu, lambda);
            let te = t.symmetric_eigenvalues();
            let (ac, ang) = acoustic_min(&t);
            let xi = w.p.x0[i] + s.u[i];
            let near = (0..w.len())
                .filter(|&j| j != i && !w.bonds.of(i).any(|b| w.bonds.nbr[b] as usize == j))
                .map(|j| ((w.p.x0[j] + s.u[j] - xi).norm() / w.l0, j))
                .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a });
            println!(
                "  p{i:3}: x [{:.4} {:.4}] nearest unbonded {} at {:.3} l0",
                xi[0], xi[1], near.1, near.0
            );
            println!(
                "  p{i:3}: F [{:+.4} {:+.4}; {:+.4} {:+.4}] stretches {:.4} {:.4} det {:+.4} tangent eig/mu min {:+.4} acoustic min/mu {:+.4} at {:.0} deg |v| {:.3}",
                f[(0, 0)], f[(0, 1)], f[(1, 0)], f[(1, 1)],
                svd.singular_values[0], svd.singular_values[1], f.determinant(),
                te.min() / mu, ac / mu, ang, s.v[i].norm()
            );
        }
    }
    if std::env::var("SPECTRUM").is_ok() {
        let nspec: usize = std::env::var("SPECTRUM").unwrap().parse().unwrap_or(3);
        let l = hist.len();
        for s in hist
            .iter()
            .skip(l.saturating_sub(nspec * every))
            .step_by(every)
        {
            let (ev, vecs, dofs) = tangent_spectrum(w, &s.u);
            let n = ev.len();
            let dt = w.max_dt();
            println!(
                "spectrum t {:.6}: omega_max {:.4e} (dt omega {:.3}); lowest omega^2 {:.4e} {:.4e} {:.4e}",
                s.time, ev[n - 1].sqrt(), ev[n - 1].sqrt() * dt, ev[0], ev[1], ev[2]
            );
            for (name, c) in [("lowest", 0), ("highest", n - 1)] {
                let mut amp: Vec<(f64, usize)> = (0..w.len()).map(|i| (0.0, i)).collect();
                for (r, &(i, _)) in dofs.iter().enumerate() {
                    amp[i].0 += vecs[(r, c)].powi(2);
                }
                amp.sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap());
                println!(
                    "   {name} mode concentrated on {:?}",
                    amp.iter()
                        .take(5)
                        .map(|a| (a.1, (a.0 * 100.0).round()))
                        .collect::<Vec<_>>()
                );
            }
        }
    }
}

#[allow(dead_code)]
pub fn advance_once(safety: f64, t_end: f64) {
    let law = std::env::var("LAW").ok();
    let sc = scene(safety, law.as_deref());
    let mut m = Model::<2>::build(&sc).unwrap();
    let w = &mut m.world;
    let t = if t_end > 0.0 {
        t_end
    } else {
        4000.0 * w.max_dt()
    };
    let r = w.advance_to(t);
    println!(
        "advance_to({t:.5}) safety {safety}: {:?} at t {:.5} step {}, omega {:.4e}, {} refreshes",
        r.map_err(|e| e.to_string()),
        w.time,
        w.steps,
        w.omega_elastic(),
        w.step_refreshes
    );
}
