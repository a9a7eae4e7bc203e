//! Builds a physics World from a validated Scene: particles from boxes and shapes, groups and
//! load regions from regions and shapes, probes located at their nearest particle.
use super::fill::body_fill;
use super::{axis_index, err, BodyVelocity, Region, Scene, SceneError, SceneWarning};
use crate::physics::boundary::GravityLaw;
use crate::physics::dim::to3;
use crate::physics::world::GroupInit;
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
        assert_eq!(scene.dimension, D, "scene dimension");
        scene.validate()?;
        super::memory::check(scene)?;
        let dp = scene.particle_spacing;
        let mut bodies = Vec::new();
        let mut ranges = Vec::new();
        let mut count = 0usize;
        let mut warnings = Vec::new();
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
                fill.lost_volume,
            ));
            let velocity = initial_velocity::<D>(scene, k, &pts)?;
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
        let g = if scene.gravity.vector.is_empty() {
            Vect::<D>::zeros()
        } else {
            vect::<D>(&scene.gravity.vector)
        };
        let gravity = match scene.gravity.paper_ramp_period {
            Some(period) => GravityLaw::PaperRamp { full: g, period },
            None => GravityLaw::Constant(g),
        };
        let world = World::new(dp, scene.solver.clone(), bodies, groups, loads, gravity)
            .map_err(|e| err("scene", e.to_string()))?;
        for (k, r) in world.closure.iter().enumerate() {
            // A body already warned of as under-resolved gets no second warning: its geometry
            // is the cause, and refining it is the remedy of both.
            let field = format!("bodies[{k}]");
            let resolved = !warnings.iter().any(|w: &SceneWarning| {
                w.field
                    .strip_prefix(&field)
                    .is_some_and(|rest| rest.is_empty() || rest.starts_with(' '))
            });
            if let (Err(why), true) = (r, resolved) {
                warnings.push(SceneWarning {
                    field,
                    message: format!(
                        "second_order keeps its plain fits at the free faces of body '{}' ({why}): its summation-by-parts closure needs a body that fills one lattice box (with its mirror images), so there the particle quadrature of the weak form is first order (docs/model.md, \"Free faces\")",
                        scene.bodies[k].name
                    ),
                });
            }
        }
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
