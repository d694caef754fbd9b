//! Geometric measures of a mesh: area, enclosed volume, vertex normals, area-weighted samples.

use nalgebra::{Point3, Vector3};
use sl_cloud::TriangleMesh;

/// Total surface area, in the square of the mesh's units.
pub fn surface_area(mesh: &TriangleMesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| triangle_normal(mesh, t).norm() * 0.5)
        .sum()
}

/// Signed volume enclosed (positive when the triangles face outwards), by the divergence
/// theorem; meaningful for a closed mesh.
pub fn signed_volume(mesh: &TriangleMesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize].coords);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

/// Cross product of two edges of a triangle: normal times twice the area.
fn triangle_normal(mesh: &TriangleMesh, t: &[u32; 3]) -> Vector3<f64> {
    let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
    (b - a).cross(&(c - a))
}

/// Unit normal per vertex: the area-weighted mean of its triangles' normals (zero for a vertex
/// of no triangle).
pub fn vertex_normals(mesh: &TriangleMesh) -> Vec<Vector3<f64>> {
    let mut n = vec![Vector3::zeros(); mesh.vertices.len()];
    for t in &mesh.triangles {
        let f = triangle_normal(mesh, t);
        for &i in t {
            n[i as usize] += f;
        }
    }
    for v in &mut n {
        let l = v.norm();
        if l > 0.0 {
            *v /= l;
        }
    }
    n
}

/// Points spread over the surface in proportion to area: `per_triangle_area`, the area each
/// sample stands for, sets their number (a triangle gets `round(area / per_triangle_area)`, at
/// least its centroid when `at_least_one`). Deterministic: a triangle's samples sit on a regular
/// pattern of barycentric coordinates.
pub fn sample_surface(
    mesh: &TriangleMesh,
    area_per_sample: f64,
    at_least_one: bool,
) -> Vec<Point3<f64>> {
    let mut out = Vec::new();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        let area = (b - a).cross(&(c - a)).norm() * 0.5;
        let k = if area_per_sample > 0.0 {
            (area / area_per_sample).round() as usize
        } else {
            0
        };
        let k = if at_least_one { k.max(1) } else { k };
        // Points of a low-discrepancy sequence mapped into the triangle.
        for j in 0..k {
            let (mut u, mut v) = (
                (j as f64 + 0.5) / k as f64,
                ((j as f64 * 0.618_033_988_749_895) + 0.5).fract(),
            );
            if u + v > 1.0 {
                u = 1.0 - u;
                v = 1.0 - v;
            }
            out.push(a + (b - a) * u + (c - a) * v);
        }
    }
    out
}
