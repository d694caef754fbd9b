//! The 3-D accuracy a projector–camera calibration predicts for itself: the covariance of its
//! parameters (from the joint refinement's normal equations, scaled by its residuals, as
//! OpenCV's `stereoCalibrate` standard deviations) carried through triangulation to points of
//! the volume it was calibrated in.
//!
//! For a point `X` of the volume, the camera sees it at `u`, the projector at `v`. The
//! calibration triangulates `(u, v)` back to `X` (midpoint of the two rays); a change `δθ` of
//! its parameters moves the triangulated point by `J δθ`, `J = ∂X/∂θ` (central differences).
//! With the parameters' covariance `Σθ`, the point's is `Σx = J Σθ Jᵀ`, and `sqrt(trace Σx)`
//! is its expected 3-D error. What a scanner's user measures are shapes — lengths, forms,
//! spacings — which a rigid motion of the whole volume does not change, so the headline figure
//! takes out of each parameter's displacement field the rigid motion that fits it best (the
//! camera-frame figure is kept beside it). This is the error the calibration's own noise
//! leaves — what another draw of the same captures would change — not a bias the model cannot
//! see (a lens the distortion model does not describe, a board that is not flat).

use nalgebra::{DMatrix, Isometry3, Matrix3, Point3, SMatrix, Vector3};
use serde::{Deserialize, Serialize};
use sl_camera::{CameraModel, DistortionModel, RvecTvec};

use crate::zhang::{FULL, camera_from_full};

/// Parameters of a joint calibration: camera (13), projector (13), `T_proj_cam` (rvec, tvec).
pub(crate) const SHARED: usize = 2 * FULL + 6;

/// Multiple of the standard error that [`PredictedError::bound_mm`] states: 2σ, about 95 %
/// of the points of a normal error.
pub const PREDICTED_BOUND_SIGMAS: f64 = 2.0;

/// Relative step of the central differences, of a parameter's standard deviation: small
/// enough for the triangulation to be linear over it, far above round-off.
const STEP_OF_STD_DEV: f64 = 1e-2;

/// The 3-D error a calibration predicts over the volume it was calibrated in.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PredictedError {
    /// `PREDICTED_BOUND_SIGMAS` × `rms_mm`: the calibration is expected to add at most
    /// ± `bound_mm` to the shapes the rig measures over its volume.
    pub bound_mm: f64,
    /// RMS over the volume of the points' expected error of *shape* (mm): the 3-D error
    /// `sqrt(trace Σx)` once the rigid motion of the whole volume that best explains each
    /// parameter's effect is taken out. A shift or turn of the whole measurement (a principal
    /// point's uncertainty moves every point alike) changes no length, form or spacing.
    pub rms_mm: f64,
    /// RMS over the volume of the points' expected 3-D error in the camera frame, rigid
    /// motion included (mm).
    pub absolute_rms_mm: f64,
    /// The largest point's expected shape error (mm), usually at the volume's far corners.
    pub max_mm: f64,
    /// RMS over the volume of the expected shape error along the camera's line of sight
    /// (mm): the depth part of `rms_mm`.
    pub depth_rms_mm: f64,
    /// Points of the volume the prediction was made on (the calibration's board corners).
    pub points: usize,
    /// Nearest and farthest of those points from the camera (mm along its `z`).
    pub depth_range_mm: [f64; 2],
}

impl PredictedError {
    /// The figure for a person: "the calibration is expected to add at most ±0.003 mm to the
    /// shapes this rig measures over its volume (±0.077 mm to positions in the camera frame;
    /// 2σ of its own uncertainty, 648 board corners at 348–547 mm from the camera)".
    pub fn sentence(&self) -> String {
        format!(
            "the calibration is expected to add at most ±{:.4} mm to the shapes this rig measures over its volume (±{:.4} mm to positions in the camera frame; {:.0}σ of its own uncertainty, {} board corners at {:.0}–{:.0} mm from the camera)",
            self.bound_mm,
            PREDICTED_BOUND_SIGMAS * self.absolute_rms_mm,
            PREDICTED_BOUND_SIGMAS,
            self.points,
            self.depth_range_mm[0],
            self.depth_range_mm[1]
        )
    }
}

/// A camera, a projector and `T_cam_proj` built from the full parameter vector.
struct Rig {
    camera: CameraModel,
    projector: CameraModel,
    t_cam_proj: Isometry3<f64>,
}

fn full_vector(m: &CameraModel) -> SMatrix<f64, FULL, 1> {
    let i = &m.intrinsics;
    let mut v = SMatrix::<f64, FULL, 1>::zeros();
    v[0] = i.fx;
    v[1] = i.fy;
    v[2] = i.cx;
    v[3] = i.cy;
    v[4] = i.skew;
    for (k, c) in m.distortion.coefficients().iter().enumerate() {
        v[5 + k] = *c;
    }
    v
}

fn rig_from(
    theta: &[f64],
    models: (DistortionModel, DistortionModel),
    sizes: (&CameraModel, &CameraModel),
) -> Option<Rig> {
    let part =
        |k: usize| SMatrix::<f64, FULL, 1>::from_iterator(theta[k..k + FULL].iter().copied());
    let camera = camera_from_full(&part(0), models.0, sizes.0.size)?;
    let projector = camera_from_full(&part(FULL), models.1, sizes.1.size)?;
    let e = 2 * FULL;
    let t_proj_cam = RvecTvec::new(
        Vector3::new(theta[e], theta[e + 1], theta[e + 2]),
        Vector3::new(theta[e + 3], theta[e + 4], theta[e + 5]),
    )
    .to_isometry();
    Some(Rig {
        camera,
        projector,
        t_cam_proj: t_proj_cam.inverse(),
    })
}

/// Midpoint of the closest points of the camera ray of pixel `u` and the projector ray of
/// pixel `v` (camera frame); `None` for parallel rays or pixels without a ray.
fn triangulate(
    rig: &Rig,
    u: &nalgebra::Point2<f64>,
    v: &nalgebra::Point2<f64>,
) -> Option<Point3<f64>> {
    let d1 = rig.camera.unproject_ray(u)?.into_inner();
    let d2 = rig.t_cam_proj.rotation * rig.projector.unproject_ray(v)?.into_inner();
    let (o1, o2) = (Point3::origin(), rig.t_cam_proj * Point3::origin());
    let w = o1 - o2;
    let (a, b, c, d, e) = (
        d1.dot(&d1),
        d1.dot(&d2),
        d2.dot(&d2),
        d1.dot(&w),
        d2.dot(&w),
    );
    let den = a * c - b * b;
    if den.abs() <= f64::EPSILON * a * c {
        return None;
    }
    Some(nalgebra::center(
        &(o1 + d1 * ((b * e - c * d) / den)),
        &(o2 + d2 * ((a * e - b * d) / den)),
    ))
}

/// The prediction for the calibration `camera`, `projector`, `t_proj_cam` whose parameters
/// (in the order of [`SHARED`]) have the covariance `covariance`, over the points `volume`
/// (camera frame, mm). `None` when no point of the volume triangulates or the covariance is
/// not `SHARED × SHARED`.
pub(crate) fn predict(
    camera: &CameraModel,
    projector: &CameraModel,
    t_proj_cam: &RvecTvec,
    covariance: &DMatrix<f64>,
    volume: &[Point3<f64>],
) -> Option<PredictedError> {
    if covariance.shape() != (SHARED, SHARED) {
        return None;
    }
    let mut theta = Vec::with_capacity(SHARED);
    theta.extend(full_vector(camera).iter());
    theta.extend(full_vector(projector).iter());
    theta.extend(t_proj_cam.rvec.iter());
    theta.extend(t_proj_cam.tvec.iter());
    let models = (camera.distortion.model(), projector.distortion.model());
    let sizes = (camera, projector);
    let nominal = rig_from(&theta, models, sizes)?;
    // The parameters that move (fixed ones have zero variance), with their steps.
    let free: Vec<(usize, f64)> = (0..SHARED)
        .filter_map(|i| {
            let var = covariance[(i, i)];
            (var > 0.0 && var.is_finite()).then(|| (i, STEP_OF_STD_DEV * var.sqrt()))
        })
        .collect();
    let shifted: Vec<(Rig, Rig)> = free
        .iter()
        .map(|&(i, h)| {
            let mut up = theta.clone();
            let mut down = theta.clone();
            up[i] += h;
            down[i] -= h;
            Some((
                rig_from(&up, models, sizes)?,
                rig_from(&down, models, sizes)?,
            ))
        })
        .collect::<Option<_>>()?;
    let sub = DMatrix::from_fn(free.len(), free.len(), |a, b| {
        covariance[(free[a].0, free[b].0)]
    });
    // The displacement of every point per unit change of each free parameter.
    let mut points: Vec<Point3<f64>> = Vec::with_capacity(volume.len());
    let mut jacobians: Vec<DMatrix<f64>> = Vec::with_capacity(volume.len());
    for x in volume {
        let Some(u) = nominal.camera.project(x) else {
            continue;
        };
        let Some(v) = nominal
            .projector
            .project(&nominal.t_cam_proj.inverse_transform_point(x))
        else {
            continue;
        };
        let mut jac = DMatrix::<f64>::zeros(3, free.len());
        let mut ok = true;
        for (k, ((_, h), (up, down))) in free.iter().zip(&shifted).enumerate() {
            match (triangulate(up, &u, &v), triangulate(down, &u, &v)) {
                (Some(a), Some(b)) => jac.set_column(k, &((a - b) / (2.0 * h))),
                _ => ok = false,
            }
        }
        if ok {
            points.push(*x);
            jacobians.push(jac);
        }
    }
    let n = points.len();
    if n == 0 {
        return None;
    }
    // The shape part: each parameter's displacement field less the rigid motion that fits it
    // best (a translation and a small rotation about the volume's centroid), which moves the
    // whole measurement without changing any length in it.
    let centroid = points.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n as f64;
    let mut rigid = DMatrix::<f64>::zeros(3 * n, 6);
    for (i, p) in points.iter().enumerate() {
        let r = p.coords - centroid;
        // d = t + ω × r = [I | −[r]×] (t, ω).
        for k in 0..3 {
            rigid[(3 * i + k, k)] = 1.0;
        }
        let skew = Matrix3::new(0.0, -r.z, r.y, r.z, 0.0, -r.x, -r.y, r.x, 0.0);
        rigid.view_mut((3 * i, 3), (3, 3)).copy_from(&(-skew));
    }
    let mut stacked = DMatrix::<f64>::zeros(3 * n, free.len());
    for (i, j) in jacobians.iter().enumerate() {
        stacked.view_mut((3 * i, 0), (3, free.len())).copy_from(j);
    }
    let shape = match (rigid.transpose() * &rigid).try_inverse() {
        Some(inv) => {
            let fit = &inv * rigid.transpose() * &stacked;
            &stacked - &rigid * fit
        }
        None => stacked.clone(),
    };
    let (mut sum_sq, mut abs_sq, mut sum_depth_sq, mut max_sq) = (0.0, 0.0, 0.0, 0.0f64);
    let (mut z_min, mut z_max) = (f64::INFINITY, f64::NEG_INFINITY);
    for (i, (x, jac)) in points.iter().zip(&jacobians).enumerate() {
        let block = |m: &DMatrix<f64>| -> Matrix3<f64> {
            let rows = m.rows(3 * i, 3);
            let c = rows * &sub * rows.transpose();
            Matrix3::from_fn(|r, s| c[(r, s)])
        };
        let cov = block(&shape);
        let sq = cov.trace().max(0.0);
        let los = x.coords.normalize();
        sum_sq += sq;
        abs_sq += (jac * &sub * jac.transpose()).trace().max(0.0);
        sum_depth_sq += (los.transpose() * cov * los)[(0, 0)].max(0.0);
        max_sq = max_sq.max(sq);
        z_min = z_min.min(x.z);
        z_max = z_max.max(x.z);
    }
    let rms = (sum_sq / n as f64).sqrt();
    Some(PredictedError {
        bound_mm: PREDICTED_BOUND_SIGMAS * rms,
        rms_mm: rms,
        absolute_rms_mm: (abs_sq / n as f64).sqrt(),
        max_mm: max_sq.sqrt(),
        depth_rms_mm: (sum_depth_sq / n as f64).sqrt(),
        points: n,
        depth_range_mm: [z_min, z_max],
    })
}
