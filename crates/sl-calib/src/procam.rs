//! Projector–camera calibration (Moreno & Taubin 2012): board corners detected in the camera,
//! mapped into the projector by local homographies of the decoded patterns, each device
//! calibrated by Zhang's method, then everything refined jointly.

use nalgebra::{Isometry3, Point2, Point3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sl_camera::{Calibration, ImageSize, RmsErrors};
use sl_codec::{CorrespondenceMap, Frame};

use crate::predicted::PredictedError;
use crate::stereo::{
    StereoOptions, StereoStart, StereoView, joint_calibrations, mean_relative_pose, refine_stereo,
};
use crate::zhang::calibrate_camera_subsets;
use crate::{
    BoardCorners, BoardSize, CalibError, CalibrationView, CameraCalibration, DetectorConfig,
    LocalHomographyConfig, ProjectorCorners, ZhangConfig, calibrate_camera, detect_checkerboard,
    projector_corners,
};

/// One board pose of a projector–camera calibration.
#[derive(Debug, Clone)]
pub struct ProcamView {
    /// Name used in messages and reports (e.g. the capture folder).
    pub name: String,
    /// The board under full white projector light (for corner detection).
    pub lit: Frame<u8>,
    /// The decoded pattern sequence: projector column and row per camera pixel, both axes
    /// coded (same size as `lit`).
    pub map: CorrespondenceMap,
}

/// Options of [`calibrate_procam`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProcamConfig {
    /// Inner corners of the board.
    pub board: BoardSize,
    /// Side of a square (mm): the unit of the poses and of `T_cam_proj`.
    pub square_mm: f64,
    /// The projector's image size (px).
    pub projector_size: ImageSize,
    /// Checkerboard detection in the lit images.
    pub detector: DetectorConfig,
    /// Mapping of the corners into the projector.
    pub homography: LocalHomographyConfig,
    /// The camera's model and fixed parameters.
    pub camera: ZhangConfig,
    /// The projector's model and fixed parameters.
    pub projector: ZhangConfig,
    /// Views with fewer corners mapped into the projector are left out of the projector's
    /// own calibration (they still count in the joint refinement).
    pub min_projector_corners: usize,
    /// `true`: a view whose board is not found is left out and listed in
    /// [`ProcamCalibration::skipped_views`]; `false`: it is an error.
    pub skip_unusable_views: bool,
    /// Largest number of Levenberg–Marquardt iterations of the joint refinement.
    pub max_iterations: usize,
    /// Relative decrease of the squared error below which the joint refinement stops.
    pub tolerance: f64,
}

impl ProcamConfig {
    /// The defaults for a board of `board` inner corners with squares of `square_mm`, and a
    /// projector of `projector_size`.
    pub fn new(board: BoardSize, square_mm: f64, projector_size: ImageSize) -> Self {
        Self {
            board,
            square_mm,
            projector_size,
            ..Self::default()
        }
    }
}

/// Corners a view needs in the projector to enter the projector's own Zhang calibration: a
/// homography needs 4, and a few more keep one badly covered view from steering the start.
const MIN_PROJECTOR_CORNERS: usize = 8;

impl Default for ProcamConfig {
    /// `sl-sim`'s default board (9×6 inner corners, 20 mm squares) and projector
    /// (1920×1080), OpenCV's default models for both devices, views without a board skipped.
    fn default() -> Self {
        Self {
            board: BoardSize::new(9, 6),
            square_mm: 20.0,
            projector_size: ImageSize::new(1920, 1080),
            detector: DetectorConfig::default(),
            homography: LocalHomographyConfig::default(),
            camera: ZhangConfig::default(),
            projector: ZhangConfig::default(),
            min_projector_corners: MIN_PROJECTOR_CORNERS,
            skip_unusable_views: true,
            max_iterations: 100,
            tolerance: 1e-15,
        }
    }
}

/// A view left out of the calibration, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedView {
    /// The view's name.
    pub name: String,
    /// Why it was left out.
    pub reason: String,
}

/// What became of one used view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProcamViewReport {
    /// The view's name.
    pub name: String,
    /// Camera corners (px), board order.
    pub camera_corners: Vec<Point2<f64>>,
    /// The corners mapped into the projector, with the corners skipped and why.
    pub projector_corners: ProjectorCorners,
    /// Whether the view entered the projector's own Zhang calibration.
    pub in_projector_calibration: bool,
    /// RMS camera residual of the joint solution in this view (px).
    pub camera_rms: f64,
    /// RMS projector residual of the joint solution in this view (projector px; 0 when no
    /// corner was mapped).
    pub projector_rms: f64,
}

/// The result of [`calibrate_procam`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProcamCalibration {
    /// The camera after the joint refinement: model, `T_cam_board` per used view, its RMS,
    /// per-view RMS and residuals in the joint solution, and standard deviations.
    pub camera: CameraCalibration,
    /// The projector after the joint refinement: model, `T_proj_board = T_proj_cam ·
    /// T_cam_board` per used view, RMS and residuals in the joint solution (corners not
    /// mapped are left out of `residuals`), standard deviations of intrinsics and distortion
    /// (`std_dev.poses` is empty: the projector's poses are not free parameters).
    pub projector: CameraCalibration,
    /// Pose of the projector in the camera frame: `p_cam = T_cam_proj · p_proj` (mm).
    pub t_cam_proj: Isometry3<f64>,
    /// Standard deviations of `T_proj_cam = T_cam_proj⁻¹` as estimated: rvec (rad), tvec
    /// (mm).
    pub t_proj_cam_std_dev: [f64; 6],
    /// RMS of the camera calibrated alone (Zhang, OpenCV's `calibrateCamera` definition).
    pub rms_camera: f64,
    /// RMS of the projector calibrated alone on the mapped corners (projector px).
    pub rms_projector: f64,
    /// RMS of the joint refinement over the camera and projector residuals together
    /// (OpenCV's `stereoCalibrate` definition: `sqrt(Σ|r|² / observations)`).
    pub rms_stereo: f64,
    /// The used views, in the order of `camera.poses`.
    pub views: Vec<ProcamViewReport>,
    /// The views left out, with the reason.
    pub skipped_views: Vec<SkippedView>,
    /// Levenberg–Marquardt iterations of the joint refinement.
    pub iterations: usize,
    /// The 3-D error the calibration predicts for itself over the volume of its board poses
    /// (its parameters' covariance carried through triangulation); `None` when the joint
    /// refinement's normal equations are singular.
    pub predicted_error: Option<PredictedError>,
}

impl ProcamCalibration {
    /// The calibration file's content: both models, `T_cam_proj` and the three RMS errors.
    pub fn to_calibration(&self) -> Calibration {
        let mut c = Calibration::new(self.camera.camera);
        c.projector = Some(self.projector.camera);
        c.t_cam_proj = Some(self.t_cam_proj);
        c.rms = RmsErrors {
            camera: Some(self.rms_camera),
            projector: Some(self.rms_projector),
            stereo: Some(self.rms_stereo),
        };
        c
    }

    /// Number of board corners mapped into the projector over the used views.
    pub fn projector_corner_count(&self) -> usize {
        self.views
            .iter()
            .map(|v| v.projector_corners.mapped_count())
            .sum()
    }
}

/// Views fewer than this leave Zhang's method underdetermined.
const MIN_VIEWS: usize = 3;

fn validate(views: &[ProcamView], cfg: &ProcamConfig) -> Result<(), CalibError> {
    if !(cfg.square_mm.is_finite() && cfg.square_mm > 0.0) {
        return Err(CalibError::param(
            "square_mm",
            format!("{} is not a positive length", cfg.square_mm),
        ));
    }
    cfg.projector_size
        .validate()
        .map_err(sl_camera::CameraError::from)?;
    if cfg.min_projector_corners < 4 {
        return Err(CalibError::param(
            "min_projector_corners",
            format!(
                "{}: a view needs at least 4 corners in the projector for a homography",
                cfg.min_projector_corners
            ),
        ));
    }
    let first = views.first().map(|v| (v.lit.width(), v.lit.height()));
    for v in views {
        let (w, h) = (v.lit.width(), v.lit.height());
        if let Some((fw, fh)) = first
            && (w, h) != (fw, fh)
        {
            return Err(CalibError::Frame {
                frame: v.name.clone(),
                reason: format!(
                    "the lit image is {w}x{h} but the first view's is {fw}x{fh}: one camera, one image size"
                ),
            });
        }
        if v.map.width != w || v.map.height != h {
            return Err(CalibError::Frame {
                frame: v.name.clone(),
                reason: format!(
                    "the decoded map is {}x{} but the lit image is {w}x{h}",
                    v.map.width, v.map.height
                ),
            });
        }
    }
    Ok(())
}

fn too_few_views(used: usize, skipped: &[SkippedView], what: &str) -> CalibError {
    let mut msg = format!(
        "{used} usable view(s) for the {what}: capture at least {MIN_VIEWS} board poses (10–20 is better), tilted by 10–40° in different directions, the whole board lit by the projector"
    );
    for s in skipped {
        msg.push_str(&format!("; {} left out: {}", s.name, s.reason));
    }
    CalibError::Degenerate(msg)
}

/// Calibrates a camera and a projector from board views (Moreno & Taubin 2012): detects the
/// board in each lit image, maps its corners into the projector by local homographies of the
/// decoded patterns ([`projector_corners`]), calibrates each device by Zhang's method, then
/// refines both models, every board pose and `T_cam_proj` jointly by Levenberg–Marquardt
/// (as `cv::stereoCalibrate` without fixed intrinsics).
///
/// # Errors
/// [`CalibError::Degenerate`] with fewer than 3 usable views (listing the views left out and
/// why) or boards that do not determine the intrinsics (all parallel), saying what to capture
/// instead; [`CalibError::BoardNotFound`] naming the view when `skip_unusable_views` is off;
/// [`CalibError::SparseCorner`] when `homography.skip_sparse` is off; [`CalibError::Frame`]
/// when a view's map and image sizes differ or views differ in size;
/// [`CalibError::InvalidParameter`] for bad options.
///
/// See `tests/it/procam.rs` for a run on the virtual rig's renders.
pub fn calibrate_procam(
    views: &[ProcamView],
    cfg: &ProcamConfig,
) -> Result<ProcamCalibration, CalibError> {
    validate(views, cfg)?;
    let mut skipped_views = Vec::new();
    let mut found = Vec::new();
    // Views are independent: detect and map them in parallel, then keep the input order.
    let detected: Vec<_> = views
        .par_iter()
        .map(|v| {
            detect_checkerboard(&v.lit, cfg.board, &cfg.detector, &v.name).map(|b| {
                let p = projector_corners(&b, &v.map, &cfg.homography, &v.name);
                (b, p)
            })
        })
        .collect();
    for (v, d) in views.iter().zip(detected) {
        match d {
            Ok((camera, projector)) => found.push(Found {
                name: v.name.clone(),
                camera,
                projector: projector?,
            }),
            Err(e) if cfg.skip_unusable_views => skipped_views.push(SkippedView {
                name: v.name.clone(),
                reason: e.to_string(),
            }),
            Err(e) => return Err(e),
        }
    }
    let camera_size = match views.first() {
        Some(v) => lit_size(v)?,
        None => ImageSize::new(0, 0),
    };
    calibrate_from_corners(found, camera_size, cfg, skipped_views)
}

/// The size of a view's lit image as the camera models' [`ImageSize`].
///
/// # Errors
/// [`CalibError::Frame`] naming the view if a side does not fit the models' `u32`.
fn lit_size(v: &ProcamView) -> Result<ImageSize, CalibError> {
    let (w, h) = (v.lit.width(), v.lit.height());
    match (u32::try_from(w), u32::try_from(h)) {
        (Ok(w), Ok(h)) => Ok(ImageSize::new(w, h)),
        _ => Err(CalibError::Frame {
            frame: v.name.clone(),
            reason: format!("the lit image is {w}x{h}: a camera image side must fit in u32"),
        }),
    }
}

/// One view whose board was found: its corners in the camera and in the projector.
struct Found {
    name: String,
    camera: BoardCorners,
    projector: ProjectorCorners,
}

/// The calibration once the corners are known.
fn calibrate_from_corners(
    found: Vec<Found>,
    camera_size: ImageSize,
    cfg: &ProcamConfig,
    skipped_views: Vec<SkippedView>,
) -> Result<ProcamCalibration, CalibError> {
    if found.len() < MIN_VIEWS {
        return Err(too_few_views(found.len(), &skipped_views, "camera"));
    }
    let object = cfg.board.object_points(cfg.square_mm);
    // The camera alone.
    let camera_views: Vec<CalibrationView> = found
        .iter()
        .map(|f| CalibrationView::from_corners(&f.camera, cfg.square_mm))
        .collect();
    let camera_alone = calibrate_camera(&camera_views, camera_size, &cfg.camera)?;
    // The projector alone, on the views with enough mapped corners.
    let mut projector_views = Vec::new();
    let mut projector_index = Vec::new();
    for (k, f) in found.iter().enumerate() {
        let p = &f.projector;
        if p.mapped_count() < cfg.min_projector_corners {
            continue;
        }
        let (obj, img): (Vec<_>, Vec<_>) = object
            .iter()
            .zip(&p.fits)
            .filter_map(|(o, f)| f.map(|f| (*o, f.projector)))
            .unzip();
        projector_views.push(CalibrationView {
            object_points: obj,
            image_points: img,
        });
        projector_index.push(k);
    }
    if projector_views.len() < MIN_VIEWS {
        let mut why = skipped_views.clone();
        for f in &found {
            let p = &f.projector;
            if p.mapped_count() < cfg.min_projector_corners {
                why.push(SkippedView {
                    name: f.name.clone(),
                    reason: format!(
                        "{} of {} corners mapped into the projector, {} needed",
                        p.mapped_count(),
                        p.fits.len(),
                        cfg.min_projector_corners
                    ),
                });
            }
        }
        return Err(too_few_views(projector_views.len(), &why, "projector"));
    }
    let projector_alone =
        calibrate_camera_subsets(&projector_views, cfg.projector_size, &cfg.projector)?;
    // T_proj_cam from every view seen by both: the chordal mean of the rotations.
    let start_extrinsics = mean_relative_pose(
        projector_alone
            .poses
            .iter()
            .zip(&projector_index)
            .filter_map(|(pose_p, &k)| {
                let pose_c = camera_alone.poses.get(k)?;
                Some(pose_p.to_isometry() * pose_c.to_isometry().inverse())
            }),
        "camera-to-projector",
    )?;
    // Joint refinement.
    let projector_points: Vec<Vec<Option<Point2<f64>>>> =
        found.iter().map(|f| f.projector.points()).collect();
    let stereo_views: Vec<StereoView<'_>> = found
        .iter()
        .zip(&projector_points)
        .map(|(f, pp)| StereoView {
            object: &object,
            camera: &f.camera.corners,
            projector: pp,
        })
        .collect();
    let start = StereoStart {
        camera: camera_alone.camera,
        projector: projector_alone.camera,
        extrinsics: start_extrinsics,
        poses: camera_alone.poses.clone(),
    };
    let sol = refine_stereo(
        &stereo_views,
        &start,
        &StereoOptions {
            camera: &cfg.camera,
            projector: &cfg.projector,
            max_iterations: cfg.max_iterations,
            tolerance: cfg.tolerance,
        },
    )?;
    let (camera, projector, rms_stereo) = joint_calibrations(&sol);
    let t_proj_cam = sol.extrinsics.to_isometry();
    let views_report = found
        .into_iter()
        .enumerate()
        .map(|(k, f)| ProcamViewReport {
            name: f.name,
            camera_corners: f.camera.corners,
            projector_corners: f.projector,
            in_projector_calibration: projector_index.contains(&k),
            camera_rms: camera.view_rms.get(k).copied().unwrap_or(0.0),
            projector_rms: projector.view_rms.get(k).copied().unwrap_or(0.0),
        })
        .collect();
    // The calibrated volume: every used view's board corners, where the poses put them.
    let volume: Vec<Point3<f64>> = sol
        .poses
        .iter()
        .flat_map(|p| {
            let pose = p.to_isometry();
            object.iter().map(move |x| pose * x)
        })
        .collect();
    let predicted_error = sol.covariance.as_ref().and_then(|cov| {
        crate::predicted::predict(&sol.camera, &sol.projector, &sol.extrinsics, cov, &volume)
    });
    Ok(ProcamCalibration {
        predicted_error,
        camera,
        projector,
        t_cam_proj: t_proj_cam.inverse(),
        t_proj_cam_std_dev: sol.extrinsics_std,
        rms_camera: camera_alone.rms,
        rms_projector: projector_alone.rms,
        rms_stereo,
        views: views_report,
        skipped_views,
        iterations: sol.iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CornerFit;
    use nalgebra::Vector3;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use sl_camera::{CameraModel, Distortion, Intrinsics};

    struct Truth {
        camera: CameraModel,
        projector: CameraModel,
        t_cam_proj: Isometry3<f64>,
    }

    fn truth() -> Truth {
        Truth {
            camera: CameraModel::new(
                Intrinsics::new(1440.0, 1442.0, 641.0, 358.0),
                Distortion::from_opencv(&[-0.08, 0.12, 0.0004, -0.0003, 0.0]).unwrap(),
                ImageSize::new(1280, 720),
            )
            .unwrap(),
            projector: CameraModel::new(
                Intrinsics::new(2200.0, 2195.0, 955.0, 545.0),
                Distortion::from_opencv(&[0.04, -0.05, 0.0, 0.0, 0.0]).unwrap(),
                ImageSize::new(1920, 1080),
            )
            .unwrap(),
            // Projector 200 mm to the right, toed in by 24° about y.
            t_cam_proj: Isometry3::new(
                Vector3::new(200.0, 3.0, 10.0),
                Vector3::new(0.02, -0.42, 0.01),
            ),
        }
    }

    /// Exact (or noisy, `sigma` px per axis) corners of six board poses; corner `k` of view 1
    /// for `k` in `unmapped` is left out of the projector.
    fn corners(t: &Truth, sigma: f64, unmapped: &[usize]) -> Vec<Found> {
        let size = BoardSize::new(9, 6);
        let object = size.object_points(20.0);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        let n = Normal::new(0.0, 1.0).unwrap();
        let mut noisy = |q: Point2<f64>| {
            Point2::new(
                q.x + sigma * n.sample(&mut rng),
                q.y + sigma * n.sample(&mut rng),
            )
        };
        [
            (0.3, -0.2, 0.1),
            (-0.25, 0.15, -0.2),
            (0.1, 0.4, 0.3),
            (-0.3, -0.3, 0.0),
            (0.35, 0.2, -0.1),
            (0.0, -0.35, 0.2),
        ]
        .iter()
        .enumerate()
        .map(|(k, &(a, b, c))| {
            let pose = Isometry3::new(
                Vector3::new(-80.0 + 10.0 * k as f64, -50.0, 430.0 + 15.0 * k as f64),
                Vector3::new(a, b, c),
            );
            let cam: Vec<Point2<f64>> = object
                .iter()
                .map(|p| noisy(t.camera.project(&(pose * p)).unwrap()))
                .collect();
            let fits = object
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    if k == 1 && unmapped.contains(&i) {
                        return None;
                    }
                    let q = t
                        .projector
                        .project(&t.t_cam_proj.inverse_transform_point(&(pose * p)))
                        .unwrap();
                    Some(CornerFit {
                        projector: noisy(q),
                        decoded: 1000,
                        inliers: 1000,
                        rms: 0.0,
                    })
                })
                .collect();
            Found {
                name: format!("view {k}"),
                camera: BoardCorners { size, corners: cam },
                projector: ProjectorCorners {
                    frame: format!("view {k}"),
                    fits,
                    skipped: Vec::new(),
                },
            }
        })
        .collect()
    }

    fn config() -> ProcamConfig {
        ProcamConfig::new(BoardSize::new(9, 6), 20.0, ImageSize::new(1920, 1080))
    }

    #[test]
    fn exact_corners_recover_both_devices_and_the_extrinsics() {
        let t = truth();
        let found = corners(&t, 0.0, &[0, 1, 2, 20, 53]);
        let c = calibrate_from_corners(found, t.camera.size, &config(), Vec::new()).unwrap();
        // Noise-free: the minimum is the truth, up to the LM tolerance.
        for (e, tr) in [
            (&c.camera.camera, &t.camera),
            (&c.projector.camera, &t.projector),
        ] {
            let (e, tr) = (e.intrinsics, tr.intrinsics);
            assert!(
                (e.fx / tr.fx - 1.0).abs() < 1e-8,
                "fx {} vs {}",
                e.fx,
                tr.fx
            );
            assert!(
                (e.fy / tr.fy - 1.0).abs() < 1e-8,
                "fy {} vs {}",
                e.fy,
                tr.fy
            );
            assert!((e.cx - tr.cx).abs() < 1e-5 && (e.cy - tr.cy).abs() < 1e-5);
        }
        let k1 = c.projector.camera.distortion.k1();
        assert!((k1 - 0.04).abs() < 1e-7, "projector k1 {k1}");
        let dt = (c.t_cam_proj.translation.vector - t.t_cam_proj.translation.vector).norm();
        assert!(dt < 1e-6, "translation error {dt} mm");
        assert!(c.t_cam_proj.rotation.angle_to(&t.t_cam_proj.rotation) < 1e-9);
        assert!(c.rms_camera < 1e-6 && c.rms_projector < 1e-6 && c.rms_stereo < 1e-6);
        // The five unmapped corners are left out of the projector's residuals only.
        assert_eq!(c.projector.residuals[1].len(), 54 - 5);
        assert_eq!(c.camera.residuals[1].len(), 54);
        assert_eq!(c.projector_corner_count(), 6 * 54 - 5);
        let file = c.to_calibration();
        assert_eq!(file.rms.projector, Some(c.rms_projector));
        assert_eq!(file.t_cam_proj, Some(c.t_cam_proj));
    }

    #[test]
    fn noisy_corners_give_consistent_standard_deviations() {
        let t = truth();
        let sigma = 0.05;
        let c = calibrate_from_corners(
            corners(&t, sigma, &[]),
            t.camera.size,
            &config(),
            Vec::new(),
        )
        .unwrap();
        // RMS of 2-D residuals with σ per axis: ≈ σ√2 less the fitted degrees of freedom.
        assert!(
            c.rms_stereo > 0.8 * sigma && c.rms_stereo < 1.5 * sigma,
            "{}",
            c.rms_stereo
        );
        // The truth within 4 reported standard deviations (a 1-in-15 000 miss per check
        // for a correct σ; a wrong Jacobian or scale of σ shows up as a gross miss).
        let within = |e: f64, tr: f64, sd: f64, what: &str| {
            assert!(sd > 0.0, "{what}: σ = 0");
            assert!((e - tr).abs() < 4.0 * sd, "{what}: {e} vs {tr}, σ {sd}");
        };
        let ci = c.camera.camera.intrinsics;
        let pi = c.projector.camera.intrinsics;
        within(ci.fx, 1440.0, c.camera.std_dev.intrinsics[0], "camera fx");
        within(
            pi.fx,
            2200.0,
            c.projector.std_dev.intrinsics[0],
            "projector fx",
        );
        within(
            pi.cy,
            545.0,
            c.projector.std_dev.intrinsics[3],
            "projector cy",
        );
        let t_proj_cam = c.t_cam_proj.inverse();
        let truth_proj_cam = t.t_cam_proj.inverse();
        for i in 0..3 {
            within(
                t_proj_cam.translation.vector[i],
                truth_proj_cam.translation.vector[i],
                c.t_proj_cam_std_dev[3 + i],
                "T_proj_cam tvec",
            );
        }
    }

    #[test]
    fn malformed_views_are_named() {
        let view = |name: &str, w: usize, mw: usize| ProcamView {
            name: name.to_owned(),
            lit: Frame::filled(w, 10, 0).unwrap(),
            map: CorrespondenceMap::new(mw, 10),
        };
        let err = calibrate_procam(
            &[view("a", 20, 20), view("b", 30, 30), view("c", 20, 20)],
            &config(),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("b:") && err.contains("30x10"), "{err}");
        let err = calibrate_procam(&[view("a", 20, 20), view("b", 20, 21)], &config())
            .unwrap_err()
            .to_string();
        assert!(err.contains("b:") && err.contains("21x10"), "{err}");
        // Blank images: no board anywhere, every view named with the detector's reason.
        let err = calibrate_procam(
            &[view("a", 20, 20), view("b", 20, 20), view("c", 20, 20)],
            &config(),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("0 usable view(s)"), "{err}");
        assert!(
            err.contains("a left out") && err.contains("c left out"),
            "{err}"
        );
    }

    #[test]
    fn too_few_projector_views_are_named() {
        let t = truth();
        let mut found = corners(&t, 0.0, &[]);
        found.truncate(3);
        if let Some(f) = found.get_mut(2) {
            for fit in f.projector.fits.iter_mut().skip(5) {
                *fit = None;
            }
        }
        let err = calibrate_from_corners(found, t.camera.size, &config(), Vec::new())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("view 2") && err.contains("5 of 54 corners"),
            "{err}"
        );
        assert!(err.contains("at least 3"), "{err}");
    }
}
