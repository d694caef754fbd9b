//! The calibrated pair in the form the per-pixel solvers use: both lens models, the pose as
//! plain numbers.

use nalgebra::Isometry3;
use sl_camera::CameraModel;

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
        }
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
}
