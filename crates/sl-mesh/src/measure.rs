//! Geometric measures of a mesh: area, enclosed volume, vertex normals, area-weighted samples (`sample_surface`, in `sl-cloud`).

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
