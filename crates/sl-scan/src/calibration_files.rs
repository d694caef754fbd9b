//! The files of a calibration session: its folders and their names, the pattern sequence and
//! turntable angles of a capture, the `board.json` each capture folder holds, and what an
//! interrupted capture leaves behind.
//!
//! ```text
//! SESSION/board/pose_NNN/      white.png, the pattern frames, manifest.json, board.json
//! SESSION/turntable/angle_NNN/ the same, board.json holding motor_angle_deg
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};
use sl_calib::sl_camera::ImageSize;
use sl_calib::sl_codec::{Axis, HybridSpec, MANIFEST_FILE, Pattern, PatternSequence};

use crate::{CalibrationCaptureConfig, CaptureError};

/// Folder of the hand-held poses inside a session.
pub const BOARD_DIR: &str = "board";
/// Folder of the turntable views inside a session.
pub const TURNTABLE_DIR: &str = "turntable";
/// The board under full white in each capture folder (what corner detection reads).
pub const WHITE_IMAGE: &str = "white.png";
/// The per-folder description of the board and the motor angle.
pub const BOARD_FILE: &str = "board.json";

/// Prefix of a pose folder being written; renamed to `pose_NNN` when complete.
pub(crate) const PARTIAL_PREFIX: &str = ".partial_";

/// Folder name of hand-held pose `k`.
pub fn pose_dir_name(k: usize) -> String {
    format!("pose_{k:03}")
}

/// Folder name of turntable view `k`.
pub fn angle_dir_name(k: usize) -> String {
    format!("angle_{k:03}")
}

/// `count` motor angles spread evenly over −45° … 45° (0 for one): the turntable views of a
/// calibration session, as `slscan simulate --scene board` takes them for 7 (15° apart).
pub fn calibration_turntable_angles(count: usize) -> Vec<f64> {
    match count {
        0 => Vec::new(),
        1 => vec![0.0],
        n => (0..n)
            .map(|k| -45.0 + 90.0 * k as f64 / (n - 1) as f64)
            .collect(),
    }
}

/// Projector periods across the image of the calibration code: 30 periods (64 projector px on
/// a 1920 px projector) decode robustly on a board seen at an angle.
const CALIBRATION_PERIODS: f64 = 30.0;
/// Phase steps of the calibration code (4: 8 halve the phase noise for twice the frames).
const CALIBRATION_PHASE_STEPS: u32 = 4;

/// The default pattern sequence of a calibration capture: the complementary hybrid code on
/// the projector columns, then on its rows (the projector calibration needs both), 4 phase
/// steps, 30 periods across — as `slscan scan` calibrates the virtual rig.
pub fn calibration_patterns(projector: ImageSize) -> PatternSequence {
    let code = |axis, extent: u32| {
        Pattern::Hybrid(HybridSpec::complementary(
            axis,
            projector,
            CALIBRATION_PHASE_STEPS,
            f64::from(extent) / CALIBRATION_PERIODS,
        ))
    };
    PatternSequence::new(projector)
        .with(code(Axis::Column, projector.width))
        .with(code(Axis::Row, projector.height))
}

/// The `board.json` of a capture folder: what `slscan calibrate` reads (`motor_angle_deg`)
/// and what a resumed capture needs (the detected corners).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct BoardFile {
    pub(crate) board: BoardJson,
    pub(crate) motor_angle_deg: f64,
    /// Detected inner corners `[x, y]` (px), row by row; empty when the board was not found.
    pub(crate) detected_corners_px: Vec<[f64; 2]>,
    /// Fraction of the board's pixels saturated under white.
    pub(crate) saturated_fraction: f64,
    /// Median edge width (px).
    pub(crate) edge_width_px: Option<f64>,
}

/// The board as `board.json` names it (the keys `slscan simulate` writes for its board).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub(crate) struct BoardJson {
    pub(crate) inner_cols: u32,
    pub(crate) inner_rows: u32,
    pub(crate) square_mm: f64,
}

impl BoardJson {
    pub(crate) fn of(config: &CalibrationCaptureConfig) -> Self {
        Self {
            inner_cols: config.board.cols,
            inner_rows: config.board.rows,
            square_mm: config.square_mm,
        }
    }
}

/// The `board.json` of a complete capture folder (white frame, manifest and board file);
/// `None` when the folder is missing or incomplete.
pub(crate) fn complete_folder(dir: &Path) -> Result<Option<BoardFile>, CaptureError> {
    let file = dir.join(BOARD_FILE);
    if !(dir.join(WHITE_IMAGE).is_file() && dir.join(MANIFEST_FILE).is_file() && file.is_file()) {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&file).map_err(|e| CaptureError::io(&file, e))?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| CaptureError::BadFile {
            path: file,
            reason: e.to_string(),
        })
}

/// Removes the hidden half-written folders an interrupted run left in `dir`.
pub(crate) fn remove_partials(dir: &Path) -> Result<(), CaptureError> {
    for e in std::fs::read_dir(dir)
        .map_err(|e| CaptureError::io(dir, e))?
        .filter_map(Result::ok)
    {
        if e.file_name().to_string_lossy().starts_with(PARTIAL_PREFIX) {
            let p = e.path();
            std::fs::remove_dir_all(&p).map_err(|e| CaptureError::io(&p, e))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turntable_angles_span_ninety_degrees() {
        assert_eq!(
            calibration_turntable_angles(7),
            [-45.0, -30.0, -15.0, 0.0, 15.0, 30.0, 45.0]
        );
        assert_eq!(calibration_turntable_angles(1), [0.0]);
        assert!(calibration_turntable_angles(0).is_empty());
    }
}
