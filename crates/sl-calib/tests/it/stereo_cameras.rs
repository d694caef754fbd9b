//! Two cameras calibrated from boards rendered by the virtual rig and its second camera, against
//! the rig's truth; and what a user can get wrong (too few views both see, images of different
//! sizes).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use sl_calib::{StereoCameraConfig, StereoCameraView, calibrate_stereo_cameras, sl_codec::Frame};
use sl_sim::{
    CalibrationCaptures, CalibrationSession, RigConfig, Scene, VirtualRig, capture_board,
};

/// `count` hand-held board poses of the default rig (noise: one grey level of read noise, no
/// photon noise), seen by its camera and by its default second camera.
fn render(count: usize, seed: u64) -> (Vec<StereoCameraView>, RigConfig) {
    let mut config = RigConfig::default();
    config.render.effects.sensor.photon_noise = false;
    config.render.effects.sensor.read_noise_electrons = 10_000.0 / 255.0;
    config.render.seed = seed;
    let second = config.default_second_camera();
    let left = VirtualRig::new(config.clone(), Scene::sphere()).unwrap();
    let right = VirtualRig::new(config.seen_from(&second), Scene::sphere()).unwrap();
    let session = CalibrationSession::with_poses(count, seed);
    let captures = CalibrationCaptures::new(&left, &session).unwrap();
    let t_second_cam = second.t_cam_second.inverse();
    let views = captures
        .poses()
        .iter()
        .enumerate()
        .map(|(k, pose)| StereoCameraView {
            name: format!("pose {k}"),
            left: captures.hand_held(k, None).unwrap().white.into_u8(),
            right: capture_board(
                &right,
                &session.board,
                &(t_second_cam * pose),
                None,
                k as u64,
            )
            .unwrap()
            .white
            .into_u8(),
        })
        .collect();
    (views, config)
}

/// Both cameras' models and the baseline come out of the renders as the rig has them: over
/// three seeds, focal lengths within 0.1 %, `T_left_right` within 0.5 mm and 0.02°, the
/// stereo RMS below 0.1 px. Measured (6 poses): see the printed figures and
/// `docs/binocular.md`.
#[test]
fn two_rendered_cameras_calibrate_to_the_rigs_truth() {
    for seed in [1, 2, 3] {
        let (views, config) = render(6, seed);
        let second = config.default_second_camera();
        let c = calibrate_stereo_cameras(&views, &StereoCameraConfig::default()).unwrap();
        let d = second.t_cam_second.inverse() * c.t_left_right;
        let (angle, shift) = (d.rotation.angle().to_degrees(), d.translation.vector.norm());
        let fx = |est: f64, truth: f64| 100.0 * (est - truth) / truth;
        let (fl, fr) = (
            fx(c.left.camera.intrinsics.fx, config.camera.intrinsics.fx),
            fx(c.right.camera.intrinsics.fx, second.camera.intrinsics.fx),
        );
        eprintln!(
            "seed {seed}: {} views, {} skipped; RMS left {:.4} right {:.4} stereo {:.4} px; fx {fl:+.4} % / {fr:+.4} %; T_left_right off by {angle:.4} deg, {shift:.3} mm",
            c.views.len(),
            c.skipped_views.len(),
            c.rms_left,
            c.rms_right,
            c.rms_stereo
        );
        assert!(c.views.len() >= 3);
        assert!(c.rms_stereo < 0.1, "{}", c.rms_stereo);
        assert!(fl.abs() < 0.1 && fr.abs() < 0.1, "{fl} {fr}");
        assert!(angle < 0.02 && shift < 0.5, "{angle} deg {shift} mm");
        let pair = c.to_binocular();
        pair.validate().unwrap();
        assert_eq!(pair.rms, Some(c.rms_stereo));
    }
}

/// A board one camera misses is left out of the joint refinement and named; with fewer than
/// three views both cameras see, the error says so and lists them; a right image of another
/// size is named with the view.
#[test]
fn what_a_user_can_get_wrong_is_named() {
    let (mut views, _) = render(4, 7);
    // View 1's right image: blank (the right camera missed the board).
    let (w, h) = (views[1].right.width(), views[1].right.height());
    views[1].right = Frame::new(w, h, vec![128; w * h]).unwrap();
    let err = calibrate_stereo_cameras(&views[..3], &StereoCameraConfig::default()).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("usable view(s) for the"), "{text}");
    assert!(
        text.contains("pose 1 left out: the board is not found by the right camera"),
        "{text}"
    );

    let strict = StereoCameraConfig {
        skip_unusable_views: false,
        ..StereoCameraConfig::default()
    };
    let err = calibrate_stereo_cameras(&views, &strict).unwrap_err();
    assert!(err.to_string().contains("pose 1 (right camera)"), "{err}");

    views[2].right = Frame::new(w / 2, h / 2, vec![0; w * h / 4]).unwrap();
    let err = calibrate_stereo_cameras(&views, &StereoCameraConfig::default()).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("pose 2"), "{text}");
    assert!(text.contains("one camera, one image size"), "{text}");
}
