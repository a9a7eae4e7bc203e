//! Command line: run a scene, pack an FMU, print the scene schema; with the `studies` feature also the paper's cases,
//! the benchmark and case 3 (src/bin/mps/studies.rs).
use clap::{Parser, Subcommand, ValueEnum};
#[cfg(feature = "studies")]
mod cases;
mod studies;
use indicatif::{ProgressBar, ProgressStyle};
use mps_solid::physics::ElasticModel;
mod run_outputs;
mod run_progress;
use mps_solid::runner::{
    energy_csv, prepare_with_memo, run_prepared, series_csv, RunEvent, RunOptions,
};
use mps_solid::Scene;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "mps",
    version,
    about = "MPS particle solver for elastic solids (Amaro Junior, Cheng & Tsukamoto)"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Clone, Copy, ValueEnum)]
enum Model {
    SecondOrder,
    Corrected,
    Paper,
    PaperLocal,
}

impl From<Model> for ElasticModel {
    fn from(m: Model) -> Self {
        match m {
            Model::SecondOrder => ElasticModel::SecondOrder,
            Model::Corrected => ElasticModel::Corrected,
            Model::Paper => ElasticModel::Paper,
            Model::PaperLocal => ElasticModel::PaperLocal,
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a scene file (JSON or TOML): probe series as CSV, a summary, optionally JSON.
    Run {
        scene: PathBuf,
        /// Directory for probes.csv and summary.json (and energy.csv).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Also write energy.csv: kinetic, strain and contact energy and their sum at every
        /// output sample (a pass over the bonds per sample).
        #[arg(long)]
        energy: bool,
        /// Also write the bodies' surfaces as meshes with their displacements for ParaView:
        /// surface_NNNN.vtu (triangles; lines in 2D) at up to 101 evenly spaced output samples
        /// and surface.pvd listing them with their times.
        #[arg(long)]
        surface: bool,
        /// Print the result (including the series) as JSON on stdout.
        #[arg(long)]
        json: bool,
        /// Keep the default operator's closure (the longest stage of its set-up, a function
        /// of the geometry only) as a file in DIR, and take it from there when a run of the
        /// same geometry finds it: a sweep over materials, step or damping pays it once.
        /// Default: the environment variable MPS_CLOSURE_CACHE, else none.
        #[arg(long, value_name = "DIR")]
        closure_cache: Option<PathBuf>,
    },
    /// Pack a scene into an FMI 2.0 co-simulation FMU.
    Pack {
        /// Scene files (JSON or TOML); one FMU each.
        #[arg(required = true)]
        scenes: Vec<PathBuf>,
        /// Output file of a single scene (default: <scene name>.fmu).
        #[arg(long, conflicts_with = "out_dir")]
        out: Option<PathBuf>,
        /// Directory for the FMUs, <scene name>.fmu each.
        #[arg(long)]
        out_dir: Option<PathBuf>,
        /// The library to ship (default: the portable one that scripts/build-fmu-lib.sh builds,
        /// target/x86_64-unknown-linux-gnu/fmu/libmps_solid.so of the target directory this
        /// program was built in: stripped, linked against glibc 2.17). It must be built from the
        /// same sources as this program.
        #[arg(long)]
        lib: Option<PathBuf>,
        /// Write each scene's modelDescription.xml (without its generation time) as DIR/<name>.xml.
        #[arg(long, value_name = "DIR", conflicts_with = "check_xml")]
        write_xml: Option<PathBuf>,
        /// Fail when DIR/<name>.xml differs from the scene's generated modelDescription.xml.
        #[arg(long, value_name = "DIR")]
        check_xml: Option<PathBuf>,
        /// Only write or check the XML (--write-xml / --check-xml); pack nothing.
        #[arg(long)]
        xml_only: bool,
    },
    /// Print the JSON Schema of scene files (as committed in schema/scene.schema.json), or the
    /// scene reference page (docs/scene-reference.md) with --markdown.
    Schema {
        /// Print the reference page (Markdown: every field's type, unit, range, default).
        #[arg(long)]
        markdown: bool,
    },
    #[cfg(feature = "studies")]
    #[command(flatten)]
    Study(studies::StudyCmd),
}

fn progress(len: f64, label: &str) -> ProgressBar {
    let pb = ProgressBar::new((len * 1e6) as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:>24} [{bar:40}] {percent:>3}% {elapsed_precise} eta {eta}",
        )
        .unwrap()
        .progress_chars("=> "),
    );
    pb.set_message(label.to_string());
    pb
}

fn main() -> ExitCode {
    // A file-size limit (ulimit -f) makes a write fail with "File too large" (EFBIG), reported
    // with the file's name, instead of killing the program by SIGXFSZ with a partial file left.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_IGN before any other thread exists.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Set-up time after which `mps run` reports the set-up's stages on stderr (s): a quick set-up
/// stays silent, a long one shows its stages as they end (the ones before, at once).
const SETUP_REPORT_AFTER: f64 = 1.0;

/// The set-up's stage lines of a run: held until the set-up has taken [`SETUP_REPORT_AFTER`],
/// then written to stderr as they come.
#[derive(Default)]
struct SetupLines {
    held: Vec<String>,
    total: f64,
}

impl SetupLines {
    fn stage(&mut self, name: &str, seconds: f64, detail: &str) {
        let detail = if detail.is_empty() {
            String::new()
        } else {
            format!(" ({detail})")
        };
        self.held
            .push(format!("set-up: {name} took {seconds:.2} s{detail}"));
        self.total += seconds;
        if self.total >= SETUP_REPORT_AFTER {
            for l in self.held.drain(..) {
                eprintln!("{l}");
            }
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode, String> {
    match cli.cmd {
        Cmd::Run {
            scene,
            out,
            energy,
            surface,
            json,
            closure_cache,
        } => run_command(
            &scene,
            &out,
            energy,
            surface,
            json,
            closure_cache.or_else(|| std::env::var_os("MPS_CLOSURE_CACHE").map(PathBuf::from)),
        ),
        Cmd::Pack {
            scenes,
            out,
            out_dir,
            lib,
            write_xml,
            check_xml,
            xml_only,
        } => {
            if out.is_some() && scenes.len() > 1 {
                return Err("--out names one file: with several scenes use --out-dir".into());
            }
            // --xml-only packs no library: none is looked for.
            let lib = match lib {
                Some(l) => l,
                None if xml_only => PathBuf::new(),
                None => portable_library()?,
            };
            let mut failed = false;
            for scene in &scenes {
                if let Err(e) = pack_one(
                    scene,
                    &lib,
                    out.as_deref(),
                    out_dir.as_deref(),
                    write_xml.as_deref(),
                    check_xml.as_deref(),
                    xml_only,
                ) {
                    if scenes.len() == 1 {
                        eprintln!("error: {e}");
                    } else {
                        eprintln!("error: {}: {e}", scene.display());
                    }
                    failed = true;
                }
            }
            Ok(if failed {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            })
        }
        Cmd::Schema { markdown } => {
            use mps_solid::scene::schema;
            use std::io::Write;
            let text = if markdown {
                schema::reference_markdown()
            } else {
                schema::scene_schema_text()
            };
            std::io::stdout()
                .write_all(text.as_bytes())
                .and_then(|()| std::io::stdout().flush())
                .map_err(|e| format!("cannot write to stdout: {e}"))?;
            Ok(ExitCode::SUCCESS)
        }
        #[cfg(feature = "studies")]
        Cmd::Study(cmd) => studies::run(cmd),
    }
}

/// Set by SIGINT or SIGTERM during `mps run`: the run stops after its current step and writes
/// what it computed as partial results (a second signal ends the program at once).
static STOP: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

extern "C" fn on_interrupt(sig: libc::c_int) {
    if STOP.swap(true, std::sync::atomic::Ordering::Relaxed) {
        // SAFETY: signal and raise are async-signal-safe; the default action ends the program.
        unsafe {
            libc::signal(sig, libc::SIG_DFL);
            libc::raise(sig);
        }
    }
}

/// SIGINT and SIGTERM set [`STOP`] while this lives (the stepping of `mps run`); dropped, the
/// default actions are back.
struct StopOnInterrupt;

impl StopOnInterrupt {
    fn install() -> StopOnInterrupt {
        let handler = on_interrupt as extern "C" fn(libc::c_int) as libc::sighandler_t;
        // SAFETY: the handler only touches an atomic and async-signal-safe functions.
        unsafe {
            libc::signal(libc::SIGINT, handler);
            libc::signal(libc::SIGTERM, handler);
        }
        StopOnInterrupt
    }
}

impl Drop for StopOnInterrupt {
    fn drop(&mut self) {
        // SAFETY: restoring the default dispositions.
        unsafe {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            libc::signal(libc::SIGTERM, libc::SIG_DFL);
        }
    }
}

/// `mps run --surface`: the body's surface mesh is made at the first state, then written with
/// its displacements every `stride` output samples (at most 101 files, `surface_NNNN.vtu`) and
/// listed in `surface.pvd` once the run completed.
struct SurfaceFiles {
    out: std::path::PathBuf,
    samples: u64,
    stride: u64,
    index: u64,
    mesh: Option<mps_solid::scene::surface::SurfaceMesh>,
    pvd: mps_solid::output::PvdWriter,
    error: Option<String>,
}

impl SurfaceFiles {
    fn new(sc: &Scene, out: &std::path::Path) -> SurfaceFiles {
        let samples = (sc.end_time / sc.output_interval - 1e-9).ceil().max(1.0) as u64;
        SurfaceFiles {
            out: out.to_path_buf(),
            samples,
            stride: samples.div_ceil(100).max(1),
            index: 0,
            mesh: None,
            pvd: mps_solid::output::PvdWriter::new(),
            error: None,
        }
    }

    fn state(&mut self, sc: &Scene, sim: &mps_solid::Simulation) {
        let k = self.index;
        self.index += 1;
        if self.error.is_some() || (!k.is_multiple_of(self.stride) && k != self.samples) {
            return;
        }
        if self.mesh.is_none() {
            match sim.surface_mesh(sc) {
                Ok(m) => self.mesh = Some(m),
                Err(e) => {
                    self.error = Some(e.to_string());
                    return;
                }
            }
        }
        let m = self.mesh.as_ref().expect("made above");
        let name = format!(
            "surface_{:04}.vtu",
            k / self.stride + u64::from(!k.is_multiple_of(self.stride))
        );
        match mps_solid::output::write_surface_vtu(
            &self.out.join(&name),
            m,
            &sim.surface_displacement(m),
            sim.time(),
        ) {
            Ok(()) => self.pvd.add(sim.time(), name),
            Err(e) => self.error = Some(e),
        }
    }

    fn finish(self, complete: bool) -> Result<(), String> {
        if let Some(e) = self.error {
            return Err(format!("--surface: {e}"));
        }
        if complete {
            self.pvd.write(&self.out.join("surface.pvd"))?;
        }
        Ok(())
    }
}

/// `mps run`: the scene is built and checked first (a refusal touches no file), then the output
/// files are opened as temporary files in --out (an unusable directory fails before the run),
/// the run reports its progress on stderr, and the results replace the previous ones only when
/// the run completed. A run that stops early (blow-up, overlap) leaves the previous complete
/// results as they were and writes what it computed under names that say so:
/// probes.partial.csv, summary.partial.json (with the error) and energy.partial.csv; so does a
/// run stopped by Ctrl-C (SIGINT) or SIGTERM, after its current step.
fn run_command(
    scene: &std::path::Path,
    out: &std::path::Path,
    energy: bool,
    surface: bool,
    json: bool,
    closure_cache: Option<PathBuf>,
) -> Result<ExitCode, String> {
    let sc = Scene::load(scene).map_err(|e| e.to_string())?;
    let mut setup = SetupLines::default();
    let memo = closure_cache.map(mps_solid::physics::world::SetupMemo::in_dir);
    let sim = prepare_with_memo(&sc, memo.as_ref(), &mut |e| {
        if let RunEvent::Setup {
            stage,
            seconds,
            detail,
        } = e
        {
            setup.stage(stage.name(), seconds, detail)
        }
    });
    for note in memo.iter().flat_map(|m| m.take_notes()) {
        eprintln!("warning: closure cache: {note}");
    }
    let sim = sim?;
    let mut files = run_outputs::RunOutputs::open(out, energy)?;
    let mut progress = run_progress::RunProgress::new(&sc, &sim);
    let _interrupt = StopOnInterrupt::install();
    let opts = RunOptions {
        energy,
        stop: Some(&STOP),
    };
    let mut surface_files = surface.then(|| SurfaceFiles::new(&sc, out));
    let r = run_prepared(&sc, sim, opts, |e| {
        if let (RunEvent::State(sim), Some(f)) = (e, &mut surface_files) {
            f.state(&sc, sim);
        }
        progress.event(e)
    });
    progress.finish();
    // A run refused or failed without results: the temporary files go, nothing else changes.
    let r = r?;
    if let Some(f) = surface_files {
        f.finish(r.error.is_none())?;
    }
    let mut summary = serde_json::to_value(&r).map_err(|e| e.to_string())?;
    if let Some(o) = summary.as_object_mut() {
        o.remove("series");
    }
    let summary = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    let energy_text = energy.then(|| energy_csv(&r.series));
    let written = files.commit(
        &series_csv(&r.series, r.dimension),
        &summary,
        energy_text.as_deref(),
        r.error.is_none(),
    )?;
    if json {
        println!("{}", serde_json::to_string(&r).map_err(|e| e.to_string())?);
    } else {
        println!(
            "{}: {} particles, {} bonds, {} steps of {:.3e} s (critical {:.3e} s) to t = {} s in {:.2} s ({:.3e} pair-updates/s)",
            r.scene, r.particles, r.bonds, r.steps, r.dt, r.critical_dt, r.end_time, r.wall_time_s, r.pair_updates_per_s
        );
        for (name, u) in &r.final_displacement {
            println!(
                "  probe {name}: u = [{:.6e}, {:.6e}, {:.6e}] m",
                u[0], u[1], u[2]
            );
        }
        if let (Some(f), Some(p)) = (r.frequency_hz, r.peak_m) {
            println!("  frequency {f:.4} Hz, peak {p:.6e} m");
        }
        println!("  series written to {}", written.probes.display());
        if let Some(e) = &written.energy {
            println!("  energies written to {}", e.display());
        }
    }
    if let Some(e) = &r.error {
        eprintln!(
            "error: the run stopped early at t = {} s: {e}\n  what it computed up to then is in \
             {} and {}{}; the complete results of an earlier run in {} are kept",
            mps_solid::scene::limits::num(r.end_time),
            written.probes.display(),
            written.summary.display(),
            written
                .energy
                .as_ref()
                .map_or(String::new(), |p| format!(" (and {})", p.display())),
            out.display()
        );
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

/// `mps pack` of one scene: the FMU (unless `xml_only`), then the modelDescription.xml written
/// or checked against DIR/<name>.xml (the canonical form, without generationDateAndTime).
fn pack_one(
    scene: &std::path::Path,
    lib: &std::path::Path,
    out: Option<&std::path::Path>,
    out_dir: Option<&std::path::Path>,
    write_xml: Option<&std::path::Path>,
    check_xml: Option<&std::path::Path>,
    xml_only: bool,
) -> Result<(), String> {
    use mps_solid::fmi::pack::{model_description_xml, pack_fmu, same_file};
    let sc = Scene::load(scene).map_err(|e| e.to_string())?;
    if !xml_only {
        let out = match (out, out_dir) {
            (Some(o), _) => o.to_path_buf(),
            (None, Some(d)) => d.join(format!("{}.fmu", sc.name)),
            (None, None) => PathBuf::from(format!("{}.fmu", sc.name)),
        };
        if out == scene || same_file(&out, scene) {
            return Err(format!(
                "--out {} is the scene file itself; choose another output",
                out.display()
            ));
        }
        for w in sc.warnings() {
            eprintln!("warning: {w}");
        }
        if let Some(d) = out_dir {
            std::fs::create_dir_all(d)
                .map_err(|e| format!("cannot create the directory {}: {e}", d.display()))?;
        }
        pack_fmu(&sc, lib, &out)?;
        println!("wrote {} ({})", out.display(), packed_summary(&out, lib));
    }
    let xml = model_description_xml(&sc);
    if let Some(dir) = write_xml {
        let f = dir.join(format!("{}.xml", sc.name));
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create the directory {}: {e}", dir.display()))?;
        mps_solid::fmi::pack::replace_file(&f, xml.as_bytes())?;
        println!("wrote {}", f.display());
    }
    if let Some(dir) = check_xml {
        let f = dir.join(format!("{}.xml", sc.name));
        match std::fs::read_to_string(&f) {
            Ok(committed) if committed == xml => println!("{} is up to date", f.display()),
            Ok(_) => {
                return Err(format!(
                    "{} is stale: regenerate it with `mps pack --xml-only --write-xml {} {}`",
                    f.display(),
                    dir.display(),
                    scene.display()
                ))
            }
            Err(e) => {
                return Err(format!(
                    "{}: {e} (generate it with --write-xml)",
                    f.display()
                ))
            }
        }
    }
    Ok(())
}

/// Where scripts/build-fmu-lib.sh puts the portable library, below a cargo target directory.
const PORTABLE_LIB: &str = "x86_64-unknown-linux-gnu/fmu/libmps_solid.so";

/// The newest glibc the portable library may need (scripts/build-fmu-lib.sh links against it).
const PORTABLE_GLIBC: (u32, u32) = (2, 17);

/// The default library of `mps pack`: the portable build of scripts/build-fmu-lib.sh in the
/// target directory this program was built in (target/release/mps ->
/// target/x86_64-unknown-linux-gnu/fmu/libmps_solid.so). Missing: an error that says how to
/// build it (not the non-portable library beside this program, linked against this machine's
/// glibc).
fn portable_library() -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| {
        format!("cannot locate this program (to find the library; give --lib): {e}")
    })?;
    // target/<profile>/mps or target/<triple>/<profile>/mps.
    let candidates: Vec<PathBuf> = exe
        .ancestors()
        .skip(2)
        .take(2)
        .map(|d| d.join(PORTABLE_LIB))
        .collect();
    if let Some(found) = candidates.iter().find(|p| p.is_file()) {
        return Ok(found.clone());
    }
    let expected = candidates
        .first()
        .map_or_else(|| PORTABLE_LIB.to_string(), |p| p.display().to_string());
    Err(format!(
        "the portable FMU library {expected} is not built. Build it with\n    \
         scripts/build-fmu-lib.sh\nin the source tree ({}): the library without the studies, \
         stripped and linked against glibc {}.{} by cargo-zigbuild (the script installs it into \
         .venv, and prints the library's path; several minutes the first time), then pack again. \
         Or pass --lib PATH to pack another build of these sources (target/release/libmps_solid.so \
         is not stripped and needs this machine's glibc, so its FMU loads only where that glibc \
         or a newer one is)",
        env!("CARGO_MANIFEST_DIR"),
        PORTABLE_GLIBC.0,
        PORTABLE_GLIBC.1
    ))
}

/// "1.2 MB; library PATH 2.9 MB, needs glibc >= 2.17" for the line of a packed FMU, with a warning on
/// stderr when the library is not the portable kind (a newer glibc than 2.17).
fn packed_summary(fmu: &std::path::Path, lib: &std::path::Path) -> String {
    let mb = |p: &std::path::Path| {
        std::fs::metadata(p).map_or("?".to_string(), |m| {
            format!("{:.1} MB", m.len() as f64 / 1e6)
        })
    };
    let glibc = std::fs::read(lib)
        .ok()
        .and_then(|b| mps_solid::fmi::pack::newest_glibc(&b));
    if let Some((major, minor)) = glibc.filter(|&v| v > PORTABLE_GLIBC) {
        eprintln!(
            "warning: the packed library {} needs glibc >= {major}.{minor}: the FMU loads only on \
             Linux with that glibc or newer (the portable library of scripts/build-fmu-lib.sh \
             needs {}.{})",
            lib.display(),
            PORTABLE_GLIBC.0,
            PORTABLE_GLIBC.1
        );
    }
    format!(
        "{}; library {} {}, needs glibc >= {}",
        mb(fmu),
        lib.display(),
        mb(lib),
        glibc.map_or("?".to_string(), |(a, b)| format!("{a}.{b}"))
    )
}
