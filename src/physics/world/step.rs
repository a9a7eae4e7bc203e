//! The step: forces of the current state, symplectic Euler with the followers of clamped
//! faces, the fracture check, `step`/`advance_to`, and the inputs that drive it (group
//! motions, loads, gravity).
use super::{SimError, World};
use crate::physics::boundary::{GravityLaw, GroupMotion};
use crate::physics::contact::Overlap;
use crate::physics::dim::{Dim, Space, Vect};
use crate::physics::fracture;
use crate::physics::integrate::{symplectic_euler, StepInputs};
use crate::physics::law;
use crate::physics::params::MaterialLaw;

impl<const D: usize> World<D>
where
    Space: Dim<D>,
{
    fn overlap_error(&self, o: Overlap) -> SimError {
        SimError::Overlap {
            time: self.time,
            step: self.steps,
            bodies: [
                self.body_names[self.p.body[o.i] as usize].clone(),
                self.body_names[self.p.body[o.j] as usize].clone(),
            ],
            particles: [o.i, o.j],
            distance: o.distance,
            limit: o.limit,
        }
    }

    /// Evaluates the internal and contact forces of the current state and the reactions of the
    /// groups. An error for the first particle whose material law has no energy at its state
    /// (a collapsed neo-Hookean particle) or the first overlap found (contact forces are then
    /// incomplete).
    pub(super) fn update_forces(&mut self) -> Result<(), SimError> {
        let collapsed = self.op.forces(
            &self.p,
            &self.bonds,
            &mut self.scratch,
            &mut self.force,
            &mut self.torque,
        );
        if let Some(i) = collapsed {
            return Err(SimError::Collapsed {
                time: self.time,
                step: self.steps,
                particle: i,
                body: self.body_names[self.p.body[i] as usize].clone(),
                det: self.op.jacobian(&self.scratch, i).unwrap_or(0.0),
            });
        }
        let mut overlap = None;
        if self.contact.active {
            self.contact
                .update_list(&self.p.x, &self.p.u, &self.p.body, &self.bonds);
            overlap = self.contact.add_forces(
                &self.p.x0,
                &self.p.u,
                &self.p.v,
                &self.p.body,
                &self.p.mass,
                &mut self.force,
            );
        }
        self.set_omega_max();
        // The followers of clamped faces carry no inertia of their own; their weight, loads
        // and contact forces act through the constraint (on the layers they follow and the
        // clamp). Their elastic forces took that path in the operator.
        if !self.op.second.followers.is_empty() {
            let (g, loads) = self.follower_external_inputs(self.time);
            let so = &self.op.second;
            let force = &self.force;
            let ext: Vec<Vect<D>> = so
                .followers
                .iter()
                .zip(&loads)
                .map(|(fl, l)| force[fl.particle as usize] + l)
                .collect();
            so.spread_to_followed(
                &self.p.mass,
                g,
                |i| ext[so.followers.partition_point(|f| (f.particle as usize) < i)],
                &mut self.force,
            );
            for fl in &so.followers {
                self.force[fl.particle as usize] = Vect::<D>::zeros();
            }
            self.follower_inputs = (g, loads);
        }
        for g in &mut self.groups {
            let mut sum = Vect::<D>::zeros();
            for &i in &g.members {
                sum -= self.force[i as usize];
            }
            for k in 0..D {
                if !g.axes[k] {
                    sum[k] = 0.0;
                }
            }
            g.reaction = sum;
        }
        match overlap {
            Some(o) => Err(self.overlap_error(o)),
            None => Ok(()),
        }
    }

    /// With the Saint Venant-Kirchhoff law: what the material state of the last force
    /// evaluation says about a blow-up at particle i, as a clause of the error message (empty
    /// when the body's particles are all within the law's stability limit, for other laws and
    /// for the paper's operators, which have no deformation gradient).
    fn blow_up_note(&self, i: usize) -> String {
        let body = self.p.body[i];
        if self.op.laws.get(body as usize) != Some(&MaterialLaw::SaintVenantKirchhoff) {
            return String::new();
        }
        let state = |k: usize| {
            self.op
                .strain_of(&self.scratch, k)
                .map(|(f, e)| (law::smallest_stretch(&e), law::det(&f)))
        };
        let Some(own) = state(i) else {
            return String::new();
        };
        // (count beyond the limit, inverted count, most compressed (stretch, det, particle))
        let mut beyond = 0usize;
        let mut inverted = 0usize;
        let mut worst = (f64::INFINITY, 0.0, i);
        for k in 0..self.len() {
            if self.p.body[k] != body {
                continue;
            }
            let Some((s, d)) = state(k) else { continue };
            if s < law::SVK_STABLE_STRETCH {
                beyond += 1;
                inverted += usize::from(d <= 0.0);
            }
            if s < worst.0 {
                worst = (s, d, k);
            }
        }
        if beyond == 0 {
            return String::new();
        }
        let name = &self.body_names[body as usize];
        let at = |s: f64, d: f64| {
            format!(
                "principal stretch {s:.3}, det F {d:.3}{}",
                if d <= 0.0 { ": turned inside out" } else { "" }
            )
        };
        let own_text = if own.0 < law::SVK_STABLE_STRETCH {
            format!(
                "particle {i} is compressed to a principal stretch {:.3} < 1/sqrt(3) (det F {:.3}{})",
                own.0,
                own.1,
                if own.1 <= 0.0 { ": turned inside out" } else { "" }
            )
        } else {
            format!(
                "particle {i} itself is at {}; the most compressed is particle {} ({})",
                at(own.0, own.1),
                worst.2,
                at(worst.0, worst.1)
            )
        };
        format!(
            ". The material had failed first: {beyond} particle(s) of body '{name}' ({inverted} of them inverted) were compressed beyond a principal stretch of 1/sqrt(3), where the Saint Venant-Kirchhoff law loses stability (a further compression takes less force, and an inverted particle has the stress of its mirror image: nothing pushes it back); {own_text}. Use material.law = \"neo_hookean\", whose energy grows without bound as a particle collapses, or a smaller load"
        )
    }

    /// Eq. (42): breaks the bonds strained beyond eps_max and updates what depends on them
    /// (shape tensors, surface flags, pair list). Nothing at all when eps_max is infinite.
    fn fracture(&mut self) {
        let Some(eps) = self.options.fracture_strain else {
            return;
        };
        self.fracture_checks += 1;
        let measure = self.options.bond_strain;
        // Only the bonds whose ends have moved far enough since the last full test to reach
        // eps_max are tested (issue 25: the test of every bond each step was 12 % of case 3).
        let touched = self.strain_screen.strained(
            &self.p.x0,
            &self.p.u,
            &self.p.q,
            &self.p.body,
            &self.bonds,
            eps,
            measure,
            &mut self.frac_flag,
        );
        self.strain_tests = self.strain_screen.full_tests;
        if touched.is_empty() {
            return;
        }
        // The energy each particle held just before the break: its re-fit may not exceed it.
        let before: Vec<Option<f64>> = touched
            .iter()
            .map(|&i| self.op.particle_energy(&self.p, &self.bonds, i))
            .collect();
        let pairs = fracture::break_strained(
            &self.p.u,
            &self.p.q,
            &mut self.bonds,
            eps,
            measure,
            &touched,
        );
        self.broken_pairs += pairs;
        for (&i, before) in touched.iter().zip(before) {
            self.op.refresh_particle(&self.bonds, i, self.p.n_ref[i]);
            if let (Some(before), Some(now)) =
                (before, self.op.particle_energy(&self.p, &self.bonds, i))
            {
                self.fracture_release += self.op.limit_at_break(i, before, now);
            }
        }
        self.contact
            .bonds_broken(&self.bonds, &self.p.body, &touched);
    }

    /// Gravity at time t and each follower's share of its load region's force at t: the
    /// external inputs that reach the followers.
    fn follower_external_inputs(&self, t: f64) -> (Vect<D>, Vec<Vect<D>>) {
        let loads = self
            .op
            .second
            .followers
            .iter()
            .map(|fl| match self.load_of[fl.particle as usize] {
                u32::MAX => Vect::<D>::zeros(),
                l => {
                    let r = &self.loads[l as usize];
                    r.force_at(t) / (r.members.len().max(1) as f64)
                }
            })
            .collect();
        (self.gravity.at(t), loads)
    }

    /// The followers' external forces in `force` were spread with the inputs of the last
    /// force evaluation; if gravity or a load changed since (set between steps), spreads the
    /// difference (the spread is linear in both), so that the step sees the inputs it applies
    /// to the other particles.
    fn respread_follower_inputs(&mut self, t: f64) {
        if self.op.second.followers.is_empty() {
            return;
        }
        let (g, loads) = self.follower_external_inputs(t);
        let (g0, loads0) = &self.follower_inputs;
        if g == *g0 && loads == *loads0 {
            return;
        }
        let so = &self.op.second;
        let delta: Vec<Vect<D>> = loads.iter().zip(loads0).map(|(a, b)| a - b).collect();
        so.spread_to_followed(
            &self.p.mass,
            g - g0,
            |i| delta[so.followers.partition_point(|f| (f.particle as usize) < i)],
            &mut self.force,
        );
        self.follower_inputs = (g, loads);
    }

    /// Moves the followers of clamped faces to their constraint (displacement and velocity).
    pub(super) fn sync_followers(&mut self) {
        let p = &mut self.p;
        for fl in &self.op.second.followers {
            let i = fl.particle as usize;
            p.u[i] = fl.follow(|j| p.u[j]);
            p.v[i] = fl.follow(|j| p.v[j]);
            p.x[i] = p.x0[i] + p.u[i];
        }
    }

    /// One step of length dt (s).
    pub fn step(&mut self, dt: f64) -> Result<(), SimError> {
        self.step_to(dt, self.time + dt)
    }

    fn step_to(&mut self, dt: f64, t_new: f64) -> Result<(), SimError> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(SimError::Invalid(format!(
                "time step must be positive and finite, got {dt}"
            )));
        }
        let t = self.time;
        self.respread_follower_inputs(t);
        let group_disp: Vec<(Vect<D>, Vect<D>)> = self
            .groups
            .iter()
            .map(|g| (g.motion.at(t), g.motion.at(t_new)))
            .collect();
        let load_pp: Vec<Vect<D>> = self
            .loads
            .iter()
            .map(|l| l.force_at(t) / (l.members.len().max(1) as f64))
            .collect();
        // The velocities are those of the previous step: its forces act over half of each step
        // (`StepInputs::kick_dt`). Why (2026-12-07): the step changes whenever contact starts or
        // ends (`set_omega_max`); with the kick over the new step alone each change shifted
        // the velocities by (dt - dt_previous) / 2 times the acceleration, and in case 3, where
        // crack faces touch and part hundreds of times, those shifts pumped energy in (the
        // staggered kinetic plus strain energy of the broken block rose from 0.83 to 2.4 kJ
        // between 0.6 and 1.3 s). The first step's velocities are the initial ones.
        let kick_dt = if self.previous_step > 0.0 {
            0.5 * (self.previous_step + dt)
        } else {
            dt
        };
        let inputs = StepInputs {
            dt,
            kick_dt,
            gravity: self.gravity.at(t),
            damping: self.options.damping,
            group_of: &self.group_of,
            group_disp: &group_disp,
            load_of: &self.load_of,
            load_per_particle: &load_pp,
            max_move: 0.5 * self.l0,
        };
        let bad = symplectic_euler(
            &mut self.p,
            &self.force,
            &self.torque,
            &inputs,
            &mut self.bad,
        );
        self.sync_followers();
        self.time = t_new;
        self.steps += 1;
        self.previous_step = dt;
        if let Some(i) = bad {
            return Err(SimError::BlowUp {
                time: self.time,
                step: self.steps,
                particle: i,
                body: self.body_names[self.p.body[i] as usize].clone(),
                note: self.blow_up_note(i),
            });
        }
        self.fracture();
        self.update_forces()?;
        self.maybe_refresh_step();
        Ok(())
    }

    /// Advances to t_end with equal sub-steps no longer than `max_dt`, landing exactly on t_end.
    /// Group displacements follow their motions (see [`World::set_group_motion`]). Returns the
    /// number of steps taken.
    pub fn advance_to(&mut self, t_end: f64) -> Result<u64, SimError> {
        self.advance_to_with(t_end, |_| true)
    }

    /// [`World::advance_to`] calling `on_step(time)` after every step (progress reports; the
    /// steps are the same). When it returns false the advance stops there, after a complete
    /// step, with `SimError::Interrupted`.
    pub fn advance_to_with(
        &mut self,
        t_end: f64,
        mut on_step: impl FnMut(f64) -> bool,
    ) -> Result<u64, SimError> {
        if !t_end.is_finite() {
            return Err(SimError::Invalid(format!(
                "end time must be finite, got {t_end}"
            )));
        }
        let t0 = self.time;
        let h = t_end - t0;
        if h <= 0.0 {
            return Ok(0);
        }
        let mut taken = 0;
        let (mut t0, mut h) = (t0, h);
        'outer: loop {
            let max_dt = self.max_dt();
            let n = ((h / max_dt) * (1.0 - 1e-12)).ceil().max(1.0) as u64;
            let dt = h / n as f64;
            for k in 1..=n {
                let t_new = if k == n { t_end } else { t0 + k as f64 * dt };
                self.step_to(t_new - self.time, t_new)?;
                taken += 1;
                if !on_step(self.time) && self.time < t_end {
                    return Err(SimError::Interrupted {
                        time: self.time,
                        step: self.steps,
                    });
                }
                // The stable step was measured again and is shorter: the rest of the advance
                // in equal steps of the new length.
                if k < n && self.max_dt() < max_dt {
                    t0 = self.time;
                    h = t_end - t0;
                    continue 'outer;
                }
            }
            return Ok(taken);
        }
    }

    /// Sets the displacement law of a group (m, s): linear from `motion.from` at `motion.t_from`
    /// to `motion.to` at `motion.t_to`, constant outside.
    pub fn set_group_motion(&mut self, g: usize, motion: GroupMotion<D>) {
        self.groups[g].motion = motion;
    }

    /// Moves a group linearly from where it is now to displacement `d` (m) at time `t_end` (s):
    /// a smooth prescribed motion for a caller that knows the next target.
    pub fn ramp_group_to(&mut self, g: usize, d: Vect<D>, t_end: f64) {
        let t = self.time;
        let from = self.groups[g].motion.at(t);
        self.groups[g].motion = GroupMotion {
            from,
            to: d,
            t_from: t,
            t_to: t_end,
        };
    }

    /// Sets the total external force on a load region (N) at time `t_ref` and its rate (N/s).
    pub fn set_load(&mut self, r: usize, f: Vect<D>, rate: Vect<D>, t_ref: f64) {
        let l = &mut self.loads[r];
        l.force = f;
        l.rate = rate;
        l.t_ref = t_ref;
    }

    /// Replaces the gravity law.
    pub fn set_gravity(&mut self, law: GravityLaw<D>) {
        self.gravity = law;
    }
}
