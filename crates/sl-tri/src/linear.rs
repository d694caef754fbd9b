//! Linear triangulation (the seed design's DLT) from both projector coordinates, or from the
//! one a capture codes.
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
//!
//! # One axis
//!
//! Most real captures code the projector columns only. The DLT then has three equations for
//! three unknowns — the two of the camera ray and `(r1 - xp r3) · X + t1 - xp t3 = 0` — and
//! its solution is the meeting of the camera ray with the pinhole plane of the undistorted
//! column `xp`: `Z = -(t1 - xp t3) / ((r1 - xp r3) · (xc, yc, 1))` ([`linear_one_axis_lanes`];
//! rows alike with `r2`, `t2`, `yp`). Undistorting a column needs the row too, which the
//! capture does not give; it is taken from the point itself by a fixed-point iteration: start
//! from the previous lane group's row (or the principal point), undistort `(c, row)`, solve,
//! project the point into the projector for its row, repeat until the row settles. At the
//! fixed point the point's distorted projection has exactly the decoded column, so the
//! answer is the exact meeting with the projector's curved column surface, i.e. the
//! ray–plane method's answer, reached by the linear route. The row moves the undistorted
//! column only through the distortion's cross terms (`k1 · 2 x y`, tangential terms: ~1e-2
//! of a px per px of row for projector lenses), so each iteration shrinks the row's error
//! a hundredfold and two or three iterations settle from a neighbour's row.

use crate::kernel::{LANES, PointLanes};
use crate::stereo::Stereo;
use crate::undistort::{UndistortWarm, undistort_lanes};
use sl_codec::Axis;

/// Most fixed-point iterations of the one-axis DLT. Each divides the error of the other
/// coordinate by ~100 (see the module docs): from the principal point (error up to ~1000 px)
/// five reach 1e-7 px; eight leave room for strong lenses. A lane not settled by then has
/// no point (`NoSolution`).
const MAX_ONE_AXIS_ITERATIONS: usize = 8;

/// Change of the other projector coordinate (px) below which the iteration has settled:
/// its effect on the undistorted decoded coordinate is ~1e-2 of it, 1e-9 px, far below the
/// f32 resolution of decoded coordinates (6e-5 px at 1920).
const ONE_AXIS_SETTLED_PX: f64 = 1e-7;

/// The other coordinate of the previous lane group, the warm start of the next.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LinearOneAxisState {
    /// The coded axis.
    axis: Axis,
    /// The other projector coordinate (px) per lane of the previous group (NaN where none).
    other: [f64; LANES],
    /// Where to start without a previous answer: the principal point's other coordinate.
    centre: f64,
}

impl LinearOneAxisState {
    /// No previous answer.
    pub(crate) fn new(s: &Stereo, axis: Axis) -> Self {
        let k = &s.proj.intrinsics;
        Self {
            axis,
            other: [f64::NAN; LANES],
            centre: if axis == Axis::Column { k.cy } else { k.cx },
        }
    }
}

/// The one-axis linear points (camera frame, mm) of [`LANES`] pixels: camera rays
/// `(rx, ry, 1)` and the decoded projector coordinate `target` (px) on the state's axis, NaN
/// for lanes not to solve (see the module docs). A lane is not `ok` if its equation is
/// singular, not finite, or the iteration did not settle.
#[inline(always)]
pub(crate) fn linear_one_axis_lanes(
    s: &Stereo,
    state: &mut LinearOneAxisState,
    rx: &[f64; LANES],
    ry: &[f64; LANES],
    target: &[f64; LANES],
    warm: &mut UndistortWarm,
) -> PointLanes {
    let column = state.axis == Axis::Column;
    let (ra, ta) = if column {
        (s.r_pc[0], s.t_pc[0])
    } else {
        (s.r_pc[1], s.t_pc[1])
    };
    let (r3, t3) = (s.r_pc[2], s.t_pc[2]);
    let mut other = [0.0; LANES];
    for l in 0..LANES {
        let o = state.other[l];
        other[l] = if o.is_finite() { o } else { state.centre };
    }
    let mut out = PointLanes::default();
    let mut settled = [false; LANES];
    for _ in 0..MAX_ONE_AXIS_ITERATIONS {
        let (xn, yn) = if column {
            undistort_lanes(&s.proj, target, &other, warm)
        } else {
            undistort_lanes(&s.proj, &other, target, warm)
        };
        let w = if column { xn } else { yn };
        let mut all = true;
        for l in 0..LANES {
            let (xc, yc) = (rx[l], ry[l]);
            let a = [
                ra[0] - w[l] * r3[0],
                ra[1] - w[l] * r3[1],
                ra[2] - w[l] * r3[2],
            ];
            let den = a[0] * xc + a[1] * yc + a[2];
            let z = -(ta - w[l] * t3) / den;
            out.x[l] = z * xc;
            out.y[l] = z * yc;
            out.z[l] = z;
            out.ok[l] = (den != 0.0) & z.is_finite() & xc.is_finite() & yc.is_finite();
            // The point's other projector coordinate, for the next undistortion.
            let q = s.to_proj([out.x[l], out.y[l], z]);
            let iq = 1.0 / q[2];
            let pp = s.proj.project_normalised(q[0] * iq, q[1] * iq);
            let next = if column { pp.y } else { pp.x };
            let change = (next - other[l]).abs();
            // NaN lanes (nothing to solve) count as settled; they are not `ok` anyway.
            settled[l] = !(change >= ONE_AXIS_SETTLED_PX);
            all &= settled[l];
            other[l] = next;
        }
        if all {
            break;
        }
    }
    for l in 0..LANES {
        out.ok[l] &= settled[l];
        state.other[l] = if out.ok[l] { other[l] } else { f64::NAN };
    }
    out
}

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
