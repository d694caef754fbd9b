//! Analytic Jacobians of the projection with respect to the point, the intrinsics, the
//! distortion coefficients and a pose.

use nalgebra::{Matrix2, Matrix2x3, Point2, Point3, SMatrix};

use crate::pose::{rotation_from_rvec, rotation_jacobian};
use crate::{CameraModel, RvecTvec};

/// Names of the intrinsic parameters in the order of the columns of
/// [`ProjectionJacobians::d_intrinsics`].
pub const INTRINSIC_PARAMETERS: [&str; 5] = ["fx", "fy", "cx", "cy", "skew"];

/// A projected pixel with its analytic derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectionJacobians {
    /// The pixel `(u, v)`.
    pub pixel: Point2<f64>,
    /// `∂(u, v) / ∂(X, Y, Z)` for the point in the camera frame (pixels per mm).
    pub d_point: Matrix2x3<f64>,
    /// `∂(u, v) / ∂(fx, fy, cx, cy, skew)` (see [`INTRINSIC_PARAMETERS`]).
    pub d_intrinsics: SMatrix<f64, 2, 5>,
    /// `∂(u, v) / ∂(k1, k2, p1, p2, k3, k4, k5, k6)` (OpenCV order, see
    /// [`crate::DISTORTION_PARAMETERS`]; see [`crate::DistortionJacobians::d_coefficients`]
    /// about coefficients the model does not use).
    pub d_distortion: SMatrix<f64, 2, 8>,
}

/// A pixel projected through a pose `T_cam_world`, with the derivatives a calibration
/// (Zhang's method) needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseProjectionJacobians {
    /// Pixel and derivatives with respect to the point in the camera frame and the camera
    /// parameters.
    pub projection: ProjectionJacobians,
    /// `∂(u, v) / ∂rvec` of the pose `T_cam_world`.
    pub d_rvec: Matrix2x3<f64>,
    /// `∂(u, v) / ∂tvec` of the pose `T_cam_world` (per mm).
    pub d_tvec: Matrix2x3<f64>,
    /// `∂(u, v) / ∂p_world`.
    pub d_point_world: Matrix2x3<f64>,
}

impl CameraModel {
    /// Projects a point of the camera frame with the analytic Jacobians of the pixel with
    /// respect to the point, the intrinsics and the distortion coefficients. `None` where
    /// [`CameraModel::project`] refuses.
    ///
    /// ```
    /// use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
    /// use nalgebra::Point3;
    /// let cam = CameraModel::new(
    ///     Intrinsics::new(800.0, 800.0, 320.0, 240.0),
    ///     Distortion::from_opencv(&[-0.2, 0.05, 0.0, 0.0, 0.0])?,
    ///     ImageSize::new(640, 480),
    /// )?;
    /// let j = cam.project_with_jacobians(&Point3::new(50.0, 20.0, 500.0)).unwrap();
    /// assert_eq!(j.d_intrinsics[(0, 2)], 1.0); // ∂u/∂cx
    /// # Ok::<(), sl_camera::CameraError>(())
    /// ```
    pub fn project_with_jacobians(&self, p_cam: &Point3<f64>) -> Option<ProjectionJacobians> {
        if p_cam.z.is_nan() || p_cam.z <= 0.0 {
            return None;
        }
        let inv_z = 1.0 / p_cam.z;
        let n = Point2::new(p_cam.x * inv_z, p_cam.y * inv_z);
        if !self.distortion.is_valid_at(&n) {
            return None;
        }
        let dj = self.distortion.distort_with_jacobians(&n);
        let k = &self.intrinsics;
        let (xd, yd) = (dj.point.x, dj.point.y);
        // pixel = K2 · (xd, yd) + (cx, cy) with K2 = [[fx, skew], [0, fy]].
        let k2 = Matrix2::new(k.fx, k.skew, 0.0, k.fy);
        // ∂(x, y)/∂(X, Y, Z)
        let d_norm = Matrix2x3::new(inv_z, 0.0, -n.x * inv_z, 0.0, inv_z, -n.y * inv_z);
        let d_point = k2 * dj.d_point * d_norm;
        #[rustfmt::skip]
        let d_intrinsics = SMatrix::<f64, 2, 5>::new(
            xd, 0.0, 1.0, 0.0, yd,
            0.0, yd, 0.0, 1.0, 0.0,
        );
        let d_distortion = k2 * dj.d_coefficients;
        Some(ProjectionJacobians {
            pixel: k.pixel_from_normalised(&dj.point),
            d_point,
            d_intrinsics,
            d_distortion,
        })
    }

    /// Projects a point of the world (e.g. checkerboard) frame seen through the pose
    /// `t_cam_world` (`p_cam = R(rvec) p_world + tvec`), with the Jacobians with respect to the
    /// camera parameters, the pose and the world point. `None` where
    /// [`CameraModel::project`] refuses `p_cam`.
    pub fn project_with_pose_jacobians(
        &self,
        t_cam_world: &RvecTvec,
        p_world: &Point3<f64>,
    ) -> Option<PoseProjectionJacobians> {
        let rotation = rotation_from_rvec(&t_cam_world.rvec);
        let p_cam = rotation * p_world + t_cam_world.tvec;
        let projection = self.project_with_jacobians(&p_cam)?;
        let d_rvec = projection.d_point * rotation_jacobian(&t_cam_world.rvec, &p_world.coords);
        let d_point_world = projection.d_point * rotation.to_rotation_matrix().into_inner();
        Some(PoseProjectionJacobians {
            projection,
            d_rvec,
            d_tvec: projection.d_point,
            d_point_world,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Distortion, DistortionModel, ImageSize, Intrinsics};
    use approx::assert_relative_eq;
    use nalgebra::{Vector2, Vector3};

    fn camera(k: [f64; 8], model: DistortionModel) -> CameraModel {
        CameraModel::new(
            Intrinsics {
                fx: 1440.4,
                fy: 1437.1,
                cx: 667.8,
                cy: 354.2,
                skew: 1.7,
            },
            Distortion::new(model, k).unwrap(),
            ImageSize::new(1280, 720),
        )
        .unwrap()
    }

    fn params(cam: &CameraModel) -> [f64; 13] {
        let i = cam.intrinsics;
        let k = cam.distortion.coefficients();
        [
            i.fx, i.fy, i.cx, i.cy, i.skew, k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7],
        ]
    }

    fn with_params(p: &[f64; 13]) -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics {
                fx: p[0],
                fy: p[1],
                cx: p[2],
                cy: p[3],
                skew: p[4],
            },
            distortion: Distortion::new(
                DistortionModel::Rational,
                [p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12]],
            )
            .unwrap(),
            size: ImageSize::new(1280, 720),
        }
    }

    /// Central difference with step `h`: truncation O(h²·f'''), rounding O(ε·|f|/h). With
    /// |f| ~ 1e3 px, h = 1e-5·scale gives errors ~1e-6 px per unit of parameter; we compare
    /// with a tolerance of 1e-5 relative + 1e-5 absolute, far below any real error (O(1)).
    fn central(f: impl Fn(f64) -> Vector2<f64>, x: f64) -> Vector2<f64> {
        let h = 1e-5 * x.abs().max(1.0);
        (f(x + h) - f(x - h)) / (2.0 * h)
    }

    #[test]
    fn camera_jacobians_match_central_differences() {
        let cases = [
            (
                [0.5466, -20.20, -0.02203, 0.008259, 211.1, 0.0, 0.0, 0.0],
                DistortionModel::PlumbBob,
            ),
            (
                [2.31, 0.87, 0.00061, -0.00032, 0.029, 2.68, 1.47, 0.19],
                DistortionModel::Rational,
            ),
        ];
        for (k, model) in cases {
            let cam = camera(k, model);
            for p in [
                Point3::new(120.0, -80.0, 900.0),
                Point3::new(-300.0, -150.0, 700.0),
                Point3::new(0.0, 0.0, 500.0),
            ] {
                let j = cam.project_with_jacobians(&p).unwrap();
                for c in 0..3 {
                    let fd = central(
                        |v| {
                            let mut q = p;
                            q[c] = v;
                            cam.project(&q).unwrap().coords
                        },
                        p[c],
                    );
                    assert_relative_eq!(
                        j.d_point.column(c).into_owned(),
                        fd,
                        epsilon = 1e-5,
                        max_relative = 1e-5
                    );
                }
                let base = params(&cam);
                for c in 0..13 {
                    let fd = central(
                        |v| {
                            let mut q = base;
                            q[c] = v;
                            with_params(&q).project(&p).unwrap().coords
                        },
                        base[c],
                    );
                    let analytic = if c < 5 {
                        j.d_intrinsics.column(c).into_owned()
                    } else {
                        j.d_distortion.column(c - 5).into_owned()
                    };
                    assert_relative_eq!(analytic, fd, epsilon = 1e-5, max_relative = 1e-5);
                }
            }
        }
    }

    #[test]
    fn pose_jacobians_match_central_differences() {
        let cam = camera(
            [0.5466, -20.20, -0.02203, 0.008259, 211.1, 0.0, 0.0, 0.0],
            DistortionModel::PlumbBob,
        );
        let p_world = Point3::new(40.0, -25.0, 0.0);
        for rvec in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.2, -0.1, 0.05),
            Vector3::new(2.9, 0.3, -0.4),
        ] {
            let pose = RvecTvec::new(rvec, Vector3::new(-10.0, 15.0, 800.0));
            let j = cam.project_with_pose_jacobians(&pose, &p_world).unwrap();
            let proj = |pose: &RvecTvec, p: &Point3<f64>| {
                cam.project(&pose.transform_point(p)).unwrap().coords
            };
            assert_relative_eq!(
                j.projection.pixel.coords,
                proj(&pose, &p_world),
                epsilon = 1e-9
            );
            for c in 0..3 {
                let fd_r = central(
                    |v| {
                        let mut q = pose;
                        q.rvec[c] = v;
                        proj(&q, &p_world)
                    },
                    pose.rvec[c],
                );
                // rvec derivatives are ~1e3 px/rad: same relative tolerance.
                assert_relative_eq!(
                    j.d_rvec.column(c).into_owned(),
                    fd_r,
                    epsilon = 1e-4,
                    max_relative = 1e-5
                );
                let fd_t = central(
                    |v| {
                        let mut q = pose;
                        q.tvec[c] = v;
                        proj(&q, &p_world)
                    },
                    pose.tvec[c],
                );
                assert_relative_eq!(
                    j.d_tvec.column(c).into_owned(),
                    fd_t,
                    epsilon = 1e-5,
                    max_relative = 1e-5
                );
                let fd_p = central(
                    |v| {
                        let mut q = p_world;
                        q[c] = v;
                        proj(&pose, &q)
                    },
                    p_world[c],
                );
                assert_relative_eq!(
                    j.d_point_world.column(c).into_owned(),
                    fd_p,
                    epsilon = 1e-5,
                    max_relative = 1e-5
                );
            }
        }
    }

    #[test]
    fn refuses_like_project() {
        let cam = camera([0.0; 8], DistortionModel::None);
        assert!(
            cam.project_with_jacobians(&Point3::new(0.0, 0.0, -1.0))
                .is_none()
        );
    }
}
