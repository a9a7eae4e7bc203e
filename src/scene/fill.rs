//! Filling bodies with particles: the lattice points of a body's boxes (cell centres at the
//! particle spacing), shared by the World builder and the resolution warnings.
use super::{err, Scene, SceneError};
use crate::physics::Vect;

/// The particles of body k of a validated scene: the cell centres of its boxes, a particle
/// closer than l0 / 4 to one of an earlier box dropped; and for each particle the index of the
/// box it comes from.
pub(crate) fn body_points<const D: usize>(
    scene: &Scene,
    k: usize,
) -> Result<(Vec<Vect<D>>, Vec<u32>), SceneError> {
    let dp = scene.particle_spacing;
    let b = &scene.bodies[k];
    let mut pts: Vec<Vect<D>> = Vec::new();
    let mut box_of: Vec<u32> = Vec::new();
    let cells: usize = b
        .boxes
        .iter()
        .filter_map(|r| scene.cell_counts(r, "").ok())
        .map(|n| n.iter().product::<usize>())
        .sum();
    let oom = |e: std::collections::TryReserveError| {
        err(
            format!("{}.boxes", super::body_field(k, b)),
            format!("cannot allocate the {cells} particles of the body: {e}"),
        )
    };
    pts.try_reserve_exact(cells).map_err(oom)?;
    box_of.try_reserve_exact(cells).map_err(oom)?;
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
                box_of.push(j as u32);
            }
        }
    }
    Ok((pts, box_of))
}
