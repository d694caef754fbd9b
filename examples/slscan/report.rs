//! `slscan report CLOUD.ply --truth TRUTH.json --out DIR`: measure a scanned cloud against
//! what the scanned artefacts are known to be (sl-metrology, VDI/VDE 2634 part 2): probing
//! errors of form and size, sphere spacing, flatness. Writes `report.json` and an error heat
//! map (`error_map.png`); `docs/metrology.md` describes the truth file.

use std::path::PathBuf;

use anyhow::Context;
use sl_cloud::{PreviewConfig, read_ply};
use sl_codec::write_png_rgb8;
use sl_metrology::{EvaluateConfig, Truth, evaluate_with, heat_map};

use crate::common::{Report, open_out};
use crate::values;

/// Arguments of `slscan report`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The scanned cloud (PLY, millimetres, in the frame of the truth's nominal positions).
    pub(crate) cloud: PathBuf,
    /// The truth description (JSON; see docs/metrology.md).
    #[arg(long)]
    pub(crate) truth: PathBuf,
    /// Output folder (`report.json`, `error_map.png`).
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Write into `--out` even where it holds another command's outputs or the inputs.
    #[arg(long)]
    pub(crate) force: bool,
    /// Heat-map range (mm, 0.001 to 1000): blue at −range, red at +range.
    #[arg(long, default_value_t = sl_metrology::DEFAULT_HEAT_MAP_RANGE_MM,
          value_parser = values::as_f32(values::in_range(0.001..=1000.0)))]
    pub(crate) range: f32,
    /// Fraction of points farthest from a fitted feature left out of the `_trimmed` figures
    /// (0 up to, not including, 0.5).
    #[arg(long, default_value_t = sl_metrology::VDI_TRIM_FRACTION, value_parser = trim_fraction)]
    pub(crate) trim: f64,
    /// Heat-map viewpoint: azimuth about the vertical axis (degrees, -360 to 360).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
          value_parser = values::in_range(-360.0..=360.0))]
    pub(crate) azimuth: f64,
    /// Heat-map viewpoint: elevation (degrees, -90 to 90; negative looks from below).
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true,
          value_parser = values::in_range(-90.0..=90.0))]
    pub(crate) elevation: f64,
}

/// `--trim`: a fraction in [0, 0.5) (half the points or more would leave no feature).
fn trim_fraction(s: &str) -> Result<f64, String> {
    values::non_negative(s)
        .ok()
        .filter(|v| *v < 0.5)
        .ok_or_else(|| "must be a fraction from 0 up to, not including, 0.5".to_owned())
}

/// Runs `slscan report`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("report");
    let folder = open_out(
        &args.out,
        "report",
        &[&args.cloud, &args.truth],
        &[],
        args.force,
    )?;
    let cloud = report
        .stage("read", || read_ply(&args.cloud))
        .with_context(|| format!("cannot read {}", args.cloud.display()))?;
    let truth = Truth::load(&args.truth)?;
    let cfg = EvaluateConfig {
        trim_fraction: args.trim,
        ..EvaluateConfig::default()
    };
    let figures = report.stage("evaluate", || evaluate_with(&cloud, &truth, &cfg))?;
    let view = PreviewConfig {
        azimuth_deg: args.azimuth,
        elevation_deg: args.elevation,
        ..PreviewConfig::default()
    };
    let png = folder.path().join("error_map.png");
    report.stage("heat map", || -> anyhow::Result<()> {
        let mut img = heat_map(&cloud, &figures.signed_distances_mm, args.range, &view)?;
        sl_metrology::draw_legend(&mut img, args.range);
        write_png_rgb8(&png, img.width as usize, img.height as usize, &img.rgb)?;
        Ok(())
    })?;
    report.figure("cloud", args.cloud.display().to_string());
    report.figure("truth", serde_json::to_value(&truth)?);
    report.figure("metrology", serde_json::to_value(&figures)?);
    report.figure("heat_map", "error_map.png");
    report.figure("heat_map_range_mm", f64::from(args.range));
    report.write(folder.path())?;
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    for line in figures.summary() {
        outln!("{line}");
    }
    outln!(
        "report: {}; heat map: {}",
        out.join("report.json").display(),
        out.join("error_map.png").display()
    );
    Ok(())
}
