//! The structured-light scan pipeline as a library: each stage is a function over session folders
//! and `sl-rig`'s device traits (capture a calibration session, calibrate, capture a scan session,
//! reconstruct the views, merge, measure, report), one path for the virtual and the real rig.
//!
//! | stage | file | entry points |
//! |---|---|---|
//! | capture a calibration session | `calibration_capture.rs`, `calibration_auto.rs`, `pose_gates.rs`, `calibration_files.rs` (the session's folders and `board.json`) | [`CalibrationCapture`], [`capture_poses_auto`] |
//! | calibrate | `calibrate.rs` | [`calibrate_virtual`], [`load_scan_calibration`] |
//! | read a calibration session (own or another program's layout) | `calibration_layout.rs` | [`CalibrationLayout`], [`PoseCapture`] |
//! | calibrate from files (a session folder, board pictures) | `session_calibration.rs`, `stereo_calibration.rs` | [`calibrate_session`], [`calibrate_camera_files`], [`calibrate_procam_files`], [`calibrate_turntable_files`], two cameras: [`calibrate_stereo_files`] |
//! | measure the projector's response (a grey ramp) | `response.rs` | [`capture_ramp`], [`measure_ramp_folder`], [`capture_virtual_ramp`] |
//! | capture a scan session | `capture.rs` | [`capture_session`], [`scan_patterns`], [`full_turn_motor_angles`] |
//! | reconstruct the views | `reconstruct.rs` | [`reconstruct_session`], [`reconstruct_view_eroded`], [`reconstruct_decoded`], [`drop_grazing`]; two cameras: [`reconstruct_binocular_session`], [`reconstruct_binocular_view`] |
//! | merge | `merge.rs` | [`merge_scan`] |
//! | several placements | `placements.rs`, `virtual_placements.rs` | [`capture_placements`], [`scan_placements`], [`merge_placements`], [`scan_virtual_placements`] |
//! | scan on devices (capture, reconstruct, merge, placements, mesh) | `device_scan.rs`, `virtual_object.rs` | [`scan_devices`], [`DeviceScanConfig`], [`ScanOperator`], [`capture_device_session`], two cameras: [`scan_binocular_devices`], [`capture_binocular_device_session`], [`VirtualObjectRig`] |
//! | measure (where a truth exists) | `measure.rs` | [`measure_scan`], [`scene_truth`], [`plate_truth`] |
//! | mesh a cloud (`slscan mesh`) | `mesh_chain.rs` | [`mesh_chain`], [`MeshChainConfig`] |
//! | output folders (staged, locked, inputs kept) | `output_folder.rs` | [`OutputFolder`], [`Inputs`] |
//! | report | `report.rs`, `run_report.rs` | [`write_scan_cloud`], [`write_heat_map`], [`write_summary_html`], [`RunReport`] |
//!
//! A scan on real devices is [`scan_devices`]: [`capture_device_session`] on the drivers (per
//! placement, a [`ScanOperator`] re-placing the object in between), [`scan_session`] or
//! [`scan_placements`] (reconstruct, then merge), [`write_scan_cloud`], the mesh. A scan on the virtual rig
//! ([`scan_virtual`]) runs the same capture, reconstruct, merge and report stages on
//! `sl-sim`'s virtual devices, and adds what only the virtual rig has: a calibration from
//! simulated board captures, its truth and the measure stage. `slscan scan` is a thin wrapper
//! around both. `examples/virtual_pipeline.rs` runs calibrate, capture, scan and mesh on the
//! virtual rig through this API alone; `sl_rig::with_devices` opens the real devices for
//! [`scan_devices`], which runs unchanged on the virtual rig's devices ([`VirtualObjectRig`]).
//!
//! ```no_run
//! use std::path::Path;
//! use sl_scan::{VirtualScanConfig, scan_virtual};
//! let cfg = VirtualScanConfig { views: 8, resolution_divisor: 2, ..Default::default() };
//! let result = scan_virtual(&cfg, Path::new("scan"), |_| {})?;
//! println!("{} points, {:?}", result.merged.len(), result.accuracy.summary());
//! # Ok::<(), sl_scan::ScanError>(())
//! ```
//!
//! # Features
//! - `sim` (default): the virtual rig (`sl-sim`): [`scan_virtual`], [`calibrate_virtual`],
//!   the virtual board and object rigs and the measure stage against the truth. Without it the
//!   crate runs on real devices and files only. Implies `mesh`.
//! - `mesh` (default): the mesh stage and chain (`sl-mesh`: screened Poisson, simplification,
//!   fairing; faer and parry3d with it): [`mesh_chain`], [`mesh_stage_with`], the mesh of
//!   [`scan_devices`]. Without `sim` and `mesh`, sl-scan brings 90 packages instead of 135.
#![deny(missing_docs)]
#![cfg_attr(docsrs, feature(doc_cfg))]

mod align_scans;
mod binocular_reconstruction;
mod calibrate;
mod calibration_layout;
mod capture;
mod capture_reconstruction;
mod colour;
mod device_scan;
mod error;
mod exposures;
#[cfg(feature = "sim")]
mod measure;
mod merge;
#[cfg(feature = "mesh")]
mod mesh;
#[cfg(feature = "mesh")]
mod mesh_chain;
pub mod output_folder;
mod placements;
mod progress;
mod reconstruct;
mod report;
mod response;
mod run_report;
mod scan_records;
mod session_calibration;
mod session_scan;
mod stereo_calibration;
mod view_files;
#[cfg(feature = "sim")]
mod virtual_calibrate;
#[cfg(feature = "sim")]
mod virtual_object;
#[cfg(feature = "sim")]
mod virtual_placements;
#[cfg(feature = "sim")]
mod virtual_scan;

mod calibration_auto;
mod calibration_capture;
mod calibration_coverage;
mod calibration_files;
mod pose_gates;
mod pose_quality;
#[cfg(feature = "sim")]
mod virtual_board;

pub use align_scans::{
    CombinedScans, SCAN_PALETTE, combine_aligned, multiway_config_at, multiway_figures,
};
pub use calibration_auto::{
    AutoConfig, AutoEvent, BoardMover, HandHeld, capture_poses_auto, capture_poses_auto_with,
    wait_for_still_board,
};
pub use calibration_capture::{
    CalibrationCapture, CalibrationCaptureConfig, CaptureError, PoseRecord, TableView, TakeOutcome,
};
pub use calibration_coverage::{
    COVERAGE_COLS, COVERAGE_ROWS, Coverage, FLAT_TILT_DEG, TILT_NAMES, tilt_class,
};
pub use calibration_files::{
    BOARD_DIR, BOARD_FILE, TURNTABLE_DIR, WHITE_IMAGE, angle_dir_name, calibration_patterns,
    calibration_turntable_angles, pose_dir_name,
};
pub use calibration_layout::{
    CalibrationLayout, LAYOUT_FORMAT, LAYOUT_VERSION, LayoutError, MIN_POSES, PoseCapture,
    PoseView, check_pose_files, default_turntable_dir, projector_size,
};
pub use pose_gates::{PoseCheck, PoseGates, Refusal};
pub use pose_quality::{
    BoardGeometry, NOMINAL_FOCAL_PER_WIDTH, SATURATION_LEVEL, board_outline, edge_width_px,
    nominal_camera, saturated_fraction,
};
#[cfg(feature = "sim")]
pub use response::capture_virtual_ramp;
pub use response::{
    RAMP_FILE, RAMP_FORMAT, RESPONSE_DIR, RESPONSE_FILE, RampConfig, RampFile, ResponseFiles,
    ResponseSummary, capture_ramp, measure_ramp_folder, response_phase_error, write_response_files,
};
#[cfg(feature = "sim")]
pub use virtual_board::{
    BoardCamera, BoardPlacement, BoardProjector, BoardRightCamera, BoardTurntable,
    VirtualBoardMover, VirtualBoardRig,
};

pub use binocular_reconstruction::{BinocularReconstruction, reconstruct_binocular_capture};
pub use calibrate::{load_scan_calibration, require_turntable_axis};
pub use capture::{
    SCAN_PERIOD_PX, SCAN_PHASE_STEPS, capture_binocular_session, capture_session,
    full_turn_motor_angles, scan_patterns, scan_patterns_with,
};
pub use capture_reconstruction::{
    CaptureDecoding, CaptureReconstruction, CaptureReconstructionConfig, decode_capture,
    reconstruct_capture,
};
pub use colour::{
    ColourAccuracy, ColourConfig, ColourMode, ColourView, ScanColours, UNSEEN_COLOUR,
    colour_accuracy, placed_colours,
};
pub use device_scan::{
    AUTO_EXPOSURE_START_MS, DeviceCaptureConfig, DevicePlacement, DeviceScan, DeviceScanConfig,
    ScanOperator, SessionCapture, capture_binocular_device_session, capture_device_session,
    scan_binocular_devices, scan_devices,
};
pub use error::ScanError;
pub use exposures::{Exposures, fuse_exposure_folder};
#[cfg(feature = "sim")]
pub use measure::{
    Measurements, PLATE_SIZE_MM, PLATE_TILT_DEG, SELECT_MM, measure_scan, plate_pose, plate_scene,
    plate_truth, scene_truth,
};
pub use merge::{
    MergeReport, MergeStageConfig, MergedViews, ViewPoseReport, alignment_figures,
    largest_pose_correction_deg, merge_scan, pair_figures,
};
#[cfg(feature = "mesh")]
pub use mesh::{
    MESH_CELL_PER_SPACING, MeshColourSummary, MeshConfig, MeshFiles, MeshOutputs, MeshSummary,
    mesh_stage, mesh_stage_coloured, mesh_stage_with, scan_poisson_config, write_mesh_pictures,
};
#[cfg(feature = "mesh")]
pub use mesh_chain::{
    COLOUR_NEIGHBOURS, FarPointsDropped, MeshChain, MeshChainConfig, MeshSmoothing, mesh_chain,
};
pub use output_folder::{Inputs, OutputError, OutputFolder};
pub use placements::{
    MAX_PLACEMENTS, PLACEMENT_SESSION_DIR, PlacementAlignment, PlacementConfig, PlacementRig,
    PlacementsMerge, PlacementsScan, align_placement, capture_placements, check_placements,
    merge_placements, placement_dir_name, scan_placements,
};
pub use progress::{ScanProgress, StageTime};
pub use reconstruct::{
    ReconstructConfig, ReconstructedViews, drop_grazing, reconstruct_binocular_session,
    reconstruct_binocular_view, reconstruct_decoded, reconstruct_decoded_coloured,
    reconstruct_session, reconstruct_view, reconstruct_view_coloured, reconstruct_view_eroded,
};
#[cfg(feature = "sim")]
pub use report::write_summary_html;
pub use report::{SessionScanFiles, write_heat_map, write_scan_cloud};
pub use run_report::{RunReport, write_atomically};
pub use scan_records::{REPLACE_PROMPT, TerminalOperator, stage_lines, watertight_word};
pub use session_calibration::{
    CalibrationFilesConfig, CameraFiles, ProcamFiles, SessionCalibration, SkippedImage,
    TurntableFiles, calibrate_camera_files, calibrate_procam_files, calibrate_session,
    calibrate_turntable_files, camera_images, layout_white_frames, session_poses,
    session_projector_size, turntable_views,
};
pub use session_scan::{
    ScanCalibration, SessionScan, SessionScanConfig, scan_binocular_session, scan_session,
};
pub use stereo_calibration::{STEREO_FILE, StereoFiles, calibrate_stereo_files};
pub use view_files::{
    CloudRegistration, TRANSFORM_FILE, ViewsMerge, merge_and_write, read_transform,
    register_and_write, write_preview_png,
};
#[cfg(feature = "sim")]
pub use virtual_calibrate::{CalibrationSummary, calibrate_virtual, calibrate_virtual_binocular};
#[cfg(feature = "sim")]
pub use virtual_object::{ObjectCamera, ObjectProjector, ObjectTurntable, VirtualObjectRig};
#[cfg(feature = "sim")]
pub use virtual_placements::{
    PlacementFigures, PlacementsResult, TRUTH_MESH_FILE, scan_virtual_placements,
};
#[cfg(feature = "sim")]
pub use virtual_scan::{
    COLOUR_TRUTH_DISTANCE_MM, PhaseError, ResponseCorrection, ScanColourReport, ScanFiles,
    ScanResult, VirtualScanConfig, scaled_rig_config, scan_virtual,
};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
