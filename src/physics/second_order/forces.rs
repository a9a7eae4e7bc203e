//! The force passes of the second-order operator (module `second_order`): pass 1 per particle
//! over its own bonds (the fit, the conjugates of its cell energy and of its bonds' residuals,
//! and dE/d du of each bond), pass 2 the gather of each particle's force, then the chain rule
//! through mirror ghosts and clamp followers. Pass 1 works on the stencils' packed weights.
use super::{
    basis_len, cell_term, lanes, law, pair, Cells, SecondOrder, SecondOrderScratch, FOLLOW,
};
use crate::par_iter_mut;
use crate::physics::bonds::Bonds;
use crate::physics::cpu_versions;
use crate::physics::dim::{Dim, Mat, Space, Vect};
#[allow(unused_imports)]
use crate::physics::par::*;
use crate::physics::params::MaterialLaw;
use crate::physics::particles::Particles;

impl<const D: usize> SecondOrder<D>
where
    Space: Dim<D>,
{
    /// Weights per bond in the stencils: D gradient and D (D + 1) / 2 Hessian values.
    pub(super) const NQ: usize = basis_len(D);

    /// Internal forces of the current state (one energy, gather form), with the per-body Lame
    /// constants and laws. `collapsed[i]` is set to 1 where the law has no energy at the
    /// particle's state (a collapsed or inverted neo-Hookean particle: its stress is taken as
    /// zero), to 0 elsewhere.
    pub fn forces(
        &self,
        p: &Particles<D>,
        bonds: &Bonds<D>,
        c: &Cells<D>,
        s: &mut SecondOrderScratch<D>,
        collapsed: &mut [u8],
        force: &mut [Vect<D>],
    ) {
        let n = p.len();
        s.grad.resize(n, Mat::<D>::zeros());
        let Cells {
            lame,
            laws,
            vol,
            moments,
            retained,
            volume,
            l0,
        } = *c;
        let derived = !self.ghosts.is_empty() || !self.followers.is_empty();
        if derived {
            s.ueff.clear();
            s.ueff.extend_from_slice(&p.u);
            for g in &self.ghosts {
                let (gi, mi) = (g.ghost as usize, g.master as usize);
                s.ueff[gi] = g.reflect(&p.u[gi], &p.u[mi]);
            }
            for fl in &self.followers {
                s.ueff[fl.particle as usize] = fl.follow(|j| p.u[j]);
            }
        }
        let uu: &[Vect<D>] = if derived { &s.ueff } else { &p.u };
        // Per-particle blocks of the per-bond output (safe disjoint borrows for the gather).
        let total = *self.pad_start.last().unwrap_or(&0) as usize;
        s.dbond.resize(total, 0.0);
        let mut slices: Vec<&mut [f64]> = Vec::with_capacity(n);
        let mut rest: &mut [f64] = &mut s.dbond;
        for i in 0..n {
            let len = (self.pad_start[i + 1] - self.pad_start[i]) as usize;
            let (head, tail) = rest.split_at_mut(len);
            slices.push(head);
            rest = tail;
        }
        // Pass 1, per particle i over its own bonds (their data stays in cache; module
        // `lanes`): H_i and G_i; the conjugates A = dE/dH_i and B = dE/dG_i from the cell energy
        // and the residuals of i's bonds; then dE/d du_b = A g_b + sum_a B^(a) h_b[a] + rho_b per
        // bond, and their sum.
        let ctx = Pass1 {
            p,
            bonds,
            uu,
            lame,
            laws,
            vol,
            moments,
            retained,
            volume,
            l0,
        };
        par_iter_mut!(s.grad)
            .zip(par_iter_mut!(slices))
            .zip(par_iter_mut!(collapsed))
            .enumerate()
            .for_each(|(i, ((gr, out), c_out))| pass1_particle(self, &ctx, i, gr, out, c_out));
        let dbond = &s.dbond;
        // Pass 2: f_i = sum_j (dE/d du_ij - dE/d du_ji), du_ij = u_j - u_i: the sum of the
        // particle's block less the reverse bonds' values.
        par_iter_mut!(force)
            .enumerate()
            .for_each(|(i, f_out)| *f_out = pass2_particle(self, bonds, dbond, i));
        // Chain rule through u_g(u_m, u_group): the master gets parity . f_g; the ghost keeps
        // what its group's motion is conjugate to, 2 f_g on the held (odd) axes, so that the
        // group's reaction (minus the sum over its members) is the force across the face.
        for g in &self.ghosts {
            let (gi, mi) = (g.ghost as usize, g.master as usize);
            let fg = force[gi];
            force[mi] += fg.component_mul(&g.parity);
            force[gi] =
                Vect::<D>::from_fn(|k, _| if g.parity[k] < 0.0 { 2.0 * fg[k] } else { 0.0 });
        }
        // Chain rule through the followers' constraint: their forces go to the layers they
        // follow and to the clamp (its reaction).
        for fl in &self.followers {
            let fi = force[fl.particle as usize];
            force[fl.wall as usize] += fi * FOLLOW[0];
            force[fl.inner[0] as usize] += fi * FOLLOW[1];
            force[fl.inner[1] as usize] += fi * FOLLOW[2];
            force[fl.particle as usize] = Vect::<D>::zeros();
        }
    }
}

cpu_versions! {
    /// Pass 2 of particle i: the sum of its block of `dbond` less its reverse bonds' values (compiled
    /// also for AVX-512 and AVX2, as pass 1; the same bits in every version).
    fn pass2_particle<const D: usize>(
        op: &SecondOrder<D>,
        bonds: &Bonds<D>,
        dbond: &[f64],
        i: usize,
    ) -> Vect<D>
    where
        Space: Dim<D>,
    {
        let block = &dbond[op.pad_start[i] as usize..op.pad_start[i + 1] as usize];
        let mut back = Vect::<D>::zeros();
        for &at in &op.mirror_pos[bonds.of(i)] {
            let at = at as usize;
            back += Vect::<D>::from_fn(|a, _| dbond[at + a * lanes::LANES]);
        }
        lanes::block_sum::<D>(block) - back
    }
}

/// What pass 1 reads besides the operator (the state and the cells' constants).
struct Pass1<'a, const D: usize>
where
    Space: Dim<D>,
{
    p: &'a Particles<D>,
    bonds: &'a Bonds<D>,
    /// Displacements, ghosts and followers derived.
    uu: &'a [Vect<D>],
    lame: &'a [(f64, f64)],
    laws: &'a [MaterialLaw],
    vol: &'a [f64],
    moments: &'a [(Vect<D>, Mat<D>)],
    retained: &'a [f64],
    volume: f64,
    l0: f64,
}

cpu_versions! {
    /// Pass 1 of particle i: its fit, the conjugates of its cell energy and of its bonds'
    /// residuals, and dE/d du of each of its bonds into `out` (its block of `dbond`) (issue 25: compiled also for AVX-512 and AVX2 and chosen at run time
    /// where the CPU has them; the bond loops of module `lanes` work on groups of bonds in vector
    /// registers with fused multiply-adds, exactly rounded, so every version gives the same results
    /// bit for bit). The fuzz targets (`cfg(fuzzing)`, set by cargo-fuzz) compile the baseline
    /// only: they test the logic, and the two more instrumented copies took 10 of the crate's 100
    /// CPU-s in their build.
    fn pass1_particle<const D: usize>(
        op: &SecondOrder<D>,
        ctx: &Pass1<D>,
        i: usize,
        gr: &mut Mat<D>,
        out: &mut [f64],
        c_out: &mut u8,
    ) where
        Space: Dim<D>,
    {
        let Pass1 { bonds, uu, .. } = *ctx;
        lanes::with_groups(
            op,
            bonds,
            i,
            |k| uu[k],
            |groups| pass1_groups(op, ctx, i, groups, gr, out, c_out),
        );
    }
}

/// Pass 1 of particle i on its bonds gathered in groups (module `lanes`).
#[inline(always)]
fn pass1_groups<const D: usize>(
    op: &SecondOrder<D>,
    ctx: &Pass1<D>,
    i: usize,
    groups: &[lanes::Group<D>],
    gr: &mut Mat<D>,
    out: &mut [f64],
    c_out: &mut u8,
) where
    Space: Dim<D>,
{
    let Pass1 {
        p,
        lame,
        laws,
        vol,
        moments,
        retained,
        volume,
        l0,
        ..
    } = *ctx;
    let quad = op.quadratic[i];
    // The fit in packed form (issue 25): m = [H | G] with G's symmetric pairs (a <= c, the
    // stencils' order), by groups of bonds (the energy fits the same way).
    let m = lanes::fit(op, i, groups);
    let h = Mat::<D>::from_fn(|r, c| m[r][c]);
    let g: [Mat<D>; D] =
        std::array::from_fn(|a| Mat::<D>::from_fn(|r, c| m[r][D + pair::<D>(a, c)]));
    *gr = h;
    *c_out = 0;
    if op.rigid[i] {
        out.iter_mut().for_each(|d| *d = 0.0);
        return;
    }
    let body = p.body[i] as usize;
    let (mu, lambda) = lame[body];
    let law = laws[body];
    let full = op.full[i];
    let f = op.span[i] + h;
    let e = SecondOrder::<D>::green(&h, &op.span[i], full);
    let stress = match law.stress(&e, mu, lambda) {
        // An inverted particle (det F <= 0) of a full neighbourhood has the same C
        // as a mirrored one: only F sees it.
        Some(s) if law == MaterialLaw::SaintVenantKirchhoff || !full || law::det(&f) > 0.0 => s,
        _ => {
            *c_out = 1;
            Mat::<D>::zeros()
        }
    };
    // dW/dH = dW/dF = F S (first Piola-Kirchhoff), times the cell volume.
    let mut a_i = f * stress * vol[i];
    let mut b_i = [Mat::<D>::zeros(); D];
    if quad && !op.closed.get(i).copied().unwrap_or(false) {
        cell_term::conjugates(
            &f,
            &g,
            &e,
            (mu, lambda),
            vol[i],
            moments.get(i),
            l0,
            &mut a_i,
            &mut b_i,
        );
    }
    // The conjugates packed as the weights: cj = [A | B] with B's symmetric pairs,
    // B_(k,(a,c)) = B^(a)_kc + B^(c)_ka (a < c), B^(a)_ka (a = c), so that
    // sum_a B^(a) h_b[a] = B w_b and dE/d du_b = cj w_b.
    let mut cj: lanes::Packed<D> = [[0.0f64; 9]; D];
    for (r, row) in cj.iter_mut().enumerate() {
        for c in 0..D {
            row[c] = a_i[(r, c)];
        }
        if quad {
            for a in 0..D {
                for c in a..D {
                    row[D + pair::<D>(a, c)] = if a == c {
                        b_i[a][(r, a)]
                    } else {
                        b_i[a][(r, c)] + b_i[c][(r, a)]
                    };
                }
            }
        }
    }
    let cres = volume * mu / op.n_ref[i].max(f64::MIN_POSITIVE);
    // The residual terms of each bond, evaluated once: their direct part goes to the bond's
    // output, their conjugate also into cj. With the basis phi = (r0, r0_a r0_c / (1 + [a =
    // c])) the residual is du - m phi and its conjugate rho enters cj as -rho phi^T (A -= rho
    // r0^T, B^(a) -= rho r0^T r0_a / 2). Then dE/d du_b += cj w_b, all times the retained share
    // (which scales the whole energy of the particle).
    lanes::bond_forces(op, i, groups, &m, cres, cj, retained[i], out);
}
