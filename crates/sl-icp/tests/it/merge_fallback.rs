//! `align_views` falls back to global registration for a pair whose ICP from the turntable
//! poses fails: the bunny scans (`$SL_DATA/bunny`, skipped with a note when `SL_DATA` is
//! unset) from their nominal angles (0°, 45°, 90° about the scanner's vertical axis, while
//! bun045 really sits 34° and 53 mm away), against `bun.conf`. A merge that registers nothing
//! is an error that names the views and carries every pair's figures.

#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: helpers fail loudly

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use sl_icp::{IcpError, MergeConfig, PointCloud, PoseError, align_views};

use crate::support::bunny;

/// The merge settings of `tests/it/bunny.rs`: the Stanford scans are not in their camera
/// frames, so normals are left unoriented.
fn config() -> MergeConfig {
    MergeConfig {
        registration_normals: sl_icp::NormalConfig {
            k: 10,
            orientation: sl_icp::NormalOrientation::Unoriented,
        },
        ..MergeConfig::default()
    }
}

#[test]
fn bunny_from_nominal_angles_merges_through_the_global_fallback() {
    let Some(dir) = bunny::bunny_dir("bunny merge with global fallback") else {
        return;
    };
    let names = ["bun000", "bun045", "bun090"];
    let scans: Vec<_> = names.iter().map(|n| bunny::load(&dir, n)).collect();
    let views: Vec<PointCloud> = scans.iter().map(|s| s.cloud.clone()).collect();
    // Nominal turntable poses: a rotation by the motor angle about +y through the origin.
    let nominal: Vec<Isometry3<f64>> = [0.0f64, 45.0, 90.0]
        .iter()
        .map(|a| {
            Isometry3::from_parts(
                Default::default(),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), a.to_radians()),
            )
        })
        .collect();
    let a = align_views(&views, &nominal, &config()).unwrap();
    assert!(a.pairs.iter().any(|p| p.used && p.global), "{:?}", a.pairs);
    for i in 1..3 {
        let reference = bunny::reference(&scans[0], &scans[i]);
        let e = PoseError::between(&a.poses[i], &reference, views[i].positions());
        eprintln!("{}: {e:?}", names[i]);
        assert!(e.rms_displacement_mm <= 1.0, "{}: {e:?}", names[i]);
    }
    // Without the fallback the same merge does not place the views right.
    let no_fallback = MergeConfig {
        global_fallback: None,
        ..config()
    };
    let wrong = align_views(&views, &nominal, &no_fallback).map_or(f64::INFINITY, |a| {
        PoseError::between(
            &a.poses[1],
            &bunny::reference(&scans[0], &scans[1]),
            views[1].positions(),
        )
        .rms_displacement_mm
    });
    assert!(wrong > 5.0, "{wrong}");
}

/// A bumpy patch and a flat plate 200 mm away: nothing registers.
#[test]
fn a_merge_that_registers_nothing_names_the_views() {
    let bumpy: Vec<Point3<f64>> = (0..6400)
        .map(|i| {
            let (x, y) = (f64::from(i % 80), f64::from(i / 80));
            Point3::new(x, y, 5.0 * (x / 7.0).sin() * (y / 11.0).cos())
        })
        .collect();
    let plate: Vec<Point3<f64>> = (0..6400)
        .map(|i| Point3::new(f64::from(i % 80), f64::from(i / 80), 200.0))
        .collect();
    let views = vec![
        PointCloud::from_positions(bumpy),
        PointCloud::from_positions(plate),
    ];
    let err =
        align_views(&views, &[Isometry3::identity(); 2], &MergeConfig::default()).unwrap_err();
    let IcpError::ViewsNotPlaced { views, why, pairs } = &err else {
        panic!("expected ViewsNotPlaced, got {err}");
    };
    assert_eq!(views, &vec![1]);
    assert!(!pairs.is_empty() && pairs.iter().all(|p| !p.used && p.failure.is_some()));
    assert!(err.to_string().contains("[1]"), "{err}");
    assert!(!why.is_empty());
}
