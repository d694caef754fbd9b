//! Geometric measures of a mesh: area, enclosed volume, vertex normals, area-weighted samples.

use nalgebra::{Point3, Vector3};
use sl_cloud::TriangleMesh;

/// Total surface area, in the square of the mesh's units.
pub fn surface_area(mesh: &TriangleMesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| triangle_normal(&mesh.vertices, t).norm() * 0.5)
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
pub(crate) fn triangle_normal(pos: &[Point3<f64>], t: &[u32; 3]) -> Vector3<f64> {
    let [a, b, c] = t.map(|i| pos[i as usize]);
    (b - a).cross(&(c - a))
}

/// Unit normal per vertex: the area-weighted mean of its triangles' normals (zero for a vertex
/// of no triangle).
pub fn vertex_normals(mesh: &TriangleMesh) -> Vec<Vector3<f64>> {
    let mut n = vec![Vector3::zeros(); mesh.vertices.len()];
    for t in &mesh.triangles {
        let f = triangle_normal(&mesh.vertices, t);
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

/// Points spread over the surface in proportion to area, one per `area_per_sample` (in the
/// square of the mesh's units): a triangle gets as many as its area holds, the fractions carried
/// from triangle to triangle so that the total is the whole area over `area_per_sample` (give or
/// take one); with `at_least_one`, every triangle gets at least one. Deterministic: a
/// triangle's samples follow a low-discrepancy sequence mapped uniformly onto it. A
/// non-positive or non-finite `area_per_sample` gives no samples (or one per triangle with
/// `at_least_one`).
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// let square = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(2.0, 0.0, 0.0), Point3::new(2.0, 2.0, 0.0), Point3::new(0.0, 2.0, 0.0)],
///     triangles: vec![[0, 1, 2], [0, 2, 3]],
/// };
/// let pts = sl_mesh::sample_surface(&square, 0.01, false);
/// assert_eq!(pts.len(), 400);
/// assert!(pts.iter().all(|p| p.x >= 0.0 && p.x <= 2.0 && p.y >= 0.0 && p.y <= 2.0));
/// ```
pub fn sample_surface(
    mesh: &TriangleMesh,
    area_per_sample: f64,
    at_least_one: bool,
) -> Vec<Point3<f64>> {
    let valid = area_per_sample.is_finite() && area_per_sample > 0.0;
    let mut out = Vec::new();
    let mut carry = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        let area = (b - a).cross(&(c - a)).norm() * 0.5;
        let mut k = 0;
        if valid {
            carry += area / area_per_sample;
            k = carry.floor().max(0.0) as usize;
            carry -= k as f64;
        }
        if at_least_one && k == 0 {
            k = 1;
        }
        for j in 0..k {
            // Square-root mapping of a point of the unit square: uniform over the triangle.
            let r1 = ((j as f64 + 0.5) / k as f64).sqrt();
            let r2 = (j as f64 * GOLDEN_FRACTION + 0.5).fract();
            out.push(a + (b - a) * (r1 * (1.0 - r2)) + (c - a) * (r1 * r2));
        }
    }
    out
}

/// The fractional part of the golden ratio: the second coordinate of the low-discrepancy
/// sequence (consecutive samples are as far apart as a one-dimensional sequence allows).
const GOLDEN_FRACTION: f64 = 0.618_033_988_749_895;
