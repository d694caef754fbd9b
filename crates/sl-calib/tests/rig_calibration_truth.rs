//! The projector–camera calibration of `slscan scan` (seed 0: the same rig, board, poses,
//! noise keys and 4-step hybrid patterns on both axes as `sl_scan::calibrate_virtual`) against
//! the true rig, in 3-D: the true board corners seen through the true camera and projector,
//! triangulated with the estimated models and `T_cam_proj`. This is what the scan's accuracy
//! follows; corner errors alone do not show it (the junction fit's corners are closer to the
//! truth, its calibration reconstructs further from it).
//!
//! 29 s in a debug build (12 poses × 42 frames of 1280×720 rendered and decoded, two
//! calibrations), 20 s in release, on the loaded 2-core machine.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use nalgebra::Point3;
use sl_calib::{
    BoardSize, DetectorConfig, ProcamCalibration, ProcamConfig, ProcamView, calibrate_procam,
    sl_camera::ImageSize,
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
    let default = rig_error_mm(&config, &procam(DetectorConfig::default()), &truth);
    let junction = rig_error_mm(
        &config,
        &procam(DetectorConfig::with_junction_fit()),
        &truth,
    );
    eprintln!(
        "3-D error of the estimated rig on the true board corners: default (saddle points) {default:.4} mm, junction fit {junction:.4} mm"
    );
    // Measured over seeds 0–3 of the scan: 0.072–0.128 mm from the saddle points, 0.109–0.169
    // mm from the junction fit (0.105 against 0.159 mm on this seed, the one of the default
    // scan whose probing form doubled with the junction fit). 0.13 mm fails on the junction
    // fit's calibration of this seed and on any default that calibrates as badly.
    assert!(default < 0.13, "default: {default} mm");
    assert!(
        default < junction,
        "default {default} mm, junction fit {junction} mm"
    );
}
