//! The bodies' surfaces as meshes that move with the particles (`mps run --surface`, ParaView):
//! each body's solid (its boxes, shapes and cuts, module `shape`) triangulated (segments in 2D)
//! at about the particle spacing, each vertex carried by the nearest particle of its body with
//! the displacement interpolated there (`World::displacement_at`: exact for linear fields).
use super::{err, Model, Scene, SceneError};
use crate::physics::grid::CellGrid;
use crate::physics::{Dim, Space, Vect};

/// A surface mesh in the reference configuration.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceMesh {
    /// Vertices (m, z = 0 in 2D).
    pub points: Vec<[f64; 3]>,
    /// Triangles (3D) or segments (2D) as vertex indices, facing out of the body.
    pub cells: Vec<Vec<u32>>,
    /// The body of each cell.
    pub cell_body: Vec<u32>,
    /// The particle that carries each vertex.
    pub particle: Vec<u32>,
}

impl<const D: usize> Model<D>
where
    Space: Dim<D>,
{
    /// The surface mesh of the bodies of `scene` (the scene this model was built from).
    pub fn surface_mesh(&self, scene: &Scene) -> Result<SurfaceMesh, SceneError> {
        let w = &self.world;
        let dp = scene.particle_spacing;
        let mut out = SurfaceMesh::default();
        let mut start = 0usize;
        for (k, b) in scene.bodies.iter().enumerate() {
            let count = w.p.body[start..]
                .iter()
                .take_while(|&&x| x as usize == k)
                .count();
            let range = start..start + count;
            start += count;
            if count == 0 {
                continue;
            }
            let g = scene.geometry(b)?;
            let pts = &w.p.x0[range.clone()];
            let grid = CellGrid::build(pts, None, 3.0 * dp);
            for cell in g.surface(D, dp) {
                let mut ids = Vec::with_capacity(cell.len());
                for q in cell {
                    let v = Vect::<D>::from_fn(|a, _| q[a]);
                    let consider = |best: &mut Option<(f64, u32)>, j: u32| {
                        let d2 = (pts[j as usize] - v).norm_squared();
                        if best.is_none_or(|(bd, bj)| d2 < bd || (d2 == bd && j < bj)) {
                            *best = Some((d2, j));
                        }
                    };
                    let mut best: Option<(f64, u32)> = None;
                    grid.for_each_near(pts, &v, 3.0 * dp, |j| consider(&mut best, j));
                    if best.is_none() {
                        // A vertex far from every particle (a sliver the lattice missed).
                        for j in 0..pts.len() as u32 {
                            consider(&mut best, j);
                        }
                    }
                    let Some((_, j)) = best else {
                        return Err(err(
                            format!("bodies[{k}]"),
                            format!("body '{}' has no particle", b.name),
                        ));
                    };
                    ids.push(out.points.len() as u32);
                    out.points.push(q);
                    out.particle.push((range.start + j as usize) as u32);
                }
                out.cells.push(ids);
                out.cell_body.push(k as u32);
            }
        }
        Ok(out)
    }

    /// The displacement of each vertex of `mesh` now (m, 3-arrays).
    pub fn surface_displacement(&self, mesh: &SurfaceMesh) -> Vec<[f64; 3]> {
        mesh.points
            .iter()
            .zip(&mesh.particle)
            .map(|(q, &i)| {
                let v = Vect::<D>::from_fn(|a, _| q[a]);
                let u = self.world.displacement_at(i as usize, &v);
                std::array::from_fn(|a| if a < D { u[a] } else { 0.0 })
            })
            .collect()
    }
}
