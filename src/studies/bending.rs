//! Bending benchmarks of issue 7 as scene builders with their references: the slender 3D
//! cantilever (L/h = 10) and the 2D oscillating plate of Gray, Monaghan & Swift (2001) in plane
//! strain, each with n particles through the thickness on one uniform lattice (the clamp is
//! `ceil(re/l0)` wall layers behind the clamped face x = 0), and their linearised first
//! frequency and static tip deflection (src/studies/linear.rs) for the accuracy study.
use super::linear::{field_at, Linearised};
use crate::physics::particles::FIX_AXIS;
use crate::physics::{ElasticModel, Material, MaterialLaw, SolverOptions, Vect};
use crate::scene::Model;
use crate::scene::{
    Body, Boundary, BoundaryKind, Gravity, MirrorSpec, Probe, Region, Scene, SceneError,
};

/// The slender cantilever: rho 1000 kg/m^3, E 100 MPa, nu 0.3.
pub const CANTILEVER_MATERIAL: Material = Material {
    density: 1000.0,
    young: 1.0e8,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};
/// Cantilever length and section side (m).
pub const CANTILEVER_LENGTH: f64 = 1.0;
pub const CANTILEVER_SIDE: f64 = 0.1;

/// The GMS plate: rho 1000 kg/m^3, E 2 MPa, nu 0.3975.
pub const PLATE_MATERIAL: Material = Material {
    density: 1000.0,
    young: 2.0e6,
    poisson: 0.3975,
    law: MaterialLaw::SaintVenantKirchhoff,
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
    // The second-order model mirrors the beam across the clamped face: the clamp's layers at
    // the images -dp/2, -3 dp/2, -5 dp/2 of the beam's first three, over its section, none on
    // the face (docs/model.md, "Mirror faces"); the others hold the vertex-row grip.
    let mirror = model == ElasticModel::SecondOrder;
    let (clamp_box, clamp_region) = if mirror {
        (
            Region {
                min: lo(-walls * dp, h),
                max: hi(0.0, h),
            },
            Region {
                min: lo(-walls * dp, h),
                max: hi(-0.25 * dp, h),
            },
        )
    } else {
        (
            Region {
                min: lo(-(walls - 0.5) * dp, hv),
                max: hi(0.5 * dp, hv),
            },
            Region {
                min: lo(-(walls - 0.5) * dp, hv),
                max: hi(0.25 * dp, hv),
            },
        )
    };
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
                clamp_box,
            ],
            velocity: None,
            shapes: vec![],
            cuts: vec![],
        }],
        boundaries: vec![Boundary {
            name: "clamp".into(),
            kind: BoundaryKind::Clamped,
            body: "beam".into(),
            region: clamp_region,
            axes: None,
            mirror: mirror.then(|| MirrorSpec {
                point: vec![0.0; dim],
                normal: {
                    let mut n = vec![0.0; dim];
                    n[0] = -1.0;
                    n
                },
            }),
            shape: None,
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
        base_dir: None,
    }
}

/// How `beam_scene` clamps the beam for `model`, for the scene description.
fn clamp_text(model: ElasticModel) -> &'static str {
    if model == ElasticModel::SecondOrder {
        "clamped by mirroring the beam across the face x = 0 (3 layers at the images of the beam's first three, none on the face)"
    } else {
        "clamped by a particle layer on the face x = 0 (n + 1 rows across, edges included) and 2 wall layers behind it"
    }
}

/// The slender 3D cantilever with `n` particles across its 0.1 m square section.
pub fn cantilever3d_scene(n: usize, model: ElasticModel) -> Scene {
    beam_scene(
        "cantilever3d",
        format!(
            "Slender 3D cantilever (issue 7): L = 1 m beyond the clamp, 0.1 x 0.1 m section ({n} particles across), \
            rho 1000, E 100 MPa, nu 0.3, {}, gravity -z applied suddenly. \
            Reference: reference/cantilever3d_fem.json. Probe: the tip on the axis (x = L).",
            clamp_text(model)
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
            H = 0.02 m ({n} particles through the thickness), rho 1000, E 2 MPa, nu 0.3975, {}. Reference: reference/plate2d_fem.json. Probe: the tip on the axis (x = L).",
            clamp_text(model)
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
    /// The scene's warnings (field: message).
    pub warnings: Vec<String>,
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
                warnings: model
                    .warnings
                    .iter()
                    .map(|w| format!("{}: {}", w.field, w.message))
                    .collect(),
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
pub fn free_free_plate_f1(n: usize, model: ElasticModel) -> Result<f64, SceneError> {
    let mut s = plate2d_scene(n, model);
    s.boundaries.clear();
    s.bodies[0].boxes.truncate(1);
    s.probes[0].point = vec![0.1, 0.0];
    free_free_f1(&s)
}

/// The lowest flexural frequency (Hz) of a free 2D scene's body (no boundaries): inverse
/// iteration with the rigid motions deflated, from a bending-like start.
#[allow(clippy::needless_range_loop)]
pub fn free_free_f1(s: &Scene) -> Result<f64, SceneError> {
    let e = |m: String| SceneError {
        field: String::new(),
        message: m,
    };
    let model = Model::<2>::build(s)?;
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
pub const PLATE_FEM_JSON: &str = include_str!("../../reference/plate2d_fem.json");
/// reference/cantilever3d_fem.json (converged 3D FEM, tools/fem_bending.py).
pub const CANTILEVER_FEM_JSON: &str = include_str!("../../reference/cantilever3d_fem.json");

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

/// reference/cantilever3d_nonlinear_fem.json (finite-strain 3D FEM with the solver's laws,
/// tools/fem_large_deflection.py).
pub const CANTILEVER_NONLINEAR_FEM_JSON: &str =
    include_str!("../../reference/cantilever3d_nonlinear_fem.json");

/// Tip displacement on the axis of the finite-strain 3D FEM (Hex27, Newton, Richardson over the
/// meshes) of the cantilever under the dead load rho g, with the same strain energy law as the
/// particle model: the reference without the elastica's simplifications (linear
/// moment-curvature, inextensible, shear-free axis).
#[derive(Clone, Copy, Debug)]
pub struct NonlinearTip {
    /// Gravity magnitude (m/s^2).
    pub g: f64,
    /// Tip displacement along z and x (m).
    pub uz: f64,
    pub ux: f64,
}

/// The load levels of the finite-strain FEM reference for `law`: g = 9.81 and the three elastica
/// levels (216 / 361 / 580 m/s^2).
pub fn nonlinear_fem_reference(law: MaterialLaw) -> Vec<NonlinearTip> {
    let v: serde_json::Value =
        serde_json::from_str(CANTILEVER_NONLINEAR_FEM_JSON).expect("reference JSON");
    let levels = v["laws"][law.name()]["converged"]
        .as_array()
        .unwrap_or_else(|| panic!("nonlinear reference lacks law {}", law.name()));
    // the Richardson limit where the three finest meshes gave one, else the finest mesh
    let best = |c: &serde_json::Value| {
        c["richardson"]
            .as_f64()
            .or_else(|| c["finest"].as_f64())
            .expect("nonlinear reference lacks a tip value")
    };
    levels
        .iter()
        .map(|l| NonlinearTip {
            g: l["g_m_s2"].as_f64().expect("level lacks g_m_s2"),
            uz: best(&l["tip_uz_m"]),
            ux: best(&l["tip_ux_m"]),
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
    /// Strain energy law of the beam's material.
    pub law: MaterialLaw,
}

impl Default for RelaxOptions {
    fn default() -> Self {
        RelaxOptions {
            f1: 5.091,
            zeta: 1.0,
            ramp_periods: 0.5,
            tol: 1e-6,
            max_periods: 20.0,
            law: MaterialLaw::SaintVenantKirchhoff,
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
    s.bodies[0].material.law = opt.law;
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

/// How a torsion frequency was obtained ([`torsion_frequency`], [`torsion_frequency_time`]).
#[derive(Clone, Debug)]
pub struct TorsionInfo {
    /// "linear" (projected inverse iteration) or "time" (release and twist-angle period).
    pub method: &'static str,
    pub particles: usize,
    /// Stiffness products (linear: each two force evaluations) or time steps (time).
    pub work: u64,
    /// Inverse iterations (linear) or twist-angle periods timed (time).
    pub iterations: usize,
    /// Share of the mode's kinetic energy (its M-norm) in a rigid rotation of each cross
    /// section about the x axis (the rest is warping u_x and in-plane distortion). Linear only;
    /// NaN for the time method.
    pub rotation_fraction: f64,
    /// Eigen-residual |K y - w^2 M y| / |K y| of the last iterate (linear), or the relative
    /// spread of the single periods (time).
    pub residual: f64,
    /// |K v - P K v| / |K v| for the pure twist v in the class: how far the discrete operator
    /// is from the mirror symmetry the projection assumes (round-off: ~1e-15). Linear only.
    pub symmetry_defect: f64,
    /// CG iterations of each inverse iteration's solve (linear; empty for the time method).
    pub cg_iterations: Vec<usize>,
    /// Wall time (s).
    pub wall: f64,
}

/// The mirror maps y -> -y and z -> -z of a 3D beam's particles (index of the image), from the
/// reference positions on the half-spacing lattice; an error if a particle has no image.
pub fn mirror_maps(x0: &[Vect<3>], dp: f64) -> Result<[Vec<usize>; 3], SceneError> {
    use std::collections::HashMap;
    let key = |x: &Vect<3>| -> [i64; 3] { [0, 1, 2].map(|k| (x[k] / dp * 4.0).round() as i64) };
    let at: HashMap<[i64; 3], usize> = x0.iter().enumerate().map(|(i, x)| (key(x), i)).collect();
    if at.len() != x0.len() {
        return Err(SceneError {
            field: String::new(),
            message: "two particles share a lattice site".into(),
        });
    }
    let find = |flip: [bool; 3]| -> Result<Vec<usize>, SceneError> {
        x0.iter()
            .map(|x| {
                let mut k = key(x);
                for c in 0..3 {
                    if flip[c] {
                        k[c] = -k[c];
                    }
                }
                at.get(&k).copied().ok_or_else(|| SceneError {
                    field: String::new(),
                    message: format!("the lattice is not mirror symmetric: no image of {x:?}"),
                })
            })
            .collect()
    };
    Ok([
        find([false, true, false])?,
        find([false, false, true])?,
        find([false, true, true])?,
    ])
}

/// Projector onto the vector fields antisymmetric under both mirrors y -> -y and z -> -z (the
/// class of the torsion modes): with R_y v(p) = S_y v(M_y p) (S_y flips the y component) and
/// R_z alike, P = (1 - R_y)(1 - R_z) / 4 = (1 - R_y - R_z + R_y R_z) / 4.
pub fn project_torsion_class(maps: &[Vec<usize>; 3], v: &[Vect<3>]) -> Vec<Vect<3>> {
    let sy = Vect::<3>::new(1.0, -1.0, 1.0);
    let sz = Vect::<3>::new(1.0, 1.0, -1.0);
    let syz = Vect::<3>::new(1.0, -1.0, -1.0);
    (0..v.len())
        .map(|i| {
            (v[i] - v[maps[0][i]].component_mul(&sy) - v[maps[1][i]].component_mul(&sz)
                + v[maps[2][i]].component_mul(&syz))
                * 0.25
        })
        .collect()
}

/// The mass-weighted twist angle of each cross-section (particles binned by x on the half-
/// spacing lattice) of a displacement field, theta_s = sum m (y u_z - z u_y) / sum m (y^2 + z^2),
/// and the share of the field's M-norm^2 that these rigid section rotations carry.
fn section_twist(x0: &[Vect<3>], m: &[f64], u: &[Vect<3>], dp: f64) -> (Vec<(f64, f64)>, f64) {
    use std::collections::BTreeMap;
    let mut s: BTreeMap<i64, (f64, f64, f64)> = BTreeMap::new();
    let mut total = 0.0;
    for i in 0..x0.len() {
        let (y, z) = (x0[i][1], x0[i][2]);
        let e = s.entry((x0[i][0] / dp * 4.0).round() as i64).or_default();
        e.0 += m[i] * (y * u[i][2] - z * u[i][1]);
        e.1 += m[i] * (y * y + z * z);
        e.2 = x0[i][0];
        total += m[i] * u[i].norm_squared();
    }
    let mut rot = 0.0;
    let theta: Vec<(f64, f64)> = s
        .values()
        .filter(|e| e.1 > 0.0)
        .map(|&(a, b, x)| {
            rot += a * a / b;
            (x, a / b)
        })
        .collect();
    (theta, if total > 0.0 { rot / total } else { 0.0 })
}

/// Relative CG residual of the solves of [`torsion_frequency`]. The error it leaves in
/// y = K^-1 M x along a mode k other than the first is |r_k| / lambda_k <= tol |M x| / lambda_2,
/// i.e. at most tol lambda_1 / lambda_2 (~tol / 9 for the second torsion mode) relative to y,
/// and the Rayleigh quotient's error is of its square: 1e-6 leaves ~1e-12 in f.
const CG_TOL: f64 = 1e-6;

/// The first torsion frequency (Hz) of a 3D beam scene along x whose lattice and clamp are
/// symmetric under the mirrors y -> -y and z -> -z (`cantilever3d_scene`), from its
/// linearisation (src/studies/linear.rs): inverse iteration x <- K^-1 M x (K by conjugate gradients,
/// SPD with the clamp) with the iterate projected every iteration onto the fields
/// antisymmetric under both mirrors. The lowest mode of that class is the first torsion mode
/// (the bending pairs and the axial mode are symmetric under at least one mirror); the start is
/// the pure twist u = theta(x) (0, -z, y), theta = x / L. The Rayleigh quotient is y^T K y /
/// y^T M y with one extra product, so it is quadratic in the iterate's error whatever the CG
/// tolerance (`CG_TOL`); each solve starts from x / w^2 of the last iterate; stops when it changes by less than 1e-9 (relative) between iterations. The
/// scene's gravity plays no part.
pub fn torsion_frequency(scene: &Scene) -> Result<(f64, TorsionInfo), SceneError> {
    torsion_frequency_with(scene, CG_TOL)
}

/// [`torsion_frequency`] with the relative CG residual `cg_tol` of its solves.
pub fn torsion_frequency_with(
    scene: &Scene,
    cg_tol: f64,
) -> Result<(f64, TorsionInfo), SceneError> {
    let t0 = std::time::Instant::now();
    let e = |m: String| SceneError {
        field: String::new(),
        message: m,
    };
    if scene.dimension != 3 {
        return Err(e("torsion_frequency needs a 3D scene".into()));
    }
    let model = Model::<3>::build(scene)?;
    let w = &model.world;
    let n = w.len();
    let m = &w.p.mass;
    let x0 = &w.p.x0;
    let maps = mirror_maps(x0, scene.particle_spacing)?;
    let free = |v: &mut [Vect<3>]| {
        for (i, vi) in v.iter_mut().enumerate() {
            for k in 0..3 {
                if w.p.fix[i] & FIX_AXIS[k] != 0 {
                    vi[k] = 0.0;
                }
            }
        }
    };
    let length = x0.iter().map(|x| x[0]).fold(f64::MIN, f64::max);
    let mut x: Vec<Vect<3>> = x0
        .iter()
        .map(|p| Vect::<3>::new(0.0, -p[2], p[1]) * (p[0].max(0.0) / length))
        .collect();
    free(&mut x);
    let mut lin = Linearised::new(w).map_err(|x| e(x.to_string()))?;
    let dot =
        |a: &[Vect<3>], b: &[Vect<3>]| -> f64 { a.iter().zip(b).map(|(p, q)| p.dot(q)).sum() };
    let kx = lin.stiffness_times(&x);
    let pkx = project_torsion_class(&maps, &kx);
    let defect = kx
        .iter()
        .zip(&pkx)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt()
        / dot(&kx, &kx).sqrt();
    let mut last = f64::INFINITY;
    let mut w2 = f64::NAN;
    let mut residual = f64::NAN;
    let mut iterations = 0;
    let mut cg = Vec::new();
    let max_cg = 40 * n + 1000;
    for it in 1..=40 {
        iterations = it;
        let mx: Vec<Vect<3>> = (0..n).map(|i| x[i] * m[i]).collect();
        // Warm start: the iterate over the last Rayleigh quotient is K^-1 M x for an eigenvector.
        let guess: Option<Vec<Vect<3>>> =
            w2.is_finite().then(|| x.iter().map(|v| v / w2).collect());
        let (y, cg_it) = lin
            .solve_from(&mx, guess.as_deref(), cg_tol, max_cg)
            .map_err(|x| e(x.to_string()))?;
        cg.push(cg_it);
        let mut y = project_torsion_class(&maps, &y);
        free(&mut y);
        let ky = lin.stiffness_times(&y);
        let my2: f64 = (0..n).map(|i| m[i] * y[i].norm_squared()).sum();
        w2 = dot(&y, &ky) / my2;
        residual = (0..n)
            .map(|i| (ky[i] - y[i] * (w2 * m[i])).norm_squared())
            .sum::<f64>()
            .sqrt()
            / dot(&ky, &ky).sqrt();
        let norm = my2.sqrt();
        x = y.iter().map(|v| v / norm).collect();
        if ((w2 - last) / w2).abs() < 1e-9 {
            break;
        }
        last = w2;
    }
    let (_, rot) = section_twist(x0, m, &x, scene.particle_spacing);
    Ok((
        w2.sqrt() / (2.0 * std::f64::consts::PI),
        TorsionInfo {
            method: "linear",
            particles: n,
            work: lin.products,
            iterations,
            rotation_fraction: rot,
            residual,
            symmetry_defect: defect,
            cg_iterations: cg,
            wall: t0.elapsed().as_secs_f64(),
        },
    ))
}

/// The first torsion frequency (Hz) of a 3D beam scene along x from a time-domain run: the
/// beam released from its reference state with the velocity of a small twist rate
/// v = omega(x) (0, -z, y), omega(x) = omega_tip sin(pi x / 2 L) (the first torsion mode of a
/// uniform clamped-free shaft; omega_tip = 2 pi 45 Hz x 1e-5 rad: twist amplitude ~1e-5 rad,
/// linear), no gravity, stepped at the automatic step. The twist angle of the tip section
/// (mass-weighted rigid-rotation fit of its particles' displacements) is timed over `periods`
/// periods by its upward zero crossings (linear interpolation between steps). The start lies in
/// the class of the torsion modes, so only torsion modes take part; the sine shape puts
/// almost all of the energy into the first.
pub fn torsion_frequency_time(
    scene: &Scene,
    periods: usize,
) -> Result<(f64, TorsionInfo), SceneError> {
    let t0 = std::time::Instant::now();
    let e = |m: String| SceneError {
        field: String::new(),
        message: m,
    };
    if scene.dimension != 3 {
        return Err(e("torsion_frequency_time needs a 3D scene".into()));
    }
    let mut s = scene.clone();
    s.gravity.vector = vec![0.0, 0.0, 0.0];
    let mut model = Model::<3>::build(&s)?;
    let w = &mut model.world;
    let n = w.len();
    let dp = s.particle_spacing;
    let length = w.p.x0.iter().map(|x| x[0]).fold(f64::MIN, f64::max);
    let tip: Vec<usize> = (0..n)
        .filter(|&i| (w.p.x0[i][0] - length).abs() < 0.25 * dp)
        .collect();
    let omega_tip = 2.0 * std::f64::consts::PI * 45.0 * 1e-5;
    let mut st = w.state();
    for i in 0..n {
        let p = w.p.x0[i];
        let om = omega_tip * (0.5 * std::f64::consts::PI * p[0].max(0.0) / length).sin();
        st.v[i] = Vect::<3>::new(0.0, -p[2], p[1]) * om;
        for (k, bit) in FIX_AXIS.iter().enumerate() {
            if w.p.fix[i] & bit != 0 {
                st.v[i][k] = 0.0;
            }
        }
    }
    w.set_state(&st).map_err(|x| e(x.to_string()))?;
    let twist = |w: &crate::physics::World<3>| -> f64 {
        let (mut a, mut b) = (0.0, 0.0);
        for &i in &tip {
            let (y, z) = (w.p.x0[i][1], w.p.x0[i][2]);
            let u = w.p.displacement(i);
            a += y * u[2] - z * u[1];
            b += y * y + z * z;
        }
        a / b
    };
    let mut crossings: Vec<f64> = Vec::new();
    let mut prev = (w.time, twist(w));
    let mut steps = 0u64;
    while crossings.len() < periods + 1 {
        let dt = w.max_dt();
        w.step(dt).map_err(|x| e(x.to_string()))?;
        steps += 1;
        let now = (w.time, twist(w));
        // upward zero crossings, after the start (the twist starts at zero going up)
        if prev.1 < 0.0 && now.1 >= 0.0 {
            crossings.push(prev.0 + (now.0 - prev.0) * (-prev.1) / (now.1 - prev.1));
        }
        prev = now;
        if steps > 100_000_000 {
            return Err(e("torsion_frequency_time: no oscillation found".into()));
        }
    }
    let k = crossings.len() - 1;
    let period = (crossings[k] - crossings[0]) / k as f64;
    let single: Vec<f64> = crossings.windows(2).map(|c| c[1] - c[0]).collect();
    let spread = single
        .iter()
        .map(|p| (p - period).abs())
        .fold(0.0, f64::max)
        / period;
    Ok((
        1.0 / period,
        TorsionInfo {
            method: "time",
            particles: n,
            work: steps,
            iterations: k,
            rotation_fraction: f64::NAN,
            residual: spread,
            symmetry_defect: f64::NAN,
            cg_iterations: Vec::new(),
            wall: t0.elapsed().as_secs_f64(),
        },
    ))
}

/// The FEM first torsion frequencies (Hz) of the slender cantilever: at nu = 0.3 (converged
/// Hex27, `converged.f1_torsion_hz`) and at nu = 0.499 (the mixed Q2-P1disc element, finest
/// mesh, `near_incompressible.converged.f1_torsion_hz`; the displacement Hex27 value differs by
/// 0.014 %: torsion is isochoric).
pub fn cantilever_torsion_reference() -> (f64, f64) {
    let v: serde_json::Value = serde_json::from_str(CANTILEVER_FEM_JSON).expect("reference JSON");
    let a = v["converged"]["f1_torsion_hz"]
        .as_f64()
        .expect("converged.f1_torsion_hz");
    let b = v["near_incompressible"]["converged"]["f1_torsion_hz"]
        .as_f64()
        .expect("near_incompressible.converged.f1_torsion_hz");
    (a, b)
}
