//! Ray–plane triangulation with one decoded projector coordinate, projector distortion
//! included: the camera ray is intersected with the projector's exact (curved) column or row
//! surface.
//!
//! The projector rays whose pixel column is `c` form a plane only without distortion; with
//! distortion they form a curved surface. Along the camera ray `p(t) = t · ray` (`t` is the
//! depth in mm), the projector column `u(t)` of `p(t)` is a smooth function; the solver starts
//! from the pinhole column plane (closed form) and finishes with Newton's method on
//! `u(t) = c`, with the analytic derivative of the distorted projection. No undistortion and
//! no guess of the row is needed, so the answer is exact for the full OpenCV model.

use nalgebra::Vector3;
use sl_codec::Axis;

use crate::stereo::Stereo;

/// Newton iterations allowed on the projector surface. From the pinhole plane the depth is off
/// by the distortion (a few px, i.e. a few mm); Newton then converges quadratically, in 2–3
/// steps for projector lenses, so 12 leaves room for strong ones.
const MAX_SURFACE_ITERATIONS: usize = 12;

/// Depth step (mm) at which Newton stops: quadratic convergence means the depth is then
/// exact to far below 1e-9 mm.
const SURFACE_STEP_TOLERANCE_MM: f64 = 1e-6;

/// Depth `t` (mm; the point is `t · ray`) at which the camera ray `ray = (x, y, 1)` meets the
/// projector surface of coordinate `target` on `axis`. `None` if the ray misses it in front
/// of both devices or leaves the projector's valid region.
#[inline]
pub(crate) fn ray_surface_depth(
    s: &Stereo,
    ray: &Vector3<f64>,
    target: f64,
    axis: Axis,
) -> Option<f64> {
    let a = s.r_pc * ray;
    let b = s.t_pc;
    let n = match axis {
        Axis::Column => s.proj.column_plane(target),
        Axis::Row => s.proj.row_plane(target),
    };
    let n = Vector3::new(n[0], n[1], n[2]);
    let na = n.dot(&a);
    let mut t = -n.dot(&b) / na;
    if !t.is_finite() {
        return None;
    }
    for _ in 0..MAX_SURFACE_ITERATIONS {
        let q = a * t + b;
        if !(q.z > 0.0) || !(t > 0.0) {
            return None;
        }
        let (x, y) = (q.x / q.z, q.y / q.z);
        if !s.proj.valid(x, y) {
            return None;
        }
        let pj = s.proj.pixel_jac(x, y);
        let dx = (a.x - x * a.z) / q.z;
        let dy = (a.y - y * a.z) / q.z;
        let (value, slope) = match axis {
            Axis::Column => (pj.u, pj.j[0][0] * dx + pj.j[0][1] * dy),
            Axis::Row => (pj.v, pj.j[1][0] * dx + pj.j[1][1] * dy),
        };
        let step = (value - target) / slope;
        if !step.is_finite() {
            return None;
        }
        t -= step;
        if step.abs() < SURFACE_STEP_TOLERANCE_MM {
            let q = a * t + b;
            return (t > 0.0 && q.z > 0.0 && s.proj.valid(q.x / q.z, q.y / q.z)).then_some(t);
        }
    }
    None
}
