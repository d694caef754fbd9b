//! The end-to-end scan of `slscan scan`, small: the virtual rig at half resolution, 8 views,
//! calibrated from 8 simulated board poses. Checks the merged cloud against the known
//! dumbbell (two spheres of radius 25 mm, centres 120 mm apart), the flatness of the tilted
//! plate, that `slscan report` on the written PLY and truth reproduces the figures, and that
//! every file the user is promised exists. The ground truth is the scene's own geometry, not an earlier output.

use sl_scan::{ScanProgress, VirtualScanConfig, scan_virtual, write_summary_html};

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "a full simulation, minutes unoptimised: .ci/run runs it (step \"full simulations\")"
)]
fn a_small_virtual_scan_measures_the_dumbbell() {
    let out = tempfile::tempdir().unwrap();
    let cfg = VirtualScanConfig {
        views: 8,
        calibration_poses: 8,
        resolution_divisor: 2,
        ..VirtualScanConfig::default()
    };
    let mut stages = Vec::new();
    let result = scan_virtual(&cfg, out.path(), |p: ScanProgress<'_>| {
        if stages.last() != Some(&p.stage.to_owned()) {
            stages.push(p.stage.to_owned());
        }
    })
    .unwrap();
    assert_eq!(
        stages,
        [
            "calibrate",
            "capture",
            "reconstruct",
            "merge",
            "plate",
            "report"
        ]
    );

    // The estimated calibration, not the true one: close to the rig's truth. At half
    // resolution corner noise doubles in mm; the full-resolution run gives 0.006 deg and
    // 0.12 mm, and the sl-calib targets are 0.05 deg / 0.1 % on fx.
    let c = &result.calibration_summary;
    assert!(c.axis_direction_error_deg < 0.05, "{c:?}");
    assert!(c.camera_fx_error_percent.abs() < 0.2, "{c:?}");
    assert!(c.baseline_error_mm < 1.0, "{c:?}");

    // Accuracy against the truth (the scene's geometry: radius 25 mm, centres 120 mm apart).
    // Full resolution measures 0.07 mm RMS, spacing 0.005 mm and size 0.016 mm
    // (docs/user-guide.md); half resolution doubles the pixel footprint on the object, so the
    // bounds allow about twice the full-resolution figures plus margin. The RMS is in the
    // estimated camera frame: the calibration's frame error (a few tenths of a mm of shift
    // at half resolution) adds to every point.
    let a = &result.accuracy;
    for line in a.summary() {
        eprintln!("{line}");
    }
    for line in result.flatness.iter().flat_map(|f| f.summary()) {
        eprintln!("{line}");
    }
    assert_eq!(a.spheres.len(), 2);
    assert!(a.rms_to_reference_mm < 0.6, "{a:?}");
    assert_eq!(a.sphere_pairs.len(), 1);
    assert!((a.sphere_pairs[0].nominal_distance_mm - 120.0).abs() < 1e-9);
    assert!(a.sphere_pairs[0].sphere_spacing_mm.abs() < 0.15, "{a:?}");
    for s in &a.spheres {
        assert!(s.points > 1000, "{s:?}");
        assert!(s.probing_size_mm.abs() < 0.15, "{s:?}");
        assert!((s.radius_mm - 25.0).abs() < 0.1, "{s:?}");
        // The shape error alone (residuals of the free fit): 0.04 mm at half resolution.
        assert!(s.fit_rms_mm < 0.1, "{s:?}");
    }
    // Most merged points lie on the true spheres.
    assert!(
        (a.points - a.assigned_points) * 100 < result.merged.len(),
        "{a:?}"
    );

    // Flatness of the tilted plate: one view through the same calibration and triangulation.
    // The sl-tri target is a plane RMS of 0.02 mm at full resolution; at half resolution
    // allow 0.05 mm RMS, and a range within 12 σ of it.
    let f = result
        .flatness
        .as_ref()
        .expect("the plate is captured by default");
    let plate = &f.planes[0];
    assert!(plate.points > 10_000, "{plate:?}");
    assert!(plate.fit_rms_mm < 0.05, "{plate:?}");
    assert!(
        plate.flatness_trimmed_mm < 12.0 * plate.fit_rms_mm.max(0.01),
        "{plate:?}"
    );
    // The plate's normal is the true one (to the calibration's rotation error, < 0.5 deg).
    let truth_normal = match &sl_metrology::Truth::load(&out.path().join("plate_truth.json"))
        .unwrap()
        .features[0]
    {
        sl_metrology::Feature::Plane(p) => p.nominal.unwrap().normal,
        other => panic!("{other:?}"),
    };
    assert!(
        plate.normal.dot(&truth_normal).abs() > 0.5f64.to_radians().cos(),
        "{plate:?}"
    );

    // `slscan report merged.ply --truth truth.json` computes exactly these figures: the PLY
    // is binary double and the JSON round-trips every f64.
    let merged = sl_cloud::read_ply(&out.path().join("merged.ply")).unwrap();
    let truth = sl_metrology::Truth::load(&out.path().join("truth.json")).unwrap();
    assert_eq!(truth, result.truth);
    let again = sl_metrology::evaluate(&merged, &truth).unwrap();
    assert_eq!(
        serde_json::to_value(&again).unwrap(),
        serde_json::to_value(a).unwrap()
    );
    let bits = |r: &sl_metrology::Report| -> Vec<u32> {
        r.signed_distances_mm.iter().map(|d| d.to_bits()).collect()
    };
    assert_eq!(bits(&again), bits(a));
    let plate_cloud = sl_cloud::read_ply(&out.path().join("plate.ply")).unwrap();
    let plate_truth = sl_metrology::Truth::load(&out.path().join("plate_truth.json")).unwrap();
    assert_eq!(
        serde_json::to_value(sl_metrology::evaluate(&plate_cloud, &plate_truth).unwrap()).unwrap(),
        serde_json::to_value(f).unwrap()
    );

    // The files.
    for f in [
        "calibration.json",
        "merged.ply",
        "error_map.png",
        "truth.json",
        "plate.ply",
        "plate_truth.json",
        "plate_error_map.png",
        "session/session.json",
        "session/view_007/manifest.json",
    ] {
        assert!(out.path().join(f).is_file(), "{f} missing");
    }
    let cloud = sl_cloud::read_ply(&out.path().join("merged.ply")).unwrap();
    assert_eq!(cloud.len(), result.merged.len());
    let html = write_summary_html(out.path(), &result).unwrap();
    let text = std::fs::read_to_string(html).unwrap();
    assert!(text.contains("preview_0.png") && text.contains("error_map.png"));

    // Run again: the session is complete, nothing is captured anew, the figures are the same.
    let again = scan_virtual(&cfg, out.path(), |_| {}).unwrap();
    assert_eq!(again.views_captured, 0);
    assert_eq!(again.view_points, result.view_points);
}

/// The grazing-angle filter keeps a point whose normal faces both the camera (the origin) and
/// the projector within the limit, and drops one seen or lit more obliquely; points without a
/// normal stay. Angles are constructed, not measured: a point on the optical axis with its
/// normal tilted by a known angle about y, the projector on the x axis.
#[test]
fn grazing_points_are_dropped() {
    use nalgebra::{Point3, Vector3};
    use sl_scan::drop_grazing;
    let p = Point3::new(0.0, 0.0, 400.0);
    let tilted = |deg: f64| {
        let a = f64::to_radians(deg);
        // Rotated about y from -z (facing the camera) toward -x.
        Vector3::new(-a.sin(), 0.0, -a.cos())
    };
    // The projector 100 mm to the right: seen from p at atan(100/400) = 14.0 deg, on the
    // side the normal tilts away from, so its angle is the tilt + 14.0 deg.
    let projector = Point3::new(100.0, 0.0, 0.0);
    let cloud = sl_cloud::PointCloud::from_positions(vec![p; 4])
        .with_normals(vec![
            tilted(10.0),
            tilted(50.0),
            tilted(65.0),
            Vector3::zeros(),
        ])
        .unwrap();
    // Limit 70 deg: 10 (24 to the projector) and 50 (64) stay, 65 (79 to the projector) goes.
    let kept = drop_grazing(cloud.clone(), &projector, 70.0).unwrap();
    assert_eq!(kept.len(), 3);
    assert_eq!(kept.normals().unwrap()[1], tilted(50.0));
    assert_eq!(kept.normals().unwrap()[2], Vector3::zeros());
    // 90 keeps everything; a limit of 0 or NaN is refused.
    assert_eq!(
        drop_grazing(cloud.clone(), &projector, 90.0).unwrap().len(),
        4
    );
    assert!(drop_grazing(cloud, &projector, f64::NAN).is_err());
}
