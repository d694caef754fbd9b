//! Initial poses of turntable views from the calibrated axis and the motor angles, so that no
//! manual pre-alignment is needed.

use nalgebra::Isometry3;
use sl_camera::TurntableAxis;

use crate::IcpError;

/// The poses `T_world_view` of views taken at the motor readings `motor_deg` (degrees), with
/// the world frame the camera frame of the first view.
///
/// The platter carries the object by `M(θ) = axis.motion(θ)` (right-handed rotation about the
/// axis direction, through the axis point, camera frame), so a point seen at `x_i` in view `i`
/// is at `M(θ_0) M(θ_i)^-1 x_i` in view 0's frame:
/// `T_world_view_i = M(θ_0) · M(θ_i)^-1`, a rotation by `-(θ_i - θ_0)` (platter degrees)
/// about the axis. With `θ_0 = 0` it is the rotation by `-θ_i`.
///
/// # Errors
/// [`IcpError::Camera`] for an invalid axis, [`IcpError::InvalidParameter`] for a non-finite
/// angle.
///
/// ```
/// use nalgebra::{Point3, Vector3};
/// use sl_icp::{turntable_poses, TurntableAxis};
/// // Axis up (-y, y points down) through (0, 0, 500 mm).
/// let axis = TurntableAxis::new(-Vector3::y(), Point3::new(0.0, 0.0, 500.0))?;
/// let poses = turntable_poses(&axis, &[0.0, 90.0])?;
/// // After a quarter turn, the point the camera sees at (100, 0, 500) (100 mm right of the
/// // axis) was, in view 0, on the near side of the axis: (0, 0, 400).
/// let p = poses[1] * Point3::new(100.0, 0.0, 500.0);
/// assert!((p - Point3::new(0.0, 0.0, 400.0)).norm() < 1e-9);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
pub fn turntable_poses(
    axis: &TurntableAxis,
    motor_deg: &[f64],
) -> Result<Vec<Isometry3<f64>>, IcpError> {
    let mut axis = *axis;
    axis.normalize()?;
    if let Some(bad) = motor_deg.iter().find(|a| !a.is_finite()) {
        return Err(IcpError::invalid("motor_deg", bad, "angles must be finite"));
    }
    let Some(&first) = motor_deg.first() else {
        return Ok(Vec::new());
    };
    let m0 = axis.motion(first);
    Ok(motor_deg
        .iter()
        .map(|&a| m0 * axis.motion(a).inverse())
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn poses_undo_the_platter_motion() {
        // An object point p0 (view 0) is seen at M(θ) M(θ0)^-1 p0 in view θ; the pose must map
        // it back to p0, for any axis and angles.
        let axis = TurntableAxis::new(Vector3::new(0.1, -1.0, 0.2), Point3::new(5.0, -20.0, 450.0))
            .unwrap();
        let angles = [12.0, 22.0, 100.0, 371.5];
        let poses = turntable_poses(&axis, &angles).unwrap();
        assert_relative_eq!(poses[0], Isometry3::identity(), epsilon = 1e-12);
        let p0 = Point3::new(30.0, 10.0, 420.0);
        for (pose, &a) in poses.iter().zip(&angles) {
            let seen = axis.motion(a) * axis.motion(angles[0]).inverse() * p0;
            assert_relative_eq!(pose * seen, p0, epsilon = 1e-9);
            // A rotation by -(θ - θ0) about the axis.
            let expected = (a - angles[0])
                .to_radians()
                .rem_euclid(std::f64::consts::TAU);
            let got = pose.rotation.angle();
            let wrapped = expected.min(std::f64::consts::TAU - expected);
            assert_relative_eq!(got, wrapped, epsilon = 1e-9);
        }
        assert!(turntable_poses(&axis, &[0.0, f64::NAN]).is_err());
        assert!(turntable_poses(&axis, &[]).unwrap().is_empty());
        let mut bad = axis;
        bad.direction = Vector3::zeros();
        assert!(turntable_poses(&bad, &[0.0]).is_err());
    }
}
