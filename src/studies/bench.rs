//! The benchmark: run time against error for cases 1 and 2 over particle spacings, with the
//! automatic step and the paper's fixed step; single-thread force-loop throughput; the stable
//! step probed at multiples of the bound. Prints a Markdown table (kept in BENCHMARKS.md).
use super::cases::{case2_scene, Support};
use super::report;
use crate::physics::ElasticModel;
use crate::sim::Simulation;
use std::fmt::Write;
use std::time::Instant;

/// One benchmark row.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    pub case: u8,
    pub dp: f64,
    pub step: String,
    pub particles: usize,
    pub bonds: usize,
    pub steps: u64,
    pub wall_s: f64,
    pub pair_updates_per_s: f64,
    /// Case 1: max-norm error of u_z over s >= 0.2; case 2: frequency error vs 3D FEM.
    pub error: f64,
    pub note: String,
}

/// Which runs: (case, dp, fixed dt).
pub fn plan(quick: bool) -> Vec<(u8, f64, Option<f64>)> {
    if quick {
        return vec![(1, 0.05, None), (2, 0.025, None)];
    }
    vec![
        (1, 0.05, None),
        (1, 0.05, Some(1e-5)),
        (1, 0.025, None),
        (1, 0.025, Some(1e-5)),
        (1, 0.0125, None),
        (2, 0.025, None),
        (2, 0.025, Some(1e-5)),
        (2, 0.0125, None),
    ]
}

/// Runs one row.
pub fn run_row(case: u8, dp: f64, dt: Option<f64>) -> Result<Row, String> {
    let step = dt
        .map(|d| format!("paper {d:e} s"))
        .unwrap_or_else(|| "auto".into());
    let (run, error, note) = if case == 1 {
        let r = report::case1(dp, ElasticModel::Corrected, dt, |_| {})?;
        let note = format!("u_x err {:.2}%, dt {:.3e} s", 100.0 * r.error_ux, r.run.dt);
        (r.run, r.error_uz, note)
    } else {
        let r = report::case2(dp, ElasticModel::Corrected, dt, |_| {})?;
        let note = format!(
            "f {:.3} Hz, peak err {:+.2}%, dt {:.3e} s",
            r.frequency_hz,
            100.0 * r.peak_error,
            r.run.dt
        );
        (r.run, r.frequency_error, note)
    };
    Ok(Row {
        case,
        dp,
        step,
        particles: run.particles,
        bonds: run.bonds,
        steps: run.steps,
        wall_s: run.wall_time_s,
        pair_updates_per_s: run.pair_updates_per_s,
        error,
        note,
    })
}

/// Force-loop throughput on one thread: directed bonds per second per force pass (case 2,
/// dp = 0.025, 300 steps, with `model`).
pub fn single_thread_throughput(model: ElasticModel) -> Result<f64, String> {
    #[cfg(feature = "parallel")]
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| e.to_string())?;
    #[cfg(feature = "parallel")]
    let install = |f: &(dyn Fn() -> Result<f64, String> + Sync)| pool.install(f);
    #[cfg(not(feature = "parallel"))]
    let install = |f: &(dyn Fn() -> Result<f64, String> + Sync)| f();
    install(&|| {
        let mut sim = Simulation::new(&case2_scene(0.025, model, None, Support::Face))
            .map_err(|e| e.to_string())?;
        let dt = sim.max_dt();
        let start = Instant::now();
        sim.advance_to(300.0 * dt).map_err(|e| e.to_string())?;
        Ok(2.0 * sim.bonds() as f64 * sim.steps() as f64 / start.elapsed().as_secs_f64())
    })
}

/// Runs case 2 (dp = 0.025) for 0.05 s at a multiple of the critical step; reports whether the
/// solver stayed stable.
pub fn stability_probe(factor: f64) -> String {
    let mut sc = case2_scene(0.025, ElasticModel::Corrected, None, Support::Face);
    let Ok(sim0) = Simulation::new(&sc) else {
        return "build failed".into();
    };
    sc.solver.dt = Some(factor * sim0.critical_dt());
    let mut sim = Simulation::new(&sc).expect("same scene");
    match sim.advance_to(0.05) {
        Ok(n) => format!(
            "stable over {n} steps (max probe |u| {:.3e} m)",
            sim.probe_displacement(0)
                .iter()
                .fold(0.0f64, |a, v| a.max(v.abs()))
        ),
        Err(e) => format!("unstable: {e}"),
    }
}

/// The Markdown report.
pub fn markdown(
    rows: &[Row],
    single: &[(&str, f64)],
    stability: &[(f64, String)],
    fmu: Option<(f64, f64)>,
    threads: usize,
) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "Machine: {} rayon threads. Model: corrected operator. Error: case 1 = max |u_z - closed form| / max |closed form| over s >= 0.2 m; case 2 = first frequency vs the converged 3D FEM reference.\n", threads);
    let _ = writeln!(out, "| case | dp (m) | step | particles | bonds | steps | wall (s) | pair-updates/s | error | notes |");
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {:.2} | {:.3e} | {} | {} |",
            r.case,
            r.dp,
            r.step,
            r.particles,
            r.bonds,
            r.steps,
            r.wall_s,
            r.pair_updates_per_s,
            if r.case == 3 {
                "-".to_string()
            } else {
                format!("{:+.2}%", 100.0 * r.error)
            },
            r.note
        );
    }
    for (model, s) in single {
        let _ = writeln!(out, "\nSingle-thread 3D force loop (case 2, dp = 0.025, {model}): {s:.3e} pair-updates/s per core (a pair-update = one directed bond evaluated in one of the two force passes of a step).");
    }
    if let Some((f, d)) = fmu {
        let _ = writeln!(out, "\nFMU overhead (case 2, dp = 0.025, 600 communication steps of 1 ms, probe outputs read after each): FMI instance {f:.2} s, direct Simulation {d:.2} s, overhead {:+.1}%.", 100.0 * (f / d - 1.0));
    }
    if !stability.is_empty() {
        let _ = writeln!(out, "\nStable step (case 2, dp = 0.025, 0.05 s):\n");
        for (f, s) in stability {
            let _ = writeln!(out, "- dt = {f} x critical: {s}");
        }
    }
    out
}

/// Case 2 (dp = 0.025) to 0.6 s in 1 ms communication steps, reading every probe output after
/// each step: through the FMI instance (the safe layer under the C ABI: state machine, variable
/// table, the instance's own thread pool) and directly through `Simulation`. Returns the wall
/// times (s) of (FMU, direct).
pub fn fmu_overhead() -> Result<(f64, f64), String> {
    let scene = case2_scene(0.025, ElasticModel::Corrected, None, Support::Face);
    let (h, n) = (1e-3, 600);
    let fmu_time = super::realtime::fmu_timing(&scene, n as f64 * h, h)?.stepping_s;
    let direct_time = {
        let mut sim = Simulation::new(&scene).map_err(|e| e.to_string())?;
        let mut sink = 0.0;
        let start = Instant::now();
        for k in 1..=n {
            sim.advance_to(k as f64 * h).map_err(|e| e.to_string())?;
            for p in 0..scene.probes.len() {
                sink += sim.probe_displacement(p)[2];
            }
        }
        std::hint::black_box(sink);
        start.elapsed().as_secs_f64()
    };
    Ok((fmu_time, direct_time))
}

/// Case 3 with contact detection between fractured surfaces to 1.7 s at dp = 0.05: a row.
pub fn case3_row() -> Result<Row, String> {
    use super::case3::{case3_report, case3_scene};
    let scene = case3_scene(0.05, true, ElasticModel::Corrected);
    let sim = Simulation::new(&scene).map_err(|e| e.to_string())?;
    let bonds = sim.bonds();
    drop(sim);
    let r = case3_report(&scene, 1.7, 0.01, 0.0025, |_| {})?;
    let f = |t: Option<f64>| t.map_or("-".to_string(), |t| format!("{t:.3}"));
    Ok(Row {
        case: 3,
        dp: 0.05,
        step: "auto".into(),
        particles: r.particles,
        bonds,
        steps: r.steps,
        wall_s: r.wall_time_s,
        pair_updates_per_s: 2.0 * bonds as f64 * r.steps as f64 / r.wall_time_s,
        error: 0.0,
        note: format!(
            "to {:.2} s; contact {} s, fracture {} s, {} broken bonds, {} contact searches (no error measure: no reference)",
            r.end_time,
            f(r.first_contact),
            f(r.first_fracture),
            r.final_broken_bonds,
            r.contact_searches
        ),
    })
}

/// One row of the bending front (issue 7): an operator at one resolution of a bending case, its
/// errors against the converged FEM (linearised model) and its run time per simulated period.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BendRow {
    /// "plate2d" (GMS plate, plane strain) or "cantilever3d".
    pub case: String,
    pub model: String,
    /// Particles through the thickness.
    pub across: usize,
    pub particles: usize,
    /// Automatic step (s).
    pub dt: f64,
    /// Wall time of one solver step, measured over `timed_steps` steps (s).
    pub step_s: f64,
    /// Wall time to simulate one first-mode period at the automatic step (s).
    pub wall_per_period_s: f64,
    /// First frequency and static tip deflection relative to the FEM (-).
    pub err_f1: f64,
    pub err_tip: f64,
}

impl BendRow {
    /// The larger of the two errors (-).
    pub fn error(&self) -> f64 {
        self.err_f1.abs().max(self.err_tip.abs())
    }
}

/// The bending front: each operator (second_order; corrected at its default stabilisation 0.5)
/// on the GMS plate at 4, 8, 16 particles through the thickness and the slender cantilever at
/// 4 and 8 (`quick`: the plate at 4 and 8 only; `fine`: also the cantilever at 16 with
/// second_order, whose linearisation alone takes about 20 minutes on 2 cores).
pub fn bending_front(quick: bool, fine: bool) -> Result<Vec<BendRow>, String> {
    use super::bending::{
        cantilever3d_scene, cantilever_reference, linear_bending, plate2d_scene, plate_reference,
    };
    let mut cases: Vec<(&str, usize)> = vec![("plate2d", 4), ("plate2d", 8)];
    if !quick {
        cases.extend([("plate2d", 16), ("cantilever3d", 4), ("cantilever3d", 8)]);
    }
    if fine {
        cases.push(("cantilever3d", 16));
    }
    let mut rows = Vec::new();
    for (case, n) in cases {
        for (name, model) in [
            ("second_order", ElasticModel::SecondOrder),
            ("corrected", ElasticModel::Corrected),
        ] {
            if case == "cantilever3d" && n == 16 && model != ElasticModel::SecondOrder {
                continue;
            }
            let (scene, r) = if case == "plate2d" {
                (plate2d_scene(n, model), plate_reference())
            } else {
                (cantilever3d_scene(n, model), cantilever_reference())
            };
            eprintln!("bench: {case} {name} n = {n}");
            let lin = linear_bending(&scene).map_err(|e| e.to_string())?;
            let mut sim = Simulation::new(&scene).map_err(|e| e.to_string())?;
            let dt = sim.max_dt();
            let timed = 100;
            let t0 = Instant::now();
            sim.advance_to(dt * timed as f64)
                .map_err(|e| e.to_string())?;
            let step_s = t0.elapsed().as_secs_f64() / sim.steps().max(1) as f64;
            rows.push(BendRow {
                case: case.into(),
                model: name.into(),
                across: n,
                particles: lin.particles,
                dt,
                step_s,
                wall_per_period_s: step_s / (dt * r.f1),
                err_f1: lin.f1 / r.f1 - 1.0,
                err_tip: lin.tip / r.tip - 1.0,
            });
        }
    }
    Ok(rows)
}

/// The bending front as Markdown.
pub fn bending_markdown(rows: &[BendRow], threads: usize) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "## Bending: run time against error (issue 7)\n");
    let _ = writeln!(out, "Errors of the first frequency and the static tip deflection against the converged FEM (reference/plate2d_fem.json, reference/cantilever3d_fem.json), from the linearised model (src/linear.rs); run time = wall time of one first-mode period at the automatic step, from {threads} rayon threads timing 100 steps.\n");
    let _ = writeln!(out, "| case | operator | across | particles | dt (s) | step (ms) | wall per period (s) | f1 error | tip error |");
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {:.3e} | {:.3} | {:.3} | {:+.3}% | {:+.3}% |",
            r.case,
            r.model,
            r.across,
            r.particles,
            r.dt,
            1e3 * r.step_s,
            r.wall_per_period_s,
            100.0 * r.err_f1,
            100.0 * r.err_tip
        );
    }
    // Cost to reach 1 %: interpolated in log-log between the rows that bracket it.
    let _ = writeln!(out, "\nCost to reach 1 % (the larger of the two errors), interpolated log-log between the resolutions that bracket it:\n");
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in rows {
        let k = (r.case.clone(), r.model.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    for (case, model) in keys {
        let rs: Vec<&BendRow> = rows
            .iter()
            .filter(|r| r.case == case && r.model == model)
            .collect();
        let mut found = None;
        for w in rs.windows(2) {
            let (a, b) = (w[0], w[1]);
            if a.error() > 0.01 && b.error() <= 0.01 {
                let t = (0.01f64.ln() - a.error().ln()) / (b.error().ln() - a.error().ln());
                found = Some(
                    (a.wall_per_period_s.ln()
                        + t * (b.wall_per_period_s.ln() - a.wall_per_period_s.ln()))
                    .exp(),
                );
            }
        }
        let text = match (found, rs.first()) {
            (Some(w), _) => format!("{w:.3} s per period"),
            (None, Some(f)) if f.error() <= 0.01 => format!(
                "below 1 % already at {} across ({:.3} s per period)",
                f.across, f.wall_per_period_s
            ),
            _ => "not reached at the resolutions run".into(),
        };
        let _ = writeln!(out, "- {case}, {model}: {text}");
    }
    out
}

/// Draws the front (wall time per period against the larger error, log-log) as a PNG.
pub fn write_front_png(rows: &[BendRow], path: &std::path::Path) -> Result<(), String> {
    use plotters::prelude::*;
    crate::output::png::ensure_font()?;
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (xmin, xmax) = rows.iter().fold((f64::INFINITY, 0.0f64), |(a, b), r| {
        (a.min(r.wall_per_period_s), b.max(r.wall_per_period_s))
    });
    let (ymin, ymax) = rows.iter().fold((f64::INFINITY, 0.0f64), |(a, b), r| {
        (a.min(r.error()), b.max(r.error()))
    });
    if !(xmin > 0.0 && ymin > 0.0) {
        return Err("the front needs positive run times and errors".into());
    }
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Bending: run time against error (FEM references)",
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (xmin / 2.0..xmax * 2.0).log_scale(),
            (ymin / 2.0..ymax * 2.0).log_scale(),
        )
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_labels(6)
        .y_labels(6)
        .x_desc("wall time per simulated period (s)")
        .y_desc("max(|f1 error|, |tip error|)")
        // Percent with as many decimals as the decade needs (0.001 % has three).
        .y_label_formatter(&|v| {
            let pct = 100.0 * v;
            let decimals = (-pct.log10().floor()).clamp(0.0, 6.0) as usize;
            format!("{pct:.decimals$}%")
        })
        .draw()
        .map_err(|e| e.to_string())?;
    let colours = [
        RGBColor(0, 114, 178),
        RGBColor(213, 94, 0),
        RGBColor(0, 158, 115),
        RGBColor(204, 121, 167),
    ];
    let mut keys: Vec<(String, String)> = rows
        .iter()
        .map(|r| (r.case.clone(), r.model.clone()))
        .collect();
    keys.sort();
    keys.dedup();
    for (k, (case, model)) in keys.iter().enumerate() {
        let c = colours[k % colours.len()];
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| &r.case == case && &r.model == model)
            .map(|r| (r.wall_per_period_s, r.error()))
            .collect();
        chart
            .draw_series(std::iter::once(PathElement::new(
                pts.clone(),
                c.stroke_width(2),
            )))
            .map_err(|e| e.to_string())?
            .label(format!("{case} {model}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))
            .map_err(|e| e.to_string())?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}
