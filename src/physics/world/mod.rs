//! The simulated world: bodies of particles, bonds, boundary groups, loads and gravity, and the
//! order of a step (integrate with the forces of the current state, then evaluate the forces of
//! the new state, so reactions and energies always describe the current time).
//!
//! By concern: `build` (World::new), `step` (the forces, the step and its inputs),
//! `stable_step` (omega_max and its refresh), `mirror` (ghosts and followers of mirror faces),
//! `state` (capture and restore), `queries` (energies, momenta, probes, fragments).
mod build;
pub mod faces;
mod mirror;
mod queries;
mod setup;
mod stable_step;
mod state;
mod step;

pub use build::MIN_SPACING_BITS;
pub use mirror::MirrorFace;
pub use setup::{SetupInterrupt, SetupMemo, SetupObserver, SetupStage, Unobserved};
pub use stable_step::{
    StableStepState, LANCZOS_ITERATIONS, LANCZOS_LEAST, LANCZOS_SETTLED, LANCZOS_SETTLE_WINDOW,
    OMEGA_MARGIN, REFRESH_CHECK_EVERY, REFRESH_DEFORMATION, REFRESH_ITERATIONS, REFRESH_MIN_STEPS,
};
pub use state::WorldState;

use super::bonds::Bonds;
use super::boundary::{BoundaryGroup, GravityLaw, LoadRegion};
use super::contact::Contact;
use super::dim::{Dim, Mat, Space, Vect};
use super::elastic::{ElasticOperator, ElasticScratch};
pub use super::ghosts::Ghost;
use super::params::{Material, SolverOptions};
use super::particles::Particles;

/// Errors of the solver; each says what happened, when and where.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    #[error("numerical blow-up at t = {time:.6e} s (step {step}): particle {particle} of body '{body}' was accelerated by more than half a particle spacing in one step (dt times its change of velocity) or became non-finite; reduce dt or check loads{note}")]
    BlowUp {
        time: f64,
        step: u64,
        particle: usize,
        body: String,
        /// What the material state says about the cause (empty when nothing is known): with
        /// the Saint Venant-Kirchhoff law, the particles compressed beyond its stability limit.
        note: String,
    },
    #[error("material collapse at t = {time:.6e} s (step {step}): particle {particle} of body '{body}' has det F = {det:.4e} <= 0 (compressed to nothing or turned inside out), where the neo-Hookean law has no energy; its energy grows without bound as det F -> 0, so only a step too long for the stiffening of the crushed particle or a load the discretisation cannot carry gets there (try a smaller solver.safety or particle spacing, or a smaller load)")]
    Collapsed {
        time: f64,
        step: u64,
        particle: usize,
        body: String,
        /// det F of the particle (its area or volume ratio; in the span of its bonds after
        /// fracture) (-).
        det: f64,
    },
    #[error("particles overlap at t = {time:.6e} s (step {step}): particle {} of body '{}' and particle {} of body '{}', not joined by an intact bond, are {distance:.4e} m apart, below the overlap limit {limit:.4e} m (contact.overlap_fraction x the pair's contact distance, l0 or the reference length of a broken bond){}", particles[0], bodies[0], particles[1], bodies[1], if bodies[0] == bodies[1] { "; they are parts of one body separated by fracture" } else { "" })]
    Overlap {
        time: f64,
        step: u64,
        /// Names of the bodies of the two particles.
        bodies: [String; 2],
        particles: [usize; 2],
        /// Their distance (m).
        distance: f64,
        /// The overlap limit: overlap_fraction times the pair's contact distance (m).
        limit: f64,
    },
    #[error("invalid input: {0}")]
    Invalid(String),
    /// Invalid input of one boundary group (index `group` of the groups given), naming the
    /// group's field at fault.
    #[error("invalid input: group '{name}' ({field}): {message}")]
    Boundary {
        group: usize,
        name: String,
        field: String,
        message: String,
    },
    #[error("{}", work_refusal(*t_end, *steps, *dt, *particles, *limit, *max_particle_steps, *wall_estimate_s))]
    TooMuchWork {
        /// Time the advance was asked to reach (s).
        t_end: f64,
        /// Steps it would take.
        steps: u64,
        /// solver.max_steps.
        limit: u64,
        /// The solver step (s).
        dt: f64,
        /// Particles of the scene.
        particles: usize,
        /// solver.max_particle_steps (particle-steps: particles x solver steps).
        max_particle_steps: u64,
        /// The advance's estimated wall time on two cores (s; `Simulation::estimate_wall_time`).
        wall_estimate_s: f64,
    },
    #[error("stopped on request at t = {time:e} s (step {step})")]
    Interrupted {
        /// Time reached (s): the state is that of a complete step.
        time: f64,
        step: u64,
    },
    #[error("out of memory: {0}")]
    OutOfMemory(String),
    #[error("{what}, more than solver.max_setup_seconds = {limit} s; nothing was built (raise solver.max_setup_seconds to let it finish, or use a larger particle spacing)")]
    SetupTooLong {
        /// How long the set-up took or would take, and how that is known.
        what: String,
        /// solver.max_setup_seconds (s).
        limit: f64,
    },
    #[error("the set-up was stopped {0}")]
    Stopped(String),
}

/// The message of [`SimError::TooMuchWork`]: which limit the advance exceeds, its estimated
/// wall time and how to get under the limit.
fn work_refusal(
    t_end: f64,
    steps: u64,
    dt: f64,
    particles: usize,
    limit: u64,
    max_particle_steps: u64,
    wall_estimate_s: f64,
) -> String {
    let work = steps as f64 * particles as f64;
    let (over, raise) = if steps > limit {
        (
            format!("more than solver.max_steps = {limit}"),
            "solver.max_steps",
        )
    } else {
        (
            format!(
                "{} particle-steps for {particles} particles, more than solver.max_particle_steps = {:e}",
                sci(work),
                max_particle_steps as f64
            ),
            "solver.max_particle_steps",
        )
    };
    format!(
        "advancing to t = {t_end:e} s would take {steps} solver steps of dt = {dt:.4e} s, {over} \
         (about {} of wall time on two cores); nothing was done (use a shorter advance, a larger \
         particle spacing or a softer/denser material, or raise {raise})",
        duration_text(wall_estimate_s)
    )
}

/// A large count in short scientific notation: 5.6e9.
fn sci(v: f64) -> String {
    let s = format!("{v:.2e}");
    // 5.60e9 -> 5.6e9, 1.00e10 -> 1e10.
    match s.split_once('e') {
        Some((m, e)) => format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.')),
        None => s,
    }
}

/// A wall time for a person: "40 s", "12 min", "3.5 h", "9 days", "2e3 years".
pub fn duration_text(s: f64) -> String {
    if !s.is_finite() {
        return "an unbounded time".into();
    }
    let (v, unit) = if s < 90.0 {
        (s, "s")
    } else if s < 5400.0 {
        (s / 60.0, "min")
    } else if s < 2.0 * 86400.0 {
        (s / 3600.0, "h")
    } else if s < 730.0 * 86400.0 {
        (s / 86400.0, "days")
    } else {
        (s / (365.25 * 86400.0), "years")
    };
    if v >= 1e4 {
        format!("{} {unit}", sci(v))
    } else if v >= 10.0 {
        format!("{v:.0} {unit}")
    } else {
        format!("{v:.1} {unit}")
    }
}

/// A body to create: its material, particle positions and initial velocity.
#[derive(Clone, Debug)]
pub struct BodyInit<const D: usize>
where
    Space: Dim<D>,
{
    pub name: String,
    pub material: Material,
    pub points: Vec<Vect<D>>,
    pub velocity: InitialVelocity<D>,
    /// A body filled from a solid: its particles' volumes, normals and areas. None: every
    /// particle has the volume l0^d.
    pub shape: Option<ShapeFill<D>>,
}

/// What a body filled from a solid (scene shapes, issue 26) carries per particle, in the order
/// of its points.
#[derive(Clone, Debug)]
pub struct ShapeFill<const D: usize> {
    /// The solid's volume the particle stands for (m^d): its mass is the density times it.
    pub volumes: Vec<f64>,
    /// Outward unit normal of the solid's surface in the particle's cells (zero inside).
    pub normals: Vec<Vect<D>>,
    /// Area of that surface (m^(d-1); per m of depth in 2D; 0 inside).
    pub areas: Vec<f64>,
    /// Distance from the particle's centre to the solid's surface (m, > 0): the radius of the
    /// largest ball about the centre inside the solid, which is what the particle stands for in
    /// contact (module `contact`).
    pub depths: Vec<f64>,
    /// First and second moments of the particle's solid about its centre (m^(d+1), m^(d+2)):
    /// what the second-order operator's cell energy integrates with (module `second_order`).
    /// A whole cell: zero and l0^(d+2) / 12 on the diagonal.
    pub moments: Vec<(Vect<D>, Mat<D>)>,
    /// The solid when it is one axis-aligned box (its least and greatest corners, m): a box
    /// given as shapes whose sides need not be whole numbers of spacings. The second-order
    /// operator's closure (module `sbp`) then knows its faces, also where they cut cells.
    pub solid_box: Option<(Vect<D>, Vect<D>)>,
}

/// Initial velocity of the particles of a body. Particles of a boundary group start with zero
/// velocity along the group's held axes, and with zero angular velocity when the group holds
/// rotation, whatever is given here.
#[derive(Clone, Debug)]
pub enum InitialVelocity<const D: usize>
where
    Space: Dim<D>,
{
    /// Every particle moves with this velocity (m/s) and does not spin.
    Uniform(Vect<D>),
    /// One velocity (m/s) and one angular velocity (rad/s) per point, in the order of
    /// `BodyInit::points`. The angular velocities are kept only by operators with particle
    /// rotations (the paper's); the corrected operator has no rotational degree of freedom (no
    /// moments, so a spin given to its particles would stay constant and only add a constant to
    /// the kinetic energy), and its particles start with zero angular velocity.
    PerParticle {
        v: Vec<Vect<D>>,
        w: Vec<<Space as Dim<D>>::Ang>,
    },
}

impl<const D: usize> From<Vect<D>> for InitialVelocity<D>
where
    Space: Dim<D>,
{
    fn from(v: Vect<D>) -> Self {
        InitialVelocity::Uniform(v)
    }
}

/// A boundary group to create (member indices are global particle indices).
#[derive(Clone, Debug)]
pub struct GroupInit {
    pub name: String,
    pub members: Vec<u32>,
    pub axes: [bool; 3],
    pub fix_rotation: bool,
    /// The group as a mirror of the body across this face (second-order operator only).
    pub mirror: Option<MirrorFace>,
}

/// The simulated world.
pub struct World<const D: usize>
where
    Space: Dim<D>,
{
    pub options: SolverOptions,
    /// Initial particle spacing l0 (m).
    pub l0: f64,
    /// Effective radius re (m).
    pub re: f64,
    pub body_names: Vec<String>,
    pub p: Particles<D>,
    pub bonds: Bonds<D>,
    pub op: ElasticOperator<D>,
    pub groups: Vec<BoundaryGroup<D>>,
    pub loads: Vec<LoadRegion<D>>,
    pub gravity: GravityLaw<D>,
    pub time: f64,
    pub steps: u64,
    /// Surface particles and contact (section 2.5).
    pub contact: Contact<D>,
    /// Fracture checks so far, one per step (0 when eps_max is infinite).
    pub fracture_checks: u64,
    /// Checks that tested every bond (the others were screened out: no bond could have
    /// reached eps_max since the last test, `strain_screen::StrainScreen`).
    pub strain_tests: u64,
    /// Bond pairs broken so far, Eq. (42).
    pub broken_pairs: u64,
    /// Strain energy released by the breaks so far (J): at each break, what the particles
    /// that lost bonds held just before less what they hold after their re-fit (never
    /// negative, `ElasticOperator::limit_at_break`). 0 for the paper's operators.
    pub fracture_release: f64,
    omega_max: f64,
    /// Length of the step that led to the current state (s); 0 before the first step. The
    /// velocities are this step's (`StepInputs::kick_dt`).
    previous_step: f64,
    omega_elastic: f64,
    /// omega_max of the elastic model in the reference configuration (with the margin).
    omega_reference: f64,
    /// Contact bound of omega^2 (rad^2/s^2).
    omega2_contact: f64,
    stable: StableStepState<D>,
    /// Force evaluations the set-up's Lanczos measurement of omega_max took (at most
    /// LANCZOS_ITERATIONS, fewer once its value settled).
    pub lanczos_evaluations: usize,
    /// Measurements of the stable step in the current configuration so far.
    pub step_refreshes: u64,
    /// Wall time spent checking and refreshing the stable step (s).
    pub step_refresh_seconds: f64,
    frac_flag: Vec<u8>,
    strain_screen: crate::physics::strain_screen::StrainScreen<D>,
    scratch: ElasticScratch<D>,
    force: Vec<Vect<D>>,
    /// The gravity (m/s^2) and the followers' load shares (N, per follower) with which the
    /// followers' external forces were spread into `force` (its last evaluation): a step whose
    /// inputs changed since (a co-simulation host setting gravity or loads) spreads the
    /// difference first.
    follower_inputs: (Vect<D>, Vec<Vect<D>>),
    torque: Vec<<Space as Dim<D>>::Ang>,
    group_of: Vec<u32>,
    load_of: Vec<u32>,
    bad: Vec<u8>,
    /// Per particle, the outward normal and area (m^(d-1)) of the solid's surface it carries
    /// (bodies filled from shapes; zero elsewhere). Empty when no body has a shape.
    pub surface: Vec<(Vect<D>, f64)>,
    /// Second-order operator: per body, its summation-by-parts closure at the free faces
    /// (module `sbp`: the solve's figures) or why the body keeps the plain fits. Empty for
    /// the other operators.
    pub closure: Vec<Result<String, String>>,
    /// Second-order operator: per clamped group without a mirror face (all axes held), its
    /// face from the geometry with followers (Ok), or why it keeps the rigid grip (module
    /// `faces`). Empty for the other operators.
    pub clamp_faces: Vec<(usize, Result<(), String>)>,
    /// Second-order operator: per support without a mirror face (some axes held), the face it
    /// mirrors the body across from the geometry, or why not (module `faces`). Empty for the
    /// other operators.
    pub support_faces: Vec<(usize, faces::SupportFace)>,
}

impl<const D: usize> World<D>
where
    Space: Dim<D>,
{
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.p.len()
    }

    pub fn is_empty(&self) -> bool {
        self.p.is_empty()
    }
}
