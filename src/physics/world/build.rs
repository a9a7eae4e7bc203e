//! Construction of a world: World::new (particles, bonds, groups and mirror faces, the
//! operators and the summation-by-parts closure, the first measurement of the stable step)
//! and the checks of its input.
use super::faces::{
    self, check_mirror, group_faces, infer_clamp_followers, infer_support_faces, Face, SupportFace,
};
use super::mirror::{clamp_followers, find_ghosts};
use super::setup::{SetupClock, SetupObserver, SetupStage, StageCosts, Unobserved};
use super::stable_step::{StableStepState, LANCZOS_ITERATIONS, OMEGA_MARGIN};
use super::{BodyInit, GroupInit, InitialVelocity, MirrorFace, SimError, World};
use crate::physics::bonds::{lattice_number_density, max_lattice_neighbours, Bonds};
use crate::physics::boundary::{BoundaryGroup, GravityLaw, GroupMotion, LoadRegion};
use crate::physics::contact::Contact;
use crate::physics::dim::{Dim, Mat, Space, Vect};
use crate::physics::elastic::{ElasticOperator, ElasticScratch};
use crate::physics::ghosts::LUMP;
use crate::physics::params::{ElasticModel, Material, MaterialLaw, SolverOptions};
use crate::physics::particles::{Particles, FIX_AXIS, FIX_ROT};
use crate::physics::sbp;

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
        Self::new_observed(l0, options, bodies, groups, loads, gravity, &Unobserved)
    }

    /// [`World::new`] with each stage timed and told to `observer` as it ends; at each stage
    /// boundary the observer may stop the set-up, and so may the bound
    /// `solver.max_setup_seconds` (checked from the bonds stage on with an estimate of the
    /// whole set-up, then with the time taken, and within the closure's solves).
    pub fn new_observed(
        l0: f64,
        options: SolverOptions,
        bodies: Vec<BodyInit<D>>,
        groups: Vec<GroupInit>,
        loads: Vec<(String, Vec<u32>)>,
        gravity: GravityLaw<D>,
        observer: &dyn SetupObserver,
    ) -> Result<Self, SimError> {
        let mut clock = SetupClock::new(observer, options.max_setup_seconds);
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
            if let Some(s) = &body.shape {
                let n = body.points.len();
                if s.volumes.len() != n
                    || s.normals.len() != n
                    || s.areas.len() != n
                    || s.depths.len() != n
                    || s.moments.len() != n
                {
                    return Err(SimError::Invalid(format!(
                        "body '{}' (bodies[{b}]) has {n} points but {} volumes, {} normals, {} areas, {} depths and {} moments",
                        body.name,
                        s.volumes.len(),
                        s.normals.len(),
                        s.areas.len(),
                        s.depths.len(),
                        s.moments.len()
                    )));
                }
                if let Some(v) = s.volumes.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                    return Err(SimError::Invalid(format!(
                        "body '{}' (bodies[{b}]): a particle volume is {v} m^d, not positive",
                        body.name
                    )));
                }
                if let Some(v) = s.depths.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                    return Err(SimError::Invalid(format!(
                        "body '{}' (bodies[{b}]): a particle's depth below the solid's surface is {v} m, not positive",
                        body.name
                    )));
                }
            }
        }
        if matches!(
            options.model,
            ElasticModel::Paper | ElasticModel::PaperLocal
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
            ElasticModel::Paper | ElasticModel::PaperLocal
        );
        for (b, body) in bodies.iter().enumerate() {
            for (k, pt) in body.points.iter().enumerate() {
                let m =
                    body.material.density * body.shape.as_ref().map_or(volume, |s| s.volumes[k]);
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
        let bonds = Bonds::try_build(&p.x0, &p.body, re, max_lattice_neighbours(D, l0, re))
            .map_err(|e| SimError::OutOfMemory(format!("cannot allocate the bonds: {e}")))?;
        let bonds_seconds = clock.done(
            SetupStage::Bonds,
            &format!("{} bonds of {n} particles", bonds.len()),
        )?;
        clock.estimate(bonds.len(), bonds_seconds, &stage_costs(&options))?;
        p.n_ref = (0..n)
            .map(|i| bonds.of(i).map(|b| bonds.w0[b]).sum())
            .collect();
        let n0 = lattice_number_density::<D>(l0, re);
        let materials: Vec<Material> = bodies.iter().map(|b| b.material).collect();
        let mut group_of = vec![u32::MAX; n];
        let mut gs = Vec::new();
        let mut mirrors: Vec<(usize, MirrorFace, [bool; 3])> = Vec::new();
        let mut mirrored: Vec<bool> = Vec::new();
        let mut group_names: Vec<String> = Vec::new();
        for (gi, g) in groups.into_iter().enumerate() {
            mirrored.push(g.mirror.is_some());
            group_names.push(g.name.clone());
            for &i in &g.members {
                let i = i as usize;
                if i >= n {
                    return Err(SimError::Invalid(format!(
                        "group '{}' names particle {i} of {n}",
                        g.name
                    )));
                }
                // A mirror group's members are ghosts or walls of its face alone: a particle
                // that another group holds too would be claimed twice.
                let other = group_of[i];
                if other != u32::MAX
                    && other != gi as u32
                    && (g.mirror.is_some() || mirrored[other as usize])
                {
                    return Err(SimError::Boundary {
                        group: gi,
                        name: g.name.clone(),
                        field: "region".into(),
                        message: format!(
                            "it selects particles that group '{}' holds too (e.g. the particle at {:?} m), and one of the two has a mirror face, whose layers must be its own; remove the duplicate group or make the regions disjoint",
                            group_names[other as usize],
                            p.x0[i].as_slice()
                        ),
                    });
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
        if options.model == ElasticModel::SecondOrder {
            // A mirror face must be the face between the group and its body.
            for &(gi, face, _) in &mirrors {
                let found = group_faces(&p, &bonds, l0, &group_of, gi as u32);
                let point = Vect::<D>::from_fn(|k, _| face.point[k]);
                let normal = Vect::<D>::from_fn(|k, _| face.normal[k]);
                check_mirror(&found, &point, &normal, l0).map_err(|message| {
                    SimError::Boundary {
                        group: gi,
                        name: names[gi].clone(),
                        field: "mirror".into(),
                        message,
                    }
                })?;
            }
        }
        let mut support_faces = Vec::new();
        // Supports written without a mirror face (issue 24): the face from the geometry where
        // the group's members are the images of the body's particles across it (module
        // `faces`).
        if options.model == ElasticModel::SecondOrder {
            let eligible: Vec<bool> = gs
                .iter()
                .zip(&mirrored)
                .map(|(g, m)| {
                    let held = g.axes.iter().take(D).filter(|&&a| a).count();
                    !m && held > 0 && held < D && !g.members.is_empty()
                })
                .collect();
            for (g, r) in infer_support_faces(&p, &bonds, l0, &group_of, &eligible) {
                match r {
                    Ok((point, normal)) => {
                        let c =
                            |v: Vect<D>| std::array::from_fn(|k| if k < D { v[k] } else { 0.0 });
                        let face = MirrorFace {
                            point: c(point),
                            normal: c(normal),
                        };
                        mirrors.push((g, face, gs[g].axes));
                        support_faces.push((
                            g,
                            SupportFace::Mirror(faces::face_name(&Face {
                                normal,
                                offset: point.dot(&normal),
                            })),
                        ));
                    }
                    Err(why) => support_faces.push((g, why)),
                }
            }
        }
        let ghosts = find_ghosts(&p, l0, &group_of, &mirrors, &names, options.model)?;
        let (ghosts, mut followers, mut walls) =
            clamp_followers(&p, l0, &group_of, &mirrors, ghosts);
        // Clamps written without a mirror face (issue 24): the face between the group and its
        // body from the geometry, and the followers there (module `faces`).
        let mut clamp_faces = Vec::new();
        if options.model == ElasticModel::SecondOrder {
            let eligible: Vec<bool> = gs
                .iter()
                .zip(&mirrored)
                .map(|(g, m)| !m && g.axes.iter().take(D).all(|&a| a) && !g.members.is_empty())
                .collect();
            let (inferred, report) =
                infer_clamp_followers(&p, &bonds, l0, &group_of, &eligible, &followers);
            if !inferred.is_empty() {
                if walls.is_empty() {
                    walls = vec![false; n];
                }
                for (g, r) in &report {
                    if r.is_ok() {
                        for &m in &gs[*g].members {
                            walls[m as usize] = true;
                        }
                    }
                }
                followers.extend(inferred);
                followers.sort_by_key(|f| f.particle);
            }
            clamp_faces = report
                .into_iter()
                .map(|(g, r)| (g, r.map(|_| ())))
                .collect();
        }
        if !mirrors.is_empty() || !followers.is_empty() {
            clock.done(
                SetupStage::Clamps,
                &format!("{} ghosts, {} followers", ghosts.len(), followers.len()),
            )?;
        }
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
        // Particle volumes of bodies filled from solids (the closure below replaces those of a
        // body it closes).
        let mut surface = Vec::new();
        // Contact radii (module `contact`): empty, every particle l0 / 2, unless a body is
        // filled from a solid.
        let mut contact_radius = Vec::new();
        if bodies.iter().any(|b| b.shape.is_some()) {
            surface = vec![(Vect::<D>::zeros(), 0.0); n];
            contact_radius = vec![0.5 * l0; n];
            // Cell moments per unit volume: a whole cell's (0, l0^2 / 12 I) unless filled from
            // a solid.
            op.cell_moments =
                vec![(Vect::<D>::zeros(), Mat::<D>::identity() * (l0 * l0 / 12.0)); n];
            let mut at = 0usize;
            for body in &bodies {
                if let Some(s) = &body.shape {
                    for k in 0..body.points.len() {
                        op.vol[at + k] = s.volumes[k];
                        op.base_vol[at + k] = s.volumes[k];
                        surface[at + k] = (s.normals[k], s.areas[k]);
                        contact_radius[at + k] =
                            s.depths[k].min(crate::physics::contact::max_radius(l0, re));
                        let (m1, m2) = &s.moments[k];
                        op.cell_moments[at + k] = (m1 / s.volumes[k], m2 / s.volumes[k]);
                    }
                }
                at += body.points.len();
            }
        }
        clock.done(
            SetupStage::OperatorFits,
            &format!("{} operator", options.model.name()),
        )?;
        // The second-order operator's summation-by-parts closure at free faces (module `sbp`):
        // particle volumes (and masses) that integrate quadratics exactly and gradient weights
        // whose transpose passes the integration constraint.
        let mut closure = Vec::new();
        if options.model == ElasticModel::SecondOrder {
            // The closure's solves are the longest loop of a set-up (tens of seconds for a
            // bulky body): they stop within an iteration at the bound or a stop request.
            let interrupt = clock.interrupt();
            let faces: Vec<sbp::BodyFaces<D>> = bodies
                .iter()
                .map(|b| match &b.shape {
                    None => sbp::BodyFaces::Lattice,
                    Some(s) => s.solid_box.map_or(sbp::BodyFaces::Other, |(lo, hi)| {
                        sbp::BodyFaces::Box(lo, hi)
                    }),
                })
                .collect();
            let names: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
            let input = sbp::ClosureInputs {
                x0: &p.x0,
                faces: &faces,
                body: &p.body,
                bonds: &bonds,
                so: &op.second,
                l0,
                re_factor: options.re_factor,
                names: &names,
            };
            // A closure an earlier set-up computed for this geometry (an FMU instance built
            // again with other materials, step or damping, or the one `mps pack` shipped) is
            // taken as it is.
            let key = observer.memo().map(|_| sbp::memo::key(&input));
            let kept = observer
                .memo()
                .zip(key)
                .and_then(|(m, k)| m.closure::<D>(k))
                .filter(|cl| sbp::memo::fits(cl, &input));
            let reused_closure = kept.is_some();
            let cl = match kept {
                Some(cl) => cl,
                None => {
                    let cl = sbp::close(&input, &|| interrupt.hit());
                    if let Some(progress) = &cl.interrupted {
                        return Err(clock.interrupted(SetupStage::Closure, progress));
                    }
                    let cl = std::sync::Arc::new(cl);
                    if let (Some(m), Some(k)) = (observer.memo(), key) {
                        m.keep_closure(k, cl.clone());
                    }
                    cl
                }
            };
            let closable: Vec<bool> = cl.vol.iter().map(|v| v.is_some()).collect();
            for (i, v) in cl.vol.iter().enumerate() {
                if let Some(v) = v {
                    op.vol[i] = *v;
                    op.base_vol[i] = *v;
                    p.mass[i] = bodies[p.body[i] as usize].material.density * v;
                }
            }
            op.second.set_closure(&bonds, l0, cl.dg.clone(), closable);
            // The followers' inertia, lumped on the layers they follow.
            for fl in &op.second.followers {
                let m = p.mass[fl.particle as usize];
                for (j, share) in fl.inner.iter().zip(LUMP) {
                    p.mass[*j as usize] += share * m;
                }
            }
            closure = cl.report.clone();
            let closed = closure.iter().filter(|r| r.is_ok()).count();
            clock.done(
                SetupStage::Closure,
                &format!(
                    "{closed} of {} {} closed{}",
                    closure.len(),
                    if closure.len() == 1 { "body" } else { "bodies" },
                    if reused_closure {
                        ", as an earlier set-up of this geometry closed them"
                    } else {
                        ""
                    }
                ),
            )?;
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
            contact_radius,
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
            strain_tests: 0,
            broken_pairs: 0,
            fracture_release: 0.0,
            omega_max: 0.0,
            previous_step: 0.0,
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
            lanczos_evaluations: 0,
            step_refresh_seconds: 0.0,
            frac_flag: Vec::new(),
            strain_screen: Default::default(),
            scratch: ElasticScratch::default(),
            force: vec![Vect::<D>::zeros(); n],
            follower_inputs: (Vect::<D>::zeros(), Vec::new()),
            torque: vec![<Space as Dim<D>>::ang_zero(); n],
            group_of,
            load_of,
            bad: vec![0; n],
            surface,
            closure,
            clamp_faces,
            support_faces,
        };
        // The largest Ritz value of the Lanczos process approaches omega_max^2 from below: in 3D
        // 20 force evaluations leave omega up to 0.35 % short (80 power iterations, before: up
        // to 0.77 %; it stops at 12 to 20 once the value has settled, LANCZOS_SETTLED), and the
        // current configuration (large deflection) adds 1-2 %; the margin
        // covers both so that safety = 1 is stable. No eigenvector is kept: the first refresh
        // (a deforming body) measures from the deterministic start.
        let scratch = std::mem::take(&mut world.scratch);
        let (omega, evaluations, scratch) = world.lanczos_omega_max_in(LANCZOS_ITERATIONS, scratch);
        world.scratch = scratch;
        world.lanczos_evaluations = evaluations;
        world.omega_elastic = omega * (1.0 + OMEGA_MARGIN);
        world.omega_reference = world.omega_elastic;
        world.stable = StableStepState {
            omega_elastic: world.omega_elastic,
            omega_measured: world.omega_elastic,
            u_measured: Vec::new(),
            step_measured: 0,
            eig_t: Vec::new(),
            eig_r: Vec::new(),
        };
        // Contact adds stiffness that the reference state does not show: while a repelling pair
        // is in contact its bound is added to the measured omega^2 (Weyl: lambda_max(A + B) <=
        // lambda_max(A) + lambda_max(B); `set_omega_max`, after each force evaluation).
        let c2 = if world.contact.active
            && (world.body_names.len() >= 2 || world.options.contact.fractured_surfaces)
        {
            world.contact.omega2_bound(&world.p.mass)
        } else {
            0.0
        };
        world.omega2_contact = c2;
        world.omega_max = world.omega_elastic;
        let in_contact = if c2 > 0.0 {
            format!(
                " ({:.4e} while bodies are in contact)",
                (world.omega_elastic.powi(2) + c2).sqrt()
            )
        } else {
            String::new()
        };
        clock.done(
            SetupStage::StableStep,
            &format!(
                "omega_max {:.4e} rad/s{in_contact}, {evaluations} force evaluations",
                world.omega_max
            ),
        )?;
        match world.update_forces() {
            Err(e @ SimError::Overlap { .. }) => {
                return Err(SimError::Invalid(format!(
                    "bodies overlap in the initial state: {e}"
                )))
            }
            r => r?,
        }
        clock.done(SetupStage::InitialForces, "")?;
        Ok(world)
    }
}

/// Stage costs in bonds-stage seconds (see [`stage_costs`]): rough, for an estimate that
/// refuses a set-up hours long, not one a few tens of percent over its bound. Measured with
/// `mps run` on a loaded 2-core machine (BENCHMARKS.md, "Set-up stages": small3d at
/// 0.00625 m, 18,944 particles: fits 5.7, stable step and initial forces 49 bonds-stage
/// seconds with 80 power iterations; the stable step's Lanczos measurement takes 21 force
/// evaluations where those took 81, so 13), rounded up. The closure's 60 is far below what a bulky clamped body's closure
/// takes (500-800 bonds-stage seconds for a 15^3 cube or small3d at 0.00625 m: its solves run
/// on a box of at most 15 layers per axis, so no per-bond figure prices them); its solves
/// check the bound themselves (`sbp::close`).
const SECOND_ORDER_FITS: f64 = 10.0;
const SECOND_ORDER_CLOSURE: f64 = 60.0;
const FIRST_ORDER_FITS: f64 = 5.0;
const STABLE_STEP_COST: f64 = 15.0;

/// The cost of the stages after the bonds, in bonds-stage seconds, for the estimate of the
/// set-up's duration ([`SetupClock::estimate`]).
fn stage_costs(options: &SolverOptions) -> StageCosts {
    match options.model {
        ElasticModel::SecondOrder => StageCosts {
            fits: SECOND_ORDER_FITS,
            closure: SECOND_ORDER_CLOSURE,
            stable: STABLE_STEP_COST,
        },
        _ => StageCosts {
            fits: FIRST_ORDER_FITS,
            closure: 0.0,
            stable: STABLE_STEP_COST,
        },
    }
}
