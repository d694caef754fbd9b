//! The structured-light scan pipeline as a library: each stage is a function over session folders
//! and `sl-rig`'s device traits (capture a calibration session, calibrate, capture a scan session,
//! reconstruct the views, merge, measure), one path for the virtual and the real rig.
//!
//! The stages are being moved here from the facade package (issue 14).
#![deny(missing_docs)]

mod calibration_capture;
mod calibration_coverage;
mod pose_quality;
mod virtual_board;

pub use calibration_capture::{
    AutoConfig, AutoEvent, BOARD_DIR, BOARD_FILE, BoardMover, CalibrationCapture,
    CalibrationCaptureConfig, CaptureError, HandHeld, PoseCheck, PoseGates, PoseRecord, Refusal,
    TURNTABLE_DIR, TableView, TakeOutcome, WHITE_IMAGE, angle_dir_name, calibration_patterns,
    calibration_turntable_angles, capture_poses_auto, pose_dir_name, wait_for_still_board,
};
pub use calibration_coverage::{
    COVERAGE_COLS, COVERAGE_ROWS, Coverage, FLAT_TILT_DEG, TILT_NAMES, tilt_class,
};
pub use pose_quality::{
    BoardGeometry, NOMINAL_FOCAL_PER_WIDTH, SATURATION_LEVEL, board_outline, edge_width_px,
    nominal_camera, saturated_fraction,
};
pub use virtual_board::{
    BoardCamera, BoardPlacement, BoardProjector, BoardTurntable, VirtualBoardMover, VirtualBoardRig,
};
