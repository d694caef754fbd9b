//! The sign of normals for descriptors, chosen from the cloud alone so that it moves with the
//! cloud.
//!
//! FPFH depends on the sign of the normals, and PCA gives none. Orienting toward the camera
//! (the origin of a view's frame) is right for a scan in its camera frame, but a cloud moved by
//! a rigid motion (another placement, a file in another frame) would then get other signs and
//! other descriptors. Here the sign is a function of the points only:
//!
//! - each normal first faces away from the centroid (outward on a closed, roughly star-shaped
//!   model, and on the near side of a single view of an object);
//! - if most of those agree with one direction (the cloud's axis of least spread, which for a
//!   single range view is roughly the viewing direction), the cloud is a one-sided view and
//!   every normal is made to face along that direction, which also fixes the concave parts
//!   that face the camera but point toward the centroid.

use nalgebra::{Matrix3, Point3, Vector3};

/// Fraction of centroid-outward normals that must agree with the least-spread axis for the
/// cloud to count as one view seen from one side: a range view of an object gives 0.8 to 0.95
/// (only silhouettes disagree), a closed model about 0.5.
const ONE_SIDED_AGREEMENT: f64 = 0.75;

/// Flips `normals` (one per point, zero vectors left alone) to a sign that depends only on the
/// geometry of `points`, so that it is unchanged by a rigid motion of the cloud (see the module
/// docs for the rule). Returns whether the cloud was taken for a one-sided view.
///
/// ```
/// use nalgebra::{Point3, Vector3};
/// use sl_icp::orient_normals_outward;
/// // A cap of a sphere seen from +z: every normal should face +z-ish, away from the centre.
/// let pts: Vec<Point3<f64>> = (0..400).map(|i| {
///     let (a, b) = ((i % 20) as f64 * 0.05 - 0.5, (i / 20) as f64 * 0.05 - 0.5);
///     Point3::new(a.sin() * b.cos(), b.sin(), a.cos() * b.cos()) * 50.0
/// }).collect();
/// let mut normals: Vec<Vector3<f64>> = pts.iter().map(|p| -p.coords.normalize()).collect();
/// assert!(orient_normals_outward(&pts, &mut normals));
/// assert!(normals.iter().zip(&pts).all(|(n, p)| n.dot(&p.coords) > 0.0));
/// ```
pub fn orient_normals_outward(points: &[Point3<f64>], normals: &mut [Vector3<f64>]) -> bool {
    let n = points.len().min(normals.len());
    if n == 0 {
        return false;
    }
    let centroid = Point3::from(
        points
            .iter()
            .take(n)
            .fold(Vector3::zeros(), |s, p| s + p.coords)
            / n as f64,
    );
    for (p, normal) in points.iter().zip(normals.iter_mut()) {
        if normal.dot(&(p - centroid)) < 0.0 {
            *normal = -*normal;
        }
    }
    let mut cov = Matrix3::zeros();
    for p in points.iter().take(n) {
        let d = p - centroid;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let axis: Vector3<f64> = eig.eigenvectors.column(eig.eigenvalues.imin()).into_owned();
    let (mut along, mut valid) = (0usize, 0usize);
    for normal in normals.iter().take(n) {
        if normal.norm_squared() > 0.0 {
            valid += 1;
            if normal.dot(&axis) > 0.0 {
                along += 1;
            }
        }
    }
    if valid == 0 {
        return false;
    }
    let agreement = along as f64 / valid as f64;
    let direction = if agreement >= ONE_SIDED_AGREEMENT {
        axis
    } else if 1.0 - agreement >= ONE_SIDED_AGREEMENT {
        -axis
    } else {
        return false;
    };
    for normal in normals.iter_mut().take(n) {
        if normal.dot(&direction) < 0.0 {
            *normal = -*normal;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};

    fn sphere(n: usize) -> Vec<Point3<f64>> {
        // A Fibonacci sphere of radius 40 mm: a closed model.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - y * y).sqrt();
                let t = golden * i as f64;
                Point3::new(r * t.cos(), y, r * t.sin()) * 40.0
            })
            .collect()
    }

    #[test]
    fn closed_model_faces_outward_and_follows_a_rigid_motion() {
        let pts = sphere(2000);
        let mut normals: Vec<Vector3<f64>> = pts
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let n = p.coords.normalize();
                if i % 3 == 0 { -n } else { n }
            })
            .collect();
        let one_sided = orient_normals_outward(&pts, &mut normals);
        assert!(!one_sided);
        assert!(
            normals
                .iter()
                .zip(&pts)
                .all(|(n, p)| n.dot(&p.coords) > 0.0)
        );
        // The same cloud moved: the moved normals come out, moved.
        let m = Isometry3::new(
            Vector3::new(100.0, -20.0, 5.0),
            Vector3::new(0.3, 1.2, -0.4),
        );
        let moved: Vec<Point3<f64>> = pts.iter().map(|p| m * p).collect();
        let mut moved_normals: Vec<Vector3<f64>> = normals.iter().map(|n| -(m * n)).collect();
        orient_normals_outward(&moved, &mut moved_normals);
        for (a, b) in normals.iter().zip(&moved_normals) {
            assert!((m * a - b).norm() < 1e-12);
        }
    }
}
