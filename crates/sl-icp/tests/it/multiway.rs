//! Multiway alignment of unordered clouds with no poses ([`align_unordered`]): the three
//! bunny scans (`$SL_DATA/bunny`, skipped with a note when `SL_DATA` is unset) against the
//! reference poses of `bun.conf`; synthetic partial views of a blob (always) with a cloud
//! that belongs to nothing, which must be named as unplaced; the law that the order of the
//! inputs does not change the relative poses; and the pruning of a wrong verified edge.

#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: helpers fail loudly

use nalgebra::{Isometry3, Point3, Vector3};
use sl_icp::{GlobalCloud, MultiwayConfig, PointCloud, PoseError, align_unordered, place_views};

use crate::support::blob::blob;
use crate::support::bunny;

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

/// The views' points as clouds, in the order of the views.
fn clouds_of(views: &[(Vec<Point3<f64>>, Isometry3<f64>)]) -> Vec<PointCloud> {
    views
        .iter()
        .map(|(p, _)| PointCloud::from_positions(p.clone()))
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
    let mut clouds = clouds_of(&views);
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
    let clouds = clouds_of(&views);
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

/// A verified pair whose transform is deliberately wrong (20° and 19 mm off, yet still marked
/// verified, as a pair that slid along a symmetric surface would be) is pruned as an outlier
/// edge, and the views are placed as well as with no corruption. The views overlap in a
/// cycle, so the graph has the redundancy to tell the wrong edge from the right ones; without
/// pruning the same graph places the views centimetres off, so the test can fail.
#[test]
fn a_corrupted_verified_edge_is_pruned_and_the_views_still_placed() {
    let views = blob_views();
    let clouds = clouds_of(&views);
    let config = MultiwayConfig::default();
    let a = align_unordered(&clouds, &config).unwrap();
    // (Some candidate pairs of these smooth views may verify wrongly and be pruned already:
    // the count below is relative to this run.)
    let used: Vec<usize> = (0..a.pairs.len()).filter(|&k| a.pairs[k].used()).collect();
    // Corrupt a used edge whose two views each keep at least two other used edges: only
    // there can the graph outvote it (a view held by one right and one wrong edge is a tie
    // that no pruning can settle). Of those, the one of highest fitness, which the spanning
    // tree of the initial poses takes first, so the corruption also reaches the graph's
    // starting point.
    let edges_of = |v: usize| {
        used.iter()
            .filter(|&&e| a.pairs[e].source == v || a.pairs[e].target == v)
            .count()
    };
    let k = *used
        .iter()
        .filter(|&&e| edges_of(a.pairs[e].source) >= 3 && edges_of(a.pairs[e].target) >= 3)
        .max_by(|&&x, &&y| {
            a.pairs[x]
                .fitness()
                .unwrap()
                .total_cmp(&a.pairs[y].fitness().unwrap())
        })
        .expect("an edge the graph can outvote");
    let wrong = Isometry3::new(Vector3::new(15.0, -10.0, 5.0), Vector3::new(0.0, 0.35, 0.0));
    let mut pairs = a.pairs.clone();
    let r = pairs[k].registration.as_mut().unwrap();
    r.pose *= wrong;
    r.registration.pose = r.pose;
    let described: Vec<GlobalCloud> = clouds
        .iter()
        .enumerate()
        .map(|(i, c)| GlobalCloud::new(c, &config.global, &format!("view {i}")).unwrap())
        .collect();
    let error_of = |poses: &[Option<Isometry3<f64>>], i: usize| {
        let truth = views[0].1.inverse() * views[i].1;
        PoseError::between(&poses[i].unwrap(), &truth, &views[i].0)
    };

    let b = place_views(&described, pairs.clone(), &config).unwrap();
    assert!(
        b.pairs[k].pruned,
        "the wrong edge survived: {:?}",
        b.pairs[k]
    );
    assert!(
        b.pairs[k]
            .reason
            .as_deref()
            .is_some_and(|r| r.starts_with("pruned")),
        "{:?}",
        b.pairs[k].reason
    );
    assert_eq!(
        b.pruned_edges,
        a.pruned_edges + 1,
        "a right edge was pruned too: {:?}",
        b.pairs
    );
    assert!(b.unplaced.is_empty(), "{:?}", b.unplaced);
    for i in 1..views.len() {
        let e = error_of(&b.poses, i);
        // As the uncorrupted synthetic test: only the 2 mm voxel grids limit the answer.
        assert!(e.rms_displacement_mm <= 0.2, "view {i}: {e:?}");
    }

    // The same graph with pruning and refinement off keeps the wrong edge and misplaces
    // views by far more than the tolerance above.
    let keep_all = MultiwayConfig {
        max_edge_disagreement: 1e9,
        refine: None,
        ..config
    };
    let c = place_views(&described, pairs, &keep_all).unwrap();
    assert_eq!(c.pruned_edges, 0);
    assert!(c.pairs[k].used());
    let worst = (1..views.len())
        .map(|i| error_of(&c.poses, i).rms_displacement_mm)
        .fold(0.0, f64::max);
    assert!(worst > 2.0, "the corruption did not matter: {worst} mm");
}
