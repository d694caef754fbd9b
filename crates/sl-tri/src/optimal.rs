//! Optimal triangulation: the point that minimises the sum of squared reprojection errors in
//! the camera and the projector, distortion included, by Gauss–Newton from a closed-form
//! start.
//!
//! Residuals are the four pixel differences (camera: projected point minus the pixel centre;
//! projector: projected point minus the decoded `(c, r)`), Jacobians analytic (pinhole,
//! OpenCV distortion, pose). The start is the exact ray–surface point on the decoded column,
//! which already has zero camera and column residuals, so one or two Gauss–Newton steps
//! reach the optimum.

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2, Vector3};
use sl_camera::CameraModel;

use crate::stereo::Stereo;

/// Step (mm) below which Gauss–Newton stops. For the small residuals of a scan (below a
/// few px) Gauss–Newton converges at least linearly with a rate ρ ≪ 1 (the residual times
/// the curvature of the projections, ~1e-2 here), so the error left after a step `s` is
/// about ρ·s: 1e-5 mm leaves ~1e-7 mm, far below the 1e-3 mm the scanner resolves. From
/// the ray–plane start the first step is that small for noise-free data, the second for
/// noisy data.
const OPTIMAL_STEP_TOLERANCE_MM: f64 = 1e-5;

/// The refined point and its reprojection error.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Refined {
    /// Camera frame, mm.
    pub(crate) p: Vector3<f64>,
    /// RMS over the four residuals' two images, px (see `Stereo::reprojection`).
    pub(crate) reprojection: f64,
}

/// Residual and Jacobian of the projection of `q` (lens frame) with respect to `q`.
#[inline(always)]
fn residual(
    lens: &CameraModel,
    q: &Vector3<f64>,
    target: (f64, f64),
) -> Option<(Vector2<f64>, Matrix2x3<f64>)> {
    if !(q.z > 0.0) {
        return None;
    }
    let iz = 1.0 / q.z;
    let (x, y) = (q.x * iz, q.y * iz);
    if !lens.in_valid_region(x, y) {
        return None;
    }
    let pj = lens.project_normalised_with_jacobian(x, y);
    let dn = Matrix2x3::new(iz, 0.0, -x * iz, 0.0, iz, -y * iz);
    let j = Matrix2::new(pj.du_dx, pj.du_dy, pj.dv_dx, pj.dv_dy) * dn;
    Some((Vector2::new(pj.u - target.0, pj.v - target.1), j))
}

/// Refines `start` (camera frame, mm) for camera pixel `(u, v)` and projector point `(c, r)`.
///
/// Scalar and iterative (each pixel stops when its own step is small): the start already
/// has zero camera and column residuals, so most pixels stop after one or two steps. The
/// reprojection error is that of the residuals after the last step, predicted by the
/// linearisation the step was computed with (exact to the square of that step, i.e. to
/// far below 1e-9 px) instead of a fifth projection of the point. `None` if a projection
/// fails or the refined point leaves the projector's valid region.
#[inline]
pub(crate) fn refine(
    s: &Stereo,
    start: Vector3<f64>,
    (u, v): (f64, f64),
    (c, r): (f64, f64),
    max_iterations: usize,
) -> Option<Refined> {
    let [r0, r1, r2] = s.r_pc;
    let r_pc = Matrix3::new(
        r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2],
    );
    let t_pc = Vector3::from(s.t_pc);
    let mut p = start;
    let mut e2 = f64::NAN;
    for _ in 0..max_iterations {
        let (ec, jc) = residual(&s.cam, &p, (u, v))?;
        let q = r_pc * p + t_pc;
        let (ep, jq) = residual(&s.proj, &q, (c, r))?;
        let jp = jq * r_pc;
        let h: Matrix3<f64> = jc.transpose() * jc + jp.transpose() * jp;
        let g = jc.transpose() * ec + jp.transpose() * ep;
        let step = h.try_inverse()? * g;
        p -= step;
        if !p.iter().all(|x| x.is_finite()) {
            return None;
        }
        e2 = (ec - jc * step).norm_squared() + (ep - jp * step).norm_squared();
        if step.norm() < OPTIMAL_STEP_TOLERANCE_MM {
            break;
        }
    }
    let q = r_pc * p + t_pc;
    let valid = p.z > 0.0 && q.z > 0.0 && s.proj.in_valid_region(q.x / q.z, q.y / q.z);
    valid.then(|| Refined {
        p,
        reprojection: (0.5 * e2).sqrt(),
    })
}
