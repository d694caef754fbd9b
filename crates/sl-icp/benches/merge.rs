//! The 36-view turntable merge of the virtual rig (`tests/it/support/turntable_scene.rs`): views
//! of ~100k points with 0.03 mm noise, initial poses from a slightly wrong axis; the issue's
//! target is at most 5 s on 2 cores. Rendering the views is outside the timing.
//!
//! `cargo bench -p sl-icp --bench merge -- --warm-up-time 1 --measurement-time 3`

#![allow(clippy::unwrap_used, clippy::expect_used)] // benches: fail loudly on bad setup

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Rotation3, Vector3};
use sl_icp::{MergeConfig, PointCloud, align_views, merge_aligned, merge_views, turntable_poses};

#[path = "../tests/it/support/turntable_scene.rs"]
mod scene;

fn bench(c: &mut Criterion) {
    let scene = scene::Scene::new(100_000, 0.03);
    let angles: Vec<f64> = (0..36).map(|i| i as f64 * 10.0).collect();
    let views: Vec<PointCloud> = angles
        .iter()
        .enumerate()
        .map(|(i, &a)| scene.view(a, i as u64))
        .collect();
    let per_view = views.iter().map(PointCloud::len).sum::<usize>() / views.len();
    let mut wrong = scene.axis;
    wrong.direction =
        Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3f64.to_radians()) * wrong.direction;
    wrong.point_mm += Vector3::new(0.5, 0.0, -0.3);
    wrong.angle_scale = 1.001;
    let initial = turntable_poses(&wrong, &angles).unwrap();
    let config = MergeConfig::default();
    let merged = merge_views(&views, &initial, &config).unwrap();
    let (rms, _) = scene.surface_error(0.0, merged.cloud.positions());
    eprintln!(
        "36 views of {per_view} points: merged {} points, RMS to the true surface {rms:.4} mm",
        merged.cloud.len()
    );
    let mut g = c.benchmark_group("turntable_36_views");
    g.sample_size(10);
    g.bench_function("merge_views", |b| {
        b.iter(|| merge_views(&views, &initial, &config).unwrap())
    });
    g.bench_function("align_views", |b| {
        b.iter(|| align_views(&views, &initial, &config).unwrap())
    });
    let poses = merged.alignment.poses.clone();
    g.bench_function("merge_aligned", |b| {
        b.iter(|| merge_aligned(&views, &poses, &config).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
