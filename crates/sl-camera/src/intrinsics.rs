//! Pinhole intrinsics.

use nalgebra::{Matrix3, Point2};
use serde::{Deserialize, Serialize};

use crate::CameraError;

/// How far the fixed entries of a camera matrix (`K[1][0]`, `K[2][0]`, `K[2][1]` = 0,
/// `K[2][2]` = 1) may be from their value. Files written in single precision (SLStudio writes
/// `Matx33f`) still hold these entries exactly, so any visible deviation means the matrix is
/// not a camera matrix (or is scaled, which we refuse rather than guess).
const FIXED_ENTRY_TOLERANCE: f64 = 1e-9;

/// Pinhole intrinsics in pixels: the upper-triangular camera matrix
///
/// ```text
///     | fx  skew  cx |
/// K = |  0   fy   cy |
///     |  0    0    1 |
/// ```
///
/// so that a distorted normalised point `(xd, yd)` lands on the pixel
/// `u = fx·xd + skew·yd + cx`, `v = fy·yd + cy` (pixel (0, 0) is the centre of the top-left
/// pixel, as in OpenCV).
///
/// `skew` is the `K[0][1]` entry in pixels. OpenCV's calibration fixes it at 0 and
/// `cv::projectPoints` ignores it; it is kept here for completeness and for other tools.
///
/// ```
/// use sl_camera::Intrinsics;
/// let k = Intrinsics::new(1440.4, 1437.1, 667.8, 354.2);
/// assert_eq!(k.matrix()[(0, 2)], 667.8);
/// assert_eq!(Intrinsics::from_matrix(&k.matrix())?, k);
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    /// Focal length along x, in pixels (`K[0][0]`).
    pub fx: f64,
    /// Focal length along y, in pixels (`K[1][1]`).
    pub fy: f64,
    /// Principal point x, in pixels (`K[0][2]`).
    pub cx: f64,
    /// Principal point y, in pixels (`K[1][2]`).
    pub cy: f64,
    /// Skew, in pixels (`K[0][1]`); 0 for every OpenCV calibration.
    #[serde(default)]
    pub skew: f64,
}

impl Intrinsics {
    /// Intrinsics without skew.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Self {
            fx,
            fy,
            cx,
            cy,
            skew: 0.0,
        }
    }

    /// The camera matrix `K`.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.fx, self.skew, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0,
        )
    }

    /// Reads a camera matrix; its lower row must be `0 0 1` and `K[1][0]` zero.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] if the matrix is not of that shape or its
    /// focal lengths are not finite and positive.
    pub fn from_matrix(k: &Matrix3<f64>) -> Result<Self, CameraError> {
        for (r, c, want) in [(1, 0, 0.0), (2, 0, 0.0), (2, 1, 0.0), (2, 2, 1.0)] {
            let got = k[(r, c)];
            if got.is_nan() || (got - want).abs() > FIXED_ENTRY_TOLERANCE {
                return Err(CameraError::invalid(
                    "camera matrix",
                    format!("entry [{r}][{c}] must be {want}, found {got}"),
                ));
            }
        }
        let intrinsics = Self {
            fx: k[(0, 0)],
            fy: k[(1, 1)],
            cx: k[(0, 2)],
            cy: k[(1, 2)],
            skew: k[(0, 1)],
        };
        intrinsics.validate()?;
        Ok(intrinsics)
    }

    /// Checks that focal lengths are finite and positive and the other entries finite.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] naming the first bad field.
    pub fn validate(&self) -> Result<(), CameraError> {
        for (name, value) in [("fx", self.fx), ("fy", self.fy)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(CameraError::invalid(
                    name,
                    format!("must be finite and positive, found {value}"),
                ));
            }
        }
        for (name, value) in [("cx", self.cx), ("cy", self.cy), ("skew", self.skew)] {
            if !value.is_finite() {
                return Err(CameraError::invalid(
                    name,
                    format!("must be finite, found {value}"),
                ));
            }
        }
        Ok(())
    }

    /// Pixel of a (distorted) normalised point: `K · (x, y, 1)`.
    #[inline]
    pub fn pixel_from_normalised(&self, p: &Point2<f64>) -> Point2<f64> {
        Point2::new(
            self.fx * p.x + self.skew * p.y + self.cx,
            self.fy * p.y + self.cy,
        )
    }

    /// (Distorted) normalised point of a pixel: `K⁻¹ · (u, v, 1)`.
    #[inline]
    pub fn normalised_from_pixel(&self, px: &Point2<f64>) -> Point2<f64> {
        let y = (px.y - self.cy) / self.fy;
        Point2::new((px.x - self.cx - self.skew * y) / self.fx, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn pixel_and_normalised_are_inverse_and_match_the_matrix() {
        let k = Intrinsics {
            fx: 1200.0,
            fy: 1190.0,
            cx: 640.0,
            cy: 360.0,
            skew: 3.5,
        };
        let p = Point2::new(0.21, -0.13);
        let px = k.pixel_from_normalised(&p);
        // Independent: the matrix product K (x, y, 1).
        let h = k.matrix() * nalgebra::Vector3::new(p.x, p.y, 1.0);
        // Both are a handful of f64 operations on values of ~1e3: 1e-12 relative is loose.
        assert_relative_eq!(px.x, h.x, max_relative = 1e-12);
        assert_relative_eq!(px.y, h.y, max_relative = 1e-12);
        let back = k.normalised_from_pixel(&px);
        assert_relative_eq!(back.x, p.x, max_relative = 1e-12);
        assert_relative_eq!(back.y, p.y, max_relative = 1e-12);
    }

    #[test]
    fn from_matrix_rejects_non_camera_matrices() {
        let mut m = Intrinsics::new(100.0, 100.0, 50.0, 50.0).matrix();
        m[(2, 2)] = 2.0;
        let e = Intrinsics::from_matrix(&m).unwrap_err().to_string();
        assert!(e.contains("[2][2]"), "{e}");
        let m = Intrinsics::new(-100.0, 100.0, 50.0, 50.0).matrix();
        let e = Intrinsics::from_matrix(&m).unwrap_err().to_string();
        assert!(e.contains("`fx`"), "{e}");
        let m = Intrinsics::new(100.0, f64::NAN, 50.0, 50.0).matrix();
        assert!(Intrinsics::from_matrix(&m).is_err());
    }
}
