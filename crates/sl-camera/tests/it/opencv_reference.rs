//! Projection and Jacobians against `cv2.projectPoints` reference vectors.
//!
//! The vectors are in `tests/data/opencv_project_points.json`, written by
//! `tests/data/gen_opencv_reference.py` (run it with a Python that has OpenCV to regenerate
//! them). Lenses: the strong reference design, a mild webcam, a 4-coefficient lens, a
//! projector-like lens with an off-centre principal point, an 8-coefficient rational lens
//! and no distortion; points cover the whole image including its exact corners. Skew is
//! zero throughout because `cv2.projectPoints` ignores `K[0][1]`; skew is checked against
//! its closed form in the unit tests of `sl-camera`.

// Test helpers outside #[test] functions may unwrap too: a panic is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{Point2, Point3, Vector3};
use serde::Deserialize;
use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics, RvecTvec};

#[derive(Deserialize)]
struct Reference {
    opencv_version: String,
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    name: String,
    width: u32,
    height: u32,
    camera_matrix: [f64; 9],
    distortion: Vec<f64>,
    rvec: [f64; 3],
    tvec: [f64; 3],
    object_points: Vec<[f64; 3]>,
    image_points: Vec<[f64; 2]>,
    jacobian: Vec<Vec<f64>>,
}

fn load() -> Reference {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/opencv_project_points.json"
    );
    let text = std::fs::read_to_string(path).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn camera(case: &Case) -> CameraModel {
    let k = &case.camera_matrix;
    assert_eq!(k[1], 0.0, "reference vectors have zero skew");
    CameraModel::new(
        Intrinsics::new(k[0], k[4], k[2], k[5]),
        Distortion::from_opencv(&case.distortion).unwrap(),
        ImageSize::new(case.width, case.height),
    )
    .unwrap()
}

/// 1e-9 px, relative for pixels far from the origin: both sides evaluate the same
/// polynomial in f64 (OpenCV in a different operation order), so they agree to ~1e-12 px.
fn close_px(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs().max(1.0)
}

#[test]
fn project_points_matches_opencv() {
    let reference = load();
    assert!(reference.cases.len() >= 6);
    let mut worst: f64 = 0.0;
    let mut count = 0;
    for case in &reference.cases {
        let cam = camera(case);
        let pose = RvecTvec::new(Vector3::from(case.rvec), Vector3::from(case.tvec));
        for (p, want) in case.object_points.iter().zip(&case.image_points) {
            let p_cam = pose.transform_point(&Point3::from(*p));
            let got = cam
                .project(&p_cam)
                .unwrap_or_else(|| panic!("{}: {p:?} refused", case.name));
            assert!(
                close_px(got.x, want[0]) && close_px(got.y, want[1]),
                "{} (OpenCV {}): point {p:?}: ours {got:?}, OpenCV {want:?}",
                case.name,
                reference.opencv_version
            );
            worst = worst.max((got.x - want[0]).abs().max((got.y - want[1]).abs()));
            count += 1;
        }
    }
    eprintln!("{count} points, worst |ours - OpenCV| = {worst:.3e} px");
}

#[test]
fn unproject_inverts_opencv_pixels() {
    for case in &load().cases {
        let cam = camera(case);
        let pose = RvecTvec::new(Vector3::from(case.rvec), Vector3::from(case.tvec));
        for (p, px) in case.object_points.iter().zip(&case.image_points) {
            let p_cam = pose.transform_point(&Point3::from(*p));
            let ray = cam
                .unproject(&Point2::new(px[0], px[1]))
                .unwrap_or_else(|| panic!("{}: pixel {px:?} refused", case.name));
            let want = p_cam.coords / p_cam.z;
            // OpenCV's pixel is exact to ~1e-12 px; 1e-12 px / fx (≥ 500 px) ≈ 2e-15 in
            // normalised units, amplified by the inverse Jacobian of strong lenses (≤ ~10).
            assert!(
                (ray - want).norm() <= 1e-12,
                "{}: pixel {px:?}: ray {ray:?}, want {want:?}",
                case.name
            );
        }
    }
}

#[test]
fn jacobians_match_opencv() {
    for case in &load().cases {
        let cam = camera(case);
        let pose = RvecTvec::new(Vector3::from(case.rvec), Vector3::from(case.tvec));
        let n_dist = case.jacobian[0].len() - 10;
        for (i, p) in case.object_points.iter().enumerate() {
            let j = cam
                .project_with_pose_jacobians(&pose, &Point3::from(*p))
                .unwrap();
            for row in 0..2 {
                let want = &case.jacobian[2 * i + row];
                let mut ours = Vec::with_capacity(want.len());
                ours.extend((0..3).map(|c| j.d_rvec[(row, c)]));
                ours.extend((0..3).map(|c| j.d_tvec[(row, c)]));
                // OpenCV: fx, fy, cx, cy; ours: fx, fy, cx, cy, skew.
                ours.extend((0..4).map(|c| j.projection.d_intrinsics[(row, c)]));
                ours.extend((0..n_dist).map(|c| j.projection.d_distortion[(row, c)]));
                for (c, (a, b)) in ours.iter().zip(want).enumerate() {
                    // Both are analytic in f64; differences come from operation order and
                    // from OpenCV's Rodrigues derivative, good to ~1e-12 relative. 1e-8
                    // relative to the largest entry of the row keeps a wide margin.
                    let scale = want.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
                    assert!(
                        (a - b).abs() <= 1e-8 * scale,
                        "{}: point {i} row {row} column {c}: ours {a}, OpenCV {b}",
                        case.name
                    );
                }
            }
        }
    }
}
