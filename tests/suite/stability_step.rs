//! The stable step holds (issue 7): safety 1 is stable in 3D, explicit damping has its own limit
//! that the automatic step respects, and a fast rigid motion is not mistaken for a blow-up.
use crate::common;
use common::{block, Rng};
use mps_solid::physics::boundary::GravityLaw;
use mps_solid::physics::integrate::critical_step;
use mps_solid::physics::world::GroupInit;
use mps_solid::physics::{
    BodyInit, Dim, ElasticModel, Material, MaterialLaw, SolverOptions, Space, Vect, World,
};

const L0: f64 = 0.01;
const MAT: Material = Material {
    density: 1000.0,
    young: 1.0e7,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};

/// A 3D cantilever of nx x 4 x 4 particles along x, its first 2 layers clamped, under sudden
/// gravity -z, with a random perturbation of 1e-6 l0 so that every mode is excited.
fn cantilever(nx: usize, opts: SolverOptions) -> World<3> {
    cantilever_g(nx, 9.81, opts)
}

fn cantilever_g(nx: usize, g: f64, opts: SolverOptions) -> World<3> {
    let pts = block::<3>([nx, 4, 4], L0);
    let xmin = pts.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let members: Vec<u32> = (0..pts.len())
        .filter(|&i| pts[i][0] < xmin + 1.5 * L0)
        .map(|i| i as u32)
        .collect();
    let mut w = World::new(
        L0,
        opts,
        vec![BodyInit {
            name: "beam".into(),
            material: MAT,
            points: pts,
            velocity: Vect::<3>::zeros().into(),
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
        GravityLaw::Constant(Vect::<3>::new(0.0, 0.0, -g)),
    )
    .unwrap();
    let mut s = w.state();
    let mut rng = Rng(7);
    for i in 0..w.len() {
        if w.p.fix[i] == 0 {
            for a in 0..3 {
                s.u[i][a] += 1e-6 * L0 * rng.next();
            }
        }
    }
    w.set_state(&s).unwrap();
    w
}

/// Runs n steps of the automatic step; returns the largest displacement over the run (m).
fn run<const D: usize>(w: &mut World<D>, n: usize) -> Result<f64, String>
where
    Space: Dim<D>,
{
    let dt = w.max_dt();
    let mut umax: f64 = 0.0;
    for _ in 0..n {
        w.step(dt).map_err(|e| e.to_string())?;
        umax = w.p.u.iter().map(|u| u.norm()).fold(umax, f64::max);
    }
    Ok(umax)
}

#[test]
#[ignore = "slow (7 s on a loaded 2-core machine): the full test command runs it"]
fn cantilever_3d_is_stable_at_safety_one() {
    // Before: the measured critical step was ~0.5 % optimistic in 3D, so safety 1 grew the
    // highest mode by ~1.1x per step and blew up within a few hundred steps.
    for model in [ElasticModel::Corrected, ElasticModel::Paper] {
        let opts = SolverOptions {
            model,
            safety: 1.0,
            ..SolverOptions::default()
        };
        let mut w = cantilever(16, opts);
        let umax = run(&mut w, 2000).unwrap_or_else(|e| panic!("{model:?}: {e}"));
        // Static tip deflection of this beam under gravity is ~6e-4 m (1.2e-3 m dynamic); a
        // growing mode would exceed l0 long before 2000 steps.
        assert!(umax < 0.3 * L0, "{model:?}: displacement grew to {umax} m");
    }
}

#[test]
fn high_damping_is_stable_at_the_default_safety() {
    // Before: mass-proportional damping above ~4000 1/s blew up: explicit damping has its own
    // limit c dt <= 2, combined with omega: dt <= (2 / omega)(sqrt(1 + zeta^2) - zeta).
    for c in [1.0e4, 1.0e5] {
        let opts = SolverOptions {
            damping: c,
            ..SolverOptions::default()
        };
        let mut w = cantilever(12, opts);
        let umax = run(&mut w, 2000).unwrap_or_else(|e| panic!("damping {c}: {e}"));
        assert!(
            umax < 0.3 * L0,
            "damping {c}: displacement grew to {umax} m"
        );
        assert!(w.max_dt() * c <= 2.0);
    }
}

#[test]
fn damped_step_bound_is_the_exact_limit() {
    // The bound is sharp: just below it a damped oscillator of frequency omega decays, just
    // above it grows. Symplectic Euler on x'' = -omega^2 x - c x'.
    let omega = 1000.0;
    for c in [0.0, 100.0, 2000.0, 1.0e5] {
        let dt_c = critical_step(omega, c);
        let amp = |dt: f64| {
            let (mut x, mut v) = (1.0f64, 0.0f64);
            for _ in 0..20000 {
                v += dt * (-omega * omega * x - c * v);
                x += dt * v;
            }
            x.abs().max(v.abs() / omega)
        };
        // Without damping the orbit near the limit is an ellipse stretched by
        // 1 / sqrt(1 - (omega dt / 2)^2) (22 at 0.999), hence the bound of 100.
        assert!(
            amp(0.999 * dt_c) < 100.0,
            "c = {c}: unstable below the bound"
        );
        let above = amp(1.001 * dt_c);
        assert!(
            above.is_nan() || above >= 100.0,
            "c = {c}: stable above the bound"
        );
    }
    assert_eq!(critical_step(omega, 0.0), 2.0 / omega);
    assert_eq!(critical_step(0.0, 50.0), 2.0 / 50.0);
}

fn soft_translating<const D: usize>(n: [usize; 3]) -> World<D>
where
    Space: Dim<D>,
{
    let mut v = Vect::<D>::zeros();
    v[0] = 5.0;
    World::new(
        L0,
        SolverOptions::default(),
        vec![BodyInit {
            name: "soft".into(),
            material: Material {
                density: 1000.0,
                young: 1.0e4,
                poisson: 0.3,
                law: MaterialLaw::SaintVenantKirchhoff,
            },
            points: block::<D>(n, L0),
            velocity: v.into(),
            shape: None,
        }],
        Vec::<GroupInit>::new(),
        vec![],
        GravityLaw::Constant(Vect::<D>::zeros()),
    )
    .unwrap()
}

#[test]
fn soft_free_body_translating_fast_runs() {
    // Before: a soft body (E = 1e4 Pa) moving rigidly at 5 m/s moves ~0.6 l0 per automatic step
    // and the blow-up check (any motion > 0.5 l0 per step) stopped it at step 1.
    let mut w3 = soft_translating::<3>([6, 5, 4]);
    run(&mut w3, 200).unwrap();
    assert!((w3.momentum()[0] / (w3.len() as f64 * 1000.0 * L0.powi(3)) - 5.0).abs() < 1e-9);
    // A rigid translation stays undeformed.
    assert!(w3.strain_energy() < 1e-12 * w3.kinetic_energy());
    let mut w2 = soft_translating::<2>([8, 6, 1]);
    run(&mut w2, 200).unwrap();
    assert!(w2.strain_energy() < 1e-12 * w2.kinetic_energy());
}

#[test]
#[ignore = "slow (29 s on a loaded 2-core machine): the full test command runs it"]
fn cantilever_deflected_to_half_its_length_is_stable_and_the_bound_follows_it() {
    // 18 x 4 x 4 particles, 2 layers clamped, sudden gravity of 1000 m/s^2 and damping 30 1/s:
    // the tip swings to 0.7-0.8 of the free length and settles near 0.45-0.5. Every step takes
    // the current max_dt, which follows the measurements of the stable step in the current
    // configuration (refresh every >= 200 steps once a bond has turned or stretched by 10 %).
    // Measured: omega_max in the deflected state is 0.05 % (corrected) and 0.5 % (paper) above
    // the reference one, inside the 3 % margin; 9-14 refreshes; 1.5-2 % of the run time.
    for model in [ElasticModel::Corrected, ElasticModel::Paper] {
        for safety in [0.8, 1.0] {
            let opts = SolverOptions {
                model,
                safety,
                damping: 30.0,
                ..SolverOptions::default()
            };
            let mut w = cantilever_g(18, 1000.0, opts);
            let omega0 = w.omega_elastic();
            let len = 16.0 * L0;
            let mut tip_max: f64 = 0.0;
            let clock = std::time::Instant::now();
            while w.time < 0.3 {
                let dt = w.max_dt();
                w.step(dt)
                    .unwrap_or_else(|e| panic!("{model:?} safety {safety}: {e}"));
                tip_max = w.p.u.iter().map(|u| -u[2]).fold(tip_max, f64::max);
            }
            let wall = clock.elapsed().as_secs_f64();
            let tip = w.p.u.iter().map(|u| -u[2]).fold(0.0, f64::max);
            eprintln!(
                "{model:?} safety {safety}: tip {:.3} L (largest {:.3} L), omega {omega0:.5e} -> {:.5e}, {} refreshes in {} steps, {:.2} % of the time",
                tip / len,
                tip_max / len,
                w.omega_elastic(),
                w.step_refreshes,
                w.steps,
                100.0 * w.step_refresh_seconds / wall
            );
            assert!(tip > 0.3 * len && tip_max < len, "tip {tip}");
            assert!(w.step_refreshes >= 3, "{} refreshes", w.step_refreshes);
            assert!(w.step_refreshes <= w.steps / 50 + 1);
            assert!(w.omega_elastic() >= omega0);
            // A restored state steps on bitwise as if it had not stopped: the refreshed bound
            // travels with the state (a fresh world starts from the reference bound).
            let s = w.state();
            let t = w.time;
            let mut fresh = cantilever_g(18, 1000.0, w.options.clone());
            fresh.set_state(&s).unwrap();
            assert_eq!(fresh.max_dt().to_bits(), w.max_dt().to_bits());
            w.advance_to(t + 0.05).unwrap();
            fresh.advance_to(t + 0.05).unwrap();
            assert_eq!(fresh.state(), w.state());
        }
    }
}

/// tests/data/small2d.json (a 0.4 x 0.1 m strip, its left end held) with another material,
/// gravity scaled by `g_scale`, no gravity ramp.
fn small2d_variant(young: f64, poisson: f64, model: &str, g_scale: f64) -> mps_solid::Scene {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("tests/data/small2d.json")).unwrap(),
    )
    .unwrap();
    v["bodies"][0]["material"]["young"] = young.into();
    v["bodies"][0]["material"]["poisson"] = poisson.into();
    v["gravity"]["vector"] = serde_json::json!([0.0, -9.81 * g_scale]);
    v["solver"] = serde_json::json!({ "model": model });
    mps_solid::Scene::from_json(&v.to_string()).unwrap()
}

#[test]
#[ignore = "slow (32 s on a loaded 2-core machine): the full test command runs it"]
fn soft_strips_collapsing_under_load_run_at_the_default_safety() {
    // Found by a random scan of 40 small2d/small3d variants (material, damping, speed, fracture,
    // gravity): valid scenes that blew up at safety 0.8 or 1.0 and ran at 0.2. The strips sag
    // far beyond their length and stiffen as they fold: omega_max rises by up to 30 % over the
    // run. With the reference bound only, the first blew up at safety 0.8 (step 876); with
    // refreshes at most every 200 steps too. What it took: refreshes at most every 50 steps,
    // the growth since the last measurement assumed again for the next interval, and the
    // deterministic start vector mixed into the warm start (a fold forming elsewhere is a new
    // stiffest mode the old eigenvector does not see), and a bound that never drops below the
    // last measurement. Safety 0.85-1.0 still blew up in three of the found scenes, hence
    // safety <= 0.8. Not in the list: E = 1e3 Pa, nu = 0.499, corrected (a jelly strip
    // collapsing under its own weight) was marginal at 0.8; the first strip thrown down at
    // 1 m/s is `thrown_strip_folds_at_safety_0_75_with_the_neo_hookean_law`.
    // The first strip carries the neo-Hookean law: with Saint Venant-Kirchhoff its root's
    // compressed fibre passes the law's stability limit, and whether the run survives the
    // material's failure is chance (the reference omega_max scaled by 1 - 1e-4, 1, 1 + 1e-4,
    // 1 + 3e-4, 1 + 1e-3: blow-ups at 0.63 s in two of the five, at particle 224, with the
    // message that the material had failed first); with the neo-Hookean law the same five
    // and 1 + 3e-3 run to the end, omega_max rising by 1.56-1.68 times.
    // (young, poisson, model, law, gravity scale, least growth of omega_max over the run)
    let cases = [
        (1e6, -0.5, "corrected", "neo_hookean", 100.0, 1.2),
        (1e5, 0.0, "corrected", "saint_venant_kirchhoff", 1.0, 1.01),
        (1e3, 0.499, "paper", "saint_venant_kirchhoff", 1.0, 1.15),
    ];
    for (young, poisson, model, law, g, growth) in cases {
        let mut v = serde_json::to_value(small2d_variant(young, poisson, model, g)).unwrap();
        v["bodies"][0]["material"]["law"] = law.into();
        let scene = mps_solid::Scene::from_json(&v.to_string()).unwrap();
        let mut m = mps_solid::scene::Model::<2>::build(&scene).unwrap();
        let w = &mut m.world;
        let omega0 = w.omega_elastic();
        let t_end = 4000.0 * w.max_dt();
        w.advance_to(t_end)
            .unwrap_or_else(|e| panic!("E {young} nu {poisson} {model} g x{g}: {e}"));
        eprintln!(
            "E {young} nu {poisson} {model} g x{g}: omega {omega0:.4e} -> {:.4e}, {} refreshes in {} steps",
            w.omega_elastic(),
            w.step_refreshes,
            w.steps
        );
        assert!(w.omega_elastic() >= growth * omega0);
    }
    // Safety above 0.8 is refused by the scene validation.
    let mut v = serde_json::to_value(small2d_variant(1e6, 0.3, "corrected", 1.0)).unwrap();
    v["solver"]["safety"] = 0.9.into();
    let e = mps_solid::Scene::from_json(&v.to_string())
        .unwrap_err()
        .to_string();
    assert!(e.contains("solver.safety") && e.contains("0.8"), "{e}");
}

#[test]
fn thrown_strip_folds_at_safety_0_75_with_the_neo_hookean_law() {
    // The first strip above (E = 1e6 Pa, nu = -0.5, 100 g) thrown down at 1 m/s blew up at
    // safety 0.8 at t = 0.152 s with the Saint Venant-Kirchhoff law, and ran at 0.75 only by
    // chance: its root is loaded far beyond what the law can carry (a linear bending strain of
    // ~3.5), so from t = 0.014 s its compressed fibre is beyond the law's stability limit
    // (principal stretch < 1/sqrt(3), the acoustic tensor loses definiteness), from 0.033 s
    // particles turn inside out (up to 33 of 256, det F down to -1.7, at 0.75 as at 0.8), and
    // the tip whips at 80-90 m/s, faster than the waves (39 m/s); the blow-up was a crushed and
    // rebounding tip corner. The step bound was not the cause: dt omega_max stayed at 1.52-1.57
    // of the allowed 2 in the last steps (src/studies/programs/fold.rs). With the neo-Hookean law,
    // whose energy grows without bound as a particle collapses, no particle gets below det F =
    // 0.09 and the largest kick of a step is 0.13 l0 over the first 0.2 s (0.2-0.4 l0 with SVK,
    // 0.5 l0 is a blow-up). At safety 0.8 the run is marginal after 0.45 s: the reference
    // omega_max scaled by 1 - 1e-4 or 1 + 3e-4 (80 power iterations) blows up at the root
    // (particle 0) at 0.53 s and 0.45 s, and so does the Lanczos measurement (+3e-4); at 0.75,
    // with the reference omega_max scaled by 1 - 1e-4, 1, 1 + 3e-4 and 1 + 1e-3, it reaches
    // the end (0.659 s, 4000 reference steps) every time (docs/model.md, "Time step").
    let scene = small2d_variant(1e6, -0.5, "corrected", 100.0);
    let mut v = serde_json::to_value(scene).unwrap();
    v["bodies"][0]["velocity"] = serde_json::json!([0.0, -1.0]);
    v["bodies"][0]["material"]["law"] = "neo_hookean".into();
    let mut scene = mps_solid::Scene::from_json(&v.to_string()).unwrap();
    assert_eq!(scene.solver.safety, 0.8);
    scene.solver.safety = 0.75;
    let mut m = mps_solid::scene::Model::<2>::build(&scene).unwrap();
    let w = &mut m.world;
    let omega0 = w.omega_elastic();
    let t_end = 4000.0 * w.max_dt();
    w.advance_to(t_end).unwrap_or_else(|e| panic!("{e}"));
    eprintln!(
        "neo-Hookean thrown strip: t {:.3} s, omega {omega0:.4e} -> {:.4e}, {} refreshes in {} steps",
        w.time,
        w.omega_elastic(),
        w.step_refreshes,
        w.steps
    );
    // It did fold: the stiffest mode of the folded, crushed strip is 1.75 times the reference
    // one (measured); 1.4 says it is the same violent run and not a strip that stayed straight.
    assert!(w.omega_elastic() >= 1.4 * omega0);
    assert!(w.strain_energy().is_finite());
}

/// Largest eigenvalue of M^-1 K over the free translational degrees of freedom of a built
/// world, K assembled column by column from the operator's forces about the reference state
/// (central differences, `Linearised::stiffness_times`) and symmetrised, as omega (rad/s).
fn assembled_omega_max(w: &World<3>) -> f64 {
    use mps_solid::physics::particles::FIX_AXIS;
    use mps_solid::studies::linear::Linearised;
    let dofs: Vec<(usize, usize)> = (0..w.len())
        .flat_map(|i| (0..3).map(move |k| (i, k)))
        .filter(|&(i, k)| w.p.fix[i] & FIX_AXIS[k] == 0)
        .collect();
    let n = dofs.len();
    let mut lin = Linearised::new(w).unwrap();
    // M^-1/2 K M^-1/2: symmetric, with the eigenvalues of M^-1 K.
    let mut a = nalgebra::DMatrix::<f64>::zeros(n, n);
    let mut e = vec![Vect::<3>::zeros(); w.len()];
    for (c, &(i, k)) in dofs.iter().enumerate() {
        e[i][k] = 1.0;
        let col = lin.stiffness_times(&e);
        e[i][k] = 0.0;
        for (r, &(j, l)) in dofs.iter().enumerate() {
            a[(r, c)] = col[j][l] / (w.p.mass[i] * w.p.mass[j]).sqrt();
        }
    }
    let sym = (&a + a.transpose()) * 0.5;
    sym.symmetric_eigenvalues().max().sqrt()
}

#[test]
fn measured_omega_max_is_the_largest_eigenvalue_of_the_assembled_stiffness() {
    // The set-up measures omega_max by LANCZOS_ITERATIONS (20) force evaluations of the Lanczos
    // process, from below like any Ritz value; the margin OMEGA_MARGIN (3 %) covers that
    // shortfall and 1-2 % of stiffening in a deflected state. Here the shortfall must be at
    // most 0.5 % (the figure the margin was set for; 80 power iterations, before, left 0.42 %
    // on this scene with `corrected` and 0.77 % on the cylinder cantilever), and the value may
    // not exceed the assembled one beyond the finite differences' round-off (1e-6).
    use mps_solid::physics::world::OMEGA_MARGIN;
    use mps_solid::scene::{Model, Scene};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small3d.json");
    for model in [ElasticModel::Corrected, ElasticModel::SecondOrder] {
        let mut scene = Scene::load(&path).unwrap();
        scene.solver.model = model;
        let m = Model::<3>::build(&scene).unwrap();
        let exact = assembled_omega_max(&m.world);
        let measured = m.world.omega_elastic() / (1.0 + OMEGA_MARGIN);
        eprintln!(
            "{model:?}: measured {measured:.6e}, assembled {exact:.6e} rad/s ({:+.4} %)",
            (measured / exact - 1.0) * 100.0
        );
        assert!(
            measured <= exact * (1.0 + 1e-6) && measured >= exact * (1.0 - 5e-3),
            "{model:?}: measured {measured:.6e} rad/s against the assembled {exact:.6e}"
        );
    }
}

#[test]
fn settled_lanczos_measurement_keeps_the_full_measurement() {
    // The set-up's Lanczos process stops before LANCZOS_ITERATIONS (20) once its largest Ritz
    // value has grown by less than 1e-4 over 3 evaluations. Ritz values grow towards omega_max,
    // so the early value may not exceed the 20-evaluation one (beyond round-off, 1e-12), and
    // it may fall short of it by at most 0.01 % (measured: at most 0.004 % on 15 scenes; the
    // margin OMEGA_MARGIN is 3 %). A free cube of 12^3 particles settles early (a 40^3 cube
    // stops at 12), so the rule is exercised, not skipped.
    use mps_solid::physics::world::{LANCZOS_ITERATIONS, OMEGA_MARGIN};
    use mps_solid::scene::{Model, Scene};
    let scene: Scene = serde_json::from_str(
        r#"{"name": "cube12", "dimension": 3, "particle_spacing": 0.025,
            "bodies": [{"name": "cube", "material": {"density": 1000.0, "young": 1e8, "poisson": 0.25},
                        "boxes": [{"min": [0, 0, 0], "max": [0.3, 0.3, 0.3]}]}],
            "end_time": 1e-6, "output_interval": 1e-6}"#,
    )
    .unwrap();
    let m = Model::<3>::build(&scene).unwrap();
    let w = &m.world;
    let early = w.omega_elastic() / (1.0 + OMEGA_MARGIN);
    let full = w.lanczos_omega_max_from(LANCZOS_ITERATIONS, w.start_vector());
    eprintln!(
        "{} evaluations: {early:.9e} rad/s, 20 evaluations: {full:.9e} rad/s ({:+.5} %)",
        w.lanczos_evaluations,
        (early / full - 1.0) * 100.0
    );
    assert!(
        w.lanczos_evaluations < LANCZOS_ITERATIONS,
        "{} evaluations",
        w.lanczos_evaluations
    );
    assert!(early <= full * (1.0 + 1e-12) && early >= full * (1.0 - 1e-4));
}
