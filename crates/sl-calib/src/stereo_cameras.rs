//! Two cameras calibrated from the same board views (as `cv::stereoCalibrate`): each camera
//! alone by Zhang's method, the relative pose started from the per-view poses, then both
//! models, every board pose and `T_right_left` refined jointly — the refinement of the
//! camera–projector pair (`stereo.rs`), with the right camera as the second device.

use nalgebra::{Isometry3, Point2};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sl_camera::{BinocularCalibration, ImageSize};
use sl_codec::Frame;

use crate::stereo::{
    StereoOptions, StereoStart, StereoView, joint_calibrations, mean_relative_pose, refine_stereo,
};
use crate::{
    BoardCorners, BoardSize, CalibError, CalibrationView, CameraCalibration, DetectorConfig,
    SkippedView, ZhangConfig, calibrate_camera, detect_checkerboard,
};

/// One board pose seen by both cameras of a binocular rig.
#[derive(Debug, Clone)]
pub struct StereoCameraView {
    /// Name used in messages and reports (e.g. the pose folder).
    pub name: String,
    /// The left camera's image of the board.
    pub left: Frame<u8>,
    /// The right camera's image of the board, taken at the same time.
    pub right: Frame<u8>,
}

/// Options of [`calibrate_stereo_cameras`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StereoCameraConfig {
    /// Inner corners of the board.
    pub board: BoardSize,
    /// Side of a square (mm): the unit of the poses and of `T_left_right`.
    pub square_mm: f64,
    /// Checkerboard detection in both cameras' images.
    pub detector: DetectorConfig,
    /// The left camera's model and fixed parameters.
    pub left: ZhangConfig,
    /// The right camera's model and fixed parameters.
    pub right: ZhangConfig,
    /// `true`: a view whose board one camera does not find is left out of the joint
    /// refinement and listed in [`StereoCameraCalibration::skipped_views`] (it still counts
    /// in the other camera's own calibration); `false`: it is an error.
    pub skip_unusable_views: bool,
    /// Largest number of Levenberg–Marquardt iterations of the joint refinement.
    pub max_iterations: usize,
    /// Relative decrease of the squared error below which the joint refinement stops.
    pub tolerance: f64,
}

impl StereoCameraConfig {
    /// The defaults for a board of `board` inner corners with squares of `square_mm`.
    pub fn new(board: BoardSize, square_mm: f64) -> Self {
        Self {
            board,
            square_mm,
            ..Self::default()
        }
    }
}

impl Default for StereoCameraConfig {
    /// `sl-sim`'s default board (9×6 inner corners, 20 mm squares), OpenCV's default model for
    /// both cameras, views the board is missing from skipped.
    fn default() -> Self {
        Self {
            board: BoardSize::new(9, 6),
            square_mm: 20.0,
            detector: DetectorConfig::default(),
            left: ZhangConfig::default(),
            right: ZhangConfig::default(),
            skip_unusable_views: true,
            max_iterations: 100,
            tolerance: 1e-15,
        }
    }
}

/// What became of one view of the joint refinement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StereoCameraViewReport {
    /// The view's name.
    pub name: String,
    /// RMS residual of the left camera in the joint solution (px).
    pub left_rms: f64,
    /// RMS residual of the right camera in the joint solution (px).
    pub right_rms: f64,
}

/// The result of [`calibrate_stereo_cameras`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StereoCameraCalibration {
    /// The left camera after the joint refinement: model, `T_left_board` per view of the
    /// refinement, RMS and residuals in the joint solution, standard deviations.
    pub left: CameraCalibration,
    /// The right camera after the joint refinement (its poses `T_right_board`; `std_dev.poses`
    /// is empty: they are not free parameters).
    pub right: CameraCalibration,
    /// The right camera's pose in the left camera's frame: `p_left = T_left_right · p_right`
    /// (mm).
    pub t_left_right: Isometry3<f64>,
    /// Standard deviations of `T_right_left = T_left_right⁻¹` as estimated: rvec (rad), tvec
    /// (mm).
    pub t_right_left_std_dev: [f64; 6],
    /// RMS of the left camera calibrated alone on every view it found the board in (px).
    pub rms_left: f64,
    /// RMS of the right camera calibrated alone (px).
    pub rms_right: f64,
    /// RMS of the joint refinement over both cameras' residuals (OpenCV's `stereoCalibrate`
    /// definition, px).
    pub rms_stereo: f64,
    /// The views of the joint refinement, in the order of `left.poses`.
    pub views: Vec<StereoCameraViewReport>,
    /// Views left out of the joint refinement, with the reason.
    pub skipped_views: Vec<SkippedView>,
    /// Levenberg–Marquardt iterations of the joint refinement.
    pub iterations: usize,
}

impl StereoCameraCalibration {
    /// The two-camera calibration file's content: both models, `T_left_right` and the stereo
    /// RMS (no projector, no turntable).
    pub fn to_binocular(&self) -> BinocularCalibration {
        let mut pair =
            BinocularCalibration::new(self.left.camera, self.right.camera, self.t_left_right);
        pair.rms = Some(self.rms_stereo);
        pair
    }
}

/// Views fewer than this leave Zhang's method underdetermined.
const MIN_VIEWS: usize = 3;

/// The image size of a camera's frames, the same in every view.
fn camera_size<'a>(
    views: &'a [StereoCameraView],
    which: &str,
    frame: impl Fn(&'a StereoCameraView) -> &'a Frame<u8>,
) -> Result<ImageSize, CalibError> {
    let mut size: Option<(usize, usize, &str)> = None;
    for v in views {
        let f = frame(v);
        let (w, h) = (f.width(), f.height());
        match size {
            Some((fw, fh, first)) if (fw, fh) != (w, h) => {
                return Err(CalibError::Frame {
                    frame: v.name.clone(),
                    reason: format!(
                        "the {which} image is {w}x{h} but {first}'s is {fw}x{fh}: one camera, one image size"
                    ),
                });
            }
            Some(_) => {}
            None => size = Some((w, h, &v.name)),
        }
    }
    let (w, h, name) = size.unwrap_or((0, 0, ""));
    match (u32::try_from(w), u32::try_from(h)) {
        (Ok(w), Ok(h)) => Ok(ImageSize::new(w, h)),
        _ => Err(CalibError::Frame {
            frame: name.to_owned(),
            reason: format!("the {which} image is {w}x{h}: a side must fit in u32"),
        }),
    }
}

/// Calibrates the two cameras of a binocular rig from board views taken by both at once:
/// detects the board in every image, calibrates each camera alone by Zhang's method on the
/// views it found the board in, starts `T_right_left` from the chordal mean of the per-view
/// relative poses, then refines both models, every pose and `T_right_left` jointly by
/// Levenberg–Marquardt over the views both cameras found the board in (as
/// `cv::stereoCalibrate` without fixed intrinsics).
///
/// # Errors
/// [`CalibError::Degenerate`] with fewer than 3 views whose board both cameras found (listing
/// the views left out and why), or boards that do not determine a camera;
/// [`CalibError::BoardNotFound`] naming the view and the camera when `skip_unusable_views` is
/// off; [`CalibError::Frame`] when a camera's images differ in size;
/// [`CalibError::InvalidParameter`] for a square size that is not a positive length.
///
/// See `tests/it/stereo_cameras.rs` for a run on the virtual rig's two cameras.
pub fn calibrate_stereo_cameras(
    views: &[StereoCameraView],
    cfg: &StereoCameraConfig,
) -> Result<StereoCameraCalibration, CalibError> {
    if !(cfg.square_mm.is_finite() && cfg.square_mm > 0.0) {
        return Err(CalibError::param(
            "square_mm",
            format!("{} is not a positive length", cfg.square_mm),
        ));
    }
    let left_size = camera_size(views, "left", |v| &v.left)?;
    let right_size = camera_size(views, "right", |v| &v.right)?;
    type Found = (Option<BoardCorners>, Option<BoardCorners>);
    let detected: Vec<Result<Found, CalibError>> = views
        .par_iter()
        .map(|v| {
            let mut found = [None, None];
            for (k, (image, which)) in [(&v.left, "left"), (&v.right, "right")]
                .into_iter()
                .enumerate()
            {
                let name = format!("{} ({which} camera)", v.name);
                match detect_checkerboard(image, cfg.board, &cfg.detector, &name) {
                    Ok(b) => found[k] = Some(b),
                    Err(e) if cfg.skip_unusable_views => {
                        if !matches!(e, CalibError::BoardNotFound { .. }) {
                            return Err(e);
                        }
                    }
                    Err(e) => return Err(e),
                }
            }
            let [l, r] = found;
            Ok((l, r))
        })
        .collect();
    let mut skipped_views = Vec::new();
    let mut found = Vec::with_capacity(views.len());
    for (v, d) in views.iter().zip(detected) {
        let (l, r) = d?;
        if l.is_none() || r.is_none() {
            let missing = match (&l, &r) {
                (None, None) => "neither camera",
                (None, Some(_)) => "the left camera",
                _ => "the right camera",
            };
            skipped_views.push(SkippedView {
                name: v.name.clone(),
                reason: format!("the board is not found by {missing}"),
            });
        }
        found.push((v.name.as_str(), l, r));
    }
    // Each camera alone, on every view it found the board in.
    let alone = |boards: Vec<&BoardCorners>, size: ImageSize, config: &ZhangConfig, which: &str| {
        if boards.len() < MIN_VIEWS {
            return Err(too_few(boards.len(), &skipped_views, which));
        }
        let own: Vec<CalibrationView> = boards
            .into_iter()
            .map(|b| CalibrationView::from_corners(b, cfg.square_mm))
            .collect();
        calibrate_camera(&own, size, config)
    };
    let left_boards = found.iter().filter_map(|f| f.1.as_ref()).collect();
    let left_alone = alone(left_boards, left_size, &cfg.left, "the left camera")?;
    let right_boards = found.iter().filter_map(|f| f.2.as_ref()).collect();
    let right_alone = alone(right_boards, right_size, &cfg.right, "the right camera")?;
    // The views both found, with each camera's own pose of them.
    let mut both = Vec::new();
    let (mut li, mut ri) = (0usize, 0usize);
    for (name, l, r) in &found {
        if let (Some(l), Some(r)) = (l, r) {
            both.push((*name, l, r, left_alone.poses[li], right_alone.poses[ri]));
        }
        li += usize::from(l.is_some());
        ri += usize::from(r.is_some());
    }
    if both.len() < MIN_VIEWS {
        return Err(too_few(both.len(), &skipped_views, "the pair"));
    }
    let start_extrinsics = mean_relative_pose(
        both.iter()
            .map(|b| b.4.to_isometry() * b.3.to_isometry().inverse()),
        "left-to-right camera",
    )?;
    let object = cfg.board.object_points(cfg.square_mm);
    let right_points: Vec<Vec<Option<Point2<f64>>>> = both
        .iter()
        .map(|b| b.2.corners.iter().copied().map(Some).collect())
        .collect();
    let stereo_views: Vec<StereoView<'_>> = both
        .iter()
        .zip(&right_points)
        .map(|(b, rp)| StereoView {
            object: &object,
            camera: &b.1.corners,
            projector: rp,
        })
        .collect();
    let sol = refine_stereo(
        &stereo_views,
        &StereoStart {
            camera: left_alone.camera,
            projector: right_alone.camera,
            extrinsics: start_extrinsics,
            poses: both.iter().map(|b| b.3).collect(),
        },
        &StereoOptions {
            camera: &cfg.left,
            projector: &cfg.right,
            max_iterations: cfg.max_iterations,
            tolerance: cfg.tolerance,
        },
    )?;
    let (left, right, rms_stereo) = joint_calibrations(&sol);
    let views_report = both
        .iter()
        .enumerate()
        .map(|(k, b)| StereoCameraViewReport {
            name: b.0.to_owned(),
            left_rms: left.view_rms.get(k).copied().unwrap_or(0.0),
            right_rms: right.view_rms.get(k).copied().unwrap_or(0.0),
        })
        .collect();
    let t_right_left = sol.extrinsics.to_isometry();
    Ok(StereoCameraCalibration {
        left,
        right,
        t_left_right: t_right_left.inverse(),
        t_right_left_std_dev: sol.extrinsics_std,
        rms_left: left_alone.rms,
        rms_right: right_alone.rms,
        rms_stereo,
        views: views_report,
        skipped_views,
        iterations: sol.iterations,
    })
}

/// Too few usable views for `what`, with the views left out and why.
fn too_few(used: usize, skipped: &[SkippedView], what: &str) -> CalibError {
    let mut msg = format!(
        "{used} usable view(s) for {what}: capture at least {MIN_VIEWS} board poses (10–20 is better) that both cameras see whole, tilted by 10–40° in different directions"
    );
    for s in skipped {
        msg.push_str(&format!("; {} left out: {}", s.name, s.reason));
    }
    CalibError::Degenerate(msg)
}
