//! Reports of the paper's cases 1 and 2: each result beside its references (closed form,
//! Euler-Bernoulli, Timoshenko, the paper's Table 1, the 3D FEM references in
//! reference/case1_fem.json and reference/case2_fem.json), as text tables or JSON.
use super::cases::*;
use crate::physics::ElasticModel;
use crate::runner::{run_scene, RunResult};
use crate::scene::Scene;
use serde::Serialize;

/// The 3D FEM reference of case 2, computed by tools/fem_reference.py (see reference/README.md).
pub const CASE2_FEM_JSON: &str = include_str!("../../reference/case2_fem.json");

/// Converged 3D FEM numbers of case 2.
#[derive(Clone, Debug, Serialize)]
pub struct FemReference {
    pub f1_hz: f64,
    pub static_max_uz_m: f64,
    pub static_max_x_m: f64,
    pub peak_dynamic_uz_m: f64,
    pub timoshenko_f1_hz: f64,
}

/// Reads the committed FEM reference.
pub fn fem_reference() -> FemReference {
    let v: serde_json::Value =
        serde_json::from_str(CASE2_FEM_JSON).expect("reference/case2_fem.json is JSON");
    let c = &v["converged"];
    let num = |x: &serde_json::Value, what: &str| {
        x.as_f64()
            .unwrap_or_else(|| panic!("reference/case2_fem.json lacks {what}"))
    };
    FemReference {
        f1_hz: num(&c["f1_hz"], "converged.f1_hz"),
        static_max_uz_m: num(&c["static_max_uz_m"], "converged.static_max_uz_m"),
        static_max_x_m: num(&c["static_max_x_m"], "converged.static_max_x_m"),
        peak_dynamic_uz_m: num(&c["peak_dynamic_uz_m"], "converged.peak_dynamic_uz_m"),
        timoshenko_f1_hz: num(
            &v["beam_theory"]["timoshenko_f1_hz"],
            "beam_theory.timoshenko_f1_hz",
        ),
    }
}

/// The 3D FEM reference of case 1 (the clamped column), computed by tools/fem_column.py.
pub const CASE1_FEM_JSON: &str = include_str!("../../reference/case1_fem.json");

/// Converged FEM displacements (u_x, u_z) of case 1 on the paper's line x = 0.1 m, y = 0, at
/// the distances `CASE1_STATIONS` from the support (m).
pub fn case1_fem_line() -> Vec<(f64, f64)> {
    let v: serde_json::Value =
        serde_json::from_str(CASE1_FEM_JSON).expect("reference/case1_fem.json is JSON");
    let line = &v["converged"]["lines"]["x0.1_y0"];
    let col = |key: &str| -> Vec<f64> {
        line[key]["converged"]
            .as_array()
            .unwrap_or_else(|| panic!("reference/case1_fem.json lacks {key}.converged"))
            .iter()
            .map(|x| x.as_f64().unwrap_or(f64::NAN))
            .collect()
    };
    let s = line["s_m"]
        .as_array()
        .expect("reference/case1_fem.json lacks s_m");
    assert!(
        s.len() == CASE1_STATIONS.len()
            && s.iter()
                .zip(CASE1_STATIONS)
                .all(|(a, b)| (a.as_f64().unwrap_or(f64::NAN) - b).abs() < 1e-9),
        "reference/case1_fem.json is not at the case 1 stations"
    );
    col("ux").into_iter().zip(col("uz")).collect()
}

/// One station of case 1.
#[derive(Clone, Debug, Serialize)]
pub struct Station {
    /// Distance from the support (m).
    pub s: f64,
    pub ux: f64,
    pub ux_closed_form: f64,
    /// The clamped column's converged 3D FEM value (m).
    pub ux_fem: f64,
    pub uz: f64,
    pub uz_closed_form: f64,
    pub uz_fem: f64,
}

/// Case 1 against its closed form.
#[derive(Clone, Debug, Serialize)]
pub struct Case1Report {
    pub dp: f64,
    pub model: ElasticModel,
    pub stations: Vec<Station>,
    /// max over s >= 0.2 of |u_x - cf| / max |cf| on the line (-).
    pub error_ux: f64,
    /// The same for the axial displacement (-).
    pub error_uz: f64,
    /// The same two against the 3D FEM of the clamped column (-): the closed form leaves the
    /// support free to contract laterally, which a clamp stops (about 1 % near the support).
    pub error_ux_fem: f64,
    pub error_uz_fem: f64,
    /// Support reaction along z (N) and the column's weight (N).
    pub reaction_z: f64,
    pub weight: f64,
    pub run: RunSummary,
}

/// Timing and size of a run.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub particles: usize,
    pub bonds: usize,
    pub steps: u64,
    pub dt: f64,
    pub critical_dt: f64,
    pub wall_time_s: f64,
    pub pair_updates_per_s: f64,
    /// Simulated time reached (s).
    pub simulated_s: f64,
    pub error: Option<String>,
}

impl From<&RunResult> for RunSummary {
    fn from(r: &RunResult) -> Self {
        RunSummary {
            particles: r.particles,
            bonds: r.bonds,
            steps: r.steps,
            dt: r.dt,
            critical_dt: r.critical_dt,
            wall_time_s: r.wall_time_s,
            pair_updates_per_s: r.pair_updates_per_s,
            simulated_s: r.end_time,
            error: r.error.clone(),
        }
    }
}

/// Relative max-norm error over the stations with s >= 0.2 m: max |num - cf| / max |cf|.
pub fn line_error(
    st: &[Station],
    num: impl Fn(&Station) -> f64,
    cf: impl Fn(&Station) -> f64,
) -> f64 {
    let used: Vec<&Station> = st.iter().filter(|s| s.s >= 0.2 - 1e-9).collect();
    let scale = used.iter().map(|s| cf(s).abs()).fold(0.0, f64::max);
    used.iter()
        .map(|s| (num(s) - cf(s)).abs())
        .fold(0.0, f64::max)
        / scale
}

/// Runs case 1 and compares with the closed form.
pub fn case1(
    dp: f64,
    model: ElasticModel,
    dt: Option<f64>,
    on_sample: impl FnMut(f64),
) -> Result<Case1Report, String> {
    case1_of(&case1_scene(dp, model, dt), on_sample)
}

/// Runs a scene of case 1 (probes at the stations of `case1_scene`) and compares.
pub fn case1_of(scene: &Scene, on_sample: impl FnMut(f64)) -> Result<Case1Report, String> {
    let (dp, model) = (scene.particle_spacing, scene.solver.model);
    let r = run_scene(scene, on_sample)?;
    let fem = case1_fem_line();
    let stations: Vec<Station> = CASE1_STATIONS
        .iter()
        .zip(&r.final_displacement)
        .zip(&fem)
        .map(|((&s, (_, u)), &(ux_fem, uz_fem))| {
            let (ux, uz) = case1_closed_form(CASE1_HALF, 0.0, s);
            Station {
                s,
                ux: u[0],
                ux_closed_form: ux,
                ux_fem,
                uz: u[2],
                uz_closed_form: uz,
                uz_fem,
            }
        })
        .collect();
    Ok(Case1Report {
        dp,
        model,
        error_ux: line_error(&stations, |s| s.ux, |s| s.ux_closed_form),
        error_uz: line_error(&stations, |s| s.uz, |s| s.uz_closed_form),
        error_ux_fem: line_error(&stations, |s| s.ux, |s| s.ux_fem),
        error_uz_fem: line_error(&stations, |s| s.uz, |s| s.uz_fem),
        stations,
        reaction_z: r.final_reaction[0].1[2],
        weight: CASE1_MATERIAL.density * G * (2.0 * CASE1_HALF).powi(2) * CASE1_LENGTH,
        run: RunSummary::from(&r),
    })
}

/// Case 2 against the FEM reference and beam theories.
#[derive(Clone, Debug, Serialize)]
pub struct Case2Report {
    pub dp: f64,
    pub model: ElasticModel,
    pub frequency_hz: f64,
    pub period_s: f64,
    /// Largest deflection at the probe x = 0.56 m under suddenly applied gravity (m).
    pub peak_deflection_m: f64,
    pub fem: FemReference,
    /// (frequency - FEM) / FEM (-).
    pub frequency_error: f64,
    /// (peak - FEM peak) / FEM peak (-).
    pub peak_error: f64,
    pub euler_bernoulli_hz: f64,
    pub euler_bernoulli_static_m: f64,
    pub run: RunSummary,
}

/// Runs case 2 (face support) and compares.
pub fn case2(
    dp: f64,
    model: ElasticModel,
    dt: Option<f64>,
    on_sample: impl FnMut(f64),
) -> Result<Case2Report, String> {
    case2_of(&case2_scene(dp, model, dt, Support::Face), on_sample)
}

/// Runs a scene of case 2 (a probe on the axis at x = 0.56 m as its analysis) and compares.
pub fn case2_of(scene: &Scene, on_sample: impl FnMut(f64)) -> Result<Case2Report, String> {
    let (dp, model) = (scene.particle_spacing, scene.solver.model);
    let r = run_scene(scene, on_sample)?;
    let fem = fem_reference();
    let f = r.frequency_hz.ok_or("no frequency measured")?;
    let peak = r.peak_m.ok_or("no peak measured")?;
    Ok(Case2Report {
        dp,
        model,
        frequency_hz: f,
        period_s: 1.0 / f,
        peak_deflection_m: peak,
        frequency_error: f / fem.f1_hz - 1.0,
        peak_error: peak / fem.peak_dynamic_uz_m - 1.0,
        fem,
        euler_bernoulli_hz: case2_euler_bernoulli_hz(),
        euler_bernoulli_static_m: -case2_euler_bernoulli_static(),
        run: RunSummary::from(&r),
    })
}

/// Case 1 as a text table.
pub fn case1_text(r: &Case1Report) -> String {
    let mut out = format!(
        "Case 1: column under its own weight, dp = {} m, model {:?} (diff: against the closed form / the 3D FEM)\n  {:>5} {:>12} {:>12} {:>12} {:>8} {:>8} {:>12} {:>12} {:>12} {:>8} {:>8}\n",
        r.dp, r.model, "s (m)", "u_x (m)", "closed form", "3D FEM", "diff", "diff", "u_z (m)", "closed form", "3D FEM", "diff", "diff"
    );
    let pct = |num: f64, cf: f64| {
        if cf.abs() > 1e-12 {
            format!("{:>7.2}%", 100.0 * (num / cf - 1.0))
        } else {
            format!("{:>8}", "-")
        }
    };
    for s in &r.stations {
        out.push_str(&format!(
            "  {:>5.2} {:>12.4e} {:>12.4e} {:>12.4e} {} {} {:>12.4e} {:>12.4e} {:>12.4e} {} {}\n",
            s.s,
            s.ux,
            s.ux_closed_form,
            s.ux_fem,
            pct(s.ux, s.ux_closed_form),
            pct(s.ux, s.ux_fem),
            s.uz,
            s.uz_closed_form,
            s.uz_fem,
            pct(s.uz, s.uz_closed_form),
            pct(s.uz, s.uz_fem)
        ));
    }
    out.push_str(&format!(
        "  error over s >= 0.2 m (max |diff| / max |closed form|): u_x {:.2}%, u_z {:.2}% (tolerance 3%)\n  against the clamped column's 3D FEM (reference/case1_fem.json; the closed form is {:.2}% / {:.2}% from it): u_x {:.2}%, u_z {:.2}%\n  support reaction {:.2} N, weight {:.2} N\n  {}\n",
        100.0 * r.error_ux,
        100.0 * r.error_uz,
        100.0 * line_error(&r.stations, |s| s.ux_closed_form, |s| s.ux_fem),
        100.0 * line_error(&r.stations, |s| s.uz_closed_form, |s| s.uz_fem),
        100.0 * r.error_ux_fem,
        100.0 * r.error_uz_fem,
        r.reaction_z,
        r.weight,
        summary_text(&r.run)
    ));
    out
}

/// Case 2 as a text table.
pub fn case2_text(r: &Case2Report) -> String {
    let mut out = format!(
        "Case 2: clamped-pinned beam, first mode, dp = {} m, model {:?}\n  {:<26} {:>10} {:>10} {:>14}\n",
        r.dp, r.model, "source", "period (s)", "freq (Hz)", "peak defl (m)"
    );
    let row = |name: &str, f: f64, d: Option<f64>| {
        format!(
            "  {:<26} {:>10.4} {:>10.3} {:>14}\n",
            name,
            1.0 / f,
            f,
            d.map(|d| format!("{d:.4e}")).unwrap_or_else(|| "-".into())
        )
    };
    out.push_str(&row("this run", r.frequency_hz, Some(r.peak_deflection_m)));
    out.push_str(&row(
        "3D FEM (reference)",
        r.fem.f1_hz,
        Some(r.fem.peak_dynamic_uz_m),
    ));
    out.push_str(&row("Timoshenko", r.fem.timoshenko_f1_hz, None));
    out.push_str(&row(
        "Euler-Bernoulli",
        r.euler_bernoulli_hz,
        Some(2.0 * r.euler_bernoulli_static_m),
    ));
    for (name, _, f, d) in PAPER_TABLE1 {
        out.push_str(&row(name, f, Some(d)));
    }
    out.push_str(&format!(
        "  frequency vs 3D FEM {:+.2}% (tolerance 3%), peak deflection vs 3D FEM {:+.2}%\n  (EB peak = 2 x static {:.3e} m; FEM static max {:.3e} m at x = {:.3} m; the paper's deflections are ~10x too large, see docs/paper-cases.md)\n  {}\n",
        100.0 * r.frequency_error,
        100.0 * r.peak_error,
        r.euler_bernoulli_static_m,
        r.fem.static_max_uz_m,
        r.fem.static_max_x_m,
        summary_text(&r.run)
    ));
    out
}

/// One line of run figures.
pub fn summary_text(r: &RunSummary) -> String {
    format!(
        "{} particles, {} bonds, {} steps of {:.3e} s (critical {:.3e} s), {:.2} s wall, {:.3e} pair-updates/s, {:.1} s of wall time per simulated second{}",
        r.particles,
        r.bonds,
        r.steps,
        r.dt,
        r.critical_dt,
        r.wall_time_s,
        r.pair_updates_per_s,
        r.wall_time_s / r.simulated_s,
        r.error.as_ref().map(|e| format!(", STOPPED: {e}")).unwrap_or_default()
    )
}
