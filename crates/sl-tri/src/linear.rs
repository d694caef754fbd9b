//! Linear least-squares triangulation (the seed design's DLT) from both projector
//! coordinates.
//!
//! With the camera ray `(xc, yc, 1)` and the undistorted projector point `(xp, yp)`, the
//! point `X` (camera frame) satisfies four linear equations, two per image:
//! `X - xc Z = 0`, `Y - yc Z = 0`, `(r1 - xp r3) · X + t1 - xp t3 = 0`,
//! `(r2 - yp r3) · X + t2 - yp t3 = 0` (`r_i`, `t_i` rows of `T_proj_cam`). This is the DLT
//! in inhomogeneous form (`W = 1`); the 4×3 system is solved by its 3×3 normal equations in
//! closed form (adjugate over determinant) — the same minimiser as an SVD of the 4×3 matrix,
//! without the iterative decomposition per pixel. Exact for exact data; with noise the
//! algebraic error it minimises is not the reprojection error (see [`crate::Method::Optimal`]).
//!
//! Hand-written on [`LANES`] pixels at once with plain numbers and no branch, so that it is
//! vectorised; a 3×3 matrix inverse per pixel through a general routine would not be.

use crate::kernel::{LANES, PointLanes};
use crate::stereo::Stereo;

/// The linear least-squares points (camera frame, mm) of [`LANES`] pixels: camera rays
/// `(rx, ry, 1)`, undistorted projector points `(xp, yp)`. A lane is not `ok` if its system
/// is singular or not finite.
#[inline(always)]
pub(crate) fn linear_lanes(
    s: &Stereo,
    rx: &[f64; LANES],
    ry: &[f64; LANES],
    xp: &[f64; LANES],
    yp: &[f64; LANES],
) -> PointLanes {
    let mut out = PointLanes::default();
    let [r1, r2, r3] = s.r_pc;
    let t = s.t_pc;
    for l in 0..LANES {
        let (xc, yc, xp, yp) = (rx[l], ry[l], xp[l], yp[l]);
        let a3 = [r1[0] - xp * r3[0], r1[1] - xp * r3[1], r1[2] - xp * r3[2]];
        let a4 = [r2[0] - yp * r3[0], r2[1] - yp * r3[1], r2[2] - yp * r3[2]];
        let b3 = -(t[0] - xp * t[2]);
        let b4 = -(t[1] - yp * t[2]);
        // Normal equations M p = g with M = Σ a_i a_iᵀ (a1 = (1, 0, -xc), a2 = (0, 1, -yc)).
        let m00 = 1.0 + a3[0] * a3[0] + a4[0] * a4[0];
        let m01 = a3[0] * a3[1] + a4[0] * a4[1];
        let m02 = -xc + a3[0] * a3[2] + a4[0] * a4[2];
        let m11 = 1.0 + a3[1] * a3[1] + a4[1] * a4[1];
        let m12 = -yc + a3[1] * a3[2] + a4[1] * a4[2];
        let m22 = xc * xc + yc * yc + a3[2] * a3[2] + a4[2] * a4[2];
        let g = [
            a3[0] * b3 + a4[0] * b4,
            a3[1] * b3 + a4[1] * b4,
            a3[2] * b3 + a4[2] * b4,
        ];
        // Adjugate of the symmetric M.
        let c00 = m11 * m22 - m12 * m12;
        let c01 = m02 * m12 - m01 * m22;
        let c02 = m01 * m12 - m02 * m11;
        let c11 = m00 * m22 - m02 * m02;
        let c12 = m01 * m02 - m00 * m12;
        let c22 = m00 * m11 - m01 * m01;
        let det = m00 * c00 + m01 * c01 + m02 * c02;
        let inv = 1.0 / det;
        let p = [
            (c00 * g[0] + c01 * g[1] + c02 * g[2]) * inv,
            (c01 * g[0] + c11 * g[1] + c12 * g[2]) * inv,
            (c02 * g[0] + c12 * g[1] + c22 * g[2]) * inv,
        ];
        out.x[l] = p[0];
        out.y[l] = p[1];
        out.z[l] = p[2];
        out.ok[l] = (det != 0.0) & p[0].is_finite() & p[1].is_finite() & p[2].is_finite();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Matrix4x3, Translation3, UnitQuaternion, Vector3, Vector4};
    use rand::{Rng, SeedableRng};
    use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};

    /// The closed form equals an independent least-squares solution of the same 4×3 system
    /// (nalgebra's SVD), for noisy (inconsistent) inputs. The normal equations square the
    /// condition number (~1e3 here), so agreement to 1e-8 relative is what f64 allows.
    #[test]
    fn closed_form_equals_svd_least_squares() {
        let model = CameraModel::new(
            Intrinsics::new(1000.0, 1000.0, 640.0, 360.0),
            Distortion::none(),
            ImageSize::new(1280, 720),
        )
        .unwrap();
        let pose = Isometry3::from_parts(
            Translation3::new(150.0, 10.0, 5.0),
            UnitQuaternion::from_euler_angles(0.01, -0.3, 0.02),
        );
        let s = Stereo::new(&model, &model, &pose);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
        let (mut rx, mut ry, mut xp, mut yp) =
            ([0.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
        for l in 0..LANES {
            rx[l] = rng.random_range(-0.5..0.5);
            ry[l] = rng.random_range(-0.3..0.3);
            xp[l] = rng.random_range(-0.5..0.5);
            yp[l] = rng.random_range(-0.3..0.3);
        }
        let out = linear_lanes(&s, &rx, &ry, &xp, &yp);
        let r = pose.inverse().rotation.to_rotation_matrix().into_inner();
        let t = pose.inverse().translation.vector;
        for l in 0..LANES {
            let a3 = r.row(0) - r.row(2) * xp[l];
            let a4 = r.row(1) - r.row(2) * yp[l];
            let a = Matrix4x3::from_rows(&[
                Vector3::new(1.0, 0.0, -rx[l]).transpose(),
                Vector3::new(0.0, 1.0, -ry[l]).transpose(),
                a3,
                a4,
            ]);
            let b = Vector4::new(0.0, 0.0, -(t.x - xp[l] * t.z), -(t.y - yp[l] * t.z));
            let reference = a.svd(true, true).solve(&b, 1e-15).unwrap();
            assert!(out.ok[l]);
            let got = Vector3::new(out.x[l], out.y[l], out.z[l]);
            assert!(
                (got - reference).norm() <= 1e-8 * reference.norm(),
                "lane {l}: {got:?} vs {reference:?}"
            );
        }
    }
}
