//! A flat copy of a camera / projector model for the hot loops: pinhole intrinsics and
//! OpenCV's distortion evaluated inline, with the pixel Jacobian.

use sl_camera::{CameraModel, DistortionModel};

/// Pinhole + OpenCV distortion in plain numbers (the formulas of `sl_camera::Distortion`,
/// inlined so that the per-pixel loops do not pay for the coefficient Jacobians).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lens {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    skew: f64,
    /// `k1 k2 p1 p2 k3 k4 k5 k6`.
    k: [f64; 8],
    distorted: bool,
    /// Square of the radius of the valid (one-to-one) disc of normalised coordinates.
    max_r2: f64,
}

/// A projected pixel and its Jacobian with respect to the normalised point `(x, y)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PixelJac {
    pub(crate) u: f64,
    pub(crate) v: f64,
    /// `[[du/dx, du/dy], [dv/dx, dv/dy]]`.
    pub(crate) j: [[f64; 2]; 2],
}

impl Lens {
    pub(crate) fn new(model: &CameraModel) -> Self {
        let i = model.intrinsics;
        let r = model.distortion.max_radius();
        Self {
            fx: i.fx,
            fy: i.fy,
            cx: i.cx,
            cy: i.cy,
            skew: i.skew,
            k: model.distortion.coefficients(),
            distorted: model.distortion.model() != DistortionModel::None,
            max_r2: r * r,
        }
    }

    /// `true` if the normalised point is inside the valid disc of the distortion.
    #[inline(always)]
    pub(crate) fn valid(&self, x: f64, y: f64) -> bool {
        let s = x * x + y * y;
        s < self.max_r2 || (!self.distorted && s.is_finite())
    }

    /// Pixel of a normalised point (no validity check).
    #[inline(always)]
    pub(crate) fn pixel(&self, x: f64, y: f64) -> (f64, f64) {
        let (xd, yd) = if self.distorted {
            let [k1, k2, p1, p2, k3, k4, k5, k6] = self.k;
            let s = x * x + y * y;
            let n = 1.0 + s * (k1 + s * (k2 + s * k3));
            let d = 1.0 + s * (k4 + s * (k5 + s * k6));
            let f = n / d;
            (
                x * f + 2.0 * p1 * x * y + p2 * (s + 2.0 * x * x),
                y * f + p1 * (s + 2.0 * y * y) + 2.0 * p2 * x * y,
            )
        } else {
            (x, y)
        };
        (
            self.fx * xd + self.skew * yd + self.cx,
            self.fy * yd + self.cy,
        )
    }

    /// Pixel of a normalised point with the Jacobian (no validity check).
    #[inline(always)]
    pub(crate) fn pixel_jac(&self, x: f64, y: f64) -> PixelJac {
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.k;
        let s = x * x + y * y;
        let n = 1.0 + s * (k1 + s * (k2 + s * k3));
        let d = 1.0 + s * (k4 + s * (k5 + s * k6));
        let dn = k1 + s * (2.0 * k2 + 3.0 * k3 * s);
        let dd = k4 + s * (2.0 * k5 + 3.0 * k6 * s);
        let f = n / d;
        let fs = (dn - f * dd) / d;
        let xd = x * f + 2.0 * p1 * x * y + p2 * (s + 2.0 * x * x);
        let yd = y * f + p1 * (s + 2.0 * y * y) + 2.0 * p2 * x * y;
        let cross = 2.0 * x * y * fs + 2.0 * p1 * x + 2.0 * p2 * y;
        let a = f + 2.0 * x * x * fs + 2.0 * p1 * y + 6.0 * p2 * x;
        let b = f + 2.0 * y * y * fs + 6.0 * p1 * y + 2.0 * p2 * x;
        // Distortion Jacobian [[a, cross], [cross, b]], then the intrinsics.
        PixelJac {
            u: self.fx * xd + self.skew * yd + self.cx,
            v: self.fy * yd + self.cy,
            j: [
                [
                    self.fx * a + self.skew * cross,
                    self.fx * cross + self.skew * b,
                ],
                [self.fy * cross, self.fy * b],
            ],
        }
    }

    /// The pinhole column plane `fx X + skew Y + (cx - u) Z = 0` (normal, in the lens frame)
    /// through the pixel column `u`, ignoring distortion: the start of the exact surface solve.
    #[inline(always)]
    pub(crate) fn column_plane(&self, u: f64) -> [f64; 3] {
        [self.fx, self.skew, self.cx - u]
    }

    /// The pinhole row plane `fy Y + (cy - v) Z = 0`.
    #[inline(always)]
    pub(crate) fn row_plane(&self, v: f64) -> [f64; 3] {
        [0.0, self.fy, self.cy - v]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use nalgebra::Point3;
    use sl_camera::{Distortion, ImageSize, Intrinsics};

    fn model() -> CameraModel {
        CameraModel::new(
            Intrinsics {
                fx: 1440.4,
                fy: 1437.1,
                cx: 667.8,
                cy: 354.2,
                skew: 0.7,
            },
            Distortion::from_opencv(&[-0.08, 0.12, 0.0004, -0.0003, 0.01, 0.02, -0.01, 0.003])
                .unwrap(),
            ImageSize::new(1280, 720),
        )
        .unwrap()
    }

    /// The inlined formulas give sl-camera's projection (to rounding: 1e-9 px) and a Jacobian
    /// equal to central differences (step 1e-6 in normalised units: truncation ~1e-12 · f,
    /// rounding ~1e-16 / 1e-6 · f ≈ 1e-7 px per unit, so 1e-3 px per normalised unit).
    #[test]
    fn matches_sl_camera_and_finite_differences() {
        let m = model();
        let lens = Lens::new(&m);
        for &(x, y) in &[(0.0, 0.0), (0.2, -0.1), (-0.35, 0.2), (0.4, 0.25)] {
            let reference = m.project(&Point3::new(x, y, 1.0)).unwrap();
            let (u, v) = lens.pixel(x, y);
            assert_abs_diff_eq!(u, reference.x, epsilon = 1e-9);
            assert_abs_diff_eq!(v, reference.y, epsilon = 1e-9);
            let pj = lens.pixel_jac(x, y);
            assert_abs_diff_eq!(pj.u, u, epsilon = 1e-9);
            assert_abs_diff_eq!(pj.v, v, epsilon = 1e-9);
            let h = 1e-6;
            let (u1, v1) = lens.pixel(x + h, y);
            let (u0, v0) = lens.pixel(x - h, y);
            assert_abs_diff_eq!(pj.j[0][0], (u1 - u0) / (2.0 * h), epsilon = 1e-3);
            assert_abs_diff_eq!(pj.j[1][0], (v1 - v0) / (2.0 * h), epsilon = 1e-3);
            let (u1, v1) = lens.pixel(x, y + h);
            let (u0, v0) = lens.pixel(x, y - h);
            assert_abs_diff_eq!(pj.j[0][1], (u1 - u0) / (2.0 * h), epsilon = 1e-3);
            assert_abs_diff_eq!(pj.j[1][1], (v1 - v0) / (2.0 * h), epsilon = 1e-3);
        }
    }
}
