//! `slscan reconstruct CAPTURE_DIR --calib FILE --out DIR`: decode a capture set and
//! triangulate it into a point cloud (PLY), depth maps, a shaded preview and `report.json`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use sl_camera::Calibration;
use sl_cloud::{PlyFormat, PreviewColoring, PreviewConfig, render_preview, write_ply};
use sl_codec::{
    Axis, CaptureSet, DecodeConfig, Frames, MANIFEST_FILE, decode, load_frame, write_png_rgb8,
};
use sl_tri::{
    DEPTH_PNG_SCALE_MM, Method, PointStatus, Texture, TriConfig, Triangulator, write_depth_png16,
    write_depth_tiff,
};

use crate::common::{Report, ensure_out_dir};

/// Triangulation method on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum MethodArg {
    /// Camera ray against the projector's (distorted) column surface: columns only.
    RayPlane,
    /// Camera ray against the projector's row surface: rows only.
    RayPlaneRow,
    /// Linear least squares (DLT): columns and rows.
    Linear,
    /// Midpoint of the two rays: columns and rows.
    Midpoint,
    /// Minimal reprojection error (Gauss–Newton): columns and rows.
    Optimal,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::RayPlane => Method::RayPlane { axis: Axis::Column },
            MethodArg::RayPlaneRow => Method::RayPlane { axis: Axis::Row },
            MethodArg::Linear => Method::Linear,
            MethodArg::Midpoint => Method::Midpoint,
            MethodArg::Optimal => Method::Optimal,
        }
    }
}

/// Arguments of `slscan reconstruct`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Capture folder holding `manifest.json` and the frames.
    pub(crate) capture: PathBuf,
    /// Calibration file (.json, or OpenCV FileStorage .yml/.yaml/.xml incl. SLStudio's).
    #[arg(long)]
    pub(crate) calib: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Triangulation method.
    #[arg(long, value_enum, default_value_t = MethodArg::RayPlane)]
    pub(crate) method: MethodArg,
    /// Drop pixels whose decode quality (8-bit grey levels) is below this.
    #[arg(long, default_value_t = 0.0)]
    pub(crate) min_quality: f32,
    /// Drop points whose reprojection error (px) is above this.
    #[arg(long, default_value_t = sl_tri::DEFAULT_MAX_REPROJECTION_PX)]
    pub(crate) max_reprojection: f64,
    /// Drop points nearer than this depth (mm).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) min_depth: f64,
    /// Drop points farther than this depth (mm).
    #[arg(long, default_value_t = f64::INFINITY)]
    pub(crate) max_depth: f64,
    /// Mixed-pixel filter: largest depth jump to a neighbour, as a fraction of the depth
    /// (`inf` turns the filter off).
    #[arg(long, default_value_t = sl_tri::DEFAULT_MAX_DEPTH_JUMP)]
    pub(crate) max_depth_jump: f64,
    /// Image of the object under full light for the colours (default: the per-pixel maximum
    /// over the capture's frames, which is the fully lit image for complementary patterns).
    #[arg(long)]
    pub(crate) texture: Option<PathBuf>,
    /// Millimetres per unit of the 16-bit depth PNG.
    #[arg(long, default_value_t = DEPTH_PNG_SCALE_MM)]
    pub(crate) depth_scale: f64,
}

/// Per-pixel maximum over all frames, as 8-bit grey.
fn max_image(frames: &Frames) -> Vec<u8> {
    match frames {
        Frames::U8(f) => {
            let mut out = vec![0u8; f.first().map_or(0, |f| f.len_pixels())];
            for frame in f {
                for (o, v) in out.iter_mut().zip(frame.data()) {
                    *o = (*o).max(*v);
                }
            }
            out
        }
        Frames::U16(f) => {
            let mut out = vec![0u16; f.first().map_or(0, |f| f.len_pixels())];
            for frame in f {
                for (o, v) in out.iter_mut().zip(frame.data()) {
                    *o = (*o).max(*v);
                }
            }
            out.into_iter().map(|v| (v >> 8) as u8).collect()
        }
    }
}

trait LenPixels {
    fn len_pixels(&self) -> usize;
}

impl<T: sl_codec::Sample> LenPixels for sl_codec::Frame<T> {
    fn len_pixels(&self) -> usize {
        self.width() * self.height()
    }
}

/// Writes through a temporary file in the same folder, renamed into place.
fn atomically<E: Into<anyhow::Error>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> anyhow::Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("tmp");
    let tmp = path.with_extension(format!("partial.{ext}"));
    write(&tmp).map_err(Into::into)?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

/// Runs `slscan reconstruct`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("reconstruct");
    let out = ensure_out_dir(&args.out)?;
    let method = Method::from(args.method);
    let options = TriConfig {
        method,
        min_quality: args.min_quality,
        min_depth_mm: args.min_depth,
        max_depth_mm: args.max_depth,
        max_reprojection_px: args.max_reprojection,
        max_depth_jump: args.max_depth_jump,
        ..TriConfig::default()
    };
    options.validate()?;

    let calibration = report.stage("read calibration", || Calibration::load(&args.calib))?;
    let capture = report.stage("read capture", || {
        CaptureSet::load(&args.capture.join(MANIFEST_FILE))
    })?;
    let map = report.stage("decode", || decode(&capture, &DecodeConfig::default()))?;
    let tri = report.stage("precompute rays", || Triangulator::new(&calibration))?;
    let texture = match &args.texture {
        Some(path) => max_image(&load_frame(path)?),
        None => max_image(&capture.frames),
    };
    let result = report
        .stage("triangulate", || {
            tri.triangulate_textured(&map, Some(Texture::Grey8(&texture)), &options)
        })
        .with_context(|| format!("cannot triangulate {}", args.capture.display()))?;
    drop(capture);
    if result.counts.valid == 0 {
        anyhow::bail!(
            "{}: no point triangulated with method {} ({})",
            args.capture.display(),
            method.name(),
            why_empty(&result.status, map.valid_fraction())
        );
    }

    let ply = out.join("cloud.ply");
    report.stage("write ply", || {
        write_ply(&ply, &result.cloud, PlyFormat::default())
    })?;
    let depth = result.depth_map();
    let (w, h) = (result.width, result.height);
    report.stage("write depth", || -> anyhow::Result<()> {
        atomically(&out.join("depth.png"), |p| {
            write_depth_png16(p, w, h, &depth, args.depth_scale)
        })?;
        atomically(&out.join("depth.tiff"), |p| {
            write_depth_tiff(p, w, h, &depth)
        })
    })?;
    let left_out = report.stage("preview", || -> anyhow::Result<usize> {
        let preview = render_preview(
            &result.cloud,
            PreviewColoring::Colors,
            &PreviewConfig::default(),
        )?;
        if let Some(note) = preview.left_out_note(result.cloud.len()) {
            println!("preview: {note}");
        }
        atomically(&out.join("preview.png"), |p| {
            write_png_rgb8(
                p,
                preview.width as usize,
                preview.height as usize,
                &preview.rgb,
            )
        })?;
        Ok(preview.left_out)
    })?;

    let c = result.counts;
    report.figure("method", method.name());
    report.figure("width", w);
    report.figure("height", h);
    report.figure("points", c.valid);
    report.figure("decoded_fraction", map.valid_fraction());
    report.figure("valid_fraction", result.valid_fraction());
    report.figure(
        "rms_reprojection_px",
        nan_to_null(result.rms_reprojection_px()),
    );
    report.figure("depth_png_scale_mm", args.depth_scale);
    report.figure("preview_left_out_points", left_out);
    let by_status: serde_json::Map<String, serde_json::Value> = PointStatus::ALL
        .iter()
        .map(|s| {
            let n = result.status.iter().filter(|x| *x == s).count();
            (s.name().to_owned(), n.into())
        })
        .collect();
    report.figure("pixels_by_status", serde_json::Value::Object(by_status));
    if let Some(b) = result.cloud.bounding_box() {
        report.figure("bbox_min_mm", vec![b.min.x, b.min.y, b.min.z]);
        report.figure("bbox_max_mm", vec![b.max.x, b.max.y, b.max.z]);
    }
    let path = report.write(&out)?;
    println!(
        "{}: {} points ({:.1} % of {}x{} pixels, decoded {:.1} %), method {}, RMS reprojection {:.3} px",
        ply.display(),
        c.valid,
        100.0 * result.valid_fraction(),
        w,
        h,
        100.0 * map.valid_fraction(),
        method.name(),
        result.rms_reprojection_px()
    );
    println!("report: {}", path.display());
    Ok(())
}

/// Why a triangulation gave no point: the pixel statuses that took them, largest first, with
/// the decoded fraction (`nothing decoded` when the decoder found no code at all).
fn why_empty(status: &[PointStatus], decoded_fraction: f64) -> String {
    let mut counts: Vec<(usize, PointStatus)> = PointStatus::ALL
        .iter()
        .map(|s| (status.iter().filter(|x| *x == s).count(), *s))
        .filter(|(n, s)| *n > 0 && *s != PointStatus::Valid)
        .collect();
    counts.sort_by_key(|c| std::cmp::Reverse(c.0));
    let statuses: Vec<String> = counts
        .iter()
        .map(|(n, s)| format!("{n} pixels {}", s.name()))
        .collect();
    if decoded_fraction == 0.0 {
        format!("nothing decoded: {}", statuses.join(", "))
    } else {
        format!(
            "decoded {:.1} % of the pixels, then {}",
            100.0 * decoded_fraction,
            statuses.join(", ")
        )
    }
}

fn nan_to_null(v: f64) -> serde_json::Value {
    if v.is_finite() {
        v.into()
    } else {
        serde_json::Value::Null
    }
}

#[cfg(test)]
mod tests {
    //! `slscan reconstruct` on a column-only capture (what most real systems record) that the
    //! virtual rig renders at a quarter of its resolution (320x180 camera, 480x270 projector),
    //! with the rig's own calibration.

    use std::path::{Path, PathBuf};

    use sl_codec::{Axis, BitDepth, HybridSpec, ImageSize, Pattern, PatternSequence};
    use sl_scan::scaled_rig_config;
    use sl_sim::{Scene, VirtualRig, simulate_scan};

    /// Quarter resolution, as the other command tests.
    const DOWNSCALE: u32 = 4;

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    /// Renders one view of the plane with the recommended hybrid code on the columns only;
    /// returns the capture folder and the calibration file.
    fn column_only_capture(dir: &Path) -> (PathBuf, PathBuf) {
        let rig = VirtualRig::new(scaled_rig_config(DOWNSCALE), Scene::plane()).unwrap();
        let p = rig.config().projector.size;
        let p = ImageSize::new(p.width, p.height);
        let manifest = PatternSequence::new(p)
            .with(Pattern::Hybrid(HybridSpec::recommended(Axis::Column, p)))
            .manifest(BitDepth::Eight);
        simulate_scan(&rig, &manifest, &[0.0], dir, |_| {}).unwrap();
        let calib = dir.join("calibration.json");
        rig.config().calibration().save(&calib).unwrap();
        (dir.join("view_000"), calib)
    }

    fn report(out: &Path) -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
    }

    /// Ray–plane, linear and optimal all triangulate the column-only capture, to the same
    /// points (linear and optimal meet the same exact column surface); midpoint is refused
    /// naming the missing rows; a run that keeps no point is an error naming the capture and
    /// what took the pixels, not an empty cloud with exit 0.
    #[test]
    fn column_only_capture_reconstructs_or_fails_loudly() {
        let tmp = tempfile::tempdir().unwrap();
        let (capture, calib) = column_only_capture(tmp.path());
        let (capture, calib) = (capture.to_str().unwrap(), calib.to_str().unwrap());
        let run = |method: &str, extra: &[&str]| {
            let out = tmp.path().join(format!("out_{method}"));
            let mut args = vec![
                "reconstruct",
                capture,
                "--calib",
                calib,
                "--out",
                out.to_str().unwrap(),
                "--method",
                method,
            ];
            args.extend_from_slice(extra);
            slscan(&args).map(|()| out)
        };
        let reference = run("ray-plane", &[]).unwrap();
        let points = report(&reference)["figures"]["points"].as_u64().unwrap();
        // The plane fills most of the 320x180 view.
        assert!(points > 20_000, "{points} points");
        let cloud = |out: &Path| sl_cloud::read_ply(&out.join("cloud.ply")).unwrap();
        let ref_cloud = cloud(&reference);
        for method in ["linear", "optimal"] {
            let out = run(method, &[]).unwrap();
            let r = report(&out);
            assert_eq!(r["figures"]["points"].as_u64().unwrap(), points, "{method}");
            let c = cloud(&out);
            let worst = c
                .positions()
                .iter()
                .zip(ref_cloud.positions())
                .map(|(a, b)| (a - b).norm())
                .fold(0.0f64, f64::max);
            // PLY stores f32: ~3e-5 mm at 450 mm.
            assert!(worst < 1e-3, "{method}: {worst} mm from ray-plane");
        }

        let err = run("midpoint", &[]).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("projector rows"), "{text}");
        assert!(text.contains(capture), "{text}");

        let err = run("linear", &["--min-depth", "5000", "--max-depth", "6000"]).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("no point triangulated"), "{text}");
        assert!(text.contains(capture), "{text}");
        assert!(text.contains("out_of_depth_range"), "{text}");
    }
}
