//! Clamped faces from the geometry (issue 24): the plane between a boundary group's members and
//! the free particles of its body along a lattice axis, however the scene wrote the group's
//! region (wall layers behind the face, the body's own end layers, a layer on the face, part of
//! a face). The second-order operator builds its clamp followers there (`ghosts::Follower`), so
//! a clamp needs no `mirror` field; a mirror face that a scene does give is checked against it.
use std::collections::HashMap;

use crate::physics::bonds::Bonds;
use crate::physics::dim::{Dim, Space, Vect};
use crate::physics::ghosts::Follower;
use crate::physics::particles::Particles;

/// Relative tolerance (of l0) of the lattice tests.
const TOL: f64 = 1e-6;

/// A plane face between a group and its body: the unit normal out of the body (into the group)
/// and the face's offset along it (m): the face is {x : x . normal = offset}.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face<const D: usize> {
    pub normal: Vect<D>,
    pub offset: f64,
}

/// What a group touches: its faces, and the followers a clamp there would have (or why not).
#[derive(Clone, Debug)]
pub struct GroupFaces<const D: usize> {
    /// The distinct faces between the group and the free particles of its body.
    pub faces: Vec<Face<D>>,
    /// The first layer of the body at those faces, following the two layers behind it; Err:
    /// why the group cannot be built as followers (it keeps the rigid grip).
    pub followers: Result<Vec<Follower>, String>,
}

/// The lattice directions (unit, both signs) of particle i: its bonds of length l0.
fn lattice_directions<const D: usize>(bonds: &Bonds<D>, i: usize, l0: f64) -> Vec<Vect<D>> {
    let mut dirs: Vec<Vect<D>> = Vec::with_capacity(2 * D);
    for b in bonds.of(i) {
        let r = bonds.r0[b];
        if (r.norm() - l0).abs() > TOL * l0 {
            continue;
        }
        let e = r / r.norm();
        for s in [e, -e] {
            if dirs.iter().all(|d| d.dot(&s) < 1.0 - 1e-9) {
                dirs.push(s);
            }
        }
    }
    dirs
}

/// The bond of i whose reference vector is `r` (within TOL l0), if any.
fn bond_to<const D: usize>(bonds: &Bonds<D>, i: usize, r: &Vect<D>, l0: f64) -> Option<usize> {
    bonds
        .of(i)
        .find(|&b| (bonds.r0[b] - r).norm() < TOL * l0)
        .map(|b| bonds.nbr[b] as usize)
}

/// The faces group `g` shares with the free particles (`group_of == u32::MAX`) of its body, and
/// its followers: a free particle i touches the group across a face of normal e when a member
/// sits at its lattice neighbour i + l0 e (the group's layers on the lattice: walls behind
/// the face, or the body's own end layers) or half a spacing out along e, within half a cell
/// sideways (a layer on the face, e.g. on the cell vertices across the section). The face is
/// then half a spacing out from i, where the followers' extrapolation puts the clamp's motion.
pub fn group_faces<const D: usize>(
    p: &Particles<D>,
    bonds: &Bonds<D>,
    l0: f64,
    group_of: &[u32],
    g: u32,
) -> GroupFaces<D>
where
    Space: Dim<D>,
{
    // Per free particle bonded to the group: the members' positions relative to it.
    let mut near: HashMap<usize, Vec<(usize, Vect<D>)>> = HashMap::new();
    for (m, gm) in group_of.iter().enumerate() {
        if *gm != g {
            continue;
        }
        for b in bonds.of(m) {
            let i = bonds.nbr[b] as usize;
            if group_of[i] == u32::MAX {
                near.entry(i).or_default().push((m, -bonds.r0[b]));
            }
        }
    }
    // Per free particle touching the group: (direction, the nearest member along it). A member
    // at the lattice site i + l0 e marks the face of normal e; so do members half a spacing
    // out along e within half a cell sideways (a layer on the face), where the body has no
    // lattice site i + l0 e; of several such directions (a particle at the face's edge) the one
    // with the most members.
    let lateral_max = (0.5 * ((D - 1) as f64).sqrt() + TOL) * l0;
    let mut touch: HashMap<usize, Vec<(Vect<D>, usize, f64)>> = HashMap::new();
    for (&i, members) in &near {
        let dirs = lattice_directions(bonds, i, l0);
        let occupied = |e: &Vect<D>| bond_to(bonds, i, &(e * l0), l0).is_some();
        let mut list: Vec<(Vect<D>, usize, f64)> = Vec::new();
        for e in &dirs {
            if let Some(&(m, _)) = members.iter().find(|(_, r)| (r - e * l0).norm() < TOL * l0) {
                list.push((*e, m, l0));
            }
        }
        if list.is_empty() {
            let mut best: Option<(Vect<D>, usize, usize)> = None;
            for e in &dirs {
                if occupied(e) {
                    continue;
                }
                let on_face: Vec<usize> = members
                    .iter()
                    .filter(|(_, r)| {
                        let n = e.dot(r);
                        (n - 0.5 * l0).abs() < TOL * l0 && (r - e * n).norm() <= lateral_max
                    })
                    .map(|(m, _)| *m)
                    .collect();
                if !on_face.is_empty() && best.as_ref().is_none_or(|b| on_face.len() > b.2) {
                    best = Some((*e, on_face[0], on_face.len()));
                }
            }
            if let Some((e, m, _)) = best {
                list.push((e, m, 0.5 * l0));
            }
        }
        if !list.is_empty() {
            touch.insert(i, list);
        }
    }
    let mut faces: Vec<Face<D>> = Vec::new();
    let mut followers = Vec::new();
    let mut why: Option<String> = None;
    let mut keys: Vec<usize> = touch.keys().copied().collect();
    keys.sort_unstable();
    for i in keys {
        let list = &touch[&i];
        for (e, _, _) in list {
            let offset = (p.x0[i] + e * (0.5 * l0)).dot(e);
            if !faces
                .iter()
                .any(|f| f.normal.dot(e) > 1.0 - 1e-9 && (f.offset - offset).abs() < TOL * l0)
            {
                faces.push(Face { normal: *e, offset });
            }
        }
        if why.is_some() {
            continue;
        }
        if list.len() > 1 {
            why = Some(format!(
                "a particle at {:?} m touches it on {} faces (an edge or corner of the body that the group wraps)",
                p.x0[i].as_slice(),
                list.len()
            ));
            continue;
        }
        let (e, wall, _) = list[0];
        let inner: Vec<Option<usize>> = [1.0, 2.0]
            .iter()
            .map(|k| bond_to(bonds, i, &(-e * (k * l0)), l0))
            .collect();
        match (inner[0], inner[1]) {
            (Some(a), Some(b)) if group_of[a] == u32::MAX && group_of[b] == u32::MAX => {
                followers.push(Follower {
                    particle: i as u32,
                    wall: wall as u32,
                    inner: [a as u32, b as u32],
                })
            }
            _ => {
                why = Some(format!(
                    "the body is less than 3 free layers deep behind the face at the particle at {:?} m",
                    p.x0[i].as_slice()
                ))
            }
        }
    }
    GroupFaces {
        faces,
        followers: match why {
            Some(w) => Err(w),
            None if followers.is_empty() => Err("it touches no free particle of its body".into()),
            None => Ok(followers),
        },
    }
}

/// Per eligible group: the number of its followers, or why it keeps the rigid grip.
pub(super) type ClampReport = Vec<(usize, Result<usize, String>)>;

/// Followers of the clamped groups without a mirror face (`eligible[g]`: all axes held), group
/// by group; a group whose followers would chain with another's (a particle at two clamped
/// faces, or a body thinner than 4 layers between two) keeps the grip. Returns the followers
/// and, per eligible group, the number of its followers or why it keeps the grip.
pub(super) fn infer_clamp_followers<const D: usize>(
    p: &Particles<D>,
    bonds: &Bonds<D>,
    l0: f64,
    group_of: &[u32],
    eligible: &[bool],
    taken: &[Follower],
) -> (Vec<Follower>, ClampReport)
where
    Space: Dim<D>,
{
    let mut per: Vec<(usize, Result<Vec<Follower>, String>)> = eligible
        .iter()
        .enumerate()
        .filter(|(_, e)| **e)
        .map(|(g, _)| (g, group_faces(p, bonds, l0, group_of, g as u32).followers))
        .collect();
    // Drop groups whose followers chain with another's until none do.
    loop {
        let mut owner: HashMap<u32, usize> =
            taken.iter().map(|f| (f.particle, usize::MAX)).collect();
        let mut clash: Vec<(usize, String)> = Vec::new();
        for (g, r) in &per {
            if let Ok(fs) = r {
                for f in fs {
                    if let Some(&o) = owner.get(&f.particle) {
                        if o != *g {
                            clash.push((*g, "a particle of its face is at another clamped face too (an edge between two clamped faces)".into()));
                            if o != usize::MAX {
                                clash.push((o, "a particle of its face is at another clamped face too (an edge between two clamped faces)".into()));
                            }
                        }
                    }
                    owner.insert(f.particle, *g);
                }
            }
        }
        for (g, r) in &per {
            if let Ok(fs) = r {
                if fs
                    .iter()
                    .any(|f| f.inner.iter().any(|j| owner.contains_key(j)))
                {
                    clash.push((
                        *g,
                        "the body is less than 4 layers thick between two clamped faces".into(),
                    ));
                }
            }
        }
        if clash.is_empty() {
            break;
        }
        for (g, why) in clash {
            if let Some(entry) = per.iter_mut().find(|(h, _)| *h == g) {
                if entry.1.is_ok() {
                    entry.1 = Err(why);
                }
            }
        }
    }
    let mut all = Vec::new();
    let mut report = Vec::new();
    for (g, r) in per {
        match r {
            Ok(fs) => {
                report.push((g, Ok(fs.len())));
                all.extend(fs);
            }
            Err(w) => report.push((g, Err(w))),
        }
    }
    (all, report)
}

/// The name of a lattice-axis direction ("+x", "-y", ...) or the vector.
fn direction_name<const D: usize>(n: &Vect<D>) -> String {
    for a in 0..D {
        if (n[a].abs() - 1.0).abs() < 1e-9 {
            let sign = if n[a] > 0.0 { "+" } else { "-" };
            return format!("{sign}{}", ["x", "y", "z"][a]);
        }
    }
    format!("{:?}", n.as_slice())
}

/// Where the face is, in the scene's words ("x = 0.25 m" for a face normal to x).
pub fn face_name<const D: usize>(f: &Face<D>) -> String {
    for a in 0..D {
        if (f.normal[a].abs() - 1.0).abs() < 1e-9 {
            let c = f.offset * f.normal[a];
            return format!("{} = {} m", ["x", "y", "z"][a], fmt_coord(c));
        }
    }
    format!(
        "normal {:?} at offset {} m",
        f.normal.as_slice(),
        fmt_coord(f.offset)
    )
}

/// A coordinate with its round-off cleaned (12 significant digits).
fn fmt_coord(c: f64) -> String {
    let v: f64 = format!("{c:.12e}").parse().unwrap_or(c);
    let v = if v == 0.0 { 0.0 } else { v };
    format!("{v}")
}

/// Checks a group's mirror face against the face between the group and its body: the group
/// touches its body on one plane face, the given normal is that face's normal (either sign)
/// and the given point lies on it. Err: what is wrong, in the scene's terms.
pub fn check_mirror<const D: usize>(
    found: &GroupFaces<D>,
    point: &Vect<D>,
    normal: &Vect<D>,
    l0: f64,
) -> Result<(), String> {
    let faces = &found.faces;
    let Some(first) = faces.first() else {
        return Err("the group touches no free particle of its body, so it has no face to mirror across (put its layers beside the body's face: a box of 2-3 layers behind it, over the body's section)".into());
    };
    if faces.len() > 1 {
        let list: Vec<String> = faces
            .iter()
            .map(|f| format!("{} (normal {})", face_name(f), direction_name(&f.normal)))
            .collect();
        let opposite = faces
            .iter()
            .any(|f| f.normal.dot(&first.normal) < -1.0 + 1e-9);
        return Err(if opposite {
            format!(
                "the group has free particles of its body on both sides ({}): it sits inside the body, where a mirror face would cut it; a mirror ends the body, so put the group at an end (or remove the mirror: a clamp needs none)",
                list.join(", ")
            )
        } else {
            format!(
                "the group touches its body on more than one face ({}); a mirror needs one plane face (remove the mirror: a clamp needs none)",
                list.join(", ")
            )
        });
    }
    let len = normal.norm();
    if !(len.is_finite() && len > 0.0) {
        return Err("the normal must be finite and not zero".into());
    }
    let n = normal / len;
    if n.dot(&first.normal).abs() < 1.0 - 1e-9 {
        return Err(format!(
            "the normal {:?} is not the normal of the face between the group and its body, which is {} ({}); give a normal along {}",
            normal.as_slice(),
            direction_name(&first.normal),
            face_name(first),
            direction_name(&first.normal)
        ));
    }
    let off = point.dot(&first.normal) - first.offset;
    if off.abs() > TOL * l0 {
        return Err(format!(
            "the point {:?} is {} m ({:.3} particle spacings) off the face between the group and its body, which is at {}; put the point on that face",
            point.as_slice(),
            fmt_coord(off.abs()),
            off.abs() / l0,
            face_name(first)
        ));
    }
    Ok(())
}

/// Why a support was not read as a mirror face: its layers are too shallow for the stencil
/// (`layers` deep behind the face, `needed` reached), or anything else (its meaning as
/// material with the axes held is then the scene's, and no warning of its own is due).
#[derive(Clone, Debug, PartialEq)]
pub enum SupportFace {
    /// Read as a mirror face (the face's name in the scene's words).
    Mirror(String),
    /// Layers beyond one face, fewer than the stencil reaches (the face's name, the layers,
    /// the layers needed).
    Shallow(String, usize, usize),
    /// Not a support on one whole face (the reason).
    NotAFace(String),
}

/// Mirror faces of the supports written without a `mirror` field (issue 24): a group holding
/// some axes but not all (`eligible[g]`) whose members fill the lattice sites beyond one plane
/// face of its body, as the images of the body's particles there, mirrors the body across
/// that face, exactly as if the scene had given the face (`MirrorFace`): wall layers behind the
/// face or the body's own end layers. Accepted only where that reading is the whole truth:
/// the group touches its body on one lattice face; its members all lie beyond the face at the
/// images of free particles of the body; every bond of a free particle that crosses the face
/// ends on a member; every bond of a free particle into the body, reflected across the face,
/// that ends beyond it ends on a member (the layers are as deep as the stencil reaches);
/// every free particle of the first layer at the face has a member at its lattice neighbour
/// across it (the group covers the whole face); and no free particle of the body lies beyond
/// the face. Otherwise (a layer on the face, a support on part of a face, a group inside the
/// body) the group keeps its meaning of material particles with those axes held. Returns per
/// eligible group the face (point, unit normal) or why not.
#[allow(clippy::type_complexity)]
pub(super) fn infer_support_faces<const D: usize>(
    p: &Particles<D>,
    bonds: &Bonds<D>,
    l0: f64,
    group_of: &[u32],
    eligible: &[bool],
) -> Vec<(usize, Result<(Vect<D>, Vect<D>), SupportFace>)>
where
    Space: Dim<D>,
{
    let key =
        |x: &Vect<D>| -> Vec<i64> { x.iter().map(|c| (c / l0 * 4.0).round() as i64).collect() };
    let mut out = Vec::new();
    for (g, _) in eligible.iter().enumerate().filter(|(_, e)| **e) {
        let not = |why: &str| Err(SupportFace::NotAFace(why.into()));
        let found = group_faces(p, bonds, l0, group_of, g as u32);
        let [face] = found.faces[..] else {
            out.push((g, not("it touches its body on no face or on several")));
            continue;
        };
        let (e, offset) = (face.normal, face.offset);
        let members: Vec<usize> = (0..p.len()).filter(|&i| group_of[i] == g as u32).collect();
        let body = p.body[members[0]];
        let free = |i: usize| group_of[i] == u32::MAX && p.body[i] == body;
        let free_at: HashMap<Vec<i64>, usize> = (0..p.len())
            .filter(|&i| free(i))
            .map(|i| (key(&p.x0[i]), i))
            .collect();
        let members_at: HashMap<Vec<i64>, usize> =
            members.iter().map(|&m| (key(&p.x0[m]), m)).collect();
        let image_of_free = |x: &Vect<D>| {
            let image = x - e * (2.0 * (x.dot(&e) - offset));
            free_at
                .get(&key(&image))
                .is_some_and(|&m| (p.x0[m] - image).norm() < TOL * l0)
        };
        let member_at = |x: &Vect<D>| {
            members_at
                .get(&key(x))
                .is_some_and(|&j| (p.x0[j] - x).norm() < TOL * l0)
        };
        // Layers beyond the face: of the group, and reached by the reflected stencils.
        let layer = |x: &Vect<D>| ((x.dot(&e) - offset) / l0 + 0.5).round() as usize;
        let layers = members.iter().map(|&m| layer(&p.x0[m])).max().unwrap_or(0);
        let mut needed = 0usize;
        let mut missing = false;
        let mut why: Option<&str> = None;
        if !members
            .iter()
            .all(|&m| p.body[m] == body && image_of_free(&p.x0[m]))
        {
            why = Some("its particles are not all at the images of the body's across the face");
        }
        for i in (0..p.len()).filter(|&i| free(i)) {
            if why.is_some() {
                break;
            }
            let depth = p.x0[i].dot(&e) - offset;
            if depth > -TOL * l0 {
                why = Some("the body has particles beyond the face");
                break;
            }
            for b in bonds.of(i) {
                let j = bonds.nbr[b] as usize;
                let r = bonds.r0[b];
                if p.x0[j].dot(&e) > offset {
                    if group_of[j] != g as u32 {
                        why = Some("another group's particles are beyond the face");
                    }
                } else if free(j) {
                    let s = p.x0[i] + r - e * (2.0 * r.dot(&e));
                    if s.dot(&e) > offset {
                        needed = needed.max(layer(&s));
                        missing |= !member_at(&s);
                    }
                }
            }
            if (depth + 0.5 * l0).abs() < TOL * l0
                && bond_to(bonds, i, &(e * l0), l0).is_none_or(|j| group_of[j] != g as u32)
            {
                why = Some("it covers part of the face only");
            }
        }
        out.push((
            g,
            match why {
                Some(w) => not(w),
                None if missing => Err(SupportFace::Shallow(face_name(&face), layers, needed)),
                None => Ok((e * offset, e)),
            },
        ));
    }
    out
}
