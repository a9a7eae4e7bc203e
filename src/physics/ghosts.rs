//! Ghosts and followers of mirror faces: the particles whose displacement in the second-order
//! operator's fits derives from others' (a ghost reflects its master across the face, a
//! follower of a clamped face extrapolates the clamp's motion from the layers behind it), and
//! the weights of that extrapolation. Built by `world::mirror`, used by `second_order` and `sbp`.
use super::dim::Vect;

/// A group member at the mirror image of a free particle (its master) across a mirror face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ghost<const D: usize> {
    pub ghost: u32,
    pub master: u32,
    /// Per axis -1 (held by the group: odd, u_g = 2 u_group - u_m) or +1 (free: even, u_g = u_m).
    pub parity: Vect<D>,
}

impl<const D: usize> Ghost<D> {
    /// The ghost's displacement (or velocity) in the fits from its own prescribed value `own`
    /// (the group's motion) and its master's `master`.
    #[inline(always)]
    pub fn reflect(&self, own: &Vect<D>, master: &Vect<D>) -> Vect<D> {
        Vect::<D>::from_fn(|k, _| {
            if self.parity[k] < 0.0 {
                2.0 * own[k] - master[k]
            } else {
                master[k]
            }
        })
    }
}

/// Extrapolation to a face of the quadratic through the layers at l0/2, 3 l0/2, 5 l0/2 from it
/// (Lagrange weights at 0): the clamped face's term in the closure (module `sbp`).
pub const FACE_EXTRAPOLATION: [f64; 3] = [15.0 / 8.0, -5.0 / 4.0, 3.0 / 8.0];

/// Weights of a follower's displacement on (its clamp's motion, the second layer, the third
/// layer) along the face's normal: the values for which FACE_EXTRAPOLATION gives the clamp's
/// motion on the face (8/15, 2/3, -1/5).
pub const FOLLOW: [f64; 3] = [
    1.0 / FACE_EXTRAPOLATION[0],
    -FACE_EXTRAPOLATION[1] / FACE_EXTRAPOLATION[0],
    -FACE_EXTRAPOLATION[2] / FACE_EXTRAPOLATION[0],
];

/// Shares of a follower's mass that the second and third layer carry: the diagonal of the
/// constraint's mass matrix S^T M S (FOLLOW[1]^2, FOLLOW[2]^2), so that the followed layers'
/// stiffness, which the constraint raises by about those shares, has the inertia that goes with
/// it and the stable step does not shrink.
pub const LUMP: [f64; 2] = [FOLLOW[1] * FOLLOW[1], FOLLOW[2] * FOLLOW[2]];

/// A particle of the first layer at a clamped face: it follows the two layers behind it and the
/// clamp (its wall particle at the mirror image carries the clamp's motion and the reaction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Follower {
    pub particle: u32,
    /// The clamp's member at the particle's mirror image (its motion, its share of the reaction).
    pub wall: u32,
    /// The particles l0 and 2 l0 further in along the face's normal.
    pub inner: [u32; 2],
}

impl Follower {
    /// The follower's value of a field f (displacement or velocity).
    #[inline(always)]
    pub fn follow<T>(&self, f: impl Fn(usize) -> T) -> T
    where
        T: std::ops::Mul<f64, Output = T> + std::ops::Add<Output = T>,
    {
        f(self.wall as usize) * FOLLOW[0]
            + f(self.inner[0] as usize) * FOLLOW[1]
            + f(self.inner[1] as usize) * FOLLOW[2]
    }
}

#[cfg(test)]
mod tests {
    use super::{FACE_EXTRAPOLATION, FOLLOW};

    /// The face extrapolation is exact for quadratics through the layers at 1/2, 3/2, 5/2 (in
    /// l0) and the follower's weights invert it: both to round-off (1e-15).
    #[test]
    fn face_extrapolation_is_exact_for_quadratics_and_followers_invert_it() {
        let x = [0.5, 1.5, 2.5];
        for p in 0..3 {
            let at_face: f64 = FACE_EXTRAPOLATION
                .iter()
                .zip(x)
                .map(|(w, xi)| w * f64::powi(xi, p))
                .sum();
            let exact = if p == 0 { 1.0 } else { 0.0 };
            assert!((at_face - exact).abs() < 1e-15, "x^{p}: {at_face}");
        }
        // u_face = E0 u1 + E1 u2 + E2 u3 with u1 = F0 u_face + F1 u2 + F2 u3, for all u.
        let e = FACE_EXTRAPOLATION;
        assert!((e[0] * FOLLOW[0] - 1.0).abs() < 1e-15);
        assert!((e[0] * FOLLOW[1] + e[1]).abs() < 1e-15);
        assert!((e[0] * FOLLOW[2] + e[2]).abs() < 1e-15);
    }
}
