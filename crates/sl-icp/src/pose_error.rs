//! How far an estimated pose is from a reference pose.

use nalgebra::{Isometry3, Point3};

/// The error of an estimated pose `T_a_b` against a reference `T_a_b`.
///
/// - `rotation_deg`: angle of `R_ref^T R_est`, degrees;
/// - `translation_mm`: `|t_est - t_ref|`, the norm of the translation of `T_ref^-1 T_est`: how
///   far the estimate misplaces the origin of frame `b` (depends on where that origin is);
/// - `rms_displacement_mm`: `sqrt(mean |T_est p - T_ref p|²)` over given points `p` of frame
///   `b`, independent of the origin (0 when no point is given).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseError {
    /// Rotation error in degrees.
    pub rotation_deg: f64,
    /// Translation error in mm (see the type's docs).
    pub translation_mm: f64,
    /// RMS displacement of the points in mm.
    pub rms_displacement_mm: f64,
}

impl PoseError {
    /// The error of `estimate` against `reference`, with the RMS displacement over `points`.
    ///
    /// ```
    /// use nalgebra::{Isometry3, Point3, Vector3};
    /// use sl_icp::PoseError;
    /// let reference = Isometry3::translation(10.0, 0.0, 0.0);
    /// let estimate = Isometry3::translation(10.0, 0.3, 0.4);
    /// let e = PoseError::between(&estimate, &reference, &[Point3::origin()]);
    /// assert!((e.translation_mm - 0.5).abs() < 1e-12 && e.rotation_deg == 0.0);
    /// assert!((e.rms_displacement_mm - 0.5).abs() < 1e-12);
    /// ```
    pub fn between(
        estimate: &Isometry3<f64>,
        reference: &Isometry3<f64>,
        points: &[Point3<f64>],
    ) -> Self {
        let rotation_deg = estimate.rotation.angle_to(&reference.rotation).to_degrees();
        let translation_mm = (estimate.translation.vector - reference.translation.vector).norm();
        let sum: f64 = points
            .iter()
            .map(|p| (estimate * p - reference * p).norm_squared())
            .sum();
        let rms_displacement_mm = if points.is_empty() {
            0.0
        } else {
            (sum / points.len() as f64).sqrt()
        };
        Self {
            rotation_deg,
            translation_mm,
            rms_displacement_mm,
        }
    }
}
