//! One capture folder (`manifest.json` and its frames) decoded into maps and pictures (what
//! `slscan decode` runs), or decoded and triangulated with a calibration into a cloud, depth
//! maps and a preview (what `slscan reconstruct` runs).

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use sl_camera::Calibration;
use sl_cloud::{PlyFormat, PreviewColoring, PreviewConfig, render_preview, write_ply};
use sl_codec::{
    CaptureSet, DecodeConfig, InvalidReason, MANIFEST_FILE, MapFormat, check_frames, decode,
    read_capture_colour, read_colour_image, write_outputs, write_png_rgb8,
};
use sl_tri::{
    DEPTH_PNG_SCALE_MM, PointStatus, Texture, TriConfig, Triangulator, check_depth_png_scale,
    write_depth_png16, write_depth_tiff,
};

use crate::error::io;
use crate::progress::timed;
use crate::{RunReport, ScanError, ScanProgress, StageTime};

/// What [`reconstruct_capture`] does beside the triangulation's own settings.
#[derive(Debug, Clone)]
pub struct CaptureReconstructionConfig {
    /// The triangulation (method, quality and depth bounds, ...).
    pub tri: TriConfig,
    /// An image of the object under full light for the colours (grey or colour); `None`: the
    /// capture's own colour (`sl_codec::read_capture_colour`: its colour frame, white frame,
    /// fringe mean or brightest frames).
    pub texture: Option<PathBuf>,
    /// Millimetres per unit of the 16-bit depth PNG.
    pub depth_png_scale_mm: f64,
}

impl Default for CaptureReconstructionConfig {
    fn default() -> Self {
        Self {
            tri: TriConfig::default(),
            texture: None,
            depth_png_scale_mm: DEPTH_PNG_SCALE_MM,
        }
    }
}

/// What [`reconstruct_capture`] made and wrote (`cloud.ply`, `depth.png`, `depth.tiff`,
/// `preview.png` in the output folder).
#[derive(Debug, Clone, Serialize)]
pub struct CaptureReconstruction {
    /// The triangulation method's name.
    pub method: &'static str,
    /// Camera image width (px).
    pub width: usize,
    /// Camera image height (px).
    pub height: usize,
    /// Points of the cloud.
    pub points: usize,
    /// Fraction of the pixels the decoder gave a code.
    pub decoded_fraction: f64,
    /// Fraction of the pixels that became a point.
    pub valid_fraction: f64,
    /// RMS reprojection error of the points (px; NaN when no point has one).
    pub rms_reprojection_px: f64,
    /// Millimetres per unit of the depth PNG.
    pub depth_png_scale_mm: f64,
    /// Points the preview could not show (beyond its budget).
    pub preview_left_out_points: usize,
    /// What the preview left out, in words, when it left something out.
    pub preview_note: Option<String>,
    /// Where the points' colours came from: `texture` (the given image), or the capture's
    /// `colour_frame`, `white_frame`, `fringe_mean` or `brightest` frames.
    pub colour_source: &'static str,
    /// Pixels per status of the triangulation (`valid`, `out_of_depth_range`, ...).
    pub pixels_by_status: Vec<(&'static str, usize)>,
    /// Corners of the cloud's bounding box (mm), when it has a point.
    pub bbox_mm: Option<([f64; 3], [f64; 3])>,
    /// The cloud.
    pub cloud: PathBuf,
    /// Wall time per stage: `read calibration`, `read capture`, `decode`, `precompute rays`,
    /// `triangulate`, `write ply`, `write depth`, `preview`.
    pub stages: Vec<StageTime>,
}

/// Writes `path` through `write` into a temporary name beside it, renamed into place: a
/// failure never leaves a half-written file in place of a good one.
fn via_temporary<E: Into<ScanError>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), ScanError> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("tmp");
    let tmp = path.with_extension(format!("partial.{ext}"));
    write(&tmp).map_err(Into::into)?;
    std::fs::rename(&tmp, path).map_err(io(path))
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

/// Decodes the capture in `capture` (its `manifest.json` and frames), triangulates it with the
/// calibration file `calibration` and writes into `out` (created when missing) `cloud.ply`,
/// `depth.png` (16-bit, [`CaptureReconstructionConfig::depth_png_scale_mm`] per unit),
/// `depth.tiff` (32-bit float, mm) and `preview.png`.
///
/// # Errors
/// The triangulation's settings out of range ([`ScanError::Tri`]); the calibration's and the
/// capture's files; [`ScanError::Step`] naming the capture when it cannot be triangulated
/// (the calibration does not fit it, or it codes an axis the method does not use);
/// [`ScanError::Session`] naming the capture when no point came out, with the pixel statuses
/// that took them; the outputs' files.
pub fn reconstruct_capture(
    capture: &Path,
    calibration: &Path,
    cfg: &CaptureReconstructionConfig,
    out: &Path,
) -> Result<CaptureReconstruction, ScanError> {
    cfg.tri.validate()?;
    std::fs::create_dir_all(out).map_err(io(out))?;
    let mut stages = Vec::new();
    let calibration = timed(&mut stages, "read calibration", || {
        Calibration::load(calibration)
    })?;
    let set = timed(&mut stages, "read capture", || {
        CaptureSet::load(&capture.join(MANIFEST_FILE))
    })?;
    let map = timed(&mut stages, "decode", || {
        decode(&set, &DecodeConfig::default())
    })?;
    let tri = timed(&mut stages, "precompute rays", || {
        Triangulator::new(&calibration)
    })?;
    let (texture, colour_source) = match &cfg.texture {
        Some(path) => (read_colour_image(path)?, "texture"),
        None => {
            let c = read_capture_colour(&capture.join(MANIFEST_FILE))?;
            (c.image, c.source.name())
        }
    };
    let method = cfg.tri.method;
    let result = timed(&mut stages, "triangulate", || {
        tri.triangulate_textured(&map, Some(Texture::Rgb8(texture.data())), &cfg.tri)
    })
    .map_err(|e| ScanError::Step {
        what: format!("cannot triangulate {}", capture.display()),
        source: Box::new(e.into()),
    })?;
    drop(set);
    if result.counts.valid == 0 {
        return Err(ScanError::Session {
            path: capture.to_path_buf(),
            reason: format!(
                "no point triangulated with method {} ({})",
                method.name(),
                why_empty(&result.status, map.valid_fraction())
            ),
        });
    }
    // Nothing is written at a depth scale that would lose depths in `depth.png`.
    let depth = result.depth_map();
    check_depth_png_scale(&depth, cfg.depth_png_scale_mm)?;
    let ply = out.join("cloud.ply");
    timed(&mut stages, "write ply", || {
        write_ply(&ply, &result.cloud, PlyFormat::default())
    })?;
    let (w, h) = (result.width, result.height);
    timed(&mut stages, "write depth", || -> Result<(), ScanError> {
        via_temporary(&out.join("depth.png"), |p| {
            write_depth_png16(p, w, h, &depth, cfg.depth_png_scale_mm)
        })?;
        via_temporary(&out.join("depth.tiff"), |p| {
            write_depth_tiff(p, w, h, &depth)
        })
    })?;
    let (left_out, note) = timed(&mut stages, "preview", || -> Result<_, ScanError> {
        let preview = render_preview(
            &result.cloud,
            PreviewColoring::Colors,
            &PreviewConfig::default(),
        )?;
        via_temporary(&out.join("preview.png"), |p| {
            write_png_rgb8(
                p,
                preview.width as usize,
                preview.height as usize,
                &preview.rgb,
            )
        })?;
        Ok((preview.left_out, preview.left_out_note(result.cloud.len())))
    })?;
    Ok(CaptureReconstruction {
        method: method.name(),
        width: w,
        height: h,
        points: result.counts.valid,
        decoded_fraction: map.valid_fraction(),
        valid_fraction: result.valid_fraction(),
        rms_reprojection_px: result.rms_reprojection_px(),
        depth_png_scale_mm: cfg.depth_png_scale_mm,
        preview_left_out_points: left_out,
        preview_note: note,
        colour_source,
        pixels_by_status: PointStatus::ALL
            .iter()
            .map(|s| (s.name(), result.status.iter().filter(|x| *x == s).count()))
            .collect(),
        bbox_mm: result
            .cloud
            .bounding_box()
            .map(|b| ([b.min.x, b.min.y, b.min.z], [b.max.x, b.max.y, b.max.z])),
        cloud: ply,
        stages,
    })
}

/// `{"name": count, …}` in the given order, for the pixel counts of the reports.
fn counts_by_name(counts: &[(&'static str, usize)]) -> serde_json::Value {
    serde_json::Value::Object(
        counts
            .iter()
            .map(|&(name, n)| (name.to_owned(), n.into()))
            .collect(),
    )
}

impl CaptureReconstruction {
    /// Records the figures of `slscan reconstruct`'s `report.json` and the stage times in
    /// `report`.
    pub fn record(&self, report: &mut RunReport) {
        report.add_stages(&self.stages);
        report.figure("method", self.method);
        report.figure("width", self.width);
        report.figure("height", self.height);
        report.figure("points", self.points);
        report.figure("decoded_fraction", self.decoded_fraction);
        report.figure("valid_fraction", self.valid_fraction);
        report.figure(
            "rms_reprojection_px",
            if self.rms_reprojection_px.is_finite() {
                self.rms_reprojection_px.into()
            } else {
                serde_json::Value::Null
            },
        );
        report.figure("depth_png_scale_mm", self.depth_png_scale_mm);
        report.figure("preview_left_out_points", self.preview_left_out_points);
        report.figure("pixels_by_status", counts_by_name(&self.pixels_by_status));
        report.figure("colour_source", self.colour_source);
        if let Some((min, max)) = self.bbox_mm {
            report.figure("bbox_min_mm", min.to_vec());
            report.figure("bbox_max_mm", max.to_vec());
        }
    }

    /// What the reconstruction made, a line each: what the preview left out (when it did),
    /// then the cloud.
    #[must_use]
    pub fn summary(&self) -> Vec<String> {
        let mut lines: Vec<String> = self
            .preview_note
            .iter()
            .map(|note| format!("preview: {note}"))
            .collect();
        lines.push(format!(
            "{}: {} points ({:.1} % of {}x{} pixels, decoded {:.1} %), method {}, RMS reprojection {:.3} px",
            self.cloud.display(),
            self.points,
            100.0 * self.valid_fraction,
            self.width,
            self.height,
            100.0 * self.decoded_fraction,
            self.method,
            self.rms_reprojection_px
        ));
        lines
    }
}

/// What [`decode_capture`] decoded and wrote.
#[derive(Debug, Clone, Serialize)]
pub struct CaptureDecoding {
    /// Camera image width (px).
    pub width: usize,
    /// Camera image height (px).
    pub height: usize,
    /// Frames of the capture.
    pub frames: usize,
    /// Bits per sample of the frames.
    pub bit_depth: u32,
    /// Pattern blocks of the manifest.
    pub blocks: usize,
    /// Fraction of the pixels given a code.
    pub valid_fraction: f64,
    /// Wall time of the decoding alone (ms).
    pub decode_ms: f64,
    /// Pixels per reason (`valid`, `shadow`, ...), every reason listed.
    pub pixels_by_reason: Vec<(&'static str, usize)>,
    /// Frames that do not show what the manifest says was projected (`sl_codec::check_frames`:
    /// a repeated, mixed or dark frame), one message each naming the frame; decoded all the
    /// same.
    pub frame_issues: Vec<String>,
    /// The files written: the float maps, the label PNG, the pictures.
    pub files: Vec<PathBuf>,
    /// Wall time per stage: `read`, `decode`, `check frames`, `write`.
    pub stages: Vec<StageTime>,
}

/// Decodes the capture `capture` (a folder holding `manifest.json`, or the manifest itself;
/// the frames looked for in `frames_dir` when given) and writes into `out` the column, row and
/// quality maps in `format`, the label PNG and the false-colour pictures (sl-codec's
/// `write_outputs`), reporting each of the three steps as progress of the stage `decode`.
/// A capture where no pixel decoded is written all the same (the pictures show why) and is
/// not an error here: see [`CaptureDecoding::nothing_decoded`].
///
/// # Errors
/// The settings out of range; [`ScanError::Step`] naming the capture when it cannot be read;
/// the outputs' files.
pub fn decode_capture(
    capture: &Path,
    frames_dir: Option<&Path>,
    config: &DecodeConfig,
    format: MapFormat,
    out: &Path,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<CaptureDecoding, ScanError> {
    config.validate()?;
    let mut step = |done| {
        progress(ScanProgress {
            stage: "decode",
            done,
            total: 3,
        });
    };
    let mut stages = Vec::new();
    step(0);
    let set = timed(&mut stages, "read", || {
        CaptureSet::load_with_frames_dir(capture, frames_dir)
    })
    .map_err(|e| ScanError::Step {
        what: format!("cannot load the capture set {}", capture.display()),
        source: Box::new(e.into()),
    })?;
    step(1);
    let started = Instant::now();
    let map = timed(&mut stages, "decode", || decode(&set, config))?;
    let decode_ms = started.elapsed().as_secs_f64() * 1e3;
    let frame_issues = timed(&mut stages, "check frames", || check_frames(&set, &map))
        .iter()
        .map(ToString::to_string)
        .collect();
    step(2);
    let files = timed(&mut stages, "write", || {
        write_outputs(&map, out, format, Some(set.manifest.projector))
    })?;
    step(3);
    Ok(CaptureDecoding {
        width: map.width,
        height: map.height,
        frames: set.frames.len(),
        bit_depth: set.frames.bit_depth(),
        blocks: set.manifest.blocks.len(),
        valid_fraction: map.valid_fraction(),
        decode_ms,
        frame_issues,
        pixels_by_reason: InvalidReason::ALL
            .iter()
            .zip(map.reason_counts())
            .map(|(r, n)| (r.name(), n))
            .collect(),
        files: files
            .maps
            .into_iter()
            .chain([files.labels])
            .chain(files.pictures)
            .collect(),
        stages,
    })
}

impl CaptureDecoding {
    /// Records the figures of `slscan decode`'s `report.json` and the stage times in `report`.
    pub fn record(&self, report: &mut RunReport) {
        report.add_stages(&self.stages);
        report.figure("width", self.width);
        report.figure("height", self.height);
        report.figure("frames", self.frames);
        report.figure("valid_fraction", self.valid_fraction);
        report.figure("decode_ms", self.decode_ms);
        report.figure("pixels_by_reason", counts_by_name(&self.pixels_by_reason));
        report.figure("frame_issues", self.frame_issues.clone());
        let files: Vec<String> = self.files.iter().map(|p| p.display().to_string()).collect();
        report.figure("files", files);
    }

    /// The invalid pixels by reason, `N pixels REASON`, for the reasons that took some.
    fn invalid(&self) -> impl Iterator<Item = (&'static str, usize)> + '_ {
        self.pixels_by_reason
            .iter()
            .copied()
            .filter(|&(name, n)| name != InvalidReason::Valid.name() && n > 0)
    }

    /// What the decoding found, a line each: the capture (`capture`, as given), the valid
    /// fraction and time, the invalid pixels by reason.
    #[must_use]
    pub fn summary(&self, capture: &Path) -> Vec<String> {
        let mut lines = vec![
            format!(
                "{}: {} frames of {}x{} ({}-bit), {} block(s)",
                capture.display(),
                self.frames,
                self.width,
                self.height,
                self.bit_depth,
                self.blocks
            ),
            format!(
                "valid {:.1}% in {:.1} ms",
                100.0 * self.valid_fraction,
                self.decode_ms
            ),
        ];
        lines.extend(self.invalid().map(|(name, n)| format!("  {name:<18} {n}")));
        lines.extend(self.frame_issues.iter().map(|i| format!("warning: {i}")));
        lines
    }

    /// When no pixel decoded: why, `N pixels REASON, …` (the outputs stay for the diagnosis;
    /// a caller should not call it a success).
    #[must_use]
    pub fn nothing_decoded(&self) -> Option<String> {
        (self.valid_fraction == 0.0).then(|| {
            self.invalid()
                .map(|(name, n)| format!("{n} pixels {name}"))
                .collect::<Vec<_>>()
                .join(", ")
        })
    }
}
