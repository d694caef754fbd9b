//! `slscan decode CAPTURE_DIR --out DIR`: decode a capture set into the projector column and
//! row of every camera pixel, written as float maps, false-colour pictures and `report.json`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use sl_codec::{CaptureSet, DecodeConfig, InvalidReason, MapFormat, decode, write_outputs};

use crate::common::{Report, ensure_out_dir};

/// File format of the float maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FormatArg {
    /// 32-bit float TIFF (numpy via tifffile, OpenCV with `IMREAD_UNCHANGED`).
    Tiff,
    /// numpy `.npy`.
    Npy,
}

/// Arguments of `slscan decode`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Capture folder holding `manifest.json` (or the manifest file itself).
    pub(crate) capture: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Look for the frames here instead of where the manifest says.
    #[arg(long)]
    pub(crate) frames: Option<PathBuf>,
    /// File format of the float maps.
    #[arg(long, value_enum, default_value_t = FormatArg::Tiff)]
    pub(crate) format: FormatArg,
    /// Gray code: smallest direct light, 8-bit grey levels.
    #[arg(long, default_value_t = sl_codec::DEFAULT_MIN_DIRECT)]
    pub(crate) min_direct: f32,
    /// Gray code: smallest pattern/inverse difference for a bit, 8-bit grey levels.
    #[arg(long, default_value_t = sl_codec::DEFAULT_MIN_CONTRAST)]
    pub(crate) min_contrast: f32,
    /// Phase: smallest fringe modulation, 8-bit grey levels.
    #[arg(long, default_value_t = sl_codec::DEFAULT_MIN_MODULATION)]
    pub(crate) min_modulation: f32,
    /// Temporal unwrapping tolerance, in periods.
    #[arg(long, default_value_t = sl_codec::DEFAULT_UNWRAP_TOLERANCE)]
    pub(crate) unwrap_tolerance: f32,
    /// Gray code: plain pattern-against-inverse comparison instead of Xu & Aliaga's rules.
    #[arg(long)]
    pub(crate) no_robust: bool,
}

/// Runs `slscan decode`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("decode");
    let out = ensure_out_dir(&args.out)?;
    let config = DecodeConfig {
        min_direct: args.min_direct,
        min_contrast: args.min_contrast,
        min_modulation: args.min_modulation,
        unwrap_tolerance: args.unwrap_tolerance,
        robust: !args.no_robust,
        ..DecodeConfig::default()
    };
    config.validate()?;
    let bar = crate::common::progress(3, "decode");
    let capture = report
        .stage("read", || {
            CaptureSet::load_with_frames_dir(&args.capture, args.frames.as_deref())
        })
        .with_context(|| format!("cannot load the capture set {}", args.capture.display()))?;
    bar.inc(1);
    let started = Instant::now();
    let map = report.stage("decode", || decode(&capture, &config))?;
    let decode_ms = started.elapsed().as_secs_f64() * 1e3;
    bar.inc(1);
    let format = match args.format {
        FormatArg::Tiff => MapFormat::Tiff,
        FormatArg::Npy => MapFormat::Npy,
    };
    let files = report.stage("write", || {
        write_outputs(&map, &out, format, Some(capture.manifest.projector))
    })?;
    bar.finish_and_clear();

    let counts = map.reason_counts();
    println!(
        "{}: {} frames of {}x{} ({}-bit), {} block(s)",
        args.capture.display(),
        capture.frames.len(),
        map.width,
        map.height,
        capture.frames.bit_depth(),
        capture.manifest.blocks.len()
    );
    println!(
        "valid {:.1}% in {decode_ms:.1} ms",
        100.0 * map.valid_fraction()
    );
    for (reason, n) in InvalidReason::ALL.iter().zip(counts) {
        if !reason.is_valid() && n > 0 {
            println!("  {:<18} {n}", reason.name());
        }
    }
    report.figure("width", map.width);
    report.figure("height", map.height);
    report.figure("frames", capture.frames.len());
    report.figure("valid_fraction", map.valid_fraction());
    report.figure("decode_ms", decode_ms);
    let reasons: serde_json::Map<String, serde_json::Value> = InvalidReason::ALL
        .iter()
        .zip(counts)
        .map(|(r, n)| (r.name().to_owned(), n.into()))
        .collect();
    report.figure("pixels_by_reason", serde_json::Value::Object(reasons));
    let written: Vec<String> = files
        .maps
        .iter()
        .chain([&files.labels])
        .chain(&files.pictures)
        .map(|p| p.display().to_string())
        .collect();
    report.figure("files", written);
    let path = report.write(&out)?;
    println!(
        "maps and pictures in {}; report: {}",
        out.display(),
        path.display()
    );
    // No empty success: the maps and the report stay for the diagnosis, the exit code says it.
    if map.valid_fraction() == 0.0 {
        let why: Vec<String> = InvalidReason::ALL
            .iter()
            .zip(counts)
            .filter(|(r, n)| !r.is_valid() && *n > 0)
            .map(|(r, n)| format!("{n} pixels {}", r.name()))
            .collect();
        anyhow::bail!(
            "{}: no pixel decoded ({}); the invalid-pixel picture in {} shows where",
            args.capture.display(),
            why.join(", "),
            out.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    //! `slscan decode` on a capture of black frames: an error naming the capture, not an
    //! empty success.

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    #[test]
    fn a_capture_that_decodes_nothing_is_an_error() {
        let tmp = tempfile::tempdir().unwrap();
        let capture = tmp.path().join("capture");
        let c = capture.to_str().unwrap();
        slscan(&[
            "patterns",
            "--projector",
            "64x32",
            "--axes",
            "columns",
            "--out",
            c,
        ])
        .unwrap();
        // The "camera" saw nothing: every frame black.
        let black = sl_codec::Frame::filled(64, 32, 0).unwrap();
        for f in crate::common::files_below(&capture) {
            if f.extension().is_some_and(|e| e == "png") {
                sl_codec::write_png_grey8(&f, &black).unwrap();
            }
        }
        let out = tmp.path().join("out");
        let err = slscan(&["decode", c, "--out", out.to_str().unwrap()]).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("no pixel decoded"), "{text}");
        assert!(text.contains(c), "{text}");
        assert!(text.contains("2048 pixels shadow"), "{text}");
        assert!(out.join("report.json").is_file());
    }
}
