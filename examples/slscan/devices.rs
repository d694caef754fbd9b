//! `slscan devices`: the cameras, monitors and serial ports this machine offers a rig, and the
//! device features this `slscan` was built without.

use std::path::{Path, PathBuf};

use crate::common::{Report, ensure_out_dir};

/// Arguments of `slscan devices`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Also write the list as `report.json` into this folder.
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
}

/// Prefixes of the serial ports a turntable hangs on: USB–serial adapters (FTDI, CH340, the
/// U2D2) are `ttyUSB*`, Arduinos and other CDC-ACM boards `ttyACM*`.
const SERIAL_PREFIXES: [&str; 2] = ["ttyUSB", "ttyACM"];

/// Runs `slscan devices`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("devices");
    let mut not_built: Vec<&str> = Vec::new();

    cameras(&mut report, &mut not_built);
    monitors(&mut report, &mut not_built);

    let ports = serial_ports(Path::new("/dev"));
    println!("serial ports ({}):", ports.len());
    for port in &ports {
        println!("  {}", port.display());
    }
    if ports.is_empty() {
        println!("  none (/dev/ttyUSB*, /dev/ttyACM*)");
    }
    report.figure(
        "serial_ports",
        ports
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>(),
    );

    if !not_built.is_empty() {
        println!(
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
        let out = ensure_out_dir(out)?;
        let path = report.write(&out)?;
        println!("report: {}", path.display());
    }
    Ok(())
}

/// `/dev/ttyUSB*` and `/dev/ttyACM*` in `dev`, sorted.
fn serial_ports(dev: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dev) else {
        return Vec::new();
    };
    let mut ports: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .filter(|e| {
            e.file_name()
                .to_str()
                .is_some_and(|n| SERIAL_PREFIXES.iter().any(|p| n.starts_with(p)))
        })
        .map(|e| e.path())
        .collect();
    ports.sort();
    ports
}

#[cfg(feature = "v4l")]
fn cameras(report: &mut Report, _not_built: &mut Vec<&str>) {
    match sl_rig::list_v4l_cameras() {
        Ok(list) => {
            println!("V4L2 cameras ({}):", list.len());
            if list.is_empty() {
                println!("  none (/dev/video*)");
            }
            let mut rows = Vec::new();
            for cam in &list {
                if let Some(err) = &cam.error {
                    println!("  {}: cannot open: {err}", cam.path.display());
                } else {
                    println!(
                        "  {}: {} (driver {}, {})",
                        cam.path.display(),
                        cam.name,
                        cam.driver,
                        cam.bus
                    );
                    for f in &cam.formats {
                        let sizes: Vec<String> =
                            f.sizes.iter().map(|(w, h)| format!("{w}x{h}")).collect();
                        let usable = if f.pixel_format.is_some() {
                            ""
                        } else {
                            " [not converted]"
                        };
                        println!(
                            "    {} ({}){usable}: {}",
                            f.fourcc,
                            f.description,
                            sizes.join(" ")
                        );
                    }
                }
                rows.push(serde_json::json!({
                    "path": cam.path.display().to_string(),
                    "name": cam.name,
                    "driver": cam.driver,
                    "error": cam.error,
                    "formats": cam.formats.iter().map(|f| serde_json::json!({
                        "fourcc": f.fourcc, "sizes": f.sizes,
                    })).collect::<Vec<_>>(),
                }));
            }
            report.figure("cameras", rows);
        }
        Err(e) => println!("V4L2 cameras: {e}"),
    }
}

#[cfg(not(feature = "v4l"))]
fn cameras(_report: &mut Report, not_built: &mut Vec<&str>) {
    println!("V4L2 cameras: not built (feature `v4l`)");
    not_built.push("v4l (cameras)");
}

#[cfg(feature = "window")]
fn monitors(report: &mut Report, _not_built: &mut Vec<&str>) {
    match sl_rig::list_monitors() {
        Ok(list) => {
            println!("monitors ({}):", list.len());
            let mut rows = Vec::new();
            for m in &list {
                let refresh = m
                    .refresh_millihertz
                    .map(|r| format!(", {:.2} Hz", f64::from(r) / 1000.0))
                    .unwrap_or_default();
                println!(
                    "  {}: {} {}x{} at ({}, {}), scale {}{refresh}{}",
                    m.index,
                    m.name,
                    m.size.0,
                    m.size.1,
                    m.position.0,
                    m.position.1,
                    m.scale_factor,
                    if m.primary { ", primary" } else { "" }
                );
                rows.push(serde_json::json!({
                    "index": m.index, "name": m.name, "size": m.size, "position": m.position,
                    "scale_factor": m.scale_factor, "primary": m.primary,
                }));
            }
            report.figure("monitors", rows);
        }
        Err(e) => println!("monitors: {e}"),
    }
}

#[cfg(not(feature = "window"))]
fn monitors(_report: &mut Report, not_built: &mut Vec<&str>) {
    println!("monitors: not built (feature `window`)");
    not_built.push("window (monitors, projector)");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serial_ports_are_usb_and_acm_nodes_sorted() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["ttyUSB1", "ttyS0", "ttyACM0", "ttyUSB0", "video0"] {
            std::fs::write(dir.path().join(name), b"").unwrap();
        }
        let names: Vec<String> = serial_ports(dir.path())
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["ttyACM0", "ttyUSB0", "ttyUSB1"]);
        assert!(serial_ports(&dir.path().join("missing")).is_empty());
    }
}
