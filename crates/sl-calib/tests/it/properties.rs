//! Laws of the calibration, over random seeds (proptest):
//! - Zhang's calibration recovers the camera it was given from exact projections;
//! - the turntable axis fit recovers the axis, scale and offset it was given;
//! - the axis fit does not depend on the choice of camera frame: moving every pose by a
//!   rigid motion `G` moves the fitted axis line by `G`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use sl_calib::sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics, TurntableAxis};
use sl_calib::{
    BoardSize, CalibrationView, PoseAtAngle, TurntableConfig, TurntableView, ZhangConfig,
    calibrate_camera, calibrate_turntable, fit_turntable_axis,
};

fn camera(fx: f64, fy: f64, cx: f64, cy: f64, k1: f64, k2: f64) -> CameraModel {
    CameraModel::new(
        Intrinsics::new(fx, fy, cx, cy),
        Distortion::from_opencv(&[k1, k2, 0.0, 0.0, 0.0]).unwrap(),
        ImageSize::new(1280, 720),
    )
    .unwrap()
}

/// Board of 9x6 corners of 20 mm, centred on its pose's origin.
fn board_points() -> Vec<Point3<f64>> {
    BoardSize::new(9, 6)
        .object_points(20.0)
        .into_iter()
        .map(|p| Point3::new(p.x - 80.0, p.y - 50.0, 0.0))
        .collect()
}

fn project_view(cam: &CameraModel, pose: &Isometry3<f64>) -> Option<CalibrationView> {
    let object_points = board_points();
    let mut image_points = Vec::new();
    for p in &object_points {
        let q = cam.project(&(pose * p))?;
        if !cam.size.contains(q.x, q.y) {
            return None;
        }
        image_points.push(q);
    }
    Some(CalibrationView {
        object_points,
        image_points,
    })
}

/// Distance of a point from a line (unit direction `d` through `p`).
fn line_distance(d: &Vector3<f64>, p: &Point3<f64>, q: &Point3<f64>) -> f64 {
    let v = q - p;
    (v - d * d.dot(&v)).norm()
}

fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    // atan2 of |a×b| and a·b: full precision for tiny angles (acos loses half the digits).
    a.cross(b).norm().atan2(a.dot(b)).to_degrees()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn zhang_recovers_the_camera_from_exact_projections(
        fx in 900.0..1800.0f64,
        aspect in 0.98..1.02f64,
        cx in 600.0..680.0f64,
        cy in 330.0..390.0f64,
        k1 in -0.2..0.1f64,
        k2 in -0.1..0.1f64,
        tilts in prop::collection::vec((-0.5..0.5f64, -0.5..0.5f64, -0.3..0.3f64, 500.0..800.0f64), 6),
    ) {
        let cam = camera(fx, fx * aspect, cx, cy, k1, k2);
        let views: Vec<CalibrationView> = tilts
            .iter()
            .filter_map(|&(a, b, c, z)| {
                let pose = Isometry3::from_parts(
                    Translation3::new(0.0, 0.0, z),
                    UnitQuaternion::from_euler_angles(a, b, c),
                );
                project_view(&cam, &pose)
            })
            .collect();
        prop_assume!(views.len() >= 4);
        let cal = calibrate_camera(&views, cam.size, &ZhangConfig::default()).unwrap();
        // Exact data: the optimum is the truth; LM's stop and rounding leave far less than
        // 1e-6 relative on the focal lengths and 1e-4 px on the principal point.
        let i = &cal.camera.intrinsics;
        prop_assert!((i.fx / fx - 1.0).abs() < 1e-6, "fx {} vs {}", i.fx, fx);
        prop_assert!((i.fy / (fx * aspect) - 1.0).abs() < 1e-6);
        prop_assert!((i.cx - cx).abs() < 1e-4 && (i.cy - cy).abs() < 1e-4);
        prop_assert!((cal.camera.distortion.k1() - k1).abs() < 1e-5);
        prop_assert!(cal.rms < 1e-6);
    }

    #[test]
    fn turntable_fit_recovers_the_axis_it_was_given(
        tilt_x in -0.6..-0.1f64,
        tilt_z in -0.1..0.1f64,
        px in -30.0..30.0f64,
        pz in 550.0..700.0f64,
        scale in 0.9..1.1f64,
        offset in -20.0..20.0f64,
        step in 8.0..15.0f64,
    ) {
        let cam = camera(1440.0, 1440.0, 639.5, 359.5, -0.08, 0.12);
        // The axis: "up" in the camera frame, tipped towards the camera.
        let mut axis = TurntableAxis::new(
            Vector3::new(tilt_z, -1.0, tilt_x),
            Point3::new(px, 60.0, pz),
        ).unwrap();
        axis.angle_scale = scale;
        axis.angle_offset_deg = offset;
        // The board upright on the axis, facing the camera, at platter angle 0.
        let up = axis.direction;
        let x = Vector3::x() - up * up.x;
        let rot = nalgebra::Rotation3::from_basis_unchecked(&[
            x.normalize(),
            -up,
            x.normalize().cross(&-up),
        ]);
        let board = Isometry3::from_parts(
            Translation3::from(axis.point_mm.coords),
            UnitQuaternion::from_rotation_matrix(&rot),
        );
        let object_points = board_points();
        let views: Vec<TurntableView> = (-3..=3)
            .map(|k| {
                let m = f64::from(k) * step;
                let pose = axis.motion(m) * board;
                TurntableView {
                    label: format!("motor {m}"),
                    motor_angle_deg: m,
                    view: CalibrationView {
                        object_points: object_points.clone(),
                        image_points: object_points
                            .iter()
                            .map(|p| cam.project(&(pose * p)).unwrap())
                            .collect(),
                    },
                }
            })
            .collect();
        let fit = calibrate_turntable(&cam, &views, &TurntableConfig::default()).unwrap();
        // Exact data: errors are rounding and the stopping rule, far below these bounds.
        prop_assert!(angle_deg(&fit.axis.direction, &axis.direction) < 1e-6);
        prop_assert!(line_distance(&fit.axis.direction, &fit.axis.point_mm, &axis.point_mm) < 1e-5);
        prop_assert!((fit.axis.angle_scale - scale).abs() < 1e-8);
        prop_assert!((fit.axis.angle_offset_deg - offset).abs() < 1e-5,
            "offset {} vs {}", fit.axis.angle_offset_deg, offset);
    }

    #[test]
    fn axis_fit_moves_with_the_camera_frame(
        rx in -1.0..1.0f64, ry in -1.0..1.0f64, rz in -1.0..1.0f64,
        tx in -500.0..500.0f64, ty in -500.0..500.0f64, tz in -500.0..500.0f64,
        noise_seed in 0u64..1000,
    ) {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(noise_seed);
        let axis = TurntableAxis::new(Vector3::new(0.05, -1.0, -0.3), Point3::new(10.0, 50.0, 600.0)).unwrap();
        let board = Isometry3::translation(-80.0, -50.0, 560.0);
        // Poses with a little noise, so the fit is a real least-squares answer.
        let poses: Vec<PoseAtAngle> = [-45.0, -30.0, -15.0, 0.0, 15.0, 30.0, 45.0]
            .iter()
            .map(|&m| {
                let wobble = UnitQuaternion::from_euler_angles(
                    rng.random_range(-1e-3..1e-3),
                    rng.random_range(-1e-3..1e-3),
                    rng.random_range(-1e-3..1e-3),
                );
                let shift = Translation3::new(
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.05..0.05),
                );
                PoseAtAngle {
                    motor_angle_deg: m,
                    t_cam_board: Isometry3::from_parts(shift, wobble) * axis.motion(m) * board,
                }
            })
            .collect();
        let g = Isometry3::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::from_euler_angles(rx, ry, rz),
        );
        let moved: Vec<PoseAtAngle> = poses
            .iter()
            .map(|p| PoseAtAngle { motor_angle_deg: p.motor_angle_deg, t_cam_board: g * p.t_cam_board })
            .collect();
        let cfg = TurntableConfig::default();
        let a = fit_turntable_axis(&poses, &cfg).unwrap();
        let b = fit_turntable_axis(&moved, &cfg).unwrap();
        // Same line up to rounding (the problem is solved in double precision; 1e-9 relative
        // to the ~1000 mm coordinates).
        let e = angle_deg(&(g.rotation * a.direction), &b.direction);
        prop_assert!(e < 1e-7, "direction differs by {e} deg: {:?} vs {:?}", g.rotation * a.direction, b.direction);
        prop_assert!(line_distance(&b.direction, &b.point_mm, &(g * a.point_mm)) < 1e-6);
        prop_assert!((a.angle_scale - b.angle_scale).abs() < 1e-10);
    }
}
