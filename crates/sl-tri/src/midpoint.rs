//! Midpoint triangulation: the point halfway between the closest points of the camera ray
//! and the projector ray (both undistorted), in closed form.
//!
//! Hand-written on [`LANES`] pixels at once, branch-free, so that it is vectorised.

use crate::kernel::{LANES, PointLanes};
use crate::stereo::{Stereo, mul};

/// The midpoints (camera frame, mm) of [`LANES`] pixels: camera rays `(rx, ry, 1)`,
/// undistorted projector points `(xp, yp)`. A lane is not `ok` for parallel rays or a closest
/// point behind either device.
#[inline(always)]
pub(crate) fn midpoint_lanes(
    s: &Stereo,
    rx: &[f64; LANES],
    ry: &[f64; LANES],
    xp: &[f64; LANES],
    yp: &[f64; LANES],
) -> PointLanes {
    let mut out = PointLanes::default();
    let c = s.c_p;
    let w0 = [-c[0], -c[1], -c[2]];
    let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    for l in 0..LANES {
        let d1 = [rx[l], ry[l], 1.0];
        let d2 = mul(&s.r_cp, [xp[l], yp[l], 1.0]);
        let a = dot(d1, d1);
        let b = dot(d1, d2);
        let cc = dot(d2, d2);
        let d = dot(d1, w0);
        let e = dot(d2, w0);
        let inv = 1.0 / (a * cc - b * b);
        let t1 = (b * e - cc * d) * inv;
        let t2 = (a * e - b * d) * inv;
        out.x[l] = (d1[0] * t1 + c[0] + d2[0] * t2) * 0.5;
        out.y[l] = (d1[1] * t1 + c[1] + d2[1] * t2) * 0.5;
        out.z[l] = (d1[2] * t1 + c[2] + d2[2] * t2) * 0.5;
        out.ok[l] = (t1 > 0.0) & (t2 > 0.0) & t1.is_finite() & t2.is_finite();
    }
    out
}
