//! The Stanford bunny (`$SL_DATA/bunny`, real Cyberware scans): bun045 onto bun000 against the
//! reference poses of `bun.conf`, from a 5° start and from the raw scan poses, and the merge of
//! the three scans. Skips (saying so) when `SL_DATA` is unset.
//!
//! The reference poses are good to about 0.1° (see `$SL_DATA/README.md`), so the bounds below
//! cannot be much tighter than that.

#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: helpers fail loudly

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_icp::{
    IcpConfig, MergeConfig, Metric, NormalSource, PoseError, PrepareConfig, PreparedCloud,
    align_views, register,
};

use crate::support::bunny;

fn prep(voxel: f64, normals: bool) -> PrepareConfig {
    PrepareConfig {
        voxel_size: Some(voxel),
        normals: if normals {
            NormalSource::default()
        } else {
            NormalSource::None
        },
    }
}

#[test]
fn bun045_onto_bun000_from_5_degrees_meets_the_targets() {
    let Some(dir) = bunny::bunny_dir("bunny registration from 5 degrees") else {
        return;
    };
    let (target, source) = (bunny::load(&dir, "bun000"), bunny::load(&dir, "bun045"));
    let reference = bunny::reference(&target, &source);
    let start = bunny::perturbed(&reference, &source.cloud.centroid().unwrap());
    let e0 = PoseError::between(&start, &reference, source.cloud.positions());
    assert!((e0.rotation_deg - 5.0).abs() < 1e-9);
    // Point-to-plane, 1 mm voxels, 5 mm gate (Open3D's settings): ≤ 0.1° and ≤ 0.05 mm.
    let s = PreparedCloud::new(&source.cloud, &prep(1.0, false)).unwrap();
    let t = PreparedCloud::new(&target.cloud, &prep(1.0, true)).unwrap();
    let r = register(&s, &t, &start, &IcpConfig::default()).unwrap();
    let e = PoseError::between(&r.pose, &reference, source.cloud.positions());
    eprintln!(
        "point-to-plane 1 mm: {e:?}, {} iterations, fitness {:.3}",
        r.iterations, r.fitness
    );
    assert!(r.converged && r.iterations <= 10);
    assert!(e.rotation_deg <= 0.1 && e.translation_mm <= 0.05, "{e:?}");
    // Generalized ICP, 2 mm voxels: within the reference's 0.1°.
    let s = PreparedCloud::new(&source.cloud, &prep(2.0, true)).unwrap();
    let t = PreparedCloud::new(&target.cloud, &prep(2.0, true)).unwrap();
    let config = IcpConfig {
        metric: Metric::Generalized,
        ..IcpConfig::default()
    };
    let r = register(&s, &t, &start, &config).unwrap();
    let e = PoseError::between(&r.pose, &reference, source.cloud.positions());
    eprintln!("generalized 2 mm: {e:?}, {} iterations", r.iterations);
    assert!(
        r.converged && e.rotation_deg <= 0.1 && e.rms_displacement_mm <= 0.15,
        "{e:?}"
    );
}

#[test]
fn from_the_raw_poses_point_to_plane_converges_where_point_to_point_fails() {
    let Some(dir) = bunny::bunny_dir("bunny registration from the raw poses") else {
        return;
    };
    let (target, source) = (bunny::load(&dir, "bun000"), bunny::load(&dir, "bun045"));
    let reference = bunny::reference(&target, &source);
    let raw = PoseError::between(&Isometry3::identity(), &reference, source.cloud.positions());
    assert!(raw.rotation_deg > 34.0 && raw.translation_mm > 50.0);
    let t = PreparedCloud::new(&target.cloud, &prep(1.0, true)).unwrap();
    let s = PreparedCloud::new(&source.cloud, &prep(1.0, false)).unwrap();
    // Point-to-point with a 5 mm gate stalls far away (as Open3D's does).
    let p2p = IcpConfig {
        metric: Metric::PointToPoint,
        ..IcpConfig::default()
    };
    let r = register(&s, &t, &Isometry3::identity(), &p2p).unwrap();
    let e = PoseError::between(&r.pose, &reference, source.cloud.positions());
    assert!(
        e.rotation_deg > 10.0,
        "point-to-point was expected to fail: {e:?}"
    );
    // Point-to-plane with the same 5 mm gate converges to the reference.
    let r = register(&s, &t, &Isometry3::identity(), &IcpConfig::default()).unwrap();
    let e = PoseError::between(&r.pose, &reference, source.cloud.positions());
    eprintln!(
        "point-to-plane from raw: {e:?}, {} iterations",
        r.iterations
    );
    assert!(
        r.converged && e.rotation_deg <= 0.1 && e.translation_mm <= 0.05,
        "{e:?}"
    );
}

#[test]
fn the_three_scans_merge_within_0_2_degrees_of_the_reference() {
    let Some(dir) = bunny::bunny_dir("bunny merge") else {
        return;
    };
    let names = ["bun000", "bun045", "bun090"];
    let scans: Vec<_> = names.iter().map(|n| bunny::load(&dir, n)).collect();
    let reference: Vec<Isometry3<f64>> = scans
        .iter()
        .map(|s| scans[0].t_world_scan.inverse() * s.t_world_scan)
        .collect();
    // Start every view but the first 5° (alternating sign) about the vertical through its
    // centroid, and 2 mm off, as a rough turntable calibration would.
    let initial: Vec<Isometry3<f64>> = reference
        .iter()
        .zip(&scans)
        .enumerate()
        .map(|(i, (r, s))| {
            if i == 0 {
                return *r;
            }
            let sign = if i % 2 == 0 { -1.0 } else { 1.0 };
            let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), sign * 5f64.to_radians());
            let c = s.cloud.centroid().unwrap().coords;
            let p = Isometry3::from_parts(
                Translation3::from(c - q * c + Vector3::new(2.0, 0.0, 0.0)),
                q,
            );
            r * p
        })
        .collect();
    let views: Vec<_> = scans.iter().map(|s| s.cloud.clone()).collect();
    // The Stanford scans are not in their camera frames: orient nothing (the metrics ignore
    // the sign of normals).
    let config = MergeConfig {
        registration_normals: sl_icp::NormalConfig {
            k: 10,
            orientation: sl_icp::NormalOrientation::Unoriented,
        },
        ..MergeConfig::default()
    };
    let a = align_views(&views, &initial, &config).unwrap();
    for p in &a.pairs {
        eprintln!(
            "pair {} <- {}: used {} fitness {:?} {:?}",
            p.target,
            p.source,
            p.used,
            p.registration.as_ref().map(|r| r.fitness),
            p.failure
        );
    }
    for (i, (got, want)) in a.poses.iter().zip(&reference).enumerate() {
        let e = PoseError::between(got, want, views[i].positions());
        eprintln!("{}: {e:?}", names[i]);
        assert!(e.rotation_deg <= 0.2, "{}: {e:?}", names[i]);
    }
}
