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
//! `tests/it/support/board_render.rs`), detects the corners with `detect_checkerboard` (with
//! `DetectorConfig::with_junction_fit()`; `--junction-fraction 0` for the default saddle
//! points), writes
//! the images and `manifest.json` (truth per image) to `--out`, runs
//! `benches/peers/opencv_corners.py` on them with `--python` when given, and prints one table:
//! per condition the RMS and largest corner error against truth (px), ours and OpenCV's.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // a command-line tool

#[path = "../tests/it/support/board_render.rs"]
mod board_render;

use std::path::PathBuf;
use std::time::Instant;

use board_render::{Fringes, RenderSpec, corner_errors, mean, p95, render, rms};
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
    let fringe_mean = |w, h, sq, blur, period_px, ripple, noise| RenderSpec {
        fringes: fringes(period_px, ripple),
        ..base(w, h, sq, blur, 0.3, 2.2, noise)
    };
    let cond = |name, spec, max_tilt_deg| Condition {
        name,
        spec,
        max_tilt_deg,
    };
    vec![
        // Image size and square size: 0.3–5 MP, 20–120 px.
        cond(
            "640x480, 30 px, sharp (blur 0.5)",
            base(640, 480, 30.0, 0.5, 0.2, 1.0, 1.0),
            25.0,
        ),
        cond(
            "1024x768, 20 px, blur 0.8",
            base(1024, 768, 20.0, 0.8, 0.3, 2.2, 2.0),
            25.0,
        ),
        cond(
            "1024x768, 20 px, defocus 2",
            base(1024, 768, 20.0, 2.0, 0.3, 2.2, 2.0),
            25.0,
        ),
        cond(
            "1280x1024, 40 px, blur 1",
            base(1280, 1024, 40.0, 1.0, 0.3, 2.2, 2.0),
            25.0,
        ),
        cond(
            "1920x1200, 60 px, blur 1.2, tilt 45",
            base(1920, 1200, 60.0, 1.2, 0.3, 2.2, 2.0),
            45.0,
        ),
        cond(
            "2592x1944 (5 MP), 120 px, blur 2",
            base(2592, 1944, 120.0, 2.0, 0.4, 2.2, 3.0),
            20.0,
        ),
        // Lens blur σ 0.5–2 on the issue's real set: 1688x1352, 50 px squares.
        cond(
            "1688x1352, 50 px, blur 0.5",
            base(1688, 1352, 50.0, 0.5, 0.3, 2.2, 2.0),
            20.0,
        ),
        cond(
            "1688x1352, 50 px, blur 1",
            base(1688, 1352, 50.0, 1.0, 0.3, 2.2, 2.0),
            20.0,
        ),
        cond(
            "1688x1352, 50 px, defocus 2",
            base(1688, 1352, 50.0, 2.0, 0.3, 2.2, 2.0),
            20.0,
        ),
        cond(
            "1688x1352, 50 px, defocus 3, noise 4",
            base(1688, 1352, 50.0, 3.0, 0.3, 2.2, 4.0),
            20.0,
        ),
        // Boards lit by the mean of three phase-shifted fringes (no white frame).
        cond(
            "1688x1352, 50 px, blur 1.5, fringe mean",
            fringe_mean(1688, 1352, 50.0, 1.5, 21.0, 0.04, 3.0),
            20.0,
        ),
        cond(
            "1688x1352, 50 px, blur 1.5, fringe mean, dim, noise 5",
            RenderSpec {
                exposure: 160.0,
                vignetting: 0.4,
                ..fringe_mean(1688, 1352, 50.0, 1.5, 18.0, 0.08, 5.0)
            },
            20.0,
        ),
        cond(
            "1688x1352, 50 px, defocus 2.5, fringe mean, tilt 40",
            fringe_mean(1688, 1352, 50.0, 2.5, 24.0, 0.08, 3.0),
            40.0,
        ),
        cond(
            "2592x1944 (5 MP), 120 px, blur 2, fringe mean 16 % ripple",
            RenderSpec {
                vignetting: 0.4,
                ..fringe_mean(2592, 1944, 120.0, 2.0, 36.0, 0.16, 3.0)
            },
            20.0,
        ),
        // Lens distortion: the board's edges curve across a wide fitting window.
        cond(
            "1688x1352, 50 px, blur 1.5, fringe mean, barrel k1 -0.3",
            RenderSpec {
                k1: -0.3,
                ..fringe_mean(1688, 1352, 50.0, 1.5, 21.0, 0.04, 3.0)
            },
            20.0,
        ),
        cond(
            "2592x1944 (5 MP), 120 px, blur 2, barrel k1 -0.3",
            RenderSpec {
                k1: -0.3,
                ..base(2592, 1944, 120.0, 2.0, 0.4, 2.2, 3.0)
            },
            20.0,
        ),
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
    let mut cfg = DetectorConfig::with_junction_fit();
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
            sl_calib::sl_codec::write_png_grey8(&out.join(&file), &board.image)
                .expect("write the image");
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
    let mut opencv: std::collections::HashMap<String, Peer> = std::collections::HashMap::new();
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
            let f = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
            opencv.insert(
                name.clone(),
                Peer {
                    mean: f("mean"),
                    rms: f("rms"),
                    p95: f("p95"),
                    max: f("max"),
                    found: r["found"].as_u64().unwrap_or(0) as usize,
                    ms: f("ms_per_image"),
                },
            );
        }
    } else {
        eprintln!(
            "OpenCV not run: pass --python /work/peers/bin/python (or run benches/peers/opencv_corners.py {})",
            manifest_path.display()
        );
    }
    println!(
        "| condition | ours mean / RMS / p95 (px) | OpenCV mean / RMS / p95 (px) | max ours / OpenCV | found ours / OpenCV | ms/image ours / OpenCV |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, t) in &tallies {
        let max = t.errors.iter().copied().fold(0.0, f64::max);
        let o = opencv.get(*name).copied().unwrap_or(Peer {
            mean: f64::NAN,
            rms: f64::NAN,
            p95: f64::NAN,
            max: f64::NAN,
            found: 0,
            ms: f64::NAN,
        });
        println!(
            "| {name} | {:.4} / {:.4} / {:.4} | {:.4} / {:.4} / {:.4} | {max:.3} / {:.3} | {}/{} / {}/{} | {:.0} / {:.0} |",
            mean(&t.errors),
            rms(&t.errors),
            p95(&t.errors),
            o.mean,
            o.rms,
            o.p95,
            o.max,
            t.found,
            t.tried,
            o.found,
            t.tried,
            1e3 * t.seconds / t.tried.max(1) as f64,
            o.ms,
        );
    }
}

/// OpenCV's figures for one condition, from `opencv.json`.
#[derive(Debug, Clone, Copy)]
struct Peer {
    mean: f64,
    rms: f64,
    p95: f64,
    max: f64,
    found: usize,
    ms: f64,
}
