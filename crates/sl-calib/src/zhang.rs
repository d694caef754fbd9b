//! Zhang's camera calibration: homographies, closed-form intrinsics, per-view extrinsics and
//! a linear distortion start, then Levenberg–Marquardt over intrinsics, distortion and every
//! pose with analytic Jacobians, solved through the Schur complement over the poses.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Point2, Point3, SMatrix, Vector2, Vector6};
use serde::{Deserialize, Serialize};
use sl_camera::{
    CameraModel, Distortion, DistortionModel, ImageSize, Intrinsics, RvecTvec, isometry_from_rt,
};

use crate::homography::homography_dlt;
use crate::lm::{
    Normal, SchurProblem, levenberg_marquardt, std_dev, step_poses, unscaled_covariance,
};
use crate::{BoardCorners, CalibError};

/// One view of a planar calibration target: board points (`z = 0`) and their pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationView {
    /// Points of the board in the board frame (`z = 0`), in mm or the board's unit.
    pub object_points: Vec<Point3<f64>>,
    /// Their observed pixels, in the same order.
    pub image_points: Vec<Point2<f64>>,
}

impl CalibrationView {
    /// A view from detected corners, for squares of `square` units.
    pub fn from_corners(corners: &BoardCorners, square: f64) -> Self {
        Self {
            object_points: corners.size.object_points(square),
            image_points: corners.corners.clone(),
        }
    }
}

/// Options of [`calibrate_camera`], after OpenCV's `CALIB_*` flags.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ZhangConfig {
    /// `Some(r)`: keep `fx / fy = r` (`CALIB_FIX_ASPECT_RATIO`).
    pub aspect_ratio: Option<f64>,
    /// Keep the skew at zero (OpenCV never estimates it; the default).
    pub zero_skew: bool,
    /// Keep the principal point at the image centre (`CALIB_FIX_PRINCIPAL_POINT`).
    pub fix_principal_point: bool,
    /// Keep `k3 = 0` (`CALIB_FIX_K3`).
    pub fix_k3: bool,
    /// Estimate the 8-coefficient rational model (`CALIB_RATIONAL_MODEL`).
    pub rational_model: bool,
    /// Keep `p1 = p2 = 0` (`CALIB_ZERO_TANGENT_DIST`).
    pub zero_tangential: bool,
    /// Largest number of Levenberg–Marquardt iterations (OpenCV's default is 30; more never
    /// hurts since the loop stops at convergence).
    pub max_iterations: usize,
    /// Relative decrease of the squared error below which the iteration stops.
    pub tolerance: f64,
}

impl Default for ZhangConfig {
    /// OpenCV's defaults: 5 distortion coefficients, zero skew, everything else free.
    fn default() -> Self {
        Self {
            aspect_ratio: None,
            zero_skew: true,
            fix_principal_point: false,
            fix_k3: false,
            rational_model: false,
            zero_tangential: false,
            max_iterations: 100,
            tolerance: 1e-15,
        }
    }
}

/// Standard deviations of the estimated parameters (zero for fixed ones).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterStdDev {
    /// `fx, fy, cx, cy, skew` (px).
    pub intrinsics: [f64; 5],
    /// `k1 k2 p1 p2 k3 k4 k5 k6`.
    pub distortion: [f64; 8],
    /// Per view: `rvec` (rad) then `tvec` (board units).
    pub poses: Vec<[f64; 6]>,
}

/// The result of [`calibrate_camera`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraCalibration {
    /// The calibrated camera.
    pub camera: CameraModel,
    /// `T_cam_board` of every view (OpenCV's `rvecs`/`tvecs`).
    pub poses: Vec<RvecTvec>,
    /// RMS reprojection error over all corners (px), OpenCV's definition.
    pub rms: f64,
    /// RMS reprojection error of each view (px).
    pub view_rms: Vec<f64>,
    /// Per view, per corner: observed minus projected pixel.
    pub residuals: Vec<Vec<Vector2<f64>>>,
    /// Standard deviations of the parameters (as OpenCV's `stdDeviations*`).
    pub std_dev: ParameterStdDev,
    /// Levenberg–Marquardt iterations made.
    pub iterations: usize,
}

/// Number of camera parameters in the full vector: `fx fy cx cy skew k1 k2 p1 p2 k3 k4 k5 k6`.
pub(crate) const FULL: usize = 13;

/// Views fewer than this leave Zhang's closed form underdetermined with noise.
const MIN_VIEWS: usize = 3;

/// Second-smallest eigenvalue of Zhang's `VᵀV`, relative to its trace, below which the
/// null space has more than one dimension: the views are parallel and the conic `B` is
/// not determined.
const DEGENERATE_EIGEN_RATIO: f64 = 1e-9;

/// Which free parameters are estimated, as linear maps into the full 13-vector.
pub(crate) struct Layout {
    /// Column `c` of `t` maps free parameter `c` into the full vector.
    pub(crate) t: DMatrix<f64>,
    pub(crate) model: DistortionModel,
}

impl Layout {
    pub(crate) fn new(cfg: &ZhangConfig) -> Self {
        let mut cols: Vec<[f64; FULL]> = Vec::new();
        let unit = |i: usize| {
            let mut c = [0.0; FULL];
            if let Some(v) = c.get_mut(i) {
                *v = 1.0;
            }
            c
        };
        match cfg.aspect_ratio {
            Some(r) => {
                let mut c = [0.0; FULL];
                c[0] = r;
                c[1] = 1.0;
                cols.push(c);
            }
            None => {
                cols.push(unit(0));
                cols.push(unit(1));
            }
        }
        if !cfg.fix_principal_point {
            cols.push(unit(2));
            cols.push(unit(3));
        }
        if !cfg.zero_skew {
            cols.push(unit(4));
        }
        cols.push(unit(5));
        cols.push(unit(6));
        if !cfg.zero_tangential {
            cols.push(unit(7));
            cols.push(unit(8));
        }
        if !cfg.fix_k3 {
            cols.push(unit(9));
        }
        if cfg.rational_model {
            for i in 10..13 {
                cols.push(unit(i));
            }
        }
        let mut t = DMatrix::zeros(FULL, cols.len());
        for (c, col) in cols.iter().enumerate() {
            for (r, v) in col.iter().enumerate() {
                t[(r, c)] = *v;
            }
        }
        Self {
            t,
            model: if cfg.rational_model {
                DistortionModel::Rational
            } else {
                DistortionModel::PlumbBob
            },
        }
    }
}

pub(crate) fn camera_from_full(
    p: &SMatrix<f64, FULL, 1>,
    model: DistortionModel,
    size: ImageSize,
) -> Option<CameraModel> {
    let intr = Intrinsics {
        fx: p[0],
        fy: p[1],
        cx: p[2],
        cy: p[3],
        skew: p[4],
    };
    let mut k = [0.0; 8];
    for (i, v) in k.iter_mut().enumerate() {
        *v = p[5 + i];
    }
    let d = Distortion::new(model, k).ok()?;
    CameraModel::new(intr, d, size).ok()
}

/// Calibrates a camera from ≥ 3 views of a planar board (Zhang 2000), refined by
/// Levenberg–Marquardt over all parameters with analytic Jacobians.
///
/// # Errors
/// [`CalibError::Degenerate`] for fewer than 3 views or views that do not determine the
/// intrinsics (e.g. all parallel), saying what to capture instead; [`CalibError::View`] for
/// a malformed view (point counts differ, fewer than 4 points, points off the `z = 0`
/// plane, non-finite values); [`CalibError::InvalidParameter`] for a bad option.
///
/// ```
/// use sl_calib::{CalibrationView, ZhangConfig, calibrate_camera, BoardSize};
/// use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics, RvecTvec};
/// use nalgebra::Vector3;
/// let truth = CameraModel::new(
///     Intrinsics::new(800.0, 805.0, 321.0, 238.0),
///     Distortion::from_opencv(&[-0.1, 0.05, 0.0, 0.0, 0.0])?,
///     ImageSize::new(640, 480),
/// )?;
/// let board = BoardSize::new(9, 6).object_points(25.0);
/// let views: Vec<CalibrationView> = [(0.3, -0.2), (-0.25, 0.1), (0.1, 0.35), (-0.3, -0.3)]
///     .iter()
///     .map(|&(a, b)| {
///         let pose = RvecTvec::new(Vector3::new(a, b, 0.05), Vector3::new(-100.0, -60.0, 600.0));
///         CalibrationView {
///             object_points: board.clone(),
///             image_points: board.iter().map(|p| truth.project(&pose.transform_point(p)).unwrap()).collect(),
///         }
///     })
///     .collect();
/// let calib = calibrate_camera(&views, ImageSize::new(640, 480), &ZhangConfig::default())?;
/// assert!((calib.camera.intrinsics.fx - 800.0).abs() < 1e-4);
/// assert!(calib.rms < 1e-6);
/// # Ok::<(), sl_calib::CalibError>(())
/// ```
pub fn calibrate_camera(
    views: &[CalibrationView],
    size: ImageSize,
    config: &ZhangConfig,
) -> Result<CameraCalibration, CalibError> {
    validate(views, size, config, true)?;
    let init = initial_estimate(views, size, config)?;
    refine(views, size, config, init)
}

/// As [`calibrate_camera`], but views may hold different numbers of points (a subset of the
/// board's corners each): the projector calibration, where corners without enough decoded
/// pixels around them are left out.
pub(crate) fn calibrate_camera_subsets(
    views: &[CalibrationView],
    size: ImageSize,
    config: &ZhangConfig,
) -> Result<CameraCalibration, CalibError> {
    validate(views, size, config, false)?;
    let init = initial_estimate(views, size, config)?;
    refine(views, size, config, init)
}

fn validate(
    views: &[CalibrationView],
    size: ImageSize,
    config: &ZhangConfig,
    same_count: bool,
) -> Result<(), CalibError> {
    if views.len() < MIN_VIEWS {
        return Err(CalibError::Degenerate(format!(
            "{} view(s): capture at least {MIN_VIEWS} views of the board (10–20 is better), tilted by 10–40° in different directions",
            views.len()
        )));
    }
    size.validate().map_err(sl_camera::CameraError::from)?;
    if let Some(r) = config.aspect_ratio
        && !(r.is_finite() && r > 0.0)
    {
        return Err(CalibError::param(
            "aspect_ratio",
            format!("{r} is not a positive ratio"),
        ));
    }
    let first = views.first().map(|v| v.object_points.len()).unwrap_or(0);
    for (k, v) in views.iter().enumerate() {
        if v.object_points.len() != v.image_points.len() {
            return Err(CalibError::View {
                view: k,
                reason: format!(
                    "{} board points but {} image points",
                    v.object_points.len(),
                    v.image_points.len()
                ),
            });
        }
        if v.object_points.len() < 4 {
            return Err(CalibError::View {
                view: k,
                reason: format!(
                    "{} points: a view needs at least 4 board corners",
                    v.object_points.len()
                ),
            });
        }
        if same_count && v.object_points.len() != first {
            return Err(CalibError::View {
                view: k,
                reason: format!(
                    "{} corners while view 0 has {first}: detect the same board size in every image",
                    v.object_points.len()
                ),
            });
        }
        if let Some(i) = v
            .object_points
            .iter()
            .position(|p| p.z != 0.0 || !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(CalibError::View {
                view: k,
                reason: format!("board point {i} is not on the z = 0 plane (or not finite)"),
            });
        }
        if let Some(i) = v
            .image_points
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(CalibError::View {
                view: k,
                reason: format!("image point {i} is not finite"),
            });
        }
    }
    Ok(())
}

struct Estimate {
    camera: SMatrix<f64, FULL, 1>,
    poses: Vec<RvecTvec>,
}

fn v_ij(h: &Matrix3<f64>, i: usize, j: usize) -> SMatrix<f64, 6, 1> {
    let hi = h.column(i);
    let hj = h.column(j);
    SMatrix::<f64, 6, 1>::from_column_slice(&[
        hi[0] * hj[0],
        hi[0] * hj[1] + hi[1] * hj[0],
        hi[1] * hj[1],
        hi[2] * hj[0] + hi[0] * hj[2],
        hi[2] * hj[1] + hi[1] * hj[2],
        hi[2] * hj[2],
    ])
}

fn initial_estimate(
    views: &[CalibrationView],
    size: ImageSize,
    config: &ZhangConfig,
) -> Result<Estimate, CalibError> {
    let mut homographies = Vec::with_capacity(views.len());
    for (k, v) in views.iter().enumerate() {
        let plane: Vec<Point2<f64>> = v
            .object_points
            .iter()
            .map(|p| Point2::new(p.x, p.y))
            .collect();
        let h = homography_dlt(&plane, &v.image_points).ok_or_else(|| CalibError::View {
            view: k,
            reason: "no homography: the board points are collinear or coincide".to_owned(),
        })?;
        homographies.push(h);
    }
    // Zhang's linear system on B = K⁻ᵀK⁻¹, in pixel coordinates shifted to the image centre
    // and scaled (better conditioning).
    let (w, h) = (f64::from(size.width), f64::from(size.height));
    let scale = 1.0 / w.max(h);
    let centre = Vector2::new((w - 1.0) / 2.0, (h - 1.0) / 2.0);
    let norm = Matrix3::new(
        scale,
        0.0,
        -scale * centre.x,
        0.0,
        scale,
        -scale * centre.y,
        0.0,
        0.0,
        1.0,
    );
    let mut vtv = SMatrix::<f64, 6, 6>::zeros();
    let mut add = |r: SMatrix<f64, 6, 1>| vtv += r * r.transpose();
    for hm in &homographies {
        // H is known up to scale: bring its first two columns to unit size so every view
        // weighs the same whatever the board's unit.
        let hn = norm * hm;
        let col_scale = 0.5 * (hn.column(0).norm() + hn.column(1).norm());
        let hn = if col_scale > 0.0 { hn / col_scale } else { hn };
        add(v_ij(&hn, 0, 1));
        add(v_ij(&hn, 0, 0) - v_ij(&hn, 1, 1));
    }
    // Zero skew: B12 = 0. A principal point fixed at the centre: B13 = B23 = 0 in these
    // centred coordinates. Weighted strongly so the constraint holds.
    let data_trace = vtv.trace();
    let weight = data_trace.max(f64::MIN_POSITIVE) * 1e3;
    let mut constrain = |i: usize| {
        let mut r = SMatrix::<f64, 6, 1>::zeros();
        r[i] = 1.0;
        vtv += weight * r * r.transpose();
    };
    if config.zero_skew {
        constrain(1);
    }
    if config.fix_principal_point {
        constrain(3);
        constrain(4);
    }
    let eig = vtv.symmetric_eigen();
    let mut order: Vec<usize> = (0..6).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let parallel = || {
        CalibError::Degenerate(
            "the views do not determine the focal length (are the boards all parallel?): tilt the board by 10–40° about different axes between views".to_owned(),
        )
    };
    let second = eig.eigenvalues[order[1]];
    if second.partial_cmp(&(DEGENERATE_EIGEN_RATIO * data_trace))
        != Some(std::cmp::Ordering::Greater)
    {
        return Err(parallel());
    }
    let mut b = eig.eigenvectors.column(order[0]).into_owned();
    if b[0] < 0.0 {
        b = -b;
    }
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha2 = lambda / b11;
    let beta2 = lambda * b11 / den;
    if !(alpha2 > 0.0 && beta2 > 0.0 && den > 0.0) {
        return Err(parallel());
    }
    let (alpha, beta) = (alpha2.sqrt(), beta2.sqrt());
    let gamma = -b12 * alpha * alpha * beta / lambda;
    let u0 = gamma * v0 / beta - b13 * alpha * alpha / lambda;
    // Back to pixels.
    let mut fx = alpha / scale;
    let mut fy = beta / scale;
    let skew = if config.zero_skew { 0.0 } else { gamma / scale };
    let (cx, cy) = if config.fix_principal_point {
        (centre.x, centre.y)
    } else {
        (u0 / scale + centre.x, v0 / scale + centre.y)
    };
    if let Some(r) = config.aspect_ratio {
        let f = (fx / r + fy) / 2.0;
        fy = f;
        fx = r * f;
    }
    if !(fx.is_finite() && fy.is_finite() && cx.is_finite() && cy.is_finite()) {
        return Err(parallel());
    }
    let k = Matrix3::new(fx, skew, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
    let k_inv = k.try_inverse().ok_or_else(parallel)?;
    let mut poses = Vec::with_capacity(views.len());
    for (idx, hm) in homographies.iter().enumerate() {
        let a1 = k_inv * hm.column(0);
        let a2 = k_inv * hm.column(1);
        let a3 = k_inv * hm.column(2);
        let mut l = 1.0 / a1.norm();
        if a3.z * l < 0.0 {
            l = -l; // the board must be in front of the camera
        }
        let r1 = a1 * l;
        let r2 = a2 * l;
        let r3 = r1.cross(&r2);
        let t = a3 * l;
        let r = Matrix3::from_columns(&[r1, r2, r3]);
        // Nearest rotation (SVD).
        let svd = r.svd(true, true);
        let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
            return Err(CalibError::View {
                view: idx,
                reason: "the initial rotation could not be orthonormalised".to_owned(),
            });
        };
        let mut rot = u * vt;
        if rot.determinant() < 0.0 {
            rot = -rot;
        }
        let iso = isometry_from_rt(&rot, &t)?;
        poses.push(RvecTvec::from_isometry(&iso));
    }
    let mut camera = SMatrix::<f64, FULL, 1>::zeros();
    camera[0] = fx;
    camera[1] = fy;
    camera[2] = cx;
    camera[3] = cy;
    camera[4] = skew;
    // Zhang's linear start for k1, k2 (radial only) from the ideal projections.
    let mut ata = nalgebra::Matrix2::<f64>::zeros();
    let mut atb = Vector2::<f64>::zeros();
    for (v, pose) in views.iter().zip(&poses) {
        for (p, q) in v.object_points.iter().zip(&v.image_points) {
            let pc = pose.transform_point(p);
            if pc.z <= 0.0 {
                continue;
            }
            let (x, y) = (pc.x / pc.z, pc.y / pc.z);
            let r2 = x * x + y * y;
            let u = fx * x + skew * y + cx;
            let vv = fy * y + cy;
            for (d, obs, ideal) in [(u - cx, q.x, u), (vv - cy, q.y, vv)] {
                let row = Vector2::new(d * r2, d * r2 * r2);
                ata += row * row.transpose();
                atb += row * (obs - ideal);
            }
        }
    }
    if let Some(k12) = ata.try_inverse().map(|m| m * atb) {
        let mut trial = camera;
        trial[5] = k12.x;
        trial[6] = k12.y;
        let model = Layout::new(config).model;
        if k12.iter().all(|v| v.is_finite())
            && camera_from_full(&trial, model, size)
                .is_some_and(|cam| all_project(&cam, views, &poses))
        {
            camera = trial;
        }
    }
    Ok(Estimate { camera, poses })
}

fn all_project(cam: &CameraModel, views: &[CalibrationView], poses: &[RvecTvec]) -> bool {
    views.iter().zip(poses).all(|(v, pose)| {
        v.object_points
            .iter()
            .all(|p| cam.project(&pose.transform_point(p)).is_some())
    })
}

/// Squared error of all views, `None` when a point does not project.
fn total_cost(cam: &CameraModel, views: &[CalibrationView], poses: &[RvecTvec]) -> Option<f64> {
    let mut sum = 0.0;
    for (v, pose) in views.iter().zip(poses) {
        for (p, q) in v.object_points.iter().zip(&v.image_points) {
            let px = cam.project(&pose.transform_point(p))?;
            sum += (q - px).norm_squared();
        }
    }
    Some(sum)
}

fn build_normal(
    cam: &CameraModel,
    views: &[CalibrationView],
    poses: &[RvecTvec],
    layout: &Layout,
) -> Option<Normal> {
    let nc = layout.t.ncols();
    let mut u = DMatrix::zeros(nc, nc);
    let mut g_c = DVector::zeros(nc);
    let mut vs = Vec::with_capacity(views.len());
    let mut ws = Vec::with_capacity(views.len());
    let mut gps = Vec::with_capacity(views.len());
    let mut cost = 0.0;
    let tt = layout.t.transpose();
    for (view, pose) in views.iter().zip(poses) {
        let mut v = Matrix6::zeros();
        let mut w = DMatrix::zeros(nc, 6);
        let mut gp = Vector6::zeros();
        // Accumulate in the full 13-parameter space, map to the free ones once per view.
        let mut u_full = SMatrix::<f64, FULL, FULL>::zeros();
        let mut g_full = SMatrix::<f64, FULL, 1>::zeros();
        let mut w_full = SMatrix::<f64, FULL, 6>::zeros();
        for (p, q) in view.object_points.iter().zip(&view.image_points) {
            let j = cam.project_with_pose_jacobians(pose, p)?;
            let r = q - j.projection.pixel;
            cost += r.norm_squared();
            let mut jc = SMatrix::<f64, 2, FULL>::zeros();
            jc.fixed_view_mut::<2, 5>(0, 0)
                .copy_from(&j.projection.d_intrinsics);
            jc.fixed_view_mut::<2, 8>(0, 5)
                .copy_from(&j.projection.d_distortion);
            let mut jp = SMatrix::<f64, 2, 6>::zeros();
            jp.fixed_view_mut::<2, 3>(0, 0).copy_from(&j.d_rvec);
            jp.fixed_view_mut::<2, 3>(0, 3).copy_from(&j.d_tvec);
            u_full += jc.transpose() * jc;
            g_full += jc.transpose() * r;
            w_full += jc.transpose() * jp;
            v += jp.transpose() * jp;
            gp += jp.transpose() * r;
        }
        let tu = &tt * DMatrix::from_column_slice(FULL, FULL, u_full.as_slice());
        u += &tu * &layout.t;
        g_c += &tt * DVector::from_column_slice(g_full.as_slice());
        w += &tt * DMatrix::from_column_slice(FULL, 6, w_full.as_slice());
        vs.push(v);
        ws.push(w);
        gps.push(gp);
    }
    Some(Normal {
        u,
        g_c,
        v: vs,
        w: ws,
        g_p: gps,
        cost,
    })
}

fn apply(
    camera: &SMatrix<f64, FULL, 1>,
    poses: &[RvecTvec],
    layout: &Layout,
    dc: &DVector<f64>,
    dp: &[Vector6<f64>],
) -> (SMatrix<f64, FULL, 1>, Vec<RvecTvec>) {
    let full = &layout.t * dc;
    let mut c = *camera;
    for i in 0..FULL {
        c[i] += full[i];
    }
    (c, step_poses(poses, dp))
}

fn refine(
    views: &[CalibrationView],
    size: ImageSize,
    config: &ZhangConfig,
    init: Estimate,
) -> Result<CameraCalibration, CalibError> {
    let layout = Layout::new(config);
    let camera = init.camera;
    let poses = init.poses;
    let not_projecting = || {
        CalibError::Degenerate(
            "the initial estimate does not project every corner: check the board size and corner order of every view".to_owned(),
        )
    };
    let cam = camera_from_full(&camera, layout.model, size).ok_or_else(not_projecting)?;
    let problem = ZhangProblem {
        views,
        layout: &layout,
        size,
    };
    let min = levenberg_marquardt(
        &problem,
        ZhangState { camera, cam, poses },
        config.max_iterations,
        config.tolerance,
    )
    .ok_or_else(not_projecting)?;
    let (normal, iterations) = (min.normal, min.iterations);
    let ZhangState { cam, poses, .. } = min.state;
    // Residuals and statistics at the solution.
    let mut residuals = Vec::with_capacity(views.len());
    let mut view_rms = Vec::with_capacity(views.len());
    let mut total = 0.0;
    let mut count = 0usize;
    for (v, pose) in views.iter().zip(&poses) {
        let mut res = Vec::with_capacity(v.image_points.len());
        let mut sum = 0.0;
        for (p, q) in v.object_points.iter().zip(&v.image_points) {
            let px = cam
                .project(&pose.transform_point(p))
                .ok_or_else(not_projecting)?;
            let r = q - px;
            sum += r.norm_squared();
            res.push(r);
        }
        view_rms.push((sum / res.len().max(1) as f64).sqrt());
        total += sum;
        count += res.len();
        residuals.push(res);
    }
    let rms = (total / count.max(1) as f64).sqrt();
    let std_dev = std_deviations(&normal, &layout, total, count, views.len());
    Ok(CameraCalibration {
        camera: cam,
        poses,
        rms,
        view_rms,
        residuals,
        std_dev,
        iterations,
    })
}

struct ZhangState {
    camera: SMatrix<f64, FULL, 1>,
    cam: CameraModel,
    poses: Vec<RvecTvec>,
}

struct ZhangProblem<'a> {
    views: &'a [CalibrationView],
    layout: &'a Layout,
    size: ImageSize,
}

impl SchurProblem for ZhangProblem<'_> {
    type State = ZhangState;

    fn normal(&self, s: &ZhangState) -> Option<Normal> {
        build_normal(&s.cam, self.views, &s.poses, self.layout)
    }

    fn cost(&self, s: &ZhangState) -> Option<f64> {
        total_cost(&s.cam, self.views, &s.poses)
    }

    fn step(&self, s: &ZhangState, dc: &DVector<f64>, dp: &[Vector6<f64>]) -> Option<ZhangState> {
        let (camera, poses) = apply(&s.camera, &s.poses, self.layout, dc, dp);
        let cam = camera_from_full(&camera, self.layout.model, self.size)?;
        Some(ZhangState { camera, cam, poses })
    }
}

/// `σ² (JᵀJ)⁻¹` with `σ² = cost / (2N − parameters)`, as OpenCV: the camera block is the
/// inverse of the Schur complement; each pose block is
/// `V⁻¹ + V⁻¹ Wᵀ S⁻¹ W V⁻¹`.
fn std_deviations(
    n: &Normal,
    layout: &Layout,
    cost: f64,
    points: usize,
    views: usize,
) -> ParameterStdDev {
    let nc = layout.t.ncols();
    let dof = (2 * points).saturating_sub(nc + 6 * views).max(1) as f64;
    let sigma2 = cost / dof;
    let mut out = ParameterStdDev {
        intrinsics: [0.0; 5],
        distortion: [0.0; 8],
        poses: vec![[0.0; 6]; views],
    };
    let Some(cov) = unscaled_covariance(n) else {
        return out;
    };
    // Free-parameter covariance mapped to the full vector: T S⁻¹ Tᵀ.
    let full = cov.mapped(&layout.t);
    for i in 0..5 {
        out.intrinsics[i] = std_dev(sigma2, full[(i, i)]);
    }
    for i in 0..8 {
        out.distortion[i] = std_dev(sigma2, full[(5 + i, 5 + i)]);
    }
    out.poses = cov.pose_std_devs(sigma2);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BoardSize;
    use approx::assert_relative_eq;
    use nalgebra::Vector3;

    fn synthetic(noise: f64) -> (CameraModel, Vec<CalibrationView>) {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let truth = CameraModel::new(
            Intrinsics::new(800.0, 805.0, 321.0, 238.0),
            Distortion::from_opencv(&[-0.1, 0.05, 0.001, -0.0005, 0.0]).unwrap(),
            ImageSize::new(640, 480),
        )
        .unwrap();
        let board = BoardSize::new(9, 6).object_points(25.0);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let n = Normal::new(0.0, 1.0).unwrap();
        let views = [
            (0.3, -0.2),
            (-0.25, 0.1),
            (0.1, 0.35),
            (-0.3, -0.3),
            (0.2, 0.25),
        ]
        .iter()
        .map(|&(a, b)| {
            let pose = RvecTvec::new(Vector3::new(a, b, 0.05), Vector3::new(-100.0, -60.0, 600.0));
            CalibrationView {
                object_points: board.clone(),
                image_points: board
                    .iter()
                    .map(|p| {
                        let q = truth.project(&pose.transform_point(p)).unwrap();
                        Point2::new(
                            q.x + noise * n.sample(&mut rng),
                            q.y + noise * n.sample(&mut rng),
                        )
                    })
                    .collect(),
            }
        })
        .collect();
        (truth, views)
    }

    #[test]
    fn exact_data_recovers_the_camera() {
        let (truth, views) = synthetic(0.0);
        let c = calibrate_camera(&views, truth.size, &ZhangConfig::default()).unwrap();
        // Noise-free: the minimum is the truth, to the LM tolerance.
        assert_relative_eq!(c.camera.intrinsics.fx, 800.0, max_relative = 1e-7);
        assert_relative_eq!(c.camera.intrinsics.fy, 805.0, max_relative = 1e-7);
        assert_relative_eq!(c.camera.intrinsics.cx, 321.0, epsilon = 1e-5);
        assert_relative_eq!(c.camera.distortion.k1(), -0.1, epsilon = 1e-7);
        assert!(c.rms < 1e-6);
    }

    #[test]
    fn closed_form_start_is_near_the_truth() {
        let (truth, views) = synthetic(0.0);
        let init = initial_estimate(&views, truth.size, &ZhangConfig::default()).unwrap();
        eprintln!("init {:?}", init.camera.as_slice());
        // Distortion is ignored by the homographies: a few percent off, no more.
        assert_relative_eq!(init.camera[0], 800.0, max_relative = 0.05);
    }

    #[test]
    fn noise_gives_consistent_standard_deviations() {
        let (truth, views) = synthetic(0.2);
        let c = calibrate_camera(&views, truth.size, &ZhangConfig::default()).unwrap();
        // RMS of 2-D residuals of σ = 0.2 px per axis: ≈ 0.2·√2 minus the fitted dof.
        assert!(c.rms > 0.2 && c.rms < 0.3, "rms {}", c.rms);
        // Truth within 4 standard deviations.
        assert!((c.camera.intrinsics.fx - 800.0).abs() < 4.0 * c.std_dev.intrinsics[0]);
        assert!(c.std_dev.intrinsics[0] > 0.0);
    }

    #[test]
    fn degenerate_inputs_say_what_to_capture() {
        let (truth, views) = synthetic(0.0);
        let err = calibrate_camera(&views[..2], truth.size, &ZhangConfig::default()).unwrap_err();
        assert!(err.to_string().contains("at least 3 views"), "{err}");
        let mut bad = views.clone();
        bad[1].image_points.pop();
        let err = calibrate_camera(&bad, truth.size, &ZhangConfig::default()).unwrap_err();
        assert!(err.to_string().contains("view 1"), "{err}");
        // Three parallel boards: translated only.
        let parallel: Vec<CalibrationView> = (0..3)
            .map(|k| {
                let pose = RvecTvec::new(
                    Vector3::zeros(),
                    Vector3::new(-100.0 + 20.0 * f64::from(k), -60.0, 600.0),
                );
                CalibrationView {
                    object_points: views[0].object_points.clone(),
                    image_points: views[0]
                        .object_points
                        .iter()
                        .map(|p| truth.project(&pose.transform_point(p)).unwrap())
                        .collect(),
                }
            })
            .collect();
        let err = calibrate_camera(&parallel, truth.size, &ZhangConfig::default()).unwrap_err();
        assert!(err.to_string().contains("tilt the board"), "{err}");
    }

    #[test]
    fn options_hold_their_constraints() {
        let (truth, views) = synthetic(0.0);
        let cfg = ZhangConfig {
            fix_principal_point: true,
            aspect_ratio: Some(1.0),
            fix_k3: true,
            ..ZhangConfig::default()
        };
        let c = calibrate_camera(&views, truth.size, &cfg).unwrap();
        let i = c.camera.intrinsics;
        // Constraints are exact by construction (fixed parameters never move).
        assert_relative_eq!(i.cx, 319.5, epsilon = 1e-12);
        assert_relative_eq!(i.cy, 239.5, epsilon = 1e-12);
        assert_relative_eq!(i.fx, i.fy, epsilon = 1e-9);
        assert_eq!(c.camera.distortion.k3(), 0.0);
        assert_eq!(c.std_dev.intrinsics[2], 0.0);
        // The model is wrong (the truth has fx != fy, an off-centre principal point): the
        // residual shows it.
        assert!(c.rms > 0.1);
        // The rational model fits the 5-coefficient truth exactly (k4..k6 = 0 is in it).
        let r = calibrate_camera(
            &views,
            truth.size,
            &ZhangConfig {
                rational_model: true,
                ..ZhangConfig::default()
            },
        )
        .unwrap();
        assert!(r.rms < 1e-5, "rms {}", r.rms);
        assert_relative_eq!(r.camera.intrinsics.fx, 800.0, max_relative = 1e-5);
    }
}
