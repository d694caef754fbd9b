//! The projector–camera calibration of `slscan scan` (seed 0: the same rig, board, poses,
//! noise keys and 4-step hybrid patterns on both axes as `sl_scan::calibrate_virtual`) against
//! the true rig, in 3-D: the true board corners seen through the true camera and projector,
//! triangulated with the estimated models and `T_cam_proj`. This is what the scan's accuracy
//! follows, and the figure the calibration predicts for itself must cover it.
//!
//! 29 s in a debug build (12 poses × 42 frames of 1280×720 rendered and decoded, two
//! calibrations), 20 s in release, on the loaded 2-core machine.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use nalgebra::Point3;
use sl_calib::{
    BoardSize, CornerRefiner, DetectorConfig, ProcamCalibration, ProcamConfig, ProcamView,
    calibrate_procam, sl_camera::ImageSize,
};
use sl_codec::ProjectorSize;
use sl_sim::{BoardTruth, Checkerboard, RigConfig, Scene, calibration_sequence};

#[path = "support/procam_render.rs"]
mod procam_render;

/// The scan's hand-held calibration views (seed 0: 12 poses, 4-step hybrid code with 30 px
/// periods on both axes, the dumbbell scene) with their truth.
fn scan_views() -> (RigConfig, Vec<ProcamView>, Vec<BoardTruth>) {
    let mut config = RigConfig::default();
    config.render.seed = 0;
    let p = ProjectorSize::new(config.projector.size.width, config.projector.size.height);
    let sequence = calibration_sequence(p);
    let r = procam_render::render_with(config, Scene::dumbbell(), &sequence, 12, 0);
    (r.config, r.views, r.truth)
}

/// RMS (mm) of the 3-D error of the estimated rig `c` on the true corners of `truth`: each
/// corner projected by the true camera and projector, triangulated (midpoint of the two rays)
/// with the estimated ones.
fn rig_error_mm(config: &RigConfig, c: &ProcamCalibration, truth: &[BoardTruth]) -> f64 {
    let (mut sq, mut n) = (0.0, 0usize);
    for t in truth {
        for x in &t.corners_cam {
            let u = config.camera.project(x).unwrap();
            let v = config
                .projector
                .project(&config.t_cam_proj.inverse_transform_point(x))
                .unwrap();
            let d1 = c.camera.camera.unproject_ray(&u).unwrap().into_inner();
            let d2 =
                c.t_cam_proj.rotation * c.projector.camera.unproject_ray(&v).unwrap().into_inner();
            let (o1, o2) = (Point3::origin(), c.t_cam_proj * Point3::origin());
            let w = o1 - o2;
            let (a, b, cc, d, e) = (
                d1.dot(&d1),
                d1.dot(&d2),
                d2.dot(&d2),
                d1.dot(&w),
                d2.dot(&w),
            );
            let den = a * cc - b * b;
            let p = nalgebra::center(
                &(o1 + d1 * ((b * e - cc * d) / den)),
                &(o2 + d2 * ((a * e - b * d) / den)),
            );
            sq += (p - x).norm_squared();
            n += 1;
        }
    }
    (sq / n as f64).sqrt()
}

#[test]
fn scan_calibration_reconstructs_the_true_board() {
    let (config, views, truth) = scan_views();
    let board = Checkerboard::default();
    let procam = |detector: DetectorConfig| {
        let mut pc = ProcamConfig::new(
            BoardSize::new(board.inner_cols, board.inner_rows),
            board.square_mm,
            ImageSize::new(config.projector.size.width, config.projector.size.height),
        );
        pc.detector = detector;
        calibrate_procam(&views, &pc).unwrap()
    };
    let default_calibration = procam(DetectorConfig::default());
    let default = rig_error_mm(&config, &default_calibration, &truth);
    let saddle = rig_error_mm(
        &config,
        &procam(DetectorConfig::with_refiner(CornerRefiner::Saddle)),
        &truth,
    );
    eprintln!(
        "3-D error of the estimated rig on the true board corners: default (junction fit) {default:.4} mm, saddle points {saddle:.4} mm"
    );
    // Measured over seeds 0–7 of the scan (`rig_corner_truth --procam`): 0.006–0.026 mm from
    // the junction fit; 0.020–0.082 mm from the saddle points (0.0097 against 0.0815 mm on
    // this seed). Before the renderer integrated the board over each pixel, 0.105 (saddle) and
    // 0.159 mm (junction) here. 0.02 mm fails on the saddle points' calibration of this seed
    // and on any default that calibrates twice as badly as the junction fit does.
    assert!(default < 0.02, "default: {default} mm");
    assert!(
        default < saddle,
        "default {default} mm, saddle points {saddle} mm"
    );
    // The calibration's own prediction covers what it achieved (measured: ±0.059 mm 2σ, RMS
    // 0.030 mm predicted against 0.0097 mm achieved on this seed; seeds 0–7 all inside).
    let predicted = default_calibration.predicted_error.unwrap();
    assert!(
        default <= predicted.rms_mm,
        "achieved {default} mm, predicted RMS {} mm",
        predicted.rms_mm
    );
}
