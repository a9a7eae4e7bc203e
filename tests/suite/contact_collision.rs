//! Contact between bodies (section 2.5): two cubes meeting head-on do not interpenetrate,
//! conserve momentum to round-off and separate; the contact search runs only when needed and is
//! rebuilt only as motion requires; an overlap stops the run with a clear error, never NaN;
//! results do not depend on the thread count.
use mps_solid::physics::{
    ContactOptions, ElasticModel, Material, MaterialLaw, SolverOptions, World,
};
use mps_solid::scene::{Body, Boundary, BoundaryKind, Gravity, Region, Scene};
use mps_solid::Simulation;

const L0: f64 = 0.05;
const SOFT: Material = Material {
    density: 1000.0,
    young: 1.0e6,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};

fn cube(name: &str, min: [f64; 3], side: f64, v: [f64; 3]) -> Body {
    Body {
        name: name.into(),
        material: SOFT,
        boxes: vec![Region {
            min: min.to_vec(),
            max: min.iter().map(|m| m + side).collect(),
        }],
        velocity: Some(mps_solid::scene::BodyVelocity::Uniform(v.to_vec())),
        shapes: vec![],
        cuts: vec![],
    }
}

fn scene(bodies: Vec<Body>, solver: SolverOptions) -> Scene {
    Scene {
        name: "contact_test".into(),
        description: String::new(),
        dimension: 3,
        particle_spacing: L0,
        solver,
        gravity: Gravity::default(),
        bodies,
        boundaries: vec![],
        loads: vec![],
        probes: vec![],
        end_time: 1.0,
        output_interval: 0.01,
        analysis: None,
        base_dir: None,
    }
}

/// Two 5 x 5 x 5 cubes, 0.1 m apart, closing at 2 v (m/s) along x; the second is shifted by
/// `offset` (m) across the axis.
fn head_on(v: f64, offset: [f64; 2], solver: SolverOptions) -> Scene {
    let s = 5.0 * L0;
    scene(
        vec![
            cube("left", [-s - 0.05, 0.0, 0.0], s, [v, 0.0, 0.0]),
            cube("right", [0.05, offset[0], offset[1]], s, [-v, 0.0, 0.0]),
        ],
        solver,
    )
}

fn world(sim: &Simulation) -> &World<3> {
    match sim {
        Simulation::D3(m) => &m.world,
        _ => unreachable!(),
    }
}

/// Closest distance between particles of different bodies (brute force) (m).
fn closest(w: &World<3>) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..w.len() {
        for j in i + 1..w.len() {
            if w.p.body[i] != w.p.body[j] {
                best = best.min((w.p.x[j] - w.p.x[i]).norm());
            }
        }
    }
    best
}

fn centre_velocity(w: &World<3>, body: u32) -> f64 {
    let ids: Vec<usize> = (0..w.len()).filter(|&i| w.p.body[i] == body).collect();
    ids.iter().map(|&i| w.p.v[i].x).sum::<f64>() / ids.len() as f64
}

#[test]
#[ignore = "slow (7 s on a loaded 2-core machine): the full test command runs it"]
fn cubes_meeting_head_on_repel_conserve_momentum_and_separate() {
    // Closing speed 4 m/s (2 m/s each), about 5 % of the P-wave speed of the cubes (37 m/s):
    // a hard hit. Contact starts at t = 0.1 / 4 = 0.025 s. Checked every 0.5 ms: the closest
    // distance between the bodies stays above 0.75 l0 (the overlap limit is 0.5 l0), the total
    // momentum stays at round-off (the pair forces are equal and opposite), the total energy
    // (kinetic + strain + contact, with the velocities half a step off the positions as
    // symplectic Euler has them) stays within 25 % during the hit (the contact oscillation runs
    // at omega dt ~ 1 at the automatic step, so the measured energy swings; it has no drift) and
    // within 6 % once the cubes are apart, and after the hit the cubes move apart with no pair
    // in contact.
    for offset in [[0.0, 0.0], [0.5 * L0, 0.5 * L0]] {
        let mut sim = Simulation::new(&head_on(2.0, offset, SolverOptions::default())).unwrap();
        let p_scale = 2.0 * 125.0 * 1000.0 * L0.powi(3) * 2.0;
        let e0 = sim.kinetic_energy();
        let mut min_d = f64::INFINITY;
        let mut touched = false;
        let mut max_pairs = 0;
        for k in 1..=400 {
            sim.advance_to(k as f64 * 5e-4).unwrap();
            let w = world(&sim);
            min_d = min_d.min(closest(w));
            let p = w.momentum();
            assert!(
                p.norm() < 1e-12 * p_scale,
                "offset {offset:?}: momentum {p:?} at t = {}",
                sim.time()
            );
            let e = sim.kinetic_energy() + sim.strain_energy() + sim.contact_energy();
            assert!(
                (e - e0).abs() < 0.25 * e0,
                "offset {offset:?}: energy {e} vs {e0} at t = {}",
                sim.time()
            );
            touched |= sim.contact_pairs() > 0;
            max_pairs = max_pairs.max(sim.contact_pairs());
        }
        let w = world(&sim);
        assert!(touched, "the cubes never touched");
        assert!(
            min_d > 0.75 * L0,
            "offset {offset:?}: closest distance {min_d} m = {} l0",
            min_d / L0
        );
        assert_eq!(sim.contact_pairs(), 0, "still in contact at the end");
        let e = sim.kinetic_energy() + sim.strain_energy();
        assert!((e - e0).abs() < 0.06 * e0, "energy {e} vs {e0} at the end");
        assert!(closest(w) > 2.0 * L0, "not apart: {}", closest(w));
        let (vl, vr) = (centre_velocity(w, 0), centre_velocity(w, 1));
        assert!(vl < -0.5 && vr > 0.5, "not separating: {vl} {vr}");
        assert!(max_pairs >= 25, "{max_pairs} pairs at most");
        assert_eq!(sim.broken_bonds(), 0);
        assert_eq!(sim.fracture_checks(), 0, "eps_max infinite: no checks");
    }
}

#[test]
fn contact_search_runs_only_when_needed() {
    // One body, fracture off: no contact search at all, no fracture checks.
    let one = scene(
        vec![cube("a", [0.0; 3], 5.0 * L0, [1.0, 0.0, 0.0])],
        SolverOptions::default(),
    );
    let mut sim = Simulation::new(&one).unwrap();
    sim.advance_to(0.02).unwrap();
    assert!(sim.steps() > 10);
    assert_eq!(sim.contact_searches(), 0);
    assert_eq!(sim.fracture_checks(), 0);
    // Two bodies at rest, far apart: one search at the start, never again (nothing moves).
    let two = scene(
        vec![
            cube("a", [0.0; 3], 5.0 * L0, [0.0; 3]),
            cube("b", [1.0, 0.0, 0.0], 5.0 * L0, [0.0; 3]),
        ],
        SolverOptions::default(),
    );
    let mut sim = Simulation::new(&two).unwrap();
    sim.advance_to(0.02).unwrap();
    assert_eq!(sim.contact_searches(), 1);
    // Two bodies moving at 2 m/s: the list is rebuilt when a particle has moved half the skin
    // (0.25 l0 = 12.5 mm, every ~6 ms, ~12 steps), not every step.
    let mut sim = Simulation::new(&head_on(2.0, [0.0; 2], SolverOptions::default())).unwrap();
    sim.advance_to(0.02).unwrap();
    let (steps, searches) = (sim.steps(), sim.contact_searches());
    assert!(
        searches >= 2 && searches * 5 < steps,
        "{searches} searches in {steps} steps"
    );
    // Contact disabled: no search even with two bodies.
    let off = SolverOptions {
        contact: ContactOptions {
            enabled: false,
            ..ContactOptions::default()
        },
        ..SolverOptions::default()
    };
    let mut sim = Simulation::new(&head_on(2.0, [0.0; 2], off)).unwrap();
    sim.advance_to(0.02).unwrap();
    assert_eq!(sim.contact_searches(), 0);
    // One body with fracture on: fracture checks every step, and a search (fractured surfaces).
    let frac = SolverOptions {
        fracture_strain: Some(0.2),
        ..SolverOptions::default()
    };
    let mut sim = Simulation::new(&scene(
        vec![cube("a", [0.0; 3], 5.0 * L0, [1.0, 0.0, 0.0])],
        frac,
    ))
    .unwrap();
    sim.advance_to(0.02).unwrap();
    assert_eq!(sim.fracture_checks(), sim.steps());
    assert!(sim.contact_searches() >= 1);
}

#[test]
fn contact_enters_the_stable_step_while_bodies_touch() {
    // Contact adds to omega_max^2 only while pairs are in contact, and then Gershgorin's bound
    // over those pairs: max_i min(n_i, max_partners) k_c (1/m_i + 1/sqrt(m_i m_j)), n_i the
    // partners of particle i closer than l0, recomputed here by brute force over all pairs. The
    // cubes of `head_on` start 0.1 m apart and close at 4 m/s, so they touch from t = 0.025 s
    // and are apart well before 0.2 s (see the test above). Both are SOFT: k_c = 2 d 2 mu l0^d
    // / l0^2.
    let one = scene(
        vec![cube("a", [0.0; 3], 5.0 * L0, [0.0; 3])],
        SolverOptions::default(),
    );
    let w1 = Simulation::new(&one).unwrap();
    let a = world(&w1);
    assert_eq!(a.omega_max(), a.omega_elastic());
    // Faces aligned (one partner per particle), then offset by half a spacing in y and z (four
    // partners at an angle, counted as `max_partners`).
    for offset in [[0.0; 2], [0.5 * L0, 0.5 * L0]] {
        let mut w2 = Simulation::new(&head_on(2.0, offset, SolverOptions::default())).unwrap();
        let b = world(&w2);
        // Apart at the start: the elastic step, the same cubes' as one alone (to the Lanczos
        // measurement's convergence, whose start vector differs with the particle count: 1e-3).
        assert_eq!(b.omega_max(), b.omega_elastic());
        assert!((w2.max_dt() / w1.max_dt() - 1.0).abs() < 1e-3);
        let mu = SOFT.young / (2.0 * (1.0 + SOFT.poisson));
        let kc = 2.0 * 3.0 * 2.0 * mu * L0.powi(3) / (L0 * L0);
        let max_partners = ContactOptions::default().max_partners;
        let (mut during, mut apart_after, mut two_partners) = (0, 0, 0);
        for k in 1..=400 {
            w2.advance_to(k as f64 * 5e-4).unwrap();
            let b = world(&w2);
            // Per particle: its partners, and the largest k_c (1/m_i + 1/sqrt(m_i m_j)) among them
            // (the closure's quadrature gives face particles less volume, so masses differ).
            let rows: Vec<(usize, f64)> = (0..b.len())
                .map(|i| {
                    let partners: Vec<usize> = (0..b.len())
                        .filter(|&j| b.p.body[j] != b.p.body[i])
                        .filter(|&j| (b.p.x[j] - b.p.x[i]).norm() < L0)
                        .collect();
                    let (mi, m) = (b.p.mass[i], &b.p.mass);
                    let stiffest = partners
                        .iter()
                        .map(|&j| kc * (1.0 / mi + 1.0 / (mi * m[j]).sqrt()))
                        .fold(0.0, f64::max);
                    (partners.len(), stiffest)
                })
                .collect();
            let most = rows.iter().map(|r| r.0).max().unwrap();
            let expected = rows
                .iter()
                .map(|&(n, k)| (n as f64).min(max_partners) * k)
                .fold(0.0, f64::max);
            let added = b.omega_max().powi(2) - b.omega_elastic().powi(2);
            assert!(
                (added - expected).abs() <= 1e-9 * (expected + b.omega_elastic().powi(2)),
                "t = {}: contact adds {added} rad^2/s^2, expected {expected} ({most} partners)",
                w2.time()
            );
            if most > 0 {
                during += 1;
                two_partners += usize::from(most >= 2);
            } else if during > 0 {
                apart_after += 1;
            }
        }
        assert!(during >= 5, "in contact at {during} of 400 instants");
        assert!(apart_after >= 5, "apart again at {apart_after} instants");
        eprintln!("offset {offset:?}: {during} instants in contact, {two_partners} with a particle of 2 or more partners");
        assert_eq!(two_partners > 0, offset[0] > 0.0, "offset {offset:?}");
    }
}

#[test]
fn a_fast_pair_first_touches_on_the_soft_ramp_of_the_contact_law() {
    // The cubes of `head_on` closing at 60 m/s: at the elastic step of the soft cubes (5.4e-4
    // s) a pair would close by 0.65 l0 in one step, past the contact law's soft onset
    // (`contact::ONSET` c) and near the overlap limit (0.5 c). The step is held to the one after
    // which no closing pair gets deeper than `APPROACH_DEPTH` c (half the onset band) within its
    // contact distance c = l0: the closest distance of the step in which the cubes first touch
    // must not be below (1 - APPROACH_DEPTH) l0 (before the touch no force acts, so the step's
    // velocities are the ones it was chosen with, and the bound is exact to round-off).
    use mps_solid::physics::contact::APPROACH_DEPTH;
    let mut sim = Simulation::new(&head_on(30.0, [0.0; 2], SolverOptions::default())).unwrap();
    let elastic = sim.max_dt();
    let w = match &mut sim {
        Simulation::D3(m) => &mut m.world,
        _ => unreachable!(),
    };
    assert!(
        60.0 * elastic > 0.5 * L0,
        "the test needs an elastic step that closes more than 0.5 l0 ({elastic} s)"
    );
    let mut shortest = f64::INFINITY;
    for step in 0..10_000 {
        let dt = w.max_dt();
        shortest = shortest.min(dt);
        w.step(dt).unwrap();
        let d = closest(w);
        if d < L0 {
            assert!(
                d >= (1.0 - APPROACH_DEPTH) * L0 * (1.0 - 1e-9),
                "first touch at step {step}: closest {} l0 after a step of {dt} s",
                d / L0
            );
            assert!(shortest < 0.5 * elastic, "{shortest} vs {elastic}");
            return;
        }
    }
    panic!("the cubes never touched");
}

#[test]
fn overlap_stops_the_run_with_a_clear_error_not_nan() {
    // Contact a million times too soft: the cubes run into each other and the solver must stop
    // with an overlap error naming the time and both bodies, with a finite state.
    let soft = SolverOptions {
        contact: ContactOptions {
            stiffness: 1e-6,
            ..ContactOptions::default()
        },
        ..SolverOptions::default()
    };
    let mut sim = Simulation::new(&head_on(2.0, [0.0; 2], soft)).unwrap();
    let err = sim.advance_to(0.2).expect_err("must overlap");
    let msg = err.to_string();
    assert!(msg.contains("overlap"), "{msg}");
    assert!(msg.contains("'left'") && msg.contains("'right'"), "{msg}");
    assert!(msg.contains("t = "), "{msg}");
    // Contact at 0.025 s; the overlap limit 0.5 l0 is crossed 0.025 l0 / 4 m/s ~ 0.3 ms later
    // (the elastic bodies slow a little, so allow a few ms).
    let t = sim.time();
    assert!(t > 0.025 && t < 0.035, "overlap at {t}");
    match err {
        mps_solid::physics::SimError::Overlap {
            time,
            bodies,
            distance,
            limit,
            ..
        } => {
            assert_eq!(time, t);
            assert_eq!(bodies, ["left".to_string(), "right".to_string()]);
            assert!(distance < limit && distance > 0.0);
        }
        e => panic!("wrong error {e:?}"),
    }
    let w = world(&sim);
    assert!(w.p.x.iter().all(|x| x.iter().all(|c| c.is_finite())));
    assert!(sim.kinetic_energy().is_finite() && sim.strain_energy().is_finite());
    // Without contact at all the bodies pass through each other silently.
    let off = SolverOptions {
        contact: ContactOptions {
            enabled: false,
            ..ContactOptions::default()
        },
        ..SolverOptions::default()
    };
    let mut sim = Simulation::new(&head_on(2.0, [0.0; 2], off)).unwrap();
    sim.advance_to(0.1).unwrap();
}

#[test]
fn bodies_overlapping_at_the_start_are_refused() {
    let s = 5.0 * L0;
    let sc = scene(
        vec![
            cube("a", [0.0; 3], s, [0.0; 3]),
            cube("b", [s - 0.6 * L0, 0.0, 0.0], s, [0.0; 3]),
        ],
        SolverOptions::default(),
    );
    let e = Simulation::new(&sc)
        .err()
        .expect("overlap at start")
        .to_string();
    assert!(e.contains("overlap"), "{e}");
}

#[test]
fn contact_and_fracture_do_not_depend_on_thread_count() {
    // A cube hits a clamped plate hard enough to break bonds (eps_max = 0.02), with contact
    // between fractured surfaces: bitwise the same trajectory with 1 and 2 threads.
    let run = |threads: usize, model: ElasticModel| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let solver = SolverOptions {
                model,
                fracture_strain: Some(0.02),
                ..SolverOptions::default()
            };
            let mut sc = scene(
                vec![
                    cube("cube", [0.1, 0.1, 0.05], 4.0 * L0, [0.0, 0.0, -6.0]),
                    Body {
                        name: "plate".into(),
                        material: SOFT,
                        boxes: vec![Region {
                            min: vec![0.0, 0.0, -0.1],
                            max: vec![0.4, 0.4, 0.0],
                        }],
                        velocity: None,
                        shapes: vec![],
                        cuts: vec![],
                    },
                ],
                solver,
            );
            sc.boundaries = vec![Boundary {
                name: "edge".into(),
                kind: BoundaryKind::Clamped,
                body: "plate".into(),
                region: Region {
                    min: vec![0.0, 0.0, -0.1],
                    max: vec![0.1, 0.4, 0.0],
                },
                axes: None,
                mirror: None,
                shape: None,
            }];
            let mut sim = Simulation::new(&sc).unwrap();
            sim.advance_to(0.04).unwrap();
            let w = world(&sim).p.x.clone();
            (
                w,
                sim.broken_bonds(),
                sim.kinetic_energy(),
                sim.contact_energy(),
                sim.fragments(),
            )
        })
    };
    for model in [ElasticModel::Corrected, ElasticModel::Paper] {
        let (a, b) = (run(1, model), run(2, model));
        assert!(a.1 > 0, "{model:?}: no bond broke");
        assert_eq!(a.1, b.1);
        assert_eq!(a.4, b.4);
        assert_eq!(a.2.to_bits(), b.2.to_bits());
        assert_eq!(a.3.to_bits(), b.3.to_bits());
        assert!(a.0.iter().zip(&b.0).all(|(p, q)| p
            .iter()
            .zip(q.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits())));
    }
}
