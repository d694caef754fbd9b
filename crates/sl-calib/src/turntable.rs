//! Turntable axis calibration: a board standing on the platter is seen at several motor
//! readings; the axis (direction and a point, camera frame) and the motor's angle scale are
//! fitted in closed form from the relative board poses, then refined by Levenberg–Marquardt
//! over the reprojections of every corner of every view.
//!
//! The model: the board pose at motor reading `m` is `T_cam_board(m) = M(θ(m)) · B`, where
//! `M(θ)` turns by `θ = scale · m + offset` about the axis and `B` is the board's pose at
//! platter angle 0. The offset cannot be observed from relative motions; it is fixed by a
//! convention (see [`TurntableCalibration`]).

use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Point2, Point3, SMatrix, Translation3, Unit,
    UnitQuaternion, Vector2, Vector3, Vector6,
};
use serde::{Deserialize, Serialize};
use sl_camera::{CameraModel, RvecTvec, TurntableAxis, isometry_from_rt, rotation_from_rvec};
use sl_codec::Frame;

use crate::homography::homography_dlt;
use crate::lm::{INITIAL_DAMPING, MAX_DAMPING};
use crate::{
    BoardCorners, BoardSize, CalibError, CalibrationView, DetectorConfig, detect_checkerboard,
};

/// Fewer motor readings than this cannot separate the axis point from noise: two poses give
/// one relative motion, whose screw axis is the answer with no redundancy at all.
pub const MIN_TURNTABLE_VIEWS: usize = 3;

/// Board points needed for a pose: a plane homography needs 4.
const MIN_POINTS: usize = 4;

/// Relative step of the central differences of the axis refinement: with parameters of
/// order 1 (radians, the scale) to 1e3 (mm), truncation `O(h²)` and rounding `O(ε/h)` are
/// balanced near `ε^(1/3) ≈ 6e-6`.
const DIFF_STEP: f64 = 6e-6;

/// Pose refinement: LM iterations at most (a 6-parameter problem from a homography start
/// converges in a handful).
const POSE_ITERATIONS: usize = 50;

/// Turn scale (platter radians per motor radian) below which the board is taken as not
/// having turned: a millionth is far below any gear error and far above rounding.
const MIN_SCALE: f64 = 1e-6;

/// A board direction whose component across the axis is shorter than this (unit vectors)
/// is too close to the axis to define the platter angle; the next board axis is used.
const MIN_ACROSS: f64 = 0.5;

/// One view of the board on the turntable.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TurntableView {
    /// Name of the view (image file or folder), used in messages.
    pub label: String,
    /// The motor reading, degrees.
    pub motor_angle_deg: f64,
    /// Board points and their observed pixels.
    pub view: CalibrationView,
}

impl TurntableView {
    /// A view from detected corners, for squares of `square_mm`.
    pub fn from_corners(
        label: impl Into<String>,
        motor_angle_deg: f64,
        corners: &BoardCorners,
        square_mm: f64,
    ) -> Self {
        Self {
            label: label.into(),
            motor_angle_deg,
            view: CalibrationView::from_corners(corners, square_mm),
        }
    }

    /// Detects the board in the image of the view taken at `motor_angle_deg`.
    ///
    /// # Errors
    /// [`CalibError::BoardNotFoundAtAngle`] naming the angle and the image (`label`).
    pub fn detect(
        image: &Frame<u8>,
        label: &str,
        motor_angle_deg: f64,
        size: BoardSize,
        square_mm: f64,
        config: &DetectorConfig,
    ) -> Result<Self, CalibError> {
        let corners = detect_checkerboard(image, size, config, label).map_err(|e| {
            CalibError::BoardNotFoundAtAngle {
                motor_angle_deg,
                source: Box::new(e),
            }
        })?;
        Ok(Self::from_corners(
            label,
            motor_angle_deg,
            &corners,
            square_mm,
        ))
    }
}

/// A board pose seen at a motor reading (input of [`fit_turntable_axis`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseAtAngle {
    /// The motor reading, degrees.
    pub motor_angle_deg: f64,
    /// `T_cam_board`: board coordinates into the camera frame (mm).
    pub t_cam_board: Isometry3<f64>,
}

/// Options of [`calibrate_turntable`] and [`fit_turntable_axis`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TurntableConfig {
    /// Smallest accepted span of the motor readings, degrees. The direction error grows as
    /// the inverse of the span; 20° of a board seen with 0.1 px noise already gives the
    /// direction to about 0.02° on the virtual rig.
    pub min_span_deg: f64,
    /// Largest number of Levenberg–Marquardt iterations (the loop stops at convergence).
    pub max_iterations: usize,
    /// Relative decrease of the squared error below which the iteration stops.
    pub tolerance: f64,
}

impl Default for TurntableConfig {
    fn default() -> Self {
        Self {
            min_span_deg: 20.0,
            max_iterations: 100,
            tolerance: 1e-14,
        }
    }
}

/// Standard deviations of the refined axis (σ² estimated from the residuals, as OpenCV).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TurntableStdDev {
    /// Angular standard deviation of the direction (degrees): root of the summed variances
    /// of its two tilts.
    pub direction_deg: f64,
    /// Standard deviation of the axis point across the axis (mm): root of the summed
    /// variances of its two components across the axis.
    pub point_mm: f64,
    /// Standard deviation of `angle_scale`.
    pub angle_scale: f64,
}

/// The result of [`calibrate_turntable`].
///
/// `axis.point_mm` is the **foot of the axis nearest the camera centre** (the point of the
/// axis line closest to the camera's origin): the only point of the line the board poses
/// determine. `axis.angle_offset_deg` follows a convention: platter angle 0 is the
/// orientation in which the board's x axis, seen along the turntable axis, points along
/// the camera's x axis (the board's y axis when its x axis is within 60° of the turntable
/// axis; the camera's y axis likewise). A board standing upright and facing the camera
/// therefore has angle 0. The direction is signed so that `angle_scale > 0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TurntableCalibration {
    /// The refined axis.
    pub axis: TurntableAxis,
    /// The closed-form axis the refinement started from.
    pub initial_axis: TurntableAxis,
    /// `T_cam_board` at platter angle 0 (motor reading `-offset / scale`).
    pub t_cam_board_ref: Isometry3<f64>,
    /// `T_cam_board` of each view, estimated alone (the closed form's input).
    pub view_poses: Vec<Isometry3<f64>>,
    /// RMS reprojection error over all corners (px), OpenCV's definition.
    pub rms: f64,
    /// RMS reprojection error of each view (px).
    pub view_rms: Vec<f64>,
    /// Per view, per corner: observed minus predicted pixel.
    pub residuals: Vec<Vec<Vector2<f64>>>,
    /// Standard deviations of the axis parameters.
    pub std_dev: TurntableStdDev,
    /// Levenberg–Marquardt iterations made.
    pub iterations: usize,
}

/// Estimates the pose `T_cam_board` of a planar board (`z = 0` points) from its pixels
/// through a calibrated camera: a homography of the undistorted normalised points gives the
/// start, Levenberg–Marquardt over the reprojection error (analytic Jacobians) the answer.
///
/// # Errors
/// [`CalibError::Frame`] naming `label` when there are fewer than 4 points, the point
/// counts differ, the points are not on `z = 0`, a pixel cannot be undistorted, or the
/// points are degenerate (collinear).
pub fn board_pose(
    camera: &CameraModel,
    view: &CalibrationView,
    label: &str,
) -> Result<Isometry3<f64>, CalibError> {
    let frame = |reason: String| CalibError::Frame {
        frame: label.to_owned(),
        reason,
    };
    let n = view.object_points.len();
    if n != view.image_points.len() {
        return Err(frame(format!(
            "{n} board points but {} pixels",
            view.image_points.len()
        )));
    }
    if n < MIN_POINTS {
        return Err(frame(format!(
            "{n} board points, at least {MIN_POINTS} needed for a pose"
        )));
    }
    if view.object_points.iter().any(|p| p.z != 0.0) {
        return Err(frame("board points must lie on z = 0".into()));
    }
    let mut normalised = Vec::with_capacity(n);
    for (k, px) in view.image_points.iter().enumerate() {
        let ray = camera
            .unproject(px)
            .ok_or_else(|| frame(format!("corner {k} at {px} cannot be undistorted")))?;
        normalised.push(Point2::new(ray.x, ray.y));
    }
    let plane: Vec<Point2<f64>> = view
        .object_points
        .iter()
        .map(|p| Point2::new(p.x, p.y))
        .collect();
    let h = homography_dlt(&plane, &normalised)
        .ok_or_else(|| frame("board points are degenerate (collinear?)".into()))?;
    let (h1, h2, h3) = (h.column(0), h.column(1), h.column(2));
    let mut lambda = 2.0 / (h1.norm() + h2.norm());
    if h3.z * lambda < 0.0 {
        lambda = -lambda; // the board is in front of the camera
    }
    let r1 = h1 * lambda;
    let r2 = h2 * lambda;
    let r = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    let svd = r.svd(true, true);
    let r = match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => u * v_t,
        _ => return Err(frame("homography does not decompose into a pose".into())),
    };
    let start = isometry_from_rt(&r, &(h3 * lambda))?;
    Ok(refine_pose(camera, view, start))
}

/// Levenberg–Marquardt over one pose (analytic Jacobians of `sl-camera`).
fn refine_pose(
    camera: &CameraModel,
    view: &CalibrationView,
    start: Isometry3<f64>,
) -> Isometry3<f64> {
    let cost_jac = |pose: &RvecTvec, with_jac: bool| {
        let mut cost = 0.0;
        let mut jtj = SMatrix::<f64, 6, 6>::zeros();
        let mut jtr = Vector6::zeros();
        for (x, u) in view.object_points.iter().zip(&view.image_points) {
            let j = camera.project_with_pose_jacobians(pose, x)?;
            let r = u - j.projection.pixel;
            cost += r.norm_squared();
            if with_jac {
                let mut jj = SMatrix::<f64, 2, 6>::zeros();
                jj.fixed_view_mut::<2, 3>(0, 0).copy_from(&j.d_rvec);
                jj.fixed_view_mut::<2, 3>(0, 3).copy_from(&j.d_tvec);
                jtj += jj.transpose() * jj;
                jtr += jj.transpose() * r;
            }
        }
        Some((cost, jtj, jtr))
    };
    let mut pose = RvecTvec::from_isometry(&start);
    let mut mu = INITIAL_DAMPING;
    for _ in 0..POSE_ITERATIONS {
        let Some((cost, jtj, jtr)) = cost_jac(&pose, true) else {
            break;
        };
        let mut improved = false;
        while mu < MAX_DAMPING {
            let mut a = jtj;
            for i in 0..6 {
                a[(i, i)] += mu * jtj[(i, i)].max(f64::EPSILON);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&jtr)) else {
                mu *= 10.0;
                continue;
            };
            let trial = RvecTvec::new(
                pose.rvec + step.fixed_rows::<3>(0),
                pose.tvec + step.fixed_rows::<3>(3),
            );
            match cost_jac(&trial, false) {
                Some((c, _, _)) if c < cost => {
                    let done = cost - c <= 1e-15 * cost;
                    pose = trial;
                    mu = (mu * 0.1).max(1e-12);
                    improved = !done;
                    break;
                }
                _ => mu *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    pose.to_isometry()
}

/// The signed angle (radians, in `(-π, π]`) of a rotation about a unit direction.
fn signed_angle(q: &UnitQuaternion<f64>, d: &Vector3<f64>) -> f64 {
    let s = q.imag().dot(d);
    2.0 * s.atan2(q.scalar())
}

/// Motion by `angle` (radians) about the line through `point` along `direction`.
fn rotation_about(direction: &Vector3<f64>, point: &Point3<f64>, angle: f64) -> Isometry3<f64> {
    let q = UnitQuaternion::from_axis_angle(&Unit::new_normalize(*direction), angle);
    Isometry3::from_parts(Translation3::from(point.coords - q * point.coords), q)
}

/// The foot of the line (`point`, unit `direction`) nearest the origin.
fn foot(direction: &Vector3<f64>, point: &Point3<f64>) -> Point3<f64> {
    point - direction * direction.dot(&point.coords)
}

fn check_angles(angles: &[(String, f64)], cfg: &TurntableConfig) -> Result<(), CalibError> {
    if angles.len() < MIN_TURNTABLE_VIEWS {
        return Err(CalibError::TooFewAngles {
            found: angles.len(),
            needed: MIN_TURNTABLE_VIEWS,
        });
    }
    for (label, a) in angles {
        if !a.is_finite() {
            return Err(CalibError::Frame {
                frame: label.clone(),
                reason: format!("motor angle {a} is not finite"),
            });
        }
    }
    let lo = angles.iter().map(|a| a.1).fold(f64::INFINITY, f64::min);
    let hi = angles.iter().map(|a| a.1).fold(f64::NEG_INFINITY, f64::max);
    if !(cfg.min_span_deg.is_finite() && cfg.min_span_deg >= 0.0) {
        return Err(CalibError::param(
            "min_span_deg",
            format!("{} is not a non-negative angle", cfg.min_span_deg),
        ));
    }
    if hi - lo < cfg.min_span_deg {
        return Err(CalibError::AngleSpan {
            span_deg: hi - lo,
            needed_deg: cfg.min_span_deg,
        });
    }
    Ok(())
}

/// The closed-form axis from board poses at several motor readings: the direction is the
/// common null vector of `R_ij − I` over every pair of relative rotations, the point solves
/// `(I − R_ij) c = t_ij` with `d · c = 0` in least squares, and the scale is the
/// least-squares slope of the relative turn angles over the motor steps between
/// neighbouring readings. `point_mm` is the foot nearest the camera centre and the offset
/// is 0 (the reference orientation is that of motor reading 0); see
/// [`TurntableCalibration`] for the conventions of the refined fit.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use sl_calib::{PoseAtAngle, TurntableConfig, fit_turntable_axis};
/// use sl_calib::sl_camera::TurntableAxis;
/// let truth = TurntableAxis::new(Vector3::new(0.0, -1.0, 0.1), Point3::new(5.0, 0.0, 600.0))?;
/// let board = Isometry3::translation(-50.0, -40.0, 560.0);
/// let poses: Vec<PoseAtAngle> = [-30.0, 0.0, 30.0]
///     .iter()
///     .map(|&m| PoseAtAngle { motor_angle_deg: m, t_cam_board: truth.motion(m) * board })
///     .collect();
/// let axis = fit_turntable_axis(&poses, &TurntableConfig::default())?;
/// assert!((axis.direction - truth.direction).norm() < 1e-9);
/// assert!((axis.angle_scale - 1.0).abs() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`CalibError::TooFewAngles`], [`CalibError::AngleSpan`], and [`CalibError::Degenerate`]
/// when the board did not turn.
pub fn fit_turntable_axis(
    poses: &[PoseAtAngle],
    cfg: &TurntableConfig,
) -> Result<TurntableAxis, CalibError> {
    let labelled: Vec<(String, f64)> = poses
        .iter()
        .map(|p| {
            (
                format!("motor {} deg", p.motor_angle_deg),
                p.motor_angle_deg,
            )
        })
        .collect();
    check_angles(&labelled, cfg)?;
    let mut m = Matrix3::zeros();
    let mut rel = Vec::new();
    for (i, a) in poses.iter().enumerate() {
        for b in poses.iter().skip(i + 1) {
            let t = b.t_cam_board * a.t_cam_board.inverse();
            let r = t.rotation.to_rotation_matrix().into_inner() - Matrix3::identity();
            m += r.transpose() * r;
            rel.push((r, t.translation.vector));
        }
    }
    let eig = m.symmetric_eigen();
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |acc, (i, &v)| if v < acc.1 { (i, v) } else { acc },
        );
    let mut d: Vector3<f64> = eig.eigenvectors.column(imin).into_owned();
    // Scale from neighbouring readings (small turns: no wrap-around).
    let mut order: Vec<&PoseAtAngle> = poses.iter().collect();
    order.sort_by(|a, b| a.motor_angle_deg.total_cmp(&b.motor_angle_deg));
    let (mut num, mut den) = (0.0, 0.0);
    for w in order.windows(2) {
        if let [a, b] = w {
            let q = (b.t_cam_board * a.t_cam_board.inverse()).rotation;
            let dm = (b.motor_angle_deg - a.motor_angle_deg).to_radians();
            num += signed_angle(&q, &d) * dm;
            den += dm * dm;
        }
    }
    let mut scale = if den > 0.0 { num / den } else { 0.0 };
    if scale.is_nan() || scale.abs() <= MIN_SCALE {
        return Err(CalibError::Degenerate(
            "the board did not turn between motor readings: check that it stands on the \
             platter and that the motor moved"
                .into(),
        ));
    }
    if scale < 0.0 {
        d = -d;
        scale = -scale;
    }
    // Point: (I − R) c = t for every pair, plus d·c = 0.
    let rows = 3 * rel.len() + 1;
    let mut a = DMatrix::zeros(rows, 3);
    let mut b = DVector::zeros(rows);
    for (k, (r, t)) in rel.iter().enumerate() {
        a.view_mut((3 * k, 0), (3, 3)).copy_from(&(-r));
        b.rows_mut(3 * k, 3).copy_from(t);
    }
    a.row_mut(rows - 1).copy_from(&d.transpose());
    let c = a
        .svd(true, true)
        .solve(&b, 1e-12)
        .map_err(|e| CalibError::Degenerate(format!("axis point: {e}")))?;
    let mut axis = TurntableAxis::new(d, Point3::new(c[0], c[1], c[2]))?;
    axis.angle_scale = scale;
    Ok(axis)
}

/// Parameters of the refinement: direction, foot, scale (offset 0), reference board pose.
#[derive(Clone, Copy)]
struct AxisState {
    direction: Vector3<f64>,
    point: Point3<f64>,
    scale: f64,
    board: Isometry3<f64>,
}

/// Number of free parameters: 2 direction tilts, 2 point moves, the scale, 6 pose.
const NP: usize = 11;

impl AxisState {
    /// Two unit vectors across the direction.
    fn across(&self) -> (Vector3<f64>, Vector3<f64>) {
        let d = self.direction;
        let helper = if d.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = d.cross(&helper).normalize();
        (e1, d.cross(&e1))
    }

    fn moved(&self, delta: &[f64; NP]) -> Self {
        let (e1, e2) = self.across();
        let direction = (self.direction + e1 * delta[0] + e2 * delta[1]).normalize();
        let point = foot(&direction, &(self.point + e1 * delta[2] + e2 * delta[3]));
        let w = Vector3::new(delta[5], delta[6], delta[7]);
        let tau = Vector3::new(delta[8], delta[9], delta[10]);
        let step = Isometry3::from_parts(Translation3::from(tau), rotation_from_rvec(&w));
        Self {
            direction,
            point,
            scale: self.scale + delta[4],
            board: step * self.board,
        }
    }

    fn pose(&self, motor_deg: f64) -> Isometry3<f64> {
        rotation_about(
            &self.direction,
            &self.point,
            (self.scale * motor_deg).to_radians(),
        ) * self.board
    }

    /// Residuals (observed − predicted), two per corner, or `None` if a point leaves the
    /// camera's valid region.
    fn residuals(&self, camera: &CameraModel, views: &[TurntableView]) -> Option<Vec<f64>> {
        let mut out = Vec::new();
        for v in views {
            let pose = self.pose(v.motor_angle_deg);
            for (x, u) in v.view.object_points.iter().zip(&v.view.image_points) {
                let p = camera.project(&(pose * x))?;
                out.push(u.x - p.x);
                out.push(u.y - p.y);
            }
        }
        Some(out)
    }
}

/// Jacobian of the residuals by central differences (11 parameters).
fn jacobian(
    state: &AxisState,
    camera: &CameraModel,
    views: &[TurntableView],
    rows: usize,
) -> Option<DMatrix<f64>> {
    let t = state.board.translation.vector.norm().max(1.0);
    let mut jac = DMatrix::zeros(rows, NP);
    for c in 0..NP {
        // Steps in mm for the point and translation, radians / unit scale otherwise.
        let h = match c {
            2 | 3 | 8..=10 => DIFF_STEP * t,
            _ => DIFF_STEP,
        };
        let mut plus = [0.0; NP];
        plus[c] = h;
        let mut minus = [0.0; NP];
        minus[c] = -h;
        let rp = state.moved(&plus).residuals(camera, views)?;
        let rm = state.moved(&minus).residuals(camera, views)?;
        for (r, (a, b)) in rp.iter().zip(&rm).enumerate() {
            jac[(r, c)] = (a - b) / (2.0 * h);
        }
    }
    Some(jac)
}

/// The platter angle (radians) of a board pose under the convention of
/// [`TurntableCalibration`].
fn convention_angle(direction: &Vector3<f64>, board: &Isometry3<f64>) -> f64 {
    let across = |v: Vector3<f64>| v - direction * direction.dot(&v);
    let pick = |a: Vector3<f64>, b: Vector3<f64>| {
        let pa = across(a);
        if pa.norm() >= MIN_ACROSS {
            pa
        } else {
            across(b)
        }
    };
    let b = pick(board.rotation * Vector3::x(), board.rotation * Vector3::y());
    let c = pick(Vector3::x(), Vector3::y());
    direction.dot(&c.cross(&b)).atan2(c.dot(&b))
}

/// Calibrates the turntable axis from views of a board standing on the platter at several
/// motor readings, seen by a calibrated camera: a pose per view ([`board_pose`]), the
/// closed form of [`fit_turntable_axis`], then Levenberg–Marquardt over the axis direction,
/// the axis point, the angle scale and the board's reference pose, minimising the
/// reprojection error of every corner of every view. See [`TurntableCalibration`] for the
/// conventions of the result.
///
/// # Errors
/// [`CalibError::TooFewAngles`], [`CalibError::AngleSpan`], [`CalibError::Frame`] naming a
/// view whose pose cannot be estimated, [`CalibError::Degenerate`] when the board did not
/// turn or the refinement fails.
pub fn calibrate_turntable(
    camera: &CameraModel,
    views: &[TurntableView],
    cfg: &TurntableConfig,
) -> Result<TurntableCalibration, CalibError> {
    let labelled: Vec<(String, f64)> = views
        .iter()
        .map(|v| (v.label.clone(), v.motor_angle_deg))
        .collect();
    check_angles(&labelled, cfg)?;
    let view_poses = views
        .iter()
        .map(|v| board_pose(camera, &v.view, &v.label))
        .collect::<Result<Vec<_>, _>>()?;
    let poses: Vec<PoseAtAngle> = views
        .iter()
        .zip(&view_poses)
        .map(|(v, p)| PoseAtAngle {
            motor_angle_deg: v.motor_angle_deg,
            t_cam_board: *p,
        })
        .collect();
    let initial = fit_turntable_axis(&poses, cfg)?;
    // Reference pose from the views: mean of the back-turned poses (rotation by the first,
    // translation averaged).
    let back = |p: &PoseAtAngle| {
        rotation_about(
            &initial.direction,
            &initial.point_mm,
            -(initial.angle_scale * p.motor_angle_deg).to_radians(),
        ) * p.t_cam_board
    };
    let mut board = poses.first().map(back).unwrap_or_else(Isometry3::identity);
    let mean_t = poses
        .iter()
        .map(|p| back(p).translation.vector)
        .sum::<Vector3<f64>>()
        / poses.len() as f64;
    board.translation.vector = mean_t;
    let mut state = AxisState {
        direction: initial.direction,
        point: initial.point_mm,
        scale: initial.angle_scale,
        board,
    };
    let fail = || {
        CalibError::Degenerate(
            "turntable refinement: a board corner left the camera's valid region".into(),
        )
    };
    let mut r = state.residuals(camera, views).ok_or_else(fail)?;
    let rows = r.len();
    let mut cost: f64 = r.iter().map(|v| v * v).sum();
    let mut mu = INITIAL_DAMPING;
    let mut iterations = 0;
    let mut jac = jacobian(&state, camera, views, rows).ok_or_else(fail)?;
    for _ in 0..cfg.max_iterations {
        let jtj = jac.transpose() * &jac;
        // Residuals are observed − predicted: the Gauss–Newton step solves JᵀJ δ = −Jᵀr.
        let jtr = -(jac.transpose() * DVector::from_column_slice(&r));
        let mut accepted = None;
        while mu < MAX_DAMPING {
            let mut a = jtj.clone();
            for i in 0..NP {
                a[(i, i)] += mu * jtj[(i, i)].max(f64::EPSILON);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&jtr)) else {
                mu *= 10.0;
                continue;
            };
            let mut delta = [0.0; NP];
            delta.copy_from_slice(step.as_slice());
            let trial = state.moved(&delta);
            match trial.residuals(camera, views) {
                Some(tr) => {
                    let c: f64 = tr.iter().map(|v| v * v).sum();
                    if c < cost {
                        accepted = Some((trial, tr, c));
                        mu = (mu * 0.1).max(1e-12);
                        break;
                    }
                    mu *= 10.0;
                }
                None => mu *= 10.0,
            }
        }
        let Some((trial, tr, c)) = accepted else {
            break;
        };
        let converged = cost - c <= cfg.tolerance * cost;
        iterations += 1;
        state = trial;
        r = tr;
        cost = c;
        jac = jacobian(&state, camera, views, rows).ok_or_else(fail)?;
        if converged {
            break;
        }
    }
    // Standard deviations: σ² (JᵀJ)⁻¹ with σ² = cost / (residuals − parameters).
    let dof = rows.saturating_sub(NP).max(1) as f64;
    let sigma2 = cost / dof;
    let cov = (jac.transpose() * &jac)
        .try_inverse()
        .unwrap_or_else(|| DMatrix::from_element(NP, NP, f64::NAN));
    let std_dev = TurntableStdDev {
        direction_deg: (sigma2 * (cov[(0, 0)] + cov[(1, 1)])).sqrt().to_degrees(),
        point_mm: (sigma2 * (cov[(2, 2)] + cov[(3, 3)])).sqrt(),
        angle_scale: (sigma2 * cov[(4, 4)]).sqrt(),
    };
    // Residuals per view.
    let mut residuals = Vec::with_capacity(views.len());
    let mut view_rms = Vec::with_capacity(views.len());
    let mut at = 0;
    for v in views {
        let n = v.view.object_points.len();
        let res: Vec<Vector2<f64>> = (0..n)
            .filter_map(|k| Some(Vector2::new(*r.get(at + 2 * k)?, *r.get(at + 2 * k + 1)?)))
            .collect();
        at += 2 * n;
        let ss: f64 = res.iter().map(|e| e.norm_squared()).sum();
        view_rms.push(if n > 0 { (ss / n as f64).sqrt() } else { 0.0 });
        residuals.push(res);
    }
    let corners = rows / 2;
    let rms = if corners > 0 {
        (cost / corners as f64).sqrt()
    } else {
        0.0
    };
    // Offset convention: platter angle 0 where the board's x axis points along the camera's.
    let offset = convention_angle(&state.direction, &state.board);
    let t_cam_board_ref = rotation_about(&state.direction, &state.point, -offset) * state.board;
    let mut axis = TurntableAxis::new(state.direction, state.point)?;
    axis.angle_scale = state.scale;
    axis.angle_offset_deg = offset.to_degrees();
    axis.normalize()?;
    Ok(TurntableCalibration {
        axis,
        initial_axis: initial,
        t_cam_board_ref,
        view_poses,
        rms,
        view_rms,
        residuals,
        std_dev,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use sl_camera::{Distortion, ImageSize, Intrinsics};

    fn camera() -> CameraModel {
        CameraModel::new(
            Intrinsics::new(1440.0, 1440.0, 639.5, 359.5),
            Distortion::from_opencv(&[-0.08, 0.12, 0.0004, -0.0003, 0.0]).unwrap(),
            ImageSize::new(1280, 720),
        )
        .unwrap()
    }

    fn board_view(cam: &CameraModel, pose: &Isometry3<f64>) -> CalibrationView {
        let object_points: Vec<Point3<f64>> = (0..6)
            .flat_map(|r| (0..9).map(move |c| Point3::new(c as f64 * 20.0, r as f64 * 20.0, 0.0)))
            .collect();
        let image_points = object_points
            .iter()
            .map(|p| cam.project(&(pose * p)).unwrap())
            .collect();
        CalibrationView {
            object_points,
            image_points,
        }
    }

    #[test]
    fn board_pose_recovers_an_exact_pose() {
        let cam = camera();
        let truth = Isometry3::from_parts(
            Translation3::new(-60.0, -40.0, 650.0),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 0.1),
        );
        let pose = board_pose(&cam, &board_view(&cam, &truth), "synthetic").unwrap();
        // Exact projections: only rounding and the LM stop remain (1e-6 mm at 650 mm).
        assert_abs_diff_eq!(
            pose.translation.vector,
            truth.translation.vector,
            epsilon = 1e-6
        );
        assert_abs_diff_eq!(pose.rotation.angle_to(&truth.rotation), 0.0, epsilon = 1e-9);
    }

    #[test]
    fn convention_angle_is_zero_for_a_board_facing_the_camera() {
        let d = Vector3::new(0.0, -1.0, -0.2).normalize();
        assert_abs_diff_eq!(
            convention_angle(&d, &Isometry3::identity()),
            0.0,
            epsilon = 1e-12
        );
        let turned = rotation_about(&d, &Point3::new(0.0, 0.0, 600.0), 0.4);
        assert_abs_diff_eq!(convention_angle(&d, &turned), 0.4, epsilon = 1e-12);
    }
}
