//! Strain energy laws of the energy operators (corrected, second-order): the energy density W and
//! the second Piola-Kirchhoff stress S = dW/dE of the Green strain E, for Saint Venant-Kirchhoff
//! and a compressible neo-Hookean law (docs/model.md, "Material law").
//!
//! E is the operator's Green strain in the span of the particle's intact bonds,
//! `E = (F^T F - P) / 2` (P = I for a full neighbourhood), so `C = I + 2E` is the right
//! Cauchy-Green tensor with the directions the bonds do not reach left unstretched. A 2D body is
//! in plane strain: its out-of-plane stretch is 1, so I1 counts a 1 for it and J = det C^(1/2) is
//! the in-plane area ratio. Everything is written in E, never as `C - I`, so that a small strain
//! has no cancellation (the linearised analyses difference forces at strains of 1e-6).
use super::dim::Mat;
use super::params::MaterialLaw;

/// Principal stretch below which the Saint Venant-Kirchhoff law loses stability (-): in uniaxial
/// stress S11 is linear in E11 = (lambda^2 - 1) / 2 for any nu, so the first Piola-Kirchhoff
/// stress `P11 = lambda S11` is proportional to `lambda^3 - lambda`, extremal at
/// `lambda = 1/sqrt(3)`; beyond it a further compression takes less force.
pub const SVK_STABLE_STRETCH: f64 = 0.577_350_269_189_625_8;

/// Determinant of a 2x2 or 3x3 matrix.
pub fn det<const D: usize>(m: &Mat<D>) -> f64 {
    match D {
        1 => m[(0, 0)],
        2 => m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)],
        3 => {
            m[(0, 0)] * (m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)])
                - m[(0, 1)] * (m[(1, 0)] * m[(2, 2)] - m[(1, 2)] * m[(2, 0)])
                + m[(0, 2)] * (m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)])
        }
        _ => unreachable!("the solver is 2D or 3D"),
    }
}

/// Adjugate of a 2x2 or 3x3 matrix (`adj(A) A = det(A) I`).
fn adjugate<const D: usize>(m: &Mat<D>) -> Mat<D> {
    let mut a = Mat::<D>::zeros();
    match D {
        1 => a[(0, 0)] = 1.0,
        2 => {
            a[(0, 0)] = m[(1, 1)];
            a[(1, 1)] = m[(0, 0)];
            a[(0, 1)] = -m[(0, 1)];
            a[(1, 0)] = -m[(1, 0)];
        }
        3 => {
            for r in 0..3 {
                for c in 0..3 {
                    // Cofactor of (c, r): rows other than c, columns other than r, cyclic.
                    let (r1, r2) = ((c + 1) % 3, (c + 2) % 3);
                    let (c1, c2) = ((r + 1) % 3, (r + 2) % 3);
                    a[(r, c)] = m[(r1, c1)] * m[(r2, c2)] - m[(r1, c2)] * m[(r2, c1)];
                }
            }
        }
        _ => unreachable!("the solver is 2D or 3D"),
    }
    a
}

/// `det(I + 2E) - 1` summed from the invariants of `A = 2E`, exact to round-off of E itself:
/// 2D `tr A + det A`, 3D `tr A + (tr(A)^2 - tr(A^2)) / 2 + det A`.
pub fn det_c_minus_one<const D: usize>(e: &Mat<D>) -> f64 {
    let a = e * 2.0;
    let tr = a.trace();
    match D {
        1 => tr,
        2 => tr + det(&a),
        3 => tr + 0.5 * (tr * tr - (a * a).trace()) + det(&a),
        _ => unreachable!("the solver is 2D or 3D"),
    }
}

/// Smallest principal stretch of `C = I + 2E` (-): the smallest singular value of F in the span
/// of the bonds (1 in the directions they do not reach).
pub fn smallest_stretch<const D: usize>(e: &Mat<D>) -> f64 {
    let c = Mat::<D>::identity() + e * 2.0;
    let (ev, _) = super::dim::sym_eigen(&c);
    ev.iter()
        .fold(f64::INFINITY, |a, &b| a.min(b))
        .max(0.0)
        .sqrt()
}

impl MaterialLaw {
    /// Name of the law as a scene writes it (`material.law`).
    pub fn name(self) -> &'static str {
        match self {
            MaterialLaw::SaintVenantKirchhoff => "saint_venant_kirchhoff",
            MaterialLaw::NeoHookean => "neo_hookean",
        }
    }

    /// Second Piola-Kirchhoff stress S = dW/dE (Pa) of the Green strain `e`, with the shear
    /// modulus `mu` and Lame's `lambda` (Pa). None when the state has no energy: `det C <= 0`
    /// (collapsed to zero area or volume) for the neo-Hookean law; Saint Venant-Kirchhoff is
    /// defined everywhere.
    ///
    /// * Saint Venant-Kirchhoff, Eqs. (6)-(7) at finite strain: `S = 2 mu E + lambda tr(E) I`.
    /// * neo-Hookean (docs/model.md, Eq. (NH2)):
    ///   `S = 2 mu J^(-2/3) C^-1 (E - tr(E)/3 I) + K/2 (J^2 - 1) C^-1`, `K = lambda + 2 mu / 3`,
    ///   which is `mu J^(-2/3) (I - I1/3 C^-1) + K/2 (J^2 - 1) C^-1` written without cancellation.
    #[inline(always)]
    pub fn stress<const D: usize>(self, e: &Mat<D>, mu: f64, lambda: f64) -> Option<Mat<D>> {
        match self {
            MaterialLaw::SaintVenantKirchhoff => {
                Some(e * (2.0 * mu) + Mat::<D>::identity() * (lambda * e.trace()))
            }
            MaterialLaw::NeoHookean => {
                let dc = det_c_minus_one(e);
                let det_c = 1.0 + dc;
                if det_c.is_nan() || det_c <= 0.0 {
                    return None;
                }
                let c = Mat::<D>::identity() + e * 2.0;
                let c_inv = adjugate(&c) / det_c;
                // J^(-2/3) = det C^(-1/3).
                let j23 = (-dc.ln_1p() / 3.0).exp();
                let k = lambda + 2.0 * mu / 3.0;
                let dev = e - Mat::<D>::identity() * (e.trace() / 3.0);
                let s = c_inv * dev * (2.0 * mu * j23) + c_inv * (0.5 * k * dc);
                // C^-1 commutes with E: S is symmetric up to round-off, made exact.
                Some((s + s.transpose()) * 0.5)
            }
        }
    }

    /// Strain energy density W (J/m^3, Pa) of the Green strain `e`; None where `stress` is.
    ///
    /// * Saint Venant-Kirchhoff: `W = mu E:E + lambda/2 tr(E)^2`.
    /// * neo-Hookean (docs/model.md, Eq. (NH1)):
    ///   `W = mu/2 (J^(-2/3) I1 - 3) + K/4 (J^2 - 1 - 2 ln J)`, `I1 = tr C + 3 - d` (plane strain
    ///   counts the unit out-of-plane stretch).
    #[inline(always)]
    pub fn energy<const D: usize>(self, e: &Mat<D>, mu: f64, lambda: f64) -> Option<f64> {
        match self {
            MaterialLaw::SaintVenantKirchhoff => {
                Some(mu * e.component_mul(e).sum() + 0.5 * lambda * e.trace().powi(2))
            }
            MaterialLaw::NeoHookean => {
                let dc = det_c_minus_one(e);
                if dc.is_nan() || 1.0 + dc <= 0.0 {
                    return None;
                }
                let ln_c = dc.ln_1p();
                // J^(-2/3) I1 - 3 = 3 (J^(-2/3) - 1) + 2 tr(E) J^(-2/3), I1 = 3 + 2 tr(E).
                let g = (-ln_c / 3.0).exp_m1();
                let k = lambda + 2.0 * mu / 3.0;
                // J^2 - 1 - 2 ln J = dc - ln(1 + dc).
                Some(0.5 * mu * (3.0 * g + 2.0 * e.trace() * (1.0 + g)) + 0.25 * k * (dc - ln_c))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    /// A deformation gradient with rotation, shear and volume change.
    fn sample_f() -> Matrix3<f64> {
        Matrix3::new(1.1, 0.2, -0.05, -0.1, 0.9, 0.15, 0.07, -0.12, 1.05)
    }

    fn green(f: &Matrix3<f64>) -> Matrix3<f64> {
        (f.transpose() * f - Matrix3::identity()) * 0.5
    }

    #[test]
    fn stress_is_the_derivative_of_the_energy() {
        // S = dW/dE, checked by central differences of W over symmetric perturbations of E
        // (dE_ab = dE_ba = h / 2 off the diagonal, so dW = S_ab h). Central differences leave
        // h^2 W''' / 6 ~ 1e-12 relative at h = 1e-6; round-off adds eps W / h ~ 1e-10.
        let (mu, lambda) = (1.0e6, -0.5e6);
        for law in [MaterialLaw::SaintVenantKirchhoff, MaterialLaw::NeoHookean] {
            let e = green(&sample_f());
            let s = law.stress(&e, mu, lambda).unwrap();
            let h = 1e-6;
            for a in 0..3 {
                for b in 0..3 {
                    let mut d = Matrix3::zeros();
                    d[(a, b)] += 0.5 * h;
                    d[(b, a)] += 0.5 * h;
                    let w = |x: f64| law.energy(&(e + d * x), mu, lambda).unwrap();
                    let fd = (w(1.0) - w(-1.0)) / (2.0 * h);
                    let want = if a == b {
                        s[(a, a)]
                    } else {
                        s[(a, b)] + s[(b, a)]
                    };
                    let want = if a == b { want } else { 0.5 * want };
                    assert!(
                        (fd - want).abs() < 1e-8 * mu,
                        "{law:?} S[{a}{b}]: {fd} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn laws_agree_at_small_strain_and_differ_in_compression() {
        // Both laws have the small-strain limit 2 mu e + lambda tr(e) I: at a strain of 1e-7 they
        // differ by O(strain^2) relative, i.e. 1e-7 of the stress, 1e-6 is the bound.
        let (mu, lambda) = (1.0e6, 1.5e6);
        let e = green(&sample_f()) * 1e-6;
        let s0 = MaterialLaw::SaintVenantKirchhoff
            .stress(&e, mu, lambda)
            .unwrap();
        let s1 = MaterialLaw::NeoHookean.stress(&e, mu, lambda).unwrap();
        assert!((s1 - s0).amax() < 1e-6 * s0.amax(), "{s0} {s1}");
        // At rest: exactly zero stress and energy.
        let z = Matrix3::zeros();
        for law in [MaterialLaw::SaintVenantKirchhoff, MaterialLaw::NeoHookean] {
            assert_eq!(law.stress(&z, mu, lambda).unwrap(), z);
            assert_eq!(law.energy(&z, mu, lambda).unwrap(), 0.0);
        }
        // Collapsed to zero volume: SVK has finite energy, the neo-Hookean law none.
        let e = Matrix3::identity() * -0.5;
        assert!(MaterialLaw::SaintVenantKirchhoff
            .energy(&e, mu, lambda)
            .unwrap()
            .is_finite());
        assert!(MaterialLaw::NeoHookean.stress(&e, mu, lambda).is_none());
    }

    #[test]
    fn determinant_and_stretch_helpers() {
        let f = sample_f();
        let e = green(&f);
        let c = f.transpose() * f;
        assert!((det_c_minus_one(&e) - (c.determinant() - 1.0)).abs() < 1e-14);
        assert!((det(&f) - f.determinant()).abs() < 1e-15);
        let sv = f.singular_values().min();
        assert!((smallest_stretch(&e) - sv).abs() < 1e-12);
        assert!((SVK_STABLE_STRETCH - 1.0 / 3f64.sqrt()).abs() < 1e-16);
    }
}
