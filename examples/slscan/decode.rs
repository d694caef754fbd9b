//! `slscan decode CAPTURE_DIR --out DIR`: decode a capture set into the projector column and
//! row of every camera pixel, written as float maps, false-colour pictures and `report.json`.

use std::path::PathBuf;

use anyhow::Context;

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
    /// Correct the phase for the projector's response this calibration holds (`slscan
    /// calibrate response`); a calibration without one is refused.
    #[arg(long)]
    pub(crate) calib: Option<PathBuf>,
    /// Fuse the capture's exposures first: its `exposures.json` lists the sub-folders of one
    /// capture at several exposures (docs/capture-format.md); the fused frames (and the
    /// manifest, when the folder has none) are written into the capture folder, then decoded.
    #[arg(long)]
    pub(crate) fuse: bool,
}

/// Runs `slscan decode`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("decode");
    let fusion = if args.fuse {
        let summary = structured_light::scan::fuse_exposure_folder(&args.capture)
            .with_context(|| format!("cannot fuse the exposures of {}", args.capture.display()))?;
        outln!(
            "fused {} exposures ({} ms): pixels per exposure {:?}, {} saturated at every one",
            summary.exposures_ms.len(),
            summary
                .exposures_ms
                .iter()
                .map(|t| format!("{t:.3}"))
                .collect::<Vec<_>>()
                .join(", "),
            summary.pixels,
            summary.saturated_everywhere
        );
        Some(summary)
    } else {
        None
    };
    let manifest = manifest_file(&args.capture);
    let projector_response = match &args.calib {
        Some(path) => {
            let calibration = sl_camera::Calibration::load(path)
                .with_context(|| format!("cannot read the calibration {}", path.display()))?;
            let Some(response) = calibration.projector_response else {
                anyhow::bail!(
                    "--calib {}: the calibration holds no projector response (add one with slscan calibrate response --calib {0})",
                    path.display()
                );
            };
            Some(response)
        }
        None => None,
    };
    let folder = open_out(&args.out, "decode", &[&manifest], &[], args.force)?;
    let config = DecodeConfig {
        projector_response,
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
    if let Some(fusion) = &fusion {
        report.figure("exposure_fusion", serde_json::to_value(fusion)?);
    }
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

    /// A frame that repeats the previous one (a late projector) decodes all the same and is
    /// named in the output's report, with what happened; the capture as written has none.
    #[test]
    fn a_repeated_frame_is_named() {
        let tmp = tempfile::tempdir().unwrap();
        let capture = patterns(tmp.path(), "capture");
        let c = capture.to_str().unwrap();
        let issues = |out: &std::path::Path| -> Vec<String> {
            let text = std::fs::read_to_string(out.join("report.json")).unwrap();
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            serde_json::from_value(v["figures"]["frame_issues"].clone()).unwrap()
        };
        let clean = tmp.path().join("clean");
        slscan(&["decode", c, "--out", clean.to_str().unwrap()]).unwrap();
        assert_eq!(issues(&clean), Vec::<String>::new());
        std::fs::copy(capture.join("004.png"), capture.join("005.png")).unwrap();
        let late = tmp.path().join("late");
        slscan(&["decode", c, "--out", late.to_str().unwrap()]).unwrap();
        let found = issues(&late);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(
            found[0].starts_with("frame 5 (") && found[0].contains("005.png"),
            "{found:?}"
        );
        assert!(found[0].contains("shows frame 4's pattern"), "{found:?}");
    }

    /// `slscan patterns` for a 64x32 projector (Gray code, both axes) into `dir/name`.
    fn patterns(dir: &std::path::Path, name: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        slscan(&[
            "patterns",
            "--projector",
            "64x32",
            "--out",
            p.to_str().unwrap(),
        ])
        .unwrap();
        p
    }

    /// A frame the manifest names that is a folder, or a symbolic link to `/dev/zero`, is
    /// named for what it is (and `/dev/zero` is never read); until issue 30 both were "missing:
    /// … does not exist".
    #[test]
    fn a_frame_that_is_not_a_file_is_named_for_what_it_is() {
        let tmp = tempfile::tempdir().unwrap();
        let capture = patterns(tmp.path(), "capture");
        let c = capture.to_str().unwrap();
        let frame = capture.join("003.png");
        let out = tmp.path().join("out");
        let o = out.to_str().unwrap();
        std::fs::remove_file(&frame).unwrap();
        std::fs::create_dir(&frame).unwrap();
        let err = format!("{:#}", slscan(&["decode", c, "--out", o]).unwrap_err());
        assert!(
            err.contains("003.png") && err.contains("is a directory"),
            "{err}"
        );
        assert!(!err.contains("does not exist"), "{err}");
        #[cfg(unix)]
        {
            std::fs::remove_dir(&frame).unwrap();
            std::os::unix::fs::symlink("/dev/zero", &frame).unwrap();
            let err = format!("{:#}", slscan(&["decode", c, "--out", o]).unwrap_err());
            assert!(
                err.contains("003.png") && err.contains("is not a regular file"),
                "{err}"
            );
            assert!(err.contains("/dev/zero"), "{err}");
            assert!(!err.contains("does not exist"), "{err}");
        }
    }

    /// A capture of grey 32-bit float TIFF frames (written by the `tiff` crate's encoder, as
    /// a camera program using libtiff would) decodes to the maps of the same capture in 8-bit
    /// PNG: the frames hold `v / 255` for the PNG's grey level `v` (docs/capture-format.md:
    /// float frames are clamped to [0, 1] and scaled to 16 bits, so `v / 255` reads as
    /// `257 v`, the PNG's `v` widened). The frames are the patterns dimmed to 40..218 so that
    /// the grey levels, not only black and white, must come through. Until issue 30 such a
    /// frame was refused ("does not support the color type Unknown(32)").
    #[test]
    fn a_float_tiff_capture_decodes_as_its_png_twin() {
        let tmp = tempfile::tempdir().unwrap();
        let pat = patterns(tmp.path(), "patterns");
        let (png, tif) = (tmp.path().join("png"), tmp.path().join("tif"));
        for d in [&png, &tif] {
            std::fs::create_dir(d).unwrap();
            std::fs::copy(pat.join("manifest.json"), d.join("manifest.json")).unwrap();
        }
        let mut frames = 0;
        for f in crate::common::files_below(&pat) {
            if f.extension().is_none_or(|e| e != "png") {
                continue;
            }
            let name = f.file_name().unwrap();
            let g = sl_codec::read_grey8(&f).unwrap();
            let dim: Vec<u8> = g
                .data()
                .iter()
                .map(|&v| 40 + (f64::from(v) * 0.7).round() as u8)
                .collect();
            let (w, h) = (g.width(), g.height());
            let frame = sl_codec::Frame::new(w, h, dim.clone()).unwrap();
            sl_codec::write_png_grey8(&png.join(name), &frame).unwrap();
            // The manifest names `NNN.png`; the reader finds `NNN.tif` beside it.
            let file = std::fs::File::create(tif.join(name).with_extension("tif")).unwrap();
            let float: Vec<f32> = dim.iter().map(|&v| f32::from(v) / 255.0).collect();
            tiff::encoder::TiffEncoder::new(file)
                .unwrap()
                .write_image::<tiff::encoder::colortype::Gray32Float>(w as u32, h as u32, &float)
                .unwrap();
            frames += 1;
        }
        assert!(frames > 10, "{frames} frames");
        let decode = |capture: &std::path::Path, name: &str| {
            let out = tmp.path().join(name);
            slscan(&[
                "decode",
                capture.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--format",
                "npy",
            ])
            .unwrap();
            out
        };
        let (a, b) = (decode(&png, "out_png"), decode(&tif, "out_tif"));
        for map in ["col.npy", "row.npy", "quality.npy"] {
            let (x, y) = (
                std::fs::read(a.join(map)).unwrap(),
                std::fs::read(b.join(map)).unwrap(),
            );
            assert!(x == y, "{map} differs");
        }
        // The maps are not empty: every projector column is seen (the frames are the patterns).
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(b.join("report.json")).unwrap()).unwrap();
        let valid = report["figures"]["valid_fraction"].as_f64();
        assert!(valid.is_some_and(|v| v > 0.99), "{report}");
    }
}
