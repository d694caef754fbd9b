//! Undistortion of decoded projector coordinates on [`LANES`] pixels at once, for the methods
//! that use both coordinates (linear, midpoint).
//!
//! A decoded point `(c, r)` is a projector pixel; the methods need its undistorted normalised
//! point `p` with `distort(p) = K⁻¹ (c, r, 1)`. Newton's method on that equation, branch-free
//! on the lanes (so that it is vectorised), started from the previous lane group's answer for
//! the same lane shifted by the change of the distorted point (neighbouring camera pixels see
//! neighbouring projector pixels, so the start is within ~1e-4 of the answer and two steps
//! reach rounding level), or from the distorted point itself where there is no previous
//! answer. Every lane is then checked as `sl_camera`'s own undistortion checks its answer
//! (residual below the same tolerance, inside the valid disc); lanes that fail the check take
//! the general scalar undistortion ([`sl_camera::CameraModel::unproject`]), so the answers
//! are those of the careful solver.
//!
//! This replaces a bilinear lookup in a full-resolution table of the projector's rays: the
//! table cost ~90 ms to build at the first call of a method and four scattered loads per
//! coordinate per pixel, which kept the lookup scalar; the Newton steps are a few dozen
//! vectorised operations and need no table.

use nalgebra::Point2;
use sl_camera::CameraModel;

use crate::kernel::LANES;

/// Most Newton steps on the lanes. From the warm start (error ~1e-4 normalised, the
/// distortion's gradient times the projector step between lane groups) the errors go as
/// C·e² with C ≈ |D²distort| / 2 ≲ 0.1 for projector lenses: 1e-4 → 1e-9 → 1e-19, two steps;
/// from the distorted point (error = the distortion itself, up to ~1e-2) four steps. The group
/// stops when every lane's step is below [`SETTLED_STEP`].
const MAX_LANE_STEPS: usize = 4;

/// Newton step (normalised units) below which a lane has settled: the error left after a
/// step `s` is about C·s², below 1e-17 for C ≤ 0.1, i.e. at rounding level. (Whether the
/// answer is accepted is decided by the residual check, not by this.)
const SETTLED_STEP: f64 = 1e-9;

/// Accepted residual `|distort(p) − pd|` (normalised units, relative to `max(1, |pd|)`): the
/// tolerance of `sl_camera`'s own undistortion (1e-13, i.e. 1e-10 px at a focal length of
/// 1000 px).
const RESIDUAL_TOLERANCE: f64 = 1e-13;

/// The answers of the previous lane group, the warm start of the next.
#[derive(Clone, Copy, Debug)]
pub(crate) struct UndistortWarm {
    /// Undistorted normalised point per lane (NaN where none).
    x: [f64; LANES],
    y: [f64; LANES],
    /// The distorted normalised point it solved.
    xd: [f64; LANES],
    yd: [f64; LANES],
}

impl Default for UndistortWarm {
    fn default() -> Self {
        Self {
            x: [f64::NAN; LANES],
            y: [f64::NAN; LANES],
            xd: [f64::NAN; LANES],
            yd: [f64::NAN; LANES],
        }
    }
}

/// Undistorted normalised points `(x, y)` of the projector pixels `(c, r)` of [`LANES`]
/// pixels; NaN where `(c, r)` is NaN or the lens has no ray there. `warm` is updated with
/// this group's answers.
#[inline(always)]
pub(crate) fn undistort_lanes(
    lens: &CameraModel,
    c: &[f64; LANES],
    r: &[f64; LANES],
    warm: &mut UndistortWarm,
) -> ([f64; LANES], [f64; LANES]) {
    let k = &lens.intrinsics;
    let (ifx, ify) = (1.0 / k.fx, 1.0 / k.fy);
    let mut xd = [0.0; LANES];
    let mut yd = [0.0; LANES];
    let mut x = [0.0; LANES];
    let mut y = [0.0; LANES];
    for l in 0..LANES {
        // K⁻¹ (c, r, 1), as `Intrinsics::normalised_from_pixel` (by multiplications with the
        // reciprocals: the difference is a rounding of the input, far below the f32
        // resolution of decoded coordinates).
        yd[l] = (r[l] - k.cy) * ify;
        xd[l] = (c[l] - k.cx - k.skew * yd[l]) * ifx;
        let gx = warm.x[l] + (xd[l] - warm.xd[l]);
        let gy = warm.y[l] + (yd[l] - warm.yd[l]);
        let warm_ok = gx.is_finite() & gy.is_finite();
        x[l] = if warm_ok { gx } else { xd[l] };
        y[l] = if warm_ok { gy } else { yd[l] };
    }
    let d = &lens.distortion;
    for _ in 0..MAX_LANE_STEPS {
        let mut settled = true;
        for l in 0..LANES {
            let ([fx, fy], [[a, b], [c2, e]]) = d.distort_xy_with_jacobian(x[l], y[l]);
            let (rx, ry) = (fx - xd[l], fy - yd[l]);
            let inv = 1.0 / (a * e - b * c2);
            let sx = (e * rx - b * ry) * inv;
            let sy = (a * ry - c2 * rx) * inv;
            x[l] -= sx;
            y[l] -= sy;
            // NaN steps count as settled: another step would not help that lane.
            settled &= !(sx.abs().max(sy.abs()) >= SETTLED_STEP);
        }
        if settled {
            break;
        }
    }
    // The acceptance test of `Distortion::undistort`: residual and valid disc.
    let mut ok = [false; LANES];
    for l in 0..LANES {
        let [fx, fy] = d.distort_xy(x[l], y[l]);
        let (rx, ry) = (fx - xd[l], fy - yd[l]);
        let scale = (xd[l] * xd[l] + yd[l] * yd[l]).max(1.0);
        ok[l] = (rx * rx + ry * ry <= RESIDUAL_TOLERANCE * RESIDUAL_TOLERANCE * scale)
            & lens.in_valid_region(x[l], y[l]);
    }
    for l in 0..LANES {
        if !ok[l] && c[l].is_finite() && r[l].is_finite() {
            // The general solver (rare: the edge of the valid disc, strong lenses).
            (x[l], y[l]) = lens
                .unproject(&Point2::new(c[l], r[l]))
                .map_or((f64::NAN, f64::NAN), |n| (n.x, n.y));
        } else if !ok[l] {
            (x[l], y[l]) = (f64::NAN, f64::NAN);
        }
    }
    warm.x = x;
    warm.y = y;
    warm.xd = xd;
    warm.yd = yd;
    (x, y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use sl_camera::{Distortion, ImageSize, Intrinsics};

    /// Projectors: the virtual rig's default lens, a strong radial + tangential lens, a
    /// rational one, and none.
    fn lenses() -> Vec<CameraModel> {
        let k = Intrinsics::new(2000.0, 2000.0, 960.0, 1050.0);
        let size = ImageSize::new(1920, 1080);
        [
            sl_sim::RigConfig::default()
                .calibration()
                .projector
                .map(|p| p.distortion)
                .unwrap_or_else(Distortion::none),
            Distortion::from_opencv(&[0.06, -0.08, 0.001, -0.0007, 0.01]).unwrap(),
            Distortion::from_opencv(&[-0.25, 0.08, 0.002, 0.001, 0.0]).unwrap(),
            Distortion::from_opencv(&[0.1, 0.02, 0.0, 0.0, 0.0, 0.05, 0.01, 0.0]).unwrap(),
            Distortion::none(),
        ]
        .into_iter()
        .map(|d| CameraModel::new(k, d, size).unwrap())
        .collect()
    }

    /// The lanes give `CameraModel::unproject`'s point (both solve the same equation to its
    /// rounding level: 1e-12 normalised is 2e-9 px, far below the f32 resolution of decoded
    /// coordinates, 6e-5 px at 1920) for rows of decoded points as a scan walks them (warm
    /// starts), for scattered points (cold and bad warm starts), and NaN where there is none.
    #[test]
    fn lanes_equal_the_exact_undistortion() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(17);
        for lens in lenses() {
            let mut warm = UndistortWarm::default();
            let mut worst = 0.0f64;
            for group in 0..400 {
                let (mut c, mut r) = ([0.0; LANES], [0.0; LANES]);
                for l in 0..LANES {
                    if group % 2 == 0 {
                        // A row of a scan: 12 projector px per lane group, slowly sloping.
                        let base = (group / 2) as f64;
                        c[l] = -20.0 + 10.0 * base + 1.5 * l as f64 + 0.01 * base * base;
                        r[l] = 40.0 + 2.5 * base;
                    } else {
                        c[l] = rng.random_range(-50.0..1970.0);
                        r[l] = rng.random_range(-50.0..1130.0);
                    }
                }
                if group % 7 == 3 {
                    c[2] = f64::NAN;
                    r[5] = f64::NAN;
                }
                let (x, y) = undistort_lanes(&lens, &c, &r, &mut warm);
                for l in 0..LANES {
                    match lens.unproject(&Point2::new(c[l], r[l])) {
                        Some(n) => {
                            let e = (x[l] - n.x).abs().max((y[l] - n.y).abs());
                            worst = worst.max(e);
                            assert!(e < 1e-12, "lane {l} at ({}, {}): {e}", c[l], r[l]);
                        }
                        None => assert!(x[l].is_nan() && y[l].is_nan()),
                    }
                }
            }
            eprintln!("{:?}: worst {worst:e}", lens.distortion.coefficients());
        }
    }
}
