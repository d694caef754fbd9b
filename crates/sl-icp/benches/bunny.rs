//! bun045 registered onto bun000 (Stanford bunny, `$SL_DATA/bunny`) from the "5° off" start,
//! with the settings of the peer figures (`benches/peers/icp_bunny.py`). Skips, saying so,
//! when `SL_DATA` is unset.
//!
//! `SL_DATA=/work/shared/data cargo bench -p sl-icp --bench bunny -- --warm-up-time 1 --measurement-time 3`
//!
//! - `icp/point_to_plane_1mm`: the ICP alone (clouds prepared beforehand), as Open3D's 39 ms;
//! - `prepare/...`: voxel grid, normals (target only for point-to-plane) and k-d tree;
//! - `total/...`: preparation and ICP together, as `small_gicp`'s 29 ms.

#![allow(clippy::unwrap_used, clippy::expect_used)] // benches: fail loudly on bad setup

use criterion::{Criterion, criterion_group, criterion_main};
use sl_icp::{
    IcpConfig, Metric, NormalConfig, NormalSource, PoseError, PrepareConfig, PreparedCloud,
    register,
};

#[path = "../tests/it/support/bunny.rs"]
mod bunny;

fn bench(c: &mut Criterion) {
    let Some(dir) = bunny::bunny_dir("the bunny benchmark") else {
        return;
    };
    let (target, source) = (bunny::load(&dir, "bun000"), bunny::load(&dir, "bun045"));
    let reference = bunny::reference(&target, &source);
    let start = bunny::perturbed(&reference, &source.cloud.centroid().unwrap());
    let cases = [
        ("point_to_plane_1mm", 1.0, Metric::PointToPlane, 20),
        ("point_to_plane_2mm", 2.0, Metric::PointToPlane, 20),
        ("generalized_2mm", 2.0, Metric::Generalized, 10),
    ];
    let mut g = c.benchmark_group("bunny");
    for (name, voxel, metric, k) in cases {
        let normals = NormalSource::Estimate(NormalConfig {
            k,
            ..NormalConfig::default()
        });
        let target_prep = PrepareConfig {
            voxel_size: Some(voxel),
            normals,
        };
        let source_prep = PrepareConfig {
            voxel_size: Some(voxel),
            normals: if metric == Metric::Generalized {
                normals
            } else {
                NormalSource::None
            },
        };
        let config = IcpConfig {
            metric,
            ..IcpConfig::default()
        };
        let prepare = || {
            let t = PreparedCloud::new(&target.cloud, &target_prep).unwrap();
            let s = PreparedCloud::new(&source.cloud, &source_prep).unwrap();
            t.build_index();
            (s, t)
        };
        let (s, t) = prepare();
        let r = register(&s, &t, &start, &config).unwrap();
        let e = PoseError::between(&r.pose, &reference, source.cloud.positions());
        eprintln!(
            "bunny {name}: {} + {} points, {} iterations, error {:.3} deg / {:.3} mm (rms {:.3} mm), fitness {:.3}",
            s.len(),
            t.len(),
            r.iterations,
            e.rotation_deg,
            e.translation_mm,
            e.rms_displacement_mm,
            r.fitness
        );
        g.bench_function(format!("icp/{name}"), |b| {
            b.iter(|| register(&s, &t, &start, &config).unwrap())
        });
        g.bench_function(format!("prepare/{name}"), |b| b.iter(prepare));
        g.bench_function(format!("total/{name}"), |b| {
            b.iter(|| {
                let (s, t) = prepare();
                register(&s, &t, &start, &config).unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
