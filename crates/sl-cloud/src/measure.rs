//! Area-weighted samples of a triangle mesh's surface.

use nalgebra::Point3;

use crate::TriangleMesh;

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
/// let pts = sl_cloud::sample_surface(&square, 0.01, false);
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
