//! Rigid poses: OpenCV Rodrigues vectors, rotation matrices and their derivatives.
//!
//! Poses are [`nalgebra::Isometry3<f64>`] named `T_a_b`: the pose that maps coordinates
//! expressed in frame `b` into frame `a` (`p_a = T_a_b * p_b`), translations in millimetres.

use nalgebra::{Isometry3, Matrix3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::CameraError;

/// Below this rotation angle (rad) the coefficient functions of the Rodrigues formula and
/// its derivative are evaluated by their Taylor series: their closed forms lose `ε/θ²` to
/// cancellation (2e-14 at 0.1 rad), the 4-term series are exact to 1e-15 below 0.1 rad.
const SERIES_ANGLE: f64 = 0.1;

/// How far `RᵀR` may be from the identity (max entry) for a matrix read from a file to be
/// accepted as a rotation. Rotations stored in single precision (SLStudio) are off by ~1e-7;
/// 1e-5 leaves a wide margin while rejecting anything that is not meant as a rotation.
const ROTATION_TOLERANCE: f64 = 1e-5;

/// A pose as OpenCV's `rvec`/`tvec` pair: `p_a = R(rvec) · p_b + tvec` for the pose
/// `T_a_b`, with `R(rvec)` the rotation by `|rvec|` radians about `rvec` (Rodrigues) and
/// `tvec` in millimetres.
///
/// ```
/// use sl_camera::RvecTvec;
/// use nalgebra::{Point3, Vector3};
/// let pose = RvecTvec::new(Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2), Vector3::new(10.0, 0.0, 0.0));
/// let t_cam_world = pose.to_isometry();
/// let p_cam = t_cam_world * Point3::new(1.0, 0.0, 0.0);
/// assert!((p_cam - Point3::new(10.0, 1.0, 0.0)).norm() < 1e-12);
/// let back = RvecTvec::from_isometry(&t_cam_world);
/// assert!((back.rvec - pose.rvec).norm() < 1e-12);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RvecTvec {
    /// Rotation vector (axis × angle in radians), as `cv::Rodrigues`.
    pub rvec: Vector3<f64>,
    /// Translation in millimetres.
    pub tvec: Vector3<f64>,
}

impl RvecTvec {
    /// A pose from its two vectors.
    pub fn new(rvec: Vector3<f64>, tvec: Vector3<f64>) -> Self {
        Self { rvec, tvec }
    }

    /// The rotation vector and translation of a pose; the angle `|rvec|` is in `[0, π]`.
    pub fn from_isometry(pose: &Isometry3<f64>) -> Self {
        Self {
            rvec: rvec_from_rotation(&pose.rotation),
            tvec: pose.translation.vector,
        }
    }

    /// The pose as an isometry.
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.tvec),
            rotation_from_rvec(&self.rvec),
        )
    }

    /// `R(rvec) · p + tvec`.
    pub fn transform_point(&self, p: &Point3<f64>) -> Point3<f64> {
        rotation_from_rvec(&self.rvec) * p + self.tvec
    }
}

/// The rotation of a Rodrigues vector (accurate for any angle, including 0 and π).
pub fn rotation_from_rvec(rvec: &Vector3<f64>) -> UnitQuaternion<f64> {
    let theta2 = rvec.norm_squared();
    let theta = theta2.sqrt();
    // q = (cos θ/2, sin(θ/2)/θ · rvec)
    let (w, s) = if theta < SERIES_ANGLE {
        let t4 = theta2 * theta2;
        (
            1.0 - theta2 / 8.0 + t4 / 384.0 - t4 * theta2 / 46080.0,
            0.5 - theta2 / 48.0 + t4 / 3840.0 - t4 * theta2 / 645_120.0,
        )
    } else {
        ((0.5 * theta).cos(), (0.5 * theta).sin() / theta)
    };
    UnitQuaternion::new_normalize(Quaternion::new(w, s * rvec.x, s * rvec.y, s * rvec.z))
}

/// The Rodrigues vector of a rotation, with angle in `[0, π]` (accurate near 0 and π; at
/// exactly π both `±axis·π` are valid and either may be returned).
pub fn rvec_from_rotation(rotation: &UnitQuaternion<f64>) -> Vector3<f64> {
    let q = rotation.quaternion();
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let n = v.norm();
    if n == 0.0 {
        return Vector3::zeros();
    }
    // angle = 2 atan2(|v|, w); atan2 keeps full relative accuracy for small |v| and near π.
    v * (2.0 * n.atan2(w) / n)
}

/// A pose from a rotation matrix and a translation (mm), as stored in calibration files
/// (`p_a = R · p_b + t` for `T_a_b`). The matrix is snapped to the nearest rotation.
///
/// # Errors
/// [`CameraError::InvalidParameter`] if `R` is not a rotation (not orthonormal within 1e-5,
/// a reflection, or not finite) or `t` is not finite.
pub fn isometry_from_rt(r: &Matrix3<f64>, t: &Vector3<f64>) -> Result<Isometry3<f64>, CameraError> {
    if !r.iter().chain(t.iter()).all(|v| v.is_finite()) {
        return Err(CameraError::invalid(
            "rotation/translation",
            "entries must be finite",
        ));
    }
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err.is_nan() || err > ROTATION_TOLERANCE {
        return Err(CameraError::invalid(
            "rotation",
            format!("not orthonormal: |RᵀR − I| = {err:.3e} exceeds {ROTATION_TOLERANCE:e}"),
        ));
    }
    if r.determinant() <= 0.0 {
        return Err(CameraError::invalid(
            "rotation",
            "determinant is negative: a reflection, not a rotation",
        ));
    }
    // Nearest rotation (polar decomposition) through the SVD.
    let svd = r.svd(true, true);
    let rot = match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => u * v_t,
        _ => *r,
    };
    let rotation =
        UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(rot));
    Ok(Isometry3::from_parts(Translation3::from(*t), rotation))
}

/// A pose as a 4×4 row-major homogeneous matrix `[R t; 0 0 0 1]` (how numpy and OpenCV users
/// read poses; the JSON files of the toolkit write poses so).
///
/// ```
/// use sl_camera::{pose_from_matrix, pose_to_matrix};
/// use sl_camera::nalgebra::{Isometry3, Vector3};
/// let pose = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, -0.2, 0.3));
/// let m = pose_to_matrix(&pose);
/// assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0]);
/// assert_eq!(m[1][3], 2.0);
/// let back = pose_from_matrix(&m)?;
/// assert!((back.to_homogeneous() - pose.to_homogeneous()).abs().max() < 1e-12);
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
pub fn pose_to_matrix(pose: &Isometry3<f64>) -> [[f64; 4]; 4] {
    let m = pose.to_homogeneous();
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
}

/// The pose of a 4×4 row-major homogeneous matrix ([`pose_to_matrix`]'s inverse).
///
/// # Errors
/// [`CameraError::InvalidParameter`] naming `last row` when it is not `0 0 0 1`, or the
/// rotation as [`isometry_from_rt`] does (not finite, not orthonormal, a reflection).
pub fn pose_from_matrix(m: &[[f64; 4]; 4]) -> Result<Isometry3<f64>, CameraError> {
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(CameraError::invalid(
            "last row",
            format!("{:?}: a rigid motion's is 0 0 0 1", m[3]),
        ));
    }
    let r = Matrix3::from_fn(|i, j| m[i][j]);
    isometry_from_rt(&r, &Vector3::new(m[0][3], m[1][3], m[2][3]))
}

/// Rotation matrix and translation of a pose (`p_a = R · p_b + t` for `T_a_b`).
pub(crate) fn isometry_to_rt(pose: &Isometry3<f64>) -> (Matrix3<f64>, Vector3<f64>) {
    (
        pose.rotation.to_rotation_matrix().into_inner(),
        pose.translation.vector,
    )
}

/// `∂(R(rvec) · p) / ∂rvec`: the derivative of a rotated point with respect to the
/// Rodrigues vector (analytic, smooth through `rvec = 0`).
///
/// With `θ = |ω|`, `R p = p + a ω×p + b ω×(ω×p)`, `a = sin θ/θ`, `b = (1 − cos θ)/θ²`, so
/// `∂(Rp)/∂ω = −a [p]× + (ω×p) c ωᵀ + b ((ω·p) I + ω pᵀ − 2 p ωᵀ) + (ω×(ω×p)) d ωᵀ` with
/// `c = a'/θ`, `d = b'/θ`.
pub fn rotation_jacobian(rvec: &Vector3<f64>, p: &Vector3<f64>) -> Matrix3<f64> {
    let w = rvec;
    let theta2 = w.norm_squared();
    let theta = theta2.sqrt();
    let (a, b, c, d) = if theta < SERIES_ANGLE {
        let t2 = theta2;
        let t4 = t2 * t2;
        let t6 = t4 * t2;
        (
            1.0 - t2 / 6.0 + t4 / 120.0 - t6 / 5040.0,
            0.5 - t2 / 24.0 + t4 / 720.0 - t6 / 40320.0,
            -1.0 / 3.0 + t2 / 30.0 - t4 / 840.0 + t6 / 45360.0,
            -1.0 / 12.0 + t2 / 180.0 - t4 / 6720.0 + t6 / 453_600.0,
        )
    } else {
        let (s, co) = theta.sin_cos();
        let t3 = theta2 * theta;
        (
            s / theta,
            (1.0 - co) / theta2,
            (theta * co - s) / t3,
            (theta * s - 2.0 * (1.0 - co)) / (theta2 * theta2),
        )
    };
    let wxp = w.cross(p);
    let wwxp = w.cross(&wxp);
    let wdp = w.dot(p);
    -a * p.cross_matrix()
        + wxp * (c * w).transpose()
        + b * (Matrix3::identity() * wdp + w * p.transpose() - 2.0 * p * w.transpose())
        + wwxp * (d * w).transpose()
}

/// Serialised pose in the JSON calibration file: rotation matrix rows and a translation in
/// millimetres (unambiguous and readable, unlike quaternion component orders).
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PoseRepr {
    /// Rotation matrix, row by row.
    pub(crate) rotation: [[f64; 3]; 3],
    /// Translation in millimetres.
    pub(crate) translation_mm: [f64; 3],
}

impl PoseRepr {
    pub(crate) fn from_isometry(pose: &Isometry3<f64>) -> Self {
        let (r, t) = isometry_to_rt(pose);
        Self {
            rotation: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            translation_mm: [t.x, t.y, t.z],
        }
    }

    pub(crate) fn to_isometry(&self) -> Result<Isometry3<f64>, CameraError> {
        let r = Matrix3::from_fn(|i, j| self.rotation[i][j]);
        isometry_from_rt(&r, &Vector3::from(self.translation_mm))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use std::f64::consts::PI;

    /// Rodrigues' formula for the matrix, written independently of the quaternion path.
    fn rodrigues_matrix(w: &Vector3<f64>) -> Matrix3<f64> {
        let theta = w.norm();
        if theta == 0.0 {
            return Matrix3::identity();
        }
        let k = w / theta;
        let kx = k.cross_matrix();
        Matrix3::identity() + theta.sin() * kx + (1.0 - theta.cos()) * kx * kx
    }

    #[test]
    fn rvec_to_matrix_matches_rodrigues_formula() {
        for w in [
            Vector3::new(0.3, -0.2, 0.9),
            Vector3::new(1e-9, 2e-9, -1e-9),
            Vector3::new(0.05, 0.0, 0.01),
            Vector3::new(0.0, PI - 1e-9, 0.0),
            Vector3::new(1.0, 1.0, 1.0).normalize() * PI,
        ] {
            let r = rotation_from_rvec(&w).to_rotation_matrix().into_inner();
            // Both are accurate to a few ulps of entries ≤ 1.
            assert_relative_eq!(r, rodrigues_matrix(&w), epsilon = 1e-14);
        }
    }

    #[test]
    fn rvec_round_trip_near_zero_and_pi() {
        for w in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1e-12, -3e-12, 2e-12),
            Vector3::new(0.01, 0.02, -0.03),
            Vector3::new(-1.2, 0.4, 2.0),
            Vector3::new(0.6, -0.8, 0.0) * (PI - 1e-7),
            Vector3::new(0.0, 0.0, PI - 1e-12),
        ] {
            let back = rvec_from_rotation(&rotation_from_rvec(&w));
            // The vector is recovered to ~1e-15 absolute (1e-12 relative near 0).
            assert_relative_eq!(back, w, epsilon = 1e-14, max_relative = 1e-9);
        }
        // At exactly π: either sign of the axis, same rotation.
        let w = Vector3::new(0.0, 1.0, 0.0) * PI;
        let back = rvec_from_rotation(&rotation_from_rvec(&w));
        assert_relative_eq!(back.norm(), PI, epsilon = 1e-12);
        assert_relative_eq!(
            rodrigues_matrix(&back),
            rodrigues_matrix(&w),
            epsilon = 1e-12
        );
    }

    #[test]
    fn matrix_to_rvec_near_pi_from_matrix() {
        // Build R from the formula, go through isometry_from_rt (SVD + quaternion).
        let w = Vector3::new(2.0, -1.0, 0.5).normalize() * (PI - 1e-6);
        let pose = isometry_from_rt(&rodrigues_matrix(&w), &Vector3::new(1.0, 2.0, 3.0)).unwrap();
        let back = RvecTvec::from_isometry(&pose);
        assert_relative_eq!(back.rvec, w, epsilon = 1e-9);
        assert_eq!(back.tvec, Vector3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn a_matrix_that_is_not_a_rigid_motion_is_refused_naming_what() {
        let mut m = pose_to_matrix(&Isometry3::identity());
        m[3] = [0.0, 0.0, 1.0, 1.0];
        let err = pose_from_matrix(&m).unwrap_err().to_string();
        assert!(err.contains("last row"), "{err}");
        let mut m = pose_to_matrix(&Isometry3::identity());
        m[0][0] = -1.0;
        let err = pose_from_matrix(&m).unwrap_err().to_string();
        assert!(err.contains("reflection"), "{err}");
        let mut m = pose_to_matrix(&Isometry3::identity());
        m[1][1] = 1.1;
        let err = pose_from_matrix(&m).unwrap_err().to_string();
        assert!(err.contains("orthonormal"), "{err}");
    }

    #[test]
    fn isometry_from_rt_rejects_non_rotations() {
        let t = Vector3::zeros();
        let mut m = Matrix3::identity();
        m[(0, 0)] = -1.0;
        assert!(isometry_from_rt(&m, &t).is_err());
        assert!(isometry_from_rt(&(Matrix3::identity() * 1.1), &t).is_err());
        assert!(isometry_from_rt(&Matrix3::identity(), &Vector3::new(f64::NAN, 0., 0.)).is_err());
        // Single-precision noise is accepted and cleaned.
        let noisy = rodrigues_matrix(&Vector3::new(0.1, 0.2, 0.3)).map(|v| f64::from(v as f32));
        let pose = isometry_from_rt(&noisy, &t).unwrap();
        let r = pose.rotation.to_rotation_matrix().into_inner();
        assert_relative_eq!(r.transpose() * r, Matrix3::identity(), epsilon = 1e-14);
    }

    #[test]
    fn rotation_jacobian_matches_central_differences() {
        let p = Vector3::new(120.0, -45.0, 800.0);
        for w in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1e-5, -2e-5, 3e-6),
            Vector3::new(0.05, 0.03, -0.07),
            Vector3::new(0.3, -1.1, 0.7),
            Vector3::new(0.5, 0.5, -0.5).normalize() * (PI - 1e-3),
        ] {
            let j = rotation_jacobian(&w, &p);
            let h = 1e-6;
            for c in 0..3 {
                let mut a = w;
                let mut b = w;
                a[c] += h;
                b[c] -= h;
                let fd = (rodrigues_matrix(&a) * p - rodrigues_matrix(&b) * p) / (2.0 * h);
                // |p| ~ 1e3: central-difference error ≈ 1e3·(h² + ε/h) ≈ 1e-7; a wrong term
                // would be off by O(|p|).
                assert_relative_eq!(j.column(c).into_owned(), fd, epsilon = 1e-6);
            }
        }
    }

    #[test]
    fn series_and_closed_forms_agree_at_the_switch() {
        let p = Vector3::new(1.0, 2.0, 3.0);
        let dir = Vector3::new(0.2, -0.5, 0.8).normalize();
        let below = rotation_jacobian(&(dir * (SERIES_ANGLE * (1.0 - 1e-12))), &p);
        let above = rotation_jacobian(&(dir * (SERIES_ANGLE * (1.0 + 1e-12))), &p);
        // The function is smooth; a jump larger than rounding would reveal a wrong series.
        assert_relative_eq!(below, above, epsilon = 1e-12);
    }
}
