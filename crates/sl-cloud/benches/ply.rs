//! PLY throughput on 1 M points: to and from a file in a temporary directory, and in memory.
//!
//! `cargo bench -p sl-cloud --bench ply -- --warm-up-time 1 --measurement-time 3`
//!
//! Throughput is reported in bytes of PLY file per second.

#![allow(clippy::unwrap_used, clippy::expect_used)] // benches: fail loudly on bad setup

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use sl_cloud::{
    PlyEncoding, PlyFormat, PlyScalar, PointCloud, read_ply, read_ply_from_bytes, write_ply,
    write_ply_to_bytes,
};

const POINTS: usize = 1_000_000;

fn clouds() -> Vec<(&'static str, PointCloud, PlyFormat)> {
    let mut rng = Pcg64::seed_from_u64(42);
    let pos: Vec<Point3<f64>> = (0..POINTS)
        .map(|_| {
            Point3::new(
                rng.random_range(-200.0..200.0),
                rng.random_range(-200.0..200.0),
                rng.random_range(300.0..600.0),
            )
        })
        .collect();
    let nor: Vec<Vector3<f64>> = (0..POINTS)
        .map(|_| {
            Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                1.0,
            )
            .normalize()
        })
        .collect();
    let col: Vec<[u8; 3]> = (0..POINTS).map(|_| rng.random()).collect();
    let q: Vec<f32> = (0..POINTS).map(|_| rng.random()).collect();
    let full = PointCloud::from_parts(pos.clone(), Some(nor), Some(col), Some(q)).unwrap();
    let bare = PointCloud::from_positions(pos);
    let le = PlyEncoding::BinaryLittleEndian;
    vec![
        (
            "xyz_nxyz_rgb_q_double",
            full,
            PlyFormat {
                encoding: le,
                scalar: PlyScalar::Double,
            },
        ),
        (
            "xyz_float",
            bare,
            PlyFormat {
                encoding: le,
                scalar: PlyScalar::Float,
            },
        ),
    ]
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    for (name, cloud, format) in clouds() {
        let bytes = write_ply_to_bytes(&cloud, format);
        let path = dir.path().join(format!("{name}.ply"));
        write_ply(&path, &cloud, format).unwrap();
        let mut g = c.benchmark_group(format!("ply_1m_{name}"));
        g.sample_size(10);
        g.throughput(Throughput::Bytes(bytes.len() as u64));
        g.bench_function("write_memory", |b| {
            b.iter(|| write_ply_to_bytes(&cloud, format))
        });
        g.bench_function("read_memory", |b| {
            b.iter(|| read_ply_from_bytes(&bytes).unwrap())
        });
        g.bench_function("write_file", |b| {
            b.iter(|| write_ply(&path, &cloud, format).unwrap())
        });
        g.bench_function("read_file", |b| b.iter(|| read_ply(&path).unwrap()));
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
