//! Screened Poisson reconstruction of a sampled sphere, and the simplification of its
//! extraction.
use criterion::BatchSize;
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Point3, Vector3};
use sl_cloud::PointCloud;
use sl_mesh::{PoissonConfig, SimplifyConfig, poisson_reconstruct, simplify};

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
    // The extraction at depth 8 (1.5 million triangles on this sphere of radius 20, cells of
    // 0.17), simplified with the defaults of `slscan mesh`.
    if let Ok(surface) = poisson_reconstruct(
        &cloud,
        &PoissonConfig {
            depth: 8,
            ..PoissonConfig::default()
        },
    ) {
        g.bench_function("simplify_sphere_depth8", |b| {
            b.iter_batched(
                || surface.mesh.clone(),
                |mut mesh| simplify(&mut mesh, &surface.densities, &SimplifyConfig::default()),
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
