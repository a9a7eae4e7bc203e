//! The key under which a set-up keeps the closure for the next one (`world::SetupMemo`): a hash
//! of everything [`super::close`] reads, so that a kept closure is taken only for the geometry
//! it was computed for.
use std::hash::Hasher;

use super::BodyFaces;
use crate::physics::bonds::Bonds;
use crate::physics::dim::{Dim, Space, Vect};
use crate::physics::second_order::SecondOrder;

fn vect<const D: usize>(h: &mut impl Hasher, v: &Vect<D>) {
    for c in v.iter() {
        h.write_u64(c.to_bits());
    }
}

/// Hash of the closure's inputs: the reference positions and bodies, the bonds and their
/// weights, the bodies' faces and names, the spacing and stencil radius, and what the
/// second-order operator's set-up decided before the closure (rigid and wall particles,
/// mirror ghosts, clamp followers). The fits the closure also reads follow from these. Not
/// the materials, the step or the damping, which the closure does not depend on.
#[allow(clippy::too_many_arguments)]
pub fn key<const D: usize>(
    x0: &[Vect<D>],
    faces: &[BodyFaces<D>],
    body: &[u32],
    bonds: &Bonds<D>,
    so: &SecondOrder<D>,
    l0: f64,
    re_factor: f64,
    names: &[&str],
) -> u64
where
    Space: Dim<D>,
{
    let mut h = rustc_hash::FxHasher::default();
    h.write_usize(D);
    h.write_u64(l0.to_bits());
    h.write_u64(re_factor.to_bits());
    h.write_usize(x0.len());
    x0.iter().for_each(|x| vect(&mut h, x));
    body.iter().for_each(|&b| h.write_u32(b));
    bonds.start.iter().for_each(|&s| h.write_u32(s));
    bonds.nbr.iter().for_each(|&j| h.write_u32(j));
    bonds.w0.iter().for_each(|w| h.write_u64(w.to_bits()));
    for f in faces {
        match f {
            BodyFaces::Lattice => h.write_u8(0),
            BodyFaces::Box(lo, hi) => {
                h.write_u8(1);
                vect(&mut h, lo);
                vect(&mut h, hi);
            }
            BodyFaces::Other => h.write_u8(2),
        }
    }
    for n in names {
        h.write(n.as_bytes());
        h.write_u8(0xff);
    }
    so.rigid.iter().for_each(|&r| h.write_u8(r as u8));
    so.walls.iter().for_each(|&w| h.write_u8(w as u8));
    h.write_usize(so.ghosts.len());
    for g in &so.ghosts {
        h.write_u32(g.ghost);
        h.write_u32(g.master);
        vect(&mut h, &g.parity);
    }
    h.write_usize(so.followers.len());
    for f in &so.followers {
        h.write_u32(f.particle);
        h.write_u32(f.wall);
        h.write_u32(f.inner[0]);
        h.write_u32(f.inner[1]);
    }
    h.finish()
}
