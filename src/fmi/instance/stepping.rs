//! Stepping: fmi2DoStep's sub-stepping with the inputs applied over the step, fmi2CancelStep,
//! and the status queries (fmi2Get*Status).
use super::inputs::{BoundaryTiming, GravitySource, Inputs};
use super::lifecycle::{Instance, Mode};
use super::status::{FmiError, FmiResult, Status};
use crate::physics::duration_text;
use crate::scene::limits::num;
use crate::sim::Simulation;

/// fmi2StatusKind values.
pub const DO_STEP_STATUS: i32 = 0;
pub const PENDING_STATUS: i32 = 1;
pub const LAST_SUCCESSFUL_TIME: i32 = 2;
pub const TERMINATED: i32 = 3;

/// Largest relative difference between the step a doStep simulates and the step the host asked
/// for (round-off of the simulated time): a step that cannot be resolved this well is refused.
const STEP_RESOLUTION: f64 = 1e-6;

/// Estimated wall time (s, on two cores) above which a doStep warns the host before it starts:
/// the host hears how long the call will block (issue 27.8: a doStep of 1e7 sub-steps, within
/// solver.max_steps, blocked for many minutes without a word).
pub const LONG_STEP_WARNING_S: f64 = 60.0;

/// Relative tolerance of time comparisons.
fn time_tol(t: f64) -> f64 {
    1e-9 * t.abs().max(1.0)
}

impl Instance {
    /// Hands the inputs to the simulation for the step [time, time + h] (simulation time).
    fn apply_inputs(sim: &mut Simulation, inputs: &Inputs, h: f64) {
        let t = sim.time();
        if inputs.gravity_source == GravitySource::Inputs {
            sim.set_gravity_linear(inputs.gravity, inputs.gravity_rate, t);
        }
        for (r, (f, df)) in inputs.load.iter().zip(&inputs.load_rate).enumerate() {
            sim.set_load(r, *f, *df, t);
        }
        for (g, (d, dd)) in inputs
            .displacement
            .iter()
            .zip(&inputs.displacement_rate)
            .enumerate()
        {
            match inputs.boundary_timing {
                BoundaryTiming::AtStepStart => {
                    let end = [d[0] + dd[0] * h, d[1] + dd[1] * h, d[2] + dd[2] * h];
                    sim.set_group_motion(g, *d, end, t, t + h);
                }
                BoundaryTiming::AtStepEnd => {
                    let now = sim.group_displacement(g);
                    sim.set_group_motion(g, now, *d, t, t + h);
                }
            }
        }
    }

    /// fmi2DoStep: advances from t to exactly t + h with the solver's stable sub-steps. A step
    /// that would take more than `solver.max_steps` solver steps (or `solver.max_particle_steps`)
    /// is refused before any work, leaving the instance as it was; one estimated at more than
    /// [`LONG_STEP_WARNING_S`] of wall time is logged as a warning at once, before the work.
    pub fn do_step(&mut self, t: f64, h: f64) -> FmiResult<()> {
        self.require("fmi2DoStep", &[Mode::StepComplete])?;
        if !(h.is_finite() && h > 0.0) {
            return Err(FmiError::Invalid(format!(
                "communicationStepSize = {} must be positive and finite",
                num(h)
            )));
        }
        if !(t.is_finite() && (t - self.time).abs() <= time_tol(t)) {
            return Err(FmiError::Invalid(format!(
                "currentCommunicationPoint = {} but the last step ended at {}",
                num(t),
                num(self.time)
            )));
        }
        let t_end = t + h;
        if let Some(stop) = self.stop_time {
            if t_end > stop + time_tol(stop) {
                return Err(FmiError::Invalid(format!(
                    "the step would end at {}, after stopTime = {}",
                    num(t_end),
                    num(stop)
                )));
            }
        }
        let sim = self
            .sim
            .as_mut()
            .ok_or_else(|| FmiError::Fatal("no model built".into()))?;
        // The simulated time is kept relative to startTime (the scene's time 0), so that a step
        // far from time zero simulates h, not t + h - t rounded to the spacing of doubles at t
        // (issue 27.9: at t = 1e14, t + 0.005 == t). What stays unresolved is a step below the
        // spacing of doubles at the simulated time itself: refused, before any work.
        let sim_now = sim.time();
        let sim_end = sim_now + h;
        if ((sim_end - sim_now) - h).abs() > STEP_RESOLUTION * h {
            let spacing = (sim_end.abs().max(sim_now.abs()) * f64::EPSILON).max(f64::MIN_POSITIVE);
            return Err(FmiError::Invalid(format!(
                "communicationStepSize = {} is below the resolution of the time: {} s after \
                 startTime, doubles are {} s apart, so the step would simulate {} s; use steps \
                 of at least {} s",
                num(h),
                num(sim_now),
                num(spacing),
                num(sim_end - sim_now),
                num(spacing / STEP_RESOLUTION)
            )));
        }
        // Refused before any work, the instance unchanged (not an Error state).
        sim.check_work(sim_end).map_err(|e| {
            FmiError::Invalid(format!(
                "doStep(t = {}, h = {}) refused: {e}; use shorter communication steps",
                num(t),
                num(h)
            ))
        })?;
        let steps = sim.estimate_steps(sim_end);
        let wall = sim.estimate_wall_time(steps);
        if wall > LONG_STEP_WARNING_S {
            self.log.warn_now(&format!(
                "fmi2DoStep(t = {}, h = {}): {steps} solver steps of {} particles (dt = {:.4e} s), \
                 about {} of wall time on two cores before this call returns; shorter \
                 communication steps return sooner, and solver.max_steps or \
                 solver.max_particle_steps in the scene bound one step's work",
                num(t),
                num(h),
                sim.particles(),
                h / steps as f64,
                duration_text(wall)
            ));
        }
        Self::apply_inputs(sim, &self.inputs, sim_end - sim.time());
        let res = self.pool.install(|| sim.advance_to(sim_end));
        let res = match res {
            Ok(n) => self.refresh_outputs().map(|_| n),
            Err(e) => Err(FmiError::Solver(format!(
                "step from t = {} to {} failed: {e}",
                num(t),
                num(t_end)
            ))),
        };
        self.inputs.clear_rates();
        match res {
            Ok(n) => {
                self.time = t_end;
                self.last_successful_time = t_end;
                self.log.trace(&format!(
                    "doStep t = {}, h = {}: {n} solver steps",
                    num(t),
                    num(h)
                ));
                Ok(())
            }
            Err(e) => {
                self.mode = Mode::Error;
                Err(e)
            }
        }
    }

    /// fmi2CancelStep with no call running: doStep is synchronous (it never returns
    /// fmi2Pending), so there is never a step to cancel; the work of one doStep is bounded by
    /// `solver.max_steps` instead. (A set-up running on another thread is stopped by the C
    /// layer through [`super::SetupControl`], without this instance's lock.)
    pub fn cancel_step(&mut self) -> FmiResult<()> {
        Err(FmiError::Invalid(
            "fmi2CancelStep: there is nothing to cancel: fmi2DoStep is synchronous and never \
             returns fmi2Pending (the work of one step is bounded by solver.max_steps); only a \
             set-up running on another thread can be stopped"
                .into(),
        ))
    }

    const STATUS_MODES: [Mode; 3] = [Mode::StepComplete, Mode::Error, Mode::Terminated];

    /// fmi2GetStatus: only meaningful after fmi2Pending, which this FMU never returns.
    pub fn get_status(&self, kind: i32) -> FmiResult<Status> {
        self.require("fmi2GetStatus", &Self::STATUS_MODES)?;
        Err(FmiError::NotProvided(format!(
            "status kind {kind} is not provided: fmi2DoStep is synchronous and never returns fmi2Pending"
        )))
    }

    /// fmi2GetRealStatus: fmi2LastSuccessfulTime.
    pub fn get_real_status(&self, kind: i32) -> FmiResult<f64> {
        self.require("fmi2GetRealStatus", &Self::STATUS_MODES)?;
        if kind == LAST_SUCCESSFUL_TIME {
            Ok(self.last_successful_time)
        } else {
            Err(FmiError::NotProvided(format!(
                "status kind {kind} is not provided as a Real (only fmi2LastSuccessfulTime)"
            )))
        }
    }

    /// fmi2GetIntegerStatus: no Integer status is defined by FMI 2.0.
    pub fn get_integer_status(&self, kind: i32) -> FmiResult<i32> {
        self.require("fmi2GetIntegerStatus", &Self::STATUS_MODES)?;
        Err(FmiError::NotProvided(format!(
            "status kind {kind} is not provided as an Integer"
        )))
    }

    /// fmi2GetBooleanStatus: fmi2Terminated (this FMU never asks to stop: false).
    pub fn get_boolean_status(&self, kind: i32) -> FmiResult<bool> {
        self.require("fmi2GetBooleanStatus", &Self::STATUS_MODES)?;
        if kind == TERMINATED {
            Ok(false)
        } else {
            Err(FmiError::NotProvided(format!(
                "status kind {kind} is not provided as a Boolean (only fmi2Terminated)"
            )))
        }
    }

    /// fmi2GetStringStatus: fmi2PendingStatus is only meaningful after fmi2Pending.
    pub fn get_string_status(&self, kind: i32) -> FmiResult<&'static str> {
        self.require("fmi2GetStringStatus", &Self::STATUS_MODES)?;
        Err(FmiError::NotProvided(format!(
            "status kind {kind} is not provided: no asynchronous step is ever pending"
        )))
    }
}
