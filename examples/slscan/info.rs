//! `slscan info FILE`: a summary of a point cloud (PLY) or a calibration file.

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde_json::json;
use sl_camera::{Calibration, CalibrationLayout, ImageSize, LoadConfig};
use sl_cloud::{PlyPropertyKind, read_ply, read_ply_header};

use crate::common::{Report, open_out};

/// Arguments of `slscan info`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// A PLY point cloud, or a calibration file: .json, or OpenCV FileStorage .yml/.yaml/.xml
    /// in the layout of OpenCV's calibration or stereo sample, SLStudio, scan3d-capture or
    /// SLMaster (detected by its keys; see docs/formats.md).
    pub(crate) file: PathBuf,
    /// Also write the summary as `report.json` into this folder.
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// Read the calibration as this layout instead of detecting it: json, opencv-camera,
    /// slstudio, scan3d-capture, slmaster, opencv-stereo.
    #[arg(long, value_parser = parse_layout)]
    pub(crate) layout: Option<CalibrationLayout>,
    /// The camera's image size (`WxH`), for layouts that do not store it (scan3d-capture,
    /// OpenCV's stereo sample); each side at most 65536.
    #[arg(long, value_parser = crate::values::camera_size)]
    pub(crate) camera_size: Option<ImageSize>,
    /// The projector's size (`WxH`), for layouts that do not store it (scan3d-capture,
    /// SLMaster, OpenCV's stereo sample); each side at most 16384.
    #[arg(long, value_parser = crate::values::projector_size)]
    pub(crate) projector_size: Option<ImageSize>,
    /// Write the calibration back to this file (.json, .yml, .yaml or .xml), in `--format`.
    #[arg(long)]
    pub(crate) write: Option<PathBuf>,
    /// Layout of `--write` (default: the layout read when the file type allows it, else
    /// JSON for .json and SLStudio's or OpenCV's calibration sample's for FileStorage).
    #[arg(long, value_parser = parse_layout, requires = "write")]
    pub(crate) format: Option<CalibrationLayout>,
}

fn parse_layout(s: &str) -> Result<CalibrationLayout, String> {
    s.parse().map_err(|e: sl_camera::CameraError| e.to_string())
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
        "json" | "yml" | "yaml" | "xml" => calibration_info(args, &mut report)?,
        _ => anyhow::bail!(
            "{}: unknown file type (expected .ply, .json, .yml, .yaml or .xml)",
            args.file.display()
        ),
    }
    if let Some(out) = &args.out {
        let folder = open_out(out, "info", &[&args.file], &[], false)?;
        report.write(folder.path())?;
        folder.commit()?;
        outln!("report: {}", out.join("report.json").display());
    }
    Ok(())
}

fn ply_info(path: &Path, report: &mut Report) -> anyhow::Result<()> {
    let header = report.stage("read_header", || read_ply_header(path))?;
    let cloud = report.stage("read", || read_ply(path))?;
    outln!(
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
        outln!(
            "  element {} {}: {}",
            element.name,
            element.count,
            props.join(", ")
        );
    }
    for c in &header.comments {
        outln!("  comment {c}");
    }
    outln!("points: {}", cloud.len());
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
    outln!("attributes: {attrs_text}");
    report.figure("format", header.encoding.keyword());
    report.figure("points", cloud.len());
    report.figure("attributes", attrs.clone());
    match cloud.bounding_box() {
        Some(b) => {
            let e = b.extent();
            outln!(
                "bounding box: min ({:.6}, {:.6}, {:.6}) max ({:.6}, {:.6}, {:.6}); extent ({:.6}, {:.6}, {:.6}) (file units)",
                b.min.x,
                b.min.y,
                b.min.z,
                b.max.x,
                b.max.y,
                b.max.z,
                e.x,
                e.y,
                e.z
            );
            report.figure(
                "bounding_box",
                json!({ "min": [b.min.x, b.min.y, b.min.z], "max": [b.max.x, b.max.y, b.max.z] }),
            );
        }
        None => outln!("bounding box: none (no finite point)"),
    }
    Ok(())
}

fn calibration_info(args: &Args, report: &mut Report) -> anyhow::Result<()> {
    let path = &args.file;
    let options = LoadConfig {
        layout: args.layout,
        camera_size: args.camera_size,
        projector_size: args.projector_size,
    };
    let loaded = report
        .stage("read", || Calibration::load_with(path, &options))
        .with_context(|| format!("cannot read calibration {}", path.display()))?;
    let calib = &loaded.calibration;
    outln!("{}:", path.display());
    outln!(
        "layout: {} ({})",
        loaded.layout,
        loaded.layout.description()
    );
    if loaded.files.len() > 1 {
        let others: Vec<String> = loaded.files[1..]
            .iter()
            .map(|f| f.display().to_string())
            .collect();
        outln!("read with: {}", others.join(", "));
    }
    out!("{calib}");
    report.figure("layout", loaded.layout.name());
    report.figure(
        "files",
        loaded
            .files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>(),
    );
    if let Some(out) = &args.write {
        let layout = args
            .format
            .unwrap_or_else(|| default_write_layout(loaded.layout, out, calib));
        let written = calib
            .save_as(out, layout)
            .with_context(|| format!("cannot write {} as {layout}", out.display()))?;
        for f in &written {
            outln!("written ({layout}): {}", f.display());
        }
        report.figure("written_layout", layout.name());
    }
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

/// The layout `--write` uses without `--format`: the one read if the output's type can hold
/// it, else what `Calibration::save` writes for that file type.
fn default_write_layout(
    read: CalibrationLayout,
    out: &Path,
    calib: &Calibration,
) -> CalibrationLayout {
    let json = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    match (json, read) {
        (true, _) => CalibrationLayout::Json,
        (false, CalibrationLayout::Json) => CalibrationLayout::default_for(calib),
        (false, layout) => layout,
    }
}

#[cfg(test)]
mod tests {
    //! `slscan info` on calibration files of other systems: the layout is named, missing sizes
    //! are asked for, and `--write --format` converts between layouts without loss.

    use std::path::PathBuf;

    use sl_camera::{Calibration, CalibrationLayout, LoadConfig};

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    fn peer_file(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("crates/sl-camera/tests/data/layouts")
            .join(name)
    }

    #[test]
    fn info_names_the_layout_and_converts_scan3d_capture_to_slmaster() {
        let src = peer_file("scan3d_capture/calibration.yml");
        let s = src.to_str().unwrap();
        let err = slscan(&["info", s]).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("--camera-size"), "{text}");

        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("caliInfo.yml");
        let report = tmp.path().join("report");
        slscan(&[
            "info",
            s,
            "--camera-size",
            "1280x1024",
            "--projector-size",
            "1024x768",
            "--write",
            out.to_str().unwrap(),
            "--format",
            "slmaster",
            "--out",
            report.to_str().unwrap(),
        ])
        .unwrap();
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(report.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(r["figures"]["layout"], "scan3d-capture");
        assert_eq!(r["figures"]["written_layout"], "slmaster");
        // The SLMaster file holds the same rig (its projector size under an extra key).
        let back = Calibration::load_with(&out, &LoadConfig::default()).unwrap();
        assert_eq!(back.layout, CalibrationLayout::SlMaster);
        let options = LoadConfig {
            camera_size: Some(sl_camera::ImageSize::new(1280, 1024)),
            projector_size: Some(sl_camera::ImageSize::new(1024, 768)),
            ..LoadConfig::default()
        };
        let orig = Calibration::load_with(&src, &options).unwrap().calibration;
        assert_eq!(back.calibration.camera, orig.camera);
        assert_eq!(back.calibration.projector, orig.projector);
        assert_eq!(back.calibration.rms, orig.rms);
        let (a, b) = (
            back.calibration.t_cam_proj.unwrap(),
            orig.t_cam_proj.unwrap(),
        );
        assert!((a.to_homogeneous() - b.to_homogeneous()).abs().max() < 1e-12);
    }

    #[test]
    fn info_reads_the_stereo_sample_from_either_file_and_refuses_a_bad_size() {
        let e = peer_file("opencv_stereo/extrinsics.yml");
        let tmp = tempfile::tempdir().unwrap();
        let report = tmp.path().join("r");
        slscan(&[
            "info",
            e.to_str().unwrap(),
            "--camera-size",
            "1280x1024",
            "--projector-size",
            "1024x768",
            "--out",
            report.to_str().unwrap(),
        ])
        .unwrap();
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(report.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(r["figures"]["layout"], "opencv-stereo");
        assert_eq!(r["figures"]["files"].as_array().unwrap().len(), 2);
        let err = slscan(&["info", e.to_str().unwrap(), "--camera-size", "1280by1024"])
            .unwrap_err()
            .to_string();
        assert!(err.contains("WIDTHxHEIGHT"), "{err}");
    }
}
