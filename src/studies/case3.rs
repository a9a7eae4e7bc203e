//! The paper's case 3 (section 3.3): a cube hits a block; contact, fracture, and contact between
//! fractured surfaces. Scene builders for both variants (with and without contact detection
//! between fractured surfaces) and a report of the event times.
use std::path::{Path, PathBuf};

use crate::output::{write_grid_png_3d, write_png_3d, Camera, Frame3d, Grid3d, Label3d};
use crate::physics::{ContactOptions, ElasticModel, Material, MaterialLaw, SolverOptions};
use crate::scene::limits::num;
use crate::scene::{
    Body, BodyVelocity, Boundary, BoundaryKind, Gravity, MirrorSpec, Probe, Region, Scene,
};
use crate::sim::{ParticleSnapshot, Simulation};
use serde::{Deserialize, Serialize};

/// Cube: rho = 1000 kg/m^3, E = 6 MPa, nu = 0.3.
pub const CASE3_CUBE: Material = Material {
    density: 1000.0,
    young: 6.0e6,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};
/// Block: rho = 1000 kg/m^3, E = 10 MPa, nu = 0.3.
pub const CASE3_BLOCK: Material = Material {
    density: 1000.0,
    young: 10.0e6,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};
/// The paper's particle spacing of case 3 (m).
pub const CASE3_DP: f64 = 0.05;
/// Cube side (m) and speed (m/s, along -y).
pub const CUBE_SIDE: f64 = 0.5;
pub const CUBE_SPEED: f64 = 5.0;
/// Block extents (m): x, y, z.
pub const BLOCK: [f64; 3] = [1.0, 0.25, 2.0];
/// Gap between the cube and the block (m): contact at gap / speed = 0.07 s, the paper's time.
pub const GAP: f64 = 0.35;
/// The paper's critical bond strain, Eq. (42).
pub const EPS_MAX: f64 = 0.2;
/// The critical bond strain the case 3 scenes use. With the paper's 0.2 nothing breaks in this
/// model: the largest bond strain of the run is 0.094 (at 0.35 s, at the clamped foot on the
/// left; 0.09 with the paper's operator or with the block held as a bridge), so the scenes use
/// 0.08, which breaks the left foot of the block (see docs/contact-fracture.md).
pub const EPS_MAX_USED: f64 = 0.08;
/// The paper's times (s): contact, first fracture, contact between fractured surfaces (parts
/// move apart), failure of the run without that contact detection.
pub const PAPER_TIMES: [(&str, f64); 4] = [
    ("contact", 0.07),
    ("fracture", 0.60),
    ("fractured-surface contact / separation", 0.70),
    ("failure without fractured-surface contact", 1.70),
];

/// Where the cube hits: the centre of its face on the block, in x and z (m) (z for the bridge).
pub const IMPACT_X: f64 = 0.25;
pub const IMPACT_Z: f64 = 1.0;

/// Case 3 scene (eps_max = `EPS_MAX_USED`; the paper's value breaks nothing here). The block stands in the x-z plane, x in
/// [-0.5, 0.5], y in [-0.25, 0], z in [0, 2]; its base z = 0 is clamped (three layers of wall
/// particles below it, like the supports of cases 1 and 2): a wall fixed at its foot, which bends
/// and twists under the impact instead of flying away. The cube, y in [0.35, 0.85], moves at
/// -5 m/s and hits the top of the right half of the block (centred at x = 0.25, flush with the
/// block's right edge, z in [1.5, 2]); the wall bends and twists, and the first bonds break at
/// its clamped foot on the left side (x = -0.5), as in the paper. No gravity. `fractured_surfaces`: contact detection between
/// fractured surfaces (the paper's right column) or not (left column).
pub fn case3_scene(dp: f64, fractured_surfaces: bool, model: ElasticModel) -> Scene {
    case3_scene_with(
        dp,
        fractured_surfaces,
        model,
        Hold::Cantilever,
        EPS_MAX_USED,
    )
}

/// How the block is held.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Hold {
    /// Both ends z = 0 and z = 2 m clamped; the cube hits at mid-height.
    Bridge,
    /// Base z = 0 clamped (a wall standing on the ground); the cube hits the top.
    Cantilever,
}

/// Case 3 with a choice of how the block is held and of eps_max.
pub fn case3_scene_with(
    dp: f64,
    fractured_surfaces: bool,
    model: ElasticModel,
    hold: Hold,
    eps_max: f64,
) -> Scene {
    let opts = SolverOptions {
        model,
        fracture_strain: Some(eps_max),
        contact: ContactOptions {
            fractured_surfaces,
            ..ContactOptions::default()
        },
        ..SolverOptions::default()
    };
    let walls = opts.re_factor.ceil() * dp;
    let [bx, by, bz] = BLOCK;
    let h = 0.5 * CUBE_SIDE;
    let cx = IMPACT_X;
    let cz = match hold {
        Hold::Bridge => IMPACT_Z,
        Hold::Cantilever => BLOCK[2] - 0.5 * CUBE_SIDE,
    };
    let tol = 0.25 * dp;
    // The wall layers sit at the images of the block's first three across its clamped faces;
    // the second-order model mirrors the block across them (docs/model.md, "Mirror faces"),
    // the others hold them as a rigid grip.
    let mirror = |z: f64, nz: f64| {
        (model == ElasticModel::SecondOrder).then(|| MirrorSpec {
            point: vec![0.0, 0.0, z],
            normal: vec![0.0, 0.0, nz],
        })
    };
    let region = |min: [f64; 3], max: [f64; 3]| Region {
        min: min.to_vec(),
        max: max.to_vec(),
    };
    Scene {
        name: if fractured_surfaces {
            "case3_collision".into()
        } else {
            "case3_collision_no_fracture_contact".into()
        },
        description: format!(
            "Paper case 3 (section 3.3): a cube 0.5 m (rho 1000, E 6 MPa, nu 0.3) at v_y = -5 m/s hits a block \
            1.0 (x) x 0.25 (y) x 2.0 (z) m (rho 1000, E 10 MPa, nu 0.3) at rest; dp = {dp} m, eps_max = {eps_max} \
            (paper: {EPS_MAX}, which breaks no bond in this model: the largest bond strain of the run is 0.094); contact detection between fractured surfaces {}. Choices the paper leaves open (its \
            figure 8 is missing): the block stands in the x-z plane with its face at y = 0; {} (a free block would just \
            be pushed away); the cube starts {GAP} m in front of the block (contact at {GAP} / 5 = 0.07 s, the paper's \
            time), centred at x = {cx} m (flush with the block's right edge: bending and twisting then break the wall's foot first on the left side, where the paper's fracture starts) and at \
            z = {cz} m; no gravity (the paper names none; over 1.7 s it would move the free cube by 14 m). Contact law, \
            stable step and overlap rule: docs/contact-fracture.md.",
            if fractured_surfaces { "on" } else { "off" },
            match hold {
                Hold::Bridge => "it is held at both ends z = 0 and z = 2 m by three layers of clamped wall particles beyond each end (a bridge), and the cube hits it at mid-height",
                Hold::Cantilever => "it stands on the ground: its base z = 0 is clamped by three layers of wall particles below it (a wall fixed at its foot; second_order mirrors the block across z = 0 in them), and the cube hits the top of its right half",
            }
        ),
        dimension: 3,
        particle_spacing: dp,
        solver: opts,
        gravity: Gravity::default(),
        bodies: vec![
            Body {
                name: "cube".into(),
                material: CASE3_CUBE,
                boxes: vec![region(
                    [cx - h, GAP, cz - h],
                    [cx + h, GAP + CUBE_SIDE, cz + h],
                )],
                velocity: Some(BodyVelocity::Uniform(vec![0.0, -CUBE_SPEED, 0.0])),
                shapes: vec![],
                cuts: vec![],
            },
            Body {
                name: "block".into(),
                material: CASE3_BLOCK,
                boxes: vec![
                    region([-0.5 * bx, -by, 0.0], [0.5 * bx, 0.0, bz]),
                    region([-0.5 * bx, -by, -walls], [0.5 * bx, 0.0, 0.0]),
                    region([-0.5 * bx, -by, bz], [0.5 * bx, 0.0, bz + walls]),
                ]
                .into_iter()
                .take(if hold == Hold::Bridge { 3 } else { 2 })
                .collect(),
                velocity: None,
                shapes: vec![],
                cuts: vec![],
            },
        ],
        boundaries: [
            Boundary {
                name: "bottom".into(),
                kind: BoundaryKind::Clamped,
                body: "block".into(),
                region: region([-0.5 * bx, -by, -walls], [0.5 * bx, 0.0, -tol]),
                axes: None,
                mirror: mirror(0.0, -1.0),
                shape: None,
            },
            Boundary {
                name: "top".into(),
                kind: BoundaryKind::Clamped,
                body: "block".into(),
                region: region([-0.5 * bx, -by, bz + tol], [0.5 * bx, 0.0, bz + walls]),
                axes: None,
                mirror: mirror(bz, 1.0),
                shape: None,
            },
        ]
        .into_iter()
        .take(if hold == Hold::Bridge { 2 } else { 1 })
        .collect(),
        loads: vec![],
        probes: vec![
            Probe {
                name: "cube_centre".into(),
                point: vec![cx, GAP + h, cz],
                body: Some("cube".into()),
            },
            Probe {
                name: "block_impact".into(),
                point: vec![cx, -0.5 * by, cz],
                body: Some("block".into()),
            },
        ],
        end_time: 1.7,
        output_interval: 0.01,
        analysis: None,
        base_dir: None,
    }
}

/// One sample of the broken-bond history.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Case3Sample {
    /// Time (s).
    pub time: f64,
    /// Broken bond pairs so far.
    pub broken_bonds: u64,
    /// Separate fragments (connected components over intact bonds, both bodies).
    pub fragments: usize,
    /// Particle pairs in contact.
    pub contact_pairs: usize,
    /// Kinetic, strain and contact energy (J).
    pub kinetic: f64,
    pub strain: f64,
    pub contact: f64,
    /// Strain energy released by broken bonds so far (J).
    pub fracture: f64,
    /// Total momentum y (kg m/s) (not conserved: the clamped ends react).
    pub momentum_y: f64,
    /// Largest strain over the intact bonds (-).
    pub max_bond_strain: f64,
}

/// The report of a case 3 run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Case3Report {
    pub scene: String,
    pub fractured_surfaces: bool,
    pub dp: f64,
    pub particles: usize,
    pub dt: f64,
    pub critical_dt: f64,
    pub steps: u64,
    /// Contact pair-list builds (cell-grid searches).
    pub contact_searches: u64,
    /// Fracture checks that tested every bond (the rest were screened out).
    #[serde(default)]
    pub strain_tests: u64,
    pub wall_time_s: f64,
    /// Time reached (s): end_time, or when the run failed.
    pub end_time: f64,
    /// First time two bodies are in contact (s).
    pub first_contact: Option<f64>,
    /// First bond broken (s).
    pub first_fracture: Option<f64>,
    /// First contact between particles of one body across a broken bond (fractured surfaces)
    /// (s); only with contact detection between fractured surfaces.
    pub first_fractured_surface_contact: Option<f64>,
    /// First time the block is in two or more fragments of at least `MIN_FRAGMENT` particles (s).
    pub separation: Option<f64>,
    /// Time and message of the failure (overlap), if the run stopped.
    pub failure_time: Option<f64>,
    pub failure: Option<String>,
    pub final_broken_bonds: u64,
    pub final_fragments: usize,
    /// Large fragments (>= MIN_FRAGMENT particles) at the end.
    pub final_large_fragments: usize,
    pub history: Vec<Case3Sample>,
    /// The paper's times (s), for comparison.
    pub paper: Vec<(String, f64)>,
    /// Time up to which this run was the other variant's (s): it went on from that run's
    /// state there, to the bit as from the start (`case3_report_resumed`); its wall time is
    /// its own part's.
    #[serde(default)]
    pub resumed_from: Option<f64>,
}

/// A fragment of at least this many particles counts as a part of the block (s).
pub const MIN_FRAGMENT: usize = 20;

/// What a callback of [`case3_report_with`] is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckPoint {
    /// The initial state, before the first step (not shown to [`case3_report`]'s callback).
    Start,
    /// The state at an event check (every `check` s).
    Regular,
    /// The state where the run stopped on an error (overlap, blow-up); the last call.
    Failure,
}

/// Runs a case 3 scene to `end_time`, sampling every `interval` (s). Contact and fracture times
/// are resolved to the sampling interval of the event checks, `check` (s). `on_check` sees the
/// simulation after every check (progress bars, snapshots).
pub fn case3_report(
    scene: &Scene,
    end_time: f64,
    interval: f64,
    check: f64,
    mut on_check: impl FnMut(&Simulation),
) -> Result<Case3Report, String> {
    case3_report_with(scene, end_time, interval, check, |sim, kind| {
        if kind == CheckPoint::Regular {
            on_check(sim)
        }
    })
}

/// [`case3_report`] whose callback also sees the state where a failed run stopped
/// ([`CheckPoint::Failure`], once, last), e.g. for the overlap panel of Figure 9.
pub fn case3_report_with(
    scene: &Scene,
    end_time: f64,
    interval: f64,
    check: f64,
    on_check: impl FnMut(&Simulation, CheckPoint),
) -> Result<Case3Report, String> {
    case3_from_start(scene, (end_time, interval, check), on_check, None)
}

/// A case 3 run stopped at an event check, from which a run of the same scene with the other
/// `solver.contact.fractured_surfaces` goes on bit for bit: taken while no pair of one body has
/// come within its contact distance (`Simulation::same_body_touches` is 0), the only pairs
/// whose forces that flag changes. The paper's two variants share their first 0.47 s so.
#[derive(Clone, Debug)]
pub struct Case3Fork {
    /// The scene with the flag set to false, to check that a resumed run is of the same case.
    scene: Scene,
    /// (end time, sampling interval, check interval) (s).
    schedule: (f64, f64, f64),
    state: crate::sim::SimState,
    report: Case3Report,
    /// The check the resumed run does next.
    next_check: u64,
}

impl Case3Fork {
    /// The time of the state (s).
    pub fn time(&self) -> f64 {
        self.report.end_time
    }
}

/// [`case3_report_with`] that also hands `fork` the last state from which the scene's other
/// variant can go on (once: when a pair of one body first touches, or where the run ends).
pub fn case3_report_forking(
    scene: &Scene,
    end_time: f64,
    interval: f64,
    check: f64,
    on_check: impl FnMut(&Simulation, CheckPoint),
    fork: &mut dyn FnMut(Case3Fork),
) -> Result<Case3Report, String> {
    case3_from_start(scene, (end_time, interval, check), on_check, Some(fork))
}

/// A case 3 run from its scene's start (`case3_drive`).
fn case3_from_start(
    scene: &Scene,
    schedule: (f64, f64, f64),
    on_check: impl FnMut(&Simulation, CheckPoint),
    fork: Option<&mut dyn FnMut(Case3Fork)>,
) -> Result<Case3Report, String> {
    let sim = Simulation::new(scene).map_err(|e| e.to_string())?;
    case3_drive(scene, sim, None, schedule, on_check, fork)
}

/// Runs `scene` on from `fork`, taken in a run of the same scene with the other
/// `fractured_surfaces` and the same schedule: the same report, to the bit, as a run from the
/// start (its wall time is this run's; `resumed_from` says where it started).
pub fn case3_report_resumed(
    scene: &Scene,
    fork: Case3Fork,
    on_check: impl FnMut(&Simulation, CheckPoint),
) -> Result<Case3Report, String> {
    if fork_key(scene) != fork.scene {
        return Err(format!(
            "the fork was taken in another case 3 scene than '{}' (they may differ only in solver.contact.fractured_surfaces)",
            scene.name
        ));
    }
    let mut sim = Simulation::new(scene).map_err(|e| e.to_string())?;
    sim.set_state(&fork.state).map_err(|e| e.to_string())?;
    let schedule = fork.schedule;
    case3_drive(scene, sim, Some(fork), schedule, on_check, None)
}

/// The scene as a fork compares it: `fractured_surfaces` set to false.
fn fork_key(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    s.solver.contact.fractured_surfaces = false;
    s.name.clear();
    s.description.clear();
    s
}

/// The loop of the case 3 runs: from the start (`from` None) or from a fork, over the event
/// checks of `schedule` = (end time, sampling interval, check interval) (s).
fn case3_drive(
    scene: &Scene,
    mut sim: Simulation,
    from: Option<Case3Fork>,
    (end_time, interval, check): (f64, f64, f64),
    mut on_check: impl FnMut(&Simulation, CheckPoint),
    mut fork: Option<&mut dyn FnMut(Case3Fork)>,
) -> Result<Case3Report, String> {
    let t0 = std::time::Instant::now();
    sim.check_work(end_time).map_err(|e| e.to_string())?;
    let sample = |sim: &Simulation| Case3Sample {
        time: sim.time(),
        broken_bonds: sim.broken_bonds(),
        fragments: sim.fragments(),
        contact_pairs: sim.contact_pairs(),
        kinetic: sim.kinetic_energy(),
        strain: sim.strain_energy(),
        contact: sim.contact_energy(),
        fracture: sim.fracture_energy(),
        momentum_y: sim.momentum()[1],
        max_bond_strain: sim.max_bond_strain(),
    };
    // The counts of the shared part, to which this run's are added.
    let (mut r, first_check, (searches0, tests0)) = match from {
        Some(f) => {
            let counts = (f.report.contact_searches, f.report.strain_tests);
            let mut r = f.report;
            r.scene = scene.name.clone();
            r.fractured_surfaces = scene.solver.contact.fractured_surfaces;
            r.resumed_from = Some(r.end_time);
            (r, f.next_check, counts)
        }
        None => {
            let mut r = Case3Report {
                scene: scene.name.clone(),
                fractured_surfaces: scene.solver.contact.fractured_surfaces,
                dp: scene.particle_spacing,
                particles: sim.particles(),
                dt: sim.max_dt(),
                critical_dt: sim.critical_dt(),
                steps: 0,
                contact_searches: 0,
                strain_tests: 0,
                wall_time_s: 0.0,
                end_time: 0.0,
                first_contact: None,
                first_fracture: None,
                first_fractured_surface_contact: None,
                separation: None,
                failure_time: None,
                failure: None,
                final_broken_bonds: 0,
                final_fragments: 0,
                final_large_fragments: 0,
                history: Vec::new(),
                paper: PAPER_TIMES
                    .iter()
                    .map(|(n, t)| (n.to_string(), *t))
                    .collect(),
                resumed_from: None,
            };
            r.history.push(sample(&sim));
            on_check(&sim, CheckPoint::Start);
            (r, 1, (0, 0))
        }
    };
    let n_checks = (end_time / check).round().max(1.0) as u64;
    let per_sample = ((interval / check).round() as u64).max(1);
    // What is known at the end of a check (for a fork taken there).
    let finish = |r: &mut Case3Report, sim: &Simulation| {
        r.end_time = sim.time();
        r.steps = sim.steps();
        r.contact_searches = searches0 + sim.contact_searches();
        r.strain_tests = tests0 + sim.strain_tests();
        r.final_broken_bonds = sim.broken_bonds();
        r.final_fragments = sim.fragments();
        r.final_large_fragments = events(sim).large_block_fragments;
    };
    let key = fork.is_some().then(|| fork_key(scene));
    // The last state the other variant can go on from, and the check after it.
    let mut candidate: Option<(crate::sim::SimState, Case3Report, u64)> = None;
    let mut hand_over = |candidate: &mut Option<(crate::sim::SimState, Case3Report, u64)>| {
        if let (Some(f), Some(key), Some((state, report, next_check))) =
            (fork.as_mut(), key.as_ref(), candidate.take())
        {
            f(Case3Fork {
                scene: key.clone(),
                schedule: (end_time, interval, check),
                state,
                report,
                next_check,
            });
        }
    };
    for k in first_check..=n_checks {
        let t = end_time * k as f64 / n_checks as f64;
        if let Err(e) = sim.advance_to(t) {
            r.failure_time = Some(sim.time());
            r.failure = Some(e.to_string());
            r.history.push(sample(&sim));
            on_check(&sim, CheckPoint::Failure);
            break;
        }
        on_check(&sim, CheckPoint::Regular);
        let ev = events(&sim);
        if r.first_contact.is_none() && ev.inter_body_contact {
            r.first_contact = Some(t);
        }
        if r.first_fracture.is_none() && sim.broken_bonds() > 0 {
            r.first_fracture = Some(t);
        }
        if r.first_fractured_surface_contact.is_none() && ev.fractured_contact {
            r.first_fractured_surface_contact = Some(t);
        }
        if r.separation.is_none() && ev.large_block_fragments >= 2 {
            r.separation = Some(t);
        }
        if k % per_sample == 0 || k == n_checks {
            r.history.push(sample(&sim));
        }
        if key.is_some() && k < n_checks {
            if sim.same_body_touches() == 0 {
                let mut at = r.clone();
                finish(&mut at, &sim);
                candidate = Some((sim.state(), at, k + 1));
            } else {
                hand_over(&mut candidate);
            }
        }
    }
    hand_over(&mut candidate);
    finish(&mut r, &sim);
    r.wall_time_s = t0.elapsed().as_secs_f64();
    Ok(r)
}

struct Events {
    inter_body_contact: bool,
    fractured_contact: bool,
    large_block_fragments: usize,
}

fn events(sim: &Simulation) -> Events {
    match sim {
        Simulation::D2(m) => events_of(&m.world),
        Simulation::D3(m) => events_of(&m.world),
    }
}

fn events_of<const D: usize>(w: &crate::physics::World<D>) -> Events
where
    crate::physics::Space: crate::physics::Dim<D>,
{
    let (inter, same) = w.contact_pairs_by_kind();
    let block = w.body_names.iter().position(|n| n == "block").unwrap_or(0) as u32;
    let sizes = w.fragment_sizes();
    let large = sizes
        .iter()
        .filter(|&&(b, n)| b == block && n >= MIN_FRAGMENT)
        .count();
    Events {
        inter_body_contact: inter > 0,
        fractured_contact: same > 0,
        large_block_fragments: large,
    }
}

/// A short text of a report beside the paper's times.
pub fn case3_text(r: &Case3Report) -> String {
    let f = |t: Option<f64>| t.map_or("-".to_string(), |t| format!("{t:.3} s"));
    let mut s = format!(
        "{} (fractured-surface contact {}): {} particles, {} steps of {:.3e} s (critical {:.3e} s) to t = {:.3} s in {:.1} s, {} contact searches, {} bond-strain tests\n",
        r.scene,
        if r.fractured_surfaces { "on" } else { "off" },
        r.particles,
        r.steps,
        r.dt,
        r.critical_dt,
        r.end_time,
        r.wall_time_s,
        r.contact_searches,
        r.strain_tests
    );
    s += &format!(
        "  first contact            {:>10}   (paper 0.07 s)\n",
        f(r.first_contact)
    );
    s += &format!(
        "  first fracture           {:>10}   (paper 0.60 s)\n",
        f(r.first_fracture)
    );
    s += &format!(
        "  fractured-surface contact {:>9}   (paper 0.70 s)\n",
        f(r.first_fractured_surface_contact)
    );
    s += &format!("  block in >= 2 parts      {:>10}\n", f(r.separation));
    s += &format!(
        "  failure                  {:>10}   (paper, without detection: 1.70 s)\n",
        f(r.failure_time)
    );
    if let Some(m) = &r.failure {
        s += &format!("  message: {m}\n");
    }
    if let Some(t) = r.resumed_from {
        s += &format!(
            "  (the same run as the other variant's to t = {t:.4} s, before any pair of one body touched: went on from its state there; the wall time is of the rest)\n"
        );
    }
    s += &format!(
        "  broken bonds {}, fragments {} ({} of the block with >= {} particles)\n",
        r.final_broken_bonds, r.final_fragments, r.final_large_fragments, MIN_FRAGMENT
    );
    s
}

/// The instants of the paper's Figure 9 (s) and what the paper says of each (section 3.3).
pub const FIGURE9_INSTANTS: [(f64, &str); 5] = [
    (0.07, "the cube and the block collide"),
    (0.60, "fracture on the left side of the block"),
    (0.70, "the fractured surfaces collide, the parts move apart"),
    (
        1.00,
        "repulsion of the fractured surfaces visible (with detection)",
    ),
    (
        1.70,
        "without detection a stronger collision, stop on an overlap",
    ),
];

/// A detail of Figure 9: the particles inside a box, drawn larger, as `NAME_TAG.png`.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure9Detail {
    /// File name part and a description for the title.
    pub tag: String,
    pub description: String,
    /// Min and max corners (m), in the current (deformed) positions.
    pub clip: ([f64; 3], [f64; 3]),
}

/// The detail of case 3's Figure 9: the foot of the block, where it cracks.
pub fn figure9_foot() -> Figure9Detail {
    Figure9Detail {
        tag: "foot".into(),
        description: "detail: the foot of the block (particles with z < 0.45 m), where it cracks"
            .into(),
        clip: ([-0.8, -0.6, -0.3], [0.8, 0.4, 0.45]),
    }
}

/// The paper's note for an instant of Figure 9, if it is one of [`FIGURE9_INSTANTS`].
pub fn figure9_note(t: f64) -> Option<&'static str> {
    FIGURE9_INSTANTS
        .iter()
        .find(|(ti, _)| (ti - t).abs() < 1e-9)
        .map(|(_, n)| *n)
}

/// One panel of a Figure 9 column: the state at (or, for a run that stopped before it, the last
/// state before) an instant.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure9Panel {
    /// The instant asked for (s); `snapshot.time` is when the state was taken.
    pub instant: f64,
    pub snapshot: ParticleSnapshot,
    /// The run stopped (overlap, blow-up) before `instant`: `snapshot` is where it stopped.
    pub stopped: bool,
}

/// Most instants of a Figure 9 (the paper's has five): each is a row of the composite image
/// (both runs side by side, about [`FIGURE9_ROW_PX`] pixels tall and 1200 wide) and a snapshot
/// of each run kept until the end. 20 rows are about 13 million pixels, within
/// [`crate::output::MAX_IMAGE_PIXELS`].
pub const FIGURE9_MAX_INSTANTS: usize = 20;

/// Height of a row of the Figure 9 composite (pixels, about: the title lines of its panels
/// add to it).
pub const FIGURE9_ROW_PX: usize = 550;

/// Collects the snapshots of one case 3 run at given instants: pass [`Figure9Capture::check`]
/// to [`case3_report_with`] (with event checks that land on the instants, e.g. every 2.5 ms
/// for the paper's), then [`Figure9Capture::finish`].
#[derive(Clone, Debug)]
pub struct Figure9Capture {
    times: Vec<f64>,
    snaps: Vec<Option<ParticleSnapshot>>,
    failure: Option<ParticleSnapshot>,
    body_names: Vec<String>,
}

impl Figure9Capture {
    /// Instants (s): finite, >= 0, increasing, at least one.
    pub fn new(times: &[f64]) -> Result<Self, String> {
        if times.is_empty() {
            return Err("no instant given for the Figure 9 snapshots".into());
        }
        if let Some(t) = times.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
            return Err(format!(
                "Figure 9 instants must be finite times >= 0 s, got {}",
                num(*t)
            ));
        }
        if times.len() > FIGURE9_MAX_INSTANTS {
            return Err(format!(
                "Figure 9 takes at most {FIGURE9_MAX_INSTANTS} instants, got {}: its composite \
                 image has a row of about {FIGURE9_ROW_PX} pixels per instant ({} rows: about \
                 {} million pixels, more than an image may have) and every instant keeps a \
                 snapshot of each run in memory; give fewer instants, or run case3 --snapshots \
                 for a snapshot every 0.1 s",
                times.len(),
                times.len(),
                (times.len() * FIGURE9_ROW_PX * 1200).div_ceil(1_000_000)
            ));
        }
        if times.windows(2).any(|w| w[1] <= w[0]) {
            let k = times
                .windows(2)
                .position(|w| w[1] <= w[0])
                .expect("found above");
            return Err(format!(
                "Figure 9 instants must increase, got {} s after {} s (instants {} and {})",
                num(times[k + 1]),
                num(times[k]),
                k + 1,
                k + 2
            ));
        }
        Ok(Figure9Capture {
            times: times.to_vec(),
            snaps: vec![None; times.len()],
            failure: None,
            body_names: Vec::new(),
        })
    }

    /// Takes the snapshots due at this state.
    pub fn check(&mut self, sim: &Simulation, kind: CheckPoint) {
        if self.body_names.is_empty() {
            self.body_names = sim.body_names();
        }
        if kind == CheckPoint::Failure {
            self.failure = Some(sim.particle_snapshot());
            return;
        }
        let t = sim.time();
        let mut snap = None;
        for (k, ti) in self.times.iter().enumerate() {
            if self.snaps[k].is_none() && t >= ti - 1e-9 * ti.max(1.0) {
                let s = snap.get_or_insert_with(|| sim.particle_snapshot());
                self.snaps[k] = Some(s.clone());
            }
        }
    }

    /// The body names of the run (empty before the first check).
    pub fn body_names(&self) -> &[String] {
        &self.body_names
    }

    /// One panel per instant. An instant after the time a failed run stopped gets the state
    /// where it stopped (`stopped`); an instant the run did not reach otherwise is an error.
    pub fn finish(self, report: &Case3Report) -> Result<Vec<Figure9Panel>, String> {
        self.times
            .iter()
            .zip(self.snaps)
            .map(|(&t, snap)| match (snap, &self.failure) {
                (Some(s), _) => Ok(Figure9Panel {
                    instant: t,
                    snapshot: s,
                    stopped: false,
                }),
                (None, Some(f)) => Ok(Figure9Panel {
                    instant: t,
                    snapshot: f.clone(),
                    stopped: true,
                }),
                (None, None) => Err(format!(
                    "{}: the run ended at {} s, before the Figure 9 instant {} s",
                    report.scene,
                    num(report.end_time),
                    num(t)
                )),
            })
            .collect()
    }
}

/// A column of Figure 9: a heading, a short tag for file names, its panels (one per instant,
/// the same instants in every column) and the failure message of its run, if any.
#[derive(Clone, Debug)]
pub struct Figure9Column {
    pub heading: String,
    pub tag: String,
    pub panels: Vec<Figure9Panel>,
    pub failure: Option<String>,
}

/// The file name stem of Figure 9 (`--figure9-name`): not empty, no path separator, NUL or
/// control character, not "." or "..".
fn check_figure9_name_text(name: &str) -> Result<(), String> {
    if name.is_empty()
        || name == "."
        || name == ".."
        || name.contains(['/', '\\'])
        || name.chars().any(char::is_control)
    {
        return Err(format!(
            "Figure 9 name {name:?} must be a non-empty file name stem (no '/', '\\' or control \
             character)"
        ));
    }
    Ok(())
}

/// Checks the Figure 9 name before any run: a valid stem ([`write_figure9`]'s check), short
/// enough for its longest file name (NAME_without_tT.png for the instants `times`) and a name
/// under which a file can be created in `dir` (tried with that longest name and removed).
pub fn check_figure9_name(dir: &Path, name: &str, times: &[f64]) -> Result<(), String> {
    check_figure9_name_text(name)?;
    let longest = times
        .iter()
        .map(|&t| format!("{name}_without_t{}.png", time_tag(t)))
        .chain(std::iter::once(format!("{name}.png")))
        .max_by_key(String::len)
        .expect("one name at least");
    if longest.len() > 255 {
        return Err(format!(
            "Figure 9 name is {} bytes long: its file {longest:.40}... would be {} bytes, more \
             than a file name may have (255)",
            name.len(),
            longest.len()
        ));
    }
    let probe = dir.join(format!(".{longest}.{}", std::process::id()));
    let probe = if probe.file_name().is_some_and(|f| f.len() > 255) {
        dir.join(&longest)
    } else {
        probe
    };
    if !probe.exists() {
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&probe)
            .map_err(|e| {
                format!(
                    "Figure 9 cannot be written into {}: {}: {e}",
                    dir.display(),
                    probe.display()
                )
            })?;
        let _ = std::fs::remove_file(&probe);
    }
    Ok(())
}

/// `t` as a short file-name part: two decimals, three when needed (0.07 -> "0.07",
/// 0.345 -> "0.345").
fn time_tag(t: f64) -> String {
    let three = format!("{t:.3}");
    match three.strip_suffix('0') {
        Some(two) => two.to_string(),
        None => three,
    }
}

/// Writes Figure 9: `dir/NAME.png`, the columns side by side and one row per instant, and
/// `dir/NAME_TAG_tT.png` for every panel; all drawn with one frame (same position, scale and
/// depth shading) seen by `camera`, fitted to the bulk of the bodies (pieces thrown far away
/// are left out and counted in the titles); with `detail`, also `dir/NAME_DETAILTAG.png`, the same grid
/// of the particles inside the detail's box only. Returns the paths written, the composite
/// first. `title` and `subtitle` head the composites. Errors: no column, columns of different
/// instants, empty or non-finite snapshots, a detail box without particles, a directory or file
/// that cannot be written.
#[allow(clippy::too_many_arguments)]
pub fn write_figure9(
    dir: &Path,
    name: &str,
    title: &str,
    subtitle: &str,
    body_names: &[String],
    columns: &[Figure9Column],
    camera: Camera,
    detail: Option<&Figure9Detail>,
) -> Result<Vec<PathBuf>, String> {
    let first = columns
        .first()
        .ok_or_else(|| "Figure 9 needs at least one column".to_string())?;
    let instants: Vec<f64> = first.panels.iter().map(|p| p.instant).collect();
    if instants.is_empty() {
        return Err("Figure 9 needs at least one instant".into());
    }
    for c in columns {
        let other: Vec<f64> = c.panels.iter().map(|p| p.instant).collect();
        if other != instants {
            return Err(format!(
                "Figure 9 column `{}` has the instants {other:?}, not {instants:?}",
                c.heading
            ));
        }
    }
    check_figure9_name_text(name)?;
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let snaps: Vec<&ParticleSnapshot> = columns
        .iter()
        .flat_map(|c| c.panels.iter().map(|p| &p.snapshot))
        .collect();
    let frame = Frame3d::fit_bulk(camera, &snaps)?;
    let label = |c: &Figure9Column, p: &Figure9Panel, variant: bool| {
        let mut notes: Vec<String> = Vec::new();
        if let Some(n) = figure9_note(p.instant) {
            notes.push(format!("paper at {} s: {n}", time_tag(p.instant)));
        }
        if p.stopped {
            // "particles overlap at t = ... (step ...): ..." -> "particles overlap".
            let why = c
                .failure
                .as_deref()
                .and_then(|m| m.split([':', '(']).next())
                .map(|m| m.split(" at t =").next().unwrap_or(m).trim())
                .unwrap_or("failure");
            notes.push(format!(
                "run stopped at {:.3} s ({why}): last state",
                p.snapshot.time
            ));
        }
        Label3d {
            body_names: body_names.to_vec(),
            variant: if variant {
                c.heading.clone()
            } else {
                String::new()
            },
            note: if notes.is_empty() {
                None
            } else {
                Some(notes.join("\n"))
            },
        }
    };
    let composite = dir.join(format!("{name}.png"));
    let mut written = vec![composite.clone()];
    let grid = Grid3d {
        title: title.to_string(),
        subtitle: subtitle.to_string(),
        columns: columns.iter().map(|c| c.heading.clone()).collect(),
        cells: (0..instants.len())
            .map(|r| {
                columns
                    .iter()
                    .map(|c| (&c.panels[r].snapshot, label(c, &c.panels[r], false)))
                    .collect()
            })
            .collect(),
    };
    write_grid_png_3d(&composite, &grid, &frame)?;
    if let Some(d) = detail {
        let frame = Frame3d::fit_clipped(camera, &snaps, Some(d.clip))?;
        let path = dir.join(format!("{name}_{}.png", d.tag));
        let grid = Grid3d {
            title: format!("{title}; {}", d.description),
            ..grid.clone()
        };
        write_grid_png_3d(&path, &grid, &frame)?;
        written.push(path);
    }
    for c in columns {
        for p in &c.panels {
            let path = dir.join(format!("{name}_{}_t{}.png", c.tag, time_tag(p.instant)));
            write_png_3d(&path, &p.snapshot, &label(c, p, true), &frame)?;
            written.push(path);
        }
    }
    Ok(written)
}
