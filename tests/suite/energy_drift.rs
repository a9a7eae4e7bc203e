//! Energy conservation of the undamped integrator (issue 7): a small 2D cantilever in free
//! vibration keeps kinetic + strain energy to 0.1 % over 100 periods, and a contact impact
//! between two blocks returns the energy it stored: the energy symplectic Euler conserves (its
//! shadow energy) within 0.1 % at closing speeds of 0.5-16 m/s, the staggered energy within 0.2 %
//! at 2 m/s, both at the default safety.
use crate::common;
use common::block;
use mps_solid::physics::boundary::GravityLaw;
use mps_solid::physics::world::GroupInit;
use mps_solid::physics::{BodyInit, Material, MaterialLaw, SolverOptions, Vect, World};
use nalgebra::Vector2;

const L0: f64 = 0.01;
const MAT: Material = Material {
    density: 1000.0,
    young: 1.0e7,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};

#[test]
#[ignore = "slow (20 s on a loaded 2-core machine): the full test command runs it"]
fn undamped_cantilever_keeps_its_energy_over_100_periods() {
    let (mut w, tip) = vibrating_cantilever();
    let dt = w.max_dt();
    let sw = Swing::record(&mut w, &tip, 102, |_| dt, |_, _, _| {});
    let (first, last, drift) = sw.drift(0, 100);
    eprintln!(
        "E0 = {:.6e} J, first period mean {first:.6e}, after 100 periods {last:.6e}: drift {:.3e} ({} steps/period)",
        sw.e[0],
        drift,
        (sw.crossings[101] - sw.crossings[0]) / 101
    );
    assert!(drift < 1e-3, "energy drift {drift} over 100 periods");
}

#[test]
fn a_step_that_changes_with_the_motion_creates_no_energy() {
    // The solver's step changes with the state (contact starting or ending, a refresh of the
    // stable step). Here the cantilever's step is the full stable step while its tip moves up
    // and 0.4 of it while the tip moves down, switched each time the tip turns: the worst case
    // of a step correlated with the motion. The velocities are those of the step that led to
    // the state, so the next step's forces act over half of each step (`StepInputs::kick_dt`);
    // with the kick over the new step alone each switch shifted the velocities by
    // (dt - dt_previous) / 2 times the acceleration, in phase with the motion here, and the
    // energy grew until the run blew up at t = 0.30 s (step 14,795; measured 2026-12-07). Now
    // it changes by 4e-4 over 20 periods; bound 1 %, what a step correlated with the motion
    // may leave in the measured energy's mean over a period (it oscillates within a period by
    // O(omega dt) of the energy).
    let (mut w, tip) = vibrating_cantilever();
    let full = w.max_dt();
    let tip_velocity =
        |w: &World<2>| tip.iter().map(|&i| w.p.v[i][1]).sum::<f64>() / tip.len() as f64;
    let sw = Swing::record(
        &mut w,
        &tip,
        22,
        |w| {
            if tip_velocity(w) > 0.0 {
                full
            } else {
                0.4 * full
            }
        },
        |_, _, _| {},
    );
    let (first, last, drift) = sw.drift(0, 20);
    eprintln!("first period mean {first:.6e} J, after 20 periods {last:.6e}: drift {drift:.3e}");
    assert!(drift < 1e-2, "energy changed by {drift} over 20 periods");
}

/// A small 2D cantilever in free vibration: 12 x 4 particles, the first 2 layers clamped,
/// released with a bending velocity profile v_y = 0.05 m/s (s / L)^2 and no gravity; and the
/// particles of its tip.
fn vibrating_cantilever() -> (World<2>, Vec<usize>) {
    let pts = block::<2>([12, 4, 1], L0);
    let xmin = pts.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let xmax = pts.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max);
    let members: Vec<u32> = (0..pts.len())
        .filter(|&i| pts[i][0] < xmin + 1.5 * L0)
        .map(|i| i as u32)
        .collect();
    let mut w = World::new(
        L0,
        SolverOptions::default(),
        vec![BodyInit {
            name: "beam".into(),
            material: MAT,
            points: pts.clone(),
            velocity: Vect::<2>::zeros().into(),
            shape: None,
        }],
        vec![GroupInit {
            name: "clamp".into(),
            members,
            axes: [true; 3],
            fix_rotation: true,
            mirror: None,
        }],
        vec![],
        GravityLaw::Constant(Vect::<2>::zeros()),
    )
    .unwrap();
    let root = xmin + 1.5 * L0;
    let mut s = w.state();
    for (i, p) in pts.iter().enumerate() {
        if w.p.fix[i] == 0 {
            let xi = (p[0] - root) / (xmax - root);
            s.v[i] = Vector2::new(0.0, 0.05 * xi * xi);
        }
    }
    w.set_state(&s).unwrap();
    let tip = (0..w.len())
        .filter(|&i| pts[i][0] > xmax - 0.5 * L0)
        .collect::<Vec<_>>();
    (w, tip)
}

/// A free vibration's record: kinetic + strain energy at the start and after every step, and the
/// steps at which the mean tip displacement u_y crosses zero upwards.
struct Swing {
    e: Vec<f64>,
    crossings: Vec<usize>,
}

impl Swing {
    /// Steps `w` by `dt(w)` until `n` upward zero crossings of the mean u_y of `tip`; `each` sees
    /// the world, the step count and that mean after every step.
    fn record(
        w: &mut World<2>,
        tip: &[usize],
        n: usize,
        dt: impl Fn(&World<2>) -> f64,
        mut each: impl FnMut(&World<2>, usize, f64),
    ) -> Swing {
        let energy = |w: &World<2>| w.kinetic_energy() + w.strain_energy();
        let mut sw = Swing {
            e: vec![energy(w)],
            crossings: vec![],
        };
        let mut prev = 0.0;
        while sw.crossings.len() < n {
            w.step(dt(w)).unwrap();
            sw.e.push(energy(w));
            let uy = tip.iter().map(|&i| w.p.u[i][1]).sum::<f64>() / tip.len() as f64;
            each(w, sw.e.len() - 1, uy);
            if prev < 0.0 && uy >= 0.0 {
                sw.crossings.push(sw.e.len() - 1);
            }
            prev = uy;
            assert!(sw.e.len() < 2_000_000, "no vibration found");
        }
        sw
    }

    /// Mean energy over period a and over period b (J), and their relative difference (-). The
    /// measured energy of symplectic Euler oscillates by O(omega dt) within a period around a
    /// conserved shadow energy; its mean drifts only if the scheme gains or loses energy.
    fn drift(&self, a: usize, b: usize) -> (f64, f64, f64) {
        let c = &self.crossings;
        let mean = |k: usize| self.e[c[k]..c[k + 1]].iter().sum::<f64>() / (c[k + 1] - c[k]) as f64;
        let (first, last) = (mean(a), mean(b));
        (first, last, (last - first).abs() / first)
    }
}

/// Two 8 x 8 blocks, 2 l0 apart, closing at `closing` m/s (half each) along x; no gravity.
fn collision(safety: f64, closing: f64) -> World<2> {
    let a: Vec<_> = block::<2>([8, 8, 1], L0)
        .into_iter()
        .map(|p| p - Vector2::new(4.5 * L0, 0.0))
        .collect();
    let b: Vec<_> = block::<2>([8, 8, 1], L0)
        .into_iter()
        .map(|p| p + Vector2::new(4.5 * L0, 0.0))
        .collect();
    let body = |name: &str, pts, v: f64| BodyInit {
        name: name.into(),
        material: MAT,
        points: pts,
        velocity: Vector2::new(v, 0.0).into(),
        shape: None,
    };
    World::new(
        L0,
        SolverOptions {
            safety,
            ..SolverOptions::default()
        },
        vec![body("a", a, 0.5 * closing), body("b", b, -0.5 * closing)],
        Vec::<GroupInit>::new(),
        vec![],
        GravityLaw::Constant(Vect::<2>::zeros()),
    )
    .unwrap()
}

/// Kinetic energy at the current positions as symplectic Euler conserves it: the velocity of
/// the step that led here times the velocity of the next step, 1/2 m v_(n-1/2) . v_(n+1/2)
/// (the exact invariant of the scheme for a linear system; the plain 1/2 m v^2 fluctuates by
/// O(omega dt) of the energy in each mode). No gravity or loads in these tests.
fn kinetic_staggered(w: &World<2>, dt: f64) -> f64 {
    (0..w.len())
        .map(|i| {
            let m = w.p.mass[i];
            let v = w.p.v[i];
            0.5 * m * v.dot(&(v + w.internal_force(i) * (dt / m)))
        })
        .sum()
}

/// Relative energy changes of an impact (-), after separation (mean over 2000 steps) against
/// before it.
struct Impact {
    /// Staggered kinetic + strain + contact energy.
    staggered: f64,
    /// Plain kinetic + strain + contact energy.
    plain: f64,
    /// The staggered energy plus (dt^2 / 6) sum_i |f_i|^2 / m_i: symplectic Euler's shadow
    /// energy of a vibration mode of angular frequency omega exceeds its staggered energy by
    /// (omega dt)^2 / 6 of it (for x'' = -omega^2 x the scheme is a rotation at omega~ with
    /// sin(omega~ dt / 2) = omega dt / 2, and its generating energy is the staggered invariant
    /// times omega~ / (omega cos(omega~ dt / 2)) = 1 + (omega dt)^2 / 6 + O(dt^4)), and the time
    /// mean of sum |f|^2 / m over a vibration is sum_k omega_k^2 E_k. Before the impact the
    /// blocks only translate (f = 0).
    shadow: f64,
}

/// The impact of [`collision`] with block a shifted back by `shift` (m) along x.
fn impact(safety: f64, closing: f64, shift: f64) -> Impact {
    let mut w = collision(safety, closing);
    let mut s = w.state();
    for (u, b) in s.u.iter_mut().zip(&w.p.body) {
        if *b == 0 {
            u[0] -= shift;
        }
    }
    w.set_state(&s).unwrap();
    let dt = w.max_dt();
    let plain = |w: &World<2>| w.kinetic_energy() + w.strain_energy() + w.contact_energy();
    let stag = |w: &World<2>| kinetic_staggered(w, dt) + w.strain_energy() + w.contact_energy();
    let f2m = |w: &World<2>| {
        (0..w.len())
            .map(|i| w.internal_force(i).norm_squared() / w.p.mass[i])
            .sum::<f64>()
    };
    let (e0, s0) = (plain(&w), stag(&w));
    let mut touched = false;
    let mut steps = 0;
    loop {
        w.step(dt).unwrap();
        steps += 1;
        let c = w.contact_pairs();
        touched |= c > 0;
        if touched && c == 0 {
            break;
        }
        assert!(steps < 200_000, "the blocks never separated");
    }
    let n = 2000.0;
    let (mut sum, mut ssum, mut fsum) = (0.0, 0.0, 0.0);
    for _ in 0..2000 {
        w.step(dt).unwrap();
        sum += plain(&w);
        ssum += stag(&w);
        fsum += f2m(&w);
    }
    Impact {
        staggered: ssum / n / s0 - 1.0,
        plain: sum / n / e0 - 1.0,
        shadow: (ssum + dt * dt / 6.0 * fsum) / n / s0 - 1.0,
    }
}

/// The impact over 4 phases of the first touch within a step (block a shifted back by a quarter
/// of the closing distance of a step each time).
fn phases(safety: f64, closing: f64) -> Vec<Impact> {
    let dt = collision(safety, closing).max_dt();
    (0..4)
        .map(|k| {
            let r = impact(safety, closing, (k as f64 + 0.5) / 4.0 * closing * dt);
            eprintln!(
                "safety {safety}, {closing} m/s, phase {k}/4: staggered {:+.4} %, plain {:+.4} %, shadow {:+.5} %",
                100.0 * r.staggered,
                100.0 * r.plain,
                100.0 * r.shadow
            );
            r
        })
        .collect()
}

#[test]
#[ignore = "slow (27 s on a loaded 2-core machine): the full test command runs it"]
fn contact_impact_returns_its_energy() {
    // The staggered energy (kinetic m v_(n-1/2).v_(n+1/2)/2 + strain + contact) after the blocks
    // (closing at 2 m/s) have separated, against before the impact, over 4 phases of the first
    // touch within a step. Symplectic Euler's error of an impact is second order in dt. With the
    // paper's spring (a kink at first touch) it had a random sign with the phase: at safety
    // 1.0 / 0.8 / 0.4 / 0.2 mean +0.88 / -0.77 / -0.25 / -0.08 %, largest 5.7 / 1.9 / 0.80 /
    // 0.15 % (8 phases). With the C1 onset of `contact::ONSET` it is phase-free and one-signed:
    // -0.21 / -0.14 / -0.034 / -0.009 %, the offset of the vibration the impact leaves
    // (`Impact::shadow`). The issue asks for 0.2 % at the default safety (0.8); the bounds below
    // are the measured values plus half, and the order in dt must be about 2 (factor 4 per
    // halving: 3.5 to 4.5).
    let mut mean = vec![];
    for (safety, tol) in [(1.0, 0.0032), (0.8, 0.002), (0.4, 0.0006), (0.2, 0.00015)] {
        let runs = phases(safety, 2.0);
        for (k, r) in runs.iter().enumerate() {
            assert!(
                r.staggered.abs() < tol,
                "safety {safety}, phase {k}: energy changed by {} (bound {tol})",
                r.staggered
            );
        }
        mean.push(runs.iter().map(|r| r.staggered).sum::<f64>() / 4.0);
    }
    let order = mean[2] / mean[3];
    eprintln!("mean error {mean:?}; 0.4 -> 0.2: factor {order:.2}");
    assert!((3.5..4.5).contains(&order), "not second order: {order}");
}

#[test]
#[ignore = "slow (31 s on a loaded 2-core machine): the full test command runs it"]
fn contact_impact_keeps_the_shadow_energy_of_symplectic_euler() {
    // Issue 7: an impact conserves energy within 0.2 % at the default safety. What the
    // staggered energy loses in an impact is the offset of the vibration the impact leaves,
    // -(dt^2 / 6) sum_k omega_k^2 E_k (`Impact::shadow`), which grows with the closing speed as
    // the vibration does (safety 0.8: -0.045 / -0.136 / -0.41 / -0.65 % at 0.5 / 2 / 8 / 16 m/s);
    // the energy the scheme conserves, the shadow energy, is kept at every speed: measured
    // within 0.0011 / 0.0046 / 0.025 / 0.047 % at 0.5 / 2 / 8 / 16 m/s (safety 0.8) and 0.0091 %
    // at 2 m/s and safety 1.0 (4 phases each). This needs a smooth law: with the paper's spring
    // (its stiffness jumps to k_c at first touch) it changed by percents with the phase of the
    // touch (safety 0.8, 2 m/s: staggered -2.2 to +1.9 % against a vibration offset of about
    // -0.8 %). Bound: 0.1 %, twice the largest measured value and half the 0.2 %.
    for (safety, closing) in [(1.0, 2.0), (0.8, 2.0), (0.8, 0.5), (0.8, 8.0), (0.8, 16.0)] {
        for (k, r) in phases(safety, closing).iter().enumerate() {
            assert!(
                r.shadow.abs() < 1e-3,
                "safety {safety}, {closing} m/s, phase {k}: shadow energy changed by {}",
                r.shadow
            );
        }
    }
}

/// Issue 7, energy at large deformation: small2d (a 0.4 x 0.1 m plane-strain cantilever, L/H = 4,
/// second_order with its rigid holder) released without gravity with the first cantilever mode's
/// velocity at 5 m/s at the tip swings to a tip deflection of 57 % of its length, with bond strains
/// up to 0.29, undamped, at the default safety. The mean energy over a period after 8 periods is
/// that of the first period within 0.1 % (the bound for small vibrations; measured
/// 5e-5). Beyond this, at bond strains of 0.45 (8 m/s, 77 % of L), the default step lets the
/// energy grow by 3.6 % in 8 periods (nonlinear resonance of the fastest modes, whose omega dt
/// is up to 1.6 at safety 0.8, past the 4:1 resonance of symplectic Euler at sqrt(2)); safety 0.6
/// or 0.4 keeps it within 0.1 % (7e-4); docs/model.md, "Time step". That case is not held
/// here.
#[test]
#[ignore = "slow (27 s on a loaded 2-core machine): the full test command runs it"]
fn large_amplitude_vibration_keeps_its_energy() {
    use mps_solid::scene::{Model, Scene};
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/small2d.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["gravity"] = serde_json::json!({ "vector": [] });
    v["bodies"][0]["velocity"] = serde_json::json!({ "profiles": [{ "mode_shape": {
        "shape": "clamped_free_1", "axis": "x", "component": "y",
        "x0": 0.0, "length": 0.4, "amplitude": 5.0 } }] });
    let scene = Scene::from_json(&v.to_string()).unwrap();
    let mut m = Model::<2>::build(&scene).unwrap();
    let w = &mut m.world;
    let tip: Vec<usize> = (0..w.len())
        .filter(|&i| (w.p.x[i] - w.p.u[i])[0] > 0.39)
        .collect();
    let (mut peak, mut strain) = (0.0f64, 0.0f64);
    let sw = Swing::record(w, &tip, 10, World::max_dt, |w, step, uy| {
        peak = peak.max(uy.abs());
        if step % 50 == 0 {
            strain = strain.max(w.max_bond_strain().0);
        }
    });
    let (first, last, drift) = sw.drift(0, 8);
    eprintln!(
        "tip deflection up to {peak:.4} m, bond strain up to {strain:.3}; energy first period {first:.6e}, ninth {last:.6e}: drift {drift:.2e}"
    );
    assert!(peak > 0.2, "not a large deflection: {peak} m");
    assert!(drift < 1e-3, "energy drift {drift} over 8 periods");
}
