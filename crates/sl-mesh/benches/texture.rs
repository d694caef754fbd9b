//! Baking a texture atlas (and writing the textured OBJ) of a 100k-triangle mesh: a height
//! field of 224 × 224 squares, coloured by a function of position as a camera lookup would.
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Point3;
use sl_mesh::{TextureConfig, TriangleMesh, bake_texture};

/// A wavy 100 × 100 mm height field of `n × n` squares, two triangles each.
fn height_field(n: usize) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (100.0 * i as f64 / n as f64, 100.0 * j as f64 / n as f64);
            let z = 5.0 * (x * 0.1).sin() * (y * 0.13).cos();
            mesh.vertices.push(Point3::new(x, y, z));
        }
    }
    let at = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    for j in 0..n {
        for i in 0..n {
            mesh.triangles
                .push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            mesh.triangles
                .push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    mesh
}

fn bench(c: &mut Criterion) {
    let mesh = height_field(224);
    let mut g = c.benchmark_group("texture");
    g.sample_size(10);
    let sample = |p: &Point3<f64>, _: &nalgebra::Vector3<f64>| {
        Some([
            (p.x * 2.5) as u8,
            (p.y * 2.5) as u8,
            (128.0 + 20.0 * p.z) as u8,
        ])
    };
    g.bench_function("bake_100k_triangles_8_texels", |b| {
        b.iter(|| bake_texture(&mesh, &TextureConfig::default(), sample))
    });
    #[cfg(feature = "image-files")]
    if let Ok(atlas) = bake_texture(&mesh, &TextureConfig::default(), sample)
        && let Ok(dir) = tempfile::tempdir()
    {
        let path = dir.path().join("field.obj");
        g.bench_function("write_obj_textured_100k_triangles", |b| {
            b.iter(|| sl_mesh::write_obj_textured(&path, &mesh, &atlas))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
