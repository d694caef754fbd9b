//! Issue 30's "done when": no success on nonsense. Two sweeps through `slscan` itself.
//!
//! **Every numeric option of every subcommand** — found through clap's introspection
//! (`Cli::command()`: the subcommands, their options that take a value whose parser yields a
//! number, a size, a board or an overlap) — is fed hostile values on top of a small, fast base
//! invocation of its command, and:
//! - a run that succeeds must have written a non-empty, finite result: every PLY has at least
//!   one point and only finite coordinates, every `report.json` parses, the pictures that carry
//!   data are not of one grey (and not most of a pattern set's frames);
//! - a run that fails must name the option (`--name`) in its message.
//!
//! How the values are picked, per option:
//! 1. a fixed hostile list by kind: negative, zero, −0, NaN, ±inf, ±1e308, 1e-308, the smallest
//!    subnormal, 2^32, 2^64, fractions; for whole numbers also 255/256, 65535/65536, 2^32−1,
//!    2^64−1, `1e3` and `1.5`; for sizes `0x0`, `100000x100000`, one-sided and malformed ones;
//! 2. the bounds the option's parser enforces, found by bisection on clap's parse alone
//!    (between neighbours of a ladder of values that one accepts and one refuses), and the
//!    value on each side of every bound;
//! 3. a few values from a seeded generator (`Pcg64`, seed [`SEED`] plus the option's index, so
//!    the options can be swept in parallel and each still gets the same values): a random sign times
//!    10^u, u uniform in −12..12 (floats), or 10^u, u in 0..20 (whole numbers).
//!
//! A value refused by clap is checked at once (its message). Of the values clap accepts, the
//! commands that run in well under a second on the fixtures run on at most
//! [`MAX_RUNS_PER_OPTION`] of them — bounds first, then the extremes, then the random ones.
//! `scan`, `capture`, `calibrate capture` (they render a virtual rig for seconds to minutes),
//! `simulate` (it renders the full-size rig) and `calibrate camera|projector|turntable|all`
//! (they need rendered board sessions) are checked by parsing and their validation function
//! (`crate::validate`) only: there, an accepted value must at least be a finite number.
//!
//! **Every key of a capture's `manifest.json`** (from `slscan patterns`, Gray, phase and hybrid
//! codes) is given hostile JSON values (numbers out of range, wrong types, `null`, a missing
//! key) and seeded random numbers, and the capture decoded with `slscan decode`: success only
//! with a non-empty decode, else the message names the key.

use std::any::TypeId;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::CommandFactory;
use nalgebra::{Isometry3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use sl_calib::BoardSize;
use sl_cloud::{PlyFormat, PointCloud, write_ply};
use sl_codec::ImageSize;
use sl_icp::Trimming;

/// Seed of the random values.
const SEED: u64 = 30;

/// Most accepted values a command is run on per option (the others are parsed only).
const MAX_RUNS_PER_OPTION: usize = 12;

/// Random values per option.
const RANDOM_VALUES: usize = 3;

/// What an option's parser yields.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Float,
    Whole,
    Size,
    Board,
    Overlap,
}

/// The kind of `arg`'s values, `None` for options that are not numbers.
fn kind(arg: &clap::Arg) -> Option<Kind> {
    let id = arg.get_value_parser().type_id();
    let is = |t: TypeId| id == t;
    if is(TypeId::of::<f64>()) || is(TypeId::of::<f32>()) {
        Some(Kind::Float)
    } else if [
        TypeId::of::<u8>(),
        TypeId::of::<u16>(),
        TypeId::of::<u32>(),
        TypeId::of::<u64>(),
        TypeId::of::<usize>(),
        TypeId::of::<i32>(),
        TypeId::of::<i64>(),
    ]
    .into_iter()
    .any(is)
    {
        Some(Kind::Whole)
    } else if is(TypeId::of::<ImageSize>()) {
        Some(Kind::Size)
    } else if is(TypeId::of::<BoardSize>()) {
        Some(Kind::Board)
    } else if is(TypeId::of::<Trimming>()) {
        Some(Kind::Overlap)
    } else {
        None
    }
}

/// One numeric option: the subcommand's path (`["calibrate", "camera"]`), its long name, its
/// kind and whether it takes a comma-separated list.
#[derive(Debug, Clone)]
struct NumericOption {
    command: Vec<String>,
    long: String,
    kind: Kind,
    list: bool,
}

/// Every numeric option of every subcommand, through clap's introspection.
fn numeric_options() -> Vec<NumericOption> {
    fn walk(cmd: &clap::Command, path: &mut Vec<String>, found: &mut Vec<NumericOption>) {
        for arg in cmd.get_arguments() {
            let (Some(long), Some(kind)) = (arg.get_long(), kind(arg)) else {
                continue;
            };
            if arg.get_action().takes_values() {
                found.push(NumericOption {
                    command: path.clone(),
                    long: long.to_owned(),
                    kind,
                    list: arg.get_value_delimiter().is_some(),
                });
            }
        }
        for sub in cmd.get_subcommands() {
            path.push(sub.get_name().to_owned());
            walk(sub, path, found);
            path.pop();
        }
    }
    let mut found = Vec::new();
    walk(&crate::Cli::command(), &mut Vec::new(), &mut found);
    found
}

/// How a subcommand is exercised.
enum Base {
    /// Run it (`{out}` stands for a fresh output folder); the files named must not be of one
    /// grey ("pattern set": most of the frames of the manifest in `{out}` must not be).
    Run {
        args: Vec<String>,
        must_vary: &'static [&'static str],
    },
    /// Parse it and call `crate::validate` only.
    Validate(Vec<String>),
}

/// The small inputs of the base invocations.
struct Fixtures {
    dir: tempfile::TempDir,
    patterns: PathBuf,
    capture: PathBuf,
    calibration: PathBuf,
    blob_a: PathBuf,
    blob_b: PathBuf,
    ball: PathBuf,
    truth: PathBuf,
}

/// Centre of the fixtures' ball (mm), its radius 20 mm.
const BALL_CENTRE: Point3<f64> = Point3::new(0.0, 0.0, 300.0);

impl Fixtures {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let patterns = dir.path().join("patterns");
        crate::run_cli(&[
            "patterns",
            "--projector",
            "64x32",
            "--axes",
            "columns",
            "--out",
            patterns.to_str().unwrap(),
        ])
        .unwrap();
        let (capture, calibration) =
            crate::reconstruct::tests::column_only_capture(&dir.path().join("capture"));
        let blob = crate::blob_support::blob(3000);
        let blob_a = dir.path().join("blob_a.ply");
        write_ply(
            &blob_a,
            &PointCloud::from_positions(blob.iter().map(|p| p + Vector3::z() * 300.0).collect()),
            PlyFormat::default(),
        )
        .unwrap();
        let motion = Isometry3::new(
            Vector3::new(1.0, -0.5, 300.5),
            Vector3::new(0.0, 0.03, 0.01),
        );
        let blob_b = dir.path().join("blob_b.ply");
        write_ply(
            &blob_b,
            &PointCloud::from_positions(blob.iter().map(|p| motion * p).collect()),
            PlyFormat::default(),
        )
        .unwrap();
        let n = 2000;
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (p, nrm): (Vec<_>, Vec<_>) = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (f64::from(i) + 0.5) / f64::from(n);
                let t = golden * f64::from(i);
                let r = (1.0 - z * z).sqrt();
                let v = Vector3::new(r * t.cos(), r * t.sin(), z);
                (BALL_CENTRE + v * 20.0, v)
            })
            .unzip();
        let ball = dir.path().join("ball.ply");
        write_ply(
            &ball,
            &PointCloud::from_positions(p).with_normals(nrm).unwrap(),
            PlyFormat::default(),
        )
        .unwrap();
        let truth = dir.path().join("truth.json");
        sl_metrology::Truth::new("ball")
            .with(sl_metrology::Feature::Sphere(sl_metrology::SphereSpec {
                name: "ball".into(),
                radius_mm: 20.0,
                centre_mm: Some(BALL_CENTRE),
                select_mm: 2.0,
            }))
            .save(&truth)
            .unwrap();
        Self {
            dir,
            patterns,
            capture,
            calibration,
            blob_a,
            blob_b,
            ball,
            truth,
        }
    }

    /// The base invocations of `command`, `None` for a subcommand this sweep does not know
    /// (the test then fails: every subcommand with a numeric option needs one).
    fn bases(&self, command: &[String]) -> Option<Vec<Base>> {
        let s = |p: &Path| p.display().to_string();
        let v = |a: &[&str]| a.iter().map(|x| (*x).to_owned()).collect::<Vec<_>>();
        let run = |args: Vec<String>, must_vary| Base::Run { args, must_vary };
        let cmd: Vec<&str> = command.iter().map(String::as_str).collect();
        let missing = s(&self.dir.path().join("no-such-input"));
        Some(match cmd.as_slice() {
            ["patterns"] => ["gray", "phase", "hybrid"]
                .into_iter()
                .map(|codec| {
                    let args = v(&[
                        "patterns",
                        "--projector",
                        "64x32",
                        "--axes",
                        "columns",
                        "--codec",
                        codec,
                        "--out",
                        "{out}",
                    ]);
                    run(args, &["pattern set"])
                })
                .collect(),
            ["decode"] => vec![run(
                v(&["decode", &s(&self.patterns), "--out", "{out}"]),
                &["col_color.png"],
            )],
            ["reconstruct"] => vec![run(
                v(&[
                    "reconstruct",
                    &s(&self.capture),
                    "--calib",
                    &s(&self.calibration),
                    "--out",
                    "{out}",
                ]),
                &["depth.png", "preview.png"],
            )],
            ["info"] => vec![run(
                v(&["info", &s(&self.calibration), "--out", "{out}"]),
                &[],
            )],
            ["register"] => vec![run(
                v(&[
                    "register",
                    &s(&self.blob_b),
                    &s(&self.blob_a),
                    "--out",
                    "{out}",
                ]),
                &["preview.png"],
            )],
            ["align"] => vec![run(
                v(&[
                    "align",
                    &s(&self.blob_a),
                    &s(&self.blob_b),
                    "--out",
                    "{out}",
                ]),
                &["preview.png"],
            )],
            ["merge"] => vec![run(
                v(&[
                    "merge",
                    &s(&self.blob_a),
                    &s(&self.blob_b),
                    "--no-loop",
                    "--out",
                    "{out}",
                ]),
                &["preview.png"],
            )],
            ["mesh"] => vec![run(
                v(&["mesh", &s(&self.ball), "--depth", "5", "--out", "{out}"]),
                &["preview.png"],
            )],
            ["report"] => vec![run(
                v(&[
                    "report",
                    &s(&self.ball),
                    "--truth",
                    &s(&self.truth),
                    "--out",
                    "{out}",
                ]),
                &["error_map.png"],
            )],
            ["simulate"] => vec![Base::Validate(v(&[
                "simulate",
                "--scene",
                "plane",
                "--patterns",
                &s(&self.patterns),
                "--out",
                "{out}",
            ]))],
            ["calibrate", "camera" | "projector" | "all" | "stereo"] => vec![Base::Validate(v(&[
                "calibrate",
                cmd[1],
                &missing,
                "--out",
                "{out}",
            ]))],
            ["calibrate", "turntable"] => vec![Base::Validate(v(&[
                "calibrate",
                "turntable",
                &missing,
                "--calib",
                &s(&self.calibration),
                "--out",
                "{out}",
            ]))],
            ["calibrate", "capture"] => vec![Base::Validate(v(&[
                "calibrate",
                "capture",
                "--virtual",
                "--auto",
                "--out",
                "{out}",
            ]))],
            ["calibrate", "response"] => vec![run(
                v(&[
                    "calibrate",
                    "response",
                    "--virtual",
                    "--downscale",
                    "8",
                    "--levels",
                    "5",
                    "--out",
                    "{out}",
                ]),
                &["response/level_04.png"],
            )],
            ["capture"] => vec![Base::Validate(v(&["capture", "--out", "{out}"]))],
            ["scan"] => vec![Base::Validate(v(&["scan", "--out", "{out}"]))],
            _ => return None,
        })
    }
}

/// The fixed hostile values of a kind (see the module documentation).
fn hostile(kind: Kind, list: bool) -> Vec<String> {
    let floats = [
        "-1",
        "0",
        "-0",
        "NaN",
        "inf",
        "-inf",
        "1e308",
        "-1e308",
        "1e-308",
        "5e-324",
        "4294967296",
        "18446744073709551616",
        "0.5",
        "1",
    ];
    let mut v: Vec<String> = match kind {
        Kind::Float => floats.iter().map(|s| (*s).to_owned()).collect(),
        Kind::Overlap => floats
            .iter()
            .copied()
            .chain(["auto", "Auto"])
            .map(str::to_owned)
            .collect(),
        Kind::Whole => [
            "-1",
            "0",
            "1",
            "2",
            "255",
            "256",
            "65535",
            "65536",
            "4294967295",
            "4294967296",
            "18446744073709551615",
            "18446744073709551616",
            "1e3",
            "1.5",
            "NaN",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect(),
        Kind::Size | Kind::Board => [
            "0x0",
            "1x1",
            "2x2",
            "0x5",
            "5x0",
            "100000x100000",
            "4294967296x2",
            "-1x5",
            "NaNx3",
            "64",
            "x",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect(),
    };
    if list {
        v.extend(["1,2,3", "1,NaN,3", "1e308,0,0", "0,0,0", "1,2"].map(str::to_owned));
    }
    v
}

/// `args` with `{out}` replaced by `out`.
fn with_out(args: &[String], out: &Path) -> Vec<String> {
    let out = out.display().to_string();
    args.iter().map(|a| a.replace("{out}", &out)).collect()
}

/// Whether clap accepts `--long=value` on `base`.
fn parses(base: &[String], long: &str, value: &str) -> bool {
    let mut argv = vec!["slscan".to_owned()];
    argv.extend(with_out(base, Path::new("/nonexistent-out")));
    argv.push(format!("--{long}={value}"));
    <crate::Cli as clap::Parser>::try_parse_from(argv).is_ok()
}

/// The values on each side of every bound that clap enforces on `--long` (module
/// documentation, 2).
fn bounds(base: &[String], long: &str, kind: Kind) -> Vec<String> {
    let mut out = Vec::new();
    match kind {
        Kind::Float | Kind::Overlap => {
            let ladder = [
                -1e308, -1e6, -360.0, -90.0, -1.0, 0.0, 1e-300, 1e-6, 0.1, 0.5, 1.0, 2.0, 10.0,
                90.0, 255.0, 360.0, 1000.0, 1e4, 1e6, 1e308,
            ];
            let ok = |x: f64| parses(base, long, &format!("{x:e}"));
            for w in ladder.windows(2) {
                let (mut a, mut b) = (w[0], w[1]);
                let (oa, ob) = (ok(a), ok(b));
                if oa == ob {
                    continue;
                }
                for _ in 0..200 {
                    let m = if a > 0.0 && b > 0.0 {
                        (a * b).sqrt()
                    } else if a < 0.0 && b < 0.0 {
                        -(a * b).sqrt()
                    } else {
                        0.5 * (a + b)
                    };
                    if m <= a || m >= b {
                        break;
                    }
                    if ok(m) == oa {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                out.push(format!("{a:e}"));
                out.push(format!("{b:e}"));
            }
        }
        Kind::Whole | Kind::Size | Kind::Board => {
            let text = |n: u128| match kind {
                Kind::Whole => n.to_string(),
                _ => format!("{n}x2"),
            };
            let ok = |n: u128| parses(base, long, &text(n));
            let ladder: [u128; 14] = [
                0,
                1,
                2,
                3,
                8,
                100,
                256,
                1000,
                10_000,
                16_385,
                65_537,
                1 << 32,
                1 << 64,
                1 << 65,
            ];
            for w in ladder.windows(2) {
                let (mut a, mut b) = (w[0], w[1]);
                let oa = ok(a);
                if oa == ok(b) {
                    continue;
                }
                while b - a > 1 {
                    let m = a + (b - a) / 2;
                    if ok(m) == oa {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                out.push(text(a));
                out.push(text(b));
            }
        }
    }
    out
}

/// The random values of module documentation, 3.
fn random_values(rng: &mut Pcg64, kind: Kind) -> Vec<String> {
    (0..RANDOM_VALUES)
        .map(|_| match kind {
            Kind::Float | Kind::Overlap => {
                let sign = if rng.random_bool(0.5) { -1.0 } else { 1.0 };
                format!("{:e}", sign * 10f64.powf(rng.random_range(-12.0..12.0)))
            }
            Kind::Whole => (10f64.powf(rng.random_range(0.0..20.0)) as u128).to_string(),
            Kind::Size | Kind::Board => format!(
                "{}x{}",
                10f64.powf(rng.random_range(0.0..6.0)) as u64,
                10f64.powf(rng.random_range(0.0..6.0)) as u64
            ),
        })
        .collect()
}

/// Runs `slscan ARGS…`, a panic turned into an error.
fn run(args: &[String]) -> anyhow::Result<()> {
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    std::panic::catch_unwind(AssertUnwindSafe(|| crate::run_cli(&argv))).unwrap_or_else(|p| {
        let what = p
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| (*s).to_owned()))
            .unwrap_or_default();
        Err(anyhow::anyhow!("PANIC: {what}"))
    })
}

/// Whether the grey or colour picture at `path` holds more than one value.
fn varies(path: &Path) -> Result<bool, String> {
    let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let bytes = img.as_bytes();
    let px = img.color().bytes_per_pixel() as usize;
    Ok(bytes.chunks(px).any(|c| c != &bytes[..px]))
}

/// What is wrong with the outputs of a successful run in `out`, if anything.
fn bad_outputs(out: &Path, must_vary: &[&str]) -> Option<String> {
    let files = crate::common::files_below(out);
    if files.is_empty() {
        return Some("no file written".to_owned());
    }
    for f in &files {
        let name = f.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if name.ends_with(".ply") {
            match sl_cloud::read_ply(f) {
                Ok(c) if c.is_empty() => return Some(format!("{name}: no point")),
                Ok(c)
                    if !c
                        .positions()
                        .iter()
                        .all(|p| p.iter().all(|x| x.is_finite())) =>
                {
                    return Some(format!("{name}: coordinates that are not finite"));
                }
                Ok(_) => {}
                Err(e) => return Some(format!("{name}: {e}")),
            }
        }
        if name == "report.json" {
            let text = std::fs::read_to_string(f).unwrap_or_default();
            if serde_json::from_str::<serde_json::Value>(&text).is_err() {
                return Some("report.json does not parse".to_owned());
            }
        }
    }
    for &want in must_vary {
        if want == "pattern set" {
            let m = sl_codec::Manifest::load(&out.join(sl_codec::MANIFEST_FILE));
            let Ok(m) = m else {
                return Some("no readable manifest.json".to_owned());
            };
            let frames: Vec<String> = m.blocks.iter().flat_map(|b| b.frames.clone()).collect();
            let flat = frames
                .iter()
                .filter(|f| !varies(&out.join(f)).unwrap_or(false))
                .count();
            if 2 * flat > frames.len() {
                return Some(format!(
                    "{flat} of {} pattern frames are flat",
                    frames.len()
                ));
            }
        } else {
            match varies(&out.join(want)) {
                Ok(true) => {}
                Ok(false) => return Some(format!("{want} is of one value")),
                Err(e) => return Some(e),
            }
        }
    }
    if out.join("report.json").is_file() {
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).ok()?).ok()?;
        if r["command"] == "decode" && r["figures"]["valid_fraction"].as_f64() == Some(0.0) {
            return Some("an empty decode".to_owned());
        }
    }
    None
}

/// What sweeping one option found.
struct OptionSweep {
    failures: Vec<String>,
    runs: usize,
    parsed: usize,
    seconds: f64,
}

/// Sweeps option `o` (the `index`-th: its generator's seed and its output folders) over every
/// base invocation of its command.
fn sweep_option(fx: &Fixtures, o: &NumericOption, index: usize) -> OptionSweep {
    let t0 = Instant::now();
    let mut rng = Pcg64::seed_from_u64(SEED.wrapping_add(index as u64));
    let mut sweep = OptionSweep {
        failures: Vec::new(),
        runs: 0,
        parsed: 0,
        seconds: 0.0,
    };
    let mut counter = 0usize;
    let mut fresh_out = || {
        counter += 1;
        fx.dir.path().join(format!("out_{index}_{counter}"))
    };
    let flag = format!("--{}", o.long);
    let bases = fx.bases(&o.command).unwrap_or_default();
    for base in bases {
        let base_args = match &base {
            Base::Run { args, .. } | Base::Validate(args) => args.clone(),
        };
        let mut values = bounds(&base_args, &o.long, o.kind);
        values.extend(hostile(o.kind, o.list));
        values.extend(random_values(&mut rng, o.kind));
        let mut seen = std::collections::HashSet::new();
        values.retain(|v| seen.insert(v.clone()));
        let mut accepted_runs = 0;
        for value in values {
            let out = fresh_out();
            let mut args = with_out(&base_args, &out);
            args.push(format!("{flag}={value}"));
            let argv: Vec<String> = std::iter::once("slscan".to_owned())
                .chain(args.iter().cloned())
                .collect();
            sweep.parsed += 1;
            let command = match <crate::Cli as clap::Parser>::try_parse_from(&argv) {
                Ok(cli) => cli.command,
                Err(e) => {
                    let text = e.to_string();
                    if !text.contains(&flag) {
                        sweep
                            .failures
                            .push(format!("{args:?}: clap's message: {text}"));
                    }
                    continue;
                }
            };
            match &base {
                Base::Validate(_) => match crate::validate(&command) {
                    Err(e) => {
                        let text = format!("{e:#}");
                        if !text.contains(&flag) {
                            sweep.failures.push(format!("{args:?}: {text}"));
                        }
                    }
                    Ok(()) => {
                        let finite = value
                            .split([',', 'x'])
                            .all(|x| x.parse::<f64>().ok().is_none_or(f64::is_finite));
                        if !finite {
                            sweep.failures.push(format!("{args:?}: accepted"));
                        }
                    }
                },
                Base::Run { must_vary, .. } => {
                    if accepted_runs >= MAX_RUNS_PER_OPTION {
                        continue;
                    }
                    accepted_runs += 1;
                    sweep.runs += 1;
                    match run(&args) {
                        Ok(()) => {
                            if let Some(why) = bad_outputs(&out, must_vary) {
                                sweep.failures.push(format!("{args:?}: exit 0 but {why}"));
                            }
                        }
                        Err(e) => {
                            let text = format!("{e:#}");
                            if !text.contains(&flag) {
                                sweep.failures.push(format!("{args:?}: {text}"));
                            }
                        }
                    }
                }
            }
        }
    }
    sweep.seconds = t0.elapsed().as_secs_f64();
    sweep
}

/// Every numeric option of every subcommand: a run that succeeds wrote a non-empty, finite
/// result; one that fails named the option (module documentation).
#[test]
fn every_numeric_option_is_checked_where_it_is_given() {
    let start = Instant::now();
    let fx = Fixtures::new();
    let options = numeric_options();
    assert!(
        options.len() > 60,
        "only {} numeric options found",
        options.len()
    );
    // The base invocations succeed as they are.
    let mut commands: Vec<Vec<String>> = options.iter().map(|o| o.command.clone()).collect();
    commands.dedup();
    for (c, command) in commands.iter().enumerate() {
        let bases = fx
            .bases(command)
            .unwrap_or_else(|| panic!("no base invocation for `slscan {}`", command.join(" ")));
        for (b, base) in bases.into_iter().enumerate() {
            if let Base::Run { args, must_vary } = base {
                let out = fx.dir.path().join(format!("base_{c}_{b}"));
                let r = run(&with_out(&args, &out));
                assert!(r.is_ok(), "base {args:?}: {r:?}");
                assert_eq!(bad_outputs(&out, must_vary), None, "base {args:?}");
            }
        }
    }
    // The options in parallel (the runs are independent: each writes its own folder), each
    // with its own seeded generator so the values do not depend on the order they run in.
    let swept: Vec<OptionSweep> = options
        .par_iter()
        .enumerate()
        .map(|(i, o)| sweep_option(&fx, o, i))
        .collect();
    let failures: Vec<String> = swept.iter().flat_map(|s| s.failures.clone()).collect();
    let runs: usize = swept.iter().map(|s| s.runs).sum();
    let parsed: usize = swept.iter().map(|s| s.parsed).sum();
    let mut timings: Vec<(String, f64)> = options
        .iter()
        .zip(&swept)
        .map(|(o, s)| (format!("{} --{}", o.command.join(" "), o.long), s.seconds))
        .collect();
    timings.sort_by(|a, b| b.1.total_cmp(&a.1));
    eprintln!(
        "{} options, {parsed} values parsed, {runs} runs, {:.1} s; slowest: {:?}",
        options.len(),
        start.elapsed().as_secs_f64(),
        &timings[..timings.len().min(8)]
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Every leaf of `value` with its path as the manifest loader names it (`blocks[0].bits`): the
/// objects' keys and the first element of each array (the arrays themselves too).
fn leaves(value: &serde_json::Value, path: &str, out: &mut Vec<String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                out.push(p.clone());
                leaves(v, &p, out);
            }
        }
        serde_json::Value::Array(items) => {
            if let Some(first) = items.first() {
                let p = format!("{path}[0]");
                if !first.is_object() {
                    out.push(p.clone());
                }
                leaves(first, &p, out);
            }
        }
        _ => {}
    }
}

/// The place `path` names in `root` (`blocks[0].gray.bits`), and its parent's key.
fn pointer(path: &str) -> String {
    let mut p = String::new();
    for part in path.split('.') {
        match part.split_once('[') {
            Some((key, index)) => {
                p.push('/');
                p.push_str(key);
                p.push('/');
                p.push_str(index.trim_end_matches(']'));
            }
            None => {
                p.push('/');
                p.push_str(part);
            }
        }
    }
    p
}

/// The hostile JSON values a manifest key is given (`None`: the key removed), and
/// [`RANDOM_VALUES`] seeded random numbers (a random sign times 10^u, u uniform in −12..12,
/// and 10^u whole, u in 0..20).
fn hostile_json(rng: &mut Pcg64) -> Vec<Option<serde_json::Value>> {
    use serde_json::json;
    let random = (0..RANDOM_VALUES).flat_map(|_| {
        let sign = if rng.random_bool(0.5) { -1.0 } else { 1.0 };
        [
            json!(sign * 10f64.powf(rng.random_range(-12.0..12.0))),
            json!(10f64.powf(rng.random_range(0.0..20.0)) as u64),
        ]
    });
    let random: Vec<serde_json::Value> = random.collect();
    [
        json!(-1),
        json!(0),
        json!(0.5),
        json!(-0.5),
        json!(1e308),
        json!(-1e308),
        json!(1e-308),
        json!(4_294_967_296u64),
        json!(18_446_744_073_709_551_615u64),
        json!(65),
        json!(""),
        json!("x"),
        json!("../../etc/passwd"),
        json!(true),
        json!(null),
        json!([]),
        json!({}),
    ]
    .into_iter()
    .chain(random)
    .map(Some)
    .chain([None])
    .collect()
}

/// Every key of a capture's `manifest.json` (Gray, phase and hybrid codes of `slscan patterns`,
/// the frames those patterns themselves): `slscan decode` of the manifest with that key given
/// a hostile value (or removed) succeeds only with a non-empty decode, else names the key.
#[test]
fn every_manifest_key_is_checked_where_it_is_read() {
    let start = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    let mut runs = 0usize;
    let mut rng = Pcg64::seed_from_u64(SEED);
    for codec in ["gray", "phase", "hybrid"] {
        let frames = tmp.path().join(codec);
        crate::run_cli(&[
            "patterns",
            "--projector",
            "64x32",
            "--axes",
            "columns",
            "--codec",
            codec,
            "--out",
            frames.to_str().unwrap(),
        ])
        .unwrap();
        let text = std::fs::read_to_string(frames.join(sl_codec::MANIFEST_FILE)).unwrap();
        let manifest: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut keys = Vec::new();
        leaves(&manifest, "", &mut keys);
        for key in keys {
            let name = key
                .rsplit('.')
                .next()
                .unwrap_or(&key)
                .split('[')
                .next()
                .unwrap_or(&key)
                .to_owned();
            for value in hostile_json(&mut rng) {
                let mut m = manifest.clone();
                let ptr = pointer(&key);
                match &value {
                    Some(v) => {
                        if let Some(slot) = m.pointer_mut(&ptr) {
                            *slot = v.clone();
                        }
                    }
                    None => {
                        let (parent, last) = ptr.rsplit_once('/').unwrap_or(("", ""));
                        match m.pointer_mut(parent) {
                            Some(serde_json::Value::Object(o)) => {
                                o.remove(last);
                            }
                            Some(serde_json::Value::Array(a)) => {
                                a.remove(0);
                            }
                            _ => {}
                        }
                    }
                }
                if m == manifest {
                    continue;
                }
                runs += 1;
                let dir = tmp.path().join(format!("m{runs}"));
                std::fs::create_dir_all(&dir).unwrap();
                let path = dir.join(sl_codec::MANIFEST_FILE);
                std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
                let out = dir.join("out");
                let args: Vec<String> = [
                    "decode",
                    path.to_str().unwrap(),
                    "--frames",
                    frames.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                ]
                .map(str::to_owned)
                .to_vec();
                let shown = value
                    .as_ref()
                    .map_or("(removed)".to_owned(), |v| v.to_string());
                match run(&args) {
                    Ok(()) => {
                        if let Some(why) = bad_outputs(&out, &["col_color.png"]) {
                            failures.push(format!("{codec} {key} = {shown}: exit 0 but {why}"));
                        }
                    }
                    Err(e) => {
                        let text = format!("{e:#}");
                        let named = text.contains(&name)
                            || (name == "frames"
                                && value.as_ref().is_some_and(|v| {
                                    v.as_str()
                                        .is_some_and(|s| !s.is_empty() && text.contains(s))
                                }));
                        if !named {
                            failures.push(format!("{codec} {key} = {shown}: {text}"));
                        }
                    }
                }
            }
        }
    }
    eprintln!(
        "{runs} mutated manifests decoded in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
