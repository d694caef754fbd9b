//! The two cameras of a binocular rig calibrated from a session folder (what `slscan
//! calibrate stereo` runs): each board pose folder holds the left camera's `white.png` and, in
//! its `right/` folder, the right camera's picture of the same board; optionally the projector
//! on top (from the left camera's pattern captures) and the turntable axis (from
//! `SESSION/turntable/`, seen by the left camera). Writes `stereo.json` (the two-camera file)
//! and `report.json`.

use std::path::{Path, PathBuf};

use serde_json::json;
use sl_calib::{
    StereoCameraCalibration, StereoCameraConfig, StereoCameraView, TurntableConfig,
    calibrate_stereo_cameras, load_grey,
};
use sl_camera::{BinocularCalibration, Calibration};
use sl_rig::RIGHT_DIR;

use crate::error::ScanError;
use crate::run_report::RunReport;
use crate::session_calibration::{intrinsics_figure, pose_folders, white_image};
use crate::{
    CalibrationFilesConfig, ProcamFiles, ScanProgress, TurntableFiles, calibrate_procam_files,
    calibrate_turntable_files, default_turntable_dir, session_poses, session_projector_size,
    turntable_views,
};

/// Name of the two-camera calibration file `calibrate_stereo_files` writes.
pub const STEREO_FILE: &str = "stereo.json";

/// What [`calibrate_stereo_files`] calibrated (its files are in its output folder).
#[derive(Debug, Clone)]
pub struct StereoFiles {
    /// The two-camera calibration written to `stereo.json` (with the projector and the
    /// turntable axis when they were calibrated too).
    pub pair: BinocularCalibration,
    /// The two cameras' joint calibration with its per-view figures and skipped views.
    pub stereo: StereoCameraCalibration,
    /// The projector's step (in `out/projector`), when asked for.
    pub projector: Option<ProcamFiles>,
    /// The turntable's step (in `out/turntable`), when the session has a turntable folder.
    pub turntable: Option<TurntableFiles>,
    /// How many board poses were read.
    pub poses: usize,
}

/// Calibrates the two cameras of the session `session` into `out` (see the module docs);
/// `projector` also calibrates the projector from the left camera's pattern captures
/// (`calibrate_procam_files`, into `out/projector`), whose pose in the left camera's frame
/// the two-camera file then holds.
///
/// # Errors
/// [`ScanError::Session`] naming the pose folder without a left or a right board picture;
/// the pictures' and each step's errors ([`ScanError::Step`] naming the step).
pub fn calibrate_stereo_files(
    session: &Path,
    cfg: &CalibrationFilesConfig,
    projector: bool,
    out: &Path,
    command: &str,
    progress: &mut dyn FnMut(ScanProgress<'_>),
) -> Result<StereoFiles, ScanError> {
    let mut report = RunReport::new(command);
    std::fs::create_dir_all(out).map_err(crate::error::io(out))?;
    let folders = pose_folders(session)?;
    let pictures: Vec<(PathBuf, PathBuf)> = folders
        .iter()
        .map(|folder| {
            let missing = |what: &str, dir: &Path| ScanError::Session {
                path: dir.to_path_buf(),
                reason: format!(
                    "no {what} board picture (white.png): a pose of a two-camera session holds the left camera's in the pose folder and the right camera's in its {RIGHT_DIR}/ folder"
                ),
            };
            let left = white_image(folder).ok_or_else(|| missing("left camera's", folder))?;
            let right_dir = folder.join(RIGHT_DIR);
            let right =
                white_image(&right_dir).ok_or_else(|| missing("right camera's", &right_dir))?;
            Ok((left, right))
        })
        .collect::<Result<_, ScanError>>()?;
    let total = pictures.len();
    let views = report.stage("read", || -> Result<Vec<StereoCameraView>, ScanError> {
        let mut views = Vec::with_capacity(total);
        for (k, (folder, (left, right))) in folders.iter().zip(&pictures).enumerate() {
            views.push(StereoCameraView {
                name: folder.display().to_string(),
                left: load_grey(left)?,
                right: load_grey(right)?,
            });
            progress(ScanProgress {
                stage: "read",
                done: k + 1,
                total,
            });
        }
        Ok(views)
    })?;
    let scfg = StereoCameraConfig {
        detector: cfg.detector(),
        ..StereoCameraConfig::new(cfg.board, cfg.square_mm)
    };
    let stereo = report
        .stage("calibrate", || calibrate_stereo_cameras(&views, &scfg))
        .map_err(|e| ScanError::Step {
            what: format!("two-camera calibration from {total} board poses"),
            source: Box::new(e.into()),
        })?;
    drop(views);
    let mut pair = stereo.to_binocular();
    pair.metadata.notes = format!(
        "slscan calibrate stereo: {} of {total} poses of a {}x{} board of {} mm squares",
        stereo.views.len(),
        cfg.board.cols,
        cfg.board.rows,
        cfg.square_mm
    );
    // The projector on top, from the left camera's pattern captures.
    let projector = if projector {
        let poses = session_poses(session, None)?;
        let size = session_projector_size(session)?;
        let files = calibrate_procam_files(
            &poses,
            cfg,
            size,
            None,
            &out.join("projector"),
            command,
            progress,
        )?;
        if let (Some(p), Some(t)) = (files.calibration.projector, files.calibration.t_cam_proj) {
            pair.projector = Some((p, t));
        }
        Some(files)
    } else {
        None
    };
    // The turntable axis, seen by the left camera.
    let turntable = match default_turntable_dir(session) {
        Some(_) => {
            let files = calibrate_turntable_files(
                Calibration::new(pair.left),
                &turntable_views(session, None)?,
                cfg,
                &TurntableConfig::default(),
                &out.join("turntable"),
                command,
                progress,
            )?;
            pair.turntable = files.calibration.turntable;
            Some(files)
        }
        None => None,
    };
    report.figure("rms_left_px", stereo.rms_left);
    report.figure("rms_right_px", stereo.rms_right);
    report.figure("rms_stereo_px", stereo.rms_stereo);
    report.figure("left", intrinsics_figure(&stereo.left));
    report.figure("right", intrinsics_figure(&stereo.right));
    let t = stereo.t_left_right.translation.vector;
    report.figure(
        "T_left_right",
        json!({
            "translation_mm": [t.x, t.y, t.z],
            "baseline_mm": t.norm(),
            "rotation_deg": stereo.t_left_right.rotation.angle().to_degrees(),
            "T_right_left_std_dev": stereo.t_right_left_std_dev,
        }),
    );
    report.figure(
        "views",
        serde_json::to_value(&stereo.views).unwrap_or_default(),
    );
    report.figure(
        "skipped",
        serde_json::to_value(&stereo.skipped_views).unwrap_or_default(),
    );
    report.figure("iterations", stereo.iterations);
    report.figure("projector", projector.is_some());
    report.figure("turntable", turntable.is_some());
    let path = out.join(STEREO_FILE);
    report.stage("write", || pair.save(&path))?;
    report.write(out)?;
    Ok(StereoFiles {
        pair,
        stereo,
        projector,
        turntable,
        poses: total,
    })
}
