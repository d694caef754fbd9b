//! Issue 7's virtual-rig target end to end: 36 views at 10° of a known object on the virtual
//! turntable, each RENDERED by sl-rig (default 1280×720 camera, 1920×1080 projector, sensor
//! noise, projector blur), DECODED by sl-codec (hybrid: 8-step phase shift, 64 periods, plus
//! the complementary Gray code, on the columns) and TRIANGULATED by sl-tri (ray–plane) as the
//! scan does (`sl_scan::reconstruct_decoded`: smoothed coordinates, 3 px edge erosion), then
//! merged by sl-icp's `merge_views` starting from the poses of the calibrated turntable axis.
//!
//! The object is the rig's 100 mm cube turned 30° on the table (a sphere or a cylinder would
//! leave the rotation about the axis unobservable). Its surface in the merged frame (view 0's
//! camera frame) is known exactly, so the merged cloud's distance to it is the figure.
//!
//! Issue 7 targets: RMS distance to the true surface ≤ 0.03 mm, merge of 36 views of ~100k
//! points ≤ 5 s on 2 cores. Issue 28: the default merge (the turntable model: the calibrated
//! turntable kept where the registrations confirm it) is at least as good as the calibrated
//! turntable's poses alone, and corrects an axis off by 0.5° / 1 mm. The figures are in
//! `docs/registration.md`. Rendering 36 views takes minutes in the dev profile, so the test is
//! ignored there; run it with
//!
//! ```sh
//! cargo test --release --test turntable_merge -- --nocapture
//! ```

// Test helpers (not `#[test]` functions) unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::Instant;

use nalgebra::{Isometry3, Point3, Vector3};
use sl_cloud::{PlyFormat, read_ply, write_ply};
use sl_codec::{
    Axis, BitDepth, CaptureSet, DecodeConfig, Frames, HybridSpec, ImageSize, Pattern,
    PatternSequence, decode,
};
use sl_icp::{
    MergeConfig, PointCloud, PoseError, PoseModel, TurntableAxis, TurntablePrior, merge_aligned,
    merge_views, turntable_poses,
};
use sl_rig::GreyImage;
use sl_scan::{ReconstructConfig, reconstruct_decoded};
use sl_sim::{RigConfig, Scene, VirtualRig, projector_images};
use sl_tri::{Method, TriConfig, Triangulator};

/// Views of the turn and their spacing (the seed's scan).
const VIEWS: usize = 36;
const STEP_DEG: f64 = 10.0;

/// Issue 7's accuracy target for the merged cloud (mm).
const TARGET_RMS_MM: f64 = 0.03;

/// Issue 7's time target for the 36-view merge (s); printed, never asserted (speed belongs to
/// benches; `cargo bench -p sl-icp --bench merge` measures it on sampled views).
const TARGET_MERGE_S: f64 = 5.0;

/// The axis error of `sl-calib`'s turntable fit on this rig (issue 5's measurement: ~0.005°
/// and ~0.03 mm): the "calibrated" turntable the merge starts from.
const CALIBRATED_TILT_DEG: f64 = 0.005;
const CALIBRATED_SHIFT_MM: f64 = 0.03;

/// Bound on the merge from the poorly calibrated axis (measured 0.0552 mm: the registrations'
/// own bias, see the crate docs of `sl-icp`), 25 % over the measurement.
const POOR_RMS_BOUND_MM: f64 = 0.07;

/// A poorly calibrated axis, which the registrations must correct.
const POOR_TILT_DEG: f64 = 0.5;
const POOR_SHIFT_MM: f64 = 1.0;

/// Environment variable naming a folder that caches the triangulated views between runs.
const CACHE_ENV: &str = "SL_TURNTABLE_MERGE_CACHE";

/// Full side of the rig's cube (`Scene::cuboid`), mm.
const CUBE_SIDE_MM: f64 = 100.0;

fn to_frames(images: Vec<GreyImage>) -> Frames {
    let mut u8s = Vec::new();
    let mut u16s = Vec::new();
    for img in images {
        match img {
            GreyImage::U8(f) => u8s.push(f),
            GreyImage::U16(f) => u16s.push(f),
        }
    }
    assert!(u8s.is_empty() || u16s.is_empty(), "mixed bit depths");
    if u16s.is_empty() {
        Frames::U8(u8s)
    } else {
        Frames::U16(u16s)
    }
}

/// Unsigned distance from `p` to the surface of the cube of side [`CUBE_SIDE_MM`] centred on
/// the origin of its frame, `p` given in that frame (exact signed-distance formula of a box).
fn cube_distance(p: &Point3<f64>) -> f64 {
    let h = CUBE_SIDE_MM / 2.0;
    let q = Vector3::new(p.x.abs() - h, p.y.abs() - h, p.z.abs() - h);
    let outside = q.map(|v| v.max(0.0)).norm();
    let inside = q.x.max(q.y).max(q.z).min(0.0);
    (outside + inside).abs()
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

#[test]
fn cube_cube_distance_is_exact() {
    // The formula against points whose distance is obvious.
    assert_eq!(cube_distance(&Point3::new(0.0, 0.0, 50.0)), 0.0);
    assert_eq!(cube_distance(&Point3::new(0.0, 0.0, 52.0)), 2.0);
    assert_eq!(cube_distance(&Point3::new(0.0, 10.0, 45.0)), 5.0);
    assert_eq!(cube_distance(&Point3::new(53.0, 54.0, 0.0)), 5.0);
    assert_eq!(cube_distance(&Point3::origin()), 50.0);
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "renders 36 views: minutes in the dev profile; run with --release"
)]
fn rendered_turntable_scan_merges_onto_the_true_surface() {
    let config = RigConfig::default();
    let calibration = config.calibration();
    let axis = calibration.turntable.unwrap();
    let rig = VirtualRig::new(config, Scene::cuboid()).unwrap();
    let projector = ImageSize::new(1920, 1080);
    let sequence = PatternSequence::new(projector).with(Pattern::Hybrid(
        HybridSpec::complementary(Axis::Column, projector, 8, 64.0),
    ));
    let manifest = sequence.manifest(BitDepth::Eight);
    let images = projector_images(&rig, &manifest).unwrap();
    let tri = Triangulator::new(&calibration).unwrap();
    let options = TriConfig::with_method(Method::RayPlane { axis: Axis::Column });

    let angles: Vec<f64> = (0..VIEWS).map(|i| i as f64 * STEP_DEG).collect();
    let t = Instant::now();
    let mut views: Vec<PointCloud> = Vec::with_capacity(VIEWS);
    let mut t_cam_cube: Vec<Isometry3<f64>> = Vec::with_capacity(VIEWS);
    let mut view_sq = 0.0;
    let mut view_n = 0usize;
    // Developers iterating on the merge can keep the triangulated views between runs:
    // `SL_TURNTABLE_MERGE_CACHE=DIR` reads `DIR/view_NN.ply` when present, else renders the view
    // and writes it there (double-precision PLY: a bit-exact round trip).
    let cache = std::env::var_os(CACHE_ENV).map(std::path::PathBuf::from);
    for (i, &angle) in angles.iter().enumerate() {
        let view = rig.view(angle, i as u64).unwrap();
        let cached = cache.as_ref().map(|d| d.join(format!("view_{i:02}.ply")));
        let cloud = match &cached {
            Some(path) if path.is_file() => read_ply(path).unwrap(),
            _ => {
                let frames = to_frames(view.capture_all(&images).unwrap());
                let capture = CaptureSet::from_frames(manifest.clone(), frames).unwrap();
                let map = decode(&capture, &DecodeConfig::default()).unwrap();
                // As the scan reconstructs: the decoded coordinates smoothed, the points next
                // to the silhouette and the cube's creases (mixed pixels) dropped.
                let cloud =
                    reconstruct_decoded(&map, &tri, &options, &ReconstructConfig::default())
                        .unwrap();
                if let Some(path) = &cached {
                    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
                    write_ply(path, &cloud, PlyFormat::default()).unwrap();
                }
                cloud
            }
        };
        // Per-view error against the rig's truth along the ray: the floor the merge starts
        // from (the merge cannot remove a systematic error of the triangulation).
        let t_cube_cam = view.truth.objects[0].t_cam_object.inverse();
        for p in cloud.positions() {
            let d = cube_distance(&(t_cube_cam * p));
            view_sq += d * d;
            view_n += 1;
        }
        t_cam_cube.push(view.truth.objects[0].t_cam_object);
        views.push(cloud);
    }
    let capture_s = t.elapsed().as_secs_f64();
    let per_view = view_n / VIEWS;
    let view_rms = (view_sq / view_n as f64).sqrt();

    let t_cam0_cube = t_cam_cube[0];
    let t_cube_world = t_cam0_cube.inverse();
    // T_world_view_i = T_cam0_cam_i, the truth every variant is compared with.
    let true_poses: Vec<Isometry3<f64>> = t_cam_cube
        .iter()
        .map(|t| t_cam0_cube * t.inverse())
        .collect();
    let surface = |cloud: &PointCloud| -> (f64, f64) {
        let mut d: Vec<f64> = cloud
            .positions()
            .iter()
            .map(|p| cube_distance(&(t_cube_world * p)))
            .collect();
        let r = rms(d.iter().copied());
        d.sort_by(f64::total_cmp);
        (r, d[(d.len() as f64 * 0.99) as usize])
    };
    // Worst view rotation error (°) and worst RMS displacement of a view's points (mm).
    let pose_errors = |poses: &[Isometry3<f64>]| -> (f64, f64) {
        let mut worst = (0.0f64, 0.0f64);
        for ((pose, truth), view) in poses.iter().zip(&true_poses).zip(&views) {
            let sample: Vec<Point3<f64>> = view.positions().iter().step_by(97).copied().collect();
            let e = PoseError::between(pose, truth, &sample);
            worst = (
                worst.0.max(e.rotation_deg),
                worst.1.max(e.rms_displacement_mm),
            );
        }
        worst
    };
    // The default merge: the turntable model, the calibration kept where the registrations
    // agree with it.
    let config = MergeConfig::default();
    let report = |name: &str, cloud: &PointCloud, poses: &[Isometry3<f64>]| -> f64 {
        let (r, p99) = surface(cloud);
        let (deg, mm) = pose_errors(poses);
        eprintln!("| {name:<44} | {r:.4} | {p99:.4} | {deg:.4} | {mm:.4} |");
        r
    };
    eprintln!(
        "{VIEWS} rendered views of {per_view} points (render+decode+triangulate {capture_s:.1} s): \
         per-view RMS to the true surface {view_rms:.4} mm"
    );
    eprintln!(
        "| poses                                        | RMS mm | p99 mm | worst view ° | worst view mm |"
    );
    let truth_merge = merge_aligned(&views, &true_poses, &config).unwrap();
    let truth_rms = report("true poses", &truth_merge, &true_poses);

    // The turntable as sl-calib calibrates it on this rig.
    let calibrated = perturbed(&axis, CALIBRATED_TILT_DEG, CALIBRATED_SHIFT_MM);
    let initial = turntable_poses(&calibrated, &angles).unwrap();
    let odometry = merge_aligned(&views, &initial, &config).unwrap();
    let odometry_rms = report("turntable poses, calibrated axis", &odometry, &initial);
    let free = MergeConfig {
        pose_model: PoseModel::Free,
        ..config
    };
    let old = merge_views(&views, &initial, &free).unwrap();
    let old_rms = report(
        "pairwise ICP + free pose graph",
        &old.cloud,
        &old.alignment.poses,
    );
    let t = Instant::now();
    let merged = merge_views(&views, &initial, &config).unwrap();
    let merge_s = t.elapsed().as_secs_f64();
    let merged_rms = report(
        "default merge (turntable model)",
        &merged.cloud,
        &merged.alignment.poses,
    );
    eprintln!("  {}", merged.alignment.pose_summary());

    // A poorly calibrated axis: the registrations must correct it.
    let poor = perturbed(&axis, POOR_TILT_DEG, POOR_SHIFT_MM);
    let poor_initial = turntable_poses(&poor, &angles).unwrap();
    let poor_odometry = merge_aligned(&views, &poor_initial, &config).unwrap();
    let poor_odometry_rms = report(
        "turntable poses, axis off 0.5° / 1 mm",
        &poor_odometry,
        &poor_initial,
    );
    let poor_default = merge_views(&views, &poor_initial, &config).unwrap();
    report(
        "  + default merge",
        &poor_default.cloud,
        &poor_default.alignment.poses,
    );
    eprintln!("  {}", poor_default.alignment.pose_summary());
    let loose = MergeConfig {
        pose_model: PoseModel::Turntable(TurntablePrior::none()),
        ..config
    };
    let poor_loose = merge_views(&views, &poor_initial, &loose).unwrap();
    report(
        "  + turntable model, no priors",
        &poor_loose.cloud,
        &poor_loose.alignment.poses,
    );
    let (poor_deg, poor_mm) = pose_errors(&poor_default.alignment.poses);
    let poor_rms = surface(&poor_default.cloud).0;
    let fit = poor_default.alignment.turntable.as_ref().unwrap();
    eprintln!(
        "merge_views {merge_s:.2} s (target {TARGET_MERGE_S} s) for {VIEWS} x {per_view} points, \
         {} merged points",
        merged.cloud.len()
    );
    assert!(per_view > 50_000, "views too small: {per_view} points");
    assert!(
        truth_rms <= TARGET_RMS_MM,
        "true-pose merge RMS {truth_rms} mm"
    );
    assert!(
        odometry_rms <= TARGET_RMS_MM,
        "turntable-pose merge RMS {odometry_rms} mm"
    );
    // The free pose graph (no longer the default) is only measured against the default: on
    // the views the scan reconstructs now (smoothed, edges eroded, 2026-11-28) one of its
    // pairs slips (0.583 mm, worst view 0.72°; 0.0597 mm on the raw views before), an open
    // problem of `slscan merge --free-pose-graph` (docs/registration.md).
    assert!(
        merged_rms < old_rms,
        "default merge RMS {merged_rms} mm, free pose graph {old_rms} mm"
    );
    // Issue 28: the default merge is at least as good as the calibrated turntable's poses
    // (0.2 % for the rounding of a re-generated pose), and meets issue 7's target.
    assert!(
        merged_rms <= odometry_rms * 1.002,
        "default merge RMS {merged_rms} mm, calibrated turntable {odometry_rms} mm"
    );
    assert!(merged_rms <= TARGET_RMS_MM, "merged RMS {merged_rms} mm");
    assert!(merged.alignment.turntable.as_ref().unwrap().axis_confirmed);
    // The poorly calibrated axis is rejected and corrected by the registrations, down to
    // their own bias.
    assert!(!fit.axis_confirmed);
    assert!(
        poor_rms <= POOR_RMS_BOUND_MM && poor_rms < poor_odometry_rms / 5.0,
        "poor-axis merge RMS {poor_rms} mm (turntable poses {poor_odometry_rms} mm)"
    );
    assert!(
        poor_deg < 0.08 && poor_mm < 0.15,
        "poor axis not corrected: {poor_deg}° / {poor_mm} mm"
    );
}

/// `axis` tilted by `tilt_deg` (about a direction perpendicular to it) and moved by
/// `shift_mm` perpendicular to it and to the tilt: a calibration error of that size.
fn perturbed(axis: &TurntableAxis, tilt_deg: f64, shift_mm: f64) -> TurntableAxis {
    let d = axis.direction.normalize();
    let e1 = d.cross(&Vector3::x()).normalize();
    let e2 = d.cross(&e1);
    let tilt = nalgebra::UnitQuaternion::from_scaled_axis(e1 * tilt_deg.to_radians());
    TurntableAxis {
        direction: tilt * d,
        point_mm: axis.point_mm + e2 * shift_mm,
        ..*axis
    }
}
