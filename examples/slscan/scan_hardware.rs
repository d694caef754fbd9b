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
    DeviceScan, DeviceScanConfig, MergeStageConfig, ReconstructConfig, ScanError, ScanProgress,
    SessionScanConfig, TerminalOperator, scan_binocular_devices, scan_devices,
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
    /// Wait after showing a pattern (ms, hardware only; at most 10000); default 100.
    #[arg(long, value_parser = crate::values::latency_ms())]
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
/// With `--right-camera` both cameras capture every pattern and the views are matched between
/// them (`--calib` the two-camera calibration).
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    run_on(args, |cfg| {
        let description = args.hardware.description("a scan on hardware")?;
        let out = args.out.clone();
        let wait = args.placement_wait;
        let terminal =
            move || TerminalOperator::new(std::io::stdin().lock(), std::io::stdout(), wait);
        // The window lives on the main thread's event loop; the scan runs in the worker.
        let scan = sl_rig::with_described_devices(
            &description,
            move |camera, right, projector, table| {
                Ok(scan_on(
                    &cfg,
                    &out,
                    (camera, right),
                    projector,
                    table,
                    terminal(),
                ))
            },
        )??;
        Ok(scan)
    })
}

/// Runs `slscan scan` on hardware: the options checked and translated (before any device
/// opens), the scan run by `on_devices`, then `report.json` and the figures.
pub(crate) fn run_on(
    args: &Args,
    on_devices: impl FnOnce(DeviceScanConfig) -> anyhow::Result<DeviceScan>,
) -> anyhow::Result<()> {
    let mut report = Report::new("scan");
    let cfg = scan_config(args)?;
    // One run at a time in a scan folder; its sessions resume, so it is written in place.
    let folder = crate::common::open_out_in_place(&args.out, "scan")?;
    let scan = on_devices(cfg)?;
    let calib = args.rig.calib.clone().unwrap_or_default();
    scan.record(&mut report, &calib, !args.rig.no_refine)?;
    report.write(&args.out)?;
    for line in scan.summary(&args.out, &calib) {
        outln!("{line}");
    }
    // A mesh that failed keeps the merged cloud and the report on disk, and the error says so.
    if let Some(Err(e)) = scan.mesh {
        return Err(anyhow::Error::new(e).context(format!(
            "{} and its report are written; the mesh stage failed",
            args.out.join(&scan.files.merged).display()
        )));
    }
    folder.commit()?;
    Ok(())
}

/// The library's scan on `cameras` (the second one for a scan with two cameras), `projector`
/// and `table`, with progress bars and `terminal` as the operator.
pub(crate) fn scan_on<I: BufRead, O: Write>(
    cfg: &DeviceScanConfig,
    out: &Path,
    cameras: (&mut dyn Camera, Option<&mut dyn Camera>),
    projector: &mut dyn Projector,
    table: &mut dyn Turntable,
    mut terminal: TerminalOperator<I, O>,
) -> Result<DeviceScan, ScanError> {
    let mut bars = StageBars::new();
    let progress = |p: ScanProgress<'_>| bars.update(p);
    let scan = match cameras {
        (camera, None) => scan_devices(cfg, out, camera, projector, table, &mut terminal, progress),
        (left, Some(right)) => scan_binocular_devices(
            cfg,
            out,
            (left, right),
            projector,
            table,
            &mut terminal,
            progress,
        ),
    };
    bars.clear();
    scan
}

/// The scan the options ask for; everything the scan needs is checked before a device opens.
fn scan_config(args: &Args) -> anyhow::Result<DeviceScanConfig> {
    let two_cameras = args.hardware.right_camera.is_some();
    let Some(calib_path) = &args.rig.calib else {
        if two_cameras {
            anyhow::bail!(
                "a scan with two cameras needs --calib FILE: the two-camera calibration with the turntable axis, as `slscan calibrate stereo SESSION` writes it (stereo.json)"
            );
        }
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
    let mut cfg = if two_cameras {
        DeviceScanConfig::load_binocular(calib_path)?
    } else {
        DeviceScanConfig::load(calib_path)?
    };
    anyhow::ensure!(
        args.placements > 1 || args.placement_wait.is_none(),
        "--placement-wait is for a scan of several placements (--placements 2)"
    );
    cfg.placements = args.placements;
    let capture = &mut cfg.capture;
    // As `session.json` records them (the second camera's too).
    capture.devices = args
        .hardware
        .description("a scan on hardware")?
        .session_devices();
    capture.views = args.views;
    capture.patterns = crate::capture::load_patterns(args.rig.patterns.as_deref())?;
    capture.display_latency = args
        .rig
        .latency_ms
        .map_or(DEFAULT_DISPLAY_LATENCY, Duration::from_millis);
    capture.measure_latency = args.rig.measure_latency.then(LatencyConfig::default);
    capture.overwrite = args.overwrite;
    capture.exposures = args.exposure.exposures();
    capture.fusion = args.exposure.fusion();
    capture.colour = args.exposure.colour;
    cfg.session = SessionScanConfig {
        reconstruct: ReconstructConfig {
            edge_erosion_px: args.edge_erosion,
            max_view_angle_deg: args.max_view_angle,
            smoothing: crate::scan::smoothing(args),
            ..ReconstructConfig::default()
        },
        merge: MergeStageConfig::scan(
            !args.no_average,
            args.smoothing_neighbours,
            !args.rig.no_refine,
        ),
        poses: None,
        ..SessionScanConfig::default()
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
