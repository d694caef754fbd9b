//! Local surface frames of a merged scan: the PCA plane of each point's `k` nearest neighbours
//! (sl-cloud's [`fit_local_plane`], on its [`KdIndex`]) and, for overlap averaging, the
//! projection of each point onto a local quadratic surface. Plain normals of a prepared cloud
//! come from `sl_cloud::estimate_normals_with_index` directly.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::{KdIndex, Neighbour, fit_local_plane};

/// Rayon chunk size: a k-nearest query plus a 3x3 (or 6x6) fit is a few microseconds, so
/// chunks of about a thousand points amortise the task overhead.
const MIN_CHUNK: usize = 1024;

/// For every point, the unit PCA normal of its `k` nearest neighbours (unoriented, zero where
/// undefined) and their mean (the point itself where undefined).
pub(crate) fn local_planes(
    points: &[Point3<f64>],
    tree: &KdIndex,
    k: usize,
) -> Vec<(Vector3<f64>, Point3<f64>)> {
    points
        .par_iter()
        .with_min_len(MIN_CHUNK)
        .map_init(
            || Vec::with_capacity(k),
            |buf, p| {
                tree.knn_into(p, k, buf);
                pca(points, buf, p)
            },
        )
        .collect()
}

/// For every point: the unit PCA normal of its `k` nearest neighbours (unoriented, zero where
/// undefined) and the point moved along that normal onto the least-squares quadratic surface
/// `w = a + b u + c v + d u² + e uv + f v²` of the neighbourhood in the frame (tangent u, v;
/// normal w) at the point (moving least squares of degree 2, which unlike a plane fit does
/// not flatten curved surfaces). Where the fit is singular the point is projected on the PCA
/// plane instead.
pub(crate) fn quadric_projection(
    points: &[Point3<f64>],
    tree: &KdIndex,
    k: usize,
) -> Vec<(Vector3<f64>, Point3<f64>)> {
    points
        .par_iter()
        .with_min_len(MIN_CHUNK / 2)
        .map_init(
            || Vec::with_capacity(k),
            |buf, p| {
                tree.knn_into(p, k, buf);
                let (n, mean) = pca(points, buf, p);
                if n.norm_squared() == 0.0 {
                    return (n, *p);
                }
                let planar = p - n * n.dot(&(p - mean));
                let e1 = n
                    .cross(&Vector3::x())
                    .try_normalize(1e-6)
                    .unwrap_or_else(|| n.cross(&Vector3::y()).normalize());
                let e2 = n.cross(&e1);
                let mut h = nalgebra::Matrix6::<f64>::zeros();
                let mut g = nalgebra::Vector6::<f64>::zeros();
                for q in buf.iter().filter_map(|nb| points.get(nb.index)) {
                    let d = q - p;
                    let (u, v, w) = (d.dot(&e1), d.dot(&e2), d.dot(&n));
                    let row = nalgebra::Vector6::new(1.0, u, v, u * u, u * v, v * v);
                    h.ger(1.0, &row, &row, 1.0);
                    g += row * w;
                }
                match h.cholesky().map(|c| c.solve(&g)) {
                    Some(x) if x[0].is_finite() && buf.len() >= 6 => (n, p + n * x[0]),
                    _ => (n, planar),
                }
            },
        )
        .collect()
}

/// The PCA normal of the neighbours (zero if undefined) and their mean (`p` if undefined).
fn pca(
    points: &[Point3<f64>],
    neighbours: &[Neighbour],
    p: &Point3<f64>,
) -> (Vector3<f64>, Point3<f64>) {
    fit_local_plane(points, neighbours.iter().map(|n| n.index))
        .map_or((Vector3::zeros(), *p), |plane| {
            (plane.normal, plane.centroid)
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn quadric_projection_lands_on_a_sphere_and_planes_are_tangent() {
        // Points on a sphere of radius 50 pushed 0.05 mm outward alternately: the local
        // quadratic fit of a neighbourhood averages the offsets out (half the points at +0.05,
        // half at 0), so the projected points sit about 0.025 mm outside the sphere, far
        // closer than the 0.05 of the pushed ones. Normals are radial to within the cap's
        // angular size (k = 20 neighbours over ~1.5 mm of a 50 mm sphere: < 0.05 rad).
        let c = Point3::new(0.0, 0.0, 300.0);
        let mut pts = Vec::new();
        for i in 0..80 {
            for j in 0..160 {
                let th = 0.3 + 2.5 * i as f64 / 80.0;
                let ph = std::f64::consts::TAU * j as f64 / 160.0;
                let r = 50.0 + if (i + j) % 2 == 0 { 0.05 } else { 0.0 };
                pts.push(c + Vector3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * r);
            }
        }
        let tree = KdIndex::new(&pts).unwrap();
        let frames = quadric_projection(&pts, &tree, 20);
        let planes = local_planes(&pts, &tree, 20);
        for ((p, (n, moved)), (m, _)) in pts.iter().zip(&frames).zip(&planes) {
            let radial = (p - c).normalize();
            assert!(n.dot(&radial).abs() > 0.998, "normal {n} radial {radial}");
            assert_relative_eq!(n.dot(&radial).abs(), m.dot(&radial).abs(), epsilon = 1e-12);
            let r = (moved - c).norm();
            assert!((r - 50.025).abs() < 0.012, "projected radius {r}");
        }
    }
}
