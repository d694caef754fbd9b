//! Linear least-squares triangulation (the seed design's DLT) from both projector
//! coordinates.
//!
//! With the camera ray `(xc, yc, 1)` and the undistorted projector point `(xp, yp)`, the
//! point `X` (camera frame) satisfies four linear equations, two per image:
//! `X - xc Z = 0`, `Y - yc Z = 0`, `(r1 - xp r3) · X + t1 - xp t3 = 0`,
//! `(r2 - yp r3) · X + t2 - yp t3 = 0` (`r_i`, `t_i` rows of `T_proj_cam`). This is the DLT
//! in inhomogeneous form (`W = 1`); the 4×3 system is solved by its 3×3 normal equations in
//! closed form — the same minimiser as an SVD of the 4×3 matrix, without the iterative
//! decomposition per pixel. Exact for exact data; with noise the algebraic error it
//! minimises is not the reprojection error (see [`crate::Method::Optimal`]).

use nalgebra::{Matrix3, Vector3};

use crate::stereo::Stereo;

/// The linear least-squares point (camera frame, mm), or `None` if the system is singular.
#[inline]
pub(crate) fn linear_point(
    s: &Stereo,
    ray: &Vector3<f64>,
    xp: f64,
    yp: f64,
) -> Option<Vector3<f64>> {
    let r = &s.r_pc;
    let t = &s.t_pc;
    let a1 = Vector3::new(1.0, 0.0, -ray.x);
    let a2 = Vector3::new(0.0, 1.0, -ray.y);
    let r1 = Vector3::new(r[(0, 0)], r[(0, 1)], r[(0, 2)]);
    let r2 = Vector3::new(r[(1, 0)], r[(1, 1)], r[(1, 2)]);
    let r3 = Vector3::new(r[(2, 0)], r[(2, 1)], r[(2, 2)]);
    let a3 = r1 - r3 * xp;
    let a4 = r2 - r3 * yp;
    let b3 = -(t.x - xp * t.z);
    let b4 = -(t.y - yp * t.z);
    let m: Matrix3<f64> =
        a1 * a1.transpose() + a2 * a2.transpose() + a3 * a3.transpose() + a4 * a4.transpose();
    let g = a3 * b3 + a4 * b4;
    let p = m.try_inverse()? * g;
    p.iter().all(|v| v.is_finite()).then_some(p)
}
