//! The simulated world: bodies of particles, bonds, boundary groups, loads and gravity, and the
//! order of a step (integrate with the forces of the current state, then evaluate the forces of
//! the new state, so reactions and energies always describe the current time).
use super::bonds::{lattice_neighbours, lattice_number_density, Bonds};
use super::boundary::{BoundaryGroup, GravityLaw, GroupMotion, LoadRegion};
use super::contact::{Contact, Overlap};
use super::dim::{Dim, Space, Vect};
use super::elastic::{ElasticOperator, ElasticScratch};
use super::integrate::{critical_step, symplectic_euler, StepInputs};
use super::law;
use super::params::{Material, MaterialLaw, SolverOptions};
use super::particles::{Particles, FIX_AXIS, FIX_ROT};
pub use super::second_order::Ghost;
use serde::{Deserialize, Serialize};

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
    #[error("advancing to t = {t_end:e} s would take {steps} solver steps of dt = {dt:.4e} s, more than solver.max_steps = {limit}; nothing was done (use a shorter advance, a larger particle spacing or a softer/denser material, or raise solver.max_steps)")]
    TooMuchWork {
        /// Time the advance was asked to reach (s).
        t_end: f64,
        /// Steps it would take.
        steps: u64,
        /// solver.max_steps.
        limit: u64,
        /// The solver step (s).
        dt: f64,
    },
    #[error("out of memory: {0}")]
    OutOfMemory(String),
}

/// Significant bits of the particle spacing that coordinates must keep: a reference vector
/// X_j - X_i is then exact to 2^-20 (1e-6) of l0, and the lattice of a body far from the origin
/// differs from the same lattice at the origin by no more than that.
pub const MIN_SPACING_BITS: i32 = 20;

/// Refuses a body whose coordinates are too large to resolve the particle spacing: far from the
/// origin, adjacent doubles are farther apart than 2^-MIN_SPACING_BITS l0, so particles would
/// be misplaced or coincide. The displacements are relative and keep full precision anywhere;
/// only the reference lattice is limited by where the scene puts it.
fn check_resolution<const D: usize>(
    b: usize,
    name: &str,
    points: &[Vect<D>],
    l0: f64,
) -> Result<(), SimError> {
    let far = points.iter().flat_map(|p| p.iter()).fold(0.0f64, |a, c| {
        if c.is_finite() {
            a.max(c.abs())
        } else {
            f64::INFINITY
        }
    });
    // Spacing of adjacent doubles near `far`, bounded above by far * eps.
    let ulp = far * f64::EPSILON;
    // Written so that a NaN or infinite coordinate (far = inf) is refused as well.
    let resolved = ulp <= l0 * 2f64.powi(-MIN_SPACING_BITS);
    if !resolved {
        let bits = (l0 / ulp).log2().floor().max(0.0);
        return Err(SimError::Invalid(format!(
            "body '{name}' (bodies[{b}]): a coordinate of {far:.3e} m leaves only {bits} significant bits for the particle spacing {l0:.3e} m (at least {MIN_SPACING_BITS} are needed; positions there are rounded to {ulp:.1e} m); place the body nearer the origin"
        )));
    }
    Ok(())
}

/// Relative margin added to the measured largest angular frequency (-): the power iteration
/// under-estimates it (0.5 % in 3D after 80 iterations) and a deflected configuration is
/// stiffer than the reference one by 1-2 % (issue 7).
pub const OMEGA_MARGIN: f64 = 0.03;

/// Steps between two checks of whether the stable step must be measured again in the current
/// configuration (the check is one pass over the bonds, about 1/20 of a force evaluation).
pub const REFRESH_CHECK_EVERY: u64 = 20;

/// The stable step is measured again in the current configuration when some intact bond's
/// relative displacement has changed by more than this fraction of its reference length since
/// the last measurement (a strain or a rotation of 10 %; a rigid translation does not count) (-).
pub const REFRESH_DEFORMATION: f64 = 0.1;

/// Power iterations of a refresh, warm-started from the previous eigenvector.
pub const REFRESH_ITERATIONS: usize = 6;

/// Fewest steps between two refreshes: a refresh costs REFRESH_ITERATIONS + 1 force
/// evaluations, so this bounds its cost to 14 % of the steps' (reached only by bodies that
/// deform all the time: a soft strip collapsing under 100 g, 80 refreshes in 4800 steps; a
/// cantilever bent to half its length: 1-3 % of the run time). 200 was too slow to follow a
/// soft strip collapsing under 100 g (blow-up at safety 0.8, step 876); 20 costs 35 %.
pub const REFRESH_MIN_STEPS: u64 = 50;

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

/// A boundary face across which a group mirrors its body (m; the normal of any length).
///
/// The members at the mirror images of free particles become their ghosts: in the
/// second-order operator's fits a ghost's displacement is its master's reflected, odd on the
/// group's held axes about the group's motion (u_g = 2 u_group - u_m: zero relative
/// displacement on the face) and even on the free ones (u_g = u_m: zero normal gradient). A
/// clamp (all axes held) so holds u = 0 on the face, a face support with the normal axis free
/// holds the tangential displacement and no normal stress, and the particles next to the face
/// see the full stencil of the interior: no one-sided fit, no O(l0) slip of the face
/// (docs/model.md, "Mirror faces").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MirrorFace {
    pub point: [f64; 3],
    pub normal: [f64; 3],
}

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
}

/// What the stable step's refresh carries from step to step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct StableStepState<const D: usize>
where
    Space: Dim<D>,
{
    /// omega_max of the elastic model the step uses (rad/s): the last measurement with the
    /// margin, extrapolated over the next interval when it grew (see `maybe_refresh_step`).
    pub omega_elastic: f64,
    /// The last measurement with the margin, not extrapolated (rad/s).
    pub omega_measured: f64,
    /// Displacements at the last measurement (empty: the reference state).
    pub u_measured: Vec<Vect<D>>,
    /// Step count at the last measurement.
    pub step_measured: u64,
    /// Last iterate of the power iteration (translations, rotations), the warm start of the
    /// next refresh (empty: none).
    pub eig_t: Vec<Vect<D>>,
    pub eig_r: Vec<<Space as Dim<D>>::Ang>,
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
    /// Fracture-check passes so far (0 when eps_max is infinite).
    pub fracture_checks: u64,
    /// Bond pairs broken so far, Eq. (42).
    pub broken_pairs: u64,
    /// Strain energy released by the breaks so far (J): at each break, what the particles
    /// that lost bonds held just before less what they hold after their re-fit (never
    /// negative, `ElasticOperator::limit_at_break`). 0 for the paper's operators.
    pub fracture_release: f64,
    omega_max: f64,
    omega_elastic: f64,
    /// omega_max of the elastic model in the reference configuration (with the margin).
    omega_reference: f64,
    /// Contact bound of omega^2 (rad^2/s^2).
    omega2_contact: f64,
    stable: StableStepState<D>,
    /// Measurements of the stable step in the current configuration so far.
    pub step_refreshes: u64,
    /// Wall time spent checking and refreshing the stable step (s).
    pub step_refresh_seconds: f64,
    frac_flag: Vec<u8>,
    scratch: ElasticScratch<D>,
    force: Vec<Vect<D>>,
    torque: Vec<<Space as Dim<D>>::Ang>,
    group_of: Vec<u32>,
    load_of: Vec<u32>,
    bad: Vec<u8>,
    /// Second-order operator: per body, its summation-by-parts closure at the free faces
    /// (module `sbp`: the solve's figures) or why the body keeps the plain fits. Empty for
    /// the other operators.
    pub closure: Vec<Result<String, String>>,
}

impl<const D: usize> World<D>
where
    Space: Dim<D>,
{
    /// Builds the particles, finds the bonds, precomputes the operators, measures the stable
    /// step and evaluates the forces of the initial state.
    pub fn new(
        l0: f64,
        options: SolverOptions,
        bodies: Vec<BodyInit<D>>,
        groups: Vec<GroupInit>,
        loads: Vec<(String, Vec<u32>)>,
        gravity: GravityLaw<D>,
    ) -> Result<Self, SimError> {
        let re = options.re_factor * l0;
        let mut p = Particles::<D> {
            x0: vec![],
            u: vec![],
            x: vec![],
            v: vec![],
            q: vec![],
            w: vec![],
            body: vec![],
            mass: vec![],
            inertia: vec![],
            fix: vec![],
            n_ref: vec![],
        };
        for (b, body) in bodies.iter().enumerate() {
            check_resolution(b, &body.name, &body.points, l0)?;
            if let InitialVelocity::PerParticle { v, w } = &body.velocity {
                if v.len() != body.points.len() || w.len() != body.points.len() {
                    return Err(SimError::Invalid(format!(
                        "body '{}' (bodies[{b}]) has {} points but {} initial velocities and {} angular velocities",
                        body.name,
                        body.points.len(),
                        v.len(),
                        w.len()
                    )));
                }
            }
            let finite = match &body.velocity {
                InitialVelocity::Uniform(v) => v.iter().all(|c| c.is_finite()),
                InitialVelocity::PerParticle { v, w } => {
                    v.iter().all(|v| v.iter().all(|c| c.is_finite()))
                        && w.iter().all(<Space as Dim<D>>::ang_finite)
                }
            };
            if !finite {
                return Err(SimError::Invalid(format!(
                    "body '{}' (bodies[{b}]): an initial velocity is not finite",
                    body.name
                )));
            }
        }
        if matches!(
            options.model,
            super::params::ElasticModel::Paper | super::params::ElasticModel::PaperLocal
        ) {
            if let Some((b, body)) = bodies
                .iter()
                .enumerate()
                .find(|(_, b)| b.material.law != MaterialLaw::SaintVenantKirchhoff)
            {
                return Err(SimError::Invalid(format!(
                    "body '{}' (bodies[{b}]): material.law = {} needs an operator with a strain energy density (solver.model corrected or second_order); the paper's spring operators have none",
                    body.name,
                    body.material.law.name()
                )));
            }
        }
        let total: usize = bodies.iter().map(|b| b.points.len()).sum();
        let oom = |e: std::collections::TryReserveError| {
            SimError::OutOfMemory(format!(
                "cannot allocate the arrays of {total} particles: {e}"
            ))
        };
        p.x0.try_reserve_exact(total).map_err(oom)?;
        p.u.try_reserve_exact(total).map_err(oom)?;
        p.x.try_reserve_exact(total).map_err(oom)?;
        p.v.try_reserve_exact(total).map_err(oom)?;
        p.q.try_reserve_exact(total).map_err(oom)?;
        p.w.try_reserve_exact(total).map_err(oom)?;
        p.body.try_reserve_exact(total).map_err(oom)?;
        p.mass.try_reserve_exact(total).map_err(oom)?;
        p.inertia.try_reserve_exact(total).map_err(oom)?;
        p.fix.try_reserve_exact(total).map_err(oom)?;
        let volume = l0.powi(D as i32);
        // Operators with particle rotations take the given angular velocities (see
        // InitialVelocity::PerParticle).
        let rotational = matches!(
            options.model,
            super::params::ElasticModel::Paper | super::params::ElasticModel::PaperLocal
        );
        for (b, body) in bodies.iter().enumerate() {
            let m = body.material.density * volume;
            for (k, pt) in body.points.iter().enumerate() {
                let (v, w) = match &body.velocity {
                    InitialVelocity::Uniform(v) => (*v, <Space as Dim<D>>::ang_zero()),
                    InitialVelocity::PerParticle { v, w } => (
                        v[k],
                        if rotational {
                            w[k]
                        } else {
                            <Space as Dim<D>>::ang_zero()
                        },
                    ),
                };
                p.x0.push(*pt);
                p.u.push(Vect::<D>::zeros());
                p.x.push(*pt);
                p.v.push(v);
                p.q.push(<Space as Dim<D>>::identity());
                p.w.push(w);
                p.body.push(b as u32);
                p.mass.push(m);
                p.inertia.push(<Space as Dim<D>>::particle_inertia(m, l0));
                p.fix.push(0);
            }
        }
        let n = p.len();
        if n == 0 {
            return Err(SimError::Invalid("the scene has no particles".into()));
        }
        let bonds = Bonds::try_build(&p.x0, &p.body, re, lattice_neighbours::<D>(l0, re))
            .map_err(|e| SimError::OutOfMemory(format!("cannot allocate the bonds: {e}")))?;
        p.n_ref = (0..n)
            .map(|i| bonds.of(i).map(|b| bonds.w0[b]).sum())
            .collect();
        let n0 = lattice_number_density::<D>(l0, re);
        let materials: Vec<Material> = bodies.iter().map(|b| b.material).collect();
        let mut group_of = vec![u32::MAX; n];
        let mut gs = Vec::new();
        let mut mirrors: Vec<(usize, MirrorFace, [bool; 3])> = Vec::new();
        for (gi, g) in groups.into_iter().enumerate() {
            for &i in &g.members {
                let i = i as usize;
                if i >= n {
                    return Err(SimError::Invalid(format!(
                        "group '{}' names particle {i} of {n}",
                        g.name
                    )));
                }
                group_of[i] = gi as u32;
                // A held axis starts at rest (its motion law has no rate at t = 0), as does a
                // held rotation.
                for (k, (held, bit)) in g.axes.iter().zip(FIX_AXIS).take(D).enumerate() {
                    if *held {
                        p.fix[i] |= bit;
                        p.v[i][k] = 0.0;
                    }
                }
                if g.fix_rotation {
                    p.fix[i] |= FIX_ROT;
                    p.w[i] = <Space as Dim<D>>::ang_zero();
                }
            }
            if let Some(face) = g.mirror {
                mirrors.push((gi, face, g.axes));
            }
            gs.push(BoundaryGroup {
                name: g.name,
                members: g.members,
                axes: g.axes,
                fix_rotation: g.fix_rotation,
                motion: GroupMotion::default(),
                reaction: Vect::<D>::zeros(),
            });
        }
        let all_axes: u8 = FIX_AXIS.iter().take(D).fold(0, |a, b| a | b);
        let names: Vec<String> = gs.iter().map(|g| g.name.clone()).collect();
        let ghosts = find_ghosts(&p, l0, &group_of, &mirrors, &names, options.model)?;
        let (ghosts, followers, walls) = clamp_followers(&p, l0, &group_of, &mirrors, ghosts);
        for g in &ghosts {
            // A ghost follows its master: it is moved by nothing else.
            p.fix[g.ghost as usize] |= all_axes;
        }
        // Particles of clamped groups (all axes held) and ghosts: the second-order operator
        // treats them as a rigid grip.
        let rigid: Vec<bool> = p.fix.iter().map(|f| f & all_axes == all_axes).collect();
        for fl in &followers {
            // A follower is moved by its constraint only (it keeps its energy).
            p.fix[fl.particle as usize] |= all_axes;
        }
        let op = ElasticOperator::new(
            options.model,
            l0,
            options.re_factor,
            n0,
            options.stabilisation,
            &materials,
            &bonds,
            n,
            &rigid,
            &ghosts,
            &followers,
            &walls,
        );
        let mut op = op;
        // The second-order operator's summation-by-parts closure at free faces (module `sbp`):
        // particle volumes (and masses) that integrate quadratics exactly and gradient weights
        // whose transpose passes the integration constraint.
        let mut closure = Vec::new();
        if options.model == super::params::ElasticModel::SecondOrder {
            let cl = super::sbp::close(
                &p.x0,
                &p.body,
                &bonds,
                &op.second,
                l0,
                options.re_factor,
                bodies.len(),
            );
            let closable: Vec<bool> = cl.vol.iter().map(|v| v.is_some()).collect();
            for (i, v) in cl.vol.iter().enumerate() {
                if let Some(v) = v {
                    op.vol[i] = *v;
                    op.base_vol[i] = *v;
                    p.mass[i] = bodies[p.body[i] as usize].material.density * v;
                }
            }
            op.second.set_closure(&bonds, l0, cl.dg, closable);
            // The followers' inertia, lumped on the layers they follow.
            for fl in &op.second.followers {
                let m = p.mass[fl.particle as usize];
                for (j, share) in fl.inner.iter().zip(super::second_order::LUMP) {
                    p.mass[*j as usize] += share * m;
                }
            }
            closure = cl.report;
        }
        let mut load_of = vec![u32::MAX; n];
        let mut ls = Vec::new();
        for (li, (name, members)) in loads.into_iter().enumerate() {
            for &i in &members {
                load_of[i as usize] = li as u32;
            }
            ls.push(LoadRegion {
                name,
                members,
                force: Vect::<D>::zeros(),
                rate: Vect::<D>::zeros(),
                t_ref: 0.0,
            });
        }
        let contact = Contact::new(
            options.contact.clone(),
            l0,
            n0,
            &materials.iter().map(|m| m.mu()).collect::<Vec<_>>(),
            &p.body,
            &bonds,
            options.fracture_strain.is_some(),
        );
        let mut world = World {
            options,
            l0,
            re,
            body_names: bodies.into_iter().map(|b| b.name).collect(),
            p,
            bonds,
            op,
            groups: gs,
            loads: ls,
            gravity,
            time: 0.0,
            steps: 0,
            contact,
            fracture_checks: 0,
            broken_pairs: 0,
            fracture_release: 0.0,
            omega_max: 0.0,
            omega_elastic: 0.0,
            omega_reference: 0.0,
            omega2_contact: 0.0,
            stable: StableStepState {
                omega_elastic: 0.0,
                omega_measured: 0.0,
                u_measured: Vec::new(),
                step_measured: 0,
                eig_t: Vec::new(),
                eig_r: Vec::new(),
            },
            step_refreshes: 0,
            step_refresh_seconds: 0.0,
            frac_flag: Vec::new(),
            scratch: ElasticScratch::default(),
            force: vec![Vect::<D>::zeros(); n],
            torque: vec![<Space as Dim<D>>::ang_zero(); n],
            group_of,
            load_of,
            bad: vec![0; n],
            closure,
        };
        // The Rayleigh quotient of the power iteration approaches omega_max^2 from below: in 3D
        // 80 iterations leave it ~0.5 % short in omega, and the current configuration (large
        // deflection) adds 1-2 %; the margin covers both so that safety = 1 is stable.
        let (omega, eig_t, eig_r) = world.measure_omega_max(80, None);
        world.omega_elastic = omega * (1.0 + OMEGA_MARGIN);
        world.omega_reference = world.omega_elastic;
        world.stable = StableStepState {
            omega_elastic: world.omega_elastic,
            omega_measured: world.omega_elastic,
            u_measured: Vec::new(),
            step_measured: 0,
            eig_t,
            eig_r,
        };
        // Contact adds stiffness that the reference state does not show: its bound is added to
        // the measured omega^2 (Weyl: lambda_max(A + B) <= lambda_max(A) + lambda_max(B)).
        let c2 = if world.contact.active
            && (world.body_names.len() >= 2 || world.options.contact.fractured_surfaces)
        {
            world.contact.omega2_bound(&world.p.mass)
        } else {
            0.0
        };
        world.omega2_contact = c2;
        world.omega_max = (world.omega_elastic.powi(2) + c2).sqrt();
        match world.update_forces() {
            Err(e @ SimError::Overlap { .. }) => {
                return Err(SimError::Invalid(format!(
                    "bodies overlap in the initial state: {e}"
                )))
            }
            r => r?,
        }
        Ok(world)
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.p.len()
    }
    pub fn is_empty(&self) -> bool {
        self.p.is_empty()
    }

    /// Largest angular frequency of the linearised particle model (rad/s), contact included.
    pub fn omega_max(&self) -> f64 {
        self.omega_max
    }

    /// Largest angular frequency of the elastic model alone, measured by power iteration (rad/s).
    pub fn omega_elastic(&self) -> f64 {
        self.omega_elastic
    }

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

    /// Stability limit of symplectic Euler for this model with its damping (s): 2 / omega_max
    /// without damping, less with it (see [`critical_step`]).
    pub fn critical_dt(&self) -> f64 {
        critical_step(self.omega_max, self.options.damping)
    }

    /// The step the solver takes at most: the scene's fixed dt, or safety * critical_dt (s).
    pub fn max_dt(&self) -> f64 {
        self.options
            .dt
            .unwrap_or(self.options.safety * self.critical_dt())
    }

    /// Evaluates the internal and contact forces of the current state and the reactions of the
    /// groups. An error for the first particle whose material law has no energy at its state
    /// (a collapsed neo-Hookean particle) or the first overlap found (contact forces are then
    /// incomplete).
    fn update_forces(&mut self) -> Result<(), SimError> {
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
            overlap = self
                .contact
                .add_forces(&self.p.x0, &self.p.u, &self.p.body, &mut self.force);
        }
        // The followers of clamped faces carry no inertia of their own; their weight, loads
        // and contact forces act through the constraint (on the layers they follow and the
        // clamp). Their elastic forces took that path in the operator.
        if !self.op.second.followers.is_empty() {
            let g = self.gravity.at(self.time);
            let (p, loads, load_of) = (&self.p, &self.loads, &self.load_of);
            let time = self.time;
            let ext: Vec<Vect<D>> = self
                .op
                .second
                .followers
                .iter()
                .map(|fl| {
                    let i = fl.particle as usize;
                    let mut e = self.force[i];
                    let l = load_of[i];
                    if l != u32::MAX {
                        let r = &loads[l as usize];
                        e += r.force_at(time) / (r.members.len().max(1) as f64);
                    }
                    e
                })
                .collect();
            let so = &self.op.second;
            so.spread_to_followed(
                &p.mass,
                g,
                |i| ext[so.followers.partition_point(|f| (f.particle as usize) < i)],
                &mut self.force,
            );
            for fl in &so.followers {
                self.force[fl.particle as usize] = Vect::<D>::zeros();
            }
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
        let touched = super::fracture::strained_particles(
            &self.p.u,
            &self.p.q,
            &self.bonds,
            eps,
            measure,
            &mut self.frac_flag,
        );
        if touched.is_empty() {
            return;
        }
        // The energy each particle held just before the break: its re-fit may not exceed it.
        let before: Vec<Option<f64>> = touched
            .iter()
            .map(|&i| self.op.particle_energy(&self.p, &self.bonds, i))
            .collect();
        let pairs = super::fracture::break_strained(
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

    /// Moves the followers of clamped faces to their constraint (displacement and velocity).
    fn sync_followers(&mut self) {
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
        let inputs = StepInputs {
            dt,
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

    /// Kinetic energy of translation and rotation (J).
    pub fn kinetic_energy(&self) -> f64 {
        // (A follower's motion is its constraint's: it carries no kinetic energy of its own.)
        let following = &self.op.second.following;
        (0..self.len())
            .filter(|&i| !following.get(i).copied().unwrap_or(false))
            .map(|i| {
                0.5 * self.p.mass[i] * self.p.v[i].norm_squared()
                    + 0.5 * self.p.inertia[i] * <Space as Dim<D>>::ang_dot(self.p.w[i], self.p.w[i])
            })
            .sum()
    }

    /// Elastic strain energy of the current state (J).
    pub fn strain_energy(&self) -> f64 {
        self.op.strain_energy(&self.p, &self.bonds, &self.scratch)
    }

    /// Contact potential energy of the current state (J): the work the contact forces have
    /// stored; kinetic + strain + contact energy is conserved between bond breaks (a break
    /// releases the strain energy of the bond).
    pub fn contact_energy(&self) -> f64 {
        if self.contact.active {
            self.contact.energy(&self.p.x0, &self.p.u, &self.p.body)
        } else {
            0.0
        }
    }

    /// Pairs in contact now (closer than l0 and repelling), each pair once.
    pub fn contact_pairs(&self) -> usize {
        if self.contact.active {
            self.contact.pairs_in_contact(&self.p.x0, &self.p.u)
        } else {
            0
        }
    }

    /// Contact pair-list builds (cell-grid searches) so far; stays 0 when no search is needed
    /// (one body and fracture off, or contact disabled).
    pub fn contact_searches(&self) -> u64 {
        self.contact.searches
    }

    /// Surface flag of particle i, Eq. (41) (or lost a bond, Eq. (42)).
    pub fn is_surface(&self, i: usize) -> bool {
        self.contact.surface[i]
    }

    /// Broken bonds of particle i.
    pub fn broken_bonds_of(&self, i: usize) -> u32 {
        super::fracture::broken_of(&self.bonds, i)
    }

    /// Number of separate fragments: connected components over the intact bonds (computed on
    /// demand, O(bonds)). Bodies that never broke count one each.
    pub fn fragments(&self) -> usize {
        super::fracture::fragments(&self.bonds, self.len())
    }

    /// Largest strain over the intact bonds now (-), and a particle that has it (O(bonds)).
    pub fn max_bond_strain(&self) -> (f64, usize) {
        super::fracture::max_bond_strain(&self.p.u, &self.bonds)
    }

    /// Sizes of the fragments as (body, particles), in order of their lowest particle index.
    pub fn fragment_sizes(&self) -> Vec<(u32, usize)> {
        let root = super::fracture::components(&self.bonds, self.len());
        let mut count = vec![0usize; self.len()];
        for &r in &root {
            count[r as usize] += 1;
        }
        (0..self.len())
            .filter(|&i| root[i] == i as u32)
            .map(|i| (self.p.body[i], count[i]))
            .collect()
    }

    /// Pairs closer than l0 now: (different bodies, one body across a broken bond).
    pub fn contact_pairs_by_kind(&self) -> (usize, usize) {
        if self.contact.active {
            self.contact
                .pairs_by_kind(&self.p.x0, &self.p.u, &self.p.body)
        } else {
            (0, 0)
        }
    }

    /// Total linear momentum (kg m/s).
    pub fn momentum(&self) -> Vect<D> {
        (0..self.len()).fold(Vect::<D>::zeros(), |acc, i| {
            acc + self.p.v[i] * self.p.mass[i]
        })
    }

    /// Total angular momentum about the origin, orbital plus spin (kg m^2/s).
    pub fn angular_momentum(&self) -> <Space as Dim<D>>::Ang {
        (0..self.len()).fold(<Space as Dim<D>>::ang_zero(), |acc, i| {
            let orb = <Space as Dim<D>>::cross(&self.p.x[i], &(self.p.v[i] * self.p.mass[i]));
            let spin = <Space as Dim<D>>::ang_scale(self.p.w[i], self.p.inertia[i]);
            <Space as Dim<D>>::ang_add(acc, <Space as Dim<D>>::ang_add(orb, spin))
        })
    }

    /// Internal force on particle i at the current state (N).
    pub fn internal_force(&self, i: usize) -> Vect<D> {
        self.force[i]
    }

    /// Displacement at a reference point near particle i: u_i + H_i (X - X_i), with the
    /// displacement gradient H_i from the corrected gradient operator (exact for linear fields).
    pub fn displacement_at(&self, i: usize, point: &Vect<D>) -> Vect<D> {
        self.interpolate_at(i, point, |j| self.p.displacement(j))
    }

    /// Velocity at a reference point near particle i (m/s), interpolated like
    /// [`World::displacement_at`].
    pub fn velocity_at(&self, i: usize, point: &Vect<D>) -> Vect<D> {
        self.interpolate_at(i, point, |j| self.p.v[j])
    }

    /// A particle field f at a reference point near particle i: f_i plus the operator's gradient
    /// of f at i times the offset from i's reference position (and, for the second-order
    /// operator, half its Hessian times the offset squared: exact for quadratic fields).
    fn interpolate_at(&self, i: usize, point: &Vect<D>, f: impl Fn(usize) -> Vect<D>) -> Vect<D> {
        let fi = f(i);
        let d = point - self.p.x0[i];
        let mut g = super::dim::Mat::<D>::zeros();
        if self.op.model == super::params::ElasticModel::SecondOrder {
            let so = &self.op.second;
            // A ghost carries its master's field reflected (as in the fits).
            let fj = |j: usize| match so.ghost_of(j) {
                Some(g) => g.reflect(&f(j), &f(g.master as usize)),
                None => f(j),
            };
            let mut q = Vect::<D>::zeros();
            for b in self.bonds.of(i) {
                if so.weight(&self.bonds, b) == 0.0 {
                    continue;
                }
                let df = fj(self.bonds.nbr[b] as usize) - fi;
                g += df * so.g[b].transpose();
                q += df * d.dot(&(so.h[b] * d));
            }
            return fi + g * d + q * 0.5;
        }
        for b in self.bonds.of(i) {
            let r0 = self.bonds.r0[b];
            let om = self.bonds.w0[b] / r0.norm_squared();
            let df = f(self.bonds.nbr[b] as usize) - fi;
            g += (df * om) * r0.transpose();
        }
        fi + g * self.op.k_inv[i] * d
    }

    /// Mean displacement (m) and mean velocity (m/s) of the particles of load region r: the
    /// motion work-conjugate to the region's force (spread evenly over the same particles).
    pub fn load_motion(&self, r: usize) -> (Vect<D>, Vect<D>) {
        let m = &self.loads[r].members;
        let n = m.len().max(1) as f64;
        let (mut u, mut v) = (Vect::<D>::zeros(), Vect::<D>::zeros());
        for &i in m {
            u += self.p.displacement(i as usize);
            v += self.p.v[i as usize];
        }
        (u / n, v / n)
    }

    /// Index of the particle of `body` (any body when None) nearest to a reference point, and
    /// its distance. Ties (a point half way between particles, as a probe on a beam's axis) go
    /// to the lowest index among the particles within 1e-6 l0 of the nearest distance, so the
    /// choice does not depend on round-off, i.e. on where the scene sits.
    pub fn nearest_particle(&self, point: &Vect<D>, body: Option<u32>) -> Option<(usize, f64)> {
        let dist = |i: usize| (self.p.x0[i] - point).norm();
        let mine = |i: &usize| body.is_none_or(|b| self.p.body[*i] == b);
        let dmin = (0..self.len())
            .filter(mine)
            .map(dist)
            .min_by(|a, b| a.total_cmp(b))?;
        (0..self.len())
            .filter(mine)
            .map(|i| (i, dist(i)))
            .find(|&(_, d)| d <= dmin + 1e-6 * self.l0)
    }

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
            && s.fracture_release.is_finite())
        {
            return Err(SimError::Invalid(
                "state holds non-finite positions, velocities or bond weights, or retained energy shares outside [0, 1]".into(),
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
        self.omega_max = (self.omega_elastic.powi(2) + self.omega2_contact).sqrt();
        self.update_forces()
    }

    /// Largest eigenvalue of M^-1 K (translations and, in the paper model, rotations) by power
    /// iteration on the model's own force function, with the mass inner product (so the
    /// operator is self-adjoint). Constrained degrees of freedom are excluded. `warm`: None
    /// linearises about the reference state from the deterministic start vector; Some(start)
    /// linearises about the current state (its tangent stiffness: geometric and material)
    /// from `start` (the last iterate of the previous measurement). Returns omega_max (rad/s)
    /// and the last iterate.
    #[allow(clippy::type_complexity)]
    fn measure_omega_max(
        &self,
        iterations: usize,
        warm: Option<(&[Vect<D>], &[<Space as Dim<D>>::Ang])>,
    ) -> (f64, Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) {
        let n = self.len();
        let mut probe = self.p.clone();
        let mut scratch = ElasticScratch::default();
        let mut f = vec![Vect::<D>::zeros(); n];
        let mut t = vec![<Space as Dim<D>>::ang_zero(); n];
        let rotational = matches!(
            self.op.model,
            super::params::ElasticModel::Paper | super::params::ElasticModel::PaperLocal
        );
        // Deterministic pseudo-random start vector that moves with the body: per particle a
        // pseudo-random combination of its bond directions (coefficients hashed from the pair
        // indices), so a translated or rotated scene starts from the translated or rotated
        // vector and measures the same omega_max to round-off.
        let coef = |i: usize, j: u32, salt: u64| -> f64 {
            let mut z = ((i as u64) << 32 | j as u64) ^ salt;
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let bond_mix = |i: usize, salt: u64| -> Vect<D> {
            let mut acc = Vect::<D>::zeros();
            for b in self.bonds.of(i) {
                let r0 = self.bonds.r0[b];
                acc += r0 * (coef(i, self.bonds.nbr[b], salt) / r0.norm());
            }
            acc
        };
        let fresh = || -> (Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) {
            (
                (0..n).map(|i| bond_mix(i, 1)).collect(),
                (0..n)
                    .map(|i| {
                        if rotational {
                            let a = <Space as Dim<D>>::cross(&bond_mix(i, 2), &bond_mix(i, 3));
                            <Space as Dim<D>>::ang_scale(a, 1.0 / self.l0)
                        } else {
                            <Space as Dim<D>>::ang_zero()
                        }
                    })
                    .collect(),
            )
        };
        let (mut zt, mut zr): (Vec<Vect<D>>, Vec<<Space as Dim<D>>::Ang>) = match warm {
            // The previous eigenvector plus as much of the deterministic start vector (in the
            // mass norm): a mode that has become the stiffest elsewhere in the body (a fold
            // forming) still has weight in the start.
            Some((t0, r0)) => {
                let (ft, fr) = fresh();
                let nm = |zt: &[Vect<D>], zr: &[<Space as Dim<D>>::Ang]| -> f64 {
                    (0..n)
                        .map(|i| {
                            self.p.mass[i] * zt[i].norm_squared()
                                + self.p.inertia[i] * <Space as Dim<D>>::ang_dot(zr[i], zr[i])
                        })
                        .sum::<f64>()
                        .sqrt()
                };
                let (a, b) = (nm(t0, r0), nm(&ft, &fr));
                let (a, b) = (
                    if a > 0.0 { 1.0 / a } else { 0.0 },
                    if b > 0.0 { 1.0 / b } else { 0.0 },
                );
                (
                    (0..n).map(|i| t0[i] * a + ft[i] * b).collect(),
                    (0..n)
                        .map(|i| {
                            <Space as Dim<D>>::ang_add(
                                <Space as Dim<D>>::ang_scale(r0[i], a),
                                <Space as Dim<D>>::ang_scale(fr[i], b),
                            )
                        })
                        .collect(),
                )
            }
            None => (
                (0..n).map(|i| bond_mix(i, 1)).collect(),
                (0..n)
                    .map(|i| {
                        if rotational {
                            let a = <Space as Dim<D>>::cross(&bond_mix(i, 2), &bond_mix(i, 3));
                            <Space as Dim<D>>::ang_scale(a, 1.0 / self.l0)
                        } else {
                            <Space as Dim<D>>::ang_zero()
                        }
                    })
                    .collect(),
            ),
        };
        // About the current state: the forces there, subtracted from the probe's.
        let base = warm.map(|_| {
            let mut f0 = vec![Vect::<D>::zeros(); n];
            let mut t0 = vec![<Space as Dim<D>>::ang_zero(); n];
            self.op
                .forces(&self.p, &self.bonds, &mut scratch, &mut f0, &mut t0);
            (f0, t0)
        });
        let mask = |p: &Particles<D>, zt: &mut [Vect<D>], zr: &mut [<Space as Dim<D>>::Ang]| {
            for i in 0..n {
                for k in 0..D {
                    if p.fix[i] & FIX_AXIS[k] != 0 {
                        zt[i][k] = 0.0;
                    }
                }
                if p.fix[i] & FIX_ROT != 0 {
                    zr[i] = <Space as Dim<D>>::ang_zero();
                }
            }
        };
        let norm_m = |zt: &[Vect<D>], zr: &[<Space as Dim<D>>::Ang]| -> f64 {
            (0..n)
                .map(|i| {
                    self.p.mass[i] * zt[i].norm_squared()
                        + self.p.inertia[i] * <Space as Dim<D>>::ang_dot(zr[i], zr[i])
                })
                .sum::<f64>()
                .sqrt()
        };
        mask(&self.p, &mut zt, &mut zr);
        let mut lambda = 0.0;
        for _ in 0..iterations {
            let nz = norm_m(&zt, &zr);
            if nz == 0.0 {
                return (0.0, zt, zr);
            }
            let eps = 1e-7 * self.l0;
            for i in 0..n {
                zt[i] /= nz;
                zr[i] = <Space as Dim<D>>::ang_scale(zr[i], 1.0 / nz);
                if base.is_some() {
                    probe.u[i] = self.p.u[i] + zt[i] * eps;
                    probe.q[i] = <Space as Dim<D>>::advance(&self.p.q[i], &zr[i], eps);
                } else {
                    probe.u[i] = zt[i] * eps;
                    probe.q[i] =
                        <Space as Dim<D>>::advance(&<Space as Dim<D>>::identity(), &zr[i], eps);
                }
            }
            self.op
                .forces(&probe, &self.bonds, &mut scratch, &mut f, &mut t);
            if let Some((f0, t0)) = &base {
                for i in 0..n {
                    f[i] -= f0[i];
                    t[i] =
                        <Space as Dim<D>>::ang_add(t[i], <Space as Dim<D>>::ang_scale(t0[i], -1.0));
                }
            }
            let mut next_t: Vec<Vect<D>> = (0..n)
                .map(|i| f[i] * (-1.0 / (eps * self.p.mass[i])))
                .collect();
            let mut next_r: Vec<<Space as Dim<D>>::Ang> = (0..n)
                .map(|i| {
                    if rotational {
                        <Space as Dim<D>>::ang_scale(t[i], -1.0 / (eps * self.p.inertia[i]))
                    } else {
                        <Space as Dim<D>>::ang_zero()
                    }
                })
                .collect();
            mask(&self.p, &mut next_t, &mut next_r);
            // Rayleigh quotient <z, A z>_M with |z|_M = 1.
            lambda = (0..n)
                .map(|i| {
                    self.p.mass[i] * zt[i].dot(&next_t[i])
                        + self.p.inertia[i] * <Space as Dim<D>>::ang_dot(zr[i], next_r[i])
                })
                .sum::<f64>();
            zt = next_t;
            zr = next_r;
        }
        (lambda.max(0.0).sqrt(), zt, zr)
    }

    /// Every `REFRESH_CHECK_EVERY` steps (automatic step only), at least `REFRESH_MIN_STEPS`
    /// after the last refresh: if some intact bond's relative
    /// displacement has changed by more than `REFRESH_DEFORMATION` of its length since the
    /// last measurement, measures omega_max again about the current state
    /// (`REFRESH_ITERATIONS` power iterations from the previous eigenvector) and takes the
    /// larger of it (with the margin) and the reference value. Returns whether it measured.
    fn maybe_refresh_step(&mut self) -> bool {
        if self.options.dt.is_some()
            || !self.steps.is_multiple_of(REFRESH_CHECK_EVERY)
            || (self.stable.step_measured > 0
                && self.steps < self.stable.step_measured + REFRESH_MIN_STEPS)
        {
            return false;
        }
        let clock = std::time::Instant::now();
        let n = self.len();
        let u = &self.p.u;
        let um = &self.stable.u_measured;
        let lim2 = REFRESH_DEFORMATION * REFRESH_DEFORMATION;
        let moved = |i: usize, j: usize| -> Vect<D> {
            if um.is_empty() {
                u[j] - u[i]
            } else {
                (u[j] - um[j]) - (u[i] - um[i])
            }
        };
        let deformed = (0..n).any(|i| {
            self.bonds.of(i).any(|b| {
                self.bonds.w0[b] != 0.0
                    && moved(i, self.bonds.nbr[b] as usize).norm_squared()
                        > lim2 * self.bonds.r0[b].norm_squared()
            })
        });
        if deformed {
            let start = (
                std::mem::take(&mut self.stable.eig_t),
                std::mem::take(&mut self.stable.eig_r),
            );
            let warm = if start.0.len() == n && start.1.len() == n {
                Some((&start.0[..], &start.1[..]))
            } else {
                None
            };
            let (omega, eig_t, eig_r) = match warm {
                Some(w) => self.measure_omega_max(REFRESH_ITERATIONS, Some(w)),
                // No previous eigenvector: a full measurement from the deterministic start.
                None => {
                    let (_, t0, r0) = self.measure_omega_max(0, None);
                    self.measure_omega_max(80, Some((&t0, &r0)))
                }
            };
            // A body that stiffens as it deforms (a soft strip folding under its load) stiffens
            // on until the next measurement: the growth since the last one is assumed again
            // for the next interval (at most x1.5).
            // Never below the last measurement: a few warm iterations from the mixed start can
            // fall short of a value an earlier refresh converged to, and a bound that drops
            // back lets the step grow past the limit (seen: small2d through the FMU, blow-up at
            // step 671). A body that softens again keeps the shorter step.
            let measured = (omega * (1.0 + OMEGA_MARGIN)).max(self.stable.omega_measured);
            let growth =
                (omega * (1.0 + OMEGA_MARGIN) / self.stable.omega_measured).clamp(1.0, 1.5);
            self.stable = StableStepState {
                omega_elastic: (measured * growth).max(self.omega_reference),
                omega_measured: measured,
                u_measured: self.p.u.clone(),
                step_measured: self.steps,
                eig_t,
                eig_r,
            };
            self.omega_elastic = self.stable.omega_elastic;
            self.omega_max = (self.omega_elastic.powi(2) + self.omega2_contact).sqrt();
            self.step_refreshes += 1;
        }
        self.step_refresh_seconds += clock.elapsed().as_secs_f64();
        deformed
    }
}

/// Splits the ghosts of clamped mirror faces (all axes held) off: the first layer of the body
/// at such a face follows the two layers behind it (`second_order::Follower`), and the face's
/// members become walls that enter no fit. Returns (the other ghosts, the followers, the walls).
#[allow(clippy::type_complexity)]
fn clamp_followers<const D: usize>(
    p: &Particles<D>,
    l0: f64,
    group_of: &[u32],
    mirrors: &[(usize, MirrorFace, [bool; 3])],
    ghosts: Vec<Ghost<D>>,
) -> (Vec<Ghost<D>>, Vec<super::second_order::Follower>, Vec<bool>)
where
    Space: Dim<D>,
{
    let n = p.len();
    let clamp_groups: Vec<u32> = mirrors
        .iter()
        .filter(|(_, _, axes)| axes.iter().take(D).all(|&a| a))
        .map(|(g, _, _)| *g as u32)
        .collect();
    if clamp_groups.is_empty() {
        return (ghosts, Vec::new(), Vec::new());
    }
    let key =
        |x: &Vect<D>| -> Vec<i64> { x.iter().map(|c| (c / l0 * 4.0).round() as i64).collect() };
    let at: std::collections::HashMap<Vec<i64>, usize> =
        (0..n).map(|i| (key(&p.x0[i]), i)).collect();
    let walls: Vec<bool> = group_of
        .iter()
        .map(|g| *g != u32::MAX && clamp_groups.contains(g))
        .collect();
    let all = ghosts.clone();
    let mut rest = Vec::new();
    let mut followers = Vec::new();
    for g in ghosts {
        let (gi, mi) = (g.ghost as usize, g.master as usize);
        if !walls[gi] {
            rest.push(g);
            continue;
        }
        let d = p.x0[mi] - p.x0[gi];
        if (d.norm() - l0).abs() > 1e-6 * l0 {
            continue;
        }
        let find = |k: f64| -> Option<u32> {
            let x = p.x0[mi] + d * k;
            at.get(&key(&x))
                .copied()
                .filter(|&j| {
                    group_of[j] == u32::MAX
                        && p.body[j] == p.body[mi]
                        && (p.x0[j] - x).norm() < 1e-6 * l0
                })
                .map(|j| j as u32)
        };
        // A body thinner than 3 layers there keeps the odd mirror at its clamps.
        let (Some(a), Some(b)) = (find(1.0), find(2.0)) else {
            return (all, Vec::new(), Vec::new());
        };
        followers.push(super::second_order::Follower {
            particle: mi as u32,
            wall: gi as u32,
            inner: [a, b],
        });
    }
    followers.sort_by_key(|f| f.particle);
    // A particle at two clamped faces (an edge between them), or a follower that another one
    // follows (a body thinner than 4 layers between two clamped faces): the constraints would
    // chain. Such a scene keeps the odd mirror at its clamps (docs/model.md, "Clamped faces").
    let following: std::collections::HashSet<u32> = followers.iter().map(|f| f.particle).collect();
    if followers.windows(2).any(|w| w[0].particle == w[1].particle)
        || followers
            .iter()
            .any(|f| f.inner.iter().any(|j| following.contains(j)))
    {
        return (all, Vec::new(), Vec::new());
    }
    (rest, followers, walls)
}

/// The ghosts of the mirror faces: each member of a mirroring group at the mirror image (within
/// 1e-6 l0) of a particle of the same body that belongs to no group. Errors: a mirror face with
/// a model other than the second-order one (the others would treat the group as walls and
/// silently differ), a degenerate normal, or a face that mirrors no particle (the group's
/// layers are not at the mirror images of the body's: e.g. a face layer on the face).
fn find_ghosts<const D: usize>(
    p: &Particles<D>,
    l0: f64,
    group_of: &[u32],
    mirrors: &[(usize, MirrorFace, [bool; 3])],
    names: &[String],
    model: super::params::ElasticModel,
) -> Result<Vec<Ghost<D>>, SimError>
where
    Space: Dim<D>,
{
    let mut ghosts = Vec::new();
    if mirrors.is_empty() {
        return Ok(ghosts);
    }
    if model != super::params::ElasticModel::SecondOrder {
        return Err(SimError::Invalid(format!(
            "group '{}' has a mirror face, which only the second_order model uses (solver.model is {model:?}); remove the mirror or use second_order",
            names[mirrors[0].0]
        )));
    }
    // Free particles by their position on a grid of l0 / 4 relative to each face's point.
    for &(gi, face, axes) in mirrors {
        let point = Vect::<D>::from_fn(|k, _| face.point[k]);
        let normal = Vect::<D>::from_fn(|k, _| face.normal[k]);
        let len = normal.norm();
        if !(len.is_finite() && len > 0.0 && point.iter().all(|c| c.is_finite())) {
            return Err(SimError::Invalid(format!(
                "group '{}': the mirror face needs a finite point and a non-zero finite normal",
                names[gi]
            )));
        }
        let normal = normal / len;
        let key = |x: &Vect<D>| -> Vec<i64> {
            (x - point)
                .iter()
                .map(|c| (c / l0 * 4.0).round() as i64)
                .collect()
        };
        let mut free = std::collections::HashMap::new();
        for (i, g) in group_of.iter().enumerate() {
            if *g == u32::MAX {
                free.insert(key(&p.x0[i]), i);
            }
        }
        let parity = Vect::<D>::from_fn(|k, _| if axes[k] { -1.0 } else { 1.0 });
        let before = ghosts.len();
        for (i, g) in group_of.iter().enumerate() {
            if *g != gi as u32 {
                continue;
            }
            let image = p.x0[i] - normal * (2.0 * (p.x0[i] - point).dot(&normal));
            if let Some(&m) = free.get(&key(&image)) {
                if p.body[m] == p.body[i] && (p.x0[m] - image).norm() < 1e-6 * l0 {
                    ghosts.push(Ghost {
                        ghost: i as u32,
                        master: m as u32,
                        parity,
                    });
                }
            }
        }
        if ghosts.len() == before {
            return Err(SimError::Invalid(format!(
                "group '{}': no member is the mirror image of a free particle of its body across the mirror face; place the group's layers at the mirror images of the body's (e.g. a box [-3 l0, 0] beside a body that starts at 0, over the same section)",
                names[gi]
            )));
        }
    }
    ghosts.sort_by_key(|g| g.ghost);
    Ok(ghosts)
}
