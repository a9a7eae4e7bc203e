//! Builds a physics World from a validated Scene: particles from boxes and shapes, groups and
//! load regions from regions and shapes, probes located at their nearest particle.
use super::fill::body_fill;
use super::{axis_index, err, BodyVelocity, Region, Scene, SceneError, SceneWarning};
use crate::physics::boundary::GravityLaw;
use crate::physics::dim::to3;
use crate::physics::world::faces::SupportFace;
use crate::physics::world::{GroupInit, SetupObserver, SetupStage, Unobserved};
use crate::physics::SimError;
use crate::physics::{BodyInit, Dim, InitialVelocity, Space, Vect, World};

/// A probe located in the built world.
#[derive(Clone, Debug)]
pub struct ProbeAt<const D: usize> {
    pub name: String,
    pub point: Vect<D>,
    pub particle: usize,
}

/// A world built from a scene, with its probes.
pub struct Model<const D: usize>
where
    Space: Dim<D>,
{
    pub world: World<D>,
    pub probes: Vec<ProbeAt<D>>,
    /// Under-resolved geometry (see `scene::resolution`; the same as `Scene::warnings`), and
    /// second-order bodies without the closure at their free faces (module `physics::sbp`).
    pub warnings: Vec<SceneWarning>,
}

/// The angular quantity of D dimensions of a 3-array (2D: its z component), built from cross
/// products of unit vectors (2D: e_x x e_y = 1 about z; 3D: e_y x e_z = e_x and cyclic).
fn ang_from3<const D: usize>(w: [f64; 3]) -> <Space as Dim<D>>::Ang
where
    Space: Dim<D>,
{
    let e = |k: usize| Vect::<D>::from_fn(|i, _| if i == k { 1.0 } else { 0.0 });
    let unit = |k: usize| <Space as Dim<D>>::cross(&e((k + 1) % 3), &e((k + 2) % 3));
    if D == 2 {
        <Space as Dim<D>>::ang_scale(<Space as Dim<D>>::cross(&e(0), &e(1)), w[2])
    } else {
        (0..3).fold(<Space as Dim<D>>::ang_zero(), |acc, k| {
            <Space as Dim<D>>::ang_add(acc, <Space as Dim<D>>::ang_scale(unit(k), w[k]))
        })
    }
}

/// The initial velocity of body k's particles `pts`: uniform for the array form, else the
/// field evaluated at each reference position. A value that is not finite (a field whose
/// parts overflow) is an error naming the body's velocity.
fn initial_velocity<const D: usize>(
    scene: &Scene,
    k: usize,
    pts: &[Vect<D>],
) -> Result<InitialVelocity<D>, SceneError>
where
    Space: Dim<D>,
{
    let b = &scene.bodies[k];
    let field = match &b.velocity {
        None => return Ok(InitialVelocity::Uniform(Vect::<D>::zeros())),
        Some(BodyVelocity::Uniform(u)) => return Ok(InitialVelocity::Uniform(vect::<D>(u))),
        Some(f) => f,
    };
    let f = format!("{}.velocity", super::body_field(k, b));
    let mut v = Vec::new();
    let mut w = Vec::new();
    let oom = |e: std::collections::TryReserveError| {
        err(
            &f,
            format!(
                "cannot allocate the initial velocities of {} particles: {e}",
                pts.len()
            ),
        )
    };
    v.try_reserve_exact(pts.len()).map_err(oom)?;
    w.try_reserve_exact(pts.len()).map_err(oom)?;
    for p in pts {
        let (vi, wi) = field.at(to3(p));
        if !vi.iter().chain(&wi).all(|c| c.is_finite()) {
            return Err(err(
                &f,
                format!(
                    "the velocity at the particle at {:?} m is {vi:?} m/s (angular {wi:?} rad/s), \
                     which is not finite",
                    to3(p)
                ),
            ));
        }
        v.push(vect::<D>(&vi));
        w.push(ang_from3::<D>(wi));
    }
    Ok(InitialVelocity::PerParticle { v, w })
}

/// Warnings where the second-order operator's accuracy is reduced (issue 24), in the scene's
/// terms: which body or clamp, the estimated effect at its resolution, and what to change.
/// The estimates are measured (`mps study family`, docs/model.md "Clamps from the geometry"): a
/// clamp held as a rigid block makes a cantilever's static deflection about 9.5 / n % too large
/// at n particles through it (+2.2 / +2.4 % at 4, +1.2 % at 8 in 2D and 3D), its first frequency
/// about half that too low; a body whose free faces are first order (a union of boxes: the
/// stepped cantilever, the L-bracket, the plate with a hole) about 25 / n^2 % too large in
/// static deflection (+1.1 to +1.7 % at 4, +0.31 to +0.52 % at 8) and 12 / n^2 % too low in f1.
fn accuracy_warnings<const D: usize>(
    scene: &Scene,
    world: &World<D>,
    through: &[usize],
    earlier: &[SceneWarning],
) -> Vec<SceneWarning>
where
    Space: Dim<D>,
{
    let mut out = Vec::new();
    for (g, r) in &world.clamp_faces {
        let Err(why) = r else { continue };
        if why.starts_with("it touches no free particle") {
            continue;
        }
        let b = &scene.boundaries[*g];
        let k = scene.body_index(&b.body).expect("validated");
        let n = through[k];
        let remedy = if why.contains("less than") {
            "make the body deeper behind the clamped face (at least 4 particles: a smaller particle_spacing), or clamp a thicker part"
        } else {
            "let the region hold the layers behind one plane face of the body only (a region per face does not help where two clamped faces meet at an edge)"
        };
        out.push(SceneWarning {
            field: format!("boundaries[{g}] ('{}')", b.name),
            message: format!(
                "clamp '{}' is held as a rigid block ({why}); body '{}' is then too flexible next to it: a cantilever's static deflection about {:.1} % too large and its first frequency about {:.1} % too low at {n} particles through '{}'; to fix it, {remedy}",
                b.name,
                b.body,
                9.5 / n as f64,
                4.75 / n as f64,
                b.body
            ),
        });
    }
    for (g, r) in &world.support_faces {
        let SupportFace::Shallow(face, layers, needed) = r else {
            continue;
        };
        let b = &scene.boundaries[*g];
        let axes = b.axes.as_deref().unwrap_or_default().join(", ");
        out.push(SceneWarning {
            field: format!("boundaries[{g}] ('{}')", b.name.escape_debug()),
            message: format!(
                "support '{}' holds {axes} on {layers} layer(s) of particles beyond the face of body '{}' at {face}, fewer than the {needed} the default operator needs there to support the body on that face; with fewer it holds them as part of the body, which then bends too easily (measured on a plate 4 particles thick resting on such a support at its end: one layer, first frequency 2.3 % too low and deflection 4.2 % too large); to fix it, let the region hold {needed} layers beyond the face (the body's boxes reaching {needed} particle spacings beyond it)",
                b.name, b.body
            ),
        });
    }
    for (k, r) in world.closure.iter().enumerate() {
        let Err(why) = r else { continue };
        // A body already warned of as under-resolved gets no second warning: its geometry is
        // the cause, and refining it is the remedy of both.
        let field = super::body_field(k, &scene.bodies[k]);
        let prefix = format!("bodies[{k}]");
        if earlier.iter().any(|w| {
            w.field
                .strip_prefix(&prefix)
                .is_some_and(|rest| rest.is_empty() || rest.starts_with(' '))
        }) {
            continue;
        }
        let name = &scene.bodies[k].name;
        let n = through[k];
        // A support too shallow to mirror the body has its own warning (above), whose remedy
        // is this one's too.
        if world.support_faces.iter().any(|(g, r)| {
            matches!(r, SupportFace::Shallow(..)) && scene.boundaries[*g].body == *name
        }) {
            continue;
        }
        if why.contains("one lattice") {
            let supports = face_layer_supports(scene, world, k);
            if !supports.is_empty() {
                for g in supports {
                    out.push(face_layer_warning(scene, g, n));
                }
                continue;
            }
        }
        let (what, remedy) = if why.contains("rigid grip") {
            (
                "a clamp held as a rigid block".to_string(),
                "see the clamp's own warning".to_string(),
            )
        } else if why.contains("filled box") || why.contains("one lattice") {
            (
                "it is not a single box".to_string(),
                "the error falls as the square of the particle spacing: halve particle_spacing for a quarter of it (a body of one box has no such error)".to_string(),
            )
        } else {
            (
                why.trim_start_matches("it ").to_string(),
                "a smaller particle_spacing reduces it".to_string(),
            )
        };
        out.push(SceneWarning {
            field,
            message: format!(
                "the stresses at the free faces of body '{name}' are computed to first order only ({what}): it bends too easily, its static deflection about {:.1} % too large and its first frequency about {:.1} % too low at {n} particles through '{name}'; {remedy}",
                25.0 / (n * n) as f64,
                12.0 / (n * n) as f64
            ),
        });
    }
    out
}

/// The boundary groups of body k holding some axes (supports) whose particles lie off the
/// body's lattice: a layer of particles on a face of the body, half a spacing out from its
/// lattice, as the corrected operator's scenes write a support (the paper's case 2). The
/// body's lattice is that of its first box (particles at its corner plus half a spacing).
fn face_layer_supports<const D: usize>(scene: &Scene, world: &World<D>, k: usize) -> Vec<usize>
where
    Space: Dim<D>,
{
    let body = &scene.bodies[k];
    let Some(first) = body.boxes.first() else {
        return Vec::new();
    };
    let dp = scene.particle_spacing;
    let off = |x: &Vect<D>| {
        (0..D).any(|a| {
            let f = (x[a] - first.min[a]) / dp - 0.5;
            (f - f.round()).abs() > 1e-6
        })
    };
    scene
        .boundaries
        .iter()
        .enumerate()
        .filter(|(_, b)| b.body == body.name && b.axes.as_ref().is_some_and(|a| a.len() < D))
        .filter(|(g, b)| {
            world.groups.get(*g).is_some_and(|grp| {
                grp.name == b.name
                    && !grp.members.is_empty()
                    && grp.members.iter().all(|&i| off(&world.p.x0[i as usize]))
            })
        })
        .map(|(g, _)| g)
        .collect()
}

/// The warning on a support written as a layer of particles on the body's face (see
/// `face_layer_supports`), `n` particles through the body. Measured (`mps study family 4`
/// with THREE_D=1, the paper's case 2 with the default operator, written for the corrected one:
/// a face layer at both ends): static deflection +1.47 % and first frequency -0.82 % at 9
/// particles through the beam, +0.459 % and -0.280 % at 18 (the same beam with `mirror` faces
/// at 9: +0.14 % and -0.07 %); the estimate at n is the power law through the two,
/// 60 / n^1.7 % and 25 / n^1.55 %.
fn face_layer_warning(scene: &Scene, g: usize, n: usize) -> SceneWarning {
    let b = &scene.boundaries[g];
    let axes = b.axes.as_deref().unwrap_or_default().join(", ");
    SceneWarning {
        field: format!("boundaries[{g}] ('{}')", b.name.escape_debug()),
        message: format!(
            "support '{}' is a layer of particles on the face of body '{}', half a particle \
             spacing off the body's own particles, holding {axes}: the default operator then \
             computes the stresses at all of the body's free faces to first order only, so it \
             bends too easily: its static deflection about {:.2} % too large and its first \
             frequency about {:.2} % too low at {n} particles through '{}' (measured on the \
             paper's clamped-pinned beam: 1.5 % and 0.8 % at 9 particles through it, 0.46 % and \
             0.28 % at 18); to fix it, put two or three layers of particles beyond the face into \
             the body's boxes instead of the layer on it and let the region hold them: the same \
             beam is then within 0.15 % at 9 particles through it",
            b.name,
            b.body,
            60.0 / (n as f64).powf(1.7),
            25.0 / (n as f64).powf(1.55),
            b.body
        ),
    }
}

fn vect<const D: usize>(v: &[f64]) -> Vect<D> {
    Vect::<D>::from_fn(|k, _| v.get(k).copied().unwrap_or(0.0))
}

fn inside<const D: usize>(p: &Vect<D>, r: &Region, tol: f64) -> bool {
    (0..D).all(|k| p[k] >= r.min[k] - tol && p[k] <= r.max[k] + tol)
}

impl<const D: usize> Model<D>
where
    Space: Dim<D>,
{
    /// Builds the world of a validated scene of dimension D. A scene whose memory estimate
    /// exceeds the memory available is refused before anything is allocated, and the big
    /// arrays are reserved fallibly, so running out of memory is an error, not an abort.
    pub fn build(scene: &Scene) -> Result<Self, SceneError> {
        Self::build_observed(scene, &Unobserved)
    }

    /// [`Model::build`] with the set-up's stages told to `observer` as they end (the particles
    /// here, the rest in `World::new_observed`), which may stop it at a stage boundary.
    pub fn build_observed(scene: &Scene, observer: &dyn SetupObserver) -> Result<Self, SceneError> {
        assert_eq!(scene.dimension, D, "scene dimension");
        let fill_start = std::time::Instant::now();
        scene.validate()?;
        super::memory::check(scene)?;
        let dp = scene.particle_spacing;
        let mut bodies = Vec::new();
        let mut ranges = Vec::new();
        let mut count = 0usize;
        let mut warnings = Vec::new();
        let mut box_ofs = Vec::new();
        for (k, b) in scene.bodies.iter().enumerate() {
            let fill = body_fill::<D>(scene, k)?;
            let (pts, box_of) = (fill.points, fill.box_of);
            warnings.extend(super::resolution::body_warnings::<D>(
                scene, k, &pts, &box_of,
            ));
            warnings.extend(super::resolution::shape_warnings(
                scene,
                k,
                fill.shape.as_ref().map(|s| s.volumes.as_slice()),
                fill.shape.as_ref().is_some_and(|s| s.solid_box.is_some()),
                fill.lost_volume,
            ));
            let velocity = initial_velocity::<D>(scene, k, &pts)?;
            box_ofs.push(box_of);
            ranges.push(count..count + pts.len());
            count += pts.len();
            bodies.push(BodyInit {
                name: b.name.clone(),
                material: b.material,
                points: pts,
                velocity,
                shape: fill.shape,
            });
        }
        let select = |body: &str,
                      r: &Region,
                      shape: Option<&super::Shape>,
                      field: &str|
         -> Result<Vec<u32>, SceneError> {
            let bi = scene.body_index(body).expect("validated");
            let open = r.min.is_empty() && r.max.is_empty();
            let solid = shape
                .map(|s| super::shape::solid(field, s, D, scene.base_dir.as_deref()))
                .transpose()?;
            let members: Vec<u32> = ranges[bi]
                .clone()
                .filter(|&i| {
                    let p = &bodies[bi].points[i - ranges[bi].start];
                    (open || inside(p, r, 1e-9 * dp))
                        && solid.as_ref().is_none_or(|s| {
                            s.distance(super::shape::to3(p.as_slice())) <= 1e-6 * dp
                        })
                })
                .map(|i| i as u32)
                .collect();
            if members.is_empty() {
                let what = match (open, shape.is_some()) {
                    (false, false) => format!("region {:?}..{:?}", r.min, r.max),
                    (true, _) => "the shape".to_string(),
                    (false, true) => format!("region {:?}..{:?} and the shape", r.min, r.max),
                };
                return Err(err(
                    field,
                    format!("{what} contains no particle of body '{body}'"),
                ));
            }
            Ok(members)
        };
        let mut groups = Vec::new();
        for (k, g) in scene.boundaries.iter().enumerate() {
            let members = select(
                &g.body,
                &g.region,
                g.shape.as_ref(),
                &format!(
                    "boundaries[{k}] ('{}').{}",
                    g.name,
                    if g.shape.is_some() { "shape" } else { "region" }
                ),
            )?;
            let mut axes = [false; 3];
            match (&g.axes, g.kind) {
                (_, super::BoundaryKind::Clamped) | (None, _) => {
                    axes[..D].iter_mut().for_each(|a| *a = true)
                }
                (Some(list), _) => list
                    .iter()
                    .for_each(|a| axes[axis_index(a).expect("validated")] = true),
            }
            groups.push(GroupInit {
                name: g.name.clone(),
                members,
                axes,
                fix_rotation: g.kind != super::BoundaryKind::Pinned,
                mirror: g.mirror.as_ref().map(|m| {
                    let mut face = crate::physics::world::MirrorFace {
                        point: [0.0; 3],
                        normal: [0.0; 3],
                    };
                    face.point[..D].copy_from_slice(&m.point[..D]);
                    face.normal[..D].copy_from_slice(&m.normal[..D]);
                    face
                }),
            });
        }
        let mut loads = Vec::new();
        for (k, l) in scene.loads.iter().enumerate() {
            loads.push((
                l.name.clone(),
                select(
                    &l.body,
                    &l.region,
                    l.shape.as_ref(),
                    &format!(
                        "loads[{k}] ('{}').{}",
                        l.name,
                        if l.shape.is_some() { "shape" } else { "region" }
                    ),
                )?,
            ));
        }
        // Particles through the thinnest section of each body: the smallest extent, over the
        // particle spacing, of its boxes that hold a particle of no boundary group.
        let through: Vec<usize> = {
            let mut held = vec![false; count];
            for g in &groups {
                for &m in &g.members {
                    held[m as usize] = true;
                }
            }
            (0..scene.bodies.len())
                .map(|k| {
                    let free_box: std::collections::HashSet<u32> = box_ofs[k]
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| !held[ranges[k].start + i])
                        .map(|(_, b)| *b)
                        .collect();
                    scene.bodies[k]
                        .boxes
                        .iter()
                        .enumerate()
                        .filter(|(j, _)| free_box.contains(&(*j as u32)))
                        .flat_map(|(_, r)| {
                            r.min
                                .iter()
                                .zip(&r.max)
                                .map(|(a, b)| ((b - a) / dp).round())
                        })
                        .fold(f64::INFINITY, f64::min)
                        .clamp(1.0, 1e9) as usize
                })
                .collect()
        };
        let g = if scene.gravity.vector.is_empty() {
            Vect::<D>::zeros()
        } else {
            vect::<D>(&scene.gravity.vector)
        };
        let gravity = match scene.gravity.paper_ramp_period {
            Some(period) => GravityLaw::PaperRamp { full: g, period },
            None => GravityLaw::Constant(g),
        };
        observer.stage_done(
            SetupStage::Particles,
            fill_start.elapsed().as_secs_f64(),
            &format!("{count} particles"),
        );
        let world = World::new_observed(
            dp,
            scene.solver.clone(),
            bodies,
            groups,
            loads,
            gravity,
            observer,
        )
        .map_err(|e| match e {
            SimError::SetupTooLong { .. } => err("solver.max_setup_seconds", e.to_string()),
            SimError::Boundary {
                group,
                name,
                field,
                message,
            } => err(format!("boundaries[{group}] ('{name}').{field}"), message),
            e => err("scene", e.to_string()),
        })?;
        warnings.extend(accuracy_warnings(scene, &world, &through, &warnings));
        let mut probes = Vec::new();
        for (k, p) in scene.probes.iter().enumerate() {
            let point = vect::<D>(&p.point);
            let body = match &p.body {
                Some(name) => scene.body_index(name),
                None => scene
                    .bodies
                    .iter()
                    .position(|b| scene.body_contains(b, &p.point)),
            };
            let (particle, _) = world
                .nearest_particle(&point, body.map(|b| b as u32))
                .ok_or_else(|| err(format!("probes[{k}]"), "no particle near the probe"))?;
            probes.push(ProbeAt {
                name: p.name.clone(),
                point,
                particle,
            });
        }
        Ok(Model {
            world,
            probes,
            warnings,
        })
    }

    /// Displacement of probe k (m).
    pub fn probe_displacement(&self, k: usize) -> Vect<D> {
        let p = &self.probes[k];
        self.world.displacement_at(p.particle, &p.point)
    }

    /// Velocity of probe k (m/s).
    pub fn probe_velocity(&self, k: usize) -> Vect<D> {
        let p = &self.probes[k];
        self.world.velocity_at(p.particle, &p.point)
    }
}
