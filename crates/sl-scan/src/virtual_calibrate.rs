//! The calibration stage of the virtual rig: the camera, the projector, `T_cam_proj` and the
//! turntable axis, estimated from simulated board captures (`sl_calib::calibrate_procam`,
//! `sl_calib::calibrate_turntable`) and compared with the rig's truth.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use sl_calib::{
    BoardSize, ProcamConfig, ProcamView, StereoCameraConfig, StereoCameraView, TurntableConfig,
    TurntableView, calibrate_procam, calibrate_stereo_cameras, calibrate_turntable,
};
use sl_camera::{BinocularCalibration, Calibration, TurntableAxis};
use sl_codec::{BitDepth, CaptureSet, DecodeConfig, Frames, ImageSize, decode};
use sl_rig::GreyImage;
use sl_sim::{
    CalibrationCaptures, CalibrationSession, SecondCamera, VirtualRig, calibration_sequence,
    capture_board,
};

use crate::{ScanError, ScanProgress, StageTime, VirtualScanConfig};

/// How the calibration was obtained and how far it is from the rig's truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationSummary {
    /// Where each part of the calibration comes from.
    pub sources: Vec<String>,
    /// Board poses used / rendered.
    pub poses_used: usize,
    /// RMS reprojection errors (px): camera alone, projector alone, joint. In a binocular
    /// scan the fields named `projector` are the right camera's, `camera` the left one's,
    /// and the baseline is the cameras'.
    pub rms_camera_px: f64,
    /// See `rms_camera_px`.
    pub rms_projector_px: f64,
    /// See `rms_camera_px`.
    pub rms_stereo_px: f64,
    /// RMS of the turntable-axis fit (px).
    pub rms_turntable_px: f64,
    /// Relative error of the camera's `fx` against the truth (%).
    pub camera_fx_error_percent: f64,
    /// Relative error of the projector's `fx` against the truth (%).
    pub projector_fx_error_percent: f64,
    /// Error of the camera–projector translation (mm).
    pub baseline_error_mm: f64,
    /// Angle between the fitted and the true axis direction (degrees).
    pub axis_direction_error_deg: f64,
    /// Distance of the true axis point to the fitted axis line, near the object (mm).
    pub axis_position_error_mm: f64,
    /// The 3-D error the camera–projector calibration predicts for itself over the volume of
    /// its board poses (`sl_calib::ProcamCalibration::predicted_error`); `None` when not
    /// estimated.
    pub predicted_error: Option<sl_calib::PredictedError>,
    /// The projector's response, when measured ([`VirtualScanConfig::response_correction`]).
    pub response: Option<crate::ResponseSummary>,
}

fn frames_u8(images: Vec<GreyImage>) -> Frames {
    Frames::U8(images.into_iter().map(GreyImage::into_u8).collect())
}

/// Calibrates the rig from simulated board captures: camera, projector and `T_cam_proj` by
/// `sl_calib::calibrate_procam`, the turntable axis by `sl_calib::calibrate_turntable`.
pub fn calibrate_virtual(
    rig: &VirtualRig,
    cfg: &VirtualScanConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<(Calibration, CalibrationSummary), ScanError> {
    let config = rig.config();
    let session = CalibrationSession {
        turntable_angles_deg: cfg.table_angles_deg.clone(),
        ..CalibrationSession::with_poses(cfg.calibration_poses, cfg.seed)
    };
    let board = session.board;
    let captures = CalibrationCaptures::new(rig, &session)?;
    let poses = captures.poses().len();
    let p = ImageSize::new(config.projector.size.width, config.projector.size.height);
    let sequence = calibration_sequence(p);
    let manifest = sequence.manifest(BitDepth::Eight);
    let total = poses + cfg.table_angles_deg.len();
    let mut views = Vec::with_capacity(poses);
    for k in 0..poses {
        let cap = captures.hand_held(k, Some(&sequence))?;
        let set = CaptureSet::from_frames(manifest.clone(), frames_u8(cap.frames))?;
        views.push(ProcamView {
            name: format!("board pose {k}"),
            lit: cap.white.into_u8(),
            map: decode(&set, &DecodeConfig::default())?,
        });
        progress(ScanProgress {
            stage: "calibrate",
            done: k + 1,
            total,
        });
    }
    let size = BoardSize::new(board.inner_cols, board.inner_rows);
    let detector = sl_calib::DetectorConfig::with_refiner(cfg.corners);
    let procam = calibrate_procam(
        &views,
        &ProcamConfig {
            detector,
            ..ProcamConfig::new(size, board.square_mm, config.projector.size)
        },
    )?;
    drop(views);
    let table = calibrate_table(
        &captures,
        &procam.camera.camera,
        &cfg.table_angles_deg,
        &detector,
        (poses, total),
        &mut progress,
    )?;
    let mut calibration = procam.to_calibration();
    calibration.turntable = Some(table.axis);
    calibration.metadata.notes = "estimated by slscan scan from simulated board captures of the virtual rig (sl_calib::calibrate_procam, sl_calib::calibrate_turntable)".to_owned();

    let (direction_error, position_error) = axis_errors(&config.turntable_axis(), &table.axis);
    let rel = |a: f64, b: f64| 100.0 * (a - b) / b;
    let summary = CalibrationSummary {
        sources: vec![
            "camera, projector, T_cam_proj: sl_calib::calibrate_procam on simulated board captures"
                .to_owned(),
            "turntable axis: sl_calib::calibrate_turntable on the board standing on the simulated turntable".to_owned(),
        ],
        poses_used: procam.views.len(),
        rms_camera_px: procam.rms_camera,
        rms_projector_px: procam.rms_projector,
        rms_stereo_px: procam.rms_stereo,
        rms_turntable_px: table.rms,
        camera_fx_error_percent: rel(
            procam.camera.camera.intrinsics.fx,
            config.camera.intrinsics.fx,
        ),
        projector_fx_error_percent: rel(
            procam.projector.camera.intrinsics.fx,
            config.projector.intrinsics.fx,
        ),
        baseline_error_mm: (procam.t_cam_proj.translation.vector
            - config.t_cam_proj.translation.vector)
            .norm(),
        axis_direction_error_deg: direction_error,
        axis_position_error_mm: position_error,
        predicted_error: procam.predicted_error,
        response: None,
    };
    Ok((calibration, summary))
}

/// Stage 1 of a scan on the virtual rig: the calibration estimated from simulated board
/// captures ([`calibrate_virtual`]), or the rig's truth with `cfg.true_calibration`, with the
/// projector's `response` when measured, saved as `calibration.json` in `out` (its path
/// returned) and timed into `stages`.
pub(crate) fn calibrate_virtual_stage(
    rig: &VirtualRig,
    cfg: &VirtualScanConfig,
    out: &Path,
    stages: &mut Vec<StageTime>,
    progress: impl FnMut(ScanProgress<'_>),
    response: Option<(sl_codec::ToneCurve, crate::ResponseSummary)>,
) -> Result<(Calibration, CalibrationSummary, PathBuf), ScanError> {
    let t = Instant::now();
    let (mut calibration, mut summary) = if cfg.true_calibration {
        true_calibration(rig)
    } else {
        calibrate_virtual(rig, cfg, progress)?
    };
    if let Some((curve, figures)) = response {
        calibration.projector_response = Some(curve);
        summary.response = Some(figures);
    }
    let calib_path = out.join("calibration.json");
    calibration.save(&calib_path)?;
    stages.push(StageTime::since("calibrate", t));
    Ok((calibration, summary, calib_path))
}

/// The rig's exact calibration, as [`calibrate_virtual`] would return it (diagnostic runs).
pub(crate) fn true_calibration(rig: &VirtualRig) -> (Calibration, CalibrationSummary) {
    let summary = CalibrationSummary {
        sources: vec!["the rig's true calibration (diagnostic run, nothing estimated)".to_owned()],
        poses_used: 0,
        rms_camera_px: 0.0,
        rms_projector_px: 0.0,
        rms_stereo_px: 0.0,
        rms_turntable_px: 0.0,
        camera_fx_error_percent: 0.0,
        projector_fx_error_percent: 0.0,
        baseline_error_mm: 0.0,
        axis_direction_error_deg: 0.0,
        axis_position_error_mm: 0.0,
        predicted_error: None,
        response: None,
    };
    (rig.config().calibration(), summary)
}

/// The two-camera calibration of a binocular scan on the virtual rig: both cameras, their
/// relative pose and the turntable axis estimated from simulated board captures
/// ([`calibrate_virtual_binocular`]), or the rig's truth with `cfg.true_calibration`; saved
/// as `calibration.json` (a two-camera file, `"kind": "binocular"`) in `out`.
pub(crate) fn calibrate_virtual_binocular_stage(
    left: &VirtualRig,
    right: &VirtualRig,
    second: &SecondCamera,
    cfg: &VirtualScanConfig,
    out: &Path,
    stages: &mut Vec<StageTime>,
    progress: impl FnMut(ScanProgress<'_>),
) -> Result<(BinocularCalibration, CalibrationSummary, PathBuf), ScanError> {
    let t = Instant::now();
    let (pair, summary) = if cfg.true_calibration {
        let (_, summary) = true_calibration(left);
        (left.config().binocular_calibration(), summary)
    } else {
        calibrate_virtual_binocular(left, right, second, cfg, progress)?
    };
    let calib_path = out.join("calibration.json");
    pair.save(&calib_path)?;
    stages.push(StageTime::since("calibrate", t));
    Ok((pair, summary, calib_path))
}

/// Calibrates the two cameras of a binocular virtual rig and its turntable from simulated board
/// captures: the hand-held board of [`calibrate_virtual`]'s session seen by both cameras
/// (`second` is where the right camera stands), each camera's model and the cameras' relative
/// pose from the views whose board both cameras found, then the turntable axis from the board
/// on the turntable seen by the left camera. The projector is not calibrated: a binocular scan
/// does not use it.
///
/// # Errors
/// Those of the renderer and of the calibrations (too few views with the board in both
/// cameras, named with the views left out).
pub fn calibrate_virtual_binocular(
    left: &VirtualRig,
    right: &VirtualRig,
    second: &SecondCamera,
    cfg: &VirtualScanConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<(BinocularCalibration, CalibrationSummary), ScanError> {
    let config = left.config();
    let session = CalibrationSession {
        turntable_angles_deg: cfg.table_angles_deg.clone(),
        ..CalibrationSession::with_poses(cfg.calibration_poses, cfg.seed)
    };
    let board = session.board;
    let captures = CalibrationCaptures::new(left, &session)?;
    let poses = captures.poses().len();
    let total = poses + cfg.table_angles_deg.len();
    let t_second_cam = second.t_cam_second.inverse();
    let mut views = Vec::with_capacity(poses);
    for (k, pose) in captures.poses().iter().enumerate() {
        let lit = captures.hand_held(k, None)?.white.into_u8();
        let seen = capture_board(right, &board, &(t_second_cam * pose), None, k as u64)?;
        views.push(StereoCameraView {
            name: format!("board pose {k}"),
            left: lit,
            right: seen.white.into_u8(),
        });
        progress(ScanProgress {
            stage: "calibrate",
            done: k + 1,
            total,
        });
    }
    let size = BoardSize::new(board.inner_cols, board.inner_rows);
    let detector = sl_calib::DetectorConfig::with_refiner(cfg.corners);
    let stereo = calibrate_stereo_cameras(
        &views,
        &StereoCameraConfig {
            detector,
            ..StereoCameraConfig::new(size, board.square_mm)
        },
    )?;
    drop(views);
    let left_model = stereo.left.camera;
    let table = calibrate_table(
        &captures,
        &left_model,
        &cfg.table_angles_deg,
        &detector,
        (poses, total),
        &mut progress,
    )?;
    let mut pair = stereo.to_binocular();
    pair.turntable = Some(table.axis);
    pair.metadata.notes = "estimated by slscan scan --binocular from simulated board captures of the virtual rig's two cameras (sl_calib::calibrate_stereo_cameras, sl_calib::calibrate_turntable)".to_owned();

    let (direction_error, position_error) = axis_errors(&config.turntable_axis(), &table.axis);
    let rel = |a: f64, b: f64| 100.0 * (a - b) / b;
    let summary = CalibrationSummary {
        sources: vec![
            "left and right cameras, T_left_right: sl_calib::calibrate_stereo_cameras on simulated board captures"
                .to_owned(),
            "turntable axis: sl_calib::calibrate_turntable on the board standing on the simulated turntable, seen by the left camera".to_owned(),
        ],
        poses_used: stereo.views.len(),
        rms_camera_px: stereo.rms_left,
        rms_projector_px: stereo.rms_right,
        rms_stereo_px: stereo.rms_stereo,
        rms_turntable_px: table.rms,
        camera_fx_error_percent: rel(left_model.intrinsics.fx, config.camera.intrinsics.fx),
        projector_fx_error_percent: rel(
            stereo.right.camera.intrinsics.fx,
            second.camera.intrinsics.fx,
        ),
        baseline_error_mm: (pair.t_left_right.translation.vector
            - second.t_cam_second.translation.vector)
            .norm(),
        axis_direction_error_deg: direction_error,
        axis_position_error_mm: position_error,
        predicted_error: None,
        response: None,
    };
    Ok((pair, summary))
}

/// The turntable axis from the board standing on the platter at `angles` (the session's
/// captures, seen by `camera`), reporting progress after the `done_total.0` hand-held poses of
/// `done_total.1` captures.
fn calibrate_table(
    captures: &CalibrationCaptures<'_>,
    camera: &sl_camera::CameraModel,
    angles: &[f64],
    detector: &sl_calib::DetectorConfig,
    (done, total): (usize, usize),
    progress: &mut impl FnMut(ScanProgress<'_>),
) -> Result<sl_calib::TurntableCalibration, ScanError> {
    let board = captures.session().board;
    let size = BoardSize::new(board.inner_cols, board.inner_rows);
    let mut views = Vec::with_capacity(angles.len());
    for (k, &angle) in angles.iter().enumerate() {
        let cap = captures.on_table(k, None)?;
        let label = format!("board on the turntable at {angle} degrees");
        views.push(TurntableView::detect(
            &cap.white.into_u8(),
            &label,
            angle,
            size,
            board.square_mm,
            detector,
        )?);
        progress(ScanProgress {
            stage: "calibrate",
            done: done + k + 1,
            total,
        });
    }
    Ok(calibrate_turntable(
        camera,
        &views,
        &TurntableConfig::default(),
    )?)
}

/// The angle (degrees) between the fitted and the true axis directions, and the distance (mm)
/// from the true axis point (on the table, under the object) to the fitted line.
fn axis_errors(truth: &TurntableAxis, fitted: &TurntableAxis) -> (f64, f64) {
    let d_est = fitted.direction.normalize();
    let d_true = truth.direction.normalize();
    let direction = d_est
        .dot(&d_true)
        .abs()
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let off = truth.point_mm - fitted.point_mm;
    (direction, (off - d_est * off.dot(&d_est)).norm())
}
