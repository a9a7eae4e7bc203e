//! Builds a physics World from a validated Scene: particles from boxes, groups and load regions
//! from regions, probes located at their nearest particle.
use super::{axis_index, err, Region, Scene, SceneError};
use crate::physics::boundary::GravityLaw;
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
        for (k, b) in scene.bodies.iter().enumerate() {
            let mut pts: Vec<Vect<D>> = Vec::new();
            let cells: usize = b
                .boxes
                .iter()
                .filter_map(|r| scene.cell_counts(r, "").ok())
                .map(|n| n.iter().product::<usize>())
                .sum();
            pts.try_reserve_exact(cells).map_err(|e| {
                err(
                    format!("{}.boxes", super::body_field(k, b)),
                    format!("cannot allocate the {cells} particles of the body: {e}"),
                )
            })?;
            for (j, r) in b.boxes.iter().enumerate() {
                let n = scene.cell_counts(r, &format!("bodies[{k}].boxes[{j}]"))?;
                let first_new = pts.len();
                let grid = (j > 0).then(|| crate::physics::grid::CellGrid::build(&pts, None, dp));
                for code in 0..n.iter().product::<usize>() {
                    let mut c = code;
                    let mut p = Vect::<D>::zeros();
                    for a in 0..D {
                        p[a] = r.min[a] + ((c % n[a]) as f64 + 0.5) * dp;
                        c /= n[a];
                    }
                    let mut taken = false;
                    if let Some(g) = &grid {
                        g.for_each_near(&pts[..first_new], &p, 0.25 * dp, |_| taken = true);
                    }
                    if !taken {
                        pts.push(p);
                    }
                }
            }
            ranges.push(count..count + pts.len());
            count += pts.len();
            bodies.push(BodyInit {
                name: b.name.clone(),
                material: b.material,
                points: pts,
                velocity: InitialVelocity::Uniform(
                    b.velocity
                        .as_deref()
                        .map(vect::<D>)
                        .unwrap_or_else(Vect::<D>::zeros),
                ),
            });
        }
        let select = |body: &str, r: &Region, field: &str| -> Result<Vec<u32>, SceneError> {
            let bi = scene.body_index(body).expect("validated");
            let members: Vec<u32> = ranges[bi]
                .clone()
                .filter(|&i| inside(&bodies[bi].points[i - ranges[bi].start], r, 1e-9 * dp))
                .map(|i| i as u32)
                .collect();
            if members.is_empty() {
                return Err(err(
                    field,
                    format!(
                        "region {:?}..{:?} contains no particle of body '{body}'",
                        r.min, r.max
                    ),
                ));
            }
            Ok(members)
        };
        let mut groups = Vec::new();
        for (k, g) in scene.boundaries.iter().enumerate() {
            let members = select(
                &g.body,
                &g.region,
                &format!("boundaries[{k}] ('{}').region", g.name),
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
            });
        }
        let mut loads = Vec::new();
        for (k, l) in scene.loads.iter().enumerate() {
            loads.push((
                l.name.clone(),
                select(
                    &l.body,
                    &l.region,
                    &format!("loads[{k}] ('{}').region", l.name),
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
        let mut probes = Vec::new();
        for (k, p) in scene.probes.iter().enumerate() {
            let point = vect::<D>(&p.point);
            let body = match &p.body {
                Some(name) => scene.body_index(name),
                None => scene
                    .bodies
                    .iter()
                    .position(|b| b.boxes.iter().any(|r| inside(&point, r, 1e-9))),
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
        Ok(Model { world, probes })
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
