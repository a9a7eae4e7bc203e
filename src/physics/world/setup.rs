//! Watching a world's set-up (World::new_observed): its stages, an observer told of each as it
//! ends and asked at each stage boundary whether to go on, and the bound
//! `solver.max_setup_seconds` on its wall-clock time. Physics knows nothing of where the
//! messages go (the FMI logger, stderr) or why an observer stops a set-up (a host's
//! fmi2CancelStep).
use super::SimError;
use crate::physics::sbp::{self, Closure};
use std::any::Any;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The stages of a set-up, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetupStage {
    /// The particles of the bodies (the scene's fill).
    Particles,
    /// The bonds: particle pairs closer than re (module `bonds`).
    Bonds,
    /// Clamps: the ghosts of mirror faces and the followers of clamped faces (given by `mirror`
    /// or found from the geometry).
    Clamps,
    /// The elastic operator's per-particle fits.
    OperatorFits,
    /// The second-order operator's summation-by-parts closure (module `sbp`).
    Closure,
    /// The first measurement of the stable step (the Lanczos process for omega_max).
    StableStep,
    /// The forces of the initial state.
    InitialForces,
}

impl SetupStage {
    pub fn name(self) -> &'static str {
        match self {
            SetupStage::Particles => "particles",
            SetupStage::Bonds => "bonds",
            SetupStage::Clamps => "clamps",
            SetupStage::OperatorFits => "operator fits",
            SetupStage::Closure => "closure",
            SetupStage::StableStep => "stable step",
            SetupStage::InitialForces => "initial forces",
        }
    }
}

/// Watches a set-up: told of each stage as it ends, asked at each stage boundary whether to go
/// on. Called on the thread that builds the world, between its parallel loops.
pub trait SetupObserver {
    /// `stage` has ended after `seconds` (wall clock); `detail` says what it made.
    fn stage_done(&self, stage: SetupStage, seconds: f64, detail: &str) {
        let _ = (stage, seconds, detail);
    }
    /// Some(why) stops the set-up at the next stage boundary (`SimError::Stopped`).
    fn stop(&self) -> Option<String> {
        None
    }
    /// A flag another thread sets to stop the set-up within a stage: the long loops of a stage
    /// (the closure's conjugate gradients) poll it, and `stop` then says why.
    fn stop_flag(&self) -> Option<&AtomicBool> {
        None
    }
    /// Results of an earlier set-up that this one may take instead of computing them again
    /// (an FMU instance's, across its builds: see [`SetupMemo`]).
    fn memo(&self) -> Option<&SetupMemo> {
        None
    }
}

/// What a set-up keeps for the next one: the second-order operator's closure, the longest
/// stage by far (seconds for a bulky clamped body), which depends on the geometry only
/// (positions, bonds, clamps and faces, not the materials, the step or the damping). Keyed by
/// a hash of everything it is computed from, so a set-up of another geometry computes its own
/// (and replaces it). One entry in memory (an FMU instance rebuilds one scene with other
/// parameters); with a directory ([`SetupMemo::in_dir`], `mps run --closure-cache`), every
/// closure also as a file there, found by its key by later processes (a sweep's runs).
#[derive(Default)]
pub struct SetupMemo {
    closure: Mutex<Option<(u64, Arc<dyn Any + Send + Sync>)>>,
    dir: Option<PathBuf>,
    /// What went wrong with the directory (a file that could not be written or read).
    notes: Mutex<Vec<String>>,
}

impl SetupMemo {
    /// A memo that also keeps its closures as files in `dir` (created when first written)
    /// and finds them there.
    pub fn in_dir(dir: PathBuf) -> Self {
        SetupMemo {
            dir: Some(dir),
            ..Default::default()
        }
    }

    fn file(&self, d: usize, key: u64) -> Option<PathBuf> {
        Some(
            self.dir
                .as_ref()?
                .join(format!("closure-{d}d-{key:016x}.bin")),
        )
    }

    fn note(&self, what: String) {
        self.notes
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(what);
    }

    /// What went wrong with the directory since the last call (a cache that does not work
    /// costs time, not results: the callers print it as a warning).
    pub fn take_notes(&self) -> Vec<String> {
        std::mem::take(&mut *self.notes.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// The closure kept under `key`: in memory, else from the directory's file of that key.
    pub(crate) fn closure<const D: usize>(&self, key: u64) -> Option<Arc<Closure<D>>> {
        {
            let kept = self.closure.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((k, v)) = &*kept {
                if *k == key {
                    if let Ok(c) = v.clone().downcast::<Closure<D>>() {
                        return Some(c);
                    }
                }
            }
        }
        let path = self.file(D, key)?;
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
            Err(e) => {
                self.note(format!("cannot read {}: {e}", path.display()));
                return None;
            }
        };
        let read = sbp::memo::header(&bytes).and_then(|(d, k, payload)| {
            if (d, k) != (D, key) {
                return Err("it is of another geometry".into());
            }
            sbp::memo::from_payload::<D>(payload)
        });
        match read {
            Ok(c) => {
                let c = Arc::new(c);
                *self.closure.lock().unwrap_or_else(|e| e.into_inner()) = Some((key, c.clone()));
                Some(c)
            }
            Err(e) => {
                self.note(format!("{} is not used: {e}", path.display()));
                None
            }
        }
    }

    /// Keeps `value` under `key` (replacing what was kept), and as its file in the directory
    /// (written beside it and renamed, so that a concurrent run reads a whole file or none).
    pub(crate) fn keep_closure<const D: usize>(&self, key: u64, value: Arc<Closure<D>>) {
        if let Some(path) = self.file(D, key) {
            if !path.exists() {
                if let Some(bytes) = sbp::memo::to_bytes(key, &value) {
                    let tmp = path.with_extension(format!("tmp-{}", std::process::id()));
                    let written = path
                        .parent()
                        .map_or(Ok(()), std::fs::create_dir_all)
                        .and_then(|_| std::fs::write(&tmp, &bytes))
                        .and_then(|_| std::fs::rename(&tmp, &path));
                    if let Err(e) = written {
                        let _ = std::fs::remove_file(&tmp);
                        self.note(format!("cannot write {}: {e}", path.display()));
                    }
                }
            }
        }
        *self.closure.lock().unwrap_or_else(|e| e.into_inner()) = Some((key, value));
    }

    /// The kept closure as bytes (`mps pack` ships them in the FMU: its instances then
    /// start from them), None if none is kept.
    pub fn closure_bytes(&self) -> Option<Vec<u8>> {
        let kept = self.closure.lock().unwrap_or_else(|e| e.into_inner());
        let (key, v) = kept.as_ref()?;
        if let Some(c) = v.downcast_ref::<Closure<2>>() {
            sbp::memo::to_bytes(*key, c)
        } else {
            sbp::memo::to_bytes(*key, v.downcast_ref::<Closure<3>>()?)
        }
    }

    /// A memo holding the closure of `bytes` ([`SetupMemo::closure_bytes`]); what is wrong
    /// with them otherwise (a set-up whose geometry hashes otherwise computes its own).
    pub fn from_closure_bytes(bytes: &[u8]) -> Result<Self, String> {
        let (dim, key, payload) = sbp::memo::header(bytes)?;
        let memo = SetupMemo::default();
        match dim {
            2 => memo.keep_closure(key, Arc::new(sbp::memo::from_payload::<2>(payload)?)),
            3 => memo.keep_closure(key, Arc::new(sbp::memo::from_payload::<3>(payload)?)),
            d => return Err(format!("it is of dimension {d}")),
        }
        Ok(memo)
    }

    /// Whether a closure is kept.
    pub fn holds_closure(&self) -> bool {
        self.closure
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some()
    }
}

/// What the long loops of a stage poll (from any thread): the set-up's deadline
/// (`solver.max_setup_seconds` from its start) and the observer's stop flag.
#[derive(Clone, Copy)]
pub struct SetupInterrupt<'a> {
    deadline: Option<Instant>,
    flag: Option<&'a AtomicBool>,
}

impl SetupInterrupt<'_> {
    /// Whether the loop must stop now.
    pub fn hit(&self) -> bool {
        self.flag.is_some_and(|f| f.load(Ordering::Relaxed))
            || self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

/// An observer that watches nothing.
pub struct Unobserved;
impl SetupObserver for Unobserved {}

/// Wall-clock cost of the stages after the bonds, as multiples of the bonds stage (which is
/// measured first and sets the pace of the machine). Measured with `mps run` on 2 cores: see
/// [`SetupClock::estimate`].
pub(super) struct StageCosts {
    /// Operator fits, per bonds-stage second.
    pub fits: f64,
    /// Summation-by-parts closure, per bonds-stage second (0 without it).
    pub closure: f64,
    /// Stable step and initial forces, per bonds-stage second.
    pub stable: f64,
}

/// The clock of one set-up: times the stages, tells the observer, checks the bound.
pub(super) struct SetupClock<'a> {
    observer: &'a dyn SetupObserver,
    start: Instant,
    stage_start: Instant,
    /// solver.max_setup_seconds.
    limit: f64,
}

impl<'a> SetupClock<'a> {
    pub(super) fn new(observer: &'a dyn SetupObserver, limit: f64) -> Self {
        let now = Instant::now();
        SetupClock {
            observer,
            start: now,
            stage_start: now,
            limit,
        }
    }

    /// Seconds since the set-up started.
    pub(super) fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Ends `stage`: tells the observer what it made and how long it took, then asks whether
    /// the set-up may go on (the observer's stop, the bound). Returns the stage's seconds.
    pub(super) fn done(&mut self, stage: SetupStage, detail: &str) -> Result<f64, SimError> {
        let seconds = self.stage_start.elapsed().as_secs_f64();
        self.observer.stage_done(stage, seconds, detail);
        if let Some(why) = self.observer.stop() {
            return Err(SimError::Stopped(format!(
                "after the {} stage ({:.1} s into the set-up): {why}",
                stage.name(),
                self.elapsed()
            )));
        }
        let elapsed = self.elapsed();
        if elapsed > self.limit {
            return Err(SimError::SetupTooLong {
                what: format!(
                    "the set-up was stopped after {elapsed:.1} s, at the end of its {} stage",
                    stage.name()
                ),
                limit: self.limit,
            });
        }
        self.stage_start = Instant::now();
        Ok(seconds)
    }

    /// What the long loops of the current stage poll: the bound and the observer's flag.
    pub(super) fn interrupt(&self) -> SetupInterrupt<'a> {
        SetupInterrupt {
            // A bound too large for the clock (1e300 s) is no deadline.
            deadline: Duration::try_from_secs_f64(self.limit)
                .ok()
                .and_then(|d| self.start.checked_add(d)),
            flag: self.observer.stop_flag(),
        }
    }

    /// The error of a set-up whose `stage` stopped within (its loop saw the interrupt hit);
    /// `progress` says how far the stage had come.
    pub(super) fn interrupted(&self, stage: SetupStage, progress: &str) -> SimError {
        let elapsed = self.elapsed();
        if let Some(why) = self.observer.stop() {
            return SimError::Stopped(format!(
                "during the {} stage ({elapsed:.1} s into the set-up; {progress}): {why}",
                stage.name()
            ));
        }
        SimError::SetupTooLong {
            what: format!(
                "the set-up was stopped after {elapsed:.1} s, during its {} stage ({progress})",
                stage.name()
            ),
            limit: self.limit,
        }
    }

    /// After the bonds stage (`bonds_seconds`): the whole set-up's estimated duration from
    /// the stage costs; refused before the expensive stages when it exceeds the bound.
    pub(super) fn estimate(
        &self,
        bonds: usize,
        bonds_seconds: f64,
        costs: &StageCosts,
    ) -> Result<(), SimError> {
        // Below a millisecond the bonds stage's clock says little about the machine's pace;
        // such a set-up is fast anyway.
        let pace = bonds_seconds.max(1e-3);
        let estimate = self.elapsed() + pace * (costs.fits + costs.closure + costs.stable);
        if estimate > self.limit {
            return Err(SimError::SetupTooLong {
                what: format!(
                    "the set-up would take about {estimate:.0} s (estimated from its first \
                     stages: {bonds} bonds found in {bonds_seconds:.2} s, and the operator's fits, \
                     closure and stable step cost about {:.0} times that)",
                    costs.fits + costs.closure + costs.stable
                ),
                limit: self.limit,
            });
        }
        Ok(())
    }
}
