//! `slscan devices`: the cameras, monitors and serial ports this machine offers a rig, and the
//! device features this `slscan` was built without.

use std::path::{Path, PathBuf};

use crate::common::{Report, open_out};

/// Arguments of `slscan devices`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Also write the list as `report.json` into this folder.
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
}

/// Runs `slscan devices`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("devices");
    let mut not_built: Vec<&str> = Vec::new();

    cameras(&mut report, &mut not_built);
    monitors(&mut report, &mut not_built);

    let ports = sl_rig::serial_ports(Path::new("/dev"));
    outln!("serial ports ({}):", ports.len());
    for port in &ports {
        outln!("  {}", port.display());
    }
    if ports.is_empty() {
        outln!("  none (/dev/ttyUSB*, /dev/ttyACM*)");
    }
    report.figure(
        "serial_ports",
        ports
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>(),
    );

    if !not_built.is_empty() {
        outln!(
            "not built: {} (rebuild with --features {})",
            not_built.join(", "),
            not_built
                .iter()
                .map(|f| f.split(' ').next().unwrap_or(f))
                .collect::<Vec<_>>()
                .join(",")
        );
    }
    report.figure("features_not_built", not_built.clone());
    if let Some(out) = &args.out {
        let folder = open_out(out, "devices", &[], &[], false)?;
        report.write(folder.path())?;
        folder.commit()?;
        outln!("report: {}", out.join("report.json").display());
    }
    Ok(())
}

#[cfg(feature = "v4l")]
fn cameras(report: &mut Report, _not_built: &mut Vec<&str>) {
    match sl_rig::list_v4l_cameras() {
        Ok(list) => {
            outln!("V4L2 cameras ({}):", list.len());
            if list.is_empty() {
                outln!("  none (/dev/video*)");
            }
            for cam in &list {
                outln!("  {cam}");
            }
            let rows: Vec<_> = list.iter().map(sl_rig::V4lDeviceInfo::to_json).collect();
            report.figure("cameras", rows);
        }
        Err(e) => outln!("V4L2 cameras: {e}"),
    }
}

#[cfg(not(feature = "v4l"))]
fn cameras(_report: &mut Report, not_built: &mut Vec<&str>) {
    outln!("V4L2 cameras: not built (feature `v4l`)");
    not_built.push("v4l (cameras)");
}

#[cfg(feature = "window")]
fn monitors(report: &mut Report, _not_built: &mut Vec<&str>) {
    match sl_rig::list_monitors() {
        Ok(list) => {
            outln!("monitors ({}):", list.len());
            for m in &list {
                outln!("  {m}");
            }
            let rows: Vec<_> = list.iter().map(sl_rig::MonitorInfo::to_json).collect();
            report.figure("monitors", rows);
        }
        Err(e) => outln!("monitors: {e}"),
    }
}

#[cfg(not(feature = "window"))]
fn monitors(_report: &mut Report, not_built: &mut Vec<&str>) {
    outln!("monitors: not built (feature `window`)");
    not_built.push("window (monitors, projector)");
}
