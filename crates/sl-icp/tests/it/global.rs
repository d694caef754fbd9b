//! Global registration (no initial pose) on the Stanford bunny (`$SL_DATA/bunny`, skipped
//! with a note when `SL_DATA` is unset) and on a synthetic object (always): the poses against
//! the references of `bun.conf`, and the laws of the problem (a rigid motion of all inputs
//! and the order of the inputs do not change the answer).

#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: helpers fail loudly

use std::time::Instant;

use nalgebra::{Isometry3, Point3, Vector3};
use proptest::prelude::*;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_pcg::Pcg64;
use sl_icp::{GlobalConfig, PointCloud, PoseError, register_global};

use crate::support::blob::blob;
use crate::support::bunny;

#[test]
fn bunny_pairs_register_from_no_pose_within_1_mm() {
    let Some(dir) = bunny::bunny_dir("bunny global registration") else {
        return;
    };
    let names = ["bun000", "bun045", "bun090"];
    let scans: Vec<_> = names.iter().map(|n| bunny::load(&dir, n)).collect();
    for (t, s) in [(0, 1), (0, 2), (1, 2), (1, 0)] {
        let reference = bunny::reference(&scans[t], &scans[s]);
        let start = Instant::now();
        let r =
            register_global(&scans[s].cloud, &scans[t].cloud, &GlobalConfig::default()).unwrap();
        let e = PoseError::between(&r.pose, &reference, scans[s].cloud.positions());
        eprintln!(
            "{} -> {}: {e:?} in {:.0} ms, {} matches, ransac {} inliers {} iterations {} scored, fitness {:.3} rmse {:.3}",
            names[s],
            names[t],
            start.elapsed().as_secs_f64() * 1e3,
            r.correspondences,
            r.ransac.inliers,
            r.ransac.iterations,
            r.ransac.scored,
            r.registration.fitness,
            r.registration.rmse
        );
        assert!(
            e.rms_displacement_mm <= 1.0,
            "{} -> {}: {e:?}",
            names[s],
            names[t]
        );
    }
}

/// The part of `points` seen from direction `view` (a half-space cut through the centre, as a
/// range scan sees about half of an object), so that source and target overlap only partly.
fn seen_from(points: &[Point3<f64>], view: &Vector3<f64>) -> Vec<Point3<f64>> {
    points
        .iter()
        .filter(|p| p.coords.dot(view) > -15.0)
        .copied()
        .collect()
}

fn moved(points: &[Point3<f64>], t: &Isometry3<f64>) -> Vec<Point3<f64>> {
    points.iter().map(|p| t * p).collect()
}

/// Two partial views of the blob: `(source, target, T_target_source)`.
fn blob_pair() -> (Vec<Point3<f64>>, Vec<Point3<f64>>, Isometry3<f64>) {
    let b = blob(30_000);
    let target = seen_from(&b, &Vector3::new(0.0, 0.0, 1.0));
    let world_source = seen_from(&b, &Vector3::new(1.0, 0.0, 0.3));
    let truth = Isometry3::new(
        Vector3::new(40.0, -15.0, 10.0),
        Vector3::new(0.3, 1.9, -0.2),
    );
    (moved(&world_source, &truth.inverse()), target, truth)
}

/// Answers of two runs that agree "beyond numerical noise": the final ICP runs on voxel grids
/// that are axis-aligned, so a moved or reordered cloud is downsampled to slightly different
/// points (up to half a 2 mm voxel each); averaged over thousands of points, the pose moves by
/// hundredths of a millimetre. 0.1 mm and 0.1° are several times that and far below any
/// wrong alignment (which is off by tens of mm).
const SAME_ANSWER_MM: f64 = 0.1;
const SAME_ANSWER_DEG: f64 = 0.1;

fn assert_same(a: &Isometry3<f64>, b: &Isometry3<f64>, over: &[Point3<f64>], what: &str) {
    let e = PoseError::between(a, b, over);
    assert!(
        e.rms_displacement_mm <= SAME_ANSWER_MM && e.rotation_deg <= SAME_ANSWER_DEG,
        "{what}: answers differ by {e:?}"
    );
}

#[test]
fn synthetic_pair_registers_from_no_pose() {
    let (source, target, truth) = blob_pair();
    let r = register_global(
        &PointCloud::from_positions(source.clone()),
        &PointCloud::from_positions(target),
        &GlobalConfig::default(),
    )
    .unwrap();
    let e = PoseError::between(&r.pose, &truth, &source);
    // Exact synthetic points: the answer is limited only by the 2 mm voxel grid.
    assert!(e.rms_displacement_mm <= 0.2, "{e:?}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 4, ..ProptestConfig::default() })]

    /// Moving both inputs by `M` moves the answer to `M T M⁻¹`: nothing in the pipeline
    /// depends on where the clouds sit or which way they face.
    #[test]
    fn answer_moves_with_a_rigid_motion_of_both_clouds(
        t in prop::array::uniform3(-500.0f64..500.0),
        w in prop::array::uniform3(-3.0f64..3.0),
    ) {
        let (source, target, _) = blob_pair();
        let m = Isometry3::new(Vector3::from(t), Vector3::from(w));
        let config = GlobalConfig::default();
        let base = register_global(
            &PointCloud::from_positions(source.clone()),
            &PointCloud::from_positions(target.clone()),
            &config,
        )
        .unwrap();
        let r = register_global(
            &PointCloud::from_positions(moved(&source, &m)),
            &PointCloud::from_positions(moved(&target, &m)),
            &config,
        )
        .unwrap();
        assert_same(&(m.inverse() * r.pose * m), &base.pose, &source, "moved inputs");
    }

    /// The order of the points in either cloud does not change the answer.
    #[test]
    fn answer_does_not_depend_on_point_order(seed in any::<u64>()) {
        let (source, target, _) = blob_pair();
        let config = GlobalConfig::default();
        let base = register_global(
            &PointCloud::from_positions(source.clone()),
            &PointCloud::from_positions(target.clone()),
            &config,
        )
        .unwrap();
        let mut rng = Pcg64::seed_from_u64(seed);
        let (mut s, mut t) = (source.clone(), target);
        s.shuffle(&mut rng);
        t.shuffle(&mut rng);
        let r = register_global(&PointCloud::from_positions(s), &PointCloud::from_positions(t), &config)
            .unwrap();
        assert_same(&r.pose, &base.pose, &source, "shuffled inputs");
    }
}

/// The same laws on the real scans: bun045 onto bun000, moved by a fixed rigid motion and
/// with the points shuffled, against the plain answer.
#[test]
fn bunny_answer_unchanged_by_motion_and_point_order() {
    let Some(dir) = bunny::bunny_dir("bunny global registration properties") else {
        return;
    };
    let (t, s) = (bunny::load(&dir, "bun000"), bunny::load(&dir, "bun045"));
    let config = GlobalConfig::default();
    let base = register_global(&s.cloud, &t.cloud, &config).unwrap();
    let m = Isometry3::new(
        Vector3::new(120.0, -300.0, 45.0),
        Vector3::new(1.1, -0.4, 2.0),
    );
    let mut rng = Pcg64::seed_from_u64(7);
    let mut sp = moved(s.cloud.positions(), &m);
    let mut tp = moved(t.cloud.positions(), &m);
    sp.shuffle(&mut rng);
    tp.shuffle(&mut rng);
    let r = register_global(
        &PointCloud::from_positions(sp),
        &PointCloud::from_positions(tp),
        &config,
    )
    .unwrap();
    assert_same(
        &(m.inverse() * r.pose * m),
        &base.pose,
        s.cloud.positions(),
        "bunny moved and shuffled",
    );
}
