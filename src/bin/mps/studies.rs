//! The study commands of the command line (cargo feature `studies`): the paper's cases against
//! their references (`mps cases`, the main job), the benchmark, case 3 and its Figure 9, and the
//! scene files of scenes/.
use super::cases::{run_all, CaseRun, CaseSettings};
use super::{progress, Model};
use clap::Subcommand;
use mps_solid::physics::ElasticModel;
use mps_solid::scene::limits::num;
use mps_solid::Scene;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Subcommand)]
pub enum StudyCmd {
    /// Run the paper's three cases and print each result beside its references.
    Cases {
        /// Cases to run, repeatable (default: 1, 2 and 3).
        #[arg(long = "case", value_parser = clap::value_parser!(u8).range(1..=3))]
        case: Vec<u8>,
        /// Particle spacing of cases 1 and 2 (m); the paper uses 0.025. Case 3 keeps the
        /// paper's 0.05.
        #[arg(long, default_value_t = 0.025)]
        dp: f64,
        /// Models of cases 1 and 2 (default: second_order, the default operator, and corrected
        /// for both, plus the paper's operators for case 2). Case 3 runs its scene's operator,
        /// corrected, as scenes/case3_collision.json names it.
        #[arg(long, value_enum)]
        model: Vec<Model>,
        /// Fixed time step (s) instead of the automatic one (the paper uses 1e-5), all cases.
        #[arg(long)]
        dt: Option<f64>,
        /// End time of case 3 (s); the paper's is 1.7 (both variants, side by side, the one
        /// without fractured-surface contact going on from the other's state where they part:
        /// about 25 s on 2 cores).
        #[arg(long, default_value_t = 1.7)]
        case3_end: f64,
        /// Print JSON instead of tables.
        #[arg(long)]
        json: bool,
        /// Runs at a time, each on its share of the threads (default: one per thread, which
        /// finishes first; 1: one after the other on all threads, for each run's wall time on
        /// all of them).
        #[arg(long)]
        jobs: Option<usize>,
    },
    /// Benchmark: run time against error for cases 1 and 2 (prints Markdown; see BENCHMARKS.md).
    Bench {
        /// Two small runs only.
        #[arg(long)]
        quick: bool,
        /// Also write the Markdown into this file.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Only the bending front (GMS plate and slender cantilever, each operator, against
        /// their FEM references), without the paper cases.
        #[arg(long)]
        bending: bool,
        /// Write the bending front as a PNG (wall time against error).
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Also the cantilever at 16 across with second_order (41,728 particles; about 20
        /// minutes more on 2 cores), for its order of convergence.
        #[arg(long)]
        fine: bool,
        /// Only issue 24's family of bodies written as a user writes them (single-box
        /// cantilevers with the clamp written four ways, stepped cantilevers, L-bracket, plate
        /// with a hole) at 4 and 8 particles through the thinnest section, linearised against
        /// the FEM, and the first peak under sudden gravity in the time domain; with --fine also
        /// the 3D shapes.
        #[arg(long)]
        family: bool,
        /// Only the peers: the benchmark cube through our operators and LAMMPS (peri/pmb,
        /// peri/lps, bpm/rotational; skipped with a message without `lmp`), interleaved, on 1
        /// and 2 threads. With --out, the table replaces the file's "## Peers" section.
        #[arg(long)]
        peers: bool,
        /// Only the real-time figures: cases 1 and 2 and the slender 3D cantilever with the
        /// default operator at the coarsest spacing within 1 % of the FEM, driven through the
        /// FMI instance in 1 ms communication steps (wall time per simulated second). With
        /// --out, the table replaces the file's "## Real time" section.
        #[arg(long)]
        realtime: bool,
        /// Particles along the cube's side for --peers.
        #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u64).range(4..=400))]
        peers_n: u64,
        /// Timed steps per run for --peers.
        #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(1..))]
        peers_steps: u64,
        /// Rounds of --peers (the codes interleaved in each).
        #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=20))]
        peers_rounds: u64,
    },
    /// Run the paper's case 3 (cube hits a block; contact and fracture), both variants by default.
    Case3 {
        /// Particle spacing (m); the paper uses 0.05.
        #[arg(long, default_value_t = mps_solid::studies::case3::CASE3_DP)]
        dp: f64,
        /// End time (s) (default 1.7, or the end_time of --scene).
        #[arg(long)]
        end: Option<f64>,
        /// Run this scene file (a case 3 variant, e.g. from a parameter sweep) instead of the
        /// generated scenes; --dp and --fractured-contact are then ignored.
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Only the variant with contact detection between fractured surfaces (on) or without (off).
        #[arg(long, value_parser = ["on", "off"])]
        fractured_contact: Option<String>,
        /// Write ParaView (VTU + PVD) and PNG snapshots every 0.1 s into this directory.
        #[arg(long)]
        snapshots: Option<PathBuf>,
        /// Write the paper's Figure 9 into this directory: 3D views of the run without (left) and
        /// with (right) contact between fractured surfaces at --figure9-times, as NAME.png (both
        /// columns, one row per instant) and NAME_without_tT.png / NAME_with_tT.png. Runs both
        /// variants (of --scene too: its fractured_surfaces is set off, then on).
        #[arg(long, conflicts_with = "fractured_contact")]
        figure9: Option<PathBuf>,
        /// Instants of --figure9 (s), increasing, comma separated (default: the paper's).
        #[arg(long, value_delimiter = ',', default_values_t = [0.07, 0.6, 0.7, 1.0, 1.7])]
        figure9_times: Vec<f64>,
        /// File name stem of the --figure9 images.
        #[arg(long, default_value = "figure9")]
        figure9_name: String,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Write the paper's scene files (as used under scenes/) into a directory.
    Scenes {
        #[arg(default_value = "scenes")]
        dir: PathBuf,
        /// The `$schema` each file names (editors check the scene against it): the schema's
        /// address relative to DIR, or a URL.
        #[arg(long, default_value = "../schema/scene.schema.json")]
        schema_ref: String,
    },
    /// Run one of the accuracy studies and diagnostics kept for their figures (docs/studies.md);
    /// `--list` names them.
    Study {
        /// The study's name (see --list).
        #[arg(required_unless_present = "list")]
        name: Option<String>,
        /// List the studies with a line each.
        #[arg(long)]
        list: bool,
        /// Arguments of the study (as its doc comment describes).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

pub fn run(cmd: StudyCmd) -> Result<ExitCode, String> {
    match cmd {
        StudyCmd::Cases {
            case,
            dp,
            model,
            dt,
            case3_end,
            json,
            jobs,
        } => {
            let cases: Vec<u8> = if case.is_empty() { vec![1, 2, 3] } else { case };
            if !(case3_end.is_finite() && case3_end > 0.0) {
                return Err(format!(
                    "--case3-end must be a positive finite time (s), got {}",
                    num(case3_end)
                ));
            }
            let runs: Vec<(u8, ElasticModel)> = if model.is_empty() {
                vec![
                    (1, ElasticModel::SecondOrder),
                    (1, ElasticModel::Corrected),
                    (2, ElasticModel::SecondOrder),
                    (2, ElasticModel::Corrected),
                    (2, ElasticModel::Paper),
                    (2, ElasticModel::PaperLocal),
                ]
            } else {
                model
                    .iter()
                    .flat_map(|&m| [(1, m.into()), (2, m.into())])
                    .collect()
            };
            let runs: Vec<(u8, ElasticModel)> = runs
                .into_iter()
                .filter(|(c, _)| cases.contains(c))
                .collect();
            let mut all: Vec<CaseRun> =
                runs.into_iter().map(|(c, m)| CaseRun::Beam(c, m)).collect();
            if cases.contains(&3) {
                all.extend([CaseRun::Collision(true), CaseRun::Collision(false)]);
            }
            let jobs = jobs
                .unwrap_or_else(rayon::current_num_threads)
                .clamp(1, all.len().max(1));
            let settings = CaseSettings { dp, dt, case3_end };
            if !json && jobs > 1 {
                println!(
                    "{} runs, {jobs} at a time on {} thread(s) each: each run's wall time below is on its share (--jobs 1 runs them one after the other on all threads)\n",
                    all.len(),
                    (rayon::current_num_threads() / jobs).max(1)
                );
            }
            let mut out = Vec::new();
            let mut failed = false;
            run_all(&all, settings, jobs, |k, r, bars| {
                bars.suspend(|| {
                    if !json
                        && matches!(all[k], CaseRun::Collision(_))
                        && (k == 0 || !matches!(all[k - 1], CaseRun::Collision(_)))
                    {
                        println!(
                            "Case 3: cube hits block, dp = {} m, model Corrected, to {} s: the events of the paper's Figure 9 against its times",
                            mps_solid::studies::case3::CASE3_DP,
                            num(case3_end)
                        );
                    }
                    if let (Some(text), false) = (&r.text, json) {
                        println!("{text}");
                    }
                });
                failed |= r.failed;
                out.extend(r.value);
            });
            if json {
                println!("{}", serde_json::to_string_pretty(&out).unwrap());
            }
            Ok(if failed {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            })
        }
        StudyCmd::Bench {
            quick,
            out,
            bending,
            plot,
            fine,
            family,
            peers,
            realtime,
            peers_n,
            peers_steps,
            peers_rounds,
        } => {
            use mps_solid::studies::bench;
            // The output paths are checked before the minutes of work.
            if let Some(p) = &out {
                check_output_file(p, "--out")?;
            }
            if let Some(p) = &plot {
                check_output_file(p, "--plot")?;
            }
            if family {
                let ns: &[usize] = if quick { &[4] } else { &[4, 8] };
                let md = mps_solid::studies::family::family_markdown(ns, fine, true, None);
                println!("{md}");
                if let Some(path) = out {
                    std::fs::write(&path, md)
                        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
                }
                return Ok(ExitCode::SUCCESS);
            }
            if realtime {
                use mps_solid::studies::{peers, realtime};
                let rows = realtime::real_time_rows()?;
                let md = format!(
                    "## Real time at 1 % error (issue 25)\n\n`mps bench --realtime`, default operator.\n\n{}",
                    realtime::real_time_markdown(&rows)
                );
                println!("{md}");
                if let Some(path) = out {
                    let old = std::fs::read_to_string(&path).unwrap_or_default();
                    std::fs::write(
                        &path,
                        peers::replace_section_named(&old, "## Real time", &md),
                    )
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
                }
                return Ok(ExitCode::SUCCESS);
            }
            if peers {
                use mps_solid::studies::peers;
                let (n, dp, dt) = (peers_n as usize, 0.025, 1e-5);
                let rows = peers::run_peers(n, dp, dt, peers_steps, peers_rounds as usize);
                let md = peers::peers_markdown(&rows, n, dp, dt, peers_steps);
                println!("{md}");
                if let Some(path) = out {
                    let old = std::fs::read_to_string(&path).unwrap_or_default();
                    std::fs::write(&path, peers::replace_section(&old, &md))
                        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
                }
                return Ok(ExitCode::SUCCESS);
            }
            let front = bench::bending_front(quick, fine)?;
            let front_md = bench::bending_markdown(&front, threads());
            if let Some(p) = &plot {
                bench::write_front_png(&front, p)?;
            }
            if bending {
                println!("{front_md}");
                if let Some(path) = out {
                    std::fs::write(&path, front_md)
                        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
                }
                return Ok(ExitCode::SUCCESS);
            }
            let mut rows = Vec::new();
            for (case, dp, dt) in bench::plan(quick) {
                eprintln!("bench: case {case}, dp {dp}, dt {dt:?}");
                let row = bench::run_row(case, dp, dt)?;
                eprintln!(
                    "  {} steps, {:.2} s, error {:+.2}%",
                    row.steps,
                    row.wall_s,
                    100.0 * row.error
                );
                rows.push(row);
            }
            if !quick {
                eprintln!("bench: case 3");
                rows.push(bench::case3_row()?);
            }
            let single: Vec<(&str, f64)> = [
                ("corrected", ElasticModel::Corrected),
                ("second_order", ElasticModel::SecondOrder),
            ]
            .into_iter()
            .filter_map(|(name, m)| Some((name, bench::single_thread_throughput(m).ok()?)))
            .collect();
            let fmu = bench::fmu_overhead().ok();
            let stability: Vec<(f64, String)> = if quick {
                vec![]
            } else {
                [0.8, 1.0, 1.25, 2.0]
                    .iter()
                    .map(|&f| (f, bench::stability_probe(f)))
                    .collect()
            };
            let md = bench::markdown(&rows, &single, &stability, fmu, threads()) + "\n" + &front_md;
            println!("{md}");
            if let Some(path) = out {
                std::fs::write(&path, md)
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            }
            Ok(ExitCode::SUCCESS)
        }
        StudyCmd::Case3 {
            dp,
            end,
            scene: scene_file,
            fractured_contact,
            snapshots,
            figure9,
            figure9_times,
            figure9_name,
            json,
        } => {
            use mps_solid::studies::case3::{
                case3_report_with, case3_scene, case3_text, CheckPoint, Figure9Capture,
                Figure9Column,
            };
            let from_file = match &scene_file {
                Some(p) => Some(Scene::load(p).map_err(|e| e.to_string())?),
                None => None,
            };
            let end = end.unwrap_or(from_file.as_ref().map_or(1.7, |s| s.end_time));
            if !(end.is_finite() && end > 0.0) {
                return Err(format!(
                    "--end must be a positive finite time (s), got {}",
                    num(end)
                ));
            }
            if !(dp.is_finite() && dp > 0.0) {
                return Err(format!(
                    "--dp must be a positive finite spacing (m), got {}",
                    num(dp)
                ));
            }
            if let Some(dir) = &figure9 {
                // Refuse bad instants, a bad name and an unusable directory before any run.
                Figure9Capture::new(&figure9_times)?;
                if let Some(t) = figure9_times.iter().find(|&&t| t > end + 1e-9) {
                    return Err(format!(
                        "--figure9-times {} s is after the end of the run ({} s, --end)",
                        num(*t),
                        num(end)
                    ));
                }
                std::fs::create_dir_all(dir)
                    .map_err(|e| format!("cannot create the directory {}: {e}", dir.display()))?;
                mps_solid::studies::case3::check_figure9_name(dir, &figure9_name, &figure9_times)?;
            }
            let scenes: Vec<Scene> = match from_file {
                Some(s) if figure9.is_some() => [false, true]
                    .into_iter()
                    .map(|fc| {
                        // Two names, so that --snapshots keeps both series apart.
                        let mut v = s.clone();
                        v.solver.contact.fractured_surfaces = fc;
                        let base = s.name.trim_end_matches("_no_fracture_contact");
                        v.name = if fc {
                            base.to_string()
                        } else {
                            format!("{base}_no_fracture_contact")
                        };
                        v
                    })
                    .collect(),
                Some(s) => vec![s],
                None if figure9.is_some() => [false, true]
                    .into_iter()
                    .map(|fc| case3_scene(dp, fc, ElasticModel::Corrected))
                    .collect(),
                None => {
                    let variants: Vec<bool> = match fractured_contact.as_deref() {
                        Some("on") => vec![true],
                        Some("off") => vec![false],
                        _ => vec![true, false],
                    };
                    variants
                        .into_iter()
                        .map(|fc| case3_scene(dp, fc, ElasticModel::Corrected))
                        .collect()
                }
            };
            let subtitle = scenes.first().map(figure9_subtitle).unwrap_or_default();
            let title = match &scene_file {
                Some(p) => format!(
                    "Case 3 variant {}: cube hits block (cf. the paper's Figure 9)",
                    p.display()
                ),
                None => "Case 3: cube hits block (cf. the paper's Figure 9)".to_string(),
            };
            let mut columns = Vec::new();
            let mut body_names = Vec::new();
            let mut reports = Vec::new();
            for mut scene in scenes {
                scene.end_time = end;
                scene
                    .validate()
                    .map_err(|e| format!("{e} (from --end/--dp)"))?;
                let pb = progress(end, &scene.name);
                let mut snaps = Vec::new();
                let mut next_snap = 0.0;
                let mut capture = match figure9 {
                    Some(_) => Some(Figure9Capture::new(&figure9_times)?),
                    None => None,
                };
                let r = case3_report_with(&scene, end, 0.01, 0.0025, |sim, kind| {
                    if let Some(c) = capture.as_mut() {
                        c.check(sim, kind);
                    }
                    if kind != CheckPoint::Regular {
                        return;
                    }
                    pb.set_position((sim.time() * 1e6) as u64);
                    if snapshots.is_some() && sim.time() >= next_snap - 1e-9 {
                        snaps.push(sim.particle_snapshot());
                        next_snap += 0.1;
                    }
                })?;
                pb.finish_and_clear();
                if let Some(c) = capture {
                    body_names = c.body_names().to_vec();
                    let fc = scene.solver.contact.fractured_surfaces;
                    columns.push(Figure9Column {
                        heading: format!(
                            "{} fractured-surface contact",
                            if fc { "with" } else { "without" }
                        ),
                        tag: if fc { "with" } else { "without" }.to_string(),
                        panels: c.finish(&r)?,
                        failure: r.failure.clone(),
                    });
                }
                if let Some(dir) = &snapshots {
                    let files = mps_solid::output::write_series(
                        dir,
                        &scene.name,
                        &snaps,
                        Some(mps_solid::output::View::XZ),
                    )?;
                    eprintln!(
                        "wrote {} snapshot files into {}",
                        files.len(),
                        dir.display()
                    );
                }
                if !json {
                    println!("{}", case3_text(&r));
                }
                reports.push(r);
            }
            if let Some(dir) = &figure9 {
                let files = mps_solid::studies::case3::write_figure9(
                    dir,
                    &figure9_name,
                    &title,
                    &subtitle,
                    &body_names,
                    &columns,
                    mps_solid::output::Camera::default(),
                    Some(&mps_solid::studies::case3::figure9_foot()),
                )?;
                eprintln!(
                    "wrote Figure 9 ({} images) into {}: {}",
                    files.len(),
                    dir.display(),
                    files[0].display()
                );
            }
            if json {
                println!("{}", serde_json::to_string_pretty(&reports).unwrap());
            }
            Ok(ExitCode::SUCCESS)
        }
        StudyCmd::Study { name, list, args } => {
            use mps_solid::studies::programs;
            if list {
                for (n, d) in programs::PROGRAMS {
                    println!("{n:<20} {d}");
                }
                return Ok(ExitCode::SUCCESS);
            }
            let name = name.expect("clap requires a name without --list");
            let mut argv = vec![format!("mps study {name}")];
            argv.extend(args);
            programs::run(&name, argv)?;
            Ok(ExitCode::SUCCESS)
        }
        StudyCmd::Scenes { dir, schema_ref } => {
            std::fs::create_dir_all(&dir)
                .map_err(|e| format!("cannot create the directory {}: {e}", dir.display()))?;
            for sc in paper_scenes() {
                let path = dir.join(format!("{}.json", sc.name));
                std::fs::write(&path, sc.to_json_with_schema(&schema_ref) + "\n")
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Checks before any work that `path` (the value of `flag`) can be written: not a directory,
/// its directory exists and takes a new file, and an existing file is writable (opened to
/// append, which changes nothing).
fn check_output_file(path: &std::path::Path, flag: &str) -> Result<(), String> {
    let bad = |why: String| format!("{flag} {}: {why}", path.display());
    if path.is_dir() {
        return Err(bad("is a directory; give a file name".into()));
    }
    if path.file_name().is_none() {
        return Err(bad("does not name a file".into()));
    }
    let dir = match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(d) => d.to_path_buf(),
        None => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(bad(format!(
            "its directory {} does not exist (or is not a directory)",
            dir.display()
        )));
    }
    let probe = dir.join(format!(".mps-write-check.{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|e| bad(format!("cannot create a file in {}: {e}", dir.display())))?;
    let _ = std::fs::remove_file(&probe);
    if path.exists() {
        std::fs::OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(|e| bad(format!("cannot be written: {e}")))?;
    }
    Ok(())
}

/// The scene files of scenes/: the paper's cases at the paper's spacing and the bending
/// benchmarks of issue 7.
fn paper_scenes() -> Vec<Scene> {
    let mut v = mps_solid::studies::cases::paper_scenes();
    v.extend(mps_solid::studies::bending::benchmark_scenes());
    v
}

/// The second title line of Figure 9: what the scene's options are.
fn figure9_subtitle(s: &Scene) -> String {
    let eps = s
        .solver
        .fracture_strain
        .map_or("none".to_string(), |e| format!("{e}"));
    let snake = |d: String| {
        d.chars().fold(String::new(), |mut o, c| {
            if c.is_uppercase() && !o.is_empty() {
                o.push('_');
            }
            o.push(c.to_ascii_lowercase());
            o
        })
    };
    format!(
        "dp {} m, eps_max {eps} (paper 0.2), {} operator, bond strain {}\nleft: no contact between fractured surfaces (crack faces pass through each other); right: with (they repel)",
        s.particle_spacing,
        snake(format!("{:?}", s.solver.model)),
        snake(format!("{:?}", s.solver.bond_strain)),
    )
}

/// Worker threads of the solver (1 without the `parallel` feature).
fn threads() -> usize {
    #[cfg(feature = "parallel")]
    return rayon::current_num_threads();
    #[cfg(not(feature = "parallel"))]
    1
}
