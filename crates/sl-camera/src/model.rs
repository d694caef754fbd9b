//! The camera model: intrinsics, distortion and image size, with projection and
//! unprojection.

use nalgebra::{Point2, Point3, Unit, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{CameraError, Distortion, ImageSize, Intrinsics, RayTable};

/// A pinhole camera with OpenCV lens distortion.
///
/// Build it with [`CameraModel::new`], which validates; a struct literal or serde
/// deserialisation does not, so call [`CameraModel::validate`] on models from elsewhere
/// ([`crate::Calibration::load`] does).
///
/// `project` maps a point of the camera frame (mm; x right, y down, z forward) to a pixel;
/// `unproject` maps a pixel back to the normalised ray `(x, y, 1)`. Both refuse (return
/// `None`) what the model cannot represent one-to-one: points behind the camera (`z <= 0`)
/// and points outside the valid region of the distortion (see [`Distortion`]), so a pixel is
/// never turned into a wrong ray.
///
/// ```
/// use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
/// use nalgebra::{Point2, Point3};
/// let cam = CameraModel::new(
///     Intrinsics::new(1440.4, 1437.1, 667.8, 354.2),
///     Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1])?,
///     ImageSize::new(1280, 720),
/// )?;
/// let px = cam.project(&Point3::new(120.0, -80.0, 900.0)).unwrap();
/// let ray = cam.unproject(&px).unwrap();
/// assert!((ray * 900.0 - Point3::new(120.0, -80.0, 900.0).coords).norm() < 1e-9);
/// assert!(cam.project(&Point3::new(0.0, 0.0, -1.0)).is_none()); // behind the camera
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraModel {
    /// Pinhole intrinsics (pixels).
    pub intrinsics: Intrinsics,
    /// Lens distortion (OpenCV models).
    pub distortion: Distortion,
    /// Image size (pixels).
    pub size: ImageSize,
}

/// A projector is modelled as an inverse camera with the same types: its "pixels" are the
/// pixels of the projected image, `project` gives the projector pixel that lights a point of
/// the projector frame, and `unproject` gives the ray of light leaving the projector through
/// a pixel. Calibrations by OpenCV-style tools (SLStudio, Moreno & Taubin) use exactly this
/// model for the projector, including its distortion and an often off-centre principal
/// point (`cy` near or beyond the bottom edge).
pub type ProjectorModel = CameraModel;

impl CameraModel {
    /// A validated camera model.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] if the intrinsics are not finite with positive
    /// focal lengths, or the size is zero.
    pub fn new(
        intrinsics: Intrinsics,
        distortion: Distortion,
        size: ImageSize,
    ) -> Result<Self, CameraError> {
        let model = Self {
            intrinsics,
            distortion,
            size,
        };
        model.validate()?;
        Ok(model)
    }

    /// Checks the intrinsics and the size (the distortion is validated when built).
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] naming `intrinsics.<field>` or `size.<field>`.
    pub fn validate(&self) -> Result<(), CameraError> {
        self.intrinsics
            .validate()
            .map_err(|e| prefix_parameter(e, "intrinsics"))?;
        self.size
            .validate()
            .map_err(|e| prefix_parameter(e.into(), "size"))
    }

    /// Projects a point of the camera frame to a pixel; `None` if `z <= 0` (or not finite) or
    /// the point is outside the valid region of the distortion.
    #[inline]
    pub fn project(&self, p_cam: &Point3<f64>) -> Option<Point2<f64>> {
        if p_cam.z.is_nan() || p_cam.z <= 0.0 {
            return None;
        }
        let n = Point2::new(p_cam.x / p_cam.z, p_cam.y / p_cam.z);
        let d = self.distortion.distort_if_valid(&n)?;
        Some(self.intrinsics.pixel_from_normalised(&d))
    }

    /// Unprojects a pixel to the normalised ray `(x, y, 1)` in the camera frame (undistorted
    /// by Newton's method); `None` if the pixel is not the image of a point of the valid
    /// region. Pixels outside the image are fine as long as the lens model is invertible
    /// there.
    #[inline]
    pub fn unproject(&self, px: &Point2<f64>) -> Option<Vector3<f64>> {
        let n = self.undistort(&self.intrinsics.normalised_from_pixel(px))?;
        Some(Vector3::new(n.x, n.y, 1.0))
    }

    /// Like [`CameraModel::unproject`], with Newton's iteration started from `guess` (the
    /// undistorted normalised point of a nearby pixel, e.g. the left neighbour when walking a
    /// row): the same answer in one or two steps instead of a radial start and three to
    /// five. A bad guess costs a fallback to the normal start, never a wrong ray.
    ///
    /// ```
    /// use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
    /// use nalgebra::Point2;
    /// let cam = CameraModel::new(
    ///     Intrinsics::new(500.0, 500.0, 320.0, 240.0),
    ///     Distortion::from_opencv(&[-0.2, 0.05, 0.001, 0.0, 0.0])?,
    ///     ImageSize::new(640, 480),
    /// )?;
    /// let left = cam.unproject(&Point2::new(99.0, 50.0)).unwrap();
    /// let fast = cam.unproject_from(&Point2::new(100.0, 50.0), &Point2::new(left.x, left.y));
    /// let slow = cam.unproject(&Point2::new(100.0, 50.0));
    /// assert!((fast.unwrap() - slow.unwrap()).norm() < 1e-14);
    /// # Ok::<(), sl_camera::CameraError>(())
    /// ```
    #[inline]
    pub fn unproject_from(&self, px: &Point2<f64>, guess: &Point2<f64>) -> Option<Vector3<f64>> {
        let pd = self.intrinsics.normalised_from_pixel(px);
        let n = self.distortion.undistort_from(&pd, guess)?;
        Some(Vector3::new(n.x, n.y, 1.0))
    }

    /// The pixel of the normalised point `(x, y)` (distortion and intrinsics; no validity
    /// check — see [`CameraModel::in_valid_region`]). The same numbers as
    /// [`CameraModel::project`] of `(x, y, 1)`, on plain `f64`s and branch-free, for hot loops.
    #[inline(always)]
    pub fn project_normalised(&self, x: f64, y: f64) -> Point2<f64> {
        let [xd, yd] = self.distortion.distort_xy(x, y);
        let k = &self.intrinsics;
        Point2::new(k.fx * xd + k.skew * yd + k.cx, k.fy * yd + k.cy)
    }

    /// [`CameraModel::project_normalised`] with the derivatives of the pixel with respect to
    /// the normalised point.
    #[inline(always)]
    pub fn project_normalised_with_jacobian(&self, x: f64, y: f64) -> PixelJacobian {
        let ([xd, yd], [[a, c], [c2, b]]) = self.distortion.distort_xy_with_jacobian(x, y);
        let k = &self.intrinsics;
        PixelJacobian {
            u: k.fx * xd + k.skew * yd + k.cx,
            v: k.fy * yd + k.cy,
            du_dx: k.fx * a + k.skew * c2,
            du_dy: k.fx * c + k.skew * b,
            dv_dx: k.fy * c2,
            dv_dy: k.fy * b,
        }
    }

    /// Whether the normalised point `(x, y)` is in the valid region of the distortion, where
    /// [`CameraModel::project_normalised`] is one-to-one (see [`Distortion::in_valid_disc`]).
    #[inline(always)]
    pub fn in_valid_region(&self, x: f64, y: f64) -> bool {
        self.distortion.in_valid_disc(x, y)
    }

    /// Like [`CameraModel::unproject`], as a unit vector.
    pub fn unproject_ray(&self, px: &Point2<f64>) -> Option<Unit<Vector3<f64>>> {
        self.unproject(px).map(Unit::new_normalize)
    }

    /// Distorts a normalised point (see [`Distortion::distort`]).
    #[inline]
    pub fn distort(&self, p: &Point2<f64>) -> Point2<f64> {
        self.distortion.distort(p)
    }

    /// Undistorts a normalised point (see [`Distortion::undistort`]).
    #[inline]
    pub fn undistort(&self, pd: &Point2<f64>) -> Option<Point2<f64>> {
        self.distortion.undistort(pd)
    }

    /// [`CameraModel::project`] of many points, in parallel.
    pub fn project_many(&self, points: &[Point3<f64>]) -> Vec<Option<Point2<f64>>> {
        points.par_iter().map(|p| self.project(p)).collect()
    }

    /// [`CameraModel::unproject`] of many pixels, in parallel.
    pub fn unproject_many(&self, pixels: &[Point2<f64>]) -> Vec<Option<Vector3<f64>>> {
        pixels.par_iter().map(|p| self.unproject(p)).collect()
    }

    /// The undistorted ray of every pixel of the image (see [`RayTable`]), computed in
    /// parallel: compute it once per calibration and reuse it.
    pub fn ray_table(&self) -> RayTable {
        RayTable::new(self)
    }

    /// Horizontal and vertical field of view: the angles between the rays through the
    /// middles of opposite image edges; `None` where an edge is not invertible.
    pub fn field_of_view(&self) -> Option<FieldOfView> {
        let w = f64::from(self.size.width) - 0.5;
        let h = f64::from(self.size.height) - 0.5;
        let cy = 0.5 * (h - 0.5);
        let cx = 0.5 * (w - 0.5);
        let angle = |a: Point2<f64>, b: Point2<f64>| -> Option<f64> {
            let ra = self.unproject_ray(&a)?;
            let rb = self.unproject_ray(&b)?;
            Some(ra.angle(&rb).to_degrees())
        };
        Some(FieldOfView {
            horizontal_deg: angle(Point2::new(-0.5, cy), Point2::new(w, cy))?,
            vertical_deg: angle(Point2::new(cx, -0.5), Point2::new(cx, h))?,
        })
    }
}

/// A pixel and its derivatives with respect to the normalised point `(x, y)` it is the image
/// of (see [`CameraModel::project_normalised_with_jacobian`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelJacobian {
    /// Pixel column.
    pub u: f64,
    /// Pixel row.
    pub v: f64,
    /// `∂u/∂x` (pixels per normalised unit).
    pub du_dx: f64,
    /// `∂u/∂y`.
    pub du_dy: f64,
    /// `∂v/∂x`.
    pub dv_dx: f64,
    /// `∂v/∂y`.
    pub dv_dy: f64,
}

/// Field of view of a camera or projector (see [`CameraModel::field_of_view`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldOfView {
    /// Angle between the rays through the middles of the left and right image edges (deg).
    pub horizontal_deg: f64,
    /// Angle between the rays through the middles of the top and bottom image edges (deg).
    pub vertical_deg: f64,
}

fn prefix_parameter(e: CameraError, prefix: &str) -> CameraError {
    match e {
        CameraError::InvalidParameter { parameter, message } => CameraError::InvalidParameter {
            parameter: format!("{prefix}.{parameter}"),
            message,
        },
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn reference() -> CameraModel {
        CameraModel::new(
            Intrinsics::new(1440.4, 1437.1, 667.8, 354.2),
            Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1]).unwrap(),
            ImageSize::new(1280, 720),
        )
        .unwrap()
    }

    #[test]
    fn pinhole_projection_is_closed_form() {
        let cam = CameraModel::new(
            Intrinsics {
                fx: 1000.0,
                fy: 990.0,
                cx: 320.0,
                cy: 240.0,
                skew: 2.0,
            },
            Distortion::none(),
            ImageSize::new(640, 480),
        )
        .unwrap();
        let px = cam.project(&Point3::new(10.0, -20.0, 500.0)).unwrap();
        // u = fx x + skew y + cx with x = 0.02, y = −0.04.
        assert_relative_eq!(px.x, 1000.0 * 0.02 + 2.0 * -0.04 + 320.0, epsilon = 1e-12);
        assert_relative_eq!(px.y, 990.0 * -0.04 + 240.0, epsilon = 1e-12);
        let ray = cam.unproject(&px).unwrap();
        assert_relative_eq!(ray, Vector3::new(0.02, -0.04, 1.0), epsilon = 1e-15);
    }

    /// The plain-number paths against the checked ones over a whole (coarse) image grid of
    /// the strong reference lens: `project_normalised` is `project` (same formula, so equal
    /// to a few ulps of ~1e3 px), its Jacobian equals central differences (step 1e-6:
    /// truncation ~1e-12·f, rounding ~1e-16/1e-6·f ≈ 1e-7 px per unit; 1e-3 is safe while a
    /// wrong derivative is off by O(f) = 1e3), and `unproject_from` a neighbour's ray is
    /// `unproject` (same Newton root, a few ulps).
    #[test]
    fn plain_number_paths_match_the_checked_ones() {
        let cam = reference();
        let mut left: Option<Vector3<f64>> = None;
        for y in (0..720).step_by(9) {
            for x in (0..1280).step_by(5) {
                let px = Point2::new(f64::from(x), f64::from(y));
                let Some(ray) = cam.unproject(&px) else {
                    left = None;
                    continue;
                };
                assert!(cam.in_valid_region(ray.x, ray.y));
                let back = cam.project_normalised(ray.x, ray.y);
                let checked = cam.project(&Point3::from(ray)).unwrap();
                assert_relative_eq!(back, checked, epsilon = 1e-9);
                let pj = cam.project_normalised_with_jacobian(ray.x, ray.y);
                assert_relative_eq!(pj.u, back.x, epsilon = 1e-9);
                assert_relative_eq!(pj.v, back.y, epsilon = 1e-9);
                let h = 1e-6;
                let (a, b) = (
                    cam.project_normalised(ray.x + h, ray.y),
                    cam.project_normalised(ray.x - h, ray.y),
                );
                assert_relative_eq!(pj.du_dx, (a.x - b.x) / (2.0 * h), epsilon = 1e-3);
                assert_relative_eq!(pj.dv_dx, (a.y - b.y) / (2.0 * h), epsilon = 1e-3);
                let (a, b) = (
                    cam.project_normalised(ray.x, ray.y + h),
                    cam.project_normalised(ray.x, ray.y - h),
                );
                assert_relative_eq!(pj.du_dy, (a.x - b.x) / (2.0 * h), epsilon = 1e-3);
                assert_relative_eq!(pj.dv_dy, (a.y - b.y) / (2.0 * h), epsilon = 1e-3);
                if let Some(l) = left {
                    let fast = cam.unproject_from(&px, &Point2::new(l.x, l.y)).unwrap();
                    assert_relative_eq!(fast, ray, epsilon = 1e-14);
                }
                left = Some(ray);
            }
        }
        // A hopeless guess falls back to the normal start; a pixel with no preimage stays
        // without one whatever the guess.
        let px = Point2::new(100.0, 600.0);
        let far = cam.unproject_from(&px, &Point2::new(50.0, -50.0)).unwrap();
        assert_relative_eq!(far, cam.unproject(&px).unwrap(), epsilon = 1e-14);
        assert!(
            cam.unproject_from(&Point2::new(f64::NAN, 0.0), &Point2::origin())
                .is_none()
        );
        // Outside the valid disc, and NaN, are refused.
        let r = cam.distortion.max_radius();
        assert!(!cam.in_valid_region(r, 0.0));
        assert!(!cam.in_valid_region(f64::NAN, 0.0));
    }

    #[test]
    fn behind_and_beyond_are_refused() {
        let cam = reference();
        assert!(cam.project(&Point3::new(0.0, 0.0, 0.0)).is_none());
        assert!(cam.project(&Point3::new(1.0, 1.0, -5.0)).is_none());
        assert!(cam.project(&Point3::new(f64::NAN, 1.0, 5.0)).is_none());
        // 89.9° off-axis: beyond the searched radius, refused.
        assert!(cam.project(&Point3::new(1000.0, 0.0, 1.0)).is_none());
        assert!(cam.unproject(&Point2::new(f64::INFINITY, 0.0)).is_none());
    }

    #[test]
    fn validation_names_the_field() {
        let e = CameraModel::new(
            Intrinsics::new(0.0, 1.0, 0.0, 0.0),
            Distortion::none(),
            ImageSize::new(1, 1),
        )
        .unwrap_err();
        assert!(e.to_string().contains("intrinsics.fx"), "{e}");
        let e = CameraModel::new(
            Intrinsics::new(1.0, 1.0, 0.0, 0.0),
            Distortion::none(),
            ImageSize::new(1, 0),
        )
        .unwrap_err();
        assert!(e.to_string().contains("size.height"), "{e}");
    }

    #[test]
    fn field_of_view_of_a_pinhole() {
        let cam = CameraModel::new(
            Intrinsics::new(500.0, 500.0, 319.5, 239.5),
            Distortion::none(),
            ImageSize::new(640, 480),
        )
        .unwrap();
        let fov = cam.field_of_view().unwrap();
        let (h, v) = (fov.horizontal_deg, fov.vertical_deg);
        // Edges are 320 px and 240 px from the centre: 2·atan(320/500), 2·atan(240/500).
        assert_relative_eq!(
            h,
            2.0 * (320.0_f64 / 500.0).atan().to_degrees(),
            epsilon = 1e-9
        );
        assert_relative_eq!(
            v,
            2.0 * (240.0_f64 / 500.0).atan().to_degrees(),
            epsilon = 1e-9
        );
    }
}
