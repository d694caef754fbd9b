//! Detection on one 640×480 image and Zhang's calibration on 13 views.
//!
//! The images are OpenCV's samples in `$SL_DATA/chessboard`; without `SL_DATA` the detection
//! bench uses a synthetic 640×480 board and the calibration bench the corners stored in
//! `tests/data/left_corners.json`. The 5 MP detection runs on a board rendered by the corner
//! harness's renderer (`tests/it/support/board_render.rs`): 2592×1944, 13×9 inner corners of
//! 120 px squares, lens blur σ = 2 px, vignetting, gamma, sensor noise, tilted.
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench set-up: a failure is the bench failing

#[path = "../tests/it/support/board_render.rs"]
mod board_render;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_calib::sl_codec::Frame;
use sl_calib::{
    BoardSize, CalibrationView, DetectorConfig, ZhangConfig, calibrate_camera, detect_checkerboard,
};

fn image() -> Option<Frame<u8>> {
    let dir = std::env::var_os("SL_DATA")?;
    sl_calib::load_grey(std::path::Path::new(&dir).join("chessboard/left02.jpg")).ok()
}

fn synthetic() -> Frame<u8> {
    let (w, h) = (640, 480);
    let pixels = (0..w * h).map(|k| {
        let (x, y) = ((k % w) as i32, (k / w) as i32);
        let (i, j) = ((x - 120).div_euclid(40), (y - 100).div_euclid(40));
        let inside = (0..10).contains(&i) && (0..7).contains(&j);
        if inside && (i + j) % 2 == 0 { 30 } else { 220 }
    });
    Frame::new(w, h, pixels.collect()).unwrap()
}

fn views() -> Option<Vec<CalibrationView>> {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/left_corners.json"
    ))
    .ok()?;
    let corners: Vec<Vec<[f64; 2]>> = serde_json::from_str(&text).ok()?;
    let obj = BoardSize::new(9, 6).object_points(1.0);
    Some(
        corners
            .iter()
            .map(|c| CalibrationView {
                object_points: obj.clone(),
                image_points: c
                    .iter()
                    .map(|p| nalgebra::Point2::new(p[0], p[1]))
                    .collect(),
            })
            .collect(),
    )
}

fn bench(c: &mut Criterion) {
    let img = image().unwrap_or_else(synthetic);
    let cfg = DetectorConfig::default();
    c.bench_function("detect_checkerboard 640x480 9x6", |b| {
        b.iter(|| detect_checkerboard(&img, BoardSize::new(9, 6), &cfg, "bench").is_ok())
    });
    let spec = board_render::RenderSpec {
        blur_sigma: 2.0,
        vignetting: 0.4,
        gamma: 2.2,
        noise: 3.0,
        rotation_deg: 8.0,
        tilt_x_deg: 15.0,
        tilt_y_deg: -6.0,
        seed: 5,
        ..board_render::RenderSpec::new(2592, 1944, 120.0)
    };
    let big = board_render::render(&spec).image;
    c.bench_function("detect_checkerboard 2592x1944 13x9 blur 2", |b| {
        b.iter(|| detect_checkerboard(&big, BoardSize::new(13, 9), &cfg, "bench").is_ok())
    });
    let blank = Frame::filled(640, 480, 128).unwrap();
    c.bench_function("detect_checkerboard 640x480 no board", |b| {
        b.iter(|| detect_checkerboard(&blank, BoardSize::new(9, 6), &cfg, "bench").is_err())
    });
    if let Some(v) = views() {
        let size = sl_calib::sl_camera::ImageSize::new(640, 480);
        c.bench_function("calibrate_camera 13 views 9x6", |b| {
            b.iter(|| calibrate_camera(&v, size, &ZhangConfig::default()).is_ok())
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
