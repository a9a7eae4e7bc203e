//! Peers in the benchmark (issue 25): the same lattice through our operators and through
//! LAMMPS' peridynamic pair styles, interleaved in one run, as time per particle-step.
//!
//! The lattice: a cube of n^3 particles on the simple cubic lattice of spacing dp (n = 30,
//! dp = 0.025 m), rho 1000 kg/m^3, E 1e8 Pa, nu 1/4 (the Poisson ratio of bond-based
//! peridynamics in 3D), bonds to 2.1 dp (32 neighbours: our re and LAMMPS' horizon), the bottom
//! layer held, gravity -z, a fixed step dt. LAMMPS runs the inputs of bench/lammps (embedded
//! here, so a fresh clone needs only `lmp` on the PATH, e.g. Debian's `lammps` package);
//! without `lmp` the peers are skipped with a message. Our figure: wall time of `steps` steps
//! after one untimed step, in a rayon pool of the given threads; LAMMPS': its own "Loop time"
//! (set-up excluded), with `mpirun -np T` for T > 1 threads. Set-up: our Simulation::new; LAMMPS'
//! process wall time less its loop time.
use crate::physics::ElasticModel;
use crate::scene::Scene;
use crate::sim::Simulation;
use std::fmt::Write;
use std::time::Instant;

/// The LAMMPS inputs, by pair style.
pub const LAMMPS_INPUTS: &[(&str, &str)] = &[
    ("peri/pmb", include_str!("../../bench/lammps/peri_pmb.in")),
    ("peri/lps", include_str!("../../bench/lammps/peri_lps.in")),
    (
        "bpm/rotational",
        include_str!("../../bench/lammps/bpm_rotational.in"),
    ),
];

/// Young's modulus (Pa), Poisson ratio and density (kg/m^3) of the benchmark lattice.
pub const YOUNG: f64 = 1e8;
pub const POISSON: f64 = 0.25;
pub const DENSITY: f64 = 1000.0;

/// The benchmark lattice with `model`: n^3 particles of spacing dp (m), bottom layer clamped
/// (held as a grip, no mirror: the second-order operator keeps its plain fits), gravity -z, a
/// fixed step dt (s).
pub fn cube_scene(n: usize, dp: f64, model: ElasticModel, dt: f64) -> Scene {
    let side = n as f64 * dp;
    let name = match model {
        ElasticModel::Corrected => "corrected",
        ElasticModel::SecondOrder => "second_order",
        ElasticModel::Paper => "paper",
        ElasticModel::PaperLocal => "paper_local",
    };
    let text = serde_json::json!({
        "name": format!("peers_cube{n}"),
        "dimension": 3,
        "particle_spacing": dp,
        "solver": { "model": name, "dt": dt, "re_factor": 2.1, "max_particles": 100_000_000u64 },
        "gravity": { "vector": [0.0, 0.0, -9.81] },
        "bodies": [{
            "name": "cube",
            "material": { "density": DENSITY, "young": YOUNG, "poisson": POISSON },
            "boxes": [{ "min": [0.0, 0.0, 0.0], "max": [side, side, side] }]
        }],
        "boundaries": [{
            "name": "bottom",
            "kind": "clamped",
            "body": "cube",
            "region": { "min": [-dp, -dp, -dp], "max": [side + dp, side + dp, dp] }
        }],
        "end_time": 1.0,
        "output_interval": 1.0
    });
    serde_json::from_value(text).expect("the benchmark cube is a valid scene")
}

/// One timing: set-up (s) and time per particle-step (s).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Timing {
    pub setup_s: f64,
    pub per_particle_step_s: f64,
    pub particles: usize,
}

/// Runs `f` in a rayon pool of `threads` threads (the current thread without rayon).
pub fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> Result<T, String> {
    #[cfg(feature = "parallel")]
    {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| e.to_string())?;
        Ok(pool.install(f))
    }
    #[cfg(not(feature = "parallel"))]
    {
        let _ = threads;
        Ok(f())
    }
}

/// Our operator on the benchmark lattice: build, one untimed step, then `steps` timed steps.
pub fn time_ours(scene: &Scene, threads: usize, steps: u64) -> Result<Timing, String> {
    with_threads(threads, || {
        let t0 = Instant::now();
        let mut sim = Simulation::new(scene).map_err(|e| e.to_string())?;
        let setup_s = t0.elapsed().as_secs_f64();
        let dt = scene.solver.dt.ok_or("the benchmark takes a fixed step")?;
        sim.advance_to(dt).map_err(|e| e.to_string())?;
        let t1 = Instant::now();
        sim.advance_to((steps + 1) as f64 * dt)
            .map_err(|e| e.to_string())?;
        let run = t1.elapsed().as_secs_f64();
        let taken = sim.steps() - 1;
        Ok(Timing {
            setup_s,
            per_particle_step_s: run / (taken as f64 * sim.particles() as f64),
            particles: sim.particles(),
        })
    })?
}

/// Whether `lmp` runs here, and whether it has `style` (its `-h` lists the styles it has).
pub fn lammps_has(style: &str) -> Result<(), String> {
    let out = std::process::Command::new("lmp")
        .arg("-h")
        .output()
        .map_err(|e| format!("LAMMPS (`lmp`) is not installed or not on the PATH ({e}); on Debian: apt-get install lammps"))?;
    let help = String::from_utf8_lossy(&out.stdout);
    if help.split_whitespace().any(|w| w == style) {
        Ok(())
    } else {
        Err(format!(
            "this LAMMPS build has no {style} style (its package is not compiled in)"
        ))
    }
}

/// One LAMMPS run of the benchmark lattice with pair style `style` on `procs` MPI ranks.
pub fn time_lammps(
    style: &str,
    n: usize,
    dp: f64,
    dt: f64,
    steps: u64,
    procs: usize,
) -> Result<Timing, String> {
    lammps_has(style)?;
    let input = LAMMPS_INPUTS
        .iter()
        .find(|(s, _)| *s == style)
        .ok_or_else(|| format!("no input for {style}"))?
        .1;
    let dir = std::env::temp_dir().join(format!("mps-peers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let file = dir.join("in.lmp");
    std::fs::write(&file, input).map_err(|e| e.to_string())?;
    let vars = [
        ("n", n.to_string()),
        ("dp", format!("{dp:e}")),
        ("dt", format!("{dt:e}")),
        ("steps", steps.to_string()),
    ];
    let mut cmd = if procs > 1 {
        let mut c = std::process::Command::new("mpirun");
        c.args(["--allow-run-as-root", "--oversubscribe", "-np"])
            .arg(procs.to_string())
            .arg("lmp");
        c
    } else {
        std::process::Command::new("lmp")
    };
    cmd.current_dir(&dir)
        .env("OMP_NUM_THREADS", "1")
        .arg("-in")
        .arg(&file)
        .args(["-log", "none"]);
    for (k, v) in &vars {
        cmd.args(["-var", k, v]);
    }
    let t0 = Instant::now();
    let out = cmd
        .output()
        .map_err(|e| format!("cannot run LAMMPS: {e}"))?;
    let wall = t0.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&dir);
    let text = String::from_utf8_lossy(&out.stdout);
    // "Loop time of 5.17166 on 1 procs for 50 steps with 27000 atoms"
    let line = text
        .lines()
        .find(|l| l.starts_with("Loop time of"))
        .ok_or_else(|| {
            let err = text
                .lines()
                .chain(String::from_utf8_lossy(&out.stderr).lines())
                .find(|l| l.contains("ERROR"))
                .unwrap_or("no 'Loop time' line")
                .to_string();
            format!("LAMMPS {style} failed: {err}")
        })?;
    let w: Vec<&str> = line.split_whitespace().collect();
    let loop_s: f64 = w
        .get(3)
        .and_then(|s| s.parse().ok())
        .ok_or("bad Loop line")?;
    let nsteps: f64 = w
        .get(8)
        .and_then(|s| s.parse().ok())
        .ok_or("bad Loop line")?;
    let atoms: usize = w
        .get(11)
        .and_then(|s| s.parse().ok())
        .ok_or("bad Loop line")?;
    Ok(Timing {
        setup_s: wall - loop_s,
        per_particle_step_s: loop_s / (nsteps * atoms as f64),
        particles: atoms,
    })
}

/// One row of the peers table: a code, its per-particle-step times (us) of each round on 1
/// and 2 threads, its set-up (s) on 2 threads.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PeerRow {
    pub code: String,
    pub one: Vec<f64>,
    pub two: Vec<f64>,
    pub setup_s: Vec<f64>,
    /// Why the code did not run (then the figures are empty).
    pub skipped: Option<String>,
}

fn best(v: &[f64]) -> Option<f64> {
    v.iter().copied().reduce(f64::min)
}

/// Runs every code `rounds` times, interleaved (round 1 of each, then round 2, ...), on 1 and
/// 2 threads, `steps` steps each, on the n^3 lattice of spacing dp with step dt.
pub fn run_peers(n: usize, dp: f64, dt: f64, steps: u64, rounds: usize) -> Vec<PeerRow> {
    let ours = [
        ("mps corrected", ElasticModel::Corrected),
        (
            "mps second_order (default, plain fits)",
            ElasticModel::SecondOrder,
        ),
    ];
    let mut rows: Vec<PeerRow> = ours
        .iter()
        .map(|(name, _)| PeerRow {
            code: name.to_string(),
            ..Default::default()
        })
        .chain(LAMMPS_INPUTS.iter().map(|(s, _)| PeerRow {
            code: format!("LAMMPS {s}"),
            skipped: lammps_has(s).err(),
            ..Default::default()
        }))
        .collect();
    for round in 0..rounds {
        for (k, (name, model)) in ours.iter().enumerate() {
            let scene = cube_scene(n, dp, *model, dt);
            for threads in [1, 2] {
                eprintln!("peers: round {}, {name}, {threads} thread(s)", round + 1);
                match time_ours(&scene, threads, steps) {
                    Ok(t) => {
                        let us = 1e6 * t.per_particle_step_s;
                        if threads == 1 {
                            rows[k].one.push(us);
                        } else {
                            rows[k].two.push(us);
                            rows[k].setup_s.push(t.setup_s);
                        }
                    }
                    Err(e) => rows[k].skipped = Some(e),
                }
            }
        }
        for (k, (style, _)) in LAMMPS_INPUTS.iter().enumerate() {
            let row = &mut rows[ours.len() + k];
            if row.skipped.is_some() {
                continue;
            }
            for procs in [1, 2] {
                eprintln!(
                    "peers: round {}, LAMMPS {style}, {procs} rank(s)",
                    round + 1
                );
                match time_lammps(style, n, dp, dt, steps, procs) {
                    Ok(t) => {
                        let us = 1e6 * t.per_particle_step_s;
                        if procs == 1 {
                            row.one.push(us);
                        } else {
                            row.two.push(us);
                            row.setup_s.push(t.setup_s);
                        }
                    }
                    Err(e) => {
                        row.skipped = Some(e);
                        break;
                    }
                }
            }
        }
    }
    rows
}

/// The peers table as Markdown: best round per code, and the ratio to LAMMPS peri/pmb and to
/// our corrected operator on one thread.
pub fn peers_markdown(rows: &[PeerRow], n: usize, dp: f64, dt: f64, steps: u64) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "## Peers: the same lattice through LAMMPS (issue 25)\n"
    );
    let _ = writeln!(out, "`mps bench --peers`: a cube of {n}^3 particles, dp {dp} m, E {YOUNG:e} Pa, nu {POISSON}, rho {DENSITY}, bonds / horizon 2.1 dp (32 neighbours), bottom layer held, gravity, fixed dt {dt:e} s, {steps} timed steps; the codes interleaved in rounds, best round shown (all rounds in brackets). LAMMPS: its Loop time, `mpirun -np 2` for 2 threads (its Debian build has no OpenMP styles); ours: a rayon pool. Ratios are per particle-step on one thread.\n");
    let _ = writeln!(out, "| code | us per particle-step, 1 thread | 2 threads | speed-up | set-up, 2 threads (s) | / LAMMPS peri/pmb | / mps corrected |");
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    let pmb = rows
        .iter()
        .find(|r| r.code == "LAMMPS peri/pmb")
        .and_then(|r| best(&r.one));
    let corr = rows
        .iter()
        .find(|r| r.code == "mps corrected")
        .and_then(|r| best(&r.one));
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for r in rows {
        if let (Some(why), true) = (&r.skipped, r.one.is_empty()) {
            let _ = writeln!(out, "| {} | skipped: {why} | | | | | |", r.code);
            continue;
        }
        let (b1, b2) = (best(&r.one), best(&r.two));
        let f = |x: Option<f64>, d: usize| x.map_or("-".into(), |x| format!("{x:.d$}"));
        let ratio = |base: Option<f64>| match (b1, base) {
            (Some(a), Some(b)) => format!("{:.2}", a / b),
            _ => "-".into(),
        };
        let _ = writeln!(
            out,
            "| {} | {} ({}) | {} ({}) | {} | {} | {} | {} |",
            r.code,
            f(b1, 3),
            list(&r.one),
            f(b2, 3),
            list(&r.two),
            match (b1, b2) {
                (Some(a), Some(b)) => format!("{:.2}", a / b),
                _ => "-".into(),
            },
            f(best(&r.setup_s), 2),
            ratio(pmb),
            ratio(corr),
        );
    }
    out
}

/// `doc` with its "## Peers" section (to the next "## " heading or the end) replaced by
/// `section`, or `section` appended when it has none.
pub fn replace_section(doc: &str, section: &str) -> String {
    replace_section_named(doc, "## Peers", section)
}

/// `doc` with its section headed `head` (to the next "## " heading or the end) replaced by
/// `section`, or `section` appended when it has none.
pub fn replace_section_named(doc: &str, head: &str, section: &str) -> String {
    let Some(start) = doc.find(head) else {
        let sep = if doc.is_empty() || doc.ends_with("\n\n") {
            ""
        } else if doc.ends_with('\n') {
            "\n"
        } else {
            "\n\n"
        };
        return format!("{doc}{sep}{section}");
    };
    let rest = &doc[start + head.len()..];
    match rest.find("\n## ") {
        Some(k) => {
            let next = start + head.len() + k + 1;
            format!(
                "{}{}\n\n{}",
                &doc[..start],
                section.trim_end(),
                &doc[next..]
            )
        }
        None => format!("{}{}\n", &doc[..start], section.trim_end()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_peers_section_is_replaced_in_place_or_appended() {
        let doc = "# A\n\ntext\n\n## Peers: old\n\nold table\n\n## B\n\nb\n";
        let new = replace_section(doc, "## Peers: new\n\nnew table\n");
        assert_eq!(
            new,
            "# A\n\ntext\n\n## Peers: new\n\nnew table\n\n## B\n\nb\n"
        );
        let last = replace_section("# A\n\n## Peers\n\nold\n", "## Peers\n\nnew\n");
        assert_eq!(last, "# A\n\n## Peers\n\nnew\n");
        assert_eq!(replace_section("# A\n", "## Peers\n"), "# A\n\n## Peers\n");
    }

    #[test]
    fn the_benchmark_cube_has_the_lattice_and_clamp_it_names() {
        let s = cube_scene(6, 0.025, ElasticModel::SecondOrder, 1e-5);
        let sim = Simulation::new(&s).unwrap();
        assert_eq!(sim.particles(), 216);
        assert_eq!(s.solver.dt, Some(1e-5));
    }
}
