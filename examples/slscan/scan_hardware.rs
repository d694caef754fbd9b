//! `slscan scan` on the real rig: `--camera /dev/videoN --projector-monitor N --turntable
//! /dev/ttyUSB0 --calib calibration.json --out DIR`. The options become a
//! `sl_scan::DeviceScanConfig`; `sl_rig::with_devices` opens the devices and
//! `sl_scan::scan_devices` runs the scan on them: the turntable session (`DIR/session/`,
//! resumed when interrupted), every view reconstructed and merged with the turntable poses of
//! the calibrated axis, `merged.ply`, previews and the watertight mesh (`mesh.ply`, `mesh.stl`,
//! `view3d.html`). This file writes `report.json` (and each session's own) and prints.
//! A real object has no known truth here: check the result with `slscan report` against a
//! known sphere or plane.
//!
//! With `--placements 2` the library captures `DIR/placement_1/session/`, then the terminal
//! ([`Terminal`], the scan's `sl_scan::ScanOperator`) asks the user to lay the object on its
//! side and press Enter (or waits `--placement-wait` seconds, for scripts), the library
//! captures `DIR/placement_2/session/` and merges both placements into one model.
//!
//! The devices are reached through one seam, [`run_on`]'s `on_devices`: `slscan` opens the
//! V4L2 camera, the projector window and the Dynamixel turntable of the options; the test of
//! the whole loop (`scan_hardware_placements_tests.rs`) passes the virtual rig's devices behind the
//! same `sl-rig` traits ([`scan_on`]); everything else runs unchanged.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use sl_rig::{Camera, DEFAULT_DISPLAY_LATENCY, LatencyConfig, Projector, Turntable};
use structured_light::scan::{
    DeviceScan, DeviceScanConfig, MergeStageConfig, MeshFiles, MeshSummary, ReconstructConfig,
    ScanError, ScanOperator, SessionCapture, SessionScanConfig, placement_dir_name, scan_devices,
};

use crate::common::{Report, StageBars};
use crate::scan::Args;

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

/// Runs `slscan scan` on the devices of the options, talking to the user on the terminal.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    run_on(args, |mut cfg| {
        let description = args.hardware.description("a scan on hardware")?;
        cfg.capture.devices = description.session_devices();
        let out = args.out.clone();
        let wait = args.placement_wait;
        // The window lives on the main thread's event loop; the scan runs in the worker.
        let scan = sl_rig::with_devices(&description, move |camera, projector, table| {
            let terminal = Terminal::new(std::io::stdin().lock(), std::io::stdout(), wait);
            Ok(scan_on(&cfg, &out, camera, projector, table, terminal))
        })??;
        Ok(scan)
    })
}

/// Runs `slscan scan` on hardware: the options checked and translated (before any device
/// opens), the scan run by `on_devices`, then `report.json` and the figures.
pub(crate) fn run_on(
    args: &Args,
    on_devices: impl FnOnce(DeviceScanConfig) -> anyhow::Result<DeviceScan>,
) -> anyhow::Result<()> {
    let report = Report::new("scan");
    let cfg = scan_config(args)?;
    let scan = on_devices(cfg)?;
    if args.placements > 1 {
        report_placements(args, report, scan)
    } else {
        report_single(args, report, scan)
    }
}

/// The library's scan on `camera`, `projector` and `table`, with progress bars and `terminal`
/// as the operator.
pub(crate) fn scan_on<I: BufRead, O: Write>(
    cfg: &DeviceScanConfig,
    out: &Path,
    camera: &mut dyn Camera,
    projector: &mut dyn Projector,
    table: &mut dyn Turntable,
    mut terminal: Terminal<I, O>,
) -> Result<DeviceScan, ScanError> {
    let mut bars = StageBars::new();
    let scan = scan_devices(cfg, out, camera, projector, table, &mut terminal, |p| {
        bars.update(p)
    });
    bars.clear();
    scan
}

/// The scan the options ask for; everything the scan needs is checked before a device opens.
fn scan_config(args: &Args) -> anyhow::Result<DeviceScanConfig> {
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
    let mut cfg = DeviceScanConfig::load(calib_path)?;
    anyhow::ensure!(
        args.placements > 1 || args.placement_wait.is_none(),
        "--placement-wait is for a scan of several placements (--placements 2)"
    );
    cfg.placements = args.placements;
    let capture = &mut cfg.capture;
    capture.views = args.views;
    capture.patterns = crate::capture::load_patterns(args.rig.patterns.as_deref())?;
    capture.display_latency = args
        .rig
        .latency_ms
        .map_or(DEFAULT_DISPLAY_LATENCY, Duration::from_millis);
    capture.measure_latency = args.rig.measure_latency.then(LatencyConfig::default);
    capture.overwrite = args.overwrite;
    cfg.session = SessionScanConfig {
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
    };
    cfg.placement.merge.average_overlaps = !args.no_average;
    cfg.placement.merge.output_normal_neighbours = args.smoothing_neighbours;
    cfg.mesh = crate::scan::mesh_options(args);
    cfg.check().map_err(|e| match e {
        // The parameter is the option of the same name.
        ScanError::InvalidParameter { name, reason } => anyhow::anyhow!("--{name} {reason}"),
        other => other.into(),
    })?;
    Ok(cfg)
}

/// What the user is asked to do between two placements.
pub(crate) const REPLACE_PROMPT: &str = "lay the object on its side and press Enter";

/// The person at the rig, on the terminal (`input` and `output`: stdin and stdout, or a
/// test's buffers): told which placement is captured, asked to re-place the object in between
/// (or given `wait_s` seconds to), and each session's record written as it is captured.
pub(crate) struct Terminal<I, O> {
    input: I,
    output: O,
    wait_s: Option<f64>,
}

impl<I: BufRead, O: Write> Terminal<I, O> {
    /// The terminal of `input` and `output`; `wait_s` is `--placement-wait`.
    pub(crate) fn new(input: I, output: O, wait_s: Option<f64>) -> Self {
        Self {
            input,
            output,
            wait_s,
        }
    }
}

impl<I: BufRead, O: Write> ScanOperator for Terminal<I, O> {
    fn replace(&mut self, next: usize, total: usize) -> Result<(), ScanError> {
        replace_prompt(&mut self.input, &mut self.output, next, total, self.wait_s)
    }

    fn capturing(&mut self, placement: usize, total: usize, dir: &Path) -> Result<(), ScanError> {
        if total > 1 {
            let _ = writeln!(
                self.output,
                "placement {placement}: capturing {}",
                dir.display()
            );
        }
        Ok(())
    }

    fn captured(&mut self, placement: usize, capture: &SessionCapture) -> Result<(), ScanError> {
        crate::capture::record_session(capture)
            .map(|_| ())
            .map_err(|e| ScanError::Stage {
                stage: "capture".into(),
                reason: format!("placement {placement}: {e:#}"),
            })
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

/// The report and the figures of `slscan scan --placements 2` on the devices.
fn report_placements(args: &Args, mut report: Report, scan: DeviceScan) -> anyhow::Result<()> {
    let out = &args.out;
    report.add_stages(&scan.stages);
    let mut per_placement = Vec::new();
    for p in &scan.placements {
        per_placement.push(serde_json::json!({
            "placement": p.placement,
            "views": p.scan.view_points.len(),
            "view_points": p.scan.view_points,
            "merged_points": p.scan.merged.len(),
            "merge": p.scan.merge,
            "merged": p.files.as_ref().map_or_else(
                || format!("{}/merged.ply", placement_dir_name(p.placement)),
                |f| f.merged.clone(),
            ),
            "alignment": p.alignment,
        }));
    }
    let calib = args.rig.calib.clone().unwrap_or_default();
    report.figure("rig", "hardware");
    report.figure("calibration", calib.display().to_string());
    report.figure("placements", args.placements);
    report.figure("per_placement", serde_json::Value::Array(per_placement));
    report.figure("merged_points", scan.merged.len());
    report.figure("files", serde_json::to_value(&scan.files)?);
    for a in scan.placements.iter().filter_map(|p| p.alignment.as_ref()) {
        println!(
            "placement {} aligned onto placement 1 with no pose hint: fitness {:.3}, RMSE {:.3} mm",
            a.placement, a.fitness, a.rmse_mm
        );
    }
    println!(
        "{}: {} points merged from {} placements (calibration {})",
        out.join(&scan.files.merged).display(),
        scan.merged.len(),
        args.placements,
        calib.display()
    );
    record_mesh(&mut report, scan.mesh, out, &scan.files.merged)?;
    Ok(())
}

/// The report and the figures of `slscan scan` on the devices, one placement.
fn report_single(args: &Args, mut report: Report, scan: DeviceScan) -> anyhow::Result<()> {
    let out = &args.out;
    let Some(placement) = scan.placements.first() else {
        anyhow::bail!("the scan returned no placement");
    };
    let s = &placement.scan;
    let calib = args.rig.calib.clone().unwrap_or_default();
    report.add_stages(&scan.stages);
    report.figure("rig", "hardware");
    report.figure("calibration", calib.display().to_string());
    report.figure("views", s.view_points.len());
    report.figure("motor_angles_deg", s.motor_angles_deg.clone());
    report.figure("platter_angles_deg", s.platter_angles_deg.clone());
    report.figure("view_points", s.view_points.clone());
    report.figure("merged_points", scan.merged.len());
    report.figure("icp_refinement", !args.rig.no_refine);
    report.figure("merge", serde_json::to_value(&s.merge)?);
    println!("poses: {}", s.merge.summary);
    report.figure(
        "accuracy",
        "no truth for a real object: run `slscan report merged.ply --truth …` on a scan of a known sphere or plane",
    );
    report.figure("files", serde_json::to_value(&scan.files)?);
    report.figure("session", structured_light::scan::PLACEMENT_SESSION_DIR);
    let meshed = record_mesh(&mut report, scan.mesh, out, &scan.files.merged)?;
    println!(
        "{}: {} points merged from {} views (calibration {})",
        out.join(&scan.files.merged).display(),
        scan.merged.len(),
        s.view_points.len(),
        calib.display()
    );
    if let Some((mesh, mesh_files)) = meshed {
        println!(
            "{}: {} triangles, {}",
            out.join(&mesh_files.ply).display(),
            mesh.triangles,
            crate::common::watertight(mesh.watertight)
        );
    }
    crate::common::print_stages(&report.stages);
    Ok(())
}

/// Records the mesh stage's outcome in the report and writes it. A mesh that failed keeps the
/// merged cloud (`merged_file`, relative to `out`) and the report on disk, and the error says so.
fn record_mesh(
    report: &mut Report,
    meshed: Option<Result<(MeshSummary, MeshFiles), ScanError>>,
    out: &Path,
    merged_file: &str,
) -> anyhow::Result<Option<(MeshSummary, MeshFiles)>> {
    match meshed {
        Some(Ok((mesh, mesh_files))) => {
            report.figure("mesh", serde_json::to_value(&mesh)?);
            report.figure("mesh_files", serde_json::to_value(&mesh_files)?);
            report.write(out)?;
            Ok(Some((mesh, mesh_files)))
        }
        Some(Err(e)) => {
            report.figure("mesh_error", e.to_string());
            report.write(out)?;
            Err(anyhow::Error::new(e).context(format!(
                "{} and its report are written; the mesh stage failed",
                out.join(merged_file).display()
            )))
        }
        None => {
            report.write(out)?;
            Ok(None)
        }
    }
}

#[cfg(test)]
#[path = "scan_hardware_placements_tests.rs"]
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
