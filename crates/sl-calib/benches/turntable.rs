//! `calibrate_turntable` on the board standing on the virtual rig's turntable at 7 motor
//! angles (−45° to 45° in 15° steps, as `slscan calibrate all` simulates it), 1280x720: the
//! closed-form axis from the per-view board poses, then Levenberg–Marquardt over every corner
//! (axis, board pose, angle offset and scale) with the standard deviations. Detection is
//! measured once per image beside it, for scale. Rendering the 7 views takes a few seconds
//! before the measurement starts.
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench setup: a failure ends the bench

use criterion::{Criterion, criterion_group, criterion_main};
use sl_calib::{BoardSize, DetectorConfig, TurntableConfig, TurntableView, calibrate_turntable};
use sl_sim::{Checkerboard, RigConfig, Scene, VirtualRig, capture_board_on_table};

fn bench(c: &mut Criterion) {
    let config = RigConfig::default();
    let rig = VirtualRig::new(config.clone(), Scene::plane()).unwrap();
    let board = Checkerboard::default();
    let size = BoardSize::new(board.inner_cols, board.inner_rows);
    let mut images = Vec::new();
    for (k, m) in (-3..=3).map(|k| f64::from(k) * 15.0).enumerate() {
        let cap = capture_board_on_table(&rig, &board, m, None, k as u64).unwrap();
        let img = cap.white.into_u8();
        images.push((m, img));
    }
    let detect = |(m, img): &(f64, sl_calib::sl_codec::Frame<u8>)| {
        TurntableView::detect(
            img,
            &format!("angle {m}"),
            *m,
            size,
            board.square_mm,
            &DetectorConfig::default(),
        )
        .unwrap()
    };
    let views: Vec<TurntableView> = images.iter().map(detect).collect();
    let cfg = TurntableConfig::default();

    let mut g = c.benchmark_group("turntable");
    g.bench_function("calibrate_turntable 7 views 1280x720", |b| {
        b.iter(|| calibrate_turntable(&config.camera, &views, &cfg).unwrap())
    });
    g.bench_function("detect 1 board on the turntable 1280x720", |b| {
        b.iter(|| detect(&images[3]))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
