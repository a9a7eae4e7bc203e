//! Accuracy of the elastic operators in bending (issue 7), from the linearised model
//! (src/linear.rs: static deflection by conjugate gradients, first mode by inverse iteration),
//! against the converged FEM references of tools/fem_bending.py.
use mps_solid::bending::{free_free_plate_f1, linear_bending, plate2d_scene, plate_reference};
use mps_solid::physics::ElasticModel;

/// The free-free plate has no singular corner, so it shows the operator's own order: the
/// second-order operator is exact for quadratic fields (pure bending), so its error must fall
/// as dp^2 (observed 2.16; required >= 1.8), be below 0.5 % at 4 particles through the
/// thickness (measured 0.28 % from the Richardson limit), and there must be no zero-energy
/// mode below the flexural one (an hourglass mode would make f1 near zero).
#[test]
fn second_order_converges_at_second_order_on_the_free_free_plate() {
    let f: Vec<f64> = [4, 8, 16]
        .iter()
        .map(|&n| free_free_plate_f1(n, ElasticModel::SecondOrder).unwrap())
        .collect();
    let order = ((f[1] - f[0]) / (f[2] - f[1])).log2();
    let limit = f[2] + (f[2] - f[1]) / (2f64.powf(order) - 1.0);
    let err4 = (f[0] - limit).abs() / limit;
    assert!(order >= 1.8, "observed order {order:.2} (f = {f:?})");
    assert!(
        err4 < 5e-3,
        "error at 4 across {:.3} % (f = {f:?})",
        100.0 * err4
    );
    // Thin-plate value of the free-free first mode, (4.730^2 / 2 pi L^2) sqrt(E' I / rho A) =
    // 25.05 Hz: at L/H = 10 shear and rotary inertia lower it by about 4.6 % (first-order
    // Timoshenko correction (beta L)^2 (H/L)^2 / 24 (1 + E' / (kappa G))); the limit must be
    // 2-7 % below the thin-plate value.
    let drop = 1.0 - limit / 25.05;
    assert!(
        (0.02..0.07).contains(&drop),
        "limit {limit} Hz, {:.2} % below thin-plate",
        100.0 * drop
    );
}

/// The clamped GMS plate against the converged plane-strain FEM (issue 7 targets: 2 % at 4 and
/// 1 % at 8 particles through the thickness). The clamp layer samples the whole clamped face,
/// its edges included (src/bending.rs). Measured with the second-order operator: f1 -0.31 % /
/// -0.37 % and static tip deflection +0.61 % / +0.73 % at 4 / 8. The error left is the clamp's
/// slip, O(dp): the root acts as if 0.2 dp further back (examples/clamp_probe.rs shows it on an
/// axial bar whose exact field is quadratic), partly cancelled at 4 across by an error of the
/// opposite sign. The tolerances are those figures with a margin of about a fifth, well inside
/// the targets; before the clamp sampled the edges, the tip was +2.20 % / +1.19 %.
#[test]
fn clamped_plate_against_the_fem() {
    let r = plate_reference();
    for (n, tol_f, tol_tip) in [(4, 0.004, 0.0075), (8, 0.0045, 0.009)] {
        let b = linear_bending(&plate2d_scene(n, ElasticModel::SecondOrder)).unwrap();
        let ef = b.f1 / r.f1 - 1.0;
        let et = b.tip / r.tip - 1.0;
        assert!(
            ef.abs() < tol_f,
            "n = {n}: f1 {} Hz vs FEM {} ({:+.2} %)",
            b.f1,
            r.f1,
            100.0 * ef
        );
        assert!(
            et.abs() < tol_tip,
            "n = {n}: tip {} m vs FEM {} ({:+.2} %)",
            b.tip,
            r.tip,
            100.0 * et
        );
    }
}

/// The second-order forces are minus the gradient of its strain energy: for a random
/// deformation (strain ~ 1e-3, large enough for the geometric terms) of a 3D block in which one
/// particle lost most of its bonds (first-order fallback, degenerate span) and with a clamped
/// grip on one face, f . v = -dE/du . v by central differences to 1e-6 relative (the difference
/// quotient's truncation at eps = 1e-6 is ~1e-10; round-off of E ~1e-12).
#[test]
#[allow(clippy::needless_range_loop)]
fn second_order_forces_are_the_energy_gradient() {
    use mps_solid::physics::boundary::GravityLaw;
    use mps_solid::physics::world::GroupInit;
    use mps_solid::physics::{BodyInit, Material, SolverOptions, Vect, World};
    let l0 = 0.1;
    let mut pts = vec![];
    for i in 0..6 {
        for j in 0..5 {
            for k in 0..4 {
                pts.push(Vect::<3>::new(i as f64, j as f64, k as f64) * l0);
            }
        }
    }
    let clamp: Vec<u32> = (0..pts.len() as u32)
        .filter(|&i| pts[i as usize][0] < 0.5 * l0)
        .collect();
    let mut w = World::<3>::new(
        l0,
        SolverOptions {
            model: ElasticModel::SecondOrder,
            ..SolverOptions::default()
        },
        vec![BodyInit {
            name: "b".into(),
            material: Material {
                density: 1000.0,
                young: 1e7,
                poisson: 0.3,
            },
            points: pts.clone(),
            velocity: Vect::<3>::zeros().into(),
        }],
        vec![GroupInit {
            name: "clamp".into(),
            members: clamp,
            axes: [true; 3],
            fix_rotation: true,
        }],
        vec![],
        GravityLaw::Constant(Vect::<3>::zeros()),
    )
    .unwrap();
    // Break all bonds of particle 77 but those along x (a line: rank-1 span).
    let victim = 77usize;
    let mut touched = vec![victim];
    for b in w.bonds.of(victim) {
        let r0 = w.bonds.r0[b];
        if r0[1].abs() + r0[2].abs() > 1e-9 {
            let j = w.bonds.nbr[b] as usize;
            w.bonds.w0[b] = 0.0;
            let bm = w.op.second.mirror[b] as usize;
            w.bonds.w0[bm] = 0.0;
            touched.push(j);
        }
    }
    for &i in &touched {
        let n_ref = w.p.n_ref[i];
        w.op.refresh_particle(&w.bonds, i, n_ref);
    }
    assert!(!w.op.second.quadratic[victim] && !w.op.second.full[victim]);
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let base = w.state();
    let mut u = base.clone();
    let mut v: Vec<Vect<3>> = vec![Vect::<3>::zeros(); w.len()];
    for i in 0..w.len() {
        if w.p.fix[i] == 0 {
            u.u[i] = Vect::<3>::new(rnd(), rnd(), rnd()) * (2e-3 * l0);
            v[i] = Vect::<3>::new(rnd(), rnd(), rnd());
        }
    }
    w.set_state(&u).unwrap();
    let fv: f64 = (0..w.len()).map(|i| w.internal_force(i).dot(&v[i])).sum();
    let eps = 1e-6 * l0;
    let mut e = [0.0; 2];
    for (k, s) in [1.0, -1.0].iter().enumerate() {
        let mut st = u.clone();
        for i in 0..w.len() {
            st.u[i] += v[i] * (s * eps);
        }
        w.set_state(&st).unwrap();
        e[k] = w.strain_energy();
    }
    let de = (e[0] - e[1]) / (2.0 * eps);
    assert!(fv.abs() > 0.0);
    assert!(
        (fv + de).abs() <= 1e-6 * fv.abs(),
        "f.v = {fv:e}, -dE/du.v = {:e}",
        -de
    );
}
