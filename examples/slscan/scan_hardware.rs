//! `slscan scan` on the real rig: `--camera /dev/videoN --projector-monitor N --turntable
//! /dev/ttyUSB0 --calib calibration.json --out DIR`. Captures the turntable session on the
//! devices with the code of `slscan capture` (into `DIR/session/`, resumed when interrupted),
//! then reconstructs every view and merges them with the turntable poses of the calibrated axis
//! (`sl_scan::scan_session`: the same stage functions as the virtual scan), and writes
//! `merged.ply`, previews, the watertight mesh (`mesh.ply`, `mesh.stl`, `view3d.html`: the mesh
//! stage of the virtual scan) and `report.json`.
//! A real object has no known truth here: check the result with `slscan report` against a
//! known sphere or plane.

use std::path::{Path, PathBuf};

use structured_light::mesh::PoissonConfig;
use structured_light::scan::{
    MergeStageConfig, ReconstructConfig, SessionScanConfig, load_scan_calibration, mesh_stage,
    scan_session, write_scan_cloud,
};

use crate::capture;
use crate::common::{Report, StageBars, ensure_out_dir};
use crate::scan::Args;

/// Session folder inside the output folder.
const SESSION_DIR: &str = "session";

/// The options of `slscan scan` that only a scan on hardware uses.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct ScanHardwareArgs {
    /// Calibration file with camera, projector and turntable axis, as `slscan calibrate all`
    /// writes it (a scan on hardware needs it).
    #[arg(long)]
    pub(crate) calib: Option<PathBuf>,
    /// Folder with the patterns' `manifest.json` (hardware only; default: hybrid code on the
    /// columns, 15 px periods).
    #[arg(long)]
    pub(crate) patterns: Option<PathBuf>,
    /// Wait after showing a pattern (ms, hardware only); default 100.
    #[arg(long)]
    pub(crate) latency_ms: Option<u64>,
    /// Measure the display-to-camera latency first (hardware only).
    #[arg(long)]
    pub(crate) measure_latency: bool,
    /// Place the views with the calibrated turntable poses alone, without refining them by
    /// ICP (hardware only): for a good calibration and views too far apart or too symmetric
    /// for ICP.
    #[arg(long)]
    pub(crate) no_refine: bool,
}

/// Whether `slscan scan` runs on hardware; an error when options of a hardware scan are given
/// without the devices.
pub(crate) fn wanted(args: &Args) -> anyhow::Result<bool> {
    if args.hardware.any() {
        return Ok(true);
    }
    let r = &args.rig;
    if r.calib.is_some()
        || r.patterns.is_some()
        || r.latency_ms.is_some()
        || r.measure_latency
        || r.no_refine
    {
        anyhow::bail!(
            "--calib, --patterns, --latency-ms, --measure-latency and --no-refine are for a scan on hardware (with --camera, --projector-monitor and --turntable); the virtual scan calibrates itself"
        );
    }
    Ok(false)
}

/// Runs `slscan scan` on the devices.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let Some(calib_path) = &args.rig.calib else {
        anyhow::bail!(
            "a scan on hardware needs --calib FILE: a calibration.json with camera, projector and turntable axis, as `slscan calibrate all` (or `slscan calibrate projector` then `slscan calibrate turntable`) writes it"
        );
    };
    anyhow::ensure!(
        args.downscale == 1,
        "--downscale is for the virtual rig; a camera's resolution is its own"
    );
    anyhow::ensure!(
        !args.true_calibration && !args.true_poses,
        "--true-calibration and --true-poses are diagnostics of the virtual rig: a real rig has no truth"
    );
    anyhow::ensure!(
        args.views >= 2,
        "--views {}: a turntable scan needs at least 2 views",
        args.views
    );
    // Everything the reconstruction needs is checked before a device moves.
    let calibration = load_scan_calibration(calib_path)?;

    let mut report = Report::new("scan");
    let session_dir = args.out.join(SESSION_DIR);
    let capture_args = capture::Args {
        out: session_dir.clone(),
        views: args.views,
        patterns: args.rig.patterns.clone(),
        scene: String::new(),
        downscale: 1,
        latency_ms: args.rig.latency_ms,
        measure_latency: args.rig.measure_latency,
        calib: Some(calib_path.clone()),
        overwrite: args.overwrite,
        hardware: args.hardware.clone(),
    };
    report.stage("capture", || capture::run_hardware(&capture_args))?;
    reconstruct(args, calib_path, &calibration, &session_dir, report)
}

/// Reconstructs and merges the captured session, writes the files and the report.
fn reconstruct(
    args: &Args,
    calib_path: &Path,
    calibration: &sl_camera::Calibration,
    session_dir: &Path,
    mut report: Report,
) -> anyhow::Result<()> {
    let out = ensure_out_dir(&args.out)?;
    let config = SessionScanConfig {
        reconstruct: ReconstructConfig {
            edge_erosion_px: args.edge_erosion,
            max_view_angle_deg: args.max_view_angle,
        },
        merge: MergeStageConfig::scan(
            !args.no_average,
            args.smoothing_neighbours,
            !args.rig.no_refine,
        ),
        poses: None,
    };
    let mut bars = StageBars::new();
    let scan = scan_session(session_dir, calibration, &config, |p| bars.update(p))?;
    bars.clear();
    let files = report.stage("write", || write_scan_cloud(&out, &scan.merged, |_| {}))?;
    report.add_stages(&scan.stages);
    // The same mesh stage as the virtual scan, without a truth to measure it against. The
    // merged cloud is on disk already; a cloud that cannot be meshed keeps it and its report.
    let meshed = report.stage("mesh", || {
        mesh_stage(&scan.merged, None, None, &PoissonConfig::default(), &out)
    });
    report.figure("rig", "hardware");
    report.figure("calibration", calib_path.display().to_string());
    report.figure("views", scan.view_points.len());
    report.figure("motor_angles_deg", scan.motor_angles_deg.clone());
    report.figure("platter_angles_deg", scan.platter_angles_deg.clone());
    report.figure("view_points", scan.view_points.clone());
    report.figure("merged_points", scan.merged.len());
    report.figure("icp_refinement", config.merge.icp_refinement);
    report.figure(
        "accuracy",
        "no truth for a real object: run `slscan report merged.ply --truth …` on a scan of a known sphere or plane",
    );
    report.figure("files", serde_json::to_value(&files)?);
    report.figure("session", SESSION_DIR);
    let (mesh, mesh_files) = match meshed {
        Ok(m) => m,
        Err(e) => {
            report.figure("mesh_error", e.to_string());
            report.write(&out)?;
            return Err(anyhow::Error::new(e).context(format!(
                "{} and its report are written; the mesh stage failed",
                out.join(&files.merged).display()
            )));
        }
    };
    report.figure("mesh", serde_json::to_value(&mesh)?);
    report.figure("mesh_files", serde_json::to_value(&mesh_files)?);
    report.write(&out)?;
    println!(
        "{}: {} points merged from {} views (calibration {})",
        out.join(&files.merged).display(),
        scan.merged.len(),
        scan.view_points.len(),
        calib_path.display()
    );
    println!(
        "{}: {} triangles, {}",
        out.join(&mesh_files.ply).display(),
        mesh.triangles,
        if mesh.watertight {
            "watertight"
        } else {
            "NOT watertight"
        }
    );
    for s in &report.stages {
        println!("  {:<12} {:>7.2} s", s.name, s.ms / 1e3);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use clap::Parser;
    use structured_light::scan::scaled_rig_config;

    use crate::{Cli, Command};

    fn scan(args: &[&str]) -> anyhow::Result<()> {
        let mut argv = vec!["slscan", "scan"];
        argv.extend_from_slice(args);
        match Cli::try_parse_from(argv)?.command {
            Command::Scan(a) => crate::scan::run(&a),
            other => anyhow::bail!("parsed as {other:?}"),
        }
    }

    fn text(err: &anyhow::Error) -> String {
        format!("{err:#}")
    }

    fn files_in(dir: &Path) -> Vec<(std::path::PathBuf, Vec<u8>)> {
        let mut all: Vec<_> = crate::common::files_below(dir)
            .into_iter()
            .map(|p| {
                let bytes = std::fs::read(&p).unwrap_or_default();
                (p, bytes)
            })
            .collect();
        all.sort();
        all
    }

    #[test]
    fn a_missing_port_is_named_and_an_earlier_scan_is_kept() {
        let tmp = tempfile::tempdir().unwrap();
        let calib = tmp.path().join("calibration.json");
        scaled_rig_config(4).calibration().save(&calib).unwrap();
        // An earlier, interrupted scan in the output folder.
        let out = tmp.path().join("scan");
        std::fs::create_dir_all(out.join("session/view_000")).unwrap();
        std::fs::write(out.join("session/session.json"), "{\"earlier\": true}").unwrap();
        std::fs::write(out.join("session/view_000/frame.png"), b"earlier frame").unwrap();
        let before = files_in(&out);
        let err = scan(&[
            "--out",
            out.to_str().unwrap(),
            "--camera",
            "/dev/video0",
            "--projector-monitor",
            "0",
            "--turntable",
            "/dev/does-not-exist",
            "--calib",
            calib.to_str().unwrap(),
        ])
        .unwrap_err();
        assert!(text(&err).contains("/dev/does-not-exist"), "{err:#}");
        assert_eq!(files_in(&out), before, "the earlier scan was touched");
    }

    #[test]
    fn a_calibration_without_axis_is_named_with_the_command_that_adds_it() {
        let tmp = tempfile::tempdir().unwrap();
        let calib = tmp.path().join("no_axis.json");
        let mut c = scaled_rig_config(4).calibration();
        c.turntable = None;
        c.save(&calib).unwrap();
        let out = tmp.path().join("scan");
        let err = scan(&[
            "--out",
            out.to_str().unwrap(),
            "--camera",
            "/dev/video0",
            "--projector-monitor",
            "0",
            "--turntable",
            "/dev/ttyUSB0",
            "--calib",
            calib.to_str().unwrap(),
        ])
        .unwrap_err();
        let t = text(&err);
        assert!(
            t.contains("no_axis.json") && t.contains("slscan calibrate turntable"),
            "{t}"
        );
        assert!(!out.exists(), "nothing is written before the checks");
    }

    #[test]
    fn hardware_options_without_devices_or_calibration_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("scan");
        let o = out.to_str().unwrap();
        let err = scan(&["--out", o, "--calib", "c.json"]).unwrap_err();
        assert!(text(&err).contains("--calib"), "{err:#}");
        let err = scan(&["--out", o, "--turntable", "/dev/ttyUSB0"]).unwrap_err();
        assert!(text(&err).contains("--calib FILE"), "{err:#}");
        let err = scan(&[
            "--out",
            o,
            "--turntable",
            "/dev/ttyUSB0",
            "--calib",
            "c.json",
            "--true-poses",
        ])
        .unwrap_err();
        assert!(text(&err).contains("--true-poses"), "{err:#}");
        assert!(!out.exists());
    }
}
