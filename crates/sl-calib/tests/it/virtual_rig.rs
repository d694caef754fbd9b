//! Detection and Zhang's calibration on boards rendered by the virtual rig, against the
//! rig's ground truth (corner pixels and camera model).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use nalgebra::Point2;
use sl_calib::sl_codec::Frame;
use sl_calib::{
    BoardSize, CalibrationView, DetectorConfig, ZhangConfig, calibrate_camera, detect_checkerboard,
};
use sl_sim::{CalibrationCaptures, CalibrationSession, RigConfig, Scene, VirtualRig};

/// Electrons per grey level of the default sensor (10 000 e⁻ full well over 255 levels):
/// read noise of this many electrons is 1 grey level, the noise the target names.
const ONE_GREY_LEVEL_E: f64 = 10_000.0 / 255.0;

struct Rendered {
    images: Vec<Frame<u8>>,
    truth: Vec<Vec<Point2<f64>>>,
    config: RigConfig,
}

fn render(count: usize, seed: u64) -> Rendered {
    let mut config = RigConfig::default();
    config.render.effects.sensor.photon_noise = false;
    config.render.effects.sensor.read_noise_electrons = ONE_GREY_LEVEL_E;
    let rig = VirtualRig::new(config.clone(), Scene::sphere()).unwrap();
    let session = CalibrationSession::with_poses(count, seed);
    let captures = CalibrationCaptures::new(&rig, &session).unwrap();
    let mut images = Vec::new();
    let mut truth = Vec::new();
    for k in 0..captures.poses().len() {
        let cap = captures.hand_held(k, None).unwrap();
        images.push(cap.white.into_u8());
        truth.push(cap.board.corners_px.iter().map(|c| c.unwrap()).collect());
    }
    Rendered {
        images,
        truth,
        config,
    }
}

#[test]
fn corners_match_the_truth_in_board_order_and_calibrate_the_camera() {
    let r = render(8, 3);
    let size = BoardSize::new(9, 6);
    let mut views = Vec::new();
    let mut sum = 0.0;
    let mut n = 0usize;
    let mut worst: f64 = 0.0;
    for (k, (img, truth)) in r.images.iter().zip(&r.truth).enumerate() {
        let found =
            detect_checkerboard(img, size, &DetectorConfig::default(), &format!("view {k}"))
                .unwrap();
        for (p, t) in found.corners.iter().zip(truth) {
            // Same order as the board's corners: a wrong order gives errors of whole squares.
            let e = (p - t).norm();
            sum += e;
            n += 1;
            worst = worst.max(e);
        }
        views.push(CalibrationView::from_corners(&found, 20.0));
    }
    let mean = sum / n as f64;
    eprintln!("virtual rig: mean corner error {mean:.4} px, worst {worst:.4} px over {n} corners");
    // The target: mean error <= 0.05 px with 1 grey level of noise.
    assert!(mean <= 0.05, "mean corner error {mean} px");
    assert!(worst < 0.3, "worst corner error {worst} px");

    let calib = calibrate_camera(&views, r.config.camera.size, &ZhangConfig::default()).unwrap();
    let t = r.config.camera.intrinsics;
    let e = calib.camera.intrinsics;
    eprintln!(
        "zhang on rig: rms {:.4} px, fx {:.3} (truth {}), fy {:.3} ({}), cx {:.3} ({}), cy {:.3} ({}), std fx {:.3}",
        calib.rms, e.fx, t.fx, e.fy, t.fy, e.cx, t.cx, e.cy, t.cy, calib.std_dev.intrinsics[0]
    );
    // Corner noise of ~0.05 px over 8 views: focal lengths to 0.5 %, principal point to a
    // few pixels (bounds several times the reported standard deviations).
    assert!((e.fx / t.fx - 1.0).abs() < 5e-3);
    assert!((e.fy / t.fy - 1.0).abs() < 5e-3);
    assert!((e.cx - t.cx).abs() < 5.0 && (e.cy - t.cy).abs() < 5.0);
    // The residual is the corner noise: RMS of the same order as the detection error.
    assert!(calib.rms < 0.1, "rms {}", calib.rms);
}
