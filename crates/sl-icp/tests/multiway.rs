//! Multiway alignment of unordered clouds with no poses ([`align_unordered`]): the three
//! bunny scans (`$SL_DATA/bunny`, skipped with a note when `SL_DATA` is unset) against the
//! reference poses of `bun.conf`; synthetic partial views of a blob (always) with a cloud
//! that belongs to nothing, which must be named as unplaced; and the law that the order of
//! the inputs does not change the relative poses.

#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: helpers fail loudly

use nalgebra::{Isometry3, Point3, Vector3};
use sl_icp::{MultiwayConfig, PointCloud, PoseError, align_unordered};

#[path = "support/bunny.rs"]
mod bunny;

/// A bumpy closed blob about 80 mm across (mm), as in `tests/global.rs`.
fn blob(n: usize) -> Vec<Point3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let (r, t) = ((1.0 - y * y).sqrt(), golden * i as f64);
            let d = Vector3::new(r * t.cos(), y, r * t.sin());
            let bump = 6.0 * (3.0 * d.x).sin() * (2.0 * d.y + 0.5).cos()
                + 5.0 * (4.0 * d.z * d.x).sin()
                + 8.0 * (d.y - 0.6).max(0.0);
            Point3::from(d * (40.0 + bump))
        })
        .collect()
}

/// Four views of the blob from directions 90° apart about y (each sees a bit more than half,
/// so neighbours overlap by about a third of the surface), each in its own frame:
/// `(points in the view frame, T_world_view)`.
fn blob_views() -> Vec<(Vec<Point3<f64>>, Isometry3<f64>)> {
    let b = blob(30_000);
    (0..4)
        .map(|k| {
            let a = f64::from(k) * std::f64::consts::FRAC_PI_2;
            let dir = Vector3::new(a.sin(), 0.2, a.cos());
            let seen: Vec<Point3<f64>> = b
                .iter()
                .filter(|p| p.coords.dot(&dir) > -12.0)
                .copied()
                .collect();
            let t_world_view = Isometry3::new(
                Vector3::new(30.0 * f64::from(k), -20.0, 500.0),
                Vector3::new(0.3 * f64::from(k), a, -0.1),
            );
            let inv = t_world_view.inverse();
            (seen.iter().map(|p| inv * p).collect(), t_world_view)
        })
        .collect()
}

/// A flat 100 x 100 mm plate: every descriptor the same, so it matches nothing.
fn plate() -> Vec<Point3<f64>> {
    (0..10_000)
        .map(|i| Point3::new(f64::from(i % 100), f64::from(i / 100), 300.0))
        .collect()
}

#[test]
fn synthetic_views_are_placed_and_an_unrelated_cloud_is_named() {
    let views = blob_views();
    let mut clouds: Vec<PointCloud> = views
        .iter()
        .map(|(p, _)| PointCloud::from_positions(p.clone()))
        .collect();
    clouds.insert(2, PointCloud::from_positions(plate()));
    let a = align_unordered(&clouds, &MultiwayConfig::default()).unwrap();
    assert_eq!(a.unplaced.len(), 1, "{:?}", a.unplaced);
    assert_eq!(a.unplaced[0].view, 2);
    assert!(
        a.unplaced[0].why.contains("no pair verified"),
        "{:?}",
        a.unplaced
    );
    assert!(a.poses[2].is_none());
    let truth_of = |i: usize| if i < 2 { views[i].1 } else { views[i - 1].1 };
    for i in [1, 3, 4] {
        let truth = truth_of(0).inverse() * truth_of(i);
        let points = &views[if i < 2 { i } else { i - 1 }].0;
        let e = PoseError::between(&a.poses[i].unwrap(), &truth, points);
        // Exact points: only the 2 mm voxel grids limit the answer.
        assert!(e.rms_displacement_mm <= 0.2, "view {i}: {e:?}");
    }
}

/// Relative poses of two alignments agree "beyond numerical noise": 0.1 mm RMS on the views'
/// points (the voxel grids of moved clouds differ by up to half a voxel per point; averaged
/// over thousands of points this moves a pose by hundredths of a mm).
const SAME_ANSWER_MM: f64 = 0.1;

#[test]
fn synthetic_input_order_does_not_change_the_relative_poses() {
    let views = blob_views();
    let clouds: Vec<PointCloud> = views
        .iter()
        .map(|(p, _)| PointCloud::from_positions(p.clone()))
        .collect();
    let config = MultiwayConfig::default();
    let a = align_unordered(&clouds, &config).unwrap();
    let order = [2, 0, 3, 1];
    let permuted: Vec<PointCloud> = order.iter().map(|&i| clouds[i].clone()).collect();
    let b = align_unordered(&permuted, &config).unwrap();
    assert!(a.unplaced.is_empty() && b.unplaced.is_empty());
    // b's view k is a's view order[k]; compare T_view0_viewk of both.
    let b_pose_of = |i: usize| b.poses[order.iter().position(|&o| o == i).unwrap()].unwrap();
    for (i, view) in views.iter().enumerate().skip(1) {
        let in_a = a.poses[i].unwrap();
        let in_b = b_pose_of(0).inverse() * b_pose_of(i);
        let e = PoseError::between(&in_a, &in_b, &view.0);
        assert!(e.rms_displacement_mm <= SAME_ANSWER_MM, "view {i}: {e:?}");
    }
}

#[test]
fn bunny_scans_in_any_order_are_placed_within_1_mm() {
    let Some(dir) = bunny::bunny_dir("bunny multiway alignment") else {
        return;
    };
    let names = ["bun090", "bun000", "bun045"];
    let scans: Vec<_> = names.iter().map(|n| bunny::load(&dir, n)).collect();
    let clouds: Vec<PointCloud> = scans.iter().map(|s| s.cloud.clone()).collect();
    let a = align_unordered(&clouds, &MultiwayConfig::default()).unwrap();
    assert!(a.unplaced.is_empty(), "{:?}", a.unplaced);
    for i in 1..3 {
        let reference = bunny::reference(&scans[0], &scans[i]);
        let e = PoseError::between(&a.poses[i].unwrap(), &reference, scans[i].cloud.positions());
        eprintln!("{} in {}'s frame: {e:?}", names[i], names[0]);
        assert!(e.rms_displacement_mm <= 1.0, "{}: {e:?}", names[i]);
    }
    // Another order: the same relative poses.
    let order = [2, 1, 0];
    let permuted: Vec<PointCloud> = order.iter().map(|&i| clouds[i].clone()).collect();
    let b = align_unordered(&permuted, &MultiwayConfig::default()).unwrap();
    let b_pose_of = |i: usize| b.poses[order.iter().position(|&o| o == i).unwrap()].unwrap();
    for i in 1..3 {
        let in_b = b_pose_of(0).inverse() * b_pose_of(i);
        let e = PoseError::between(&a.poses[i].unwrap(), &in_b, scans[i].cloud.positions());
        assert!(
            e.rms_displacement_mm <= SAME_ANSWER_MM,
            "{}: {e:?}",
            names[i]
        );
    }
}
