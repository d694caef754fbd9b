//! The checks a calibration file passes before a scan starts.

use std::path::Path;

use sl_camera::{Calibration, TurntableAxis};

use crate::ScanError;
use crate::error::stage_err;

/// The turntable axis of `calibration`, read from `path`; an error naming the file and the
/// command that adds the axis when it has none.
///
/// # Errors
/// [`ScanError::Stage`] (stage `calibration`) when the calibration has no turntable axis.
pub fn require_turntable_axis(
    calibration: &Calibration,
    path: &Path,
) -> Result<TurntableAxis, ScanError> {
    calibration.turntable.ok_or_else(|| {
        stage_err(
            "calibration",
            format!(
                "{}: no turntable axis: a turntable scan needs it to place the views; add it with `slscan calibrate turntable SESSION --calib {} --out DIR` (or calibrate everything with `slscan calibrate all`)",
                path.display(),
                path.display()
            ),
        )
    })
}

/// Loads a calibration file for a turntable scan and checks that it holds what a scan needs:
/// the camera, the projector with its pose, and the turntable axis.
///
/// # Errors
/// [`ScanError::Camera`] when the file cannot be read; [`ScanError::Stage`] naming the
/// file and what is missing otherwise.
pub fn load_scan_calibration(path: &Path) -> Result<Calibration, ScanError> {
    let calibration = Calibration::load(path)?;
    if calibration.projector.is_none() || calibration.t_cam_proj.is_none() {
        return Err(stage_err(
            "calibration",
            format!(
                "{}: no projector calibration: a scan needs the projector and its pose; calibrate them with `slscan calibrate projector` (or `slscan calibrate all`)",
                path.display()
            ),
        ));
    }
    require_turntable_axis(&calibration, path)?;
    Ok(calibration)
}
