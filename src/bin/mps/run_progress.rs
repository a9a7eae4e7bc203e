//! Progress of `mps run` on stderr. On a terminal, a bar over the simulated time, moved after
//! every solver step (at most ten times a second). Elsewhere (a log, a pipe), a line every
//! minute: time, steps, elapsed and remaining wall time. On both, once the first seconds give a
//! measured rate, one note with the expected wall time of the whole run when it is longer than
//! a minute, so that no long run is silent; warnings of the scene go through here too.
use indicatif::{ProgressBar, ProgressStyle};
use mps_solid::physics::duration_text;
use mps_solid::runner::RunEvent;
use mps_solid::scene::limits::num;
use mps_solid::{Scene, Simulation};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// Wall time after which the rate is measured and the expected duration noted (s).
const MEASURE_AFTER: f64 = 3.0;
/// A run expected to take longer than this gets the note (s).
const NOTE_ABOVE: f64 = 60.0;
/// Interval of the progress lines when stderr is not a terminal.
const LINE_EVERY: Duration = Duration::from_secs(60);
/// Interval of the bar's updates on a terminal.
const BAR_EVERY: Duration = Duration::from_millis(100);

/// The progress report of one run.
pub struct RunProgress {
    bar: Option<ProgressBar>,
    start: Instant,
    last_report: Instant,
    noted: bool,
    /// Solver steps the whole run takes (the estimate before it started).
    total_steps: u64,
    particles: usize,
    end_time: f64,
    /// Wall time the cost model expects (s).
    model_estimate: f64,
}

impl RunProgress {
    pub fn new(scene: &Scene, sim: &Simulation) -> RunProgress {
        let bar = std::io::stderr().is_terminal().then(|| {
            let pb = ProgressBar::new((scene.end_time * 1e6) as u64);
            pb.set_style(
                ProgressStyle::with_template(
                    "{msg:>24} [{bar:40}] {percent:>3}% {elapsed_precise} eta {eta}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            pb.set_message(scene.name.clone());
            pb
        });
        let total_steps = sim.estimate_steps(scene.end_time);
        let now = Instant::now();
        RunProgress {
            bar,
            start: now,
            last_report: now,
            noted: false,
            total_steps,
            particles: sim.particles(),
            end_time: scene.end_time,
            model_estimate: sim.estimate_wall_time(total_steps),
        }
    }

    /// Prints a line without breaking the bar.
    fn say(&self, line: &str) {
        match &self.bar {
            Some(pb) => pb.suspend(|| eprintln!("{line}")),
            None => eprintln!("{line}"),
        }
    }

    pub fn event(&mut self, e: RunEvent) {
        match e {
            RunEvent::Warning(w) => self.say(&format!("warning: {w}")),
            RunEvent::Sample(t) => {
                if let Some(pb) = &self.bar {
                    pb.set_position((t * 1e6) as u64);
                }
            }
            RunEvent::Step { time, steps } => self.step(time, steps),
            // The set-up ends before the run's progress starts (mps run prints its stages).
            RunEvent::Setup { .. } => {}
            // Whole states are for outputs (mps run --surface), not for the progress line.
            RunEvent::State(_) => {}
        }
    }

    fn step(&mut self, time: f64, steps: u64) {
        let now = Instant::now();
        let elapsed = now.duration_since(self.start).as_secs_f64();
        if !self.noted && elapsed >= MEASURE_AFTER {
            self.noted = true;
            let rate = steps as f64 / elapsed;
            let total = self.total_steps.max(steps) as f64 / rate;
            if total > NOTE_ABOVE {
                self.say(&format!(
                    "note: this run takes about {} in all ({} solver steps of {} particles at \
                     {} steps/s, measured over the first {}; the cost model expected {}); \
                     Ctrl-C stops it and keeps what it computed as partial results; a shorter \
                     end_time or a larger particle_spacing shortens it",
                    duration_text(total),
                    self.total_steps,
                    self.particles,
                    short(rate),
                    duration_text(elapsed),
                    duration_text(self.model_estimate)
                ));
            }
        }
        let every = if self.bar.is_some() {
            BAR_EVERY
        } else {
            LINE_EVERY
        };
        if now.duration_since(self.last_report) < every {
            return;
        }
        self.last_report = now;
        match &self.bar {
            Some(pb) => pb.set_position((time * 1e6) as u64),
            None => {
                let left =
                    (self.total_steps.saturating_sub(steps)) as f64 * elapsed / steps.max(1) as f64;
                eprintln!(
                    "progress: t = {} of {} s ({:.0} %), step {steps} of about {}, {} elapsed, \
                     about {} left",
                    short(time),
                    num(self.end_time),
                    100.0 * time / self.end_time,
                    self.total_steps,
                    duration_text(elapsed),
                    duration_text(left)
                );
            }
        }
    }

    /// Clears the bar.
    pub fn finish(&self) {
        if let Some(pb) = &self.bar {
            pb.finish_and_clear();
        }
    }
}

/// Four significant digits, short: 7123.4 -> "7123", 0.0123456 -> "0.01235", 1.2e9 -> "1.2e9".
fn short(v: f64) -> String {
    num(format!("{v:.4e}").parse::<f64>().unwrap_or(v))
}
