//! The calibration capture on the virtual rig through the device traits: each refusal (no
//! board, over-exposed, blurred, too close) writes nothing; taken poses land in the layout
//! `slscan calibrate all` reads; a session opened again continues its numbering; the board on
//! the turntable is captured at the angles asked, with the motor angle in `board.json`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: a failure is the test's

use std::path::Path;

use sl_calib::sl_camera::{ImageSize, Intrinsics};
use sl_codec::Frame;
use sl_rig::{Camera, GreyImage, Projector};
use sl_scan::{
    AutoConfig, AutoEvent, BoardMover, CalibrationCapture, CalibrationCaptureConfig, Refusal,
    TakeOutcome, VirtualBoardRig, calibration_turntable_angles, capture_poses_auto,
};
use sl_sim::{BoardPoseConfig, Checkerboard, RigConfig};

/// Half resolution (640x360 camera, 960x540 projector): a 20 mm square spans ~30 px at
/// 450 mm, plenty for detection, and a view casts in a fraction of the full-size time.
fn half_rig() -> RigConfig {
    let mut c = RigConfig::default();
    for m in [&mut c.camera, &mut c.projector] {
        let k = m.intrinsics;
        m.intrinsics = Intrinsics::new(
            k.fx / 2.0,
            k.fy / 2.0,
            (k.cx + 0.5) / 2.0 - 0.5,
            (k.cy + 0.5) / 2.0 - 0.5,
        );
        m.size = ImageSize::new(m.size.width / 2, m.size.height / 2);
    }
    c.render.supersampling = 2;
    c
}

fn rig(config: RigConfig, poses: usize) -> VirtualBoardRig {
    VirtualBoardRig::new(
        config,
        Checkerboard::default(),
        &BoardPoseConfig {
            count: poses,
            ..BoardPoseConfig::default()
        },
    )
    .unwrap()
}

fn session(dir: &Path, rig: &VirtualBoardRig) -> CalibrationCapture {
    let (camera, projector, _, _) = rig.devices();
    let board = Checkerboard::default();
    let size = sl_calib::BoardSize::new(board.inner_cols, board.inner_rows);
    let config = CalibrationCaptureConfig::new(size, board.square_mm, projector.image_size());
    CalibrationCapture::open(dir, config, camera.frame_size(), projector.image_size()).unwrap()
}

/// The sub-folders of `dir`, names sorted.
fn folders(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn map_pixels(img: &GreyImage, f: impl Fn(u8) -> u8) -> GreyImage {
    let GreyImage::U8(p) = img else {
        panic!("8-bit frames expected");
    };
    GreyImage::U8(
        Frame::new(
            p.width(),
            p.height(),
            p.data().iter().map(|&v| f(v)).collect(),
        )
        .unwrap(),
    )
}

#[test]
fn each_refusal_writes_nothing_and_says_why() {
    let tmp = tempfile::tempdir().unwrap();
    let rig = rig(half_rig(), 4);
    let (mut camera, mut projector, _, mut mover) = rig.devices();
    let mut s = session(tmp.path(), &rig);
    let board = tmp.path().join("board");

    // A good first pose: found with every corner, taken.
    let check = s.look(&mut camera, &mut projector).unwrap();
    assert!(check.verdict.is_ok(), "{}", check.summary());
    assert!(
        check
            .summary()
            .starts_with("board found: 54/54 corners, tilt "),
        "{}",
        check.summary()
    );
    // The virtual board is sharp (about 2 px edges) and its white squares are far from the
    // top of the sensor (exposure 0.75 of the full well for white).
    let w = check.edge_width_px.unwrap();
    assert!(w < 3.5, "edge width {w}");
    assert!(
        check.saturated_fraction < 1e-3,
        "{}",
        check.saturated_fraction
    );
    assert!(matches!(
        s.take(&check, &mut camera, &mut projector).unwrap(),
        TakeOutcome::Taken { index: 0, .. }
    ));
    assert_eq!(folders(&board), ["pose_000"]);

    // The same pose again: too close to pose 0.
    let again = s.look(&mut camera, &mut projector).unwrap();
    match &again.verdict {
        Err(Refusal::TooClose {
            pose: 0,
            shift,
            tilt_change_deg,
        }) => {
            assert!(
                *shift < 0.01 && *tilt_change_deg < 1.0,
                "{shift} {tilt_change_deg}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(
        again.summary().contains("too close to pose 0"),
        "{}",
        again.summary()
    );
    assert!(matches!(
        s.take(&again, &mut camera, &mut projector).unwrap(),
        TakeOutcome::Refused(Refusal::TooClose { .. })
    ));

    // The next pose, blurred (a board moving during the exposure: a 4 px Gaussian).
    mover.next_pose().unwrap();
    let fresh = s.look(&mut camera, &mut projector).unwrap();
    assert!(fresh.verdict.is_ok(), "{}", fresh.summary());
    let size = fresh.white.size();
    let g = image::GrayImage::from_raw(
        size.width,
        size.height,
        match &fresh.white {
            GreyImage::U8(p) => p.data().to_vec(),
            GreyImage::U16(_) => panic!("8-bit"),
        },
    )
    .unwrap();
    let blurred = image::imageops::blur(&g, 4.0);
    let blurred = GreyImage::U8(
        Frame::new(g.width() as usize, g.height() as usize, blurred.into_raw()).unwrap(),
    );
    let check = s.check(blurred);
    match &check.verdict {
        // 2.5 sigma = 10 px, wider than the 5 px allowed.
        Err(Refusal::Blurred { edge_width_px }) => assert!(*edge_width_px > 6.0, "{edge_width_px}"),
        other => panic!("{other:?}: {}", check.summary()),
    }
    assert!(matches!(
        s.take(&check, &mut camera, &mut projector).unwrap(),
        TakeOutcome::Refused(Refusal::Blurred { .. })
    ));

    // Over-exposed: three times the exposure clips the white squares (half the board).
    let bright = map_pixels(&fresh.white, |v| v.saturating_mul(3));
    let check = s.check(bright);
    match &check.verdict {
        Err(Refusal::OverExposed { saturated_fraction }) => {
            assert!(*saturated_fraction > 0.3, "{saturated_fraction}");
        }
        other => panic!("{other:?}: {}", check.summary()),
    }
    assert!(
        check.summary().contains("over-exposed"),
        "{}",
        check.summary()
    );

    // No board: a grey frame.
    let check = s.check(map_pixels(&fresh.white, |_| 120));
    assert!(
        matches!(check.verdict, Err(Refusal::BoardNotFound { .. })),
        "{:?}",
        check.verdict
    );
    assert!(
        check.summary().starts_with("board not found: 0/54"),
        "{}",
        check.summary()
    );
    assert!(matches!(
        s.take(&check, &mut camera, &mut projector).unwrap(),
        TakeOutcome::Refused(Refusal::BoardNotFound { .. })
    ));

    // Nothing was written for any refusal.
    assert_eq!(folders(&board), ["pose_000"]);
    // The fresh pose itself is fine and becomes pose 1.
    assert!(matches!(
        s.take(&fresh, &mut camera, &mut projector).unwrap(),
        TakeOutcome::Taken { index: 1, .. }
    ));
    assert_eq!(s.coverage().poses, 2);
}

#[test]
fn auto_poses_then_turntable_resume_and_drop() {
    let tmp = tempfile::tempdir().unwrap();
    let mut config = half_rig();
    config.angle_offset_deg = 3.0;
    let rig = rig(config, 5);
    let (mut camera, mut projector, mut table, mut mover) = rig.devices();
    let mut s = session(tmp.path(), &rig);
    let mut events = (0, 0);
    let cfg = AutoConfig {
        poses: 4,
        max_looks: Some(40),
        ..AutoConfig::default()
    };
    let taken =
        capture_poses_auto(
            &mut s,
            &mut camera,
            &mut projector,
            &mut mover,
            &cfg,
            |e| match e {
                AutoEvent::Taken { .. } => events.0 += 1,
                AutoEvent::Refused(_) => events.1 += 1,
                AutoEvent::Looked(_) => {}
            },
        )
        .unwrap();
    assert_eq!(taken, 4);
    assert_eq!(events.0, 4);
    let board = tmp.path().join("board");
    assert_eq!(
        folders(&board),
        ["pose_000", "pose_001", "pose_002", "pose_003"]
    );
    // Each pose folder: white frame, every pattern frame, manifest and board file.
    let manifest = &s.config().manifest;
    let pose = board.join("pose_002");
    for f in manifest.blocks.iter().flat_map(|b| b.frames.iter()) {
        assert!(pose.join(f).is_file(), "{f}");
    }
    for f in ["white.png", "manifest.json", "board.json"] {
        assert!(pose.join(f).is_file(), "{f}");
    }
    // From the third pose on, the tilts are measured with a calibration of the poses so far:
    // its focal length is within 2 % of the rig's (720 px at half size).
    let fx = s.camera().intrinsics.fx;
    assert!((fx / 720.0 - 1.0).abs() < 0.02, "fx {fx}");

    // Drop the last pose: its folder goes; a new session continues after pose 2.
    let dropped = s.drop_last().unwrap().unwrap();
    assert!(dropped.ends_with("pose_003") && !dropped.exists());
    drop(s);
    std::fs::create_dir_all(board.join(".partial_pose_003")).unwrap();
    let mut s = session(tmp.path(), &rig);
    assert_eq!(s.poses().len(), 3);
    assert!(
        !board.join(".partial_pose_003").exists(),
        "half-written pose removed"
    );
    mover.next_pose().unwrap();
    let check = s.look(&mut camera, &mut projector).unwrap();
    match s.take(&check, &mut camera, &mut projector).unwrap() {
        TakeOutcome::Taken { index, .. } => assert_eq!(index, 3),
        TakeOutcome::Refused(r) => panic!("{r}"),
    }

    // The board on the turntable: three angles, the motor angle in board.json.
    mover.onto_turntable().unwrap();
    let angles = calibration_turntable_angles(3);
    let views = s
        .capture_turntable(&mut camera, &mut projector, &mut table, &angles, |_| {})
        .unwrap();
    assert_eq!(views.len(), 3);
    assert!(views.iter().all(|v| v.board_found && !v.kept), "{views:?}");
    let text = std::fs::read_to_string(tmp.path().join("turntable/angle_002/board.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["motor_angle_deg"].as_f64(), Some(45.0));
    // Run again: every view kept.
    let again = s
        .capture_turntable(&mut camera, &mut projector, &mut table, &angles, |_| {})
        .unwrap();
    assert!(again.iter().all(|v| v.kept), "{again:?}");
}

/// With a second camera a taken pose holds `right/`: its picture of the board under white
/// light, where the board is found whole, and its captures of the same patterns (held until
/// both cameras captured) with their manifest, which decode over the board.
#[test]
fn a_binocular_pose_holds_the_right_cameras_white_and_patterns() {
    let tmp = tempfile::tempdir().unwrap();
    let config = half_rig();
    let second = config.default_second_camera();
    let rig = rig(config, 3).with_second_camera(second).unwrap();
    let (mut camera, mut projector, _, _) = rig.devices();
    let mut right = rig.right_camera().unwrap();
    let mut s = session(tmp.path(), &rig);
    let check = s.look(&mut camera, &mut projector).unwrap();
    assert!(check.verdict.is_ok(), "{}", check.summary());
    let TakeOutcome::Taken { dir, .. } = s
        .take_with(&check, &mut camera, Some(&mut right), &mut projector)
        .unwrap()
    else {
        panic!("the pose seen by both cameras was refused");
    };
    let white = sl_codec::read_grey8(&dir.join("right/white.png")).unwrap();
    let board = Checkerboard::default();
    let size = sl_calib::BoardSize::new(board.inner_cols, board.inner_rows);
    let corners =
        sl_calib::detect_checkerboard(&white, size, &sl_calib::DetectorConfig::default(), "right")
            .unwrap();
    assert_eq!(corners.corners.len(), (size.cols * size.rows) as usize);
    let left = sl_codec::CaptureSet::load(&dir.join(sl_codec::MANIFEST_FILE)).unwrap();
    let set = sl_codec::CaptureSet::load(&dir.join("right").join(sl_codec::MANIFEST_FILE)).unwrap();
    assert_eq!(set.frame_names.len(), left.frame_names.len());
    let map = sl_codec::decode(&set, &sl_codec::DecodeConfig::default()).unwrap();
    let decoded = map.col.iter().filter(|c| c.is_finite()).count();
    // The board covers a good part of the right image: a tenth of it decodes at least.
    assert!(
        decoded * 10 > map.col.len(),
        "{decoded} of {} pixels",
        map.col.len()
    );
}
