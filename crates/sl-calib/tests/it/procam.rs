//! Projector–camera calibration on boards rendered by the virtual rig with every pattern
//! projected on them, decoded by sl-codec, against the rig's truth (models, `T_cam_proj`,
//! corners in the projector image).
//!
//! Rendering ~45 frames of 1280×720 per board pose is slow in debug builds: the rig tests are
//! `#[ignore]`d there and run with
//! `cargo test --release -p sl-calib --test it procam -- --nocapture`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use std::time::Instant;

use procam_render::render;
use sl_calib::sl_codec::Frame;
use sl_calib::{
    BoardCorners, BoardSize, CalibError, ProcamConfig, calibrate_procam, projector_corners,
    sl_camera::ImageSize,
};
use sl_sim::{Checkerboard, RigConfig};

use crate::support::procam_render;

#[derive(Default)]
struct Stats {
    sum: f64,
    max: f64,
    n: usize,
}

impl Stats {
    fn add(&mut self, e: f64) {
        self.sum += e;
        self.max = self.max.max(e);
        self.n += 1;
    }
    fn mean(&self) -> f64 {
        self.sum / self.n.max(1) as f64
    }
}

fn rig_config() -> ProcamConfig {
    let rig = RigConfig::default();
    let board = Checkerboard::default();
    ProcamConfig::new(
        BoardSize::new(board.inner_cols, board.inner_rows),
        board.square_mm,
        ImageSize::new(rig.projector.size.width, rig.projector.size.height),
    )
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow in debug builds; run with --release")]
fn rig_calibration_recovers_the_truth() {
    let r = render(10, 5);
    let t0 = Instant::now();
    let c = calibrate_procam(&r.views, &rig_config()).unwrap();
    eprintln!(
        "calibrate_procam: {:.1} ms",
        t0.elapsed().as_secs_f64() * 1e3
    );
    assert!(c.skipped_views.is_empty(), "{:?}", c.skipped_views);

    // Projector corners against the truth, end to end (detected camera corners mapped) and
    // the mapping alone (the true camera corners mapped through the same decoded maps).
    let mut end = Stats::default();
    let mut alone = Stats::default();
    let mut skipped = 0usize;
    let hcfg = rig_config().homography;
    for ((v, t), view) in c.views.iter().zip(&r.truth).zip(&r.views) {
        skipped += v.projector_corners.skipped.len();
        let true_cam = BoardCorners {
            size: rig_config().board,
            corners: t.corners_px.iter().map(|q| q.unwrap()).collect(),
        };
        let mapped = projector_corners(&true_cam, &view.map, &hcfg, &view.name).unwrap();
        for ((f, g), q) in v
            .projector_corners
            .fits
            .iter()
            .zip(&mapped.fits)
            .zip(&t.corners_projector)
        {
            let q = q.unwrap();
            if let Some(f) = f {
                end.add((f.projector - q).norm());
            }
            if let Some(g) = g {
                alone.add((g.projector - q).norm());
            }
        }
    }
    eprintln!(
        "projector corners: {} mapped, {skipped} skipped; error vs truth: end to end mean {:.4} px, max {:.4} px; mapping alone mean {:.4} px, max {:.4} px",
        end.n,
        end.mean(),
        end.max,
        alone.mean(),
        alone.max
    );

    let report =
        |what: &str, e: &sl_calib::sl_camera::CameraModel, t: &sl_calib::sl_camera::CameraModel| {
            let (e, t) = (e.intrinsics, t.intrinsics);
            eprintln!(
                "{what}: fx {:.3} (truth {}), fy {:.3} ({}), cx {:.3} ({}), cy {:.3} ({})",
                e.fx, t.fx, e.fy, t.fy, e.cx, t.cx, e.cy, t.cy
            );
            // The targets: focal lengths within 0.1 %, principal point within 0.5 px.
            assert!((e.fx / t.fx - 1.0).abs() < 1e-3, "{what} fx");
            assert!((e.fy / t.fy - 1.0).abs() < 1e-3, "{what} fy");
            assert!((e.cx - t.cx).abs() < 0.5, "{what} cx");
            assert!((e.cy - t.cy).abs() < 0.5, "{what} cy");
        };
    report("camera", &c.camera.camera, &r.config.camera);
    report("projector", &c.projector.camera, &r.config.projector);
    let dt = (c.t_cam_proj.translation.vector - r.config.t_cam_proj.translation.vector).norm();
    let dr = c
        .t_cam_proj
        .rotation
        .angle_to(&r.config.t_cam_proj.rotation)
        .to_degrees();
    eprintln!(
        "T_cam_proj: translation error {dt:.4} mm, rotation error {dr:.5} deg; σ(tvec) {:?}",
        &c.t_proj_cam_std_dev[3..]
    );
    eprintln!(
        "RMS camera {:.4} px, projector {:.4} px, stereo {:.4} px (joint: camera {:.4}, projector {:.4}), {} iterations",
        c.rms_camera, c.rms_projector, c.rms_stereo, c.camera.rms, c.projector.rms, c.iterations
    );
    // The target: extrinsic translation within 0.1 mm.
    assert!(dt < 0.1, "translation error {dt} mm");
    assert!(dr < 0.02, "rotation error {dr} deg");
    // At the noise floor: the corner noise (0.04 px camera, ~0.03 px projector) and no
    // model error; a wrong model or wrong correspondences give tenths of a pixel or more.
    assert!(c.rms_camera < 0.08, "camera rms {}", c.rms_camera);
    assert!(c.rms_projector < 0.08, "projector rms {}", c.rms_projector);
    assert!(c.rms_stereo < 0.08, "stereo rms {}", c.rms_stereo);
    // End to end, the camera corners' detection error (0.04 px mean, `tests/it/virtual_rig.rs`)
    // is scaled by the ~1.5 projector px per camera px; the mapping alone averages the
    // decoding noise (~0.1 projector px per pixel) over ~1500 pixels.
    assert!(
        end.mean() < 0.08,
        "mean projector corner error {}",
        end.mean()
    );
    assert!(end.max < 0.5, "worst projector corner error {}", end.max);
    assert!(alone.mean() < 0.03, "mean mapping error {}", alone.mean());
    assert!(alone.max < 0.15, "worst mapping error {}", alone.max);
    assert_eq!(skipped, 0);
    // The file content carries everything.
    let file = c.to_calibration();
    assert_eq!(file.rms.stereo, Some(c.rms_stereo));
    assert!(file.projector.is_some() && file.t_cam_proj.is_some());
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow in debug builds; run with --release")]
fn unusable_views_are_named() {
    let mut r = render(3, 9);
    // A view without a board.
    r.views[1].lit = Frame::filled(1280, 720, 128).unwrap();
    r.views[1].name = "blank wall".to_owned();
    let err = calibrate_procam(&r.views, &rig_config()).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, CalibError::Degenerate(_)), "{msg}");
    assert!(
        msg.contains("blank wall") && msg.contains("at least 3"),
        "{msg}"
    );
    let strict = ProcamConfig {
        skip_unusable_views: false,
        ..rig_config()
    };
    let err = calibrate_procam(&r.views, &strict).unwrap_err();
    assert!(
        matches!(&err, CalibError::BoardNotFound { image, .. } if image == "blank wall"),
        "{err}"
    );
    // A map of the wrong size names the view.
    r.views[2].map = sl_codec::CorrespondenceMap::new(10, 10);
    let err = calibrate_procam(&r.views, &rig_config()).unwrap_err();
    assert!(err.to_string().contains("pose 2"), "{err}");
}
