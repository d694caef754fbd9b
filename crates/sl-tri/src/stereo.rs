//! The calibrated pair in the form the per-pixel solvers use: both lenses, the pose, and the
//! projector's ray table.

use nalgebra::{Matrix3, Point2, Vector3};
use sl_camera::{CameraModel, RayTable};

use crate::lens::Lens;

/// Camera + projector, precomputed once per calibration.
#[derive(Clone, Debug)]
pub(crate) struct Stereo {
    pub(crate) cam: Lens,
    pub(crate) proj: Lens,
    /// Rotation of `T_proj_cam` (camera coordinates into projector coordinates).
    pub(crate) r_pc: Matrix3<f64>,
    /// Translation of `T_proj_cam` (mm).
    pub(crate) t_pc: Vector3<f64>,
    /// Rotation of `T_cam_proj`.
    pub(crate) r_cp: Matrix3<f64>,
    /// Projector centre in the camera frame (mm).
    pub(crate) c_p: Vector3<f64>,
    /// The projector model (for exact undistortion where the table has no entry).
    pub(crate) proj_model: CameraModel,
    /// Undistorted rays of the projector's pixel centres.
    pub(crate) proj_rays: RayTable,
}

impl Stereo {
    /// Undistorted normalised projector coordinates of the decoded projector point `(c, r)`:
    /// bilinear interpolation in the projector's ray table (the inverse distortion is smooth:
    /// the interpolation error is below 1e-9 in normalised units for the lenses of
    /// structured-light projectors, see the tests), exact Newton undistortion where a table
    /// entry is missing.
    #[inline]
    pub(crate) fn proj_normalised(&self, c: f64, r: f64) -> Option<(f64, f64)> {
        let size = self.proj_rays.size();
        let (w, h) = (size.width as usize, size.height as usize);
        if w >= 2 && h >= 2 && c > -1.0 && r > -1.0 {
            // Cell whose corners are the pixel centres around (c, r); edges extrapolate.
            let i0 = (c.floor().max(0.0) as usize).min(w - 2);
            let j0 = (r.floor().max(0.0) as usize).min(h - 2);
            let (fu, fv) = (c - i0 as f64, r - j0 as f64);
            let table = self.proj_rays.as_slice();
            let k = j0 * w + i0;
            if let (Some(Some(a)), Some(Some(b)), Some(Some(cc)), Some(Some(d))) = (
                table.get(k),
                table.get(k + 1),
                table.get(k + w),
                table.get(k + w + 1),
            ) {
                let top = (a.x + fu * (b.x - a.x), a.y + fu * (b.y - a.y));
                let bottom = (cc.x + fu * (d.x - cc.x), cc.y + fu * (d.y - cc.y));
                return Some((
                    top.0 + fv * (bottom.0 - top.0),
                    top.1 + fv * (bottom.1 - top.1),
                ));
            }
        }
        let n = self.proj_model.unproject(&Point2::new(c, r))?;
        Some((n.x, n.y))
    }

    /// Reprojection error of a camera-frame point: the root mean square of the image
    /// distances in the camera (to the pixel centre `(u, v)`) and in the projector (to the
    /// decoded `(c, r)`; a NaN coordinate is left out), over the two images, in pixels.
    /// `None` if the point does not project.
    #[inline]
    pub(crate) fn reprojection(
        &self,
        p: &Vector3<f64>,
        u: f64,
        v: f64,
        c: f64,
        r: f64,
    ) -> Option<f64> {
        if !(p.z > 0.0) {
            return None;
        }
        let (x, y) = (p.x / p.z, p.y / p.z);
        let (pu, pv) = self.cam.pixel(x, y);
        let q = self.r_pc * p + self.t_pc;
        if !(q.z > 0.0) {
            return None;
        }
        let (qx, qy) = (q.x / q.z, q.y / q.z);
        if !self.proj.valid(qx, qy) {
            return None;
        }
        let (qu, qv) = self.proj.pixel(qx, qy);
        let mut e2 = (pu - u).powi(2) + (pv - v).powi(2);
        if c.is_finite() {
            e2 += (qu - c).powi(2);
        }
        if r.is_finite() {
            e2 += (qv - r).powi(2);
        }
        Some((e2 / 2.0).sqrt())
    }
}
