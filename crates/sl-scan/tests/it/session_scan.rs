//! `sl_scan::scan_session` on a session the virtual rig captured through the device
//! traits (`VirtualRig::devices` + `CaptureSession`), as `slscan scan` captures one on the real
//! rig. The rig's turntable has a gear scale of 0.5 platter degrees per motor degree, so the
//! motor angles must come from the calibrated scale for the platter to turn a full turn, and
//! the merge must map them back through it. The merged cloud is compared with the scene's own
//! geometry (two spheres of radius 25 mm), never with an earlier output.

use std::path::Path;
use std::time::Duration;

use nalgebra::Point3;
use sl_codec::{BitDepth, ImageSize};
use sl_rig::{CaptureSession, SessionConfig, SessionDevices, SessionPlan};
use sl_scan::{
    MergeStageConfig, ScanError, SessionScanConfig, full_turn_motor_angles, load_scan_calibration,
    mesh_stage, scaled_rig_config, scan_patterns, scan_session, write_scan_cloud,
};
use sl_sim::{Mount, Scene, Shape, VirtualRig};

/// Views of the test session: 45° apart, enough overlap for the pairwise ICP.
const VIEWS: usize = 8;
/// Platter degrees per motor degree of the test rig (a 2:1 gear).
const GEAR_SCALE: f64 = 0.5;

/// The true spheres in the camera frame of view 0 (motor angle `motor_deg`).
fn true_spheres(rig: &VirtualRig, motor_deg: f64) -> Vec<(Point3<f64>, f64)> {
    let t_cam_table = rig.config().t_cam_table_at(motor_deg);
    rig.scene()
        .objects
        .iter()
        .filter_map(|o| match o.shape {
            Shape::Sphere { radius } if matches!(o.mount, Mount::Turntable) => Some((
                Point3::from((t_cam_table * o.pose).translation.vector),
                radius,
            )),
            _ => None,
        })
        .collect()
}

#[allow(clippy::unwrap_used)] // a test helper: its failure is the test's
fn first_png(dir: &Path) -> std::path::PathBuf {
    let mut pngs: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    pngs.sort();
    pngs.swap_remove(0)
}

#[test]
fn a_captured_session_is_reconstructed_and_merged_onto_the_true_spheres() {
    let tmp = tempfile::tempdir().unwrap();
    let mut config = scaled_rig_config(2);
    config.angle_scale = GEAR_SCALE;
    config.angle_offset_deg = 7.0;
    let rig = VirtualRig::new(config, Scene::dumbbell()).unwrap();

    // The calibration file a real scan is given: here the rig's exact calibration (the
    // reconstruction is under test, not the calibration), with its turntable axis, offset and
    // scale.
    let calib_path = tmp.path().join("calibration.json");
    let truth = rig.config().calibration();
    assert_eq!(truth.turntable.map(|a| a.angle_scale), Some(GEAR_SCALE));
    truth.save(&calib_path).unwrap();
    let calibration = load_scan_calibration(&calib_path).unwrap();

    // Motor angles for a full platter turn: 90° motor steps at a 0.5 scale are 45° platter
    // steps.
    let angles = full_turn_motor_angles(calibration.turntable.as_ref(), VIEWS).unwrap();
    assert_eq!(angles.len(), VIEWS);
    for (k, a) in angles.iter().enumerate() {
        assert!((a - 90.0 * k as f64).abs() < 1e-9, "{angles:?}");
    }

    let p = rig.config().projector.size;
    let plan = SessionPlan {
        angles_deg: angles.clone(),
        manifest: scan_patterns(ImageSize::new(p.width, p.height), 15.0).manifest(BitDepth::Eight),
        devices: SessionDevices {
            camera: "virtual".to_owned(),
            projector: "virtual".to_owned(),
            turntable: "virtual, 2:1 gear".to_owned(),
            right_camera: None,
        },
        calibration: Some(calib_path.clone()),
        exposures: Default::default(),
        colour: false,
    };
    let session_dir = tmp.path().join("session");
    let session = CaptureSession::open(
        &session_dir,
        plan,
        SessionConfig {
            display_latency: Duration::ZERO,
            flush_frames: 0,
            overwrite: false,
            check_frames: true,
        },
    )
    .unwrap();
    let (mut camera, mut projector, mut table) = rig.devices();
    session
        .run(&mut camera, &mut projector, &mut table, |_| {})
        .unwrap();

    // The calibrated poses alone: with the exact calibration they are exact, and ICP on a
    // dumbbell seen every 45° has a free rotation about the bar (it moves views by degrees
    // here), so the refinement is left to the dense scans it is made for.
    let config = SessionScanConfig {
        merge: MergeStageConfig {
            icp_refinement: false,
            ..MergeStageConfig::default()
        },
        ..SessionScanConfig::default()
    };
    let mut stages = Vec::new();
    let scan = scan_session(&session_dir, &calibration, &config, |p| {
        if stages.last() != Some(&p.stage.to_owned()) {
            stages.push(p.stage.to_owned());
        }
    })
    .unwrap();
    assert_eq!(stages, ["reconstruct", "merge"]);
    assert_eq!(scan.motor_angles_deg, angles);
    for (k, a) in scan.platter_angles_deg.iter().enumerate() {
        assert!((a - (7.0 + 45.0 * k as f64)).abs() < 1e-9, "{k}: {a}");
    }
    assert_eq!(scan.view_points.len(), VIEWS);
    assert!(scan.view_points.iter().all(|&n| n > 1000), "{scan:?}");

    // Every merged point against the nearest true sphere. The views were captured through
    // the motor, 2:1 geared: had the merge ignored the scale, the views 45° apart would be
    // placed 90° apart and the spheres 60 mm off the axis would smear over tens of mm.
    let spheres = true_spheres(&rig, angles[0]);
    assert_eq!(spheres.len(), 2);
    let (mut sq, mut n, mut outliers) = (0.0, 0usize, 0usize);
    let mut per_sphere = [0usize; 2];
    for q in scan.merged.positions() {
        let (i, d) = spheres
            .iter()
            .enumerate()
            .map(|(i, (c, r))| (i, (q - c).norm() - r))
            .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .unwrap();
        // 2 mm: 20 times the accuracy asserted below, only mis-decoded or mis-merged points.
        if d.abs() > 2.0 {
            outliers += 1;
        } else {
            sq += d * d;
            n += 1;
            per_sphere[i] += 1;
        }
    }
    let rms = (sq / n as f64).sqrt();
    // The true calibration at half resolution: a single view measures 0.04 mm RMS to the
    // true spheres here; 0.1 mm leaves room for the merge's averaging and still fails on a
    // view misplaced by a tenth of a degree (60 mm off the axis × 0.1° = 0.1 mm).
    assert!(rms < 0.1, "RMS to the true spheres {rms} mm");
    assert!(outliers * 100 < scan.merged.len(), "{outliers} outliers");
    assert!(per_sphere.iter().all(|&c| c > 5000), "{per_sphere:?}");

    // The files.
    let out = tmp.path().join("out");
    let files = write_scan_cloud(&out, &scan.merged, |_| {}).unwrap();
    let back = sl_cloud::read_ply(&out.join(&files.merged)).unwrap();
    assert_eq!(back.len(), scan.merged.len());
    assert_eq!(files.previews.len(), 4);
    for f in &files.previews {
        let bytes = std::fs::read(out.join(f)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "{f}");
    }

    // The mesh stage as `slscan scan` runs it on hardware: no truth, the files beside the
    // cloud. The mesh closes what the 8 views at half resolution did not see (the spheres'
    // poles and the faces turned away between views, measured at 10-20 % of the vertices here,
    // bridged up to 2 mm off), so its vertices are held to the spheres by the median (the
    // cloud's RMS bound above) and the best 80 % within 0.3 mm (three times it).
    let poisson = sl_mesh::PoissonConfig {
        depth: 7,
        ..sl_mesh::PoissonConfig::default()
    };
    let (summary, mesh_files) = mesh_stage(&scan.merged, None, None, &poisson, &out).unwrap();
    assert!(summary.watertight && summary.manifold, "{summary:?}");
    assert!(summary.accuracy_vertices.is_none() && summary.accuracy_area.is_none());
    // Simplified by default (coarse cells on a half-resolution scan: measured 50 % of the
    // vertices kept).
    assert!(
        summary.simplify_ms.is_some() && summary.vertices * 5 < summary.vertices_extracted * 3,
        "{summary:?}"
    );
    let mesh = sl_mesh::read_ply_mesh(&out.join(&mesh_files.ply)).unwrap();
    assert_eq!(mesh.triangles.len(), summary.triangles);
    for f in [&mesh_files.stl, &mesh_files.preview, &mesh_files.view3d] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let mut d: Vec<f64> = mesh
        .vertices
        .iter()
        .map(|q| {
            spheres
                .iter()
                .map(|(c, r)| ((q - c).norm() - r).abs())
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    d.sort_by(f64::total_cmp);
    let median = d[d.len() / 2];
    let p80 = d[d.len() * 8 / 10];
    assert!(
        median < 0.1 && p80 < 0.3,
        "mesh to spheres: median {median} mm, p80 {p80} mm"
    );

    // A corrupt frame: the error names the view and its folder.
    let view3 = session_dir.join("view_003");
    std::fs::write(first_png(&view3), b"not a png").unwrap();
    let err = scan_session(&session_dir, &calibration, &config, |_| {}).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("view 3") && text.contains(&view3.display().to_string()),
        "{text}"
    );

    // A view never captured (an interrupted session): named, with what to do.
    std::fs::remove_dir_all(&view3).unwrap();
    let err = scan_session(&session_dir, &calibration, &config, |_| {}).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("view 3") && text.contains("resume"), "{text}");
}

/// RMS distance (mm) of `cloud` to the nearest of `spheres` over the points within 2 mm of
/// one, and the number of points farther.
fn distance_to_spheres(
    cloud: &sl_cloud::PointCloud,
    spheres: &[(Point3<f64>, f64)],
) -> (f64, usize) {
    let (mut sq, mut n, mut outliers) = (0.0, 0usize, 0usize);
    for q in cloud.positions() {
        let d = spheres
            .iter()
            .map(|(c, r)| (q - c).norm() - r)
            .fold(f64::INFINITY, |m, d| if d.abs() < m.abs() { d } else { m });
        if d.abs() > 2.0 {
            outliers += 1;
        } else {
            sq += d * d;
            n += 1;
        }
    }
    ((sq / n.max(1) as f64).sqrt(), outliers)
}

/// The default path of `slscan scan` on hardware: 36 views 10° apart and an axis calibrated
/// 0.2° and 0.5 mm off, refined by ICP. The calibrated poses alone misplace the spheres by
/// tenths of a millimetre; the refinement must bring the merged cloud back onto the truth.
/// Renders 36 views: release only,
/// `cargo test --release -p sl-scan --test it -- --include-ignored session_scan::a_dense`.
#[test]
#[cfg_attr(debug_assertions, ignore = "renders 36 views: run in release")]
fn a_dense_session_with_an_approximate_axis_is_refined_onto_the_true_spheres() {
    let tmp = tempfile::tempdir().unwrap();
    let rig = VirtualRig::new(scaled_rig_config(2), Scene::dumbbell()).unwrap();
    let mut calibration = rig.config().calibration();
    let mut axis = calibration.turntable.unwrap();
    let tilt = nalgebra::UnitQuaternion::from_axis_angle(
        &nalgebra::Vector3::x_axis(),
        0.2f64.to_radians(),
    );
    axis.direction = tilt * axis.direction;
    axis.point_mm += nalgebra::Vector3::new(0.5, 0.0, 0.0);
    calibration.turntable = Some(axis);
    let calib_path = tmp.path().join("calibration.json");
    calibration.save(&calib_path).unwrap();

    let angles = full_turn_motor_angles(Some(&axis), 36).unwrap();
    let p = rig.config().projector.size;
    let session_dir = tmp.path().join("session");
    let session = CaptureSession::open(
        &session_dir,
        SessionPlan {
            angles_deg: angles.clone(),
            manifest: scan_patterns(ImageSize::new(p.width, p.height), 15.0)
                .manifest(BitDepth::Eight),
            devices: SessionDevices {
                camera: "virtual".to_owned(),
                projector: "virtual".to_owned(),
                turntable: "virtual".to_owned(),
                right_camera: None,
            },
            calibration: Some(calib_path),
            exposures: Default::default(),
            colour: false,
        },
        SessionConfig {
            display_latency: Duration::ZERO,
            ..SessionConfig::default()
        },
    )
    .unwrap();
    let (mut camera, mut projector, mut table) = rig.devices();
    session
        .run(&mut camera, &mut projector, &mut table, |_| {})
        .unwrap();
    let spheres = true_spheres(&rig, angles[0]);

    let placed = scan_session(
        &session_dir,
        &calibration,
        &SessionScanConfig {
            merge: MergeStageConfig {
                icp_refinement: false,
                ..MergeStageConfig::default()
            },
            ..SessionScanConfig::default()
        },
        |_| {},
    )
    .unwrap();
    let (rms_placed, _) = distance_to_spheres(&placed.merged, &spheres);
    let refined = scan_session(
        &session_dir,
        &calibration,
        &SessionScanConfig::default(),
        |_| {},
    )
    .unwrap();
    let (rms, outliers) = distance_to_spheres(&refined.merged, &spheres);
    eprintln!(
        "dense session, axis 0.2 deg / 0.5 mm off: RMS to the true spheres {rms_placed:.4} mm with the calibrated poses, {rms:.4} mm refined ({outliers} outliers of {}); {}",
        refined.merged.len(),
        refined.merge.summary
    );
    assert_eq!(
        refined.merge.axis_confirmed,
        Some(false),
        "{:?}",
        refined.merge
    );
    // The error the refinement has to remove is there...
    assert!(rms_placed > 0.15, "{rms_placed}");
    // ...and reduced: the default sees the axis is wrong (7.4 σ) and takes the registered
    // one: 0.169 mm measured 2026-11-28 (0.387 mm with the calibrated poses). Issue 28 asks
    // for better than the calibrated poses; half their error is held. The free pose graph,
    // the default before, measured 0.035 mm here and sl-icp's former turntable model 0.93 mm:
    // the registered axis of the dumbbell is not yet as good as its free pose graph
    // (docs/registration.md).
    assert!(rms < 0.5 * rms_placed, "{rms} vs {rms_placed}");
    assert!(outliers * 100 < refined.merged.len(), "{outliers}");
}

/// Captures a dumbbell session of `views` views on `rig` into `dir` with `calibration`'s
/// motor angles (saved beside it as `calibration.json`); returns the motor angles.
#[allow(clippy::unwrap_used)] // a test helper: its failure is the test's
fn capture_dumbbell(
    rig: &VirtualRig,
    calibration: &sl_camera::Calibration,
    views: usize,
    dir: &Path,
) -> Vec<f64> {
    let calib_path = dir.join("calibration.json");
    calibration.save(&calib_path).unwrap();
    let angles = full_turn_motor_angles(calibration.turntable.as_ref(), views).unwrap();
    let p = rig.config().projector.size;
    let session = CaptureSession::open(
        &dir.join("session"),
        SessionPlan {
            angles_deg: angles.clone(),
            manifest: scan_patterns(ImageSize::new(p.width, p.height), 15.0)
                .manifest(BitDepth::Eight),
            devices: SessionDevices {
                camera: "virtual".to_owned(),
                projector: "virtual".to_owned(),
                turntable: "virtual".to_owned(),
                right_camera: None,
            },
            calibration: Some(calib_path),
            exposures: Default::default(),
            colour: false,
        },
        SessionConfig {
            display_latency: Duration::ZERO,
            flush_frames: 0,
            overwrite: false,
            check_frames: true,
        },
    )
    .unwrap();
    let (mut camera, mut projector, mut table) = rig.devices();
    session
        .run(&mut camera, &mut projector, &mut table, |_| {})
        .unwrap();
    angles
}

/// Issue 28: on the dumbbell — two spheres on a bar, whose pairwise registrations leave the
/// spheres free to turn on themselves — the default merge must not be worse than the
/// calibrated turntable's poses alone. A calibration as good as the rig's (axis 0.005° /
/// 0.03 mm off, sl-calib's accuracy) at quarter resolution, 18 views 20° apart. Before the
/// fix, the default (the free pose graph) spread the pairwise registrations' errors over the
/// views; the turntable model before it, fed the point-to-point information that claims the
/// spheres' rotations are measured, replaced the axis by a wrong one.
#[test]
fn the_default_merge_of_a_dumbbell_is_not_worse_than_the_calibrated_turntable() {
    let tmp = tempfile::tempdir().unwrap();
    let rig = VirtualRig::new(scaled_rig_config(4), Scene::dumbbell()).unwrap();
    let mut calibration = rig.config().calibration();
    let mut axis = calibration.turntable.unwrap();
    let tilt = nalgebra::UnitQuaternion::from_axis_angle(
        &nalgebra::Vector3::x_axis(),
        0.005f64.to_radians(),
    );
    axis.direction = tilt * axis.direction;
    axis.point_mm += nalgebra::Vector3::new(0.03, 0.0, 0.0);
    calibration.turntable = Some(axis);
    let angles = capture_dumbbell(&rig, &calibration, 18, tmp.path());
    let spheres = true_spheres(&rig, angles[0]);
    let session = tmp.path().join("session");
    let with = |icp_refinement: bool| {
        scan_session(
            &session,
            &calibration,
            &SessionScanConfig {
                merge: MergeStageConfig {
                    icp_refinement,
                    ..MergeStageConfig::default()
                },
                ..SessionScanConfig::default()
            },
            |_| {},
        )
        .unwrap()
    };
    let placed = with(false);
    let merged = with(true);
    let (rms_placed, _) = distance_to_spheres(&placed.merged, &spheres);
    let (rms, outliers) = distance_to_spheres(&merged.merged, &spheres);
    eprintln!(
        "dumbbell, 18 views, calibrated axis: RMS {rms_placed:.4} mm with the turntable poses, {rms:.4} mm merged; {}",
        merged.merge.summary
    );
    // The same views and voxels: equal when the calibration is kept, and 0.2 % of slack for
    // the order of the floating-point sums of a different pose.
    assert!(rms <= rms_placed * 1.002, "{rms} > {rms_placed}");
    assert!(outliers * 100 < merged.merged.len(), "{outliers}");
    // Every view says where its pose came from; the calibrated axis is confirmed.
    assert_eq!(merged.merge.views.len(), 18);
    assert_eq!(merged.merge.views[0].source, "reference");
    assert_eq!(
        merged.merge.axis_confirmed,
        Some(true),
        "{:?}",
        merged.merge
    );
    assert!(
        merged
            .merge
            .summary
            .starts_with("18 views: axis from the calibration")
    );
}

#[test]
fn a_calibration_without_turntable_axis_is_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let mut calibration = scaled_rig_config(4).calibration();
    calibration.turntable = None;
    let path = tmp.path().join("no_axis.json");
    calibration.save(&path).unwrap();
    let err = load_scan_calibration(&path).unwrap_err();
    assert!(matches!(err, ScanError::Stage { .. }), "{err:?}");
    let text = err.to_string();
    assert!(
        text.contains(&path.display().to_string()) && text.contains("slscan calibrate turntable"),
        "{text}"
    );

    // scan_session refuses it too, naming the calibration the session recorded,
    // before reading any view (this session has none).
    let session = tmp.path().join("session");
    let p = scaled_rig_config(4).projector.size;
    CaptureSession::open(
        &session,
        SessionPlan {
            angles_deg: vec![0.0, 180.0],
            manifest: scan_patterns(ImageSize::new(p.width, p.height), 15.0)
                .manifest(BitDepth::Eight),
            devices: SessionDevices {
                camera: "none".to_owned(),
                projector: "none".to_owned(),
                turntable: "none".to_owned(),
                right_camera: None,
            },
            calibration: Some(path.clone()),
            exposures: Default::default(),
            colour: false,
        },
        SessionConfig::default(),
    )
    .unwrap();
    let err = scan_session(
        &session,
        &calibration,
        &SessionScanConfig::default(),
        |_| {},
    )
    .unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("no turntable axis") && text.contains(&path.display().to_string()),
        "{text}"
    );

    // A missing calibration file is named.
    let missing = tmp.path().join("missing.json");
    let err = load_scan_calibration(&missing).unwrap_err();
    assert!(err.to_string().contains("missing.json"), "{err}");
}

#[test]
fn motor_angles_refuse_a_zero_scale() {
    let mut axis = scaled_rig_config(4).turntable_axis();
    axis.angle_scale = 0.0;
    assert!(full_turn_motor_angles(Some(&axis), 4).is_err());
    assert_eq!(
        full_turn_motor_angles(None, 4).unwrap(),
        vec![0.0, 90.0, 180.0, 270.0]
    );
}
