//! The calibrated pair in the form the per-pixel solvers use: both lens models, the pose as
//! plain numbers, and the projector's ray table (built on first use).

use std::sync::OnceLock;

use nalgebra::{Isometry3, Point2};
use sl_camera::{CameraModel, RayTable};

/// Camera + projector, precomputed once per calibration.
#[derive(Clone, Debug)]
pub(crate) struct Stereo {
    pub(crate) cam: CameraModel,
    pub(crate) proj: CameraModel,
    /// Rotation of `T_proj_cam` (camera coordinates into projector coordinates), row-major.
    pub(crate) r_pc: [[f64; 3]; 3],
    /// Translation of `T_proj_cam` (mm).
    pub(crate) t_pc: [f64; 3],
    /// Rotation of `T_cam_proj`, row-major.
    pub(crate) r_cp: [[f64; 3]; 3],
    /// Projector centre in the camera frame (mm).
    pub(crate) c_p: [f64; 3],
    /// Undistorted rays of the projector's pixel centres, for the methods that use both
    /// decoded coordinates. Built on first use: ray–plane never needs it, and it is the
    /// larger half of the precomputation (the projector has more pixels than the camera).
    proj_rays: OnceLock<RayTable>,
}

fn rows(m: &nalgebra::Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// `m · v` for a row-major 3×3 matrix on plain numbers.
#[inline(always)]
pub(crate) fn mul(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    let [a, b, c] = m;
    [
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        b[0] * v[0] + b[1] * v[1] + b[2] * v[2],
        c[0] * v[0] + c[1] * v[1] + c[2] * v[2],
    ]
}

impl Stereo {
    pub(crate) fn new(cam: &CameraModel, proj: &CameraModel, t_cam_proj: &Isometry3<f64>) -> Self {
        let t_proj_cam = t_cam_proj.inverse();
        let t = t_proj_cam.translation.vector;
        let c = t_cam_proj.translation.vector;
        Self {
            cam: *cam,
            proj: *proj,
            r_pc: rows(t_proj_cam.rotation.to_rotation_matrix().matrix()),
            t_pc: [t.x, t.y, t.z],
            r_cp: rows(t_cam_proj.rotation.to_rotation_matrix().matrix()),
            c_p: [c.x, c.y, c.z],
            proj_rays: OnceLock::new(),
        }
    }

    /// The projector's ray table, computed on the first call.
    pub(crate) fn proj_rays(&self) -> &RayTable {
        self.proj_rays.get_or_init(|| self.proj.ray_table())
    }

    /// A point of the camera frame in the projector frame.
    #[inline(always)]
    pub(crate) fn to_proj(&self, p: [f64; 3]) -> [f64; 3] {
        let q = mul(&self.r_pc, p);
        [
            q[0] + self.t_pc[0],
            q[1] + self.t_pc[1],
            q[2] + self.t_pc[2],
        ]
    }

    /// Undistorted normalised projector coordinates of the decoded projector point `(c, r)`:
    /// bilinear interpolation in the projector's ray table (the inverse distortion is smooth:
    /// the interpolation error is below 1e-9 in normalised units for the lenses of
    /// structured-light projectors, see the tests), exact Newton undistortion where a table
    /// entry is missing. `None` (as NaN) where the projector model has no ray.
    ///
    /// Hand-written rather than a call per pixel to `CameraModel::unproject`: a Newton
    /// undistortion costs three to five distortion evaluations, the lookup four loads per
    /// axis from a table that the rows of a scan walk through in order.
    #[inline(always)]
    pub(crate) fn proj_normalised(&self, table: &RayTable, c: f64, r: f64) -> [f64; 2] {
        let size = table.size();
        let (w, h) = (size.width as usize, size.height as usize);
        if w >= 2 && h >= 2 && c > -1.0 && r > -1.0 {
            // Cell whose corners are the pixel centres around (c, r); edges extrapolate.
            let i0 = (c.floor().max(0.0) as usize).min(w - 2);
            let j0 = (r.floor().max(0.0) as usize).min(h - 2);
            let (fu, fv) = (c - i0 as f64, r - j0 as f64);
            let k = j0 * w + i0;
            let (xs, ys) = (table.xs(), table.ys());
            if let (Some(x0), Some(x1), Some(y0), Some(y1)) = (
                xs.get(k..k + 2),
                xs.get(k + w..k + w + 2),
                ys.get(k..k + 2),
                ys.get(k + w..k + w + 2),
            ) {
                let lerp = |a: &[f64], b: &[f64]| {
                    let (a0, a1, b0, b1) = (a[0], a[1], b[0], b[1]);
                    let top = a0 + fu * (a1 - a0);
                    let bottom = b0 + fu * (b1 - b0);
                    top + fv * (bottom - top)
                };
                let (x, y) = (lerp(x0, x1), lerp(y0, y1));
                if x.is_finite() && y.is_finite() {
                    return [x, y];
                }
            }
        }
        self.proj
            .unproject(&Point2::new(c, r))
            .map_or([f64::NAN; 2], |n| [n.x, n.y])
    }
}
