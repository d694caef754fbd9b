//! Screened Poisson reconstruction of a sampled sphere.
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Point3, Vector3};
use sl_cloud::PointCloud;
use sl_mesh::{PoissonConfig, poisson_reconstruct};

fn sphere(n: usize) -> PointCloud {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let (pts, nrm): (Vec<_>, Vec<_>) = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            let nv = Vector3::new(r * t.cos(), r * t.sin(), z);
            (Point3::from(nv * 20.0), nv)
        })
        .unzip();
    PointCloud::from_positions(pts)
        .with_normals(nrm)
        .unwrap_or_default()
}

fn bench(c: &mut Criterion) {
    let cloud = sphere(100_000);
    let mut g = c.benchmark_group("poisson");
    g.sample_size(10);
    for depth in [7, 8] {
        let cfg = PoissonConfig {
            depth,
            ..PoissonConfig::default()
        };
        g.bench_function(format!("sphere_100k_depth{depth}"), |b| {
            b.iter(|| poisson_reconstruct(&cloud, &cfg))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
