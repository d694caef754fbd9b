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
use sl_sim::{BoardTruth, Checkerboard, RigConfig, Scene, calibration_sequence};

use crate::support::procam_render;

/// The scan's hand-held calibration views (seed 0: 12 poses, 4-step hybrid code with 30 px
/// periods on both axes, the dumbbell scene) with their truth.
fn scan_views() -> (RigConfig, Vec<ProcamView>, Vec<BoardTruth>) {
    let mut config = RigConfig::default();
    config.render.seed = 0;
    let p = ImageSize::new(config.projector.size.width, config.projector.size.height);
    let sequence = calibration_sequence(p);
    let r = procam_render::render_with(config, Scene::dumbbell(), &sequence, 12, 0);
    (r.config, r.views, r.truth)
}

/// RMS (mm) of the 3-D error of the estimated rig `c` on the true corners of `truth`: each
/// corner projected by the true camera and projector, triangulated (midpoint of the two rays)
/// with the estimated ones.
fn rig_error_mm(config: &RigConfig, c: &ProcamCalibration, truth: &[BoardTruth]) -> (f64, f64) {
    let (mut sq, mut n) = (0.0, 0usize);
    let mut pairs = Vec::new();
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
            pairs.push((p, *x));
        }
    }
    ((sq / n as f64).sqrt(), shape_error_mm(&pairs))
}

/// RMS distance (mm) between estimated and true points once the estimated ones are moved by
/// the rigid motion that fits them best (Kabsch): the error of shape.
fn shape_error_mm(pairs: &[(Point3<f64>, Point3<f64>)]) -> f64 {
    let n = pairs.len() as f64;
    let ca = pairs
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.0.coords)
        / n;
    let cb = pairs
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.1.coords)
        / n;
    let h = pairs.iter().fold(nalgebra::Matrix3::zeros(), |m, (a, b)| {
        m + (a.coords - ca) * (b.coords - cb).transpose()
    });
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = nalgebra::Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    let sq: f64 = pairs
        .iter()
        .map(|(a, b)| (r * (a.coords - ca) + cb - b.coords).norm_squared())
        .sum();
    (sq / n).sqrt()
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "a full simulation, minutes unoptimised: .ci/run runs it (step \"full simulations\")"
)]
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
    let (default, default_shape) = rig_error_mm(&config, &default_calibration, &truth);
    let (saddle, saddle_shape) = rig_error_mm(
        &config,
        &procam(DetectorConfig::with_refiner(CornerRefiner::Saddle)),
        &truth,
    );
    eprintln!(
        "3-D error of the estimated rig on the true board corners (camera frame / shape): default (junction fit) {default:.4} / {default_shape:.4} mm, saddle points {saddle:.4} / {saddle_shape:.4} mm"
    );
    // Measured on this seed: 0.0246 / 0.0021 mm from the junction fit, 0.199 / 0.0036 mm
    // from the saddle points (over seeds 0–7 the junction fit's are 0.0085–0.038 mm and
    // 0.0009–0.0022 mm). Before the renders integrated each pixel's area, 0.105 (saddle) and
    // 0.159 mm (junction fit) in the camera frame. 0.04 mm fails on the saddle points'
    // calibration of this seed.
    assert!(default < 0.04, "default: {default} mm");
    assert!(
        default < saddle,
        "default {default} mm, saddle points {saddle} mm"
    );
    assert!(
        default_shape < saddle_shape,
        "shape: default {default_shape} mm, saddle points {saddle_shape} mm"
    );
    // The calibration's own prediction (2σ) covers what it achieved, in shape and in the
    // camera frame (this seed: shape ±0.0032 mm, camera frame ±0.077 mm; seeds 0–7 all
    // inside, docs/performance.md).
    let predicted = default_calibration.predicted_error.unwrap();
    assert!(
        default_shape <= predicted.bound_mm,
        "shape: achieved {default_shape} mm, predicted ±{} mm",
        predicted.bound_mm
    );
    let absolute = sl_calib::PREDICTED_BOUND_SIGMAS * predicted.absolute_rms_mm;
    assert!(
        default <= absolute,
        "camera frame: achieved {default} mm, predicted ±{absolute} mm"
    );
}
