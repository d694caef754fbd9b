//! Calibrating from files: a session folder (ours, `slscan simulate --scene board`'s, or another
//! program's through a [`CalibrationLayout`]) or plain checkerboard pictures, into an output
//! folder holding `calibration.json` (and OpenCV YAML on request), `report.json` and pictures
//! (the detected corners on every image, the per-view RMS bars, the residual vector plot).
//!
//! Four steps, each writing its own folder: [`calibrate_camera_files`] (Zhang),
//! [`calibrate_procam_files`] (Moreno & Taubin), [`calibrate_turntable_files`] (the axis added
//! to a calibration), and [`calibrate_session`] running what a session holds. The inputs are
//! found by [`camera_images`], [`session_poses`], [`session_projector_size`] and
//! [`turntable_views`].

use std::fs;
use std::path::{Path, PathBuf};

use serde_json::json;
use sl_calib::{
    BoardCorners, BoardSize, CalibError, CalibrationView, CameraCalibration, CornerRefiner,
    DetectorConfig, PictureConfig, ProcamCalibration, ProcamConfig, ProcamView, ResidualPlot,
    TurntableCalibration, TurntableConfig, TurntableView, ZhangConfig, calibrate_camera,
    calibrate_procam, calibrate_turntable, detect_checkerboard, draw_corners, error_bars,
    load_grey, residual_plot, save_png,
};
use sl_camera::{Calibration, ImageSize};
use sl_codec::{DecodeConfig, Frame, MANIFEST_FILE, Manifest, find_image_file, is_image_file};

use crate::error::{ScanError, io};
use crate::run_report::{RunReport, write_atomically};
use crate::{
    BOARD_DIR, BOARD_FILE, CalibrationLayout, PoseCapture, ScanProgress, TURNTABLE_DIR,
    WHITE_IMAGE, check_pose_files, default_turntable_dir,
};

/// The board and the files of a calibration step.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationFilesConfig {
    /// Inner corners of the board.
    pub board: BoardSize,
    /// Side of a square (mm).
    pub square_mm: f64,
    /// How the board's corners are refined.
    pub corners: CornerRefiner,
    /// Also write the calibration as OpenCV FileStorage YAML (`calibration.yml`).
    pub yaml: bool,
}

impl Default for CalibrationFilesConfig {
    /// A 9x6 board of 20 mm squares, the default corner refiner, JSON only.
    fn default() -> Self {
        Self {
            board: BoardSize::new(9, 6),
            square_mm: 20.0,
            corners: CornerRefiner::default(),
            yaml: false,
        }
    }
}

impl CalibrationFilesConfig {
    /// The board detector these options ask for.
    #[must_use]
    pub fn detector(&self) -> DetectorConfig {
        DetectorConfig::with_refiner(self.corners)
    }
}

/// An image skipped for want of a board.
#[derive(Debug, Clone, PartialEq)]
pub struct SkippedImage {
    /// The image file.
    pub image: PathBuf,
    /// Why (the detector's error, with the motor angle for turntable views).
    pub reason: String,
}

/// The camera step's result (its files are in its output folder).
#[derive(Debug, Clone)]
pub struct CameraFiles {
    /// The calibration written to `calibration.json`.
    pub calibration: Calibration,
    /// Zhang's calibration with its per-view figures.
    pub camera: CameraCalibration,
    /// Images without a board.
    pub skipped: Vec<SkippedImage>,
}

/// The projector step's result (its files are in its output folder).
#[derive(Debug, Clone)]
pub struct ProcamFiles {
    /// The calibration written to `calibration.json`.
    pub calibration: Calibration,
    /// The joint calibration with its per-view figures and skipped views.
    pub procam: ProcamCalibration,
    /// The poses without a white frame, whose board was found in the capture's own texture:
    /// the texture's description (`fringe mean of block 0`, …) each.
    pub textured: Vec<String>,
    /// How many poses were read.
    pub poses: usize,
}

/// The turntable step's result (its files are in its output folder).
#[derive(Debug, Clone)]
pub struct TurntableFiles {
    /// The calibration with the axis, written to `calibration.json`.
    pub calibration: Calibration,
    /// The axis fit with its per-view figures.
    pub turntable: TurntableCalibration,
    /// Views without a board.
    pub skipped: Vec<SkippedImage>,
}

/// What [`calibrate_session`] ran: the camera alone or camera and projector, then the axis
/// when the session has a turntable folder.
#[derive(Debug, Clone)]
pub struct SessionCalibration {
    /// The camera step, when the poses hold no pattern captures.
    pub camera: Option<CameraFiles>,
    /// The projector step, when they do.
    pub procam: Option<ProcamFiles>,
    /// The turntable step, when the session has a turntable folder.
    pub turntable: Option<TurntableFiles>,
    /// The whole calibration (in `out/calibration.json`).
    pub calibration: Calibration,
}

/// Calibrates what a session holds into `out`: camera and projector from the board poses (the
/// camera alone when they hold no pattern captures), then the turntable axis when there is a
/// turntable folder. With a turntable step, the camera or projector step's files go to
/// `out/camera` or `out/projector` and the whole calibration to `out`; without one, `out` is
/// the camera or projector step's.
///
/// # Errors
/// [`ScanError::Session`] for a session without board poses, the layout's and each step's
/// errors ([`ScanError::Step`] naming the step).
pub fn calibrate_session(
    session: &Path,
    layout: Option<&CalibrationLayout>,
    cfg: &CalibrationFilesConfig,
    out: &Path,
    progress: &mut dyn FnMut(ScanProgress<'_>),
) -> Result<SessionCalibration, ScanError> {
    let turntable_dir = match layout {
        Some(l) => l.turntable_dir(session)?,
        None => default_turntable_dir(session),
    };
    let sub = |name: &str| {
        if turntable_dir.is_some() {
            out.join(name)
        } else {
            out.to_path_buf()
        }
    };
    let (mut camera, mut procam) = (None, None);
    let mut calibration = match layout {
        Some(l) => {
            let poses = l.poses(session)?;
            let p = calibrate_procam_files(
                &poses,
                cfg,
                l.projector_size(),
                Some(l),
                &sub("projector"),
                "calibrate all: projector",
                progress,
            )?;
            procam.insert(p).calibration.clone()
        }
        None => {
            let board_dir = session.join(BOARD_DIR);
            if !board_dir.is_dir() {
                return Err(ScanError::Session {
                    path: session.to_path_buf(),
                    reason: "no board/ folder: expected an `slscan simulate --scene board` or \
                             `slscan calibrate capture` session, or a layout file describing \
                             the session's folders"
                        .into(),
                });
            }
            let folders = pose_folders(session)?;
            if folders.iter().all(|f| f.join(MANIFEST_FILE).is_file()) {
                let poses = session_poses(session, None)?;
                let size = session_projector_size(session)?;
                let p = calibrate_procam_files(
                    &poses,
                    cfg,
                    size,
                    None,
                    &sub("projector"),
                    "calibrate all: projector",
                    progress,
                )?;
                procam.insert(p).calibration.clone()
            } else {
                let images = camera_images(std::slice::from_ref(&board_dir))?;
                let c = calibrate_camera_files(
                    &images,
                    cfg,
                    &ZhangConfig::default(),
                    &sub("camera"),
                    "calibrate all: camera",
                    progress,
                )?;
                camera.insert(c).calibration.clone()
            }
        }
    };
    let mut turntable = None;
    if let Some(dir) = turntable_dir {
        let views = turntable_views(&dir, None)?;
        let t = calibrate_turntable_files(
            calibration,
            &views,
            cfg,
            &TurntableConfig::default(),
            out,
            "calibrate all: turntable",
            progress,
        )?;
        calibration = turntable.insert(t).calibration.clone();
    }
    Ok(SessionCalibration {
        camera,
        procam,
        turntable,
        calibration,
    })
}

/// The board poses of a session: the folders a layout names, or the capture folders of an
/// `slscan` session (`board/pose_NNN/` with `manifest.json` and `white.png`); their files are
/// checked before anything is decoded.
///
/// # Errors
/// [`ScanError::Session`] when there is no pose folder, [`ScanError::Layout`] for a missing
/// frame or an image of another size.
pub fn session_poses(
    session: &Path,
    layout: Option<&CalibrationLayout>,
) -> Result<Vec<PoseCapture>, ScanError> {
    if let Some(l) = layout {
        return Ok(l.poses(session)?);
    }
    let poses: Vec<PoseCapture> = pose_folders(session)?
        .iter()
        .map(|folder| {
            // The view's name: `pose_000/white.png`, or the folder's name without a white frame.
            let name = white_image(folder).map_or_else(
                || {
                    folder.file_name().map_or_else(
                        || folder.display().to_string(),
                        |f| f.to_string_lossy().into_owned(),
                    )
                },
                |w| short_name(&w),
            );
            PoseCapture::capture_folder(folder, name)
        })
        .collect();
    check_pose_files(&poses)?;
    Ok(poses)
}

/// The white frames of the poses of a session described by a layout: the camera's images.
///
/// # Errors
/// [`ScanError::Session`] naming the layout file when it names no white frame; the layout's
/// errors.
pub fn layout_white_frames(
    layout: &CalibrationLayout,
    session: &Path,
) -> Result<Vec<PathBuf>, ScanError> {
    if layout.white.is_none() {
        return Err(ScanError::Session {
            path: layout.source.clone(),
            reason: "no white frame named (\"white\"): the camera is calibrated from the board \
                     under white light"
                .into(),
        });
    }
    Ok(layout
        .poses(session)?
        .into_iter()
        .filter_map(|p| p.white)
        .collect())
}

/// The projector size of a session: from its `rig.json` (a simulated session), else from the
/// first pose's `manifest.json` (an `slscan calibrate capture` session on real devices), else
/// 1920x1080.
///
/// # Errors
/// [`ScanError::Session`] naming `rig.json` when it is unreadable or has no `projector.size`;
/// the manifest's errors.
pub fn session_projector_size(session: &Path) -> Result<ImageSize, ScanError> {
    let path = session.join("rig.json");
    if !path.is_file() {
        let manifest = pose_folders(session)?
            .first()
            .map(|f| f.join(MANIFEST_FILE))
            .filter(|m| m.is_file());
        return Ok(match manifest {
            Some(m) => {
                let m = Manifest::load(&m)?;
                ImageSize::new(m.projector.width, m.projector.height)
            }
            None => ImageSize::new(1920, 1080),
        });
    }
    let bad = |reason: String| ScanError::Session {
        path: path.clone(),
        reason,
    };
    let text = fs::read_to_string(&path).map_err(io(&path))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let size = value
        .pointer("/projector/size")
        .cloned()
        .ok_or_else(|| bad("no projector.size".into()))?;
    serde_json::from_value(size).map_err(|e| bad(format!("bad projector.size: {e}")))
}

/// Expands checkerboard inputs into image files: files as they are; a folder's image files,
/// else its subfolders' white frames; a session's `board/` folder for the session.
///
/// # Errors
/// [`ScanError::Session`] naming an input that does not exist or a folder without images.
pub fn camera_images(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, ScanError> {
    let mut images = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let session_boards = input.join(BOARD_DIR);
            let dir = if session_boards.is_dir() {
                session_boards
            } else {
                input.clone()
            };
            let found = images_in(&dir)?;
            if found.is_empty() {
                return Err(ScanError::Session {
                    path: dir,
                    reason: format!(
                        "no checkerboard images: expected image files (.png, .jpg, .tif, .bmp) \
                         or capture folders holding {WHITE_IMAGE}"
                    ),
                });
            }
            images.extend(found);
        } else if input.is_file() {
            images.push(input.clone());
        } else {
            // Something that is neither (a device, a FIFO) is named for what it is.
            let what =
                sl_codec::not_a_regular_file(input).map(|w| w.trim_start_matches("is ").to_owned());
            return Err(ScanError::Session {
                path: input.clone(),
                reason: what.unwrap_or_else(|| "no such file or folder".into()),
            });
        }
    }
    Ok(images)
}

/// The turntable views of a session folder (its `turntable/` subfolder, or the folder itself):
/// `(image, motor angle)` in name order, the angles given or read from each view folder's
/// `board.json` (`motor_angle_deg`).
///
/// # Errors
/// [`ScanError::Session`] for a missing folder, no views, as many angles given as views, or a
/// `board.json` without the angle.
pub fn turntable_views(
    session: &Path,
    angles: Option<&[f64]>,
) -> Result<Vec<(PathBuf, f64)>, ScanError> {
    let dir = subfolder_or_itself(session, TURNTABLE_DIR)?;
    let images = images_in(&dir)?;
    if images.is_empty() {
        return Err(ScanError::Session {
            path: dir,
            reason: format!(
                "no turntable views: expected one folder per motor angle holding {WHITE_IMAGE} \
                 (and {BOARD_FILE} with motor_angle_deg, or the angles given), or image files \
                 with the angles given"
            ),
        });
    }
    match angles {
        Some(a) if a.len() != images.len() => Err(ScanError::Session {
            path: dir,
            reason: format!("{} motor angles given for {} views", a.len(), images.len()),
        }),
        Some(a) => Ok(images.into_iter().zip(a.iter().copied()).collect()),
        None => images
            .into_iter()
            .map(|p| {
                let folder = p.parent().unwrap_or(Path::new(".")).to_path_buf();
                Ok((p, angle_from_board_file(&folder)?))
            })
            .collect(),
    }
}

/// Camera calibration (Zhang) of `images` into `out`: `calibration.json`, `report.json` (under
/// `command`) and pictures. Images without a board are skipped and listed.
///
/// # Errors
/// [`ScanError::Session`] for images of different sizes, the image reader's and the
/// calibration's errors ([`ScanError::Step`] naming how many views had a board and which were
/// skipped), [`ScanError::Io`] for the outputs.
pub fn calibrate_camera_files(
    images: &[PathBuf],
    cfg: &CalibrationFilesConfig,
    zhang: &ZhangConfig,
    out: &Path,
    command: &str,
    progress: &mut dyn FnMut(ScanProgress<'_>),
) -> Result<CameraFiles, ScanError> {
    let mut report = RunReport::new(command);
    create_dir(out)?;
    let (detected, skipped, image_size) = detect_all(images, None, cfg, &mut report, progress)?;
    let views: Vec<CalibrationView> = detected
        .iter()
        .map(|d| CalibrationView::from_corners(&d.corners, cfg.square_mm))
        .collect();
    let cal = report
        .stage("calibrate", || calibrate_camera(&views, image_size, zhang))
        .map_err(failed_on("camera calibration", views.len(), &skipped))?;
    let magnification = report.stage("pictures", || {
        pictures(
            out,
            &detected,
            &cal.view_rms,
            cal.rms,
            &cal.residuals,
            image_size,
        )
    })?;
    let mut calib = Calibration::new(cal.camera);
    calib.rms.camera = Some(cal.rms);
    calib.metadata.notes = format!(
        "slscan calibrate camera: {} views of a {}x{} board of {} mm squares",
        views.len(),
        cfg.board.cols,
        cfg.board.rows,
        cfg.square_mm
    );
    report.stage("write", || write_calibration(&calib, cfg.yaml, out))?;
    let i = &cal.camera.intrinsics;
    report.figure("rms_px", cal.rms);
    report.figure(
        "view_rms_px",
        detected
            .iter()
            .zip(&cal.view_rms)
            .map(|(d, r)| json!({ "image": d.name, "rms": r }))
            .collect::<Vec<_>>(),
    );
    report.figure(
        "intrinsics",
        json!({ "fx": i.fx, "fy": i.fy, "cx": i.cx, "cy": i.cy, "skew": i.skew }),
    );
    report.figure("distortion", cal.camera.distortion.to_opencv_vec());
    report.figure(
        "std_dev",
        json!({ "intrinsics": cal.std_dev.intrinsics, "distortion": cal.std_dev.distortion }),
    );
    report.figure("views_used", views.len());
    report.figure("skipped", skipped_json(&skipped));
    report.figure("iterations", cal.iterations);
    report.figure("residual_plot", magnification);
    report.figure("image_size", json!([image_size.width, image_size.height]));
    report.write(out)?;
    Ok(CameraFiles {
        calibration: calib,
        camera: cal,
        skipped,
    })
}

/// The turntable axis from `views` (`(image, motor angle)`) added to `calib`, into `out`:
/// `calibration.json`, `report.json` (under `command`) and pictures.
///
/// # Errors
/// [`ScanError::Session`] when the views' size is not the calibrated camera's, the fit's errors
/// ([`ScanError::Step`] naming how many views had a board), [`ScanError::Io`] for the outputs.
pub fn calibrate_turntable_files(
    mut calib: Calibration,
    views: &[(PathBuf, f64)],
    cfg: &CalibrationFilesConfig,
    turntable: &TurntableConfig,
    out: &Path,
    command: &str,
    progress: &mut dyn FnMut(ScanProgress<'_>),
) -> Result<TurntableFiles, ScanError> {
    let mut report = RunReport::new(command);
    create_dir(out)?;
    let paths: Vec<PathBuf> = views.iter().map(|v| v.0.clone()).collect();
    let angles: Vec<f64> = views.iter().map(|v| v.1).collect();
    let (detected, skipped, image_size) =
        detect_all(&paths, Some(&angles), cfg, &mut report, progress)?;
    if image_size != calib.camera.size {
        return Err(ScanError::Session {
            path: paths.first().cloned().unwrap_or_default(),
            reason: format!(
                "{}x{} pixels, but the calibration's camera has {}x{}",
                image_size.width,
                image_size.height,
                calib.camera.size.width,
                calib.camera.size.height
            ),
        });
    }
    let tviews: Vec<TurntableView> = detected
        .iter()
        .filter_map(|d| {
            let (_, angle) = views.get(d.index)?;
            Some(TurntableView::from_corners(
                d.name.clone(),
                *angle,
                &d.corners,
                cfg.square_mm,
            ))
        })
        .collect();
    let fit = report
        .stage("fit axis", || {
            calibrate_turntable(&calib.camera, &tviews, turntable)
        })
        .map_err(failed_on("turntable axis", tviews.len(), &skipped))?;
    let magnification = report.stage("pictures", || {
        pictures(
            out,
            &detected,
            &fit.view_rms,
            fit.rms,
            &fit.residuals,
            image_size,
        )
    })?;
    calib.turntable = Some(fit.axis);
    report.stage("write", || write_calibration(&calib, cfg.yaml, out))?;
    let a = &fit.axis;
    report.figure(
        "axis",
        json!({
            "direction": [a.direction.x, a.direction.y, a.direction.z],
            "point_mm": [a.point_mm.x, a.point_mm.y, a.point_mm.z],
            "point": "foot of the axis nearest the camera centre",
            "angle_scale": a.angle_scale,
            "angle_offset_deg": a.angle_offset_deg,
        }),
    );
    let i = &fit.initial_axis;
    report.figure(
        "closed_form_axis",
        json!({
            "direction": [i.direction.x, i.direction.y, i.direction.z],
            "point_mm": [i.point_mm.x, i.point_mm.y, i.point_mm.z],
            "angle_scale": i.angle_scale,
        }),
    );
    report.figure(
        "std_dev",
        json!({
            "direction_deg": fit.std_dev.direction_deg,
            "point_mm": fit.std_dev.point_mm,
            "angle_scale": fit.std_dev.angle_scale,
        }),
    );
    report.figure("rms_px", fit.rms);
    report.figure(
        "view_rms_px",
        tviews
            .iter()
            .zip(&fit.view_rms)
            .map(|(v, r)| json!({ "image": v.label, "motor_angle_deg": v.motor_angle_deg, "rms": r }))
            .collect::<Vec<_>>(),
    );
    report.figure("views_used", tviews.len());
    report.figure("skipped", skipped_json(&skipped));
    report.figure("iterations", fit.iterations);
    report.figure("residual_plot", magnification);
    report.write(out)?;
    Ok(TurntableFiles {
        calibration: calib,
        turntable: fit,
        skipped,
    })
}

/// Projector–camera calibration (Moreno & Taubin) of the board poses into `out`:
/// `calibration.json`, `report.json` (under `command`, naming the layout when there is one)
/// and pictures.
///
/// # Errors
/// A pose's reading or decoding error ([`ScanError::Step`] naming the pose folder), the
/// calibration's ([`ScanError::Step`] naming how many poses), [`ScanError::Io`] for the outputs.
pub fn calibrate_procam_files(
    poses: &[PoseCapture],
    cfg: &CalibrationFilesConfig,
    projector_size: ImageSize,
    layout: Option<&CalibrationLayout>,
    out: &Path,
    command: &str,
    progress: &mut dyn FnMut(ScanProgress<'_>),
) -> Result<ProcamFiles, ScanError> {
    let mut report = RunReport::new(command);
    create_dir(out)?;
    let size = cfg.board;
    let mut board_images = Vec::with_capacity(poses.len());
    let mut textured = Vec::new();
    let views = report.stage(
        "read and decode",
        || -> Result<Vec<ProcamView>, ScanError> {
            let mut views = Vec::with_capacity(poses.len());
            for (k, pose) in poses.iter().enumerate() {
                let v = pose
                    .load(&DecodeConfig::default())
                    .map_err(|e| ScanError::Step {
                        what: format!("board pose {}", pose.folder.display()),
                        source: Box::new(e.into()),
                    })?;
                progress(ScanProgress {
                    stage: "decode",
                    done: k + 1,
                    total: poses.len(),
                });
                board_images.push(json!({ "view": v.view.name, "board_image": v.board_image }));
                if !v.white_frame {
                    textured.push(v.board_image);
                }
                views.push(v.view);
            }
            Ok(views)
        },
    )?;
    report.figure("board_images", board_images);
    report.figure(
        "session",
        json!({
            "layout": layout.map(|l| l.source.display().to_string()),
            "manifest": layout.map(|l| l.manifest_path.display().to_string()),
            "pose_folders": poses.iter().map(|p| p.folder.display().to_string()).collect::<Vec<_>>(),
        }),
    );
    let pcfg = ProcamConfig {
        detector: cfg.detector(),
        ..ProcamConfig::new(size, cfg.square_mm, projector_size)
    };
    report.figure("corners", cfg.corners.name());
    let cal = report
        .stage("calibrate", || calibrate_procam(&views, &pcfg))
        .map_err(|e| ScanError::Step {
            what: format!("projector calibration from {} board poses", views.len()),
            source: Box::new(e.into()),
        })?;
    let magnification = report.stage("pictures", || procam_pictures(out, &cal, &views, size))?;
    let mut calib = cal.to_calibration();
    calib.metadata.notes = format!(
        "slscan calibrate projector: {} poses of a {}x{} board of {} mm squares",
        cal.views.len(),
        size.cols,
        size.rows,
        cfg.square_mm
    );
    report.stage("write", || write_calibration(&calib, cfg.yaml, out))?;
    report.figure("rms_camera_px", cal.rms_camera);
    report.figure("rms_projector_px", cal.rms_projector);
    report.figure("rms_stereo_px", cal.rms_stereo);
    report.figure(
        "predicted_error",
        serde_json::to_value(cal.predicted_error).unwrap_or_default(),
    );
    report.figure("camera", intrinsics_figure(&cal.camera));
    report.figure("projector", intrinsics_figure(&cal.projector));
    let t = cal.t_cam_proj.translation.vector;
    report.figure(
        "T_cam_proj",
        json!({
            "translation_mm": [t.x, t.y, t.z],
            "rotation_deg": cal.t_cam_proj.rotation.angle().to_degrees(),
            "T_proj_cam_std_dev": cal.t_proj_cam_std_dev,
        }),
    );
    report.figure(
        "views",
        cal.views
            .iter()
            .map(|v| {
                json!({
                    "name": v.name,
                    "camera_rms": v.camera_rms,
                    "projector_rms": v.projector_rms,
                    "projector_corners": v.projector_corners.mapped_count(),
                    "in_projector_calibration": v.in_projector_calibration,
                })
            })
            .collect::<Vec<_>>(),
    );
    report.figure(
        "skipped",
        serde_json::to_value(&cal.skipped_views).unwrap_or_default(),
    );
    report.figure("iterations", cal.iterations);
    report.figure("residual_plot", magnification);
    report.write(out)?;
    Ok(ProcamFiles {
        calibration: calib,
        procam: cal,
        textured,
        poses: poses.len(),
    })
}

/// The procam step's pictures: corners on each pose's board picture, the error bars and the
/// residual plots of camera and projector; returns the plots' scales.
fn procam_pictures(
    out: &Path,
    cal: &ProcamCalibration,
    views: &[ProcamView],
    size: BoardSize,
) -> Result<serde_json::Value, ScanError> {
    let pics = create_dir(&out.join("pictures"))?;
    let pc = PictureConfig::default();
    let mut camera_corners = Vec::new();
    let mut projector_points = Vec::new();
    for (k, v) in cal.views.iter().enumerate() {
        if let Some(view) = views.iter().find(|w| w.name == v.name) {
            let corners = BoardCorners {
                size,
                corners: v.camera_corners.clone(),
            };
            save_png(
                &draw_corners(&view.lit, &corners),
                pics.join(picture_name(k, &v.name)),
            )?;
        }
        camera_corners.push(v.camera_corners.clone());
        projector_points.push(v.projector_corners.points().into_iter().flatten().collect());
    }
    let camera_rms: Vec<f64> = cal.views.iter().map(|v| v.camera_rms).collect();
    let projector_rms: Vec<f64> = cal.views.iter().map(|v| v.projector_rms).collect();
    save_png(
        &error_bars(&camera_rms, cal.camera.rms, &pc).image,
        pics.join("error_bars_camera.png"),
    )?;
    save_png(
        &error_bars(&projector_rms, cal.projector.rms, &pc).image,
        pics.join("error_bars_projector.png"),
    )?;
    let cs = cal.camera.camera.size;
    let plot = residual_plot(
        cs.width,
        cs.height,
        &camera_corners,
        &cal.camera.residuals,
        &pc,
    );
    save_png(&plot.image, pics.join("residuals_camera.png"))?;
    let ps = cal.projector.camera.size;
    let pplot = residual_plot(
        ps.width,
        ps.height,
        &projector_points,
        &cal.projector.residuals,
        &pc,
    );
    save_png(&pplot.image, pics.join("residuals_projector.png"))?;
    Ok(json!({ "camera": plot_scale(&plot), "projector": plot_scale(&pplot) }))
}

/// A calibrated device's intrinsics, distortion and their standard deviations, as the
/// calibration reports hold them.
pub(crate) fn intrinsics_figure(c: &CameraCalibration) -> serde_json::Value {
    let i = &c.camera.intrinsics;
    json!({ "fx": i.fx, "fy": i.fy, "cx": i.cx, "cy": i.cy, "skew": i.skew,
            "distortion": c.camera.distortion.to_opencv_vec(),
            "std_dev": { "intrinsics": c.std_dev.intrinsics, "distortion": c.std_dev.distortion } })
}

/// The white-light picture of a capture folder, saved in any format sl-codec reads.
pub(crate) fn white_image(folder: &Path) -> Option<PathBuf> {
    find_image_file(&folder.join(WHITE_IMAGE))
}

/// Whether a board image's name (`white.png`, `white.bmp`, …) is a white-light picture.
fn is_white_name(name: &str) -> bool {
    let path = Path::new(name);
    path.file_stem().is_some_and(|s| s == "white") && is_image_file(path)
}

fn create_dir(dir: &Path) -> Result<PathBuf, ScanError> {
    fs::create_dir_all(dir).map_err(io(dir))?;
    Ok(dir.to_path_buf())
}

/// `session/name` when it is a folder, else `session` itself (given the subfolder directly).
fn subfolder_or_itself(session: &Path, name: &str) -> Result<PathBuf, ScanError> {
    let sub = session.join(name);
    let dir = if sub.is_dir() {
        sub
    } else {
        session.to_path_buf()
    };
    if !dir.is_dir() {
        return Err(ScanError::Session {
            path: dir,
            reason: "no such folder".into(),
        });
    }
    Ok(dir)
}

/// The capture folders (one per board pose) of a session.
pub(crate) fn pose_folders(session: &Path) -> Result<Vec<PathBuf>, ScanError> {
    let dir = subfolder_or_itself(session, BOARD_DIR)?;
    // A pose folder holds a white picture, a pattern capture, or both (captures without a
    // white frame use their own texture).
    let folders: Vec<PathBuf> = sorted_entries(&dir)?
        .into_iter()
        .filter(|p| white_image(p).is_some() || p.join(MANIFEST_FILE).is_file())
        .collect();
    if folders.is_empty() {
        return Err(ScanError::Session {
            path: dir,
            reason: format!(
                "no board poses: expected one capture folder per pose holding the pattern \
                 sequence's {MANIFEST_FILE} (and {WHITE_IMAGE} if it has one)"
            ),
        });
    }
    Ok(folders)
}

fn sorted_entries(dir: &Path) -> Result<Vec<PathBuf>, ScanError> {
    let mut entries: Vec<PathBuf> = fs::read_dir(dir)
        .map_err(io(dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    entries.sort();
    Ok(entries)
}

/// The images of a folder: its image files, else its subfolders' white frames.
fn images_in(dir: &Path) -> Result<Vec<PathBuf>, ScanError> {
    let entries = sorted_entries(dir)?;
    let files: Vec<PathBuf> = entries
        .iter()
        .filter(|p| p.is_file() && is_image_file(p))
        .cloned()
        .collect();
    if !files.is_empty() {
        return Ok(files);
    }
    Ok(entries.iter().filter_map(|p| white_image(p)).collect())
}

/// Reads `motor_angle_deg` from a view folder's `board.json`.
fn angle_from_board_file(folder: &Path) -> Result<f64, ScanError> {
    let path = folder.join(BOARD_FILE);
    let bad = |reason: &str| ScanError::Session {
        path: path.clone(),
        reason: reason.to_owned(),
    };
    let text = fs::read_to_string(&path)
        .map_err(|e| bad(&format!("cannot read it for the motor angle: {e}")))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(&format!("not JSON: {e}")))?;
    value
        .get("motor_angle_deg")
        .and_then(serde_json::Value::as_f64)
        .ok_or_else(|| bad("no number `motor_angle_deg`"))
}

/// A short name of an image for messages and picture file names: the file name, or
/// `folder/white.png` for capture folders.
fn short_name(path: &Path) -> String {
    let file = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    match path.parent().and_then(|p| p.file_name()) {
        Some(parent) if is_white_name(&file) => format!("{}/{file}", parent.to_string_lossy()),
        _ => file,
    }
}

/// The images' short names ([`short_name`]), with the folder added to those that would
/// otherwise repeat (the white frames `capture_0/graycode_40.png`, `capture_1/graycode_40.png`
/// of a layout's pose folders).
fn view_names(paths: &[PathBuf]) -> Vec<String> {
    let short: Vec<String> = paths.iter().map(|p| short_name(p)).collect();
    short
        .iter()
        .zip(paths)
        .map(|(name, path)| {
            let repeated = short.iter().filter(|n| *n == name).count() > 1;
            match path.parent().and_then(|p| p.file_name()) {
                Some(parent) if repeated && !is_white_name(name) => {
                    format!("{}/{name}", parent.to_string_lossy())
                }
                _ => name.clone(),
            }
        })
        .collect()
}

fn picture_name(k: usize, name: &str) -> String {
    // Without its image extension, whichever it is (`white.bmp`, `left01.jpg`).
    let bare = match name.rsplit_once('.') {
        Some((stem, _)) if is_image_file(Path::new(name)) => stem,
        _ => name,
    };
    let stem: String = bare
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    format!("corners_{k:03}_{stem}.png")
}

/// One image with its detected board.
struct Detected {
    /// Index of the image in the input list.
    index: usize,
    name: String,
    image: Frame<u8>,
    corners: BoardCorners,
}

/// Loads and detects every image; images without a board are skipped with the reason (and
/// the motor angle, for turntable views).
fn detect_all(
    paths: &[PathBuf],
    angles: Option<&[f64]>,
    cfg: &CalibrationFilesConfig,
    report: &mut RunReport,
    progress: &mut dyn FnMut(ScanProgress<'_>),
) -> Result<(Vec<Detected>, Vec<SkippedImage>, ImageSize), ScanError> {
    let mut found = Vec::new();
    let mut skipped = Vec::new();
    let mut dims: Option<(usize, usize, String)> = None;
    let detector = cfg.detector();
    report.figure("corners", cfg.corners.name());
    report.stage("read and detect", || -> Result<(), ScanError> {
        let names = view_names(paths);
        for ((index, path), name) in paths.iter().enumerate().zip(names) {
            let image = load_grey(path)?;
            match &dims {
                None => dims = Some((image.width(), image.height(), name.clone())),
                Some((w, h, first)) if (*w, *h) != (image.width(), image.height()) => {
                    return Err(ScanError::Session {
                        path: path.clone(),
                        reason: format!(
                            "{}x{} pixels, but {first} has {w}x{h}: one camera, one image size",
                            image.width(),
                            image.height()
                        ),
                    });
                }
                Some(_) => {}
            }
            match detect_checkerboard(&image, cfg.board, &detector, &path.display().to_string()) {
                Ok(corners) => found.push(Detected {
                    index,
                    name,
                    image,
                    corners,
                }),
                Err(e @ CalibError::BoardNotFound { .. }) => {
                    let e = match angles.and_then(|a| a.get(index)) {
                        Some(&motor_angle_deg) => CalibError::BoardNotFoundAtAngle {
                            motor_angle_deg,
                            source: Box::new(e),
                        },
                        None => e,
                    };
                    skipped.push(SkippedImage {
                        image: path.clone(),
                        reason: e.to_string(),
                    });
                }
                Err(e) => return Err(e.into()),
            }
            progress(ScanProgress {
                stage: "detect",
                done: index + 1,
                total: paths.len(),
            });
        }
        Ok(())
    })?;
    let Some((w, h, first)) = dims else {
        return Err(ScanError::Stage {
            stage: "detect".into(),
            reason: "no images given".into(),
        });
    };
    let (Ok(w32), Ok(h32)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(ScanError::Stage {
            stage: "detect".into(),
            reason: format!("{first} has {w}x{h} pixels: a camera image side must fit in u32"),
        });
    };
    Ok((found, skipped, ImageSize::new(w32, h32)))
}

fn skipped_json(skipped: &[SkippedImage]) -> serde_json::Value {
    skipped
        .iter()
        .map(|s| json!({ "image": s.image.display().to_string(), "reason": s.reason }))
        .collect()
}

/// The error of a step (`what`) that failed on `used` views with a board, naming the images
/// skipped for want of one: `camera calibration from 7 views with a board (2 skipped: a.png,
/// b.png)` (the first [`SKIPPED_NAMED`], then `…`).
fn failed_on<'a>(
    what: &'a str,
    used: usize,
    skipped: &'a [SkippedImage],
) -> impl FnOnce(CalibError) -> ScanError + 'a {
    move |e| {
        let mut names: Vec<String> = skipped
            .iter()
            .take(SKIPPED_NAMED)
            .map(|s| s.image.display().to_string())
            .collect();
        if skipped.len() > SKIPPED_NAMED {
            names.push("…".to_owned());
        }
        let named = if names.is_empty() {
            String::new()
        } else {
            format!(": {}", names.join(", "))
        };
        ScanError::Step {
            what: format!(
                "{what} from {used} views with a board ({} skipped{named})",
                skipped.len()
            ),
            source: Box::new(e.into()),
        }
    }
}

/// Skipped images named in an error message: enough to find the folder, short enough to read.
const SKIPPED_NAMED: usize = 3;

/// Writes `calibration.json` (and `.yml`) atomically.
fn write_calibration(calib: &Calibration, yaml: bool, out: &Path) -> Result<(), ScanError> {
    write_atomically(&out.join("calibration.json"), calib.to_json()?.as_bytes())?;
    if yaml {
        write_atomically(
            &out.join("calibration.yml"),
            calib.to_opencv_yaml()?.as_bytes(),
        )?;
    }
    Ok(())
}

/// The three kinds of pictures for a set of views; returns the residual plot's scale.
fn pictures(
    dir: &Path,
    detected: &[Detected],
    view_rms: &[f64],
    rms: f64,
    residuals: &[Vec<nalgebra::Vector2<f64>>],
    size: ImageSize,
) -> Result<serde_json::Value, ScanError> {
    let pics = create_dir(&dir.join("pictures"))?;
    let cfg = PictureConfig::default();
    for (k, d) in detected.iter().enumerate() {
        save_png(
            &draw_corners(&d.image, &d.corners),
            pics.join(picture_name(k, &d.name)),
        )?;
    }
    save_png(
        &error_bars(view_rms, rms, &cfg).image,
        pics.join("error_bars.png"),
    )?;
    let corners: Vec<_> = detected.iter().map(|d| d.corners.corners.clone()).collect();
    let plot = residual_plot(size.width, size.height, &corners, residuals, &cfg);
    save_png(&plot.image, pics.join("residuals.png"))?;
    Ok(plot_scale(&plot))
}

fn plot_scale(plot: &ResidualPlot) -> serde_json::Value {
    json!({ "magnification": plot.magnification, "scale_arrow_px": plot.scale_arrow_px })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picture_names_drop_the_extension_and_odd_characters() {
        assert_eq!(
            picture_name(3, "pose_001/white.bmp"),
            "corners_003_pose_001_white.png"
        );
        assert_eq!(picture_name(0, "left 01.jpg"), "corners_000_left_01.png");
        assert_eq!(picture_name(12, "a.b"), "corners_012_a_b.png");
    }

    #[test]
    fn repeated_names_get_their_folder() {
        let paths = [
            PathBuf::from("s/capture_0/graycode_40.png"),
            PathBuf::from("s/capture_1/graycode_40.png"),
            PathBuf::from("s/pose_2/white.png"),
            PathBuf::from("s/left01.jpg"),
        ];
        assert_eq!(
            view_names(&paths),
            [
                "capture_0/graycode_40.png",
                "capture_1/graycode_40.png",
                "pose_2/white.png",
                "left01.jpg"
            ]
        );
    }

    #[test]
    fn turntable_views_check_the_angles_against_the_views() {
        let dir = tempfile::tempdir().unwrap();
        for k in 0..3 {
            let f = dir.path().join(format!("angle_{k}"));
            fs::create_dir(&f).unwrap();
            fs::write(f.join("white.png"), b"").unwrap();
            fs::write(
                f.join(BOARD_FILE),
                format!("{{\"motor_angle_deg\": {}}}", 10 * k),
            )
            .unwrap();
        }
        let views = turntable_views(dir.path(), None).unwrap();
        let angles: Vec<f64> = views.iter().map(|v| v.1).collect();
        assert_eq!(angles, [0.0, 10.0, 20.0]);
        let err = turntable_views(dir.path(), Some(&[1.0, 2.0])).unwrap_err();
        assert!(
            err.to_string().contains("2 motor angles given for 3 views"),
            "{err}"
        );
        fs::write(dir.path().join("angle_1").join(BOARD_FILE), "{}").unwrap();
        let err = turntable_views(dir.path(), None).unwrap_err();
        assert!(err.to_string().contains("angle_1"), "{err}");
        assert!(err.to_string().contains("motor_angle_deg"), "{err}");
    }

    #[test]
    fn inputs_that_do_not_exist_or_hold_no_image_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nope");
        let err = camera_images(std::slice::from_ref(&missing)).unwrap_err();
        assert!(err.to_string().contains("nope"), "{err}");
        let empty = dir.path().join("empty");
        fs::create_dir(&empty).unwrap();
        let err = camera_images(std::slice::from_ref(&empty)).unwrap_err();
        assert!(err.to_string().contains("no checkerboard images"), "{err}");
        let err = session_poses(&empty, None).unwrap_err();
        assert!(err.to_string().contains("no board poses"), "{err}");
    }
}
