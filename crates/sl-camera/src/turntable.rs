//! The turntable axis in the camera frame.

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::CameraError;

/// Shortest accepted direction vector before normalisation: anything shorter is zero up to
/// rounding and has no direction.
const MIN_DIRECTION_NORM: f64 = 1e-12;

/// The rotation axis of the turntable, in the camera frame, and the motor's angle scale.
///
/// The platter angle for a motor reading `m` (degrees) is
/// `θ = angle_scale · m + angle_offset_deg`: `angle_scale` corrects the motor's gear ratio or
/// step calibration, `angle_offset_deg` is the platter angle at motor reading 0 relative to
/// the reference orientation. Angles turn right-handedly about `direction`.
///
/// ```
/// use sl_camera::TurntableAxis;
/// use nalgebra::{Point3, Vector3};
/// let axis = TurntableAxis::new(Vector3::new(0.0, -1.0, 0.0), Point3::new(0.0, 0.0, 600.0))?;
/// // A point on the axis does not move.
/// let m = axis.motion(90.0);
/// assert!((m * Point3::new(0.0, 50.0, 600.0) - Point3::new(0.0, 50.0, 600.0)).norm() < 1e-12);
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurntableAxis {
    /// Unit direction of the axis in the camera frame.
    pub direction: Vector3<f64>,
    /// A point on the axis in the camera frame, in millimetres.
    pub point_mm: Point3<f64>,
    /// Platter angle (degrees) at motor reading 0.
    #[serde(default)]
    pub angle_offset_deg: f64,
    /// Platter degrees per motor degree.
    #[serde(default = "one")]
    pub angle_scale: f64,
}

fn one() -> f64 {
    1.0
}

impl TurntableAxis {
    /// An axis with offset 0 and scale 1; the direction is normalised.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] if the direction is zero or anything is not finite.
    pub fn new(direction: Vector3<f64>, point_mm: Point3<f64>) -> Result<Self, CameraError> {
        let mut axis = Self {
            direction,
            point_mm,
            angle_offset_deg: 0.0,
            angle_scale: 1.0,
        };
        axis.normalize()?;
        Ok(axis)
    }

    /// Validates the axis and makes `direction` a unit vector.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] if the direction is zero or anything is not finite.
    pub fn normalize(&mut self) -> Result<(), CameraError> {
        let finite = self
            .direction
            .iter()
            .chain(self.point_mm.coords.iter())
            .all(|v| v.is_finite());
        if !finite {
            return Err(CameraError::invalid(
                "turntable",
                "direction and point must be finite",
            ));
        }
        for (name, v) in [
            ("angle_offset_deg", self.angle_offset_deg),
            ("angle_scale", self.angle_scale),
        ] {
            if !v.is_finite() {
                return Err(CameraError::invalid(
                    format!("turntable.{name}"),
                    format!("must be finite, found {v}"),
                ));
            }
        }
        let n = self.direction.norm();
        if n.is_nan() || n <= MIN_DIRECTION_NORM {
            return Err(CameraError::invalid(
                "turntable.direction",
                format!("must be a non-zero vector, found norm {n}"),
            ));
        }
        // Idempotent: a direction already unit to rounding is left bit-for-bit unchanged,
        // so files round-trip exactly.
        if (n - 1.0).abs() > 4.0 * f64::EPSILON {
            self.direction /= n;
        }
        Ok(())
    }

    /// Platter angle in degrees for a motor reading in degrees.
    pub fn table_angle_deg(&self, motor_deg: f64) -> f64 {
        self.angle_scale * motor_deg + self.angle_offset_deg
    }

    /// The rigid motion, in the camera frame, that the platter applies to what it carries
    /// when it turns from the reference orientation to the motor reading `motor_deg`. The
    /// motion between two readings `a` and `b` is `motion(b) * motion(a).inverse()`.
    pub fn motion(&self, motor_deg: f64) -> Isometry3<f64> {
        let angle = self.table_angle_deg(motor_deg).to_radians();
        let rotation = UnitQuaternion::from_axis_angle(&Unit::new_normalize(self.direction), angle);
        let c = self.point_mm.coords;
        // x ↦ R (x − c) + c
        Isometry3::from_parts(Translation3::from(c - rotation * c), rotation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn motion_is_a_rotation_about_the_axis_line() {
        let mut axis =
            TurntableAxis::new(Vector3::new(0.0, -2.0, 0.0), Point3::new(10.0, 0.0, 500.0))
                .unwrap();
        assert_relative_eq!(axis.direction, Vector3::new(0.0, -1.0, 0.0));
        axis.angle_scale = 0.5;
        axis.angle_offset_deg = 10.0;
        assert_relative_eq!(axis.table_angle_deg(160.0), 90.0);
        let m = axis.motion(160.0);
        // 90° about −y through (10, ·, 500): (10, 0, 600) goes to (10 − 100, 0, 500)
        // (right-hand rule about −y turns +z into −x).
        let p = m * Point3::new(10.0, 7.0, 600.0);
        assert_relative_eq!(p, Point3::new(-90.0, 7.0, 500.0), epsilon = 1e-12);
        let rel = axis.motion(200.0) * axis.motion(160.0).inverse();
        assert_relative_eq!(rel.rotation.angle().to_degrees(), 20.0, epsilon = 1e-10);
    }

    #[test]
    fn rejects_degenerate_axes() {
        assert!(TurntableAxis::new(Vector3::zeros(), Point3::origin()).is_err());
        assert!(TurntableAxis::new(Vector3::x(), Point3::new(f64::NAN, 0.0, 0.0)).is_err());
    }
}
