//! Shapes with known geometry for the tests.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use sl_cloud::{PointCloud, TriangleMesh};

use crate::{PoissonConfig, poisson_reconstruct};

/// `n` points on a sphere (Fibonacci spiral, evenly spread) with outward normals.
pub(crate) fn sphere_cloud(n: usize, radius: f64, centre: Point3<f64>) -> PointCloud {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let (pts, nrm): (Vec<_>, Vec<_>) = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            let nv = Vector3::new(r * t.cos(), r * t.sin(), z);
            (centre + nv * radius, nv)
        })
        .unzip();
    PointCloud::from_positions(pts).with_normals(nrm).unwrap()
}

/// The points of `sphere_cloud(n, radius, centre)` for which `keep(position, normal)` holds:
/// a sphere with a part no view saw.
pub(crate) fn partial_sphere_cloud(
    n: usize,
    radius: f64,
    centre: Point3<f64>,
    keep: impl Fn(&Point3<f64>, &Vector3<f64>) -> bool,
) -> PointCloud {
    let full = sphere_cloud(n, radius, centre);
    let (pts, nrm): (Vec<_>, Vec<_>) = full
        .positions()
        .iter()
        .zip(full.normals().unwrap())
        .filter(|(p, n)| keep(p, n))
        .map(|(p, n)| (*p, *n))
        .unzip();
    PointCloud::from_positions(pts).with_normals(nrm).unwrap()
}

/// The Poisson surface (depth 6) of `partial_sphere_cloud(20_000, radius, origin, keep)`:
/// a sphere of radius `radius` at the origin with a part no view saw, closed by invention.
pub(crate) fn partial_sphere_surface(
    radius: f64,
    keep: impl Fn(&Point3<f64>, &Vector3<f64>) -> bool,
) -> crate::PoissonSurface {
    let cloud = partial_sphere_cloud(20_000, radius, Point3::origin(), keep);
    let cfg = PoissonConfig {
        depth: 6,
        ..PoissonConfig::default()
    };
    poisson_reconstruct(&cloud, &cfg).unwrap()
}

/// The Poisson surface (depth 6) of a ball of radius `radius` at the origin with a flat
/// bottom at `z = cut` (a pebble: a crease all round where the bottom meets the side),
/// sampled about as densely as `partial_sphere_surface`'s sphere (sphere part and disc, with
/// outward normals), without the samples for which `keep(position, normal)` fails.
pub(crate) fn cut_ball_surface(
    radius: f64,
    cut: f64,
    keep: impl Fn(&Point3<f64>, &Vector3<f64>) -> bool,
) -> crate::PoissonSurface {
    let n = 20_000;
    let sphere = sphere_cloud(n, radius, Point3::origin());
    let mut pts = Vec::new();
    let mut nrm = Vec::new();
    for (p, v) in sphere.positions().iter().zip(sphere.normals().unwrap()) {
        if p.z >= cut {
            pts.push(*p);
            nrm.push(*v);
        }
    }
    // The disc, a sunflower of the sphere's density.
    let rho = (radius * radius - cut * cut).sqrt();
    let disc = (n as f64 * rho * rho / (4.0 * radius * radius)) as usize;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..disc {
        let r = rho * ((i as f64 + 0.5) / disc as f64).sqrt();
        let t = golden * i as f64;
        pts.push(Point3::new(r * t.cos(), r * t.sin(), cut));
        nrm.push(-Vector3::z());
    }
    let (pts, nrm): (Vec<_>, Vec<_>) = pts.into_iter().zip(nrm).filter(|(p, n)| keep(p, n)).unzip();
    let cloud = PointCloud::from_positions(pts).with_normals(nrm).unwrap();
    let cfg = PoissonConfig {
        depth: 6,
        ..PoissonConfig::default()
    };
    poisson_reconstruct(&cloud, &cfg).unwrap()
}

/// Signed distance from `p` to the surface of `cut_ball_surface`'s ball (negative inside).
pub(crate) fn cut_ball_distance(p: &Point3<f64>, radius: f64, cut: f64) -> f64 {
    let (to_sphere, to_plane) = (p.coords.norm() - radius, cut - p.z);
    if to_sphere <= 0.0 && to_plane <= 0.0 {
        return to_sphere.max(to_plane);
    }
    let rho = (radius * radius - cut * cut).sqrt();
    let planar = (p.x * p.x + p.y * p.y).sqrt();
    // The nearest of the sphere part (where the radial projection is above the cut), the
    // disc (where the point is above it) and the crease's circle.
    let mut best = ((planar - rho).powi(2) + (p.z - cut).powi(2)).sqrt();
    if p.z / p.coords.norm().max(f64::MIN_POSITIVE) * radius >= cut {
        best = best.min(to_sphere.abs());
    }
    if planar <= rho {
        best = best.min(to_plane.abs());
    }
    best
}

/// A closed mesh of a sphere of radius `radius` at the origin (Poisson at `depth`).
pub(crate) fn sphere_mesh(radius: f64, depth: u32) -> TriangleMesh {
    let cloud = sphere_cloud(20_000, radius, Point3::origin());
    let cfg = PoissonConfig {
        depth,
        ..PoissonConfig::default()
    };
    poisson_reconstruct(&cloud, &cfg).unwrap().mesh
}

/// The closed surface of the cube `[-s, s]³`, each face a grid of `n × n` squares split into
/// two triangles, wound outwards.
pub(crate) fn cube_mesh(s: f64, n: usize) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let n_i = n as i64;
    let mut vertex = |q: [i64; 3], mesh: &mut TriangleMesh| -> u32 {
        *index.entry(q).or_insert_with(|| {
            let p = q.map(|c| (2.0 * c as f64 / n as f64 - 1.0) * s);
            mesh.vertices.push(Point3::from(p));
            (mesh.vertices.len() - 1) as u32
        })
    };
    for axis in 0..3 {
        for side in [0, n_i] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..n_i {
                for j in 0..n_i {
                    let at = |a: i64, b: i64| {
                        let mut q = [0i64; 3];
                        q[axis] = side;
                        q[u] = a;
                        q[v] = b;
                        q
                    };
                    let c = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
                        .map(|q| vertex(q, &mut mesh));
                    // (u, v, axis) is right-handed: u × v points along +axis.
                    if side == n_i {
                        mesh.triangles.push([c[0], c[1], c[2]]);
                        mesh.triangles.push([c[0], c[2], c[3]]);
                    } else {
                        mesh.triangles.push([c[0], c[2], c[1]]);
                        mesh.triangles.push([c[0], c[3], c[2]]);
                    }
                }
            }
        }
    }
    mesh
}

/// Distance from `p` to the surface of the cube `[-s, s]³` (outside or inside).
pub(crate) fn cube_distance(p: &Point3<f64>, s: f64) -> f64 {
    let q = p.coords.map(|c| c.abs() - s);
    let outside = q.map(|c| c.max(0.0)).norm();
    let inside = q.max().min(0.0);
    outside + inside.abs()
}

/// Moves each vertex along a seeded random direction by a normal-distributed amount of
/// standard deviation `sigma`.
pub(crate) fn add_noise(mesh: &mut TriangleMesh, sigma: f64, seed: u64) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    for p in &mut mesh.vertices {
        // Sum of uniforms: close enough to normal for a test, no extra dependency.
        let mut g = || (0..12).map(|_| rng.random::<f64>()).sum::<f64>() - 6.0;
        let d = Vector3::new(g(), g(), g());
        *p += d * (sigma / 3f64.sqrt());
    }
}

#[test]
fn cube_mesh_is_closed() {
    let m = cube_mesh(1.0, 4);
    assert!(crate::check_topology(&m).is_watertight_manifold());
    approx::assert_relative_eq!(crate::signed_volume(&m), 8.0, epsilon = 1e-12);
    approx::assert_relative_eq!(crate::surface_area(&m), 24.0, epsilon = 1e-12);
}
