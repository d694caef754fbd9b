//! Global registration (no initial pose): FPFH descriptors of 10k and 100k points of a
//! synthetic surface, and the Stanford bunny pairs (`$SL_DATA/bunny`, skipped with a note
//! when `SL_DATA` is unset) with the settings of the Open3D figures
//! (`benches/peers/global_bunny.py`: 2 mm voxels).
//!
//! `SL_DATA=/work/shared/data cargo bench -p sl-icp --bench global -- --warm-up-time 1 --measurement-time 3`
//!
//! - `fpfh/{10k,100k}`: the descriptors alone (normals and k-d tree built beforehand);
//! - `global_bunny/describe/NAME`: one scan's voxel grid, normals, orientation and FPFH
//!   (Open3D's `voxel_down_sample` + `estimate_normals` + `compute_fpfh_feature`);
//! - `global_bunny/match_ransac_icp/S_T`: matching, RANSAC and the final ICP of a described
//!   pair (Open3D's `registration_ransac_based_on_feature_matching`, which has no ICP);
//! - `global_bunny/total/S_T`: everything for one pair from the raw scans.

#![allow(clippy::unwrap_used, clippy::expect_used)] // benches: fail loudly on bad setup

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_cloud::{KdIndex, NormalConfig, NormalOrientation, estimate_normals_with_index};
use sl_icp::{FpfhConfig, GlobalCloud, GlobalConfig, compute_fpfh, register_global_prepared};

#[path = "../tests/it/support/blob.rs"]
mod blob;
#[path = "../tests/it/support/bunny.rs"]
mod bunny;

use blob::blob;

fn descriptors(c: &mut Criterion) {
    let mut g = c.benchmark_group("fpfh");
    g.sample_size(10);
    for (name, n) in [("10k", 10_000), ("100k", 100_000)] {
        let points = blob(n);
        let index = KdIndex::new(&points).unwrap();
        let normals = estimate_normals_with_index(
            &points,
            &index,
            &NormalConfig {
                k: 16,
                orientation: NormalOrientation::Unoriented,
            },
        )
        .unwrap()
        .normals;
        let config = FpfhConfig::default();
        g.bench_function(name, |b| {
            b.iter(|| black_box(compute_fpfh(&points, &normals, &index, &config).unwrap()));
        });
    }
    g.finish();
}

fn bunny_pairs(c: &mut Criterion) {
    let Some(dir) = bunny::bunny_dir("the global registration benchmark") else {
        return;
    };
    let names = ["bun000", "bun045", "bun090"];
    let scans: Vec<_> = names.iter().map(|n| bunny::load(&dir, n)).collect();
    let config = GlobalConfig::default();
    let described: Vec<GlobalCloud> = scans
        .iter()
        .zip(names)
        .map(|(s, n)| GlobalCloud::new(&s.cloud, &config, n).unwrap())
        .collect();
    let mut g = c.benchmark_group("global_bunny");
    g.sample_size(10);
    for (i, name) in names.iter().enumerate() {
        g.bench_function(format!("describe/{name}"), |b| {
            b.iter(|| black_box(GlobalCloud::new(&scans[i].cloud, &config, name).unwrap()));
        });
    }
    for (s, t) in [(1, 0), (2, 0), (2, 1)] {
        let pair = format!("{}_{}", names[s], names[t]);
        g.bench_function(format!("match_ransac_icp/{pair}"), |b| {
            b.iter(|| {
                black_box(
                    register_global_prepared(
                        &described[s],
                        &described[t],
                        &config,
                        (names[s], names[t]),
                    )
                    .unwrap(),
                )
            });
        });
        g.bench_function(format!("total/{pair}"), |b| {
            b.iter(|| {
                black_box(
                    sl_icp::register_global(&scans[s].cloud, &scans[t].cloud, &config).unwrap(),
                )
            });
        });
    }
    g.finish();
}

criterion_group!(benches, descriptors, bunny_pairs);
criterion_main!(benches);
