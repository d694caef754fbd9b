//! Our checkerboard corners of given images, as JSON, for comparison with other detectors
//! (`benches/peers/real_corner_rms.py` feeds them to `cv2.calibrateCamera`).
//!
//! ```sh
//! cargo run --release -p sl-calib --example corners_json -- \
//!     --board 9x6 --refiner junction --out corners.json IMAGE...
//! ```
//!
//! `--refiner saddle` (the saddle points alone: `junction_fraction` 0), `junction`
//! (`DetectorConfig::with_junction_fit()`) or `default` (`DetectorConfig::default()`, whatever
//! the library's default is). Images are read by `sl_calib::load_grey` (16-bit images are
//! scaled to 8 bits by `round(v / 257)`). Writes
//! `{"refiner": ..., "board": [cols, rows], "config": {...}, "images": [{"file": ...,
//! "corners": [[x, y], ...]} or {"file": ..., "error": "..."}]}`; corners in pixels (centre of
//! the top-left pixel at (0, 0), as OpenCV), in the board's order (row by row, `cols` a row).
//! An image where no board is found is recorded with its error; a file that cannot be read
//! stops the run with an error naming it.
#![allow(clippy::print_stdout, clippy::print_stderr)] // a command-line tool

use std::path::PathBuf;
use std::process::ExitCode;

use sl_calib::{BoardSize, DetectorConfig, detect_checkerboard, load_grey};

const USAGE: &str = "usage: corners_json --board COLSxROWS [--refiner saddle|junction|default] [--out FILE] IMAGE...";

/// What the command line asked for.
struct Args {
    board: BoardSize,
    refiner: String,
    config: DetectorConfig,
    out: Option<PathBuf>,
    images: Vec<PathBuf>,
}

fn parse_board(text: &str) -> Result<BoardSize, String> {
    let (c, r) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("--board {text}: expected COLSxROWS, e.g. 9x6"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("--board {text}: {v:?} is not a whole number"))
    };
    Ok(BoardSize::new(parse(c)?, parse(r)?))
}

fn parse_args() -> Result<Args, String> {
    let mut board = None;
    let mut refiner = "junction".to_owned();
    let mut out = None;
    let mut images = Vec::new();
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match a.as_str() {
            "--board" => board = Some(parse_board(&value("--board")?)?),
            "--refiner" => refiner = value("--refiner")?,
            "--out" => out = Some(PathBuf::from(value("--out")?)),
            "-h" | "--help" => return Err(USAGE.to_owned()),
            s if s.starts_with("--") => return Err(format!("unknown option {s}\n{USAGE}")),
            _ => images.push(PathBuf::from(a)),
        }
    }
    let config = match refiner.as_str() {
        "saddle" => DetectorConfig {
            junction_fraction: 0.0,
            ..DetectorConfig::default()
        },
        "junction" => DetectorConfig::with_junction_fit(),
        "default" => DetectorConfig::default(),
        other => {
            return Err(format!(
                "--refiner {other}: expected saddle, junction or default"
            ));
        }
    };
    let board = board.ok_or_else(|| format!("--board is required\n{USAGE}"))?;
    if images.is_empty() {
        return Err(format!("no images given\n{USAGE}"));
    }
    Ok(Args {
        board,
        refiner,
        config,
        out,
        images,
    })
}

fn run(args: &Args) -> Result<(), String> {
    let mut entries = Vec::with_capacity(args.images.len());
    for path in &args.images {
        let label = path.display().to_string();
        let img = load_grey(path).map_err(|e| e.to_string())?;
        let entry = match detect_checkerboard(&img, args.board, &args.config, &label) {
            Ok(found) => serde_json::json!({
                "file": label,
                "corners": found.corners.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
            }),
            Err(e) => {
                eprintln!("corners_json: {e}");
                serde_json::json!({ "file": label, "error": e.to_string() })
            }
        };
        entries.push(entry);
    }
    let doc = serde_json::json!({
        "refiner": args.refiner,
        "board": [args.board.cols, args.board.rows],
        "config": args.config,
        "images": entries,
    });
    let text = serde_json::to_string(&doc).map_err(|e| format!("JSON: {e}"))?;
    match &args.out {
        Some(out) => std::fs::write(out, text).map_err(|e| format!("{}: {e}", out.display())),
        None => {
            println!("{text}");
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match parse_args().and_then(|a| run(&a)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("corners_json: {e}");
            ExitCode::from(2)
        }
    }
}
