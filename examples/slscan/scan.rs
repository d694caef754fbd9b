//! `slscan scan --out DIR`: the whole scan in one command. Without hardware options it runs on
//! the virtual rig (`structured_light::scan::scan_virtual`): calibrates from simulated
//! board captures, captures a turntable session of a dumbbell, decodes, triangulates, merges,
//! measures the result against the truth (sl-metrology; `truth.json` beside `merged.ply`, so
//! `slscan report` reproduces the figures), captures a tilted flat plate for the flatness,
//! and writes the merged PLY, previews, error heat maps, `report.json` and `index.html`.

use std::path::PathBuf;

use structured_light::scan::{VirtualScanConfig, scan_virtual, write_summary_html};

use crate::capture::HardwareArgs;
use crate::common::{Report, StageBars, ensure_out_dir};

/// Arguments of `slscan scan`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Turntable views over a full turn.
    #[arg(long, default_value_t = 36)]
    pub(crate) views: usize,
    /// Board poses of the simulated calibration.
    #[arg(long, default_value_t = 12)]
    pub(crate) calibration_poses: usize,
    /// Divide the virtual rig's resolution by this (2 or 4 for a quick look).
    #[arg(long, default_value_t = 1)]
    pub(crate) downscale: u32,
    /// Seed of the board poses and the sensor noise.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Recapture views that an earlier run of the same scan already captured.
    #[arg(long)]
    pub(crate) overwrite: bool,
    /// Do not average overlapping views in the merge (moving least squares along the
    /// normals, on by default).
    #[arg(long)]
    pub(crate) no_average: bool,
    /// Drop points whose surface normal is more than this many degrees from the direction to
    /// the camera or the projector (90 keeps every point).
    #[arg(long, default_value_t = VirtualScanConfig::default().max_view_angle_deg)]
    pub(crate) max_view_angle: f64,
    /// Diagnostic: triangulate with the virtual rig's true calibration (nothing estimated).
    #[arg(long)]
    pub(crate) true_calibration: bool,
    /// Diagnostic: merge with the virtual rig's true turntable poses (no registration).
    #[arg(long)]
    pub(crate) true_poses: bool,
    /// Neighbours of each merged point for its normal and the moving-least-squares surface
    /// the averaging moves it onto (more: smoother).
    #[arg(long, default_value_t = VirtualScanConfig::default().smoothing_neighbours)]
    pub(crate) smoothing_neighbours: usize,
    /// Drop the points within this many pixels of the edge of the valid region of each view
    /// (silhouettes, plate edges, hole rims).
    #[arg(long, default_value_t = VirtualScanConfig::default().edge_erosion_px)]
    pub(crate) edge_erosion: usize,
    /// Do not capture the flat plate (no flatness figure).
    #[arg(long)]
    pub(crate) no_plate: bool,
    #[command(flatten)]
    pub(crate) hardware: HardwareArgs,
    #[command(flatten)]
    pub(crate) rig: crate::scan_hardware::ScanHardwareArgs,
}

/// Runs `slscan scan`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    if crate::scan_hardware::wanted(args)? {
        return crate::scan_hardware::run(args);
    }
    let mut report = Report::new("scan");
    let out = ensure_out_dir(&args.out)?;
    anyhow::ensure!(args.downscale >= 1, "--downscale must be at least 1");
    let cfg = VirtualScanConfig {
        views: args.views,
        calibration_poses: args.calibration_poses,
        resolution_divisor: args.downscale,
        seed: args.seed,
        overwrite: args.overwrite,
        average_overlaps: !args.no_average,
        max_view_angle_deg: args.max_view_angle,
        true_calibration: args.true_calibration,
        true_poses: args.true_poses,
        flatness_plate: !args.no_plate,
        smoothing_neighbours: args.smoothing_neighbours,
        edge_erosion_px: args.edge_erosion,
        ..VirtualScanConfig::default()
    };
    let mut bars = StageBars::new();
    let result = scan_virtual(&cfg, &out, |p| bars.update(p))?;
    bars.clear();
    let c = &result.calibration_summary;
    report.figure(
        "scene",
        "dumbbell: two spheres r = 25 mm, centres 120 mm apart; then a tilted 160 x 100 mm plate",
    );
    report.figure("views", args.views);
    report.figure("views_captured_this_run", result.views_captured);
    report.figure("view_points", result.view_points.clone());
    report.figure("merged_points", result.merged.len());
    report.figure("calibration", serde_json::to_value(c)?);
    report.figure("accuracy", serde_json::to_value(&result.accuracy)?);
    report.figure("flatness", serde_json::to_value(&result.flatness)?);
    report.figure("first_view", serde_json::to_value(&result.first_view)?);
    report.figure("mesh", serde_json::to_value(&result.mesh)?);
    report.figure("files", serde_json::to_value(&result.files)?);
    report.add_stages(&result.stages);
    report.write(&out)?;
    let html = write_summary_html(&out, &result)?;

    println!(
        "calibration: RMS camera {:.3} px, projector {:.3} px, stereo {:.3} px; axis {:.4} deg / {:.3} mm off the truth",
        c.rms_camera_px,
        c.rms_projector_px,
        c.rms_stereo_px,
        c.axis_direction_error_deg,
        c.axis_position_error_mm
    );
    println!(
        "{}: {} points merged from {} views",
        out.join(&result.files.merged).display(),
        result.merged.len(),
        args.views
    );
    for line in result.accuracy.summary() {
        println!("  {line}");
    }
    for s in &result.first_view.spheres {
        println!(
            "  first view alone: {} form {:.4} mm ({:.4} mm trimmed), fit RMS {:.4} mm, {} points",
            s.name, s.probing_form_mm, s.probing_form_trimmed_mm, s.fit_rms_mm, s.points
        );
    }
    if let Some(f) = &result.flatness {
        for line in f.summary() {
            println!("  {line}");
        }
    }
    for s in &result.stages {
        println!("  {:<12} {:>7.2} s", s.name, s.ms / 1e3);
    }
    println!("summary: {}", html.display());
    Ok(())
}
