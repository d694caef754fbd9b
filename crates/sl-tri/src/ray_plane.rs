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
//!
//! Two forms of the same iteration: [`ray_surface_lanes`] runs a fixed number of Newton steps
//! on [`LANES`] pixels at once without branches, so that the compiler vectorises it (it is
//! the hot loop of the default method, hand-written for that reason: an early exit per pixel
//! would keep it scalar); [`ray_surface_depth`] is the general iteration with every check at
//! every step, used for the few pixels whose lanes did not converge.

use sl_camera::PixelJacobian;
use sl_codec::Axis;

use crate::kernel::LANES;
use crate::stereo::Stereo;

/// Newton iterations allowed on the projector surface by the general solver. From the pinhole
/// plane the depth is off by the distortion (a few px, i.e. a few mm); Newton then converges
/// quadratically, in 3 steps for projector lenses, so 12 leaves room for strong ones.
const MAX_SURFACE_ITERATIONS: usize = 12;

/// Most Newton steps of the branch-free solver. The group stops as soon as every lane's last
/// step is below [`SURFACE_STEP_TOLERANCE_MM`] (the same test as the general solver's, so a
/// lane accepted after one step is as converged as one accepted after three). From the
/// extrapolated depths of the previous lane groups the error e0 is ~0 on a surface whose
/// depth is linear along the row (a wall facing the camera: one step) and ≲ 0.03 mm on
/// smooth curved surfaces, where the errors go as κ·e0² with κ = |u''/2u'| ≈ 1/depth:
/// 0.03 mm → 2e-6 mm (two steps). From the pinhole plane (error of a few mm: 4.5 mm →
/// 0.05 mm → 5e-6 mm) three steps are needed; lanes still not converged go to the general
/// solver.
const MAX_LANE_SURFACE_STEPS: usize = 3;

/// Depth step (mm) below which Newton has converged. The error left after a step `s` is
/// about κ·s² with κ = |u''/2u'|: for the pinhole part of the projection u(t) is a Möbius
/// function of the depth and κ = |`a_z`/`q_z`| ≤ 1/(projector depth), below 1/50 mm⁻¹ for any
/// rig; the distortion adds a curvature of the same order. So a step of 1e-4 mm leaves
/// an error below ~1e-9 mm, far below the f32 resolution of the decoded input (~1e-5 mm).
const SURFACE_STEP_TOLERANCE_MM: f64 = 1e-4;

/// A camera ray's meeting with a projector surface.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SurfaceHit {
    /// Depth (mm); the point is `t · ray`.
    pub(crate) t: f64,
    /// The other projector coordinate at the point (the row on a column surface), px.
    pub(crate) other: f64,
}

/// [`ray_surface_lanes`]' answer per lane.
pub(crate) struct SurfaceLanes {
    pub(crate) t: [f64; LANES],
    pub(crate) other: [f64; LANES],
    /// Converged inside the projector's valid region, in front of both devices.
    pub(crate) ok: [bool; LANES],
}

/// The pinhole plane `n · q = 0` (projector frame) through the decoded coordinate `target`.
#[inline(always)]
fn pinhole_plane(s: &Stereo, column: bool, target: f64) -> [f64; 3] {
    let k = &s.proj.intrinsics;
    if column {
        [k.fx, k.skew, k.cx - target]
    } else {
        [0.0, k.fy, k.cy - target]
    }
}

/// Value and slope (per mm of depth) of the decoded and of the other coordinate.
#[inline(always)]
fn coordinates(column: bool, pj: &PixelJacobian, dx: f64, dy: f64) -> [f64; 4] {
    let du = pj.du_dx * dx + pj.du_dy * dy;
    let dv = pj.dv_dx * dx + pj.dv_dy * dy;
    if column {
        [pj.u, du, pj.v, dv]
    } else {
        [pj.v, dv, pj.u, du]
    }
}

/// One Newton step at depth `t` along `q(t) = a t + b`: the new depth, the step, and the other
/// coordinate at the new depth (to first order, which is exact to the order of the error).
#[inline(always)]
fn newton_step(
    s: &Stereo,
    column: bool,
    a: [f64; 3],
    b: [f64; 3],
    t: f64,
    target: f64,
) -> [f64; 3] {
    let q = [a[0] * t + b[0], a[1] * t + b[1], a[2] * t + b[2]];
    let iz = 1.0 / q[2];
    let (x, y) = (q[0] * iz, q[1] * iz);
    let pj = s.proj.project_normalised_with_jacobian(x, y);
    let dx = (a[0] - x * a[2]) * iz;
    let dy = (a[1] - y * a[2]) * iz;
    let [value, slope, other, other_slope] = coordinates(column, &pj, dx, dy);
    let step = (value - target) / slope;
    [t - step, step, other - other_slope * step]
}

/// Whether depth `t` on `q(t) = a t + b` is in front of both devices and inside the
/// projector's valid region.
#[inline(always)]
fn in_front_and_valid(s: &Stereo, a: [f64; 3], b: [f64; 3], t: f64) -> bool {
    let q = [a[0] * t + b[0], a[1] * t + b[1], a[2] * t + b[2]];
    let iz = 1.0 / q[2];
    (t > 0.0) & (q[2] > 0.0) & s.proj.in_valid_region(q[0] * iz, q[1] * iz)
}

/// The surface solve on [`LANES`] camera rays `(rx, ry, 1)` at once, branch-free inside a
/// step: the start (`guess` where it is not NaN, else the pinhole plane), then Newton steps on all
/// lanes until every lane has settled, at most [`MAX_LANE_SURFACE_STEPS`]; a lane is `ok` if
/// its last step is below the tolerance and the point is valid. NaN inputs give lanes that
/// are not ok (and do not hold the group's other lanes back).
#[inline(always)]
pub(crate) fn ray_surface_lanes(
    s: &Stereo,
    axis: Axis,
    rx: &[f64; LANES],
    ry: &[f64; LANES],
    target: &[f64; LANES],
    guess: &[f64; LANES],
) -> SurfaceLanes {
    let column = axis == Axis::Column;
    let b = s.t_pc;
    // Step-major: each loop below runs one stage on all lanes, a straight-line body the
    // compiler vectorises (a lane-major loop around the Newton loop would be an outer loop,
    // which it does not vectorise, and a latency-bound chain of divisions per pixel).
    let mut a = [[0.0; 3]; LANES];
    let mut t = *guess;
    for l in 0..LANES {
        a[l] = crate::stereo::mul(&s.r_pc, [rx[l], ry[l], 1.0]);
    }
    // The pinhole-plane start only where there is no guess (NaN: the start of a block, or
    // after a hole): a warm row skips its division. (Guesses are finite or NaN; the test is
    // `is_nan` because valgrind, which the instruction counts of docs/triangulation.md come
    // from, mis-evaluated the vectorised `is_finite` select here: lanes 2–7 of a cold group
    // became NaN under valgrind only, never natively.)
    if t.iter().any(|t| t.is_nan()) {
        for l in 0..LANES {
            let n = pinhole_plane(s, column, target[l]);
            let plane = -(n[0] * b[0] + n[1] * b[1] + n[2] * b[2])
                / (n[0] * a[l][0] + n[1] * a[l][1] + n[2] * a[l][2]);
            t[l] = if t[l].is_nan() { plane } else { t[l] };
        }
    }
    let mut step = [f64::INFINITY; LANES];
    let mut other = [f64::NAN; LANES];
    for _ in 0..MAX_LANE_SURFACE_STEPS {
        for l in 0..LANES {
            [t[l], step[l], other[l]] = newton_step(s, column, a[l], b, t[l], target[l]);
        }
        // Settled: below the tolerance, or NaN (a lane without input, or one that failed and
        // goes to the general solver: another step would not help it).
        if step.iter().all(|s| !(s.abs() >= SURFACE_STEP_TOLERANCE_MM)) {
            break;
        }
    }
    let mut ok = [false; LANES];
    for l in 0..LANES {
        ok[l] = (step[l].abs() < SURFACE_STEP_TOLERANCE_MM) & in_front_and_valid(s, a[l], b, t[l]);
    }
    SurfaceLanes { t, other, ok }
}

/// The general solver: depth `t` (mm; the point is `t · ray`) at which the camera ray
/// `(rx, ry, 1)` meets the projector surface of coordinate `target` on `axis`, with every
/// check at every step. `None` if the ray misses it in front of both devices or leaves the
/// projector's valid region.
#[inline(never)]
pub(crate) fn ray_surface_depth(
    s: &Stereo,
    rx: f64,
    ry: f64,
    target: f64,
    axis: Axis,
) -> Option<SurfaceHit> {
    let column = axis == Axis::Column;
    let a = crate::stereo::mul(&s.r_pc, [rx, ry, 1.0]);
    let b = s.t_pc;
    let n = pinhole_plane(s, column, target);
    let mut t =
        -(n[0] * b[0] + n[1] * b[1] + n[2] * b[2]) / (n[0] * a[0] + n[1] * a[1] + n[2] * a[2]);
    if !t.is_finite() {
        return None;
    }
    for _ in 0..MAX_SURFACE_ITERATIONS {
        if !in_front_and_valid(s, a, b, t) {
            return None;
        }
        let [next, step, other] = newton_step(s, column, a, b, t, target);
        if !step.is_finite() {
            return None;
        }
        t = next;
        if step.abs() < SURFACE_STEP_TOLERANCE_MM {
            return in_front_and_valid(s, a, b, t).then_some(SurfaceHit { t, other });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
    use rand::{Rng, SeedableRng};
    use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};

    /// The branch-free lanes give the general solver's depth (both converge to the same
    /// root: 1e-8 mm is ~1e4 ulps of 450 mm, far above their rounding and far below any
    /// wrong root) from any start: none (pinhole plane), a good guess, or a bad one (the
    /// wrong side of a 60 mm jump); lanes that cannot settle say so rather than answer.
    #[test]
    fn lanes_agree_with_the_general_solver() {
        let cam = CameraModel::new(
            Intrinsics::new(1400.0, 1400.0, 640.0, 360.0),
            Distortion::from_opencv(&[-0.1, 0.15, 0.0005, -0.0004, 0.0]).unwrap(),
            ImageSize::new(1280, 720),
        )
        .unwrap();
        let proj = CameraModel::new(
            Intrinsics::new(2000.0, 2000.0, 960.0, 1050.0),
            Distortion::from_opencv(&[0.06, -0.08, 0.001, 0.0, 0.0]).unwrap(),
            ImageSize::new(1920, 1080),
        )
        .unwrap();
        let pose = Isometry3::from_parts(
            Translation3::new(180.0, 0.0, 20.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -0.35),
        );
        let s = Stereo::new(&cam, &proj, &pose);
        let t_proj_cam = pose.inverse();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut settled = 0;
        let mut per = [0; 3];
        for _ in 0..200 {
            let (mut rx, mut ry, mut target, mut depth) =
                ([0.0; LANES], [0.0; LANES], [f64::NAN; LANES], [0.0; LANES]);
            for l in 0..LANES {
                let px = Point2::new(rng.random_range(0.0..1280.0), rng.random_range(0.0..720.0));
                let ray = cam.unproject(&px).unwrap();
                depth[l] = rng.random_range(300.0..700.0);
                (rx[l], ry[l]) = (ray.x, ray.y);
                if let Some(pp) = proj.project(&(t_proj_cam * Point3::from(ray * depth[l]))) {
                    target[l] = pp.x;
                }
            }
            let good: [f64; LANES] = std::array::from_fn(|l| depth[l] + 0.02);
            let bad: [f64; LANES] = std::array::from_fn(|l| depth[l] + 60.0);
            for (k, guess) in [[f64::NAN; LANES], good, bad].into_iter().enumerate() {
                let out = ray_surface_lanes(&s, Axis::Column, &rx, &ry, &target, &guess);
                per[k] += out.ok.iter().filter(|o| **o).count();
                for l in 0..LANES {
                    let general = ray_surface_depth(&s, rx[l], ry[l], target[l], Axis::Column);
                    if out.ok[l] {
                        settled += 1;
                        let g = general.expect("the general solver finds what the lanes found");
                        assert!((out.t[l] - g.t).abs() < 1e-8, "{} vs {}", out.t[l], g.t);
                        assert!((out.t[l] - depth[l]).abs() < 1e-6);
                        assert!((out.other[l] - g.other).abs() < 1e-6);
                    }
                }
            }
        }
        // Nearly every lane settles without the general solver.
        // From the pinhole plane (3 steps) and from a good guess (2 steps) nearly every lane
        // settles; from a guess 60 mm off (errors 60 → 8 → 0.14 mm) three steps are not
        // enough, and those lanes are left to the general solver.
        let n = 200 * LANES;
        assert!(per[0] >= n * 99 / 100 && per[1] >= n * 99 / 100, "{per:?}");
        assert!(settled >= per[0] + per[1]);
    }
}
