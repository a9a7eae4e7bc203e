//! A simulation of either dimension behind one type, chosen by the scene: what the command line
//! and the FMI layer use. Values cross this boundary as 3-arrays (z = 0 in 2D).
use crate::physics::boundary::{GravityLaw, GroupMotion};
use crate::physics::dim::{from3, to3};
use crate::physics::world::{SetupObserver, Unobserved, WorldState};
use crate::physics::{ElasticModel, SimError};
use crate::scene::limits::num;
use crate::scene::{Model, Scene, SceneError, SceneWarning};
use serde::{Deserialize, Serialize};

/// Operator families of the cost model: the second-order operator, and the bond operators
/// (corrected and the paper's, whose costs per bond are alike).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CostFamily {
    SecondOrder,
    Bond,
}

fn model_family(m: ElasticModel) -> CostFamily {
    match m {
        ElasticModel::SecondOrder => CostFamily::SecondOrder,
        _ => CostFamily::Bond,
    }
}

/// Wall time of one solver step on two cores at re = 2.1 dp: (family, dimension, fixed cost
/// per step (s), cost per particle (s)). Fitted to the step times of BENCHMARKS.md ("Bending:
/// run time against error": the plate in 2D at 4 and 16 across, the cantilever in 3D at 4 and 8
/// across, two rayon threads on an idle machine); the fixed part is thread synchronisation and
/// the per-step passes over the groups, which dominate scenes of a few hundred particles.
pub const STEP_COST: [(CostFamily, usize, f64, f64); 4] = [
    (CostFamily::SecondOrder, 2, 22e-6, 0.20e-6),
    (CostFamily::SecondOrder, 3, 20e-6, 1.08e-6),
    (CostFamily::Bond, 2, 30e-6, 0.075e-6),
    (CostFamily::Bond, 3, 20e-6, 0.22e-6),
];

/// A built scene of dimension 2 or 3.
pub enum Simulation {
    D2(Box<Model<2>>),
    D3(Box<Model<3>>),
}

/// Per-particle data at one instant (3-arrays; z = 0 in 2D).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParticleSnapshot {
    pub time: f64,
    pub body: Vec<u32>,
    pub position: Vec<[f64; 3]>,
    pub displacement: Vec<[f64; 3]>,
    pub velocity: Vec<[f64; 3]>,
    pub surface: Vec<bool>,
    pub broken_bonds: Vec<u32>,
    /// Held by a boundary condition on at least one axis (supports, clamps); empty = none.
    #[serde(default)]
    pub fixed: Vec<bool>,
    /// The volume each particle stands for (m^3; m^2 in 2D, per m of depth); empty = unknown.
    #[serde(default)]
    pub volume: Vec<f64>,
    /// Of bodies filled from shapes: the outward unit normal of the solid's surface a particle
    /// carries (zero inside); empty when no body has a shape.
    #[serde(default)]
    pub normal: Vec<[f64; 3]>,
    /// The area of that surface (m^2; m in 2D); empty when no body has a shape.
    #[serde(default)]
    pub area: Vec<f64>,
}

/// The evolving state of a simulation as plain data (serde): FMU state, checkpoints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SimState {
    D2(WorldState<2>),
    D3(WorldState<3>),
}

macro_rules! with {
    ($s:expr, $m:ident => $e:expr) => {
        match $s {
            Simulation::D2($m) => $e,
            Simulation::D3($m) => $e,
        }
    };
}

impl Simulation {
    /// A fixed solver.dt below this fraction of the stable step is refused: it would take a
    /// million steps where one does.
    pub const MIN_DT_FRACTION: f64 = 1e-6;

    /// Validates the scene and builds its world.
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        Self::new_observed(scene, &Unobserved)
    }

    /// [`Simulation::new`] with the set-up's stages told to `observer` as they end; the
    /// observer may stop the set-up at a stage boundary.
    pub fn new_observed(scene: &Scene, observer: &dyn SetupObserver) -> Result<Self, SceneError> {
        scene.validate()?;
        let sim = match scene.dimension {
            2 => Simulation::D2(Box::new(Model::<2>::build_observed(scene, observer)?)),
            _ => Simulation::D3(Box::new(Model::<3>::build_observed(scene, observer)?)),
        };
        let crit = sim.critical_dt();
        if let Some(dt) = scene.solver.dt {
            if crit.is_finite() && dt < Self::MIN_DT_FRACTION * crit {
                return Err(SceneError {
                    field: "solver.dt".into(),
                    message: format!(
                        "{} s is below {} x the stable step {} s of this scene",
                        num(dt),
                        num(Self::MIN_DT_FRACTION),
                        num(crit)
                    ),
                });
            }
        }
        Ok(sim)
    }
    /// Warnings of under-resolved geometry found while building (see `Scene::warnings`).
    pub fn warnings(&self) -> &[SceneWarning] {
        with!(self, m => &m.warnings)
    }
    pub fn dimension(&self) -> usize {
        with!(self, _m => if matches!(self, Simulation::D2(_)) { 2 } else { 3 })
    }
    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        with!(self, m => m.world.time)
    }
    /// Steps taken since the start.
    pub fn steps(&self) -> u64 {
        with!(self, m => m.world.steps)
    }
    pub fn particles(&self) -> usize {
        with!(self, m => m.world.len())
    }
    /// Stored (directed) bonds.
    pub fn bonds(&self) -> usize {
        with!(self, m => m.world.bonds.len())
    }
    /// Stability limit 2 / omega_max of the particle model (s).
    pub fn critical_dt(&self) -> f64 {
        with!(self, m => m.world.critical_dt())
    }
    /// Largest step the solver takes (s).
    pub fn max_dt(&self) -> f64 {
        with!(self, m => m.world.max_dt())
    }
    /// The work guard of the scene: most solver steps one advance may take.
    pub fn max_steps(&self) -> u64 {
        with!(self, m => m.world.options.max_steps)
    }
    /// Solver steps an advance from the current time to t_end takes: the remaining time over
    /// the largest step, rounded up as `World::advance_to` does (0 when t_end is not ahead or
    /// not finite; saturates at u64::MAX).
    pub fn estimate_steps(&self, t_end: f64) -> u64 {
        let h = t_end - self.time();
        if !(h > 0.0 && h.is_finite()) {
            return 0;
        }
        let n = ((h / self.max_dt()) * (1.0 - 1e-12)).ceil().max(1.0);
        // `as` saturates: NaN (dt = inf over h = inf cannot occur here) gives 0, huge gives MAX.
        if n.is_nan() {
            u64::MAX
        } else {
            n as u64
        }
    }
    /// The work guard of the scene in particle-steps (particles x solver steps per advance).
    pub fn max_particle_steps(&self) -> u64 {
        with!(self, m => m.world.options.max_particle_steps)
    }
    /// Estimated wall time (s) of `steps` solver steps of this scene on two cores: a fixed cost
    /// per step plus a cost per particle-step of the operator and dimension
    /// ([`STEP_COST`]), scaled by the neighbours per particle, (re_factor / 2.1)^D. An estimate
    /// to a factor of about two (contact, fracture and the machine's load add to it).
    pub fn estimate_wall_time(&self, steps: u64) -> f64 {
        let d = self.dimension();
        let (model, re) = with!(self, m => (m.world.options.model, m.world.options.re_factor));
        let cost = STEP_COST
            .iter()
            .find(|c| c.0 == model_family(model) && c.1 == d)
            .expect("every family and dimension is listed");
        let neighbours = (re / 2.1).powi(d as i32);
        steps as f64 * (cost.2 + cost.3 * neighbours * self.particles() as f64)
    }
    /// Ok when advancing to t_end takes at most solver.max_steps steps and at most
    /// solver.max_particle_steps particle-steps, else `SimError::TooMuchWork` (nothing is
    /// changed) with the advance's estimated wall time.
    pub fn check_work(&self, t_end: f64) -> Result<(), SimError> {
        let steps = self.estimate_steps(t_end);
        let limit = self.max_steps();
        let particles = self.particles();
        let max_particle_steps = self.max_particle_steps();
        if steps > limit || steps as f64 * particles as f64 > max_particle_steps as f64 {
            return Err(SimError::TooMuchWork {
                t_end,
                steps,
                limit,
                dt: self.max_dt(),
                particles,
                max_particle_steps,
                wall_estimate_s: self.estimate_wall_time(steps),
            });
        }
        Ok(())
    }
    /// Advances to t_end, landing on it exactly; returns the steps taken. Refused before any
    /// step when it would take more work than the scene allows (`SimError::TooMuchWork`, see
    /// [`Simulation::check_work`]).
    pub fn advance_to(&mut self, t_end: f64) -> Result<u64, SimError> {
        self.advance_to_with(t_end, |_| true)
    }
    /// [`Simulation::advance_to`] calling `on_step(time)` after every solver step (progress
    /// reports; the steps are the same); it stops the advance after the step with
    /// `SimError::Interrupted` by returning false.
    pub fn advance_to_with(
        &mut self,
        t_end: f64,
        on_step: impl FnMut(f64) -> bool,
    ) -> Result<u64, SimError> {
        self.check_work(t_end)?;
        with!(self, m => m.world.advance_to_with(t_end, on_step))
    }
    /// Replaces the gravity law by `start + rate (t - t0)` (m/s^2, m/s^3, s; simulation time).
    pub fn set_gravity_linear(&mut self, start: [f64; 3], rate: [f64; 3], t0: f64) {
        with!(self, m => m.world.set_gravity(GravityLaw::Linear {
            start: from3(start),
            rate: from3(rate),
            t0,
        }))
    }
    /// Current gravity (m/s^2).
    pub fn gravity(&self) -> [f64; 3] {
        with!(self, m => to3(&m.world.gravity.at(m.world.time)))
    }
    /// Sets the motion of boundary group g: displacement `from` at `t_from`, moving linearly to
    /// `to` at `t_to`, constant outside (m, s; simulation time).
    pub fn set_group_motion(
        &mut self,
        g: usize,
        from: [f64; 3],
        to: [f64; 3],
        t_from: f64,
        t_to: f64,
    ) {
        with!(self, m => m.world.set_group_motion(g, GroupMotion {
            from: from3(from),
            to: from3(to),
            t_from,
            t_to,
        }))
    }
    /// Displacement of boundary group g at the current time (m).
    pub fn group_displacement(&self, g: usize) -> [f64; 3] {
        with!(self, m => to3(&m.world.groups[g].motion.at(m.world.time)))
    }
    /// Sets the total external force on load region r (N) at simulation time `t_ref` and its rate
    /// of change (N/s).
    pub fn set_load(&mut self, r: usize, f: [f64; 3], rate: [f64; 3], t_ref: f64) {
        with!(self, m => m.world.set_load(r, from3(f), from3(rate), t_ref))
    }
    pub fn load(&self, r: usize) -> [f64; 3] {
        with!(self, m => to3(&m.world.loads[r].force))
    }
    /// Displacement of probe k (m).
    pub fn probe_displacement(&self, k: usize) -> [f64; 3] {
        with!(self, m => to3(&m.probe_displacement(k)))
    }
    /// Velocity of probe k (m/s).
    pub fn probe_velocity(&self, k: usize) -> [f64; 3] {
        with!(self, m => to3(&m.probe_velocity(k)))
    }
    /// Mean displacement (m) and mean velocity (m/s) of the particles load region r acts on.
    pub fn load_motion(&self, r: usize) -> ([f64; 3], [f64; 3]) {
        with!(self, m => {
            let (u, v) = m.world.load_motion(r);
            (to3(&u), to3(&v))
        })
    }
    /// Particles of boundary group g.
    pub fn group_size(&self, g: usize) -> usize {
        with!(self, m => m.world.groups[g].members.len())
    }
    /// Particles of load region r.
    pub fn load_size(&self, r: usize) -> usize {
        with!(self, m => m.world.loads[r].members.len())
    }
    /// Reference position of the particle probe k is read from (m).
    pub fn probe_particle_position(&self, k: usize) -> [f64; 3] {
        with!(self, m => to3(&m.world.p.x0[m.probes[k].particle]))
    }
    /// Reaction force of boundary group g on the body (N).
    pub fn group_reaction(&self, g: usize) -> [f64; 3] {
        with!(self, m => to3(&m.world.groups[g].reaction))
    }
    /// Kinetic energy (J).
    pub fn kinetic_energy(&self) -> f64 {
        with!(self, m => m.world.kinetic_energy())
    }
    /// Strain energy (J).
    pub fn strain_energy(&self) -> f64 {
        with!(self, m => m.world.strain_energy())
    }
    /// Number of broken bonds (each pair counted once).
    pub fn broken_bonds(&self) -> u64 {
        with!(self, m => m.world.bonds.w0.iter().filter(|&&w| w == 0.0).count() as u64 / 2)
    }
    /// Broken bond pairs counted during the run (equals `broken_bonds` for bonds broken by
    /// fracture; kept as a counter, O(1)).
    /// Strain energy released by broken bonds so far (J; per metre of depth in 2D).
    pub fn fracture_energy(&self) -> f64 {
        with!(self, m => m.world.fracture_release)
    }

    pub fn broken_pairs(&self) -> u64 {
        with!(self, m => m.world.broken_pairs)
    }
    /// Largest strain over the intact bonds now (-) (O(bonds)).
    pub fn max_bond_strain(&self) -> f64 {
        with!(self, m => m.world.max_bond_strain().0)
    }
    /// Separate fragments: connected components over intact bonds, all bodies (O(bonds)).
    pub fn fragments(&self) -> usize {
        with!(self, m => m.world.fragments())
    }
    /// Contact potential energy (J).
    pub fn contact_energy(&self) -> f64 {
        with!(self, m => m.world.contact_energy())
    }
    /// Pairs of particles in contact now.
    pub fn contact_pairs(&self) -> usize {
        with!(self, m => m.world.contact_pairs())
    }
    /// Contact pair-list builds so far (0: no contact search was needed).
    pub fn contact_searches(&self) -> u64 {
        with!(self, m => m.world.contact_searches())
    }
    /// Force evaluations so far in which a pair of one body (across a broken bond, or never
    /// bonded) was within its contact distance: while 0, the scene's
    /// `solver.contact.fractured_surfaces` has changed nothing in the run.
    pub fn same_body_touches(&self) -> u64 {
        with!(self, m => m.world.same_body_touches())
    }
    /// Fracture checks so far, one per step (0 when eps_max is infinite).
    pub fn fracture_checks(&self) -> u64 {
        with!(self, m => m.world.fracture_checks)
    }
    /// Fracture checks that tested every bond; the others were screened out (no bond's ends
    /// had moved far enough since the last test to reach eps_max).
    pub fn strain_tests(&self) -> u64 {
        with!(self, m => m.world.strain_tests)
    }
    /// Number of surface particles, Eq. (41).
    pub fn surface_particles(&self) -> usize {
        with!(self, m => m.world.contact.surface_ids.len())
    }
    /// Total linear momentum (kg m/s).
    pub fn momentum(&self) -> [f64; 3] {
        with!(self, m => to3(&m.world.momentum()))
    }
    /// Names of the bodies, in scene order.
    pub fn body_names(&self) -> Vec<String> {
        with!(self, m => m.world.body_names.clone())
    }
    /// Per-particle data for output (ParaView snapshots): body, position, displacement,
    /// velocity, surface flag, broken bonds.
    pub fn particle_snapshot(&self) -> ParticleSnapshot {
        with!(self, m => {
            let w = &m.world;
            let n = w.len();
            ParticleSnapshot {
                time: w.time,
                body: w.p.body.clone(),
                position: w.p.x.iter().map(to3).collect(),
                displacement: (0..n).map(|i| to3(&w.p.displacement(i))).collect(),
                velocity: w.p.v.iter().map(to3).collect(),
                surface: w.contact.surface.clone(),
                broken_bonds: (0..n).map(|i| w.broken_bonds_of(i)).collect(),
                fixed: w.p.fix.iter().map(|&f| f != 0).collect(),
                volume: w.op.base_vol.clone(),
                normal: w.surface.iter().map(|(nrm, _)| to3(nrm)).collect(),
                area: w.surface.iter().map(|(_, a)| *a).collect(),
            }
        })
    }
    /// The surface mesh of the bodies of `scene` (the scene this simulation was built from):
    /// `mps run --surface`.
    pub fn surface_mesh(
        &self,
        scene: &Scene,
    ) -> Result<crate::scene::surface::SurfaceMesh, SceneError> {
        with!(self, m => m.surface_mesh(scene))
    }
    /// The displacement of each vertex of a surface mesh now (m).
    pub fn surface_displacement(&self, mesh: &crate::scene::surface::SurfaceMesh) -> Vec<[f64; 3]> {
        with!(self, m => m.surface_displacement(mesh))
    }
    pub fn state(&self) -> SimState {
        match self {
            Simulation::D2(m) => SimState::D2(m.world.state()),
            Simulation::D3(m) => SimState::D3(m.world.state()),
        }
    }
    pub fn set_state(&mut self, s: &SimState) -> Result<(), SimError> {
        match (self, s) {
            (Simulation::D2(m), SimState::D2(s)) => m.world.set_state(s),
            (Simulation::D3(m), SimState::D3(s)) => m.world.set_state(s),
            _ => Err(SimError::Invalid("state of the other dimension".into())),
        }
    }
}
