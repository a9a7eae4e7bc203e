//! Real time at 1 % error (issue 25): per scene (the paper's cases 1 and 2, the slender 3D
//! cantilever), the coarsest particle spacing at which the default operator's figures are within
//! 1 % of the FEM, and the wall time per simulated second of that scene driven through the FMI
//! instance (the safe layer under the C ABI) in 1 ms communication steps, as a co-simulation
//! master drives it (`mps bench --realtime`).
use std::time::Instant;

use crate::fmi::instance::{Instance, NoLogger};
use crate::fmi::variables::{Causality, VarType};
use crate::physics::ElasticModel;
use crate::scene::Scene;
use crate::studies::bending::{cantilever3d_scene, cantilever_reference, linear_bending};
use crate::studies::cases::{
    case1_scene, case1_shape_scene, case2_scene, case2_shape_scene, Support,
};
use crate::studies::report;

/// Communication step of the real-time figures (s).
pub const COMMUNICATION_STEP: f64 = 1e-3;

/// The figures' bound against the FEM (-).
pub const ERROR_BOUND: f64 = 0.01;

/// Wall times of a scene driven through an FMI instance.
#[derive(Clone, Debug)]
pub struct FmuTiming {
    /// Instantiation to the end of initialisation: the scene's set-up (s).
    pub setup_s: f64,
    /// The communication steps, reading the probes' displacement outputs after each (s).
    pub stepping_s: f64,
    /// Simulated time (s).
    pub simulated_s: f64,
    /// The instance's worker threads.
    pub threads: usize,
}

impl FmuTiming {
    /// Wall time per simulated second (-): below 1 is faster than real time.
    pub fn real_time_factor(&self) -> f64 {
        self.stepping_s / self.simulated_s
    }
}

/// Drives `scene` through an FMI instance from 0 to `end` (s) in communication steps of `h`,
/// reading every probe displacement output after each step; the wall times of set-up and
/// stepping. The scene is written to a temporary resources directory, as an FMU carries it.
pub fn fmu_timing(scene: &Scene, end: f64, h: f64) -> Result<FmuTiming, String> {
    let dir = std::env::temp_dir().join(format!(
        "mps-fmu-timing-{}-{}",
        std::process::id(),
        crate::fmi::model_description::guid(scene)
    ));
    std::fs::create_dir_all(dir.join("resources")).map_err(|e| e.to_string())?;
    let run = || -> Result<FmuTiming, String> {
        std::fs::write(dir.join("resources/scene.json"), scene.to_json())
            .map_err(|e| e.to_string())?;
        let uri = format!("file://{}", dir.join("resources").display());
        let guid = crate::fmi::model_description::guid(scene);
        let msg = |e: crate::fmi::instance::FmiError| e.message().to_string();
        let t0 = Instant::now();
        let mut inst = Instance::instantiate(
            "timing",
            true,
            &guid,
            Some(&uri),
            std::sync::Arc::new(NoLogger),
            false,
        )?;
        let vrs: Vec<u32> = inst
            .table()
            .vars
            .iter()
            .filter(|v| {
                v.causality == Causality::Output && v.ty == VarType::Real && v.name.contains(".u")
            })
            .map(|v| v.value_reference)
            .collect();
        let mut out = vec![0.0; vrs.len()];
        inst.setup_experiment(0.0, Some(end)).map_err(msg)?;
        inst.enter_initialization_mode().map_err(msg)?;
        inst.exit_initialization_mode().map_err(msg)?;
        let setup_s = t0.elapsed().as_secs_f64();
        let n = (end / h).round() as usize;
        let t1 = Instant::now();
        for k in 0..n {
            inst.do_step(k as f64 * h, h).map_err(msg)?;
            inst.get_real(&vrs, &mut out).map_err(msg)?;
        }
        let stepping_s = t1.elapsed().as_secs_f64();
        std::hint::black_box(&out);
        Ok(FmuTiming {
            setup_s,
            stepping_s,
            simulated_s: n as f64 * h,
            threads: crate::fmi::instance::instance_threads(),
        })
    };
    let r = run();
    let _ = std::fs::remove_dir_all(&dir);
    r
}

/// One scene's real-time figure.
#[derive(Clone, Debug)]
pub struct RealTimeRow {
    pub scene: String,
    /// The spacing chosen, in the scene's terms.
    pub spacing: String,
    pub particles: usize,
    /// The figures at that spacing against the FEM, and at the coarser spacings tried.
    pub errors: String,
    /// Whether the spacing's figures are within the bound (else the finest tried).
    pub within: bool,
    pub timing: FmuTiming,
}

/// A candidate spacing's figures: (name, particles, errors text, largest |error|, the scene).
type Candidate = (String, usize, String, f64, Scene);

/// The first candidate (coarsest first) within the bound, timed through the FMU; the text
/// lists the coarser ones that missed it.
fn first_within(
    name: &str,
    candidates: Vec<Box<dyn Fn() -> Result<Candidate, String>>>,
) -> Result<RealTimeRow, String> {
    let mut missed = Vec::new();
    let mut last = None;
    for c in candidates {
        let (spacing, particles, errors, worst, scene) = c()?;
        let within = worst <= ERROR_BOUND;
        last = Some((spacing.clone(), particles, errors.clone(), within, scene));
        if within {
            break;
        }
        missed.push(format!("{spacing}: {errors}"));
    }
    let (spacing, particles, errors, within, scene) = last.ok_or("no candidate spacing")?;
    let timing = fmu_timing(&scene, scene.end_time, COMMUNICATION_STEP)?;
    let errors = if missed.is_empty() || !within {
        errors
    } else {
        format!("{errors} (coarser, {})", missed.join("; "))
    };
    Ok(RealTimeRow {
        scene: name.into(),
        spacing,
        particles,
        errors,
        within,
        timing,
    })
}

fn pct(e: f64) -> String {
    format!("{:+.2} %", 100.0 * e)
}

/// The three scenes' rows with the default operator: case 1 (written as a box shape at dp =
/// 1/20, 1/21, ... m, then dp 0.025 m: its figures u_x and u_z along the column against the
/// clamped column's FEM), case 2 (written as a box
/// shape at dp = 1/20, 1/21, ... m, whole spacings along its 1 m span, its 0.225 m section cut
/// where it falls; then dp 0.025 m, the coarsest lattice that fits both: first frequency and
/// peak deflection), the slender 3D cantilever (3 and 4 particles across: the linearised first
/// frequency and the first peak under sudden gravity).
pub fn real_time_rows() -> Result<Vec<RealTimeRow>, String> {
    let so = ElasticModel::SecondOrder;
    // Case 1 written as a box shape at dp = 1/20, 1/21, ... m (whole spacings along its 1 m
    // length, its 0.2 m section cut where it falls), then at the paper's lattice.
    let case1 = |dp: f64, shape: bool| -> Box<dyn Fn() -> Result<Candidate, String>> {
        Box::new(move || {
            let scene = if shape {
                case1_shape_scene(dp)
            } else {
                case1_scene(dp, so, None)
            };
            let r = report::case1_of(&scene, |_| {})?;
            Ok((
                if shape {
                    format!("dp 1/{:.0} m, a box shape", 1.0 / dp)
                } else {
                    format!("dp {dp} m")
                },
                r.run.particles,
                format!("u_x {}, u_z {}", pct(r.error_ux_fem), pct(r.error_uz_fem)),
                r.error_ux_fem.abs().max(r.error_uz_fem.abs()),
                scene,
            ))
        })
    };
    // Case 2 at the paper's lattice (dp 0.025 m: 9 spacings through the section and 40 along
    // the span, the coarsest that fits both) or written as a box shape at a spacing of whole
    // spacings along the span only, its faces cutting the outer cells.
    let case2 = |dp: f64, shape: bool| -> Box<dyn Fn() -> Result<Candidate, String>> {
        Box::new(move || {
            let scene = if shape {
                case2_shape_scene(dp)
            } else {
                case2_scene(dp, so, None, Support::Face)
            };
            let r = report::case2_of(&scene, |_| {})?;
            Ok((
                if shape {
                    format!("dp 1/{:.0} m, a box shape", 1.0 / dp)
                } else {
                    format!("dp {dp} m")
                },
                r.run.particles,
                format!("f1 {}, peak {}", pct(r.frequency_error), pct(r.peak_error)),
                r.frequency_error.abs().max(r.peak_error.abs()),
                scene,
            ))
        })
    };
    let cantilever = |n: usize| -> Box<dyn Fn() -> Result<Candidate, String>> {
        Box::new(move || {
            let scene = cantilever3d_scene(n, so);
            let reference = cantilever_reference();
            let v: serde_json::Value =
                serde_json::from_str(crate::studies::bending::CANTILEVER_FEM_JSON)
                    .map_err(|e| e.to_string())?;
            let peak_ref = v["converged"]["peak_dynamic_tip_uz_axis_m"]
                .as_f64()
                .ok_or("no peak in the cantilever's reference")?;
            let b = linear_bending(&scene).map_err(|e| e.to_string())?;
            let peak = crate::studies::family::first_peak(&scene, reference.f1)?;
            let (ef, ep) = (b.f1 / reference.f1 - 1.0, peak / peak_ref - 1.0);
            Ok((
                format!("{n} across"),
                b.particles,
                format!("f1 {}, first peak {}", pct(ef), pct(ep)),
                ef.abs().max(ep.abs()),
                scene,
            ))
        })
    };
    Ok(vec![
        first_within(
            "case 1: column under its own weight",
            (20..40)
                .map(|n| case1(1.0 / n as f64, true))
                .chain([case1(0.025, false)])
                .collect(),
        )?,
        first_within(
            "case 2: clamped-pinned beam",
            (20..40)
                .map(|n| case2(1.0 / n as f64, true))
                .chain([case2(0.025, false)])
                .collect(),
        )?,
        first_within("slender 3D cantilever", vec![cantilever(3), cantilever(4)])?,
    ])
}

/// The rows as a Markdown table.
pub fn real_time_markdown(rows: &[RealTimeRow]) -> String {
    let mut md = String::from(
        "| scene | spacing | particles | figures against the FEM | set-up (s) | simulated (s) | wall (s) | real-time factor |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        md += &format!(
            "| {} | {}{} | {} | {} | {:.2} | {:.3} | {:.2} | **{:.1}** |\n",
            r.scene,
            r.spacing,
            if r.within { "" } else { " (none within 1 %)" },
            r.particles,
            r.errors,
            r.timing.setup_s,
            r.timing.simulated_s,
            r.timing.stepping_s,
            r.timing.real_time_factor()
        );
    }
    if let Some(r) = rows.first() {
        md += &format!(
            "\nThrough the FMI instance (the layer under the C ABI), {} worker thread(s), communication steps of {} ms reading every probe's displacement outputs; real-time factor = stepping wall time / simulated time (below 1: faster than real time; issue 25's target for case 2: at most 1). Spacing: the coarsest tried whose figures are within {} % of the FEM.\n",
            r.timing.threads,
            COMMUNICATION_STEP * 1e3,
            ERROR_BOUND * 100.0
        );
    }
    md
}
