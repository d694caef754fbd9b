//! Calibration of a structured-light rig: checkerboard detection with sub-pixel saddle-point
//! refinement and a board-fixed corner order, and Zhang's camera calibration refined by
//! Levenberg–Marquardt with analytic Jacobians. Projector–camera calibration
//! ([`calibrate_procam`], Moreno & Taubin): corners mapped into the projector by local
//! homographies of the decoded patterns ([`projector_corners`]), then both devices and
//! `T_cam_proj` refined jointly. The turntable axis ([`calibrate_turntable`]): a closed form
//! from the relative board poses at several motor angles, refined over every corner's
//! reprojection. The projector's response ([`measure_response`]) from a grey ramp's
//! captures, for the decoders' phase correction. Pictures of a calibration ([`draw_corners`], [`error_bars`],
//! [`residual_plot`]) for reports such as `slscan calibrate`'s.
//!
//! ```
//! use sl_calib::{BoardSize, DetectorConfig, detect_checkerboard};
//! use sl_calib::sl_codec::Frame;
//! // A synthetic 5x4 board of 16 px squares on a white page.
//! let (w, h) = (200, 180);
//! let pixels = (0..w * h).map(|k| {
//!     let (x, y) = ((k % w) as i32, (k / w) as i32);
//!     let (i, j) = ((x - 40).div_euclid(16), (y - 40).div_euclid(16));
//!     let inside = (0..6).contains(&i) && (0..5).contains(&j);
//!     if inside && (i + j) % 2 == 0 { 20 } else { 230 }
//! });
//! let img = Frame::new(w, h, pixels.collect())?;
//! let board = detect_checkerboard(&img, BoardSize::new(5, 4), &DetectorConfig::default(), "page")?;
//! assert_eq!(board.corners.len(), 20);
//! // Corner order is fixed by the board: first row first, left to right here.
//! assert!(board.corners[1].x > board.corners[0].x);
//! assert!(board.corners[5].y > board.corners[0].y);
//! # Ok::<(), sl_calib::CalibError>(())
//! ```
//!
//! # Conventions
//!
//! As `sl-camera`: axes x right, y down, z forward; pixel `(0, 0)` is the centre of the
//! top-left pixel; millimetres (or the board's unit) for 3-D points, pixels for image
//! points and RMS errors; poses `T_cam_board` map board coordinates into the camera frame;
//! f64 for all geometry. RMS errors follow OpenCV: the square root of the mean over corners
//! of the squared 2-D residual norm. The board frame is `sl-sim`'s: origin at the first
//! inner corner, x along a row, y along a column, z into the board.
#![deny(missing_docs)]

mod detect;
mod error;
mod grey;
mod homography;
mod junction;
mod lm;
mod local_homography;
#[cfg(feature = "pictures")]
mod pictures;
mod predicted;
mod procam;
mod response;
mod saddle;
mod stereo;
mod stereo_cameras;
mod turntable;
mod zhang;

pub use detect::{BoardCorners, BoardSize, CornerRefiner, DetectorConfig, detect_checkerboard};
pub use error::CalibError;
pub use grey::load_grey;
pub use local_homography::{
    CornerFit, LocalHomographyConfig, ProjectorCorners, SkippedCorner, projector_corners,
};
#[cfg(feature = "pictures")]
pub use pictures::{
    BAR, BarChart, FIRST_CORNER, OUTLIER_BAR, OUTLIER_FACTOR, PALETTE, PictureConfig, ResidualPlot,
    draw_corners, error_bars, residual_plot, save_png,
};
pub use predicted::{PREDICTED_BOUND_SIGMAS, PredictedError};
pub use procam::{
    ProcamCalibration, ProcamConfig, ProcamView, ProcamViewReport, SkippedView, calibrate_procam,
};
pub use response::{RESPONSE_LEVELS, ResponseMeasurement, measure_response, ramp_levels};
pub use stereo_cameras::{
    StereoCameraCalibration, StereoCameraConfig, StereoCameraView, StereoCameraViewReport,
    calibrate_stereo_cameras,
};
pub use turntable::{
    MIN_TURNTABLE_VIEWS, PoseAtAngle, TurntableCalibration, TurntableConfig, TurntableStdDev,
    TurntableView, board_pose, calibrate_turntable, fit_turntable_axis,
};
pub use zhang::{
    CalibrationView, CameraCalibration, ParameterStdDev, ZhangConfig, calibrate_camera,
};

/// Re-export of `sl-camera`, whose models the calibration produces.
pub use sl_camera;
/// Re-export of `sl-codec`, whose grey frames ([`sl_codec::Frame<u8>`]) the detector takes and
/// whose decoded maps the projector calibration takes.
pub use sl_codec;

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
