//! The key under which a set-up keeps the closure for the next one (`world::SetupMemo`): a hash
//! of everything [`super::close`] reads, so that a kept closure is taken only for the geometry
//! it was computed for.
use std::hash::Hasher;

use super::{BodyFaces, Closure, ClosureInputs};
use crate::physics::dim::{Dim, Space, Vect};

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
pub fn key<const D: usize>(input: &ClosureInputs<'_, D>) -> u64
where
    Space: Dim<D>,
{
    let (x0, bonds, so) = (input.x0, input.bonds, input.so);
    let mut h = rustc_hash::FxHasher::default();
    h.write_usize(D);
    h.write_u64(input.l0.to_bits());
    h.write_u64(input.re_factor.to_bits());
    h.write_usize(x0.len());
    x0.iter().for_each(|x| vect(&mut h, x));
    input.body.iter().for_each(|&b| h.write_u32(b));
    bonds.start.iter().for_each(|&s| h.write_u32(s));
    bonds.nbr.iter().for_each(|&j| h.write_u32(j));
    bonds.w0.iter().for_each(|w| h.write_u64(w.to_bits()));
    for f in input.faces {
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
    for n in input.names {
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

/// Whether a kept closure can serve these inputs as they index it (checked before it is
/// indexed: one read from a file may be of another model whose geometry hashed alike, or
/// crafted): one volume and one set per particle, volumes positive, the sets well formed,
/// each particle's row D values per bond, one report per body, complete.
pub fn fits<const D: usize>(cl: &Closure<D>, input: &ClosureInputs<'_, D>) -> bool
where
    Space: Dim<D>,
{
    let n = input.x0.len();
    cl.vol.len() == n
        && cl.vol.iter().flatten().all(|v| v.is_finite() && *v > 0.0)
        && cl.dg.class.len() == n
        && cl.dg.well_formed()
        && (0..n).all(|i| {
            cl.dg
                .get(i)
                .is_none_or(|row| row.len() == input.bonds.of(i).len() * D)
        })
        && cl.report.len() == input.names.len()
        && cl.interrupted.is_none()
}

/// Start of a closure written to bytes (`mps pack` ships one in the FMU's resources).
const MAGIC: &[u8; 12] = b"mps-closure\n";
/// Version of the layout below.
const FORMAT: u32 = 1;
/// Most bytes a closure may take (a 10^6-particle body's takes about 30 MB).
const MAX_BYTES: u64 = 1 << 32;

fn options() -> impl bincode::Options {
    use bincode::Options;
    bincode::DefaultOptions::new()
        .with_fixint_encoding()
        .with_little_endian()
        .with_limit(MAX_BYTES)
}

/// A closure and its key as bytes: magic, format, dimension, key, the payload's length and
/// CRC-32, then the closure (bincode).
pub fn to_bytes<const D: usize>(key: u64, closure: &Closure<D>) -> Option<Vec<u8>> {
    use bincode::Options;
    let payload = options().serialize(closure).ok()?;
    let mut out = Vec::with_capacity(payload.len() + 40);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT.to_le_bytes());
    out.extend_from_slice(&(D as u32).to_le_bytes());
    out.extend_from_slice(&key.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    Some(out)
}

/// The dimension and key of closure bytes, and the payload, checked (magic, format, length,
/// CRC-32); what is wrong otherwise.
pub fn header(bytes: &[u8]) -> Result<(usize, u64, &[u8]), String> {
    let take = |at: usize, n: usize| bytes.get(at..at + n).ok_or("it is truncated");
    if take(0, 12)? != MAGIC {
        return Err("it is not a closure written by mps".into());
    }
    let u32_at = |at| take(at, 4).map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")));
    let u64_at = |at| take(at, 8).map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")));
    let format = u32_at(12)?;
    if format != FORMAT {
        return Err(format!(
            "its format is {format}, this library reads {FORMAT}"
        ));
    }
    let dim = u32_at(16)? as usize;
    let key = u64_at(20)?;
    let len = u64_at(28)?;
    let crc = u32_at(36)?;
    let payload = bytes.get(40..).ok_or("it is truncated")?;
    if payload.len() as u64 != len {
        return Err(format!(
            "it holds {} bytes of closure where its header says {len}",
            payload.len()
        ));
    }
    if crc32fast::hash(payload) != crc {
        return Err("its checksum does not match (the file is damaged)".into());
    }
    Ok((dim, key, payload))
}

/// The closure of a payload checked by [`header`].
pub fn from_payload<const D: usize>(payload: &[u8]) -> Result<Closure<D>, String> {
    use bincode::Options;
    options()
        .deserialize(payload)
        .map_err(|e| format!("it cannot be read: {e}"))
}

#[cfg(test)]
mod tests {
    use super::super::Closure;
    use super::*;
    use crate::physics::stencils::Stencils;

    #[test]
    fn any_payload_is_read_or_refused_without_a_panic() {
        // An FMU's closure file is input: bytes that pass the checksum but were written by
        // something else must be refused (or read into sets the set-up then checks), never
        // crash the host. Every single-byte change and every truncation of a small closure.
        let mut dg = Stencils::<3>::with_particles(4);
        dg.set(0, &[1.0, 2.0, 3.0]);
        dg.set(2, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        let c = Closure::<3> {
            vol: vec![Some(1e-6), None, Some(2e-6), None],
            dg,
            report: vec![Ok("closed".into()), Err("not".into())],
            interrupted: None,
        };
        let bytes = to_bytes(7, &c).unwrap();
        let (dim, key, payload) = header(&bytes).unwrap();
        assert_eq!((dim, key), (3, 7));
        let back = from_payload::<3>(payload).unwrap();
        assert_eq!(back.vol, c.vol);
        assert!(back.dg.well_formed());
        let mut read = 0;
        for at in 0..payload.len() {
            for v in [0u8, 1, 0x7f, 0x80, 0xff] {
                let mut p = payload.to_vec();
                p[at] = v;
                if let Ok(cl) = from_payload::<3>(&p) {
                    read += 1;
                    let _ = cl.dg.well_formed();
                }
            }
            assert!(from_payload::<3>(&payload[..at]).is_err());
        }
        assert!(read > 0, "some changes (of values) must still read");
    }
}
