//! Measures the merge of a virtual-rig scan with different poses, on the same reconstructed
//! views: the rig's true poses, the calibrated turntable's poses alone, the free pose graph,
//! the turntable model and sl-icp's default. Prints one table row per merge.
//!
//! ```sh
//! slscan scan --out /tmp/s0 --seed 0                    # the dumbbell
//! cargo run --release -p sl-scan --example merge_poses -- /tmp/s0
//! slscan scan --out /tmp/p0 --seed 0 --placements 2     # the pebble, standing and on its side
//! cargo run --release -p sl-scan --example merge_poses -- /tmp/p0 --placements 2
//! ```
//!
//! Options: `--downscale D` (as the scan's), `--placements 2`, `--only-default` (sl-icp's
//! default merge alone). The dumbbell is measured
//! against the scan's `truth.json` (RMS to the true surface, probing size and form, sphere
//! spacing), each pebble placement against its true triangle mesh (RMS distance).

#![allow(clippy::print_stdout)]

use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use sl_cloud::PointCloud;
use sl_icp::{PoseModel, merge_aligned, merge_views, turntable_poses};
use sl_metrology::{
    DEFAULT_SELECT_MM, DEFAULT_TRUTH_SAMPLE_AREA_MM2, Truth, distance_to_surface, evaluate,
};
use sl_scan::{
    MergeStageConfig, ReconstructConfig, ScanError, load_scan_calibration, reconstruct_session,
    scaled_rig_config,
};
use sl_sim::Scene;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut dir = None;
    let mut downscale = 1u32;
    let mut placements = 1usize;
    let mut only_default = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--downscale" => downscale = it.next().ok_or("--downscale needs a value")?.parse()?,
            "--placements" => {
                placements = it.next().ok_or("--placements needs a value")?.parse()?
            }
            "--only-default" => only_default = true,
            other => dir = Some(PathBuf::from(other)),
        }
    }
    let dir = dir.ok_or("usage: merge_poses SCAN_DIR [--downscale D] [--placements 2]")?;
    let calibration = load_scan_calibration(&dir.join("calibration.json"))?;
    let rig = scaled_rig_config(downscale);
    if placements == 1 {
        let truth = Truth::load(&dir.join("truth.json"))?;
        let views = reconstruct(&dir.join("session"), &calibration)?;
        let true_poses = true_poses(&rig, &views.motor_angles_deg);
        for (name, cloud, sources) in merges(&views, &true_poses, only_default)? {
            let r = evaluate(&cloud, &truth)?;
            let spheres: Vec<String> = r
                .spheres
                .iter()
                .map(|s| format!("{:+.3}/{:.3}", s.probing_size_mm, s.probing_form_mm))
                .collect();
            let spacing = r.sphere_pairs.first().map_or(0.0, |p| p.sphere_spacing_mm);
            println!(
                "| {name:<24} | {:.4} | {} | {spacing:+.4} | {sources} |",
                r.rms_to_reference_mm,
                spheres.join(" "),
            );
        }
    } else {
        let t_cam_table0 = rig.t_cam_table_at(0.0);
        let mut scene = Scene::pebble()?;
        for k in 1..=placements {
            if k > 1 {
                scene = scene.laid_on_side()?;
            }
            let truth = scene.surface_mesh(&t_cam_table0)?;
            let views = reconstruct(
                &dir.join(format!("placement_{k}")).join("session"),
                &calibration,
            )?;
            let true_poses = true_poses(&rig, &views.motor_angles_deg);
            for (name, cloud, sources) in merges(&views, &true_poses, only_default)? {
                let d = distance_to_surface(
                    &cloud,
                    &truth,
                    DEFAULT_TRUTH_SAMPLE_AREA_MM2,
                    DEFAULT_SELECT_MM,
                )?;
                println!(
                    "| placement {k} | {name:<24} | {:.4} | {sources} |",
                    d.rms_mm
                );
            }
        }
    }
    Ok(())
}

fn reconstruct(
    session: &Path,
    calibration: &sl_camera::Calibration,
) -> Result<sl_scan::ReconstructedViews, ScanError> {
    // As `slscan scan` reconstructs by default (3 px edge erosion, 3 × 3 smoothing).
    reconstruct_session(session, calibration, &ReconstructConfig::default(), |_| {})
}

/// `T_world_view` of the rig's true turntable (world = the camera at the first angle).
fn true_poses(rig: &sl_sim::RigConfig, motor_deg: &[f64]) -> Vec<Isometry3<f64>> {
    let t0 = rig.t_cam_table_at(motor_deg.first().copied().unwrap_or(0.0));
    motor_deg
        .iter()
        .map(|&a| t0 * rig.t_cam_table_at(a).inverse())
        .collect()
}

/// One merge: its name, its cloud, and what it says of its poses.
type Merged = (String, PointCloud, String);

/// Each merge: name, cloud, and what the merge says of its poses.
fn merges(
    views: &sl_scan::ReconstructedViews,
    truth: &[Isometry3<f64>],
    only_default: bool,
) -> Result<Vec<Merged>, Box<dyn std::error::Error>> {
    let base = MergeStageConfig::scan(true, 16, true).merge;
    let calibrated = turntable_poses(&views.axis, &views.motor_angles_deg)?;
    if only_default {
        let m = merge_views(&views.clouds, &calibrated, &base)?;
        return Ok(vec![(
            "sl-icp default".to_owned(),
            m.cloud,
            describe(&m.alignment),
        )]);
    }
    let mut out = vec![
        (
            "true poses".to_owned(),
            merge_aligned(&views.clouds, truth, &base)?,
            String::new(),
        ),
        (
            "calibrated turntable".to_owned(),
            merge_aligned(&views.clouds, &calibrated, &base)?,
            String::new(),
        ),
    ];
    for (name, model) in [
        ("free pose graph", Some(PoseModel::Free)),
        ("sl-icp default (turntable model)", None),
    ] {
        let config = sl_icp::MergeConfig {
            pose_model: model.unwrap_or_default(),
            ..base
        };
        let m = merge_views(&views.clouds, &calibrated, &config)?;
        let sources = describe(&m.alignment);
        out.push((name.to_owned(), m.cloud, sources));
    }
    Ok(out)
}

fn describe(a: &sl_icp::ViewAlignment) -> String {
    let Some(t) = &a.turntable else {
        return "free pose graph".to_owned();
    };
    let count = |f: fn(&sl_icp::ViewPoseSource) -> bool| a.sources.iter().filter(|s| f(s)).count();
    format!(
        "axis {} ({:.1} σ), s² {:.3}, scale {:.6}; angles: motor {}, prior only {}, registrations {}",
        if t.axis_confirmed {
            "calibrated"
        } else {
            "registered"
        },
        t.axis_distance,
        t.variance_factor,
        t.angle_scale,
        count(|s| matches!(s, sl_icp::ViewPoseSource::Turntable)),
        count(|s| matches!(s, sl_icp::ViewPoseSource::TurntablePriorOnly { .. })),
        count(|s| matches!(s, sl_icp::ViewPoseSource::Registrations { .. })),
    )
}
