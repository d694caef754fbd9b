//! Leave-one-view-out reprojection error: a check of corners that a calibration cannot absorb
//! into its own parameters (shared by `real_chessboard.rs` and `real_kamino.rs`).

use sl_calib::sl_camera::ImageSize;
use sl_calib::{CalibrationView, ZhangConfig, board_pose, calibrate_camera};

/// For each view: calibrate on the others (5 coefficients), fit the pose of the left-out view
/// with those intrinsics held (`board_pose`), project its board points; the RMS of all those
/// residuals pooled (px), and the RMS of each left-out view.
pub(crate) fn held_out_rms(views: &[CalibrationView], size: ImageSize) -> (f64, Vec<f64>) {
    let mut total = 0.0;
    let mut count = 0usize;
    let mut per_view = Vec::with_capacity(views.len());
    for i in 0..views.len() {
        let rest: Vec<CalibrationView> = views
            .iter()
            .enumerate()
            .filter(|&(k, _)| k != i)
            .map(|(_, v)| v.clone())
            .collect();
        let calib = calibrate_camera(&rest, size, &ZhangConfig::default())
            .unwrap_or_else(|e| panic!("calibration without view {i}: {e}"));
        let view = &views[i];
        let pose = board_pose(&calib.camera, view, &format!("view {i}"))
            .unwrap_or_else(|e| panic!("pose of view {i}: {e}"));
        let mut sum = 0.0;
        for (p, px) in view.object_points.iter().zip(&view.image_points) {
            let proj = calib
                .camera
                .project(&(pose * p))
                .unwrap_or_else(|| panic!("view {i}: a board point does not project"));
            sum += (proj - px).norm_squared();
        }
        total += sum;
        count += view.image_points.len();
        per_view.push((sum / view.image_points.len() as f64).sqrt());
    }
    ((total / count as f64).sqrt(), per_view)
}
