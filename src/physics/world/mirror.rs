//! Mirror faces: the ghosts of a mirroring group (members at the mirror images of free
//! particles) and the followers that replace the ghosts of clamped faces.
use super::SimError;
use crate::physics::dim::{Dim, Space, Vect};
use crate::physics::ghosts::{Follower, Ghost};
use crate::physics::params::ElasticModel;
use crate::physics::particles::Particles;

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

/// Splits the ghosts of clamped mirror faces (all axes held) off: the first layer of the body
/// at such a face follows the two layers behind it (`ghosts::Follower`), and the face's
/// members become walls that enter no fit. Returns (the other ghosts, the followers, the walls).
#[allow(clippy::type_complexity)]
pub(super) fn clamp_followers<const D: usize>(
    p: &Particles<D>,
    l0: f64,
    group_of: &[u32],
    mirrors: &[(usize, MirrorFace, [bool; 3])],
    ghosts: Vec<Ghost<D>>,
) -> (Vec<Ghost<D>>, Vec<Follower>, Vec<bool>)
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
        followers.push(Follower {
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
pub(super) fn find_ghosts<const D: usize>(
    p: &Particles<D>,
    l0: f64,
    group_of: &[u32],
    mirrors: &[(usize, MirrorFace, [bool; 3])],
    names: &[String],
    model: ElasticModel,
) -> Result<Vec<Ghost<D>>, SimError>
where
    Space: Dim<D>,
{
    let mut ghosts = Vec::new();
    if mirrors.is_empty() {
        return Ok(ghosts);
    }
    if model != ElasticModel::SecondOrder {
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
