//! `slscan decode CAPTURE_DIR --out DIR`: decode a capture set into the projector column and
//! row of every camera pixel, written as float maps, false-colour pictures and `report.json`.

use std::path::PathBuf;

use sl_codec::{DecodeConfig, MapFormat};
use sl_scan::decode_capture;

use crate::common::{Report, StageBars, manifest_file, open_out};
use crate::values;

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
    /// Write into `--out` even where that replaces the capture's manifest.
    #[arg(long)]
    pub(crate) force: bool,
    /// Look for the frames here instead of where the manifest says.
    #[arg(long)]
    pub(crate) frames: Option<PathBuf>,
    /// File format of the float maps.
    #[arg(long, value_enum, default_value_t = FormatArg::Tiff)]
    pub(crate) format: FormatArg,
    /// Gray code: smallest direct light, 8-bit grey levels (0 to 255).
    #[arg(long, default_value_t = sl_codec::DEFAULT_MIN_DIRECT, value_parser = values::grey_level)]
    pub(crate) min_direct: f32,
    /// Gray code: smallest pattern/inverse difference for a bit, 8-bit grey levels (0 to 255).
    #[arg(long, default_value_t = sl_codec::DEFAULT_MIN_CONTRAST, value_parser = values::grey_level)]
    pub(crate) min_contrast: f32,
    /// Phase: smallest fringe modulation, 8-bit grey levels (0 to 255).
    #[arg(long, default_value_t = sl_codec::DEFAULT_MIN_MODULATION, value_parser = values::grey_level)]
    pub(crate) min_modulation: f32,
    /// Temporal unwrapping tolerance, in periods (0.01 to 0.5).
    #[arg(long, default_value_t = sl_codec::DEFAULT_UNWRAP_TOLERANCE,
          value_parser = values::as_f32(values::in_range(0.01..=0.5)))]
    pub(crate) unwrap_tolerance: f32,
    /// Gray code: plain pattern-against-inverse comparison instead of Xu & Aliaga's rules.
    #[arg(long)]
    pub(crate) no_robust: bool,
}

/// Runs `slscan decode`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("decode");
    let manifest = manifest_file(&args.capture);
    let folder = open_out(&args.out, "decode", &[&manifest], &[], args.force)?;
    let config = DecodeConfig {
        min_direct: args.min_direct,
        min_contrast: args.min_contrast,
        min_modulation: args.min_modulation,
        unwrap_tolerance: args.unwrap_tolerance,
        robust: !args.no_robust,
        ..DecodeConfig::default()
    };
    let format = match args.format {
        FormatArg::Tiff => MapFormat::Tiff,
        FormatArg::Npy => MapFormat::Npy,
    };
    let mut bars = StageBars::new();
    let mut d = decode_capture(
        &args.capture,
        args.frames.as_deref(),
        &config,
        format,
        folder.path(),
        |p| bars.update(p),
    )?;
    bars.clear();
    for line in d.summary(&args.capture) {
        outln!("{line}");
    }
    d.files = d.files.iter().map(|f| folder.final_path(f)).collect();
    d.record(&mut report);
    report.write(folder.path())?;
    // No empty success, and no good decode replaced by an empty one: the maps and the report
    // are kept apart for the diagnosis, the exit code says it.
    if let Some(why) = d.nothing_decoded() {
        let kept = folder.keep_as_failed()?;
        // What decides each reason: an option, or the manifest's description of the code.
        let causes: Vec<String> = [
            ("shadow", format!("--min-direct {}", args.min_direct)),
            (
                "low_modulation",
                format!(
                    "--min-contrast {}, --min-modulation {}",
                    args.min_contrast, args.min_modulation
                ),
            ),
            (
                "inconsistent_code",
                format!(
                    "--unwrap-tolerance {}, or the manifest's code (origin, phase_offset, \
                     shift_sign, periods, steps, bits, stripe_width, reference) is not the one \
                     the frames show",
                    args.unwrap_tolerance
                ),
            ),
        ]
        .into_iter()
        .filter(|(reason, _)| why.contains(reason))
        .map(|(reason, cause)| format!("{reason}: {cause}"))
        .collect();
        anyhow::bail!(
            "{}: no pixel decoded ({why}; {}); the invalid-pixel picture in {} shows where",
            args.capture.display(),
            causes.join("; "),
            kept.display()
        );
    }
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    outln!(
        "maps and pictures in {}; report: {}",
        out.display(),
        out.join("report.json").display()
    );
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
        assert!(out.join("failed-run/report.json").is_file());
    }
}
