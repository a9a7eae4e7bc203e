//! The first-order shape tensor K_i = sum_j w0/|r0|^2 r0 r0^T of a particle's intact bonds and
//! its pseudo-inverse: the corrected operator's gradient, and the second-order operator's
//! fallback for a particle whose quadratic fit is cut or ill-conditioned.
use super::bonds::Bonds;
use super::dim::{sym_pinv_above, Mat};

/// Smallest eigenvalue of a shape tensor, relative to its largest, along which a particle's
/// bonds measure strain; directions below it are outside the neighbourhood's span (the span
/// projector drops them, as for a single layer of particles).
///
/// Why (issue 7, `tests/energy_fracture.rs`): a particle that lost most of its bonds on one
/// side keeps a direction only a few nearly perpendicular bonds reach. With the round-off
/// threshold (1e-10) K^-1 amplified the bonds' motion along it without bound and the re-fit at
/// the break raised the particle's strain energy (25 J -> 70 J at fixed positions on two broken
/// pairs of the small2d impact; +16 % to +21 % total energy below the automatic step). Intact
/// lattice neighbourhoods are far above it: their smallest ratio is 0.57 in 2D and 0.47 in 3D
/// (blocks and plates two particles thick,
/// `tests/energy_fracture.rs::intact_neighbourhoods_keep_their_full_span`); 0.01 and 0.05 both
/// stop the energy creation of the impacts (0.2 cuts directions that still carry strain and
/// creates energy again: +11 % at the automatic step), 0.05 with the larger margin.
pub const SHAPE_MIN_CONDITION: f64 = 0.05;

/// Pseudo-inverse of a shape tensor with the directions below [`SHAPE_MIN_CONDITION`] dropped.
pub fn shape_pinv<const D: usize>(k: &Mat<D>) -> Mat<D> {
    sym_pinv_above(k, SHAPE_MIN_CONDITION)
}

/// Shape tensor K_i = sum_j w0/|r0|^2 r0 r0^T over the intact bonds, formed with the same
/// expression as the deformation-gradient sum, so that F = G K^-1 is the identity to round-off
/// in the reference state.
pub fn shape_tensor<const D: usize>(bonds: &Bonds<D>, i: usize) -> Mat<D> {
    let mut k = Mat::<D>::zeros();
    for b in bonds.of(i) {
        let w0 = bonds.w0[b];
        if w0 == 0.0 {
            continue;
        }
        let r0 = bonds.r0[b];
        k += (r0 * (w0 / r0.norm_squared())) * r0.transpose();
    }
    k
}
