//! Plane-to-image homographies by the normalised direct linear transform (Hartley).

use nalgebra::{Matrix3, Point2, SMatrix};

/// Similarity that moves `pts` to their centroid and scales their mean distance to √2.
fn normaliser(pts: impl Iterator<Item = Point2<f64>> + Clone) -> Option<Matrix3<f64>> {
    let n = pts.clone().count() as f64;
    if n == 0.0 {
        return None;
    }
    let c = pts
        .clone()
        .fold(nalgebra::Vector2::zeros(), |a, p| a + p.coords)
        / n;
    let mean_dist = pts.map(|p| (p.coords - c).norm()).sum::<f64>() / n;
    if !(mean_dist > 0.0 && mean_dist.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean_dist;
    Some(Matrix3::new(
        s,
        0.0,
        -s * c.x,
        0.0,
        s,
        -s * c.y,
        0.0,
        0.0,
        1.0,
    ))
}

/// The homography `H` with `image ~ H · (X, Y, 1)` from ≥ 4 correspondences, by the
/// normalised DLT. `None` when the points are degenerate (fewer than 4, collinear, ...).
pub(crate) fn homography_dlt(plane: &[Point2<f64>], image: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    if plane.len() != image.len() || plane.len() < 4 {
        return None;
    }
    let tp = normaliser(plane.iter().copied())?;
    let ti = normaliser(image.iter().copied())?;
    // Accumulate AᵀA (9×9) directly: two rows per correspondence.
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (p, q) in plane.iter().zip(image) {
        let a = tp * p.to_homogeneous();
        let b = ti * q.to_homogeneous();
        let (x, y) = (a.x / a.z, a.y / a.z);
        let (u, v) = (b.x / b.z, b.y / b.z);
        let r1 = SMatrix::<f64, 9, 1>::from_column_slice(&[
            -x,
            -y,
            -1.0,
            0.0,
            0.0,
            0.0,
            u * x,
            u * y,
            u,
        ]);
        let r2 = SMatrix::<f64, 9, 1>::from_column_slice(&[
            0.0,
            0.0,
            0.0,
            -x,
            -y,
            -1.0,
            v * x,
            v * y,
            v,
        ]);
        ata += r1 * r1.transpose() + r2 * r2.transpose();
    }
    let eig = ata.symmetric_eigen();
    let (k, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let h = eig.eigenvectors.column(k);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let hm = ti.try_inverse()? * hn * tp;
    let scale = hm[(2, 2)];
    if scale.abs() < f64::EPSILON || !hm.iter().all(|v| v.is_finite()) {
        return Some(hm);
    }
    Some(hm / scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn recovers_a_known_homography() {
        let h = Matrix3::new(800.0, 12.0, 320.0, -5.0, 790.0, 240.0, 0.0004, -0.0002, 1.0);
        let plane: Vec<Point2<f64>> = (0..6)
            .flat_map(|j| {
                (0..9).map(move |i| Point2::new(f64::from(i) * 0.05, f64::from(j) * 0.05))
            })
            .collect();
        let image: Vec<Point2<f64>> = plane
            .iter()
            .map(|p| Point2::from_homogeneous(h * p.to_homogeneous()).unwrap())
            .collect();
        let est = homography_dlt(&plane, &image).unwrap();
        // Exact data: only rounding separates the estimate from the truth.
        assert_relative_eq!(est, h, max_relative = 1e-8, epsilon = 1e-9);
    }

    #[test]
    fn collinear_points_are_refused_or_useless() {
        let plane: Vec<Point2<f64>> = (0..5).map(|i| Point2::new(f64::from(i), 0.0)).collect();
        assert!(homography_dlt(&plane[..3], &plane[..3]).is_none());
    }
}
