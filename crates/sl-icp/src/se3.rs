//! Small rigid-motion helpers: skew matrices, updates about a centre, a 6-vector chart.

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3, Vector6};

/// `[a]x`, the matrix of `x -> a × x`.
#[inline]
pub(crate) fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// The motion `x -> R(ω) (x - c) + c + v`: rotation by the rotation vector `ω` about the point
/// `c`, then translation by `v`. Linearising about `c` keeps the normal equations well
/// conditioned and makes the update independent of where the frame's origin is.
pub(crate) fn update_about(
    omega: &Vector3<f64>,
    v: &Vector3<f64>,
    c: &Point3<f64>,
) -> Isometry3<f64> {
    let r = UnitQuaternion::from_scaled_axis(*omega);
    let t = c.coords + v - r * c.coords;
    Isometry3::from_parts(Translation3::from(t), r)
}

/// The 6-vector `(ω, t)` of a pose: its rotation vector (rad) and its translation (mm). A
/// chart of SE(3) around the identity that agrees with the exponential map to first order,
/// with the update `x -> R(ω) x + t` of [`from_vector`].
pub(crate) fn to_vector(pose: &Isometry3<f64>) -> Vector6<f64> {
    let w = pose.rotation.scaled_axis();
    let t = pose.translation.vector;
    Vector6::new(w.x, w.y, w.z, t.x, t.y, t.z)
}

/// Inverse of [`to_vector`].
pub(crate) fn from_vector(x: &Vector6<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x[3], x[4], x[5]),
        UnitQuaternion::from_scaled_axis(Vector3::new(x[0], x[1], x[2])),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn skew_is_cross_product_and_update_fixes_centre() {
        let a = Vector3::new(1.0, -2.0, 3.0);
        let b = Vector3::new(0.5, 4.0, -1.0);
        assert_relative_eq!(skew(&a) * b, a.cross(&b));
        let c = Point3::new(10.0, 20.0, 30.0);
        let m = update_about(&Vector3::new(0.1, 0.2, -0.3), &Vector3::zeros(), &c);
        assert_relative_eq!(m * c, c, epsilon = 1e-12);
        let pose = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.3, -0.2, 0.1));
        assert_relative_eq!(from_vector(&to_vector(&pose)), pose, epsilon = 1e-12);
    }
}
