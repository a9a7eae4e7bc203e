//! What differs between 2D and 3D: the per-particle rotation (an angle or a unit quaternion), the
//! angular velocity (a scalar or a vector), cross products and the reference lattice.
use nalgebra::{Quaternion, SMatrix, SVector, UnitQuaternion, Vector3};
use serde::{de::DeserializeOwned, Serialize};
use std::fmt::Debug;

/// A position, velocity or force in `D` dimensions.
pub type Vect<const D: usize> = SVector<f64, D>;
/// A `D` x `D` matrix (deformation gradient, stress, shape tensor).
pub type Mat<const D: usize> = SMatrix<f64, D, D>;

/// Marker type on which the dimension-specific operations are implemented: `Space: Dim<2>` and
/// `Space: Dim<3>`. Everything else in the solver is written once, generic over `D`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Space;

/// The operations that differ between 2D and 3D.
pub trait Dim<const D: usize>: Send + Sync + 'static {
    /// Orientation of a particle: an angle (rad) in 2D, a unit quaternion in 3D.
    type Rotation: Copy + Send + Sync + Debug + PartialEq + Serialize + DeserializeOwned;
    /// Angular velocity (rad/s), moment (N m): a scalar about z in 2D, a vector in 3D.
    type Ang: Copy + Send + Sync + Debug + PartialEq + Serialize + DeserializeOwned;

    fn identity() -> Self::Rotation;
    fn ang_zero() -> Self::Ang;
    fn ang_add(a: Self::Ang, b: Self::Ang) -> Self::Ang;
    fn ang_scale(a: Self::Ang, s: f64) -> Self::Ang;
    fn ang_dot(a: Self::Ang, b: Self::Ang) -> f64;
    /// Components as a 3-vector (2D: (0, 0, w)), for output.
    fn ang_to3(a: Self::Ang) -> [f64; 3];
    /// Rotates a vector.
    fn rotate(q: &Self::Rotation, v: &Vect<D>) -> Vect<D>;
    /// The rotation half way between two orientations: Eq. (16) in 2D, the geodesic midpoint of
    /// the two quaternions in 3D (the 3D analogue of Eq. (16), see docs/model.md).
    fn midpoint(a: &Self::Rotation, b: &Self::Rotation) -> Self::Rotation;
    /// `rotate(midpoint(a, b), v)`: a vector turned by the rotation half way between two
    /// orientations, the pair rotation of Eqs. (13)-(16) applied to a reference bond.
    #[inline(always)]
    fn rotate_midpoint(a: &Self::Rotation, b: &Self::Rotation, v: &Vect<D>) -> Vect<D> {
        Self::rotate(&Self::midpoint(a, b), v)
    }
    /// Advances an orientation by a constant angular velocity over dt: Eq. (40) in 2D, the exact
    /// quaternion exponential in 3D (Eq. (21) composed with the increment).
    fn advance(q: &Self::Rotation, w: &Self::Ang, dt: f64) -> Self::Rotation;
    /// `r x f` (a scalar in 2D).
    fn cross(r: &Vect<D>, f: &Vect<D>) -> Self::Ang;
    /// Rotation angle (rad) of an orientation, for diagnostics.
    fn angle(q: &Self::Rotation) -> f64;
    /// Whether all components of the angular quantity are finite.
    fn ang_finite(a: &Self::Ang) -> bool;
    /// Inverse of a symmetric positive semi-definite matrix; the pseudo-inverse when it is
    /// (nearly) singular, e.g. the shape tensor of a particle in a single layer.
    fn sym_pinv(m: &Mat<D>) -> Mat<D>;
    /// Moment of inertia of a cubic (square) particle of side l0 and mass m about its centre.
    fn particle_inertia(mass: f64, l0: f64) -> f64 {
        mass * l0 * l0 / 6.0
    }
}

impl Dim<2> for Space {
    type Rotation = f64;
    type Ang = f64;
    fn identity() -> f64 {
        0.0
    }
    #[inline(always)]
    fn ang_zero() -> f64 {
        0.0
    }
    #[inline(always)]
    fn ang_add(a: f64, b: f64) -> f64 {
        a + b
    }
    #[inline(always)]
    fn ang_scale(a: f64, s: f64) -> f64 {
        a * s
    }
    #[inline(always)]
    fn ang_dot(a: f64, b: f64) -> f64 {
        a * b
    }
    fn ang_to3(a: f64) -> [f64; 3] {
        [0.0, 0.0, a]
    }
    // Eq. (15)
    #[inline(always)]
    fn rotate(q: &f64, v: &Vect<2>) -> Vect<2> {
        let (s, c) = q.sin_cos();
        Vect::<2>::new(c * v.x - s * v.y, s * v.x + c * v.y)
    }
    // Eq. (16)
    #[inline(always)]
    fn midpoint(a: &f64, b: &f64) -> f64 {
        0.5 * (a + b)
    }
    // Eq. (40)
    fn advance(q: &f64, w: &f64, dt: f64) -> f64 {
        q + dt * w
    }
    #[inline(always)]
    fn cross(r: &Vect<2>, f: &Vect<2>) -> f64 {
        r.x * f.y - r.y * f.x
    }
    fn angle(q: &f64) -> f64 {
        q.abs()
    }
    fn ang_finite(a: &f64) -> bool {
        a.is_finite()
    }
    fn sym_pinv(m: &Mat<2>) -> Mat<2> {
        sym_pinv_above::<2>(m, 1e-10)
    }
}

impl Dim<3> for Space {
    type Rotation = UnitQuaternion<f64>;
    type Ang = Vector3<f64>;
    fn identity() -> Self::Rotation {
        UnitQuaternion::identity()
    }
    #[inline(always)]
    fn ang_zero() -> Vector3<f64> {
        Vector3::zeros()
    }
    #[inline(always)]
    fn ang_add(a: Vector3<f64>, b: Vector3<f64>) -> Vector3<f64> {
        a + b
    }
    #[inline(always)]
    fn ang_scale(a: Vector3<f64>, s: f64) -> Vector3<f64> {
        a * s
    }
    #[inline(always)]
    fn ang_dot(a: Vector3<f64>, b: Vector3<f64>) -> f64 {
        a.dot(&b)
    }
    fn ang_to3(a: Vector3<f64>) -> [f64; 3] {
        [a.x, a.y, a.z]
    }
    // Eq. (17): the rotation matrix of the quaternion, applied to v.
    #[inline(always)]
    fn rotate(q: &Self::Rotation, v: &Vect<3>) -> Vect<3> {
        q.transform_vector(v)
    }
    #[inline(always)]
    fn midpoint(a: &Self::Rotation, b: &Self::Rotation) -> Self::Rotation {
        let (qa, mut qb) = (a.quaternion().coords, b.quaternion().coords);
        if qa.dot(&qb) < 0.0 {
            qb = -qb;
        }
        UnitQuaternion::new_normalize(Quaternion::from(qa + qb))
    }
    // The rotation of the unnormalised sum q = (s, w) of the two quaternions, divided by its
    // squared norm n: v + 2 [s (w x v) + w x (w x v)] / n, the normalised midpoint's rotation
    // without its square root (issue 25: the paper model's force loop turns every bond).
    #[inline(always)]
    fn rotate_midpoint(a: &Self::Rotation, b: &Self::Rotation, v: &Vect<3>) -> Vect<3> {
        let (qa, mut qb) = (a.quaternion().coords, b.quaternion().coords);
        if qa.dot(&qb) < 0.0 {
            qb = -qb;
        }
        // nalgebra's coords are (i, j, k, w).
        let q = qa + qb;
        let w = Vector3::new(q[0], q[1], q[2]);
        let t = w.cross(v) * (2.0 / q.norm_squared());
        v + t * q[3] + w.cross(&t)
    }
    // Eqs. (18)-(21): the increment is a rotation of |w| dt about w / |w|, composed on the left
    // (w is the angular velocity in the world frame).
    fn advance(q: &Self::Rotation, w: &Vector3<f64>, dt: f64) -> Self::Rotation {
        let inc = UnitQuaternion::from_scaled_axis(w * dt);
        UnitQuaternion::new_normalize((inc * q).into_inner())
    }
    #[inline(always)]
    fn cross(r: &Vect<3>, f: &Vect<3>) -> Vector3<f64> {
        r.cross(f)
    }
    fn angle(q: &Self::Rotation) -> f64 {
        q.angle()
    }
    fn ang_finite(a: &Vector3<f64>) -> bool {
        a.iter().all(|c| c.is_finite())
    }
    fn sym_pinv(m: &Mat<3>) -> Mat<3> {
        sym_pinv_above::<3>(m, 1e-10)
    }
}

/// Converts a vector to a fixed 3-array (2D: z = 0), for output and the FMI layer.
pub fn to3<const D: usize>(v: &Vect<D>) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate().take(D) {
        *o = v[k];
    }
    out
}

/// Builds a `D`-vector from the first `D` components of a 3-array.
pub fn from3<const D: usize>(a: [f64; 3]) -> Vect<D> {
    Vect::<D>::from_fn(|k, _| a[k])
}

/// Eigenvalues and orthonormal eigenvectors (columns) of a symmetric matrix by the cyclic
/// Jacobi method, which is accurate to round-off relative to the largest eigenvalue for any
/// symmetric input, including repeated eigenvalues with round-off off-diagonals.
///
/// nalgebra 0.33's `symmetric_eigen` is not used here: for a shape tensor with a double
/// eigenvalue and off-diagonal round-off of 1e-15 (the tensor of a surface particle of a body
/// a few metres from the origin) it returns eigenpairs that recompose to a matrix 3 % off
/// (nalgebra issue #1109), which made a body at rest carry stress depending on where it sat.
pub fn sym_eigen<const D: usize>(m: &Mat<D>) -> ([f64; D], Mat<D>) {
    let mut a = (m + m.transpose()) * 0.5;
    let mut v = Mat::<D>::identity();
    for _sweep in 0..32 {
        let off: f64 = (0..D)
            .flat_map(|p| (p + 1..D).map(move |q| (p, q)))
            .map(|(p, q)| a[(p, q)] * a[(p, q)])
            .sum();
        let diag: f64 = (0..D).map(|p| a[(p, p)] * a[(p, p)]).sum();
        if off == 0.0 || off <= 1e-36 * diag {
            break;
        }
        for p in 0..D {
            for q in p + 1..D {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                // Rotation angle that zeroes a[p][q] (Golub & Van Loan, Algorithm 8.4.1).
                let theta = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                let mut j = Mat::<D>::identity();
                j[(p, p)] = c;
                j[(q, q)] = c;
                j[(p, q)] = s;
                j[(q, p)] = -s;
                a = j.transpose() * a * j;
                a[(p, q)] = 0.0;
                a[(q, p)] = 0.0;
                v *= j;
            }
        }
    }
    (std::array::from_fn(|k| a[(k, k)]), v)
}

/// Pseudo-inverse of a symmetric positive semi-definite matrix from its Jacobi eigen
/// decomposition, keeping the eigen-directions whose eigenvalue exceeds `relative` times the
/// largest in magnitude (`Dim::sym_pinv`: 1e-10, round-off only). The result is symmetric.
pub fn sym_pinv_above<const D: usize>(m: &Mat<D>, relative: f64) -> Mat<D> {
    let (vals, vecs) = sym_eigen(m);
    let top = vals.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let mut out = Mat::<D>::zeros();
    for (k, &val) in vals.iter().enumerate() {
        if top > 0.0 && val.abs() > relative * top {
            let e = vecs.column(k);
            out += e * e.transpose() / val;
        }
    }
    (out + out.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shape tensor of a surface particle of a 1 m cube at x = 4 m (dp 0.1): a double
    /// eigenvalue with off-diagonal round-off. nalgebra 0.33's symmetric_eigen recomposes it
    /// 3 % off; the Jacobi decomposition must be exact to round-off.
    #[test]
    fn rotate_midpoint_is_the_rotation_of_the_normalised_midpoint() {
        // Two orientations a large turn apart, and the same with one quaternion's sign flipped
        // (the same rotation): the unnormalised form turns a bond as the unit midpoint does,
        // to round-off of the rotation (|v| = 1.3, 1e-15 relative).
        let a = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -1.1, 0.7));
        let b = UnitQuaternion::from_scaled_axis(Vector3::new(-0.9, 0.2, 1.4));
        let v = Vect::<3>::new(0.5, -1.0, 0.6);
        let nb = UnitQuaternion::new_unchecked(-b.into_inner());
        for (qa, qb) in [(a, b), (a, nb), (b, a), (a, a)] {
            let want = <Space as Dim<3>>::rotate(&<Space as Dim<3>>::midpoint(&qa, &qb), &v);
            let got = <Space as Dim<3>>::rotate_midpoint(&qa, &qb, &v);
            assert!((got - want).norm() < 1e-15 * 8.0, "{got} against {want}");
        }
        let want = <Space as Dim<2>>::rotate(&0.4, &Vect::<2>::new(1.0, 2.0));
        let got = <Space as Dim<2>>::rotate_midpoint(&0.3, &0.5, &Vect::<2>::new(1.0, 2.0));
        assert!((got - want).norm() < 1e-15 * 8.0);
    }

    #[test]
    fn pinv_of_near_diagonal_shape_tensor_is_the_inverse() {
        let k = Mat::<3>::new(
            4.038020141872869,
            0.0,
            5.315192730392937e-15,
            0.0,
            4.038020141872868,
            0.0,
            5.315192730392937e-15,
            0.0,
            2.403095901381118,
        );
        let inv = <Space as Dim<3>>::sym_pinv(&k);
        assert!((inv * k - Mat::<3>::identity()).amax() < 1e-14);
        let (vals, vecs) = sym_eigen(&k);
        let rec = vecs * Mat::<3>::from_diagonal(&Vect::<3>::from(vals)) * vecs.transpose();
        assert!((rec - k).amax() < 1e-14 * 4.04);
    }

    /// Pseudo-inverse of rank-deficient and rotated tensors: K+ K is the projector on the span.
    #[test]
    fn pinv_of_degenerate_tensor_projects_on_its_span() {
        let e = Vect::<3>::new(0.3, -0.4, 0.866).normalize();
        let f = e.cross(&Vect::<3>::new(1.0, 0.0, 0.0)).normalize();
        let k = e * e.transpose() * 2.0 + f * f.transpose() * 0.5;
        let p = <Space as Dim<3>>::sym_pinv(&k) * k;
        let want = e * e.transpose() + f * f.transpose();
        assert!((p - want).amax() < 1e-14);
        let k2 = Mat::<2>::new(1.0, 1e-17, 1e-17, 1.0);
        assert!((<Space as Dim<2>>::sym_pinv(&k2) * k2 - Mat::<2>::identity()).amax() < 1e-15);
        assert_eq!(
            <Space as Dim<2>>::sym_pinv(&Mat::<2>::zeros()),
            Mat::<2>::zeros()
        );
    }
}
