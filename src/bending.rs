//! Bending benchmarks of issue 7 as scene builders with their references: the slender 3D
//! cantilever (L/h = 10) and the 2D oscillating plate of Gray, Monaghan & Swift (2001) in plane
//! strain, each with n particles through the thickness on one uniform lattice (the clamp is
//! `ceil(re/l0)` wall layers behind the clamped face x = 0), and their linearised first
//! frequency and static tip deflection (src/linear.rs) for the accuracy study.
use crate::linear::{field_at, Linearised};
use crate::physics::{ElasticModel, Material, SolverOptions, Vect};
use crate::scene::Model;
use crate::scene::{Body, Boundary, BoundaryKind, Gravity, Probe, Region, Scene, SceneError};

/// The slender cantilever: rho 1000 kg/m^3, E 100 MPa, nu 0.3.
pub const CANTILEVER_MATERIAL: Material = Material {
    density: 1000.0,
    young: 1.0e8,
    poisson: 0.3,
};
/// Cantilever length and section side (m).
pub const CANTILEVER_LENGTH: f64 = 1.0;
pub const CANTILEVER_SIDE: f64 = 0.1;

/// The GMS plate: rho 1000 kg/m^3, E 2 MPa, nu 0.3975.
pub const PLATE_MATERIAL: Material = Material {
    density: 1000.0,
    young: 2.0e6,
    poisson: 0.3975,
};
/// Plate length beyond the clamp and thickness (m).
pub const PLATE_LENGTH: f64 = 0.2;
pub const PLATE_THICKNESS: f64 = 0.02;

/// Gravity of the static reference (m/s^2).
pub const G: f64 = 9.81;

fn wall_layers(re_factor: f64) -> f64 {
    re_factor.ceil()
}

/// A clamped beam along x: material particles at the cell centres of x in [0, L] over the
/// section [-h/2, h/2] in the other directions (n cells across), and `ceil(re/l0)` clamped
/// layers at x = 0, -l0, -2 l0, the first on the clamped face. The clamp layers sit on the
/// cell vertices across the section (n + 1 rows, from -h/2 to h/2): the face layer samples the
/// whole clamped face, its edges included, where the FEM reference holds u = 0. A face layer at
/// the cell centres (n rows, as in case 2) leaves the outer half cell of the face, where the
/// bending stress is largest, unclamped: 1.8x the tip error at 4 across (2.2 % against 0.6 % on
/// the plate with `second_order`; docs/model.md).
#[allow(clippy::too_many_arguments)]
fn beam_scene(
    name: &str,
    description: String,
    dim: usize,
    n_across: usize,
    length: f64,
    side: f64,
    material: Material,
    model: ElasticModel,
) -> Scene {
    let dp = side / n_across as f64;
    let opts = SolverOptions {
        model,
        ..SolverOptions::default()
    };
    let walls = wall_layers(opts.re_factor);
    let h = 0.5 * side;
    // transverse half extent e: h for the material, h + dp/2 for the clamp (vertex rows)
    let lo = |x: f64, e: f64| {
        let mut v = vec![x, -e];
        if dim == 3 {
            v.push(-e);
        }
        v
    };
    let hi = |x: f64, e: f64| {
        let mut v = vec![x, e];
        if dim == 3 {
            v.push(e);
        }
        v
    };
    let hv = h + 0.5 * dp;
    let mut tip = vec![length, 0.0];
    let mut g = vec![0.0, -G];
    if dim == 3 {
        tip.push(0.0);
        g = vec![0.0, 0.0, -G];
    }
    Scene {
        name: name.into(),
        description,
        dimension: dim,
        particle_spacing: dp,
        solver: opts,
        gravity: Gravity {
            vector: g,
            paper_ramp_period: None,
        },
        bodies: vec![Body {
            name: "beam".into(),
            material,
            boxes: vec![
                Region {
                    min: lo(0.0, h),
                    max: hi(length, h),
                },
                Region {
                    min: lo(-(walls - 0.5) * dp, hv),
                    max: hi(0.5 * dp, hv),
                },
            ],
            velocity: None,
        }],
        boundaries: vec![Boundary {
            name: "clamp".into(),
            kind: BoundaryKind::Clamped,
            body: "beam".into(),
            region: Region {
                min: lo(-(walls - 0.5) * dp, hv),
                max: hi(0.25 * dp, hv),
            },
            axes: None,
        }],
        loads: vec![],
        probes: vec![Probe {
            name: "tip".into(),
            point: tip,
            body: None,
        }],
        end_time: 1.0,
        output_interval: 1e-3,
        analysis: Some(crate::scene::Analysis {
            probe: "tip".into(),
            component: if dim == 3 { "z".into() } else { "y".into() },
        }),
    }
}

/// The slender 3D cantilever with `n` particles across its 0.1 m square section.
pub fn cantilever3d_scene(n: usize, model: ElasticModel) -> Scene {
    beam_scene(
        "cantilever3d",
        format!(
            "Slender 3D cantilever (issue 7): L = 1 m beyond the clamp, 0.1 x 0.1 m section ({n} particles across), \
            rho 1000, E 100 MPa, nu 0.3, clamped by a particle layer on the face x = 0 (n + 1 rows each way, edges included) and 2 wall layers behind it, gravity -z applied suddenly. \
            Reference: reference/cantilever3d_fem.json. Probe: the tip on the axis (x = L)."
        ),
        3,
        n,
        CANTILEVER_LENGTH,
        CANTILEVER_SIDE,
        CANTILEVER_MATERIAL,
        model,
    )
}

/// The GMS oscillating plate (plane strain) with `n` particles through its 0.02 m thickness.
pub fn plate2d_scene(n: usize, model: ElasticModel) -> Scene {
    beam_scene(
        "plate2d",
        format!(
            "Oscillating plate of Gray, Monaghan & Swift (2001), plane strain (issue 7): L = 0.2 m beyond the clamp, \
            H = 0.02 m ({n} particles through the thickness), rho 1000, E 2 MPa, nu 0.3975, clamped by a particle layer on x = 0 (n + 1 rows, edges included) and 2 wall layers behind it. Reference: reference/plate2d_fem.json. Probe: the tip on the axis (x = L)."
        ),
        2,
        n,
        PLATE_LENGTH,
        PLATE_THICKNESS,
        PLATE_MATERIAL,
        model,
    )
}

/// First frequency and static tip deflection of a scene's linearisation.
#[derive(Clone, Debug)]
pub struct LinearBending {
    pub particles: usize,
    /// First frequency (Hz).
    pub f1: f64,
    /// Static tip deflection along the gravity component of the scene's analysis (m).
    pub tip: f64,
    /// Stiffness products taken (each two force evaluations).
    pub products: u64,
    /// Wall time (s).
    pub wall: f64,
}

/// Linearised first frequency and static tip deflection under the scene's gravity.
pub fn linear_bending(scene: &Scene) -> Result<LinearBending, SceneError> {
    let t0 = std::time::Instant::now();
    let e = |m: String| SceneError {
        field: String::new(),
        message: m,
    };
    macro_rules! run {
        ($d:literal) => {{
            let mut model = Model::<$d>::build(scene)?;
            let g = Vect::<$d>::from_fn(|k, _| scene.gravity.vector[k]);
            let comp = $d - 1;
            let tip_point = model.probes[0].point;
            let (u, w1, products) = {
                let mut lin = Linearised::new(&model.world).map_err(|x| e(x.to_string()))?;
                let u = lin.static_gravity(g, 1e-10).map_err(|x| e(x.to_string()))?;
                let (w1, _) = lin.lowest_mode(&u, 1e-10).map_err(|x| e(x.to_string()))?;
                (u, w1, lin.products)
            };
            let tip = field_at(&mut model.world, &u, &tip_point, None)
                .map_err(|x| e(x.to_string()))?[comp];
            LinearBending {
                particles: model.world.len(),
                f1: w1 / (2.0 * std::f64::consts::PI),
                tip,
                products,
                wall: t0.elapsed().as_secs_f64(),
            }
        }};
    }
    Ok(match scene.dimension {
        2 => run!(2),
        _ => run!(3),
    })
}

/// First flexural frequency (Hz) of the plate of `plate2d_scene` without its clamp (free-free:
/// no singular corner, so the operator's own order of convergence shows), by shifted inverse
/// iteration with the three rigid motions projected out. A zero-energy (hourglass) mode would
/// come out as a frequency near zero.
#[allow(clippy::needless_range_loop)]
pub fn free_free_plate_f1(n: usize, model: ElasticModel) -> Result<f64, SceneError> {
    let e = |m: String| SceneError {
        field: String::new(),
        message: m,
    };
    let mut s = plate2d_scene(n, model);
    s.boundaries.clear();
    s.bodies[0].boxes.truncate(1);
    s.probes[0].point = vec![0.1, 0.0];
    let model = Model::<2>::build(&s)?;
    let w = &model.world;
    let np = w.len();
    let m = &w.p.mass;
    let c: Vect<2> = w.p.x0.iter().sum::<Vect<2>>() / np as f64;
    let mut rig: Vec<Vec<Vect<2>>> = vec![
        vec![Vect::<2>::new(1.0, 0.0); np],
        vec![Vect::<2>::new(0.0, 1.0); np],
        w.p.x0
            .iter()
            .map(|x| Vect::<2>::new(-(x[1] - c[1]), x[0] - c[0]))
            .collect(),
    ];
    for k in 0..rig.len() {
        for l in 0..k {
            let d: f64 = (0..np).map(|i| m[i] * rig[k][i].dot(&rig[l][i])).sum();
            for i in 0..np {
                let t = rig[l][i] * d;
                rig[k][i] -= t;
            }
        }
        let nn: f64 = (0..np)
            .map(|i| m[i] * rig[k][i].norm_squared())
            .sum::<f64>()
            .sqrt();
        rig[k].iter_mut().for_each(|v| *v /= nn);
    }
    let mut lin = Linearised::new(w).map_err(|x| e(x.to_string()))?;
    lin.shift = (2.0 * std::f64::consts::PI * 5.0f64).powi(2);
    lin.deflate = rig;
    // Start: a bending-like shape.
    let start: Vec<Vect<2>> =
        w.p.x0
            .iter()
            .map(|x| Vect::<2>::new(0.0, ((x[0] - c[0]) / 0.1).powi(2) - 0.33))
            .collect();
    let (w1, _) = lin
        .lowest_mode(&start, 1e-11)
        .map_err(|x| e(x.to_string()))?;
    Ok(w1 / (2.0 * std::f64::consts::PI))
}

/// reference/plate2d_fem.json (converged plane-strain FEM, tools/fem_bending.py).
pub const PLATE_FEM_JSON: &str = include_str!("../reference/plate2d_fem.json");
/// reference/cantilever3d_fem.json (converged 3D FEM, tools/fem_bending.py).
pub const CANTILEVER_FEM_JSON: &str = include_str!("../reference/cantilever3d_fem.json");

/// Converged FEM first frequency (Hz) and static tip deflection under gravity G (m).
#[derive(Clone, Copy, Debug)]
pub struct BendingReference {
    pub f1: f64,
    pub tip: f64,
}

fn reference_from(json: &str, f_key: &str, tip_key: &str) -> BendingReference {
    let v: serde_json::Value = serde_json::from_str(json).expect("reference JSON");
    let c = &v["converged"];
    let get = |k: &str| {
        c[k].as_f64()
            .unwrap_or_else(|| panic!("reference lacks converged.{k}"))
    };
    BendingReference {
        f1: get(f_key),
        tip: get(tip_key),
    }
}

/// The GMS plate's FEM reference.
pub fn plate_reference() -> BendingReference {
    reference_from(PLATE_FEM_JSON, "f1_hz", "static_tip_uy_m")
}

/// The slender cantilever's FEM reference.
pub fn cantilever_reference() -> BendingReference {
    reference_from(
        CANTILEVER_FEM_JSON,
        "f1_bending_z_hz",
        "static_tip_uz_axis_m",
    )
}

/// The GMS benchmark as it is run in the SPH literature: the plate released from rest in its
/// first mode shape, v_y = V_f c0 f(x) / f(L), c0 = sqrt(E / (3 (1 - 2 nu) rho)), no gravity;
/// V_f = 0.001 keeps the amplitude at about 1 % of L, so the linear FEM frequency applies
/// (the literature's V_f = 0.05 is a large-amplitude case). Six periods.
pub fn gms_plate_scene(n: usize, model: ElasticModel) -> Scene {
    use crate::scene::{BodyVelocity, ModeShape, ModeShapeProfile, VelocityField, VelocityProfile};
    let mut s = plate2d_scene(n, model);
    let m = PLATE_MATERIAL;
    let c0 = (m.young / (3.0 * (1.0 - 2.0 * m.poisson) * m.density)).sqrt();
    s.name = "plate2d_gms".into();
    s.description = format!(
        "{} Released from rest in the first clamped-free mode shape (Gray, Monaghan & Swift 2001) with \
        v_y(L) = V_f c0, V_f = 0.001, c0 = {c0:.4} m/s; no gravity; six periods of the FEM first mode (a two-period fit is biased by 0.7 % by the higher modes the EB shape excites).",
        s.description
    );
    s.gravity.vector = vec![0.0, 0.0];
    s.bodies[0].velocity = Some(BodyVelocity::Field(VelocityField {
        linear: None,
        angular: None,
        profiles: vec![VelocityProfile::ModeShape(ModeShapeProfile {
            shape: ModeShape::ClampedFree1,
            axis: "x".into(),
            component: "y".into(),
            x0: 0.0,
            length: PLATE_LENGTH,
            amplitude: 0.001 * c0,
        })],
    }));
    s.end_time = 1.53;
    s
}

/// The benchmark scene files of scenes/ (issue 7): the GMS plate release and the slender
/// cantilever under sudden gravity, at 4 particles through the thickness with the second-order
/// operator.
pub fn benchmark_scenes() -> Vec<Scene> {
    vec![
        gms_plate_scene(4, ElasticModel::SecondOrder),
        cantilever3d_scene(4, ElasticModel::SecondOrder),
    ]
}

/// One load level of the large-deflection reference (reference/cantilever3d_fem.json, key
/// "elastica"): the inextensible, shear-free elastica of the cantilever under a dead load
/// q = rho g b h (gravity keeps its direction -z and its magnitude per undeformed length).
#[derive(Clone, Copy, Debug)]
pub struct ElasticaLevel {
    /// Target tip deflection over L the level was chosen for (-).
    pub target: f64,
    /// Gravity magnitude (m/s^2).
    pub g: f64,
    /// Tip displacement of the plain elastica (m).
    pub uz: f64,
    pub ux: f64,
    /// The elastica times the linear 3D FEM / Euler-Bernoulli tip ratio (1.0014, the shear and
    /// 3D share of the linear solution): the primary reference for a 3D solid (m).
    pub uz_fem: f64,
    pub ux_fem: f64,
}

/// The three levels (30 / 45 / 60 % of L) of the elastica reference.
pub fn elastica_reference() -> Vec<ElasticaLevel> {
    let v: serde_json::Value = serde_json::from_str(CANTILEVER_FEM_JSON).expect("reference JSON");
    let levels = v["elastica"]["levels"]
        .as_array()
        .expect("reference lacks elastica.levels");
    levels
        .iter()
        .map(|l| {
            let get = |k: &str| {
                l[k].as_f64()
                    .unwrap_or_else(|| panic!("elastica level lacks {k}"))
            };
            ElasticaLevel {
                target: get("target_tip_deflection_over_L"),
                g: get("g_m_s2"),
                uz: get("elastica_tip_uz_m"),
                ux: get("elastica_tip_ux_m"),
                uz_fem: get("elastica_x_fem_over_eb_tip_uz_m"),
                ux_fem: get("elastica_x_fem_over_eb_tip_ux_m"),
            }
        })
        .collect()
}

/// Settings of the dynamic relaxation of [`elastica_static`].
#[derive(Clone, Copy, Debug)]
pub struct RelaxOptions {
    /// First bending frequency used to scale damping, ramp and tolerance (Hz); the converged
    /// linear FEM value 5.091 Hz by default.
    pub f1: f64,
    /// Mass-proportional damping as a fraction of critical for the first mode at small load:
    /// c = 2 zeta (2 pi f1) (1/s). 1.0 settled faster than 0.8 at 30 % and 60 % (second_order,
    /// 4 across: 15,750 against 23,050 steps and 18,600 against 23,000), with the same tip to
    /// 3e-5 relative.
    pub zeta: f64,
    /// Gravity ramp length in first periods: g(t) = g (1 - cos(pi t / T)) / 2 for t < T.
    pub ramp_periods: f64,
    /// Converged when, after the ramp, the tip speed and the mass-weighted RMS speed
    /// sqrt(2 KE / M) are both below tol L f1 (-).
    pub tol: f64,
    /// Give up (not converged) after this many first periods of simulated time.
    pub max_periods: f64,
}

impl Default for RelaxOptions {
    fn default() -> Self {
        RelaxOptions {
            f1: 5.091,
            zeta: 1.0,
            ramp_periods: 0.5,
            tol: 1e-6,
            max_periods: 20.0,
        }
    }
}

/// Result of [`elastica_static`].
#[derive(Clone, Debug)]
pub struct ElasticaResult {
    pub particles: usize,
    /// Gravity magnitude (m/s^2).
    pub g: f64,
    /// Tip displacement at the probe (L, 0, 0) (m).
    pub ux: f64,
    pub uz: f64,
    /// Tip speed and RMS speed at the end (m/s).
    pub tip_speed: f64,
    pub rms_speed: f64,
    /// Steps taken, simulated time (s), wall time (s), last step (s), damping c (1/s).
    pub steps: u64,
    pub time: f64,
    pub wall: f64,
    pub dt: f64,
    pub damping: f64,
    /// The velocity tolerance was reached.
    pub converged: bool,
    /// The step failed (blow-up, overlap): its message. The displacements are then those of the
    /// last good step.
    pub failure: Option<String>,
}

/// Nonlinear static equilibrium of the slender cantilever (`cantilever3d_scene(n, model)`)
/// under gravity `g` (m/s^2, along -z) by dynamic relaxation: gravity ramped smoothly over
/// `ramp_periods` first periods, mass-proportional damping `c = 2 zeta omega1`, explicit steps
/// at the solver's stable step until the velocity tolerance holds. The damping force `-c m v`
/// vanishes at rest, so the state it settles to is the undamped equilibrium.
pub fn elastica_static(
    n: usize,
    model: ElasticModel,
    g: f64,
    opt: &RelaxOptions,
) -> Result<ElasticaResult, SceneError> {
    use crate::physics::boundary::GravityLaw;
    let wall0 = std::time::Instant::now();
    let omega1 = 2.0 * std::f64::consts::PI * opt.f1;
    let period = 1.0 / opt.f1;
    let mut s = cantilever3d_scene(n, model);
    s.solver.damping = 2.0 * opt.zeta * omega1;
    s.gravity.vector = vec![0.0, 0.0, -g];
    let mut m = Model::<3>::build(&s)?;
    let t_ramp = opt.ramp_periods * period;
    let t_max = opt.max_periods * period;
    let tol = opt.tol * CANTILEVER_LENGTH * opt.f1;
    let total_mass: f64 = m.world.p.mass.iter().sum();
    let full = Vect::<3>::new(0.0, 0.0, -g);
    let mut failure = None;
    let mut converged = false;
    let (mut tip_speed, mut rms_speed) = (f64::INFINITY, f64::INFINITY);
    let mut dt = m.world.max_dt();
    while m.world.time < t_max {
        let t = m.world.time;
        let f = if t < t_ramp {
            0.5 - 0.5 * (std::f64::consts::PI * t / t_ramp).cos()
        } else {
            1.0
        };
        m.world.set_gravity(GravityLaw::Constant(full * f));
        dt = m.world.max_dt();
        if let Err(e) = m.world.step(dt) {
            failure = Some(e.to_string());
            break;
        }
        if m.world.steps % 50 == 0 && m.world.time >= t_ramp {
            tip_speed = m.probe_velocity(0).norm();
            rms_speed = (2.0 * m.world.kinetic_energy() / total_mass).sqrt();
            if !(tip_speed.is_finite() && rms_speed.is_finite()) {
                failure = Some("non-finite velocity".into());
                break;
            }
            if tip_speed < tol && rms_speed < tol {
                converged = true;
                break;
            }
        }
    }
    let u = m.probe_displacement(0);
    Ok(ElasticaResult {
        particles: m.world.len(),
        g,
        ux: u[0],
        uz: u[2],
        tip_speed,
        rms_speed,
        steps: m.world.steps,
        time: m.world.time,
        wall: wall0.elapsed().as_secs_f64(),
        dt,
        damping: s.solver.damping,
        converged,
        failure,
    })
}
