//! Set-up of the second-order operator's packed form (issue 25): the weights of each particle
//! interned by set (module `stencils`), each distinct quantised neighbourhood fitted once; and
//! the weights of a bond in either form.
use rustc_hash::FxHashMap;

use super::bonds::Bonds;
use super::dim::{Dim, Mat, Space, Vect};
use super::ghosts::{Follower, Ghost};
use super::second_order::{quantised, SecondOrder};
use super::stencils::Stencils;

/// Neighbourhood -> (set, geometry set, quadratic, full, span) of the quadratic fits seen so
/// far.
/// (FxHash: std's SipHash over the keys' hundred words was 12 % of a 10^6-particle fits stage.)
type Seen<const D: usize> = FxHashMap<Vec<u64>, (u32, u32, bool, bool, Mat<D>)>;

impl<const D: usize> SecondOrder<D>
where
    Space: Dim<D>,
{
    /// As [`SecondOrder::new`], in the packed form the force loop reads: each particle's
    /// weights interned by set (module `stencils`). A particle whose neighbourhood (the
    /// quantised reference vectors of its bonds in their order, which of them enter the fit)
    /// was seen before takes that particle's set without a new fit: on a lattice the fits are
    /// computed once per distinct neighbourhood, not once per particle.
    #[allow(clippy::too_many_arguments)]
    pub fn new_packed(
        bonds: &Bonds<D>,
        l0: f64,
        re_factor: f64,
        n: usize,
        rigid: &[bool],
        ghosts: &[Ghost<D>],
        followers: &[Follower],
        walls: &[bool],
    ) -> Self {
        let mut s = Self::flags(bonds, l0, re_factor, n, rigid, ghosts, followers, walls);
        s.packed = true;
        s.stencils = Stencils::with_particles(n);
        s.geometry = Stencils::with_particles(n);
        let mut values = Vec::new();
        let mut seen: Seen<D> = Default::default();
        let mut key = Vec::new();
        for i in 0..n {
            key.clear();
            let cut = bonds.of(i).any(|b| bonds.w0[b] == 0.0);
            key.push(u64::from(cut));
            // The set holds every bond's snapped vector and whether it is behind a clamp.
            for b in bonds.of(i) {
                let behind = s.behind[bonds.nbr[b] as usize];
                if s.weight(bonds, b) == 0.0 {
                    key.push(u64::MAX - u64::from(behind));
                }
                key.extend(quantised(&bonds.r0[b], l0).iter().map(|c| c.to_bits()));
            }
            if let Some(&(c, gc, quad, full, span)) = seen.get(&key) {
                s.stencils.class[i] = c;
                s.geometry.class[i] = gc;
                s.quadratic[i] = quad;
                s.full[i] = full;
                s.span[i] = span;
                continue;
            }
            s.refresh(bonds, l0, i);
            s.pack_geometry(bonds, l0, i, &mut values);
            s.geometry.set(i, &values);
            // The first-order fallback reads the unquantised reference vectors: not shared.
            if s.quadratic[i] {
                seen.insert(
                    key.clone(),
                    (
                        s.stencils.class[i],
                        s.geometry.class[i],
                        true,
                        s.full[i],
                        s.span[i],
                    ),
                );
            }
        }
        s.initial_class = s.stencils.class.clone();
        s
    }

    /// Gradient weight of bond b (of particle i) (1/m), in either form.
    pub fn grad_weight(&self, bonds: &Bonds<D>, i: usize, b: usize) -> Vect<D> {
        if self.packed {
            Stencils::<D>::g(self.stencils.of(i), b - bonds.of(i).start)
        } else {
            self.g[b]
        }
    }

    /// Hessian weight of bond b (of particle i) (1/m^2), in either form.
    pub fn hess_weight(&self, bonds: &Bonds<D>, i: usize, b: usize) -> Mat<D> {
        if self.packed {
            Stencils::<D>::h(self.stencils.of(i), b - bonds.of(i).start)
        } else {
            self.h[b]
        }
    }
}
