//! Normals of 1 M points with k = 16, and k-d tree construction.
//!
//! `cargo bench -p sl-cloud --bench normals -- --warm-up-time 1 --measurement-time 3`
//!
//! The cloud is a wavy surface sampled at random with a seeded RNG. It is saved (binary PLY,
//! double) to `$SL_BENCH_DIR/sl-cloud-normals-1m.ply` (default: the system temp dir) so that
//! `benches/peers/open3d_normals.py` times Open3D on the very same points; our normals go to
//! `sl-cloud-normals-1m-ours.ply` beside it for the script to compare.

#![allow(clippy::unwrap_used, clippy::expect_used)] // benches: fail loudly on bad setup

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Point3;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;
use sl_cloud::{KdIndex, NormalConfig, PlyFormat, PointCloud, estimate_normals, write_ply};

const POINTS: usize = 1_000_000;

/// z = 300 + 10 sin(2 pi x / 50) cos(2 pi y / 70) mm over 400 x 400 mm, with 0.02 mm noise:
/// a scanned-surface-like density of about 6 points per square millimetre.
fn wavy_surface() -> PointCloud {
    let mut rng = Pcg64::seed_from_u64(2024);
    let noise = Normal::new(0.0, 0.02).unwrap();
    let tau = std::f64::consts::TAU;
    let pts = (0..POINTS)
        .map(|_| {
            let x: f64 = rng.random_range(0.0..400.0);
            let y: f64 = rng.random_range(0.0..400.0);
            let z = 300.0
                + 10.0 * (tau * x / 50.0).sin() * (tau * y / 70.0).cos()
                + noise.sample(&mut rng);
            Point3::new(x, y, z)
        })
        .collect();
    PointCloud::from_positions(pts)
}

fn bench(c: &mut Criterion) {
    let cloud = wavy_surface();
    let dir = std::env::var_os("SL_BENCH_DIR").map_or_else(std::env::temp_dir, Into::into);
    let input = dir.join("sl-cloud-normals-1m.ply");
    write_ply(&input, &cloud, PlyFormat::default()).unwrap();
    let config = NormalConfig {
        k: 16,
        ..Default::default()
    };
    let est = estimate_normals(&cloud, &config).unwrap();
    let ours = cloud.clone().with_normals(est.normals).unwrap();
    write_ply(
        &dir.join("sl-cloud-normals-1m-ours.ply"),
        &ours,
        PlyFormat::default(),
    )
    .unwrap();
    eprintln!(
        "cloud saved to {} for benches/peers/open3d_normals.py",
        input.display()
    );

    let mut g = c.benchmark_group("normals_1m");
    g.sample_size(10);
    g.bench_function("kdtree_build", |b| {
        b.iter(|| KdIndex::new(cloud.positions()).unwrap())
    });
    g.bench_function("estimate_normals_k16", |b| {
        b.iter(|| estimate_normals(&cloud, &config).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
