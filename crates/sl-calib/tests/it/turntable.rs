//! Turntable axis calibration against ground truth: exact synthetic projections (closed
//! form and refinement must agree with the axis they were made from) and boards rendered by
//! the virtual rig on its turntable (the targets: direction within 0.05°, position
//! within 0.1 mm).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use approx::assert_abs_diff_eq;
use nalgebra::{Isometry3, Point3, Vector3};
use sl_calib::sl_camera::{CameraModel, TurntableAxis};
use sl_calib::sl_codec::Frame;
use sl_calib::{
    BoardSize, CalibError, CalibrationView, DetectorConfig, PoseAtAngle, TurntableConfig,
    TurntableView, calibrate_turntable, fit_turntable_axis,
};
use sl_sim::{Checkerboard, RigConfig, Scene, VirtualRig, capture_board_on_table};

/// Electrons per grey level of the default sensor (10 000 e⁻ full well over 255 levels).
const ONE_GREY_LEVEL_E: f64 = 10_000.0 / 255.0;

/// Foot of a line (unit `d`, point `p`) nearest the origin: the point the fit reports.
fn foot(axis: &TurntableAxis) -> Point3<f64> {
    let d = axis.direction;
    axis.point_mm - d * d.dot(&axis.point_mm.coords)
}

fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    // atan2 of |a×b| and a·b: full precision for tiny angles (acos loses half the digits).
    a.cross(b).norm().atan2(a.dot(b)).to_degrees()
}

fn synthetic_views(
    camera: &CameraModel,
    axis: &TurntableAxis,
    board: &Isometry3<f64>,
    angles: &[f64],
) -> Vec<TurntableView> {
    let object_points = BoardSize::new(9, 6).object_points(20.0);
    angles
        .iter()
        .map(|&m| {
            let pose = axis.motion(m) * board;
            let image_points = object_points
                .iter()
                .map(|p| camera.project(&(pose * p)).unwrap())
                .collect();
            TurntableView {
                label: format!("motor {m}"),
                motor_angle_deg: m,
                view: CalibrationView {
                    object_points: object_points.clone(),
                    image_points,
                },
            }
        })
        .collect()
}

/// The default rig (offset 0, scale 1) and the pose of the board standing on its table.
fn rig_truth() -> (RigConfig, Isometry3<f64>) {
    let config = RigConfig::default();
    let scene = Scene::board_on_table(Checkerboard::default());
    let t_table_board = scene.objects.first().unwrap().pose;
    (config, t_table_board)
}

#[test]
fn exact_projections_give_back_the_axis_scale_and_offset() {
    let (config, t_table_board) = rig_truth();
    // The rig's axis with a motor that is off by 4° and turns 2 % too far.
    let mut truth = config.turntable_axis();
    truth.angle_scale = 1.02;
    truth.angle_offset_deg = 4.0;
    // At platter angle 0 the board stands upright facing the camera (its x axis along the
    // camera's): the fit's offset convention gives angle 0 there, so it must find 4°.
    let board_ref = config.t_cam_table * t_table_board;
    let angles: Vec<f64> = (-3..=3).map(|k| f64::from(k) * 15.0).collect();
    let views = synthetic_views(&config.camera, &truth, &board_ref, &angles);
    let fit = calibrate_turntable(&config.camera, &views, &TurntableConfig::default()).unwrap();
    // Exact data: only rounding and the stopping rule remain (far below these bounds).
    assert!(fit.rms < 1e-6, "rms {}", fit.rms);
    assert!(angle_deg(&fit.axis.direction, &truth.direction) < 1e-7);
    assert_abs_diff_eq!(foot(&fit.axis), foot(&truth), epsilon = 1e-6);
    assert_abs_diff_eq!(fit.axis.angle_scale, 1.02, epsilon = 1e-9);
    assert_abs_diff_eq!(fit.axis.angle_offset_deg, 4.0, epsilon = 1e-6);
    // The closed form alone is exact too on exact poses (up to the PnP's stop).
    assert!(angle_deg(&fit.initial_axis.direction, &truth.direction) < 1e-5);
    assert_abs_diff_eq!(foot(&fit.initial_axis), foot(&truth), epsilon = 1e-3);
    // The reported point is the foot nearest the camera: perpendicular to the direction.
    assert_abs_diff_eq!(
        fit.axis.point_mm.coords.dot(&fit.axis.direction),
        0.0,
        epsilon = 1e-6
    );
    // The reference pose is the board at platter angle 0.
    assert_abs_diff_eq!(
        fit.t_cam_board_ref.translation.vector,
        board_ref.translation.vector,
        epsilon = 1e-5
    );
    // And the fitted axis predicts every view's pose.
    for (v, m) in fit.view_poses.iter().zip(&angles) {
        let predicted = fit.axis.motion(*m) * fit.t_cam_board_ref;
        assert_abs_diff_eq!(
            predicted.translation.vector,
            v.translation.vector,
            epsilon = 1e-5
        );
    }
}

#[test]
fn too_few_angles_and_too_small_span_are_typed_errors() {
    let (config, t_table_board) = rig_truth();
    let truth = config.turntable_axis();
    let board = config.t_cam_table * t_table_board;
    let two = synthetic_views(&config.camera, &truth, &board, &[0.0, 30.0]);
    assert!(matches!(
        calibrate_turntable(&config.camera, &two, &TurntableConfig::default()),
        Err(CalibError::TooFewAngles {
            found: 2,
            needed: 3
        })
    ));
    let narrow = synthetic_views(&config.camera, &truth, &board, &[0.0, 5.0, 10.0]);
    let err =
        calibrate_turntable(&config.camera, &narrow, &TurntableConfig::default()).unwrap_err();
    assert!(matches!(err, CalibError::AngleSpan { .. }), "{err}");
    assert!(err.to_string().contains("10.00 degrees"), "{err}");
    // The board not turning at all is degenerate, said in words.
    let still: Vec<PoseAtAngle> = [0.0, 20.0, 40.0]
        .iter()
        .map(|&m| PoseAtAngle {
            motor_angle_deg: m,
            t_cam_board: board,
        })
        .collect();
    let err = fit_turntable_axis(&still, &TurntableConfig::default()).unwrap_err();
    assert!(err.to_string().contains("did not turn"), "{err}");
}

#[test]
fn a_missing_board_names_the_angle_and_the_image() {
    let blank = Frame::filled(320, 240, 128).unwrap();
    let err = TurntableView::detect(
        &blank,
        "angle_003/white.png",
        15.0,
        BoardSize::new(9, 6),
        20.0,
        &DetectorConfig::default(),
    )
    .unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("motor angle 15 degrees"), "{msg}");
    assert!(msg.contains("angle_003/white.png"), "{msg}");
}

#[test]
fn rendered_board_on_the_turntable_meets_the_targets() {
    let mut config = RigConfig::default();
    config.render.effects.sensor.photon_noise = false;
    config.render.effects.sensor.read_noise_electrons = ONE_GREY_LEVEL_E;
    let rig = VirtualRig::new(config.clone(), Scene::sphere()).unwrap();
    let board = Checkerboard::default();
    let size = BoardSize::new(board.inner_cols, board.inner_rows);
    let mut views = Vec::new();
    for (k, m) in (-3..=3).map(|k| f64::from(k) * 15.0).enumerate() {
        let cap = capture_board_on_table(&rig, &board, m, None, k as u64).unwrap();
        let img = cap.white.into_u8();
        views.push(
            TurntableView::detect(
                &img,
                &format!("angle {m}"),
                m,
                size,
                board.square_mm,
                &DetectorConfig::default(),
            )
            .unwrap(),
        );
    }
    // The camera is the rig's own: the test isolates the axis fit from Zhang's errors.
    let fit = calibrate_turntable(&config.camera, &views, &TurntableConfig::default()).unwrap();
    let truth = config.turntable_axis();
    let dir_err = angle_deg(&fit.axis.direction, &truth.direction);
    let pos_err = (foot(&fit.axis) - foot(&truth)).norm();
    eprintln!(
        "virtual turntable: direction error {dir_err:.4} deg (std {:.4}), foot error {pos_err:.4} mm (std {:.4}), scale {:.6} (std {:.2e}), offset {:.4} deg, rms {:.4} px, {} iterations",
        fit.std_dev.direction_deg,
        fit.std_dev.point_mm,
        fit.axis.angle_scale,
        fit.std_dev.angle_scale,
        fit.axis.angle_offset_deg,
        fit.rms,
        fit.iterations
    );
    // The targets.
    assert!(dir_err < 0.05, "direction error {dir_err} deg");
    assert!(pos_err < 0.1, "position error {pos_err} mm");
    // Scale and offset: the corner noise (~0.04 px) moves them by far less than these.
    assert_abs_diff_eq!(fit.axis.angle_scale, 1.0, epsilon = 1e-3);
    assert_abs_diff_eq!(fit.axis.angle_offset_deg, 0.0, epsilon = 0.05);
    // The refinement does not make the fit worse than noise-level corners allow.
    assert!(fit.rms < 0.2, "rms {}", fit.rms);
    assert_eq!(fit.view_rms.len(), 7);
}
