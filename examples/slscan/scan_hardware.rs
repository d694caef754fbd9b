//! `slscan scan` on the real rig: `--camera /dev/videoN --projector-monitor N --turntable
//! /dev/ttyUSB0 --calib calibration.json --out DIR`. Captures the turntable session on the
//! devices with the code of `slscan capture` (into `DIR/session/`, resumed when interrupted),
//! then reconstructs every view and merges them with the turntable poses of the calibrated axis
//! (`sl_scan::scan_session`: the same stage functions as the virtual scan), and writes
//! `merged.ply`, previews, the watertight mesh (`mesh.ply`, `mesh.stl`, `view3d.html`: the mesh
//! stage of the virtual scan) and `report.json`.
//! A real object has no known truth here: check the result with `slscan report` against a
//! known sphere or plane.
//!
//! With `--placements 2` it captures `DIR/placement_1/session/`, then asks the user to lay the
//! object on its side and press Enter (or waits `--placement-wait` seconds, for scripts),
//! captures `DIR/placement_2/session/`, and merges both placements into one model
//! (`sl_scan::capture_placements`, `sl_scan::scan_placements`: the stages of the virtual rig's
//! `--placements 2`).
//!
//! The devices are reached through one seam, [`CaptureSession`]: `slscan` passes
//! `capture::run_hardware` (the V4L2 camera, the projector window and the Dynamixel turntable
//! of the options), the test of the whole loop (`scan_hardware_placements.rs`) the virtual
//! rig's devices behind the same `sl-rig` traits; everything else runs unchanged.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use sl_cloud::PointCloud;
use structured_light::mesh::PoissonConfig;
use structured_light::scan::{
    MergeStageConfig, MeshConfig, MeshFiles, MeshSummary, PlacementConfig, PlacementRig,
    ReconstructConfig, ScanError, SessionScanConfig, capture_placements, load_scan_calibration,
    mesh_stage_with, placement_dir_name, scan_placements, scan_poisson_config, scan_session,
    write_scan_cloud,
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

/// Captures one turntable session on the devices, given the arguments `slscan capture` would
/// get: `capture::run_hardware` on real devices.
pub(crate) type CaptureSession<'a> = dyn FnMut(&capture::Args) -> anyhow::Result<()> + 'a;

/// Runs `slscan scan` on the devices of the options, talking to the user on the terminal.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut on_devices = capture::run_hardware;
    run_on(
        args,
        &mut on_devices,
        std::io::stdin().lock(),
        std::io::stdout(),
    )
}

/// Runs `slscan scan` on hardware with `capture` as the devices; between two placements the
/// user is asked on `output` and answers on `input`.
pub(crate) fn run_on(
    args: &Args,
    capture: &mut CaptureSession<'_>,
    input: impl BufRead,
    output: impl Write,
) -> anyhow::Result<()> {
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
    if args.placements > 1 {
        return run_placements(args, calib_path, &calibration, capture, input, output);
    }
    anyhow::ensure!(
        args.placement_wait.is_none(),
        "--placement-wait is for a scan of several placements (--placements 2)"
    );

    let mut report = Report::new("scan");
    let session_dir = args.out.join(SESSION_DIR);
    let capture_args = capture_args(args, calib_path, &session_dir);
    report.stage("capture", || capture(&capture_args))?;
    reconstruct(args, calib_path, &calibration, &session_dir, report)
}

/// The arguments of `slscan capture` for a session of this scan in `session_dir`.
fn capture_args(args: &Args, calib_path: &Path, session_dir: &Path) -> capture::Args {
    capture::Args {
        out: session_dir.to_path_buf(),
        views: args.views,
        patterns: args.rig.patterns.clone(),
        scene: String::new(),
        downscale: 1,
        latency_ms: args.rig.latency_ms,
        measure_latency: args.rig.measure_latency,
        calib: Some(calib_path.to_path_buf()),
        overwrite: args.overwrite,
        hardware: args.hardware.clone(),
    }
}

/// What the user is asked to do between two placements.
pub(crate) const REPLACE_PROMPT: &str = "lay the object on its side and press Enter";

/// The real devices' placements: each session captured with the code of `slscan capture`,
/// the user asked to re-place the object in between (`input` and `output`: the terminal, or
/// a test's buffers).
struct DevicePlacements<'a, 'c, I, O> {
    args: &'a Args,
    calib: &'a Path,
    capture: &'a mut CaptureSession<'c>,
    input: I,
    output: O,
}

impl<I: BufRead, O: Write> PlacementRig for DevicePlacements<'_, '_, I, O> {
    fn capture(&mut self, placement: usize, dir: &Path) -> Result<usize, ScanError> {
        let _ = writeln!(
            self.output,
            "placement {placement}: capturing {}",
            dir.display()
        );
        (self.capture)(&capture_args(self.args, self.calib, dir)).map_err(|e| {
            ScanError::Stage {
                stage: "capture".into(),
                reason: format!("placement {placement}: {e:#}"),
            }
        })?;
        // `slscan capture` reports what it captured itself; the count is not needed here.
        Ok(0)
    }

    fn replace(&mut self, next: usize, total: usize) -> Result<(), ScanError> {
        replace_prompt(
            &mut self.input,
            &mut self.output,
            next,
            total,
            self.args.placement_wait,
        )
    }
}

/// Asks the user to re-place the object before placement `next`, then waits for Enter on
/// `input` — or, with `wait_s`, waits that many seconds without reading anything.
fn replace_prompt(
    input: &mut impl BufRead,
    output: &mut impl Write,
    next: usize,
    total: usize,
    wait_s: Option<f64>,
) -> Result<(), ScanError> {
    let failed = |reason: String| ScanError::Stage {
        stage: "placements".into(),
        reason,
    };
    match wait_s {
        Some(s) => {
            let wait = Duration::try_from_secs_f64(s)
                .map_err(|_| failed(format!("--placement-wait {s}: not a number of seconds")))?;
            let _ = writeln!(
                output,
                "placement {next} of {total}: lay the object on its side; scanning again in {s} s (--placement-wait)"
            );
            let _ = output.flush();
            std::thread::sleep(wait);
        }
        None => {
            let _ = write!(output, "placement {next} of {total}: {REPLACE_PROMPT} ");
            let _ = output.flush();
            let mut line = String::new();
            let read = input
                .read_line(&mut line)
                .map_err(|e| failed(format!("reading the answer from stdin: {e}")))?;
            if read == 0 {
                return Err(failed(format!(
                    "stdin closed before placement {next} was confirmed: press Enter in a terminal, or pass --placement-wait SECONDS"
                )));
            }
        }
    }
    Ok(())
}

/// `slscan scan --placements 2` on the devices: the placement loop, then each placement
/// reconstructed and merged, aligned and merged into one cloud, the mesh and the report.
fn run_placements(
    args: &Args,
    calib_path: &Path,
    calibration: &sl_camera::Calibration,
    capture: &mut CaptureSession<'_>,
    input: impl BufRead,
    output: impl Write,
) -> anyhow::Result<()> {
    let mut report = Report::new("scan");
    let mut rig = DevicePlacements {
        args,
        calib: calib_path,
        capture,
        input,
        output,
    };
    let sessions = report.stage("capture", || {
        capture_placements(&args.out, args.placements, &mut rig)
    })?;
    let out = ensure_out_dir(&args.out)?;
    let dirs: Vec<PathBuf> = sessions.into_iter().map(|(d, _)| d).collect();
    let config = session_config(args);
    let mut placement_cfg = PlacementConfig::default();
    placement_cfg.merge.average_overlaps = !args.no_average;
    placement_cfg.merge.output_normal_neighbours = args.smoothing_neighbours;
    let mut bars = StageBars::new();
    let scan = scan_placements(&dirs, calibration, &config, &placement_cfg, |p| {
        bars.update(p)
    })?;
    bars.clear();
    report.add_stages(&scan.stages);
    let mut per_placement = Vec::new();
    for (k, s) in scan.sessions.iter().enumerate() {
        let dir = out.join(placement_dir_name(k + 1));
        let files = write_scan_cloud(&dir, &s.merged, |_| {})?;
        per_placement.push(serde_json::json!({
            "placement": k + 1,
            "views": s.view_points.len(),
            "view_points": s.view_points,
            "merged_points": s.merged.len(),
            "merge": s.merge,
            "merged": format!("{}/{}", placement_dir_name(k + 1), files.merged),
            "alignment": k.checked_sub(1).and_then(|i| scan.merge.alignments.get(i)),
        }));
    }
    let merged = &scan.merge.merged;
    let files = report.stage("write", || write_scan_cloud(&out, merged, |_| {}))?;
    let meshed = report.stage("mesh", || {
        mesh_without_truth(merged, &config, &crate::scan::mesh_options(args), &out)
    });
    report.figure("rig", "hardware");
    report.figure("calibration", calib_path.display().to_string());
    report.figure("placements", args.placements);
    report.figure("per_placement", serde_json::Value::Array(per_placement));
    report.figure("merged_points", merged.len());
    report.figure("files", serde_json::to_value(&files)?);
    for a in &scan.merge.alignments {
        println!(
            "placement {} aligned onto placement 1 with no pose hint: fitness {:.3}, RMSE {:.3} mm",
            a.placement, a.fitness, a.rmse_mm
        );
    }
    println!(
        "{}: {} points merged from {} placements (calibration {})",
        out.join(&files.merged).display(),
        merged.len(),
        args.placements,
        calib_path.display()
    );
    record_mesh(&mut report, meshed, &out, &files.merged)?;
    Ok(())
}

/// The mesh stage of the virtual scan on a merged cloud, without a truth to measure it against
/// (the depth from the cloud's spacing, as `slscan scan` on the virtual rig).
fn mesh_without_truth(
    merged: &PointCloud,
    config: &SessionScanConfig,
    options: &MeshConfig,
    out: &Path,
) -> Result<(MeshSummary, MeshFiles), ScanError> {
    let poisson = scan_poisson_config(
        merged,
        config.merge.merge.output_voxel_size,
        PoissonConfig::default().depth,
    );
    mesh_stage_with(merged, None, None, &poisson, options, out)
}

/// Records the mesh stage's outcome in the report and writes it. A mesh that failed keeps the
/// merged cloud (`merged_file`, relative to `out`) and the report on disk, and the error says so.
fn record_mesh(
    report: &mut Report,
    meshed: Result<(MeshSummary, MeshFiles), ScanError>,
    out: &Path,
    merged_file: &str,
) -> anyhow::Result<(MeshSummary, MeshFiles)> {
    match meshed {
        Ok((mesh, mesh_files)) => {
            report.figure("mesh", serde_json::to_value(&mesh)?);
            report.figure("mesh_files", serde_json::to_value(&mesh_files)?);
            report.write(out)?;
            Ok((mesh, mesh_files))
        }
        Err(e) => {
            report.figure("mesh_error", e.to_string());
            report.write(out)?;
            Err(anyhow::Error::new(e).context(format!(
                "{} and its report are written; the mesh stage failed",
                out.join(merged_file).display()
            )))
        }
    }
}

/// The reconstruction and turntable merge of one session, from the options.
fn session_config(args: &Args) -> SessionScanConfig {
    SessionScanConfig {
        reconstruct: ReconstructConfig {
            edge_erosion_px: args.edge_erosion,
            max_view_angle_deg: args.max_view_angle,
            smoothing: crate::scan::smoothing(args),
        },
        merge: MergeStageConfig::scan(
            !args.no_average,
            args.smoothing_neighbours,
            !args.rig.no_refine,
        ),
        poses: None,
    }
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
    let config = session_config(args);
    let mut bars = StageBars::new();
    let scan = scan_session(session_dir, calibration, &config, |p| bars.update(p))?;
    bars.clear();
    let files = report.stage("write", || write_scan_cloud(&out, &scan.merged, |_| {}))?;
    report.add_stages(&scan.stages);
    // The same mesh stage as the virtual scan, without a truth to measure it against. The
    // merged cloud is on disk already; a cloud that cannot be meshed keeps it and its report.
    let meshed = report.stage("mesh", || {
        mesh_without_truth(
            &scan.merged,
            &config,
            &crate::scan::mesh_options(args),
            &out,
        )
    });
    report.figure("rig", "hardware");
    report.figure("calibration", calib_path.display().to_string());
    report.figure("views", scan.view_points.len());
    report.figure("motor_angles_deg", scan.motor_angles_deg.clone());
    report.figure("platter_angles_deg", scan.platter_angles_deg.clone());
    report.figure("view_points", scan.view_points.clone());
    report.figure("merged_points", scan.merged.len());
    report.figure("icp_refinement", config.merge.icp_refinement);
    report.figure("merge", serde_json::to_value(&scan.merge)?);
    println!("poses: {}", scan.merge.summary);
    report.figure(
        "accuracy",
        "no truth for a real object: run `slscan report merged.ply --truth …` on a scan of a known sphere or plane",
    );
    report.figure("files", serde_json::to_value(&files)?);
    report.figure("session", SESSION_DIR);
    let (mesh, mesh_files) = record_mesh(&mut report, meshed, &out, &files.merged)?;
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
#[path = "scan_hardware_placements.rs"]
mod placements_loop;

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

    /// Between two placements the user is asked to lay the object on its side and press
    /// Enter; a closed stdin names the non-interactive option; `--placement-wait` reads
    /// nothing.
    #[test]
    fn the_replace_prompt_waits_for_enter_or_the_given_time() {
        use super::{REPLACE_PROMPT, replace_prompt};
        let mut out = Vec::new();
        replace_prompt(&mut "\n".as_bytes(), &mut out, 2, 2, None).unwrap();
        let said = String::from_utf8(out).unwrap();
        assert!(
            said.contains(REPLACE_PROMPT) && said.contains("placement 2 of 2"),
            "{said}"
        );
        let mut out = Vec::new();
        let e = replace_prompt(&mut "".as_bytes(), &mut out, 2, 2, None).unwrap_err();
        assert!(e.to_string().contains("--placement-wait"), "{e}");
        let mut out = Vec::new();
        let mut input = "not read\n".as_bytes();
        replace_prompt(&mut input, &mut out, 2, 2, Some(0.0)).unwrap();
        assert_eq!(input, b"not read\n");
        let e = replace_prompt(&mut input, &mut Vec::new(), 2, 2, Some(-1.0)).unwrap_err();
        assert!(e.to_string().contains("--placement-wait -1"), "{e}");
    }

    #[test]
    fn placements_beyond_two_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("scan");
        let err = scan(&["--out", out.to_str().unwrap(), "--placements", "3"]).unwrap_err();
        assert!(
            text(&err).contains("--placements") && text(&err).contains("3 placements"),
            "{err:#}"
        );
        let err = scan(&["--out", out.to_str().unwrap(), "--placement-wait", "5"]).unwrap_err();
        assert!(text(&err).contains("--placement-wait"), "{err:#}");
        assert!(!out.exists());
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
