//! Plain parameter structs of the solver (serde, units in the doc comments).
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Default of `SolverOptions::max_particles`: about 4 GB in 3D and 1.6 GB in 2D at re = 2.1 dp
/// (measured 1977 and 776 bytes per particle; scene::memory has the estimate).
pub const DEFAULT_MAX_PARTICLES: usize = 2_000_000;

/// Default of `SolverOptions::max_steps`: it bounds the work of small scenes, whose steps cost
/// mostly the fixed overhead of a step (2e7 steps of the 280-particle tests/data/small2d.json
/// take about 25 min on two idle cores); `max_particle_steps` bounds the large ones.
pub const DEFAULT_MAX_STEPS: u64 = 20_000_000;

/// Default of `SolverOptions::max_particle_steps`: 1e10 particle-steps (particles x solver
/// steps), about 35 min of wall time on two cores with the corrected operator or second_order
/// in 2D and about 3 h with second_order in 3D (`Simulation::estimate_wall_time`). The paper's
/// cases take 1.5e7 (case 1) to 8e7 (case 3 with second_order).
pub const DEFAULT_MAX_PARTICLE_STEPS: u64 = 10_000_000_000;
/// Default of `SolverOptions::max_setup_seconds`: 10 minutes. A 27,000-particle cube clamped
/// with `mirror` sets up in about a minute on 2 cores.
pub const DEFAULT_MAX_SETUP_SECONDS: f64 = 600.0;

/// Isotropic elastic material: its small-strain constants and the large-strain law of the
/// energy operators.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Density rho (kg/m^3).
    pub density: f64,
    /// Young's modulus E (Pa).
    pub young: f64,
    /// Poisson's ratio nu (-), in [-0.999, 0.499] (scene::limits::POISSON says why).
    pub poisson: f64,
    /// Strain energy law at large strain of the energy operators (`corrected`, `second_order`);
    /// every law has the same small-strain limit, set by `young` and `poisson`. Absent from a
    /// scene: Saint Venant-Kirchhoff. Always serialised: FMU states are bincode, which cannot
    /// skip fields.
    #[serde(default)]
    pub law: MaterialLaw,
}

/// Strain energy density W of the energy operators at large strain (src/physics/law.rs,
/// docs/model.md "Material law"). The paper's spring operators have no strain energy density and
/// take only the default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MaterialLaw {
    /// Saint Venant-Kirchhoff, `W = mu E:E + lambda/2 tr(E)^2` in the Green strain E: linear
    /// stress in E, exact small-strain limit, but it softens in compression (the uniaxial stress
    /// falls beyond a principal stretch of 1/sqrt(3)) and has no energy barrier against collapse.
    #[default]
    SaintVenantKirchhoff,
    /// Compressible neo-Hookean in the isochoric/volumetric split,
    /// `W = mu/2 (J^(-2/3) I1 - 3) + K/4 (J^2 - 1 - 2 ln J)`, `K = lambda + 2 mu / 3`:
    /// polyconvex for every nu in (-1, 1/2), the energy grows without bound as J -> 0, so a
    /// particle resists collapse; J <= 0 (inverted) stops the run with an error.
    NeoHookean,
}

impl Material {
    /// Shear modulus mu, Eq. (3) (Pa).
    pub fn mu(&self) -> f64 {
        self.young / (2.0 * (1.0 + self.poisson))
    }
    /// Lame's first parameter lambda, Eq. (4) (Pa). This is the 3D value; 2D scenes are plane
    /// strain, for which the same lambda applies.
    pub fn lambda(&self) -> f64 {
        self.young * self.poisson / ((1.0 + self.poisson) * (1.0 - 2.0 * self.poisson))
    }
    /// P-wave speed sqrt((lambda + 2 mu) / rho) (m/s).
    pub fn p_wave_speed(&self) -> f64 {
        ((self.lambda() + 2.0 * self.mu()) / self.density).sqrt()
    }
}

/// Which discrete elasticity operator computes the internal forces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ElasticModel {
    /// Quadratic-consistent gradients and Hessians, the strain energy integrated over each
    /// particle's cell to second order, and a stabilisation of the motion no quadratic field
    /// explains with the shear modulus as its stiffness: exact for every quadratic displacement
    /// field (pure bending), no tuned factor. See src/physics/second_order/, docs/model.md.
    /// The default: a scene that names no operator gets this one.
    #[default]
    SecondOrder,
    /// Per-particle corrected operators (exact for linear displacement fields), forces from the
    /// strain energy, plus a bond-level stabilisation of the non-affine part whose stiffness is
    /// the factor `stabilisation`. See docs/model.md. About 4-5 times cheaper per bond with a
    /// twice longer stable step, and 8-45 times less accurate in bending at equal resolution.
    Corrected,
    /// The paper's Eqs. (13)-(36): normal and shear springs with per-particle rotations and a
    /// volumetric pressure, normalised by the interior reference number density n0 so that the
    /// pair forces are equal and opposite (momentum conserving).
    Paper,
    /// The paper's equations taken literally: normalised by each particle's own number density
    /// n_i (reference configuration). Not momentum conserving at free surfaces.
    PaperLocal,
}

impl ElasticModel {
    /// The operator's name as scenes write it (`solver.model`).
    pub fn name(self) -> &'static str {
        match self {
            ElasticModel::SecondOrder => "second_order",
            ElasticModel::Corrected => "corrected",
            ElasticModel::Paper => "paper",
            ElasticModel::PaperLocal => "paper_local",
        }
    }
}

/// Solver options of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SolverOptions {
    /// Elasticity operator (default: second_order).
    pub model: ElasticModel,
    /// Effective radius re as a multiple of the particle spacing l0 (-); the paper uses 2.1.
    pub re_factor: f64,
    /// Corrected model only: stiffness of the stabilisation of the non-affine bond motion, as a
    /// fraction of the paper's spring stiffness (-).
    pub stabilisation: f64,
    /// Fixed time step (s). None: chosen from the stability bound of the particle model.
    pub dt: Option<f64>,
    /// Safety factor applied to the stability bound dt_crit = 2 / omega_max (-).
    pub safety: f64,
    /// Mass-proportional damping coefficient c (1/s): adds -c m v to each particle. 0 = off.
    pub damping: f64,
    /// Largest number of particles a scene may create (memory guard; the scene is also refused
    /// when its memory estimate exceeds the memory the machine has).
    pub max_particles: usize,
    /// Most solver steps one advance may take (work guard): a whole `mps run`, one fmi2DoStep.
    /// An advance that would need more is refused before it starts (>= 1).
    pub max_steps: u64,
    /// Most particle-steps (particles x solver steps; unit: particle-steps) one advance may
    /// take: the work guard that follows the wall time, about 0.2 us (2D, corrected in 3D) to
    /// 1.1 us (second_order in 3D) per particle-step on two cores. An advance that would need
    /// more is refused before it starts, with its estimated wall time; raise it in the scene
    /// (`"solver": {"max_particle_steps": 100000000000}`) for a longer run (>= 1).
    pub max_particle_steps: u64,
    /// Most wall-clock time the set-up of the model may take (s; work guard of the set-up:
    /// bonds, operator fits, closure, stable step). Estimated after the bonds are found and
    /// refused then when the estimate is above it; checked again after every stage and in every
    /// iteration of the closure's solves, which stop when it is reached.
    pub max_setup_seconds: f64,
    /// Critical bond strain eps_max of Eq. (42) (-): a bond whose strain
    /// (|r_ij| - |r0_ij|) / |r0_ij| exceeds it breaks for good. None: no fracture (and no checks).
    pub fracture_strain: Option<f64>,
    /// The bond strain that Eq. (42) compares with eps_max (default: the stretch). Always
    /// serialised: FMU states are bincode, which cannot skip fields.
    pub bond_strain: BondStrain,
    /// Contact between bodies and across broken bonds (section 2.5).
    pub contact: ContactOptions,
}

/// The bond strain of Eq. (42). The paper writes the strain of bond ij with the relative
/// displacement u_ij, which allows more than one reading; see docs/case3-study.md.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BondStrain {
    /// (|r_ij| - |r0_ij|) / |r0_ij|: the change of the bond's length (objective).
    #[default]
    Stretch,
    /// |u_j - u_i| / |r0_ij|: the norm of the relative displacement, which also counts the
    /// bond's rigid rotation (not objective: a rigid turn by theta gives 2 sin(theta / 2)).
    RelativeDisplacement,
    /// |u_j - u_i - (R r0_ij - r0_ij)| / |r0_ij| with R the rotation half way between the two
    /// particles' orientations (Eq. (16)): the relative displacement less the rigid rotation the
    /// particles carry.
    RotationCorrected,
}

/// Contact options (section 2.5). See docs/contact-fracture.md for the force law.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ContactOptions {
    /// Contact between bodies at all. Off: bodies pass through each other (the overlap check
    /// is off as well).
    pub enabled: bool,
    /// Contact detection between fractured surfaces: particles of one body whose bond has broken
    /// (or that never had one) repel like particles of different bodies. Off: they pass through
    /// each other until they overlap (the paper's run "without contact detection").
    pub fractured_surfaces: bool,
    /// n_c of Eq. (41): particle i is a surface particle when n_i < n_max - n_c (-).
    pub surface_threshold: f64,
    /// Two particles not joined by an intact bond that come closer than this fraction of l0
    /// stop the run with an overlap error (-).
    pub overlap_fraction: f64,
    /// Multiplier of the contact stiffness k_c = 2 d 2 mu l0^d / l0^2 derived from Eqs. (27),
    /// (30) with re = l0 (-).
    pub stiffness: f64,
    /// Verlet skin of the contact pair list as a fraction of l0: the list holds the pairs within
    /// (1 + skin) l0 and is rebuilt when a surface particle has moved more than skin l0 / 2 (-).
    pub skin: f64,
    /// Most contact partners per particle counted by the stable step's bound (-): the bound
    /// sums each particle's partners in contact, at most this many; 2 covers a lattice face
    /// pressed on a lattice face, aligned (one partner) or offset by half a spacing (four
    /// partners at an angle, whose stiffness along the normal adds up to at most 2 k_c).
    pub max_partners: f64,
}

impl Default for ContactOptions {
    fn default() -> Self {
        ContactOptions {
            enabled: true,
            fractured_surfaces: true,
            surface_threshold: 0.5,
            overlap_fraction: 0.5,
            stiffness: 1.0,
            skin: 0.5,
            max_partners: 2.0,
        }
    }
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            model: ElasticModel::SecondOrder,
            re_factor: 2.1,
            stabilisation: 0.5,
            dt: None,
            safety: 0.8,
            damping: 0.0,
            max_particles: DEFAULT_MAX_PARTICLES,
            max_steps: DEFAULT_MAX_STEPS,
            max_particle_steps: DEFAULT_MAX_PARTICLE_STEPS,
            max_setup_seconds: DEFAULT_MAX_SETUP_SECONDS,
            fracture_strain: None,
            bond_strain: BondStrain::Stretch,
            contact: ContactOptions::default(),
        }
    }
}
