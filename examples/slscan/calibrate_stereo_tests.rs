//! `slscan calibrate stereo` on a two-camera session rendered by the virtual rig and its
//! second camera: the file it writes against the rig's truth, and a session without the
//! second camera's pictures named.

use std::path::Path;

use sl_sim::{
    CalibrationCaptures, CalibrationSession, Scene, SecondCamera, VirtualRig, capture_board,
};
use structured_light::camera::BinocularCalibration;
use structured_light::codec::write_png_grey;
use structured_light::scan::scaled_rig_config;

/// Renders `poses` hand-held board poses seen by the rig's camera (`board/pose_NN/white.png`)
/// and by its second camera (`board/pose_NN/right/white.png`), and the board on the turntable
/// at three angles seen by the first (`turntable/angle_N/white.png` with `board.json`), at
/// half resolution. Returns the second camera (the truth of the pair).
fn render_session(dir: &Path, poses: usize) -> SecondCamera {
    let mut config = scaled_rig_config(2);
    config.render.supersampling = 4;
    let second = config.default_second_camera();
    let left = VirtualRig::new(config.clone(), Scene::plane()).unwrap();
    let right = VirtualRig::new(config.seen_from(&second), Scene::plane()).unwrap();
    let session = CalibrationSession {
        turntable_angles_deg: vec![-30.0, 0.0, 30.0],
        ..CalibrationSession::with_poses(poses, 5)
    };
    let captures = CalibrationCaptures::new(&left, &session).unwrap();
    let t_second_cam = second.t_cam_second.inverse();
    for (k, pose) in captures.poses().iter().enumerate() {
        let folder = dir.join(format!("board/pose_{k:02}"));
        std::fs::create_dir_all(folder.join("right")).unwrap();
        let white = captures.hand_held(k, None).unwrap().white;
        write_png_grey(&folder.join("white.png"), &white).unwrap();
        let seen = capture_board(
            &right,
            &session.board,
            &(t_second_cam * pose),
            None,
            k as u64,
        )
        .unwrap();
        write_png_grey(&folder.join("right/white.png"), &seen.white).unwrap();
    }
    for (k, angle) in session.turntable_angles_deg.iter().enumerate() {
        let folder = dir.join(format!("turntable/angle_{k}"));
        std::fs::create_dir_all(&folder).unwrap();
        let white = captures.on_table(k, None).unwrap().white;
        write_png_grey(&folder.join("white.png"), &white).unwrap();
        std::fs::write(
            folder.join("board.json"),
            format!("{{\"motor_angle_deg\": {angle}}}"),
        )
        .unwrap();
    }
    second
}

/// The two cameras and the turntable axis of a rendered session: `stereo.json` loads as a
/// two-camera calibration whose `T_left_right` is the rig's within 0.5 mm and 0.05° (measured
/// at half resolution: printed), with the axis; a pose without `right/white.png` is named.
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "a full simulation, minutes unoptimised: .ci/run runs it (step \"full simulations\")"
)]
fn calibrate_stereo_recovers_the_rigs_two_cameras() {
    let tmp = tempfile::tempdir().unwrap();
    let session = tmp.path().join("session");
    let second = render_session(&session, 8);
    let out = tmp.path().join("out");
    crate::run_cli(&[
        "calibrate",
        "stereo",
        session.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap();
    let pair = BinocularCalibration::load(out.join("stereo.json")).unwrap();
    let d = second.t_cam_second.inverse() * pair.t_left_right;
    let (angle, shift) = (d.rotation.angle().to_degrees(), d.translation.vector.norm());
    eprintln!(
        "T_left_right off by {angle:.4} deg, {shift:.3} mm; RMS {:?}",
        pair.rms
    );
    assert!(angle < 0.05 && shift < 0.5, "{angle} deg, {shift} mm");
    assert!(pair.rms.is_some_and(|r| r < 0.1), "{:?}", pair.rms);
    assert!(pair.turntable.is_some());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert!(
        report["figures"]["rms_stereo_px"].as_f64().is_some(),
        "{report}"
    );

    // The second camera's picture of one pose is missing: named, nothing written.
    std::fs::remove_file(session.join("board/pose_03/right/white.png")).unwrap();
    let again = tmp.path().join("again");
    let err = crate::run_cli(&[
        "calibrate",
        "stereo",
        session.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
    ])
    .unwrap_err();
    let text = format!("{err:#}");
    assert!(text.contains("pose_03/right"), "{text}");
    assert!(text.contains("right camera"), "{text}");
    assert!(!again.exists());
}
