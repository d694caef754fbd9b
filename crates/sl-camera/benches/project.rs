//! Projection, unprojection and the per-pixel ray table with the strong reference lens.
//!
//! `cargo bench -p sl-camera --bench project -- --warm-up-time 1 --measurement-time 3`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Point2, Point3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use sl_camera::{CameraError, CameraModel, Distortion, ImageSize, Intrinsics};
use std::hint::black_box;

const N: usize = 1_000_000;

fn reference() -> Result<CameraModel, CameraError> {
    CameraModel::new(
        Intrinsics::new(1440.4, 1437.1, 667.8, 354.2),
        Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1])?,
        ImageSize::new(1280, 720),
    )
}

fn bench(c: &mut Criterion) {
    let Ok(cam) = reference() else {
        return;
    };
    let mut rng = Pcg64::seed_from_u64(7);
    // Pixels uniformly over the image; points on their rays at 0.3–2 m.
    let pixels: Vec<Point2<f64>> = (0..N)
        .map(|_| {
            Point2::new(
                rng.random_range(-0.5..1279.5),
                rng.random_range(-0.5..719.5),
            )
        })
        .collect();
    let points: Vec<Point3<f64>> = pixels
        .iter()
        .filter_map(|px| cam.unproject(px))
        .map(|ray| Point3::from(ray * rng.random_range(300.0..2000.0)))
        .collect();

    let mut g = c.benchmark_group("reference_lens_1M");
    g.sample_size(10);
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("project_serial", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for p in &points {
                if let Some(px) = cam.project(black_box(p)) {
                    acc += px.x;
                }
            }
            acc
        })
    });
    g.bench_function("project_many_parallel", |b| {
        b.iter(|| cam.project_many(black_box(&points)))
    });
    g.bench_function("unproject_serial", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for px in &pixels {
                if let Some(r) = cam.unproject(black_box(px)) {
                    acc += r.x;
                }
            }
            acc
        })
    });
    g.bench_function("unproject_many_parallel", |b| {
        b.iter(|| cam.unproject_many(black_box(&pixels)))
    });
    g.finish();

    let mut g = c.benchmark_group("ray_table");
    g.sample_size(10);
    g.throughput(Throughput::Elements(cam.size.pixel_count() as u64));
    g.bench_function("reference_lens_1280x720", |b| {
        b.iter(|| black_box(&cam).ray_table())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
