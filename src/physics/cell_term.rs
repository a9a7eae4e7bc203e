//! The cell term of the second-order operator's energy (module `second_order`): a particle's
//! energy density integrated over the solid it stands for beyond its centre value, from the
//! strain's derivatives e_a = d_a E = sym(F^T G^(a)) at the small-strain moduli. A whole lattice
//! cell adds l0^2 / 12 sum_a w(e_a) (issue 7); a particle of a body filled from a solid adds the
//! terms of its own first and second moments (issue 26, [`energy`]).
use super::dim::{Mat, Vect};
use super::params::MaterialLaw;

/// What the energy of a particle's cell needs besides the weights: per-body Lame constants
/// (mu, lambda in Pa) and laws, per-particle volume (m^d), cell moments per unit volume (m,
/// m^2; empty: whole lattice cells) and retained share, the particle volume l0^d of the
/// residual terms and the spacing l0 (m).
#[derive(Clone, Copy, Debug)]
pub struct Cells<'a, const D: usize> {
    pub lame: &'a [(f64, f64)],
    pub laws: &'a [MaterialLaw],
    pub vol: &'a [f64],
    pub moments: &'a [(Vect<D>, Mat<D>)],
    pub retained: &'a [f64],
    pub volume: f64,
    pub l0: f64,
}

/// Linear isotropic stress of a (symmetric) strain: 2 mu e + lambda tr(e) I.
#[inline(always)]
pub(super) fn lin_stress<const D: usize>(e: &Mat<D>, mu: f64, lambda: f64) -> Mat<D> {
    e * (2.0 * mu) + Mat::<D>::identity() * (lambda * e.trace())
}

/// w(x, y) = mu x : y + lambda / 2 tr x tr y: the small-strain energy density's bilinear form
/// (w(e, e) is the density of e).
#[inline(always)]
fn bilinear<const D: usize>(x: &Mat<D>, y: &Mat<D>, mu: f64, lambda: f64) -> f64 {
    mu * x.component_mul(y).sum() + 0.5 * lambda * x.trace() * y.trace()
}

/// e_a = sym(F^T G^(a)) (first order in the displacement: d_a E, objective).
#[inline(always)]
fn strain_derivative<const D: usize>(f: &Mat<D>, ga: &Mat<D>) -> Mat<D> {
    let ea = f.transpose() * ga;
    (ea + ea.transpose()) * 0.5
}

/// The cell term per unit volume of a particle with moments per unit volume (c1, c2) about
/// its centre: the energy density's Taylor expansion integrated over its solid, exact for a
/// quadratic density, int W = V [W + c1 . grad W + 1/2 c2 : grad grad W], with grad W and
/// grad grad W from the strain E and its derivatives e_a at the small-strain moduli (as the
/// whole cell's l0^2 / 12 term): sum_ab c2_ab w(e_a, e_b) + 2 sum_a c1_a w(E, e_a). A whole
/// cell (c1 = 0, c2 = l0^2 / 12 I) gives the lattice's l0^2 / 12 sum_a w(e_a). Why (issue 26):
/// with l0^2 / 12 at every particle of a curved body, its cut cells' solid was taken as whole
/// cells about their centres: the section of a round cantilever at 6 across came out 5.3 % too
/// stiff in bending (measured f1 +2.3 %, static tip -4.5 %).
fn moment_term<const D: usize>(
    m: &(Vect<D>, Mat<D>),
    e: &Mat<D>,
    es: &[Mat<D>; D],
    mu: f64,
    lambda: f64,
) -> f64 {
    let (c1, c2) = m;
    let mut t = 0.0;
    for a in 0..D {
        t += 2.0 * c1[a] * bilinear(e, &es[a], mu, lambda);
        for b in 0..D {
            t += c2[(a, b)] * bilinear(&es[a], &es[b], mu, lambda);
        }
    }
    t
}

/// Adds the cell term of a particle (J) to `total`: volume `vol` (m^d), deformation gradient
/// `f`, Hessians `g`, Green strain `e`, Lame constants (mu, lambda) (Pa), moments per unit
/// volume (None: a whole cell of side `l0`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn energy<const D: usize>(
    f: &Mat<D>,
    g: &[Mat<D>; D],
    e: &Mat<D>,
    (mu, lambda): (f64, f64),
    vol: f64,
    moments: Option<&(Vect<D>, Mat<D>)>,
    l0: f64,
    total: &mut f64,
) {
    match moments {
        None => {
            let cell = l0 * l0 / 12.0;
            for ga in g.iter() {
                let ea = strain_derivative(f, ga);
                let w = mu * ea.component_mul(&ea).sum() + 0.5 * lambda * ea.trace().powi(2);
                *total += vol * cell * w;
            }
        }
        Some(m) => {
            let es: [Mat<D>; D] = std::array::from_fn(|a| strain_derivative(f, &g[a]));
            *total += vol * moment_term(m, e, &es, mu, lambda);
        }
    }
}

/// Adds the cell term's conjugates to A = dE/dH (`a_i`) and sets B^(a) = dE/dG^(a) (`b_i`),
/// for the arguments of [`energy`]. Whole cell: d/dG^(a) of w(sym(F^T G)) = F sigma, d/dF =
/// G sigma. With moments: tau_a = dT/de_a = V (sum_b c2_ab sigma(e_b) + c1_a sigma(E)),
/// dT/dE = V sum_a c1_a sigma(e_a); then B^(a) = F tau_a, A += G^(a) tau_a + F dT/dE.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn conjugates<const D: usize>(
    f: &Mat<D>,
    g: &[Mat<D>; D],
    e: &Mat<D>,
    (mu, lambda): (f64, f64),
    vol: f64,
    moments: Option<&(Vect<D>, Mat<D>)>,
    l0: f64,
    a_i: &mut Mat<D>,
    b_i: &mut [Mat<D>; D],
) {
    match moments {
        None => {
            let vc = vol * (l0 * l0 / 12.0);
            for a in 0..D {
                let sig = lin_stress(&strain_derivative(f, &g[a]), mu, lambda);
                b_i[a] = f * sig * vc;
                *a_i += g[a] * sig * vc;
            }
        }
        Some((c1, c2)) => {
            let sig: [Mat<D>; D] =
                std::array::from_fn(|a| lin_stress(&strain_derivative(f, &g[a]), mu, lambda));
            let sig_e = lin_stress(e, mu, lambda);
            let mut dt_de = Mat::<D>::zeros();
            for a in 0..D {
                let mut tau = sig_e * c1[a];
                for (b, sb) in sig.iter().enumerate() {
                    tau += sb * c2[(a, b)];
                }
                tau *= vol;
                b_i[a] = f * tau;
                *a_i += g[a] * tau;
                dt_de += sig[a] * (vol * c1[a]);
            }
            *a_i += f * dt_de;
        }
    }
}
