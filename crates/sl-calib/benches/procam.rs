//! `calibrate_procam` on 10 board poses rendered by the virtual rig (detection, local
//! homographies of 54 corners per view, two Zhang calibrations and the joint refinement).
//! Rendering the 10 × 45 frames takes about a minute before the measurement starts.
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench setup: a failure ends the bench

use criterion::{Criterion, criterion_group, criterion_main};
use sl_calib::{BoardSize, ProcamConfig, calibrate_procam, sl_camera::ImageSize};

#[path = "../tests/it/support/procam_render.rs"]
mod procam_render;

fn bench(c: &mut Criterion) {
    let r = procam_render::render(10, 5);
    let cfg = ProcamConfig::new(
        BoardSize::new(9, 6),
        20.0,
        ImageSize::new(
            r.config.projector.size.width,
            r.config.projector.size.height,
        ),
    );
    let mut g = c.benchmark_group("procam");
    g.sample_size(10);
    g.bench_function("calibrate_procam 10 views 1280x720", |b| {
        b.iter(|| calibrate_procam(&r.views, &cfg).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
