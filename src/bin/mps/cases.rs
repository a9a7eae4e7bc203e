//! `mps cases`, the main job: the paper's runs side by side, each on its own share of the
//! threads, the longest first, their results printed in the fixed order as they become ready.
//!
//! Why side by side: a run of a few thousand particles does not use two threads fully (the
//! loops' fork and join cost per step; case 3's two variants to 0.8 s: 15.8 s one after the
//! other on two threads, 12.8 s side by side on one thread each). The results do not depend on
//! the thread count; the wall times printed are then those of each run's own share.
use super::progress;
use indicatif::{MultiProgress, ProgressBar};
use mps_solid::physics::ElasticModel;
use mps_solid::studies::case3::{
    case3_report_forking, case3_report_resumed, case3_report_with, case3_scene, case3_text,
    Case3Fork, CheckPoint, CASE3_DP,
};
use mps_solid::studies::cases::{case1_scene, case2_scene, Support};
use mps_solid::studies::report;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Condvar, Mutex};

/// One run of the main job.
#[derive(Clone, Copy, Debug)]
pub enum CaseRun {
    /// Case 1 or 2 with a model.
    Beam(u8, ElasticModel),
    /// Case 3, with contact between fractured surfaces or without.
    Collision(bool),
}

/// What a run gives: its text, its JSON, whether it failed.
pub struct RunResult {
    pub text: Option<String>,
    pub value: Option<serde_json::Value>,
    pub failed: bool,
}

/// The settings shared by the runs.
#[derive(Clone, Copy)]
pub struct CaseSettings {
    pub dp: f64,
    pub dt: Option<f64>,
    pub case3_end: f64,
}

impl CaseRun {
    /// Relative cost, for the order the runs start in (one-thread wall times at the paper's
    /// settings, s; case 3 scaled by its end time).
    fn cost(&self, s: &CaseSettings) -> f64 {
        match *self {
            CaseRun::Beam(1, ElasticModel::SecondOrder) => 28.0,
            CaseRun::Beam(_, ElasticModel::SecondOrder) => 17.0,
            CaseRun::Beam(_, ElasticModel::PaperLocal) => 14.5,
            CaseRun::Beam(_, ElasticModel::Paper) => 13.0,
            CaseRun::Beam(..) => 6.0,
            // The variant without fractured-surface contact goes on from the other's state
            // where they part (0.47 s of its 1.65 s): it comes after it.
            CaseRun::Collision(true) => 26.0 * s.case3_end / 1.7,
            CaseRun::Collision(false) => 19.0 * s.case3_end / 1.7,
        }
    }

    fn label(&self) -> String {
        match self {
            CaseRun::Beam(c, m) => format!("case {c} {m:?}"),
            CaseRun::Collision(true) => "case 3 (contact on)".into(),
            CaseRun::Collision(false) => "case 3 (contact off)".into(),
        }
    }

    /// Runs it, reporting its progress on `pb`.
    fn run(&self, s: &CaseSettings, pb: &ProgressBar, handoff: &Handoff) -> RunResult {
        let at = |t: f64| pb.set_position((t * 1e6) as u64);
        let done = |r: Result<(String, serde_json::Value), String>, label: String| match r {
            Ok((text, v)) => RunResult {
                failed: v["run"]["error"].is_string(),
                text: Some(text),
                value: Some(v),
            },
            Err(e) => {
                eprintln!("error: {label}: {e}");
                RunResult {
                    text: None,
                    value: None,
                    failed: true,
                }
            }
        };
        match *self {
            CaseRun::Beam(1, m) => {
                pb.set_length((case1_scene(s.dp, m, s.dt).end_time * 1e6) as u64);
                let r = report::case1(s.dp, m, s.dt, at)
                    .and_then(|r| Ok((report::case1_text(&r), to_json(&r)?)));
                done(r, self.label())
            }
            CaseRun::Beam(_, m) => {
                pb.set_length((case2_scene(s.dp, m, s.dt, Support::Face).end_time * 1e6) as u64);
                let r = report::case2(s.dp, m, s.dt, at)
                    .and_then(|r| Ok((report::case2_text(&r), to_json(&r)?)));
                done(r, self.label())
            }
            CaseRun::Collision(fc) => {
                // The variant without fractured-surface contact is expected to stop at an
                // overlap (the paper's failure near 1.7 s): a report, not an error.
                let mut scene = case3_scene(CASE3_DP, fc, ElasticModel::Corrected);
                scene.end_time = s.case3_end;
                if s.dt.is_some() {
                    scene.solver.dt = s.dt;
                }
                pb.set_length((s.case3_end * 1e6) as u64);
                let on_check = |sim: &mps_solid::Simulation, kind| {
                    if kind == CheckPoint::Regular {
                        at(sim.time())
                    }
                };
                let r = scene.validate().map_err(|e| e.to_string()).and_then(|()| {
                    if fc {
                        // The two variants are the same until a pair of one body touches:
                        // the other goes on from this run's state there. Closed however this
                        // run ends, so that the other never waits for nothing.
                        struct Close<'a>(&'a Handoff);
                        impl Drop for Close<'_> {
                            fn drop(&mut self) {
                                self.0.close()
                            }
                        }
                        let _close = Close(handoff);
                        case3_report_forking(
                            &scene,
                            s.case3_end,
                            0.01,
                            0.0025,
                            on_check,
                            &mut |f| handoff.offer(f),
                        )
                    } else {
                        match handoff.wait() {
                            Some(f) => case3_report_resumed(&scene, f, on_check),
                            None => case3_report_with(&scene, s.case3_end, 0.01, 0.0025, on_check),
                        }
                    }
                });
                let r = r.and_then(|r| Ok((case3_text(&r), to_json(&r)?)));
                done(r, format!("case 3 {}", scene.name))
            }
        }
    }
}

/// Case 3's fork from the run with fractured-surface contact to the run without
/// (`case3_report_forking`): offered once, taken once.
pub struct Handoff {
    slot: Mutex<Fork>,
    ready: Condvar,
}

enum Fork {
    /// The contact-on run has not offered it yet.
    Pending,
    Ready(Box<Case3Fork>),
    /// None will come (no contact-on run, or it ended without one): run from the start.
    None,
}

impl Handoff {
    /// A handoff that waits for a fork when `expected` (the contact-on run is one of the runs).
    fn new(expected: bool) -> Self {
        Handoff {
            slot: Mutex::new(if expected { Fork::Pending } else { Fork::None }),
            ready: Condvar::new(),
        }
    }

    fn offer(&self, f: Case3Fork) {
        let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
        *slot = Fork::Ready(Box::new(f));
        self.ready.notify_all();
    }

    /// No more offers.
    fn close(&self) {
        let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
        if matches!(*slot, Fork::Pending) {
            *slot = Fork::None;
        }
        self.ready.notify_all();
    }

    /// The fork, once offered (None if none will come).
    fn wait(&self) -> Option<Case3Fork> {
        let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
        while matches!(*slot, Fork::Pending) {
            slot = self.ready.wait(slot).unwrap_or_else(|e| e.into_inner());
        }
        match std::mem::replace(&mut *slot, Fork::None) {
            Fork::Ready(f) => Some(*f),
            _ => None,
        }
    }
}

fn to_json<T: serde::Serialize>(r: &T) -> Result<serde_json::Value, String> {
    serde_json::to_value(r).map_err(|e| e.to_string())
}

/// Runs `runs` on `jobs` runs at a time (each on its share of the threads), the costliest
/// first, and calls `emit(k, result)` for the runs in their given order as they become ready.
pub fn run_all(
    runs: &[CaseRun],
    s: CaseSettings,
    jobs: usize,
    mut emit: impl FnMut(usize, RunResult, &MultiProgress),
) {
    let jobs = jobs.clamp(1, runs.len().max(1));
    let per_job = (rayon::current_num_threads() / jobs).max(1);
    let mut order: Vec<usize> = (0..runs.len()).collect();
    order.sort_by(|&a, &b| runs[b].cost(&s).total_cmp(&runs[a].cost(&s)));
    let next = AtomicUsize::new(0);
    // The contact-on run is taken before the contact-off one (its cost is higher), so the
    // latter's wait always has a run to end it.
    let handoff = Handoff::new(runs.iter().any(|r| matches!(r, CaseRun::Collision(true))));
    let bars = MultiProgress::new();
    let (tx, rx) = mpsc::channel::<(usize, RunResult)>();
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            let tx = tx.clone();
            let (next, order, bars, handoff) = (&next, &order, &bars, &handoff);
            scope.spawn(move || {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(per_job).build();
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&idx) = order.get(k) else { break };
                    let run = runs[idx];
                    let pb = bars.add(progress(1.0, &run.label()));
                    let result = match &pool {
                        Ok(pool) => pool.install(|| run.run(&s, &pb, handoff)),
                        Err(_) => run.run(&s, &pb, handoff),
                    };
                    pb.finish_and_clear();
                    bars.remove(&pb);
                    if tx.send((idx, result)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(tx);
        // In the given order: a run's result waits for those before it.
        let mut ready: std::collections::BTreeMap<usize, RunResult> = Default::default();
        let mut first = 0;
        for (idx, r) in rx {
            ready.insert(idx, r);
            while let Some(r) = ready.remove(&first) {
                emit(first, r, &bars);
                first += 1;
            }
        }
    });
}
