//! Joint refinement of a camera–projector pair (as `cv::stereoCalibrate`): camera intrinsics
//! and distortion, projector intrinsics and distortion, one pose per board view and the single
//! `T_proj_cam`, by Levenberg–Marquardt with analytic Jacobians, solved through the Schur
//! complement over the per-view poses (`lm.rs`, as Zhang's calibration).

use nalgebra::{DMatrix, DVector, Matrix6, Point2, Point3, SMatrix, Vector2, Vector3, Vector6};
use sl_camera::{CameraModel, ImageSize, RvecTvec, isometry_from_rt, rotation_jacobian};

use crate::CalibError;
use crate::lm::{
    Normal, SchurProblem, levenberg_marquardt, std_dev, step_poses, unscaled_covariance,
};
use crate::zhang::{FULL, Layout, camera_from_full};
use crate::{ParameterStdDev, ZhangConfig};

use crate::predicted::SHARED;

/// The mean of per-view relative poses (`T_b_a` from each view's `T_b_board · T_a_board⁻¹`):
/// the chordal mean of the rotations (the rotation nearest the sum of their matrices) and the
/// mean of the translations; the start of a joint refinement. `what` names the pose in the
/// error.
///
/// # Errors
/// [`CalibError::Degenerate`] without a pose or when the rotations have no mean.
pub(crate) fn mean_relative_pose(
    poses: impl Iterator<Item = nalgebra::Isometry3<f64>>,
    what: &str,
) -> Result<RvecTvec, CalibError> {
    let mut r_sum = nalgebra::Matrix3::zeros();
    let mut t_sum = Vector3::zeros();
    let mut n = 0usize;
    for t in poses {
        r_sum += t.rotation.to_rotation_matrix().into_inner();
        t_sum += t.translation.vector;
        n += 1;
    }
    let svd = r_sum.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(CalibError::Degenerate(format!(
            "the per-view {what} rotations have no mean"
        )));
    };
    if n == 0 {
        return Err(CalibError::Degenerate(format!(
            "no view gives a {what} pose"
        )));
    }
    let mut rot = u * vt;
    if rot.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        rot = u * vt;
    }
    Ok(RvecTvec::from_isometry(&isometry_from_rt(
        &rot,
        &(t_sum / n as f64),
    )?))
}

/// RMS of a set of residuals (0 for none).
pub(crate) fn rms(r: &[Vector2<f64>]) -> f64 {
    if r.is_empty() {
        0.0
    } else {
        (r.iter().map(Vector2::norm_squared).sum::<f64>() / r.len() as f64).sqrt()
    }
}

/// The two devices of a joint solution as calibrations — the first with its per-view poses,
/// the second with `T_second_board = extrinsics · T_first_board` (its unmapped corners left
/// out of its residuals) — and the RMS over both devices' residuals together (OpenCV's
/// `stereoCalibrate` definition).
pub(crate) fn joint_calibrations(
    sol: &StereoSolution,
) -> (crate::CameraCalibration, crate::CameraCalibration, f64) {
    let second_residuals: Vec<Vec<Vector2<f64>>> = sol
        .projector_residuals
        .iter()
        .map(|r| r.iter().flatten().copied().collect())
        .collect();
    let all_first: Vec<Vector2<f64>> = sol.camera_residuals.iter().flatten().copied().collect();
    let all_second: Vec<Vector2<f64>> = second_residuals.iter().flatten().copied().collect();
    let both: Vec<Vector2<f64>> = all_first.iter().chain(&all_second).copied().collect();
    let t_second_first = sol.extrinsics.to_isometry();
    let first = crate::CameraCalibration {
        camera: sol.camera,
        poses: sol.poses.clone(),
        rms: rms(&all_first),
        view_rms: sol.camera_residuals.iter().map(|r| rms(r)).collect(),
        residuals: sol.camera_residuals.clone(),
        std_dev: sol.camera_std.clone(),
        iterations: sol.iterations,
    };
    let second = crate::CameraCalibration {
        camera: sol.projector,
        poses: sol
            .poses
            .iter()
            .map(|p| RvecTvec::from_isometry(&(t_second_first * p.to_isometry())))
            .collect(),
        rms: rms(&all_second),
        view_rms: second_residuals.iter().map(|r| rms(r)).collect(),
        residuals: second_residuals,
        std_dev: sol.projector_std.clone(),
        iterations: sol.iterations,
    };
    (first, second, rms(&both))
}

/// One board view: the board points, their camera pixels and (where mapped) projector pixels.
pub(crate) struct StereoView<'a> {
    pub(crate) object: &'a [Point3<f64>],
    pub(crate) camera: &'a [Point2<f64>],
    pub(crate) projector: &'a [Option<Point2<f64>>],
}

/// Where the refinement starts.
pub(crate) struct StereoStart {
    pub(crate) camera: CameraModel,
    pub(crate) projector: CameraModel,
    /// `T_proj_cam`.
    pub(crate) extrinsics: RvecTvec,
    /// `T_cam_board` per view.
    pub(crate) poses: Vec<RvecTvec>,
}

/// Options of the refinement.
pub(crate) struct StereoOptions<'a> {
    pub(crate) camera: &'a ZhangConfig,
    pub(crate) projector: &'a ZhangConfig,
    pub(crate) max_iterations: usize,
    pub(crate) tolerance: f64,
}

/// The refined pair with residuals and standard deviations.
pub(crate) struct StereoSolution {
    pub(crate) camera: CameraModel,
    pub(crate) projector: CameraModel,
    pub(crate) extrinsics: RvecTvec,
    pub(crate) poses: Vec<RvecTvec>,
    /// Per view, per corner: observed minus projected camera pixel.
    pub(crate) camera_residuals: Vec<Vec<Vector2<f64>>>,
    /// Per view, per corner: observed minus projected projector pixel (`None`: not mapped).
    pub(crate) projector_residuals: Vec<Vec<Option<Vector2<f64>>>>,
    pub(crate) camera_std: ParameterStdDev,
    pub(crate) projector_std: ParameterStdDev,
    /// `T_proj_cam`: rvec (rad) then tvec (board units).
    pub(crate) extrinsics_std: [f64; 6],
    /// Covariance of the full shared vector (camera 13, projector 13, `T_proj_cam` rvec and
    /// tvec), scaled by the residuals' variance; `None` when the normal equations are
    /// singular.
    pub(crate) covariance: Option<DMatrix<f64>>,
    pub(crate) iterations: usize,
}

struct State {
    camera: SMatrix<f64, FULL, 1>,
    projector: SMatrix<f64, FULL, 1>,
    extrinsics: RvecTvec,
    poses: Vec<RvecTvec>,
    models: Models,
}

struct Models {
    camera: CameraModel,
    projector: CameraModel,
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

struct Problem<'a> {
    views: &'a [StereoView<'a>],
    camera_layout: Layout,
    projector_layout: Layout,
    camera_size: ImageSize,
    projector_size: ImageSize,
    /// Block-diagonal map of the free shared parameters into the full `SHARED` vector.
    t: DMatrix<f64>,
}

impl<'a> Problem<'a> {
    fn new(views: &'a [StereoView<'a>], start: &StereoStart, opts: &StereoOptions<'_>) -> Self {
        let camera_layout = Layout::new(opts.camera);
        let projector_layout = Layout::new(opts.projector);
        let (nc, np) = (camera_layout.t.ncols(), projector_layout.t.ncols());
        let mut t = DMatrix::zeros(SHARED, nc + np + 6);
        t.view_mut((0, 0), (FULL, nc)).copy_from(&camera_layout.t);
        t.view_mut((FULL, nc), (FULL, np))
            .copy_from(&projector_layout.t);
        t.view_mut((2 * FULL, nc + np), (6, 6))
            .copy_from(&DMatrix::<f64>::identity(6, 6));
        Self {
            views,
            camera_size: start.camera.size,
            projector_size: start.projector.size,
            camera_layout,
            projector_layout,
            t,
        }
    }

    fn start(&self, start: &StereoStart) -> Option<State> {
        let camera = full_vector(&start.camera);
        let projector = full_vector(&start.projector);
        Some(State {
            models: self.models(&camera, &projector)?,
            camera,
            projector,
            extrinsics: start.extrinsics,
            poses: start.poses.clone(),
        })
    }

    fn models(
        &self,
        camera: &SMatrix<f64, FULL, 1>,
        projector: &SMatrix<f64, FULL, 1>,
    ) -> Option<Models> {
        Some(Models {
            camera: camera_from_full(camera, self.camera_layout.model, self.camera_size)?,
            projector: camera_from_full(
                projector,
                self.projector_layout.model,
                self.projector_size,
            )?,
        })
    }
}

impl SchurProblem for Problem<'_> {
    type State = State;

    fn cost(&self, s: &State) -> Option<f64> {
        let m = &s.models;
        let mut sum = 0.0;
        for (v, pose) in self.views.iter().zip(&s.poses) {
            for ((x, qc), qp) in v.object.iter().zip(v.camera).zip(v.projector) {
                let pc = pose.transform_point(x);
                sum += (qc - m.camera.project(&pc)?).norm_squared();
                if let Some(qp) = qp {
                    let pp = s.extrinsics.transform_point(&pc);
                    sum += (qp - m.projector.project(&pp)?).norm_squared();
                }
            }
        }
        Some(sum)
    }

    fn normal(&self, s: &State) -> Option<Normal> {
        let m = &s.models;
        let ng = self.t.ncols();
        let tt = self.t.transpose();
        let mut out = Normal {
            u: DMatrix::zeros(ng, ng),
            g_c: DVector::zeros(ng),
            v: Vec::with_capacity(self.views.len()),
            w: Vec::with_capacity(self.views.len()),
            g_p: Vec::with_capacity(self.views.len()),
            cost: 0.0,
        };
        for (view, pose) in self.views.iter().zip(&s.poses) {
            let mut u_full = SMatrix::<f64, SHARED, SHARED>::zeros();
            let mut g_full = SMatrix::<f64, SHARED, 1>::zeros();
            let mut w_full = SMatrix::<f64, SHARED, 6>::zeros();
            let mut v = Matrix6::zeros();
            let mut gp = Vector6::zeros();
            let mut add =
                |jg: &SMatrix<f64, 2, SHARED>, jp: &SMatrix<f64, 2, 6>, r: Vector2<f64>| {
                    u_full += jg.transpose() * jg;
                    g_full += jg.transpose() * r;
                    w_full += jg.transpose() * jp;
                    v += jp.transpose() * jp;
                    gp += jp.transpose() * r;
                    r.norm_squared()
                };
            for ((x, qc), qp) in view.object.iter().zip(view.camera).zip(view.projector) {
                // Camera: p_cam = T_cam_board x.
                let j = m.camera.project_with_pose_jacobians(pose, x)?;
                let mut jg = SMatrix::<f64, 2, SHARED>::zeros();
                jg.fixed_view_mut::<2, 5>(0, 0)
                    .copy_from(&j.projection.d_intrinsics);
                jg.fixed_view_mut::<2, 8>(0, 5)
                    .copy_from(&j.projection.d_distortion);
                let mut jp = SMatrix::<f64, 2, 6>::zeros();
                jp.fixed_view_mut::<2, 3>(0, 0).copy_from(&j.d_rvec);
                jp.fixed_view_mut::<2, 3>(0, 3).copy_from(&j.d_tvec);
                out.cost += add(&jg, &jp, qc - j.projection.pixel);
                // Projector: p_proj = T_proj_cam p_cam.
                let Some(qp) = qp else { continue };
                let pc = pose.transform_point(x);
                let k = m
                    .projector
                    .project_with_pose_jacobians(&s.extrinsics, &pc)?;
                let mut jg = SMatrix::<f64, 2, SHARED>::zeros();
                jg.fixed_view_mut::<2, 5>(0, FULL)
                    .copy_from(&k.projection.d_intrinsics);
                jg.fixed_view_mut::<2, 8>(0, FULL + 5)
                    .copy_from(&k.projection.d_distortion);
                jg.fixed_view_mut::<2, 3>(0, 2 * FULL).copy_from(&k.d_rvec);
                jg.fixed_view_mut::<2, 3>(0, 2 * FULL + 3)
                    .copy_from(&k.d_tvec);
                // ∂p_cam/∂rvec_i = ∂(R_i x)/∂rvec_i, ∂p_cam/∂tvec_i = I.
                let mut jp = SMatrix::<f64, 2, 6>::zeros();
                jp.fixed_view_mut::<2, 3>(0, 0)
                    .copy_from(&(k.d_point_world * rotation_jacobian(&pose.rvec, &x.coords)));
                jp.fixed_view_mut::<2, 3>(0, 3).copy_from(&k.d_point_world);
                out.cost += add(&jg, &jp, qp - k.projection.pixel);
            }
            let u = DMatrix::from_column_slice(SHARED, SHARED, u_full.as_slice());
            out.u += &tt * u * &self.t;
            out.g_c += &tt * DVector::from_column_slice(g_full.as_slice());
            out.w
                .push(&tt * DMatrix::from_column_slice(SHARED, 6, w_full.as_slice()));
            out.v.push(v);
            out.g_p.push(gp);
        }
        Some(out)
    }

    fn step(&self, s: &State, dc: &DVector<f64>, dp: &[Vector6<f64>]) -> Option<State> {
        let full = &self.t * dc;
        let mut camera = s.camera;
        let mut projector = s.projector;
        for i in 0..FULL {
            camera[i] += full[i];
            projector[i] += full[FULL + i];
        }
        let e = 2 * FULL;
        let extrinsics = RvecTvec::new(
            s.extrinsics.rvec + Vector3::new(full[e], full[e + 1], full[e + 2]),
            s.extrinsics.tvec + Vector3::new(full[e + 3], full[e + 4], full[e + 5]),
        );
        Some(State {
            models: self.models(&camera, &projector)?,
            camera,
            projector,
            extrinsics,
            poses: step_poses(&s.poses, dp),
        })
    }
}

/// Refines camera, projector, `T_proj_cam` and the board poses jointly.
pub(crate) fn refine_stereo(
    views: &[StereoView<'_>],
    start: &StereoStart,
    opts: &StereoOptions<'_>,
) -> Result<StereoSolution, CalibError> {
    let problem = Problem::new(views, start, opts);
    let not_projecting = || {
        CalibError::Degenerate(
            "the joint camera–projector estimate does not project every corner: check that camera and projector see the board from its printed side in every view".to_owned(),
        )
    };
    let state = problem.start(start).ok_or_else(not_projecting)?;
    let min = levenberg_marquardt(&problem, state, opts.max_iterations, opts.tolerance)
        .ok_or_else(not_projecting)?;
    let (state, normal, iterations) = (min.state, min.normal, min.iterations);
    let models = &state.models;
    // Residuals at the solution.
    let mut camera_residuals = Vec::with_capacity(views.len());
    let mut projector_residuals = Vec::with_capacity(views.len());
    let mut observations = 0usize;
    for (v, pose) in views.iter().zip(&state.poses) {
        let mut rc = Vec::with_capacity(v.camera.len());
        let mut rp = Vec::with_capacity(v.projector.len());
        for ((x, qc), qp) in v.object.iter().zip(v.camera).zip(v.projector) {
            let pc = pose.transform_point(x);
            rc.push(qc - models.camera.project(&pc).ok_or_else(not_projecting)?);
            observations += 1;
            rp.push(match qp {
                Some(qp) => {
                    observations += 1;
                    let pp = state.extrinsics.transform_point(&pc);
                    Some(qp - models.projector.project(&pp).ok_or_else(not_projecting)?)
                }
                None => None,
            });
        }
        camera_residuals.push(rc);
        projector_residuals.push(rp);
    }
    // σ² (JᵀJ)⁻¹ with σ² = cost / (2·observations − parameters), as OpenCV.
    let params = problem.t.ncols() + 6 * views.len();
    let dof = (2 * observations).saturating_sub(params).max(1) as f64;
    let sigma2 = normal.cost / dof;
    let mut camera_std = ParameterStdDev {
        intrinsics: [0.0; 5],
        distortion: [0.0; 8],
        poses: vec![[0.0; 6]; views.len()],
    };
    let mut projector_std = ParameterStdDev {
        intrinsics: [0.0; 5],
        distortion: [0.0; 8],
        poses: Vec::new(),
    };
    let mut extrinsics_std = [0.0; 6];
    let mut covariance = None;
    if let Some(cov) = unscaled_covariance(&normal) {
        let full = cov.mapped(&problem.t);
        covariance = Some(&full * sigma2);
        let sd = |i: usize| std_dev(sigma2, full[(i, i)]);
        for i in 0..5 {
            camera_std.intrinsics[i] = sd(i);
            projector_std.intrinsics[i] = sd(FULL + i);
        }
        for i in 0..8 {
            camera_std.distortion[i] = sd(5 + i);
            projector_std.distortion[i] = sd(FULL + 5 + i);
        }
        for (i, e) in extrinsics_std.iter_mut().enumerate() {
            *e = sd(2 * FULL + i);
        }
        camera_std.poses = cov.pose_std_devs(sigma2);
    }
    Ok(StereoSolution {
        camera: models.camera,
        projector: models.projector,
        extrinsics: state.extrinsics,
        poses: state.poses,
        camera_residuals,
        projector_residuals,
        camera_std,
        projector_std,
        extrinsics_std,
        covariance,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BoardSize;
    use sl_camera::{Distortion, Intrinsics};

    /// The normal equations' gradient `Jᵀr` is `−½ ∇cost`: checked against central
    /// differences of the cost in every shared and pose parameter, which validates the
    /// analytic Jacobians (including the chain through `T_proj_cam` and the board pose).
    #[test]
    fn gradient_matches_finite_differences() {
        let camera = CameraModel::new(
            Intrinsics::new(1440.0, 1442.0, 641.0, 358.0),
            Distortion::from_opencv(&[-0.08, 0.12, 0.0004, -0.0003, 0.01]).unwrap(),
            ImageSize::new(1280, 720),
        )
        .unwrap();
        let projector = CameraModel::new(
            Intrinsics::new(2200.0, 2195.0, 955.0, 545.0),
            Distortion::from_opencv(&[0.04, -0.05, 0.001, 0.0005, 0.0]).unwrap(),
            ImageSize::new(1920, 1080),
        )
        .unwrap();
        let object = BoardSize::new(4, 3).object_points(20.0);
        let extrinsics = RvecTvec::new(
            Vector3::new(0.02, -0.42, 0.01),
            Vector3::new(-180.0, 2.0, 90.0),
        );
        let poses = vec![
            RvecTvec::new(
                Vector3::new(0.3, -0.2, 0.1),
                Vector3::new(-40.0, -30.0, 450.0),
            ),
            RvecTvec::new(
                Vector3::new(-0.25, 0.15, -0.2),
                Vector3::new(-20.0, -10.0, 420.0),
            ),
        ];
        // Observations off the model by a few pixels, so that the residuals are not zero.
        let cam_obs: Vec<Vec<Point2<f64>>> = poses
            .iter()
            .map(|p| {
                object
                    .iter()
                    .enumerate()
                    .map(|(i, x)| {
                        camera.project(&p.transform_point(x)).unwrap()
                            + Vector2::new(0.7 * (i % 3) as f64, -0.4)
                    })
                    .collect()
            })
            .collect();
        let proj_obs: Vec<Vec<Option<Point2<f64>>>> = poses
            .iter()
            .map(|p| {
                object
                    .iter()
                    .enumerate()
                    .map(|(i, x)| {
                        (i != 4).then(|| {
                            projector
                                .project(&extrinsics.transform_point(&p.transform_point(x)))
                                .unwrap()
                                + Vector2::new(-0.5, 0.3 * (i % 4) as f64)
                        })
                    })
                    .collect()
            })
            .collect();
        let views: Vec<StereoView<'_>> = cam_obs
            .iter()
            .zip(&proj_obs)
            .map(|(c, p)| StereoView {
                object: &object,
                camera: c,
                projector: p,
            })
            .collect();
        let start = StereoStart {
            camera,
            projector,
            extrinsics,
            poses,
        };
        let cfg = ZhangConfig::default();
        let opts = StereoOptions {
            camera: &cfg,
            projector: &cfg,
            max_iterations: 0,
            tolerance: 0.0,
        };
        let problem = Problem::new(&views, &start, &opts);
        let state = problem.start(&start).unwrap();
        let normal = problem.normal(&state).unwrap();
        let ng = problem.t.ncols();
        let cost_at = |dc: &DVector<f64>, dp: &[Vector6<f64>]| {
            problem
                .cost(&problem.step(&state, dc, dp).unwrap())
                .unwrap()
        };
        let zero_p = vec![Vector6::zeros(); 2];
        for i in 0..ng {
            // Steps scaled to each parameter's size (focal lengths ~1e3, coefficients ~1e-2).
            let h = 1e-6 * full_param_scale(&problem.t, i);
            let mut dc = DVector::zeros(ng);
            dc[i] = h;
            let plus = cost_at(&dc, &zero_p);
            dc[i] = -h;
            let minus = cost_at(&dc, &zero_p);
            let fd = -(plus - minus) / (4.0 * h);
            let an = normal.g_c[i];
            assert!(
                (fd - an).abs() <= 1e-4 * an.abs().max(1.0),
                "shared {i}: fd {fd} vs analytic {an}"
            );
        }
        for v in 0..2 {
            for i in 0..6 {
                let h = 1e-6;
                let mut dp = zero_p.clone();
                dp[v][i] = h;
                let plus = cost_at(&DVector::zeros(ng), &dp);
                dp[v][i] = -h;
                let minus = cost_at(&DVector::zeros(ng), &dp);
                let fd = -(plus - minus) / (4.0 * h);
                let an = normal.g_p[v][i];
                assert!(
                    (fd - an).abs() <= 1e-4 * an.abs().max(1.0),
                    "view {v} pose {i}: fd {fd} vs analytic {an}"
                );
            }
        }
    }

    /// 1 for translations and distortion, the value's order of magnitude for intrinsics.
    fn full_param_scale(t: &DMatrix<f64>, free: usize) -> f64 {
        // Intrinsics fx fy cx cy of camera (rows 0..4) and projector (FULL..FULL+4): ~1e3.
        let intr = (0..4).chain(FULL..FULL + 4).any(|r| t[(r, free)] != 0.0);
        if intr { 1e3 } else { 1.0 }
    }
}
