//! `slscan info FILE`: a summary of a point cloud (PLY) or a calibration file.

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde_json::json;
use sl_camera::Calibration;
use sl_cloud::{PlyPropertyKind, read_ply, read_ply_header};

use crate::common::{Report, ensure_out_dir};

/// Arguments of `slscan info`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// A PLY point cloud, or a calibration file (.json, or OpenCV FileStorage .yml/.yaml/.xml).
    pub(crate) file: PathBuf,
    /// Also write the summary as `report.json` into this folder.
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
}

/// Runs `slscan info`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("info");
    report.figure("file", args.file.display().to_string());
    let ext = args
        .file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "ply" => ply_info(&args.file, &mut report)?,
        "json" | "yml" | "yaml" | "xml" => calibration_info(&args.file, &mut report)?,
        _ => anyhow::bail!(
            "{}: unknown file type (expected .ply, .json, .yml, .yaml or .xml)",
            args.file.display()
        ),
    }
    if let Some(out) = &args.out {
        let out = ensure_out_dir(out)?;
        let path = report.write(&out)?;
        println!("report: {}", path.display());
    }
    Ok(())
}

fn ply_info(path: &Path, report: &mut Report) -> anyhow::Result<()> {
    let header = report.stage("read_header", || read_ply_header(path))?;
    let cloud = report.stage("read", || read_ply(path))?;
    println!(
        "{}: PLY {} {}",
        path.display(),
        header.encoding.keyword(),
        header.version
    );
    for element in &header.elements {
        let props: Vec<String> = element
            .properties
            .iter()
            .map(|p| match p.kind {
                PlyPropertyKind::Scalar(t) => format!("{} {}", t.name(), p.name),
                PlyPropertyKind::List { count, item } => {
                    format!("list {} {} {}", count.name(), item.name(), p.name)
                }
            })
            .collect();
        println!(
            "  element {} {}: {}",
            element.name,
            element.count,
            props.join(", ")
        );
    }
    for c in &header.comments {
        println!("  comment {c}");
    }
    println!("points: {}", cloud.len());
    let attrs: Vec<&str> = [
        cloud.normals().map(|_| "normals"),
        cloud.colors().map(|_| "colours"),
        cloud.quality().map(|_| "quality"),
    ]
    .into_iter()
    .flatten()
    .collect();
    let attrs_text = if attrs.is_empty() {
        "none".to_owned()
    } else {
        attrs.join(", ")
    };
    println!("attributes: {attrs_text}");
    report.figure("format", header.encoding.keyword());
    report.figure("points", cloud.len());
    report.figure("attributes", attrs.clone());
    match cloud.bounding_box() {
        Some(b) => {
            let e = b.extent();
            println!(
                "bounding box: min ({:.6}, {:.6}, {:.6}) max ({:.6}, {:.6}, {:.6}); extent ({:.6}, {:.6}, {:.6}) (file units)",
                b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z, e.x, e.y, e.z
            );
            report.figure(
                "bounding_box",
                json!({ "min": [b.min.x, b.min.y, b.min.z], "max": [b.max.x, b.max.y, b.max.z] }),
            );
        }
        None => println!("bounding box: none (no finite point)"),
    }
    Ok(())
}

fn calibration_info(path: &Path, report: &mut Report) -> anyhow::Result<()> {
    let calib = report
        .stage("read", || Calibration::load(path))
        .with_context(|| format!("cannot read calibration {}", path.display()))?;
    println!("{}:", path.display());
    print!("{calib}");
    let cam = &calib.camera;
    report.figure(
        "camera",
        json!({
            "width": cam.size.width, "height": cam.size.height,
            "fx": cam.intrinsics.fx, "fy": cam.intrinsics.fy,
            "cx": cam.intrinsics.cx, "cy": cam.intrinsics.cy,
            "distortion": cam.distortion.to_opencv_vec(),
        }),
    );
    report.figure("has_projector", calib.projector.is_some());
    report.figure("has_extrinsics", calib.t_cam_proj.is_some());
    report.figure("has_turntable", calib.turntable.is_some());
    Ok(())
}
