//! The evolving state as plain data (FMU state, checkpoints): capture and restore.
use super::stable_step::StableStepState;
use super::{SimError, World};
use crate::physics::boundary::{GravityLaw, GroupMotion};
use crate::physics::dim::{Dim, Space, Vect};
use serde::{Deserialize, Serialize};

/// Everything that evolves in time, as plain data (FMU state, checkpoints). Restoring it and
/// stepping on gives bitwise the same results as never having stopped.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct WorldState<const D: usize>
where
    Space: Dim<D>,
{
    pub time: f64,
    pub steps: u64,
    /// Displacements u = x - X (m); positions are X + u.
    pub u: Vec<Vect<D>>,
    pub v: Vec<Vect<D>>,
    pub q: Vec<<Space as Dim<D>>::Rotation>,
    pub w: Vec<<Space as Dim<D>>::Ang>,
    pub w0: Vec<f64>,
    pub motions: Vec<GroupMotion<D>>,
    pub loads: Vec<Vect<D>>,
    pub gravity: GravityLaw<D>,
    /// The stable step as last measured (issue 7: it is measured again in the current
    /// configuration as the body deforms), so a restored state steps on with the same dt.
    pub stable_step: StableStepState<D>,
    /// Per particle, the share of its elastic energy it kept through its breaks
    /// (`ElasticOperator::retained`; empty: all 1).
    #[serde(default)]
    pub retained: Vec<f64>,
    /// Strain energy released by the breaks so far (J).
    #[serde(default)]
    pub fracture_release: f64,
    /// Length of the step that led to this state (s; 0: none yet): the velocities are this
    /// step's, and the next step's forces act over half of it and half of the next
    /// (`StepInputs::kick_dt`).
    #[serde(default)]
    pub previous_step: f64,
}

impl<const D: usize> World<D>
where
    Space: Dim<D>,
{
    /// Captures the evolving state.
    pub fn state(&self) -> WorldState<D> {
        WorldState {
            time: self.time,
            steps: self.steps,
            u: self.p.u.clone(),
            v: self.p.v.clone(),
            q: self.p.q.clone(),
            w: self.p.w.clone(),
            w0: self.bonds.w0.clone(),
            motions: self.groups.iter().map(|g| g.motion).collect(),
            loads: self.loads.iter().map(|l| l.force).collect(),
            gravity: self.gravity,
            stable_step: self.stable.clone(),
            retained: if self.op.retained.iter().all(|&r| r == 1.0) {
                Vec::new()
            } else {
                self.op.retained.clone()
            },
            fracture_release: self.fracture_release,
            previous_step: self.previous_step,
        }
    }

    /// Restores a state captured from a world built from the same scene.
    pub fn set_state(&mut self, s: &WorldState<D>) -> Result<(), SimError> {
        let n = self.len();
        if s.u.len() != n
            || s.v.len() != n
            || s.q.len() != n
            || s.w.len() != n
            || s.w0.len() != self.bonds.len()
            || s.motions.len() != self.groups.len()
            || s.loads.len() != self.loads.len()
            || ![0, n].contains(&s.stable_step.u_measured.len())
            || ![0, n].contains(&s.stable_step.eig_t.len())
            || ![0, n].contains(&s.stable_step.eig_r.len())
            || ![0, n].contains(&s.retained.len())
        {
            return Err(SimError::Invalid(
                "state does not belong to this scene (sizes differ)".into(),
            ));
        }
        // Checked before anything changes: a refused state leaves the world as it was.
        let finite = |v: &Vect<D>| v.iter().all(|c| c.is_finite());
        if !(s.time.is_finite()
            && s.u.iter().all(finite)
            && s.v.iter().all(finite)
            && s.w.iter().all(<Space as Dim<D>>::ang_finite)
            && s.w0.iter().all(|w| w.is_finite())
            && s.stable_step.omega_elastic.is_finite()
            && s.stable_step.omega_elastic > 0.0
            && s.stable_step.omega_measured.is_finite()
            && s.stable_step.omega_measured > 0.0
            && s.stable_step.u_measured.iter().all(finite)
            && s.stable_step.eig_t.iter().all(finite)
            && s.stable_step
                .eig_r
                .iter()
                .all(<Space as Dim<D>>::ang_finite)
            && s.retained.iter().all(|r| (0.0..=1.0).contains(r))
            && s.fracture_release.is_finite()
            && s.previous_step.is_finite()
            && s.previous_step >= 0.0)
        {
            return Err(SimError::Invalid(
                "state holds non-finite positions, velocities or bond weights, retained energy shares outside [0, 1] or a negative previous step".into(),
            ));
        }
        self.time = s.time;
        self.steps = s.steps;
        self.p.u.clone_from(&s.u);
        self.p.sync_positions();
        self.p.v.clone_from(&s.v);
        // Followers are derived from what they follow (a state from elsewhere may not hold them).
        self.sync_followers();
        self.p.q.clone_from(&s.q);
        self.p.w.clone_from(&s.w);
        let changed: Vec<usize> = (0..n)
            .filter(|&i| {
                self.bonds
                    .of(i)
                    .any(|k| self.bonds.w0[k].to_bits() != s.w0[k].to_bits())
            })
            .collect();
        self.bonds.w0.clone_from(&s.w0);
        // The screen's slack was of the bonds before (a restored bond may be near its limit).
        self.strain_screen.invalidate();
        for &i in &changed {
            self.op.refresh_particle(&self.bonds, i, self.p.n_ref[i]);
        }
        self.broken_pairs = self.bonds.w0.iter().filter(|&&w| w == 0.0).count() as u64 / 2;
        if s.retained.is_empty() {
            self.op.retained.iter_mut().for_each(|r| *r = 1.0);
        } else {
            self.op.retained.clone_from(&s.retained);
        }
        self.fracture_release = s.fracture_release;
        self.previous_step = s.previous_step;
        self.contact.refresh_all(&self.bonds, &self.p.body);
        for (g, m) in self.groups.iter_mut().zip(&s.motions) {
            g.motion = *m;
        }
        for (l, f) in self.loads.iter_mut().zip(&s.loads) {
            l.force = *f;
            l.rate = Vect::<D>::zeros();
        }
        self.gravity = s.gravity;
        // The stable step as it was measured for this state; never below the reference one.
        self.stable = s.stable_step.clone();
        self.omega_elastic = self.stable.omega_elastic.max(self.omega_reference);
        // omega_max follows from the forces' contact state (`set_omega_max`).
        self.update_forces()
    }
}
