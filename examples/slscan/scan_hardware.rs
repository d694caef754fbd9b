//! `slscan scan` on the real rig: `--camera … --projector-monitor … --turntable … --calib
//! FILE`.

use std::path::PathBuf;

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
}

/// Whether `slscan scan` runs on hardware; an error when options of a hardware scan are given
/// without the devices.
pub(crate) fn wanted(args: &crate::scan::Args) -> anyhow::Result<bool> {
    if args.hardware.any() {
        return Ok(true);
    }
    let r = &args.rig;
    if r.calib.is_some() || r.patterns.is_some() || r.latency_ms.is_some() || r.measure_latency {
        anyhow::bail!(
            "--calib, --patterns, --latency-ms and --measure-latency are for a scan on hardware (with --camera, --projector-monitor and --turntable); the virtual scan calibrates itself"
        );
    }
    Ok(false)
}

/// Runs `slscan scan` on the devices.
pub(crate) fn run(_args: &crate::scan::Args) -> anyhow::Result<()> {
    anyhow::bail!("`slscan scan` on hardware: not wired yet")
}
