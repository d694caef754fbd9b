//! Corner accuracy on rendered boards that look like real captures, against exact truth, with
//! OpenCV's `findChessboardCorners` + `cornerSubPix(11x11)` on the same images in the same run.
//!
//! ```sh
//! cargo run --release -p sl-calib --example corner_harness -- \
//!     --python /work/peers/bin/python [--images 3] [--repeat 5] [--out DIR]
//! ```
//!
//! Renders each condition (lens blur, vignetting, gamma, sensor noise, 0.3–5 MP, squares of
//! 20–120 px, perspective tilt, boards lit by the mean of three phase-shifted fringes; see
//! `tests/support/board_render.rs`), detects the corners with `detect_checkerboard`, writes
//! the images and `manifest.json` (truth per image) to `--out`, runs
//! `benches/peers/opencv_corners.py` on them with `--python` when given, and prints one table:
//! per condition the RMS and largest corner error against truth (px), ours and OpenCV's.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // a command-line tool

#[path = "../tests/support/board_render.rs"]
mod board_render;

use std::path::PathBuf;
use std::time::Instant;

use board_render::{Fringes, RenderSpec, corner_errors, render, rms};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use sl_calib::{BoardSize, DetectorConfig, detect_checkerboard};

/// One condition of the harness: a base spec whose pose is drawn per image.
struct Condition {
    name: &'static str,
    spec: RenderSpec,
    /// Largest tilt about each axis (degrees) drawn per image.
    max_tilt_deg: f64,
}

fn conditions() -> Vec<Condition> {
    let base = |w, h, sq, blur, vig, gamma, noise| RenderSpec {
        blur_sigma: blur,
        vignetting: vig,
        gamma,
        noise,
        ..RenderSpec::new(w, h, sq)
    };
    let fringes = |period_px, ripple| {
        Some(Fringes {
            period_px,
            angle_deg: 4.0,
            ripple,
        })
    };
    vec![
        Condition {
            name: "640x480, 30 px, sharp (blur 0.5)",
            spec: base(640, 480, 30.0, 0.5, 0.2, 1.0, 1.0),
            max_tilt_deg: 25.0,
        },
        Condition {
            name: "1024x768, 20 px, blur 0.8",
            spec: base(1024, 768, 20.0, 0.8, 0.3, 2.2, 2.0),
            max_tilt_deg: 25.0,
        },
        Condition {
            name: "1280x1024, 40 px, blur 1",
            spec: base(1280, 1024, 40.0, 1.0, 0.3, 2.2, 2.0),
            max_tilt_deg: 25.0,
        },
        Condition {
            name: "1688x1352, 50 px, defocus 2",
            spec: base(1688, 1352, 50.0, 2.0, 0.3, 2.2, 2.0),
            max_tilt_deg: 20.0,
        },
        Condition {
            name: "1688x1352, 50 px, blur 1.5, fringe mean",
            spec: RenderSpec {
                fringes: fringes(21.0, 0.04),
                ..base(1688, 1352, 50.0, 1.5, 0.3, 2.2, 3.0)
            },
            max_tilt_deg: 20.0,
        },
        Condition {
            name: "1688x1352, 50 px, blur 1.5, fringe mean, dim, noise 5",
            spec: RenderSpec {
                fringes: fringes(18.0, 0.08),
                exposure: 160.0,
                ..base(1688, 1352, 50.0, 1.5, 0.4, 2.2, 5.0)
            },
            max_tilt_deg: 20.0,
        },
        Condition {
            name: "1688x1352, 50 px, defocus 3, noise 4",
            spec: base(1688, 1352, 50.0, 3.0, 0.3, 2.2, 4.0),
            max_tilt_deg: 20.0,
        },
        Condition {
            name: "1688x1352, 50 px, defocus 2.5, fringe mean, tilt 40",
            spec: RenderSpec {
                fringes: fringes(24.0, 0.08),
                ..base(1688, 1352, 50.0, 2.5, 0.3, 2.2, 3.0)
            },
            max_tilt_deg: 40.0,
        },
        Condition {
            name: "1920x1200, 60 px, blur 1.2, tilt 45",
            spec: base(1920, 1200, 60.0, 1.2, 0.3, 2.2, 2.0),
            max_tilt_deg: 45.0,
        },
        Condition {
            name: "2592x1944, 120 px, blur 2, 16 % ripple",
            spec: RenderSpec {
                fringes: fringes(36.0, 0.16),
                ..base(2592, 1944, 120.0, 2.0, 0.4, 2.2, 3.0)
            },
            max_tilt_deg: 20.0,
        },
    ]
}

/// Per condition: errors of every corner found, images found, images tried, detection time.
#[derive(Default)]
struct Tally {
    errors: Vec<f64>,
    found: usize,
    tried: usize,
    seconds: f64,
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mut python: Option<String> = None;
    let mut out = std::env::temp_dir().join("sl-corner-harness");
    let mut images = 3usize;
    let mut only: Option<String> = None;
    let mut cfg = DetectorConfig::default();
    // Detections per image; the fastest is the time reported (the machine is shared).
    let mut repeat = 1usize;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--python" => python = args.next(),
            "--out" => out = PathBuf::from(args.next().expect("--out DIR")),
            "--images" => {
                images = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .expect("--images N")
            }
            "--only" => only = args.next(),
            "--repeat" => {
                repeat = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .expect("--repeat N")
            }
            "--junction-fraction" => {
                cfg.junction_fraction = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .expect("--junction-fraction F")
            }
            "--max-junction-radius" => {
                cfg.max_junction_radius = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .expect("--max-junction-radius PX")
            }
            _ => {
                eprintln!(
                    "usage: corner_harness [--python PEERS_PYTHON] [--out DIR] [--images N] [--only SUBSTRING] [--repeat N] [--junction-fraction F] [--max-junction-radius PX]"
                );
                std::process::exit(2);
            }
        }
    }
    std::fs::create_dir_all(&out).expect("output directory");
    let mut manifest = Vec::new();
    let mut tallies = Vec::new();
    for (ci, cond) in conditions().iter().enumerate() {
        if only.as_deref().is_some_and(|o| !cond.name.contains(o)) {
            continue;
        }
        let mut rng = Pcg64Mcg::seed_from_u64(0xC0FFEE + ci as u64);
        let mut tally = Tally::default();
        for k in 0..images {
            let t = cond.max_tilt_deg;
            let s = cond.spec;
            let spec = RenderSpec {
                rotation_deg: rng.random_range(-20.0..20.0),
                tilt_x_deg: rng.random_range(-t..t),
                tilt_y_deg: rng.random_range(-t..t) * 0.5,
                offset: (
                    rng.random_range(-0.03..0.03) * f64::from(s.width),
                    rng.random_range(-0.03..0.03) * f64::from(s.height),
                ),
                seed: rng.random(),
                ..s
            };
            let board = render(&spec);
            let file = format!("c{ci}_{k}.png");
            board.image.save(out.join(&file)).expect("write the image");
            let size = BoardSize::new(spec.cols, spec.rows);
            let mut best = f64::INFINITY;
            let mut found = detect_checkerboard(&board.image, size, &cfg, &file);
            for _ in 0..repeat {
                let start = Instant::now();
                found = detect_checkerboard(&board.image, size, &cfg, &file);
                best = best.min(start.elapsed().as_secs_f64());
            }
            tally.seconds += best;
            tally.tried += 1;
            match found {
                Ok(b) => {
                    tally.found += 1;
                    tally
                        .errors
                        .extend(corner_errors(&b.corners, &board.corners));
                }
                Err(e) => eprintln!("ours: {e}"),
            }
            manifest.push(serde_json::json!({
                "condition": cond.name,
                "file": file,
                "cols": spec.cols,
                "rows": spec.rows,
                "truth": board.corners.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
            }));
        }
        eprintln!("{}: rendered and detected", cond.name);
        tallies.push((cond.name, tally));
    }
    let manifest_path = out.join("manifest.json");
    std::fs::write(
        &manifest_path,
        serde_json::to_string(&serde_json::json!({ "images": manifest })).expect("json"),
    )
    .expect("write the manifest");
    // OpenCV on the same images.
    let mut opencv: std::collections::HashMap<String, (f64, f64, usize, usize)> =
        std::collections::HashMap::new();
    if let Some(py) = python {
        let script =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../benches/peers/opencv_corners.py");
        let status = std::process::Command::new(py)
            .arg(&script)
            .arg(&manifest_path)
            .status()
            .expect("run the peer script");
        assert!(status.success(), "{} failed", script.display());
        let text = std::fs::read_to_string(out.join("opencv.json")).expect("opencv.json");
        let v: serde_json::Value = serde_json::from_str(&text).expect("opencv.json");
        for (name, r) in v["conditions"].as_object().expect("conditions") {
            opencv.insert(
                name.clone(),
                (
                    r["rms"].as_f64().unwrap_or(f64::NAN),
                    r["max"].as_f64().unwrap_or(f64::NAN),
                    r["found"].as_u64().unwrap_or(0) as usize,
                    r["tried"].as_u64().unwrap_or(0) as usize,
                ),
            );
        }
    } else {
        eprintln!(
            "OpenCV not run: pass --python /work/peers/bin/python (or run benches/peers/opencv_corners.py {})",
            manifest_path.display()
        );
    }
    println!(
        "| condition | ours RMS (px) | ours max | found | OpenCV RMS (px) | OpenCV max | found | ours ms/image |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (name, t) in &tallies {
        let max = t.errors.iter().copied().fold(0.0, f64::max);
        let (orms, omax, ofound, otried) =
            opencv
                .get(*name)
                .copied()
                .unwrap_or((f64::NAN, f64::NAN, 0, 0));
        println!(
            "| {name} | {:.4} | {:.3} | {}/{} | {orms:.4} | {omax:.3} | {ofound}/{otried} | {:.1} |",
            rms(&t.errors),
            max,
            t.found,
            t.tried,
            1e3 * t.seconds / t.tried.max(1) as f64
        );
    }
}
