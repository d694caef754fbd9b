//! `slscan patterns --projector WxH --codec gray|binary|phase|hybrid --out DIR`: write the pattern
//! images and the `manifest.json` that describes them (and, later, the captured frames).

use std::path::PathBuf;

use anyhow::Context;
use sl_codec::{
    Axis, BitDepth, CodecError, GrayCodeSpec, GrayReference, HybridSpec, ImageSize, Pattern,
    PatternSequence, PhaseShiftSpec, RECOMMENDED_PERIOD_PX, RECOMMENDED_PHASE_STEPS, Unwrap,
};

use crate::common::{Report, open_out};
use crate::values;

/// The projector gammas `--gamma` accepts: real projectors are 1.8 to 2.6; beyond 0.1..10 the
/// pre-compensated fringes sit within a few grey levels of black or white.
const GAMMA_RANGE: std::ops::RangeInclusive<f64> = 0.1..=10.0;

/// The coding method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum CodecArg {
    /// Reflected Gray code, one stripe per projector pixel.
    Gray,
    /// Plain binary code, one stripe per projector pixel.
    Binary,
    /// N-step phase shift at several frequencies with temporal unwrapping.
    Phase,
    /// Phase shift plus the complementary Gray code for the period index.
    Hybrid,
}

/// Which projector coordinates to code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum AxesArg {
    /// Columns only (vertical stripes): enough for ray-plane triangulation.
    Columns,
    /// Rows only (horizontal stripes).
    Rows,
    /// Columns then rows.
    Both,
}

/// What Gray bits are compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ReferenceArg {
    /// Each pattern followed by its inverse (robust; twice the frames).
    Inverse,
    /// One white and one black frame per block.
    WhiteBlack,
    /// Hybrid only: the mean of the fringes (no extra frame).
    PhaseMean,
}

impl From<ReferenceArg> for GrayReference {
    fn from(r: ReferenceArg) -> Self {
        match r {
            ReferenceArg::Inverse => Self::Inverse,
            ReferenceArg::WhiteBlack => Self::WhiteBlack,
            ReferenceArg::PhaseMean => Self::PhaseMean,
        }
    }
}

/// Temporal unwrapping of `--codec phase`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum UnwrapArg {
    /// Coarsest frequency at most one period, each finer one unwrapped from the previous.
    Hierarchical,
    /// Three frequencies whose beat of beats spans the projector.
    Heterodyne,
    /// Two coprime integer period counts (plus optional refining ones).
    NumberTheoretic,
    /// A single frequency of at most one period.
    None,
}

impl From<UnwrapArg> for Unwrap {
    fn from(u: UnwrapArg) -> Self {
        match u {
            UnwrapArg::Hierarchical => Self::Hierarchical,
            UnwrapArg::Heterodyne => Self::Heterodyne,
            UnwrapArg::NumberTheoretic => Self::NumberTheoretic,
            UnwrapArg::None => Self::None,
        }
    }
}

/// Arguments of `slscan patterns`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Projector size, `WIDTHxHEIGHT` (any size, not only powers of two; each side at most
    /// 16384).
    #[arg(long, value_parser = values::projector_size)]
    pub(crate) projector: ImageSize,
    /// Coding method.
    #[arg(long, value_enum, default_value_t = CodecArg::Gray)]
    pub(crate) codec: CodecArg,
    /// Projector coordinates to code.
    #[arg(long, value_enum, default_value_t = AxesArg::Both)]
    pub(crate) axes: AxesArg,
    /// Output folder for the pattern PNGs and `manifest.json`.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Gray and hybrid: what each bit is compared with (`phase-mean`: hybrid only).
    #[arg(long, value_enum, default_value_t = ReferenceArg::Inverse)]
    pub(crate) reference: ReferenceArg,
    /// Gray: do not centre the code on the projector.
    #[arg(long)]
    pub(crate) no_center: bool,
    /// Gray: stripe width in projector pixels (2 or 4 when the camera cannot resolve single
    /// projector pixels); at least 1, and at most half the coded side so that two stripes
    /// fit.
    #[arg(long, default_value_t = 1, value_parser = values::at_least::<u32>(1))]
    pub(crate) stripe_width: u32,
    /// Phase and hybrid: phase steps per frequency (3 to 64). Default: 8 for hybrid (the
    /// capture the toolkit recommends and scans with), 4 for phase.
    #[arg(long, value_parser = values::count_in::<u32>(3..=u64::from(sl_codec::MAX_STEPS)))]
    pub(crate) steps: Option<u32>,
    /// Phase: periods across the projector, comma-separated (default: a heterodyne triple
    /// derived from `--period-px`: P1 = extent / period, P2 = 7/8 P1, P3 = 2 P2 - P1 + 0.9);
    /// each > 0, with periods of at least 2 projector pixels.
    #[arg(long, value_delimiter = ',', value_parser = values::positive)]
    pub(crate) periods: Vec<f64>,
    /// Phase and hybrid: finest fringe period in projector pixels (when `--periods` is not
    /// given). Default: 15 for hybrid (the capture the toolkit recommends), 30 for phase. From
    /// 2 px to the coded side of the projector (the smaller side with `--axes both`).
    #[arg(long, value_parser = values::positive)]
    pub(crate) period_px: Option<f64>,
    /// Phase: temporal unwrapping method.
    #[arg(long, value_enum, default_value_t = UnwrapArg::Heterodyne)]
    pub(crate) unwrap: UnwrapArg,
    /// Phase and hybrid: projector gamma to pre-compensate (1 = none; 0.1 to 10).
    #[arg(long, default_value_t = 1.0, value_parser = values::in_range(GAMMA_RANGE))]
    pub(crate) gamma: f64,
    /// Bit depth of the pattern images (8 or 16).
    #[arg(long, default_value_t = 8, value_parser = values::bit_depth::<u8>)]
    pub(crate) bit_depth: u8,
}

/// Phase steps of `--codec phase` when `--steps` is not given: 4, the classic choice that keeps
/// its three frequencies at 12 frames (hybrid defaults to [`RECOMMENDED_PHASE_STEPS`]).
const PHASE_DEFAULT_STEPS: u32 = 4;

/// Finest period (projector px) of `--codec phase` when `--period-px` is not given: 30, because
/// the heterodyne triple derived from it amplifies phase noise by the ratio of the finest period
/// to the beat of beats, which doubles at 15 px (hybrid defaults to [`RECOMMENDED_PERIOD_PX`]:
/// its Gray code does not amplify noise).
const PHASE_DEFAULT_PERIOD_PX: f64 = 30.0;

/// Phase steps and finest period (projector px) of the phase or hybrid codes: the arguments, or
/// the codec's defaults.
fn steps_and_period(args: &Args) -> (u32, f64) {
    let (steps, period) = match args.codec {
        CodecArg::Hybrid => (RECOMMENDED_PHASE_STEPS, RECOMMENDED_PERIOD_PX),
        _ => (PHASE_DEFAULT_STEPS, PHASE_DEFAULT_PERIOD_PX),
    };
    (
        args.steps.unwrap_or(steps),
        args.period_px.unwrap_or(period),
    )
}

/// The projector axes `--axes` codes.
fn axes(args: &Args) -> &'static [Axis] {
    match args.axes {
        AxesArg::Columns => &[Axis::Column],
        AxesArg::Rows => &[Axis::Row],
        AxesArg::Both => &[Axis::Column, Axis::Row],
    }
}

/// The checks of `slscan patterns` that need more than one value: each names the options as
/// the user gave them.
pub(crate) fn check(args: &Args) -> anyhow::Result<()> {
    let p = args.projector;
    // The smallest side coded: the limit of a stripe or a period.
    let (extent, side) = axes(args)
        .iter()
        .map(|&a| (a.extent(p), a.name()))
        .min()
        .unwrap_or((p.width, "column"));
    match args.codec {
        CodecArg::Gray | CodecArg::Binary => {
            let codec = if args.codec == CodecArg::Gray {
                "gray"
            } else {
                "binary"
            };
            anyhow::ensure!(
                args.reference != ReferenceArg::PhaseMean,
                "--reference phase-mean compares the Gray bits with the mean of the phase \
                 fringes, which --codec {codec} does not project: use --codec hybrid, or \
                 --reference inverse or white-black"
            );
            anyhow::ensure!(
                args.stripe_width <= extent / 2,
                "--stripe-width {}: at most {} for the projector's {extent} px {side}s coded \
                 (two stripes at least must fit, or nothing is coded)",
                args.stripe_width,
                extent / 2
            );
        }
        CodecArg::Phase | CodecArg::Hybrid => {
            if let Some(period) = args.period_px {
                let min = sl_codec::MIN_PERIOD_PIXELS;
                anyhow::ensure!(
                    (min..=f64::from(extent)).contains(&period),
                    "--period-px {period}: a fringe period must be from {min} px to the \
                     projector's {extent} px {side}s it codes (a longer one is a flat pattern)"
                );
            }
        }
    }
    Ok(())
}

/// The block of one axis.
fn block(args: &Args, axis: Axis) -> anyhow::Result<Pattern> {
    let p = args.projector;
    let extent = f64::from(axis.extent(p));
    let (steps, period_px) = steps_and_period(args);
    Ok(match args.codec {
        CodecArg::Gray | CodecArg::Binary => {
            let mut s = GrayCodeSpec::striped(axis, p, args.stripe_width, !args.no_center)
                .map_err(|e| match e {
                    CodecError::Parameter { message, .. } => {
                        anyhow::anyhow!("--stripe-width {}: {message}", args.stripe_width)
                    }
                    other => other.into(),
                })?;
            s.reference = args.reference.into();
            s.binary = args.codec == CodecArg::Binary;
            Pattern::Gray(s)
        }
        CodecArg::Phase => {
            let periods = if args.periods.is_empty() {
                PhaseShiftSpec::heterodyne_periods(extent, period_px)
            } else {
                args.periods.clone()
            };
            Pattern::Phase(PhaseShiftSpec {
                gamma: args.gamma,
                ..PhaseShiftSpec::new(axis, p, steps, periods, args.unwrap.into())
            })
        }
        CodecArg::Hybrid => {
            let mut s = HybridSpec::complementary(axis, p, steps, extent / period_px);
            s.gamma = args.gamma;
            s.gray.reference = args.reference.into();
            Pattern::Hybrid(s)
        }
    })
}

/// How the command line spells `v`.
fn arg_name(v: impl clap::ValueEnum) -> String {
    v.to_possible_value()
        .map_or_else(String::new, |p| p.get_name().to_owned())
}

/// The option of `slscan patterns` behind a parameter the pattern library names (`periods[1]`,
/// `bits`), for its errors.
fn option_of(args: &Args, name: &str) -> String {
    let field = name.rsplit('.').next().unwrap_or(name);
    let field = field.split('[').next().unwrap_or(field);
    match field {
        "periods" | "unwrap" if !args.periods.is_empty() => format!(
            "--periods {} (--unwrap {})",
            args.periods
                .iter()
                .map(f64::to_string)
                .collect::<Vec<_>>()
                .join(","),
            arg_name(args.unwrap)
        ),
        "periods" | "unwrap" => format!(
            "--period-px {} (--unwrap {})",
            steps_and_period(args).1,
            arg_name(args.unwrap)
        ),
        "steps" => format!("--steps {}", steps_and_period(args).0),
        "gamma" => format!("--gamma {}", args.gamma),
        "stripe_width" => format!("--stripe-width {}", args.stripe_width),
        "reference" => format!("--reference {}", arg_name(args.reference)),
        _ => format!("--projector {}", args.projector),
    }
}

/// Runs `slscan patterns`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    check(args)?;
    let mut report = Report::new("patterns");
    let depth = match args.bit_depth {
        16 => BitDepth::Sixteen,
        _ => BitDepth::Eight,
    };
    let mut sequence = PatternSequence::new(args.projector);
    for &axis in axes(args) {
        sequence = sequence.with(block(args, axis)?);
    }
    sequence.validate().map_err(|e| match e {
        CodecError::Parameter { name, message } => {
            anyhow::anyhow!("{}: {message} ({name})", option_of(args, &name))
        }
        other => anyhow::Error::new(other).context("the pattern parameters are not valid"),
    })?;
    let folder = open_out(&args.out, "patterns", &[], &[], false)?;
    let out = folder.path();
    let bar = crate::common::progress(1, "patterns");
    let manifest = report
        .stage("write", || sequence.write(out, depth))
        .with_context(|| format!("cannot write the patterns into {}", args.out.display()))?;
    bar.finish_and_clear();
    for (b, block) in manifest.blocks.iter().enumerate() {
        outln!(
            "block {b}: {} {} ({} frames: {} .. {})",
            block.pattern.codec_name(),
            block.pattern.axis().name(),
            block.frames.len(),
            block.frames.first().map_or("", String::as_str),
            block.frames.last().map_or("", String::as_str),
        );
    }
    if matches!(args.codec, CodecArg::Phase | CodecArg::Hybrid) {
        let (steps, period_px) = steps_and_period(args);
        let defaults = args.steps.is_none() && args.period_px.is_none();
        let note = if defaults && args.codec == CodecArg::Hybrid {
            " (defaults: the capture the toolkit recommends)"
        } else {
            ""
        };
        outln!("{steps} phase steps, finest period {period_px} projector px{note}");
        report.figure("phase_steps", steps);
        report.figure("period_px", period_px);
    }
    report.figure("projector", args.projector.to_string());
    report.figure("frames", manifest.frame_count());
    report.figure("bit_depth", depth.bits());
    report.figure("manifest", manifest.to_json());
    report.write(out)?;
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    outln!(
        "{} patterns of {} written to {} with manifest.json",
        manifest.frame_count(),
        args.projector,
        out.display()
    );
    outln!("report: {}", out.join("report.json").display());
    Ok(())
}

#[cfg(test)]
mod tests {
    //! `slscan patterns` itself: the defaults it writes into the manifest.

    use std::path::Path;

    use sl_codec::{Axis, Manifest, Pattern};

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    fn manifest(dir: &Path) -> Manifest {
        Manifest::load(&dir.join(sl_codec::MANIFEST_FILE)).unwrap()
    }

    /// `--codec hybrid` with no other option writes the capture the scan pipeline projects:
    /// 8 steps, 15 px periods (240 / 15 = 16 periods across the columns, 120 / 15 = 8 down
    /// the rows), complementary Gray code with inverses.
    #[test]
    fn hybrid_defaults_to_the_recommended_capture() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().to_str().unwrap();
        slscan(&[
            "patterns",
            "--projector",
            "240x120",
            "--codec",
            "hybrid",
            "--out",
            out,
        ])
        .unwrap();
        let m = manifest(dir.path());
        assert_eq!(m.blocks.len(), 2);
        for (block, (axis, periods)) in m
            .blocks
            .iter()
            .zip([(Axis::Column, 16.0), (Axis::Row, 8.0)])
        {
            let Pattern::Hybrid(h) = &block.pattern else {
                panic!("not a hybrid block: {:?}", block.pattern);
            };
            assert_eq!(h.axis, axis);
            assert_eq!(h.steps, 8);
            assert_eq!(h.periods, periods);
        }
        // The same numbers as the library's recommendation (which the scan pipeline uses).
        let expected =
            sl_codec::HybridSpec::recommended(Axis::Column, sl_codec::ImageSize::new(240, 120));
        assert_eq!(m.blocks[0].pattern, Pattern::Hybrid(expected));
    }

    /// Explicit `--steps` and `--period-px` still win; `--codec phase` keeps its own defaults
    /// (4 steps, finest period 30 px: 240 / 30 = 8 periods).
    #[test]
    fn explicit_values_and_phase_defaults() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().to_str().unwrap();
        slscan(&[
            "patterns",
            "--projector",
            "240x120",
            "--codec",
            "hybrid",
            "--axes",
            "columns",
            "--steps",
            "5",
            "--period-px",
            "24",
            "--out",
            out,
        ])
        .unwrap();
        let Pattern::Hybrid(h) = &manifest(dir.path()).blocks[0].pattern else {
            panic!("not hybrid");
        };
        assert_eq!((h.steps, h.periods), (5, 10.0));

        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().to_str().unwrap();
        slscan(&[
            "patterns",
            "--projector",
            "240x120",
            "--codec",
            "phase",
            "--axes",
            "columns",
            "--out",
            out,
        ])
        .unwrap();
        let Pattern::Phase(p) = &manifest(dir.path()).blocks[0].pattern else {
            panic!("not phase");
        };
        assert_eq!(p.steps, 4);
        assert_eq!(p.periods[0], 8.0);
    }

    /// A stripe of no pixel is refused naming the option, not widened to one pixel.
    #[test]
    fn a_zero_stripe_width_is_refused_by_its_option() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("p");
        let e = slscan(&[
            "patterns",
            "--projector",
            "64x32",
            "--stripe-width",
            "0",
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap_err();
        let text = format!("{e:#}");
        assert!(text.contains("'0' for '--stripe-width"), "{text}");
        assert!(!out.join("manifest.json").exists());
        // A stripe wider than half the projector leaves one stripe: nothing is coded.
        let e = slscan(&[
            "patterns",
            "--projector",
            "64x32",
            "--stripe-width",
            "40",
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap_err();
        let text = format!("{e:#}");
        assert!(text.starts_with("--stripe-width 40: "), "{text}");
        assert!(text.contains("32"), "{text}");
        assert!(!out.join("manifest.json").exists());
    }

    /// `slscan patterns ARGS… --out OUT` that must fail: its error, and no manifest written.
    fn refused(args: &[&str]) -> String {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("p");
        let mut all = vec!["patterns"];
        all.extend_from_slice(args);
        all.extend(["--out", out.to_str().unwrap()]);
        let e = slscan(&all).unwrap_err();
        assert!(
            !out.join("manifest.json").exists(),
            "{args:?} wrote a manifest"
        );
        format!("{e:#}")
    }

    /// Sets the decoder would refuse, flat patterns and sizes no projector has are refused
    /// naming the options as the user gave them: before, `--codec gray --reference
    /// phase-mean` wrote a set `slscan decode` rejects, `--period-px 1e9` wrote flat fringes,
    /// and `--projector 100000x100000` was refused as `blocks[0].bits`.
    #[test]
    fn nonsense_pattern_options_are_refused_by_their_names() {
        for codec in ["gray", "binary"] {
            let text = refused(&[
                "--projector",
                "64x32",
                "--codec",
                codec,
                "--reference",
                "phase-mean",
            ]);
            assert!(
                text.contains("--reference phase-mean")
                    && text.contains(&format!("--codec {codec}")),
                "{text}"
            );
        }
        for codec in ["phase", "hybrid"] {
            let text = refused(&[
                "--projector",
                "64x32",
                "--codec",
                codec,
                "--period-px",
                "1e9",
            ]);
            assert!(text.starts_with("--period-px 1000000000: "), "{text}");
            // The limit: the projector's height when both axes are coded.
            assert!(text.contains("32"), "{text}");
            for bad in ["NaN", "inf", "0", "-3"] {
                let text = refused(&[
                    "--projector",
                    "64x32",
                    "--codec",
                    codec,
                    &format!("--period-px={bad}"),
                ]);
                assert!(text.contains("--period-px"), "{bad}: {text}");
            }
        }
        let text = refused(&["--projector", "100000x100000"]);
        assert!(text.contains("'100000x100000' for '--projector"), "{text}");
        assert!(text.contains("16384"), "{text}");
        assert!(!text.contains("bits"), "{text}");
    }
}
