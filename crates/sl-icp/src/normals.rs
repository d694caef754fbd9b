//! PCA normals from the k nearest neighbours, on the allocation-free k-d tree of `kdtree.rs`
//! (same definition as `sl_cloud::estimate_normals`: smallest eigenvector of the neighbourhood
//! covariance about its mean, oriented by a [`NormalOrientation`]).

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::{NormalConfig, NormalOrientation};

use crate::IcpError;
use crate::kdtree::{KdTree, MAX_K, Neighbours};

/// Eigenvalue gap (relative to the trace) under which the smallest eigenvector is called
/// undefined: the neighbourhood is isotropic or a line, and its normal is noise. The
/// trigonometric eigenvalues lose precision to ~`sqrt(f64::EPSILON)` = 1.5e-8 near a repeated
/// root, so the gap must be well above that.
const MIN_GAP: f64 = 1e-6;

/// Unit normals of `points` (zero where undefined), estimated from `config.k` neighbours
/// found in `tree`, which indexes `points`.
pub(crate) fn estimate(
    points: &[Point3<f64>],
    tree: &KdTree,
    config: &NormalConfig,
) -> Result<Vec<Vector3<f64>>, IcpError> {
    if config.k < 3 || config.k > MAX_K {
        return Err(IcpError::invalid(
            "normals.k",
            config.k,
            "must be in 3..=64 (a plane needs 3 neighbours)",
        ));
    }
    let k = config.k;
    let orientation = config.orientation;
    Ok(points
        .par_iter()
        .with_min_len(1024)
        .map_init(
            || Neighbours::new(k),
            |buf, p| {
                tree.knn_into(p, buf);
                let (n, _) = pca(points, buf.as_slice());
                orient(n, p, orientation)
            },
        )
        .collect())
}

fn orient(n: Vector3<f64>, p: &Point3<f64>, orientation: NormalOrientation) -> Vector3<f64> {
    let flip = match orientation {
        NormalOrientation::Unoriented => false,
        NormalOrientation::TowardViewpoint(v) => n.dot(&(v - p)) < 0.0,
        NormalOrientation::TowardDirection(d) => n.dot(&d) < 0.0,
    };
    if flip { -n } else { n }
}

/// For every point, the unit PCA normal of its `k` nearest neighbours (unoriented, zero where
/// undefined) and their mean.
pub(crate) fn local_planes(
    points: &[Point3<f64>],
    tree: &KdTree,
    k: usize,
) -> Vec<(Vector3<f64>, Point3<f64>)> {
    points
        .par_iter()
        .with_min_len(1024)
        .map_init(
            || Neighbours::new(k),
            |buf, p| {
                tree.knn_into(p, buf);
                pca(points, buf.as_slice())
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
    tree: &KdTree,
    k: usize,
) -> Vec<(Vector3<f64>, Point3<f64>)> {
    points
        .par_iter()
        .with_min_len(512)
        .map_init(
            || Neighbours::new(k),
            |buf, p| {
                tree.knn_into(p, buf);
                let (n, mean) = pca(points, buf.as_slice());
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
                for q in buf
                    .as_slice()
                    .iter()
                    .filter_map(|&(_, i)| points.get(i as usize))
                {
                    let d = q - p;
                    let (u, v, w) = (d.dot(&e1), d.dot(&e2), d.dot(&n));
                    let row = nalgebra::Vector6::new(1.0, u, v, u * u, u * v, v * v);
                    h.ger(1.0, &row, &row, 1.0);
                    g += row * w;
                }
                match h.cholesky().map(|c| c.solve(&g)) {
                    Some(x) if x[0].is_finite() && buf.as_slice().len() >= 6 => (n, p + n * x[0]),
                    _ => (n, planar),
                }
            },
        )
        .collect()
}

/// The smallest-eigenvalue eigenvector of the covariance of the neighbours (or zero) and
/// their mean (or the origin when there are fewer than 3).
fn pca(points: &[Point3<f64>], neighbours: &[(f64, u32)]) -> (Vector3<f64>, Point3<f64>) {
    if neighbours.len() < 3 {
        return (Vector3::zeros(), Point3::origin());
    }
    let mut mean = Vector3::zeros();
    let mut count = 0.0;
    for q in neighbours
        .iter()
        .filter_map(|&(_, i)| points.get(i as usize))
    {
        mean += q.coords;
        count += 1.0;
    }
    mean /= count;
    let mut c = Matrix3::zeros();
    for q in neighbours
        .iter()
        .filter_map(|&(_, i)| points.get(i as usize))
    {
        let d = q.coords - mean;
        c += d * d.transpose();
    }
    let n = smallest_eigenvector(&c).unwrap_or_else(Vector3::zeros);
    (n, Point3::from(mean))
}

/// Smallest eigenvector of a symmetric positive semi-definite 3x3 matrix in closed form:
/// eigenvalues by the trigonometric solution of the characteristic cubic (Smith 1961), the
/// eigenvector as the largest cross product of two rows of `C - λ I`.
pub(crate) fn smallest_eigenvector(c: &Matrix3<f64>) -> Option<Vector3<f64>> {
    let trace = c.trace();
    if trace.is_nan() || trace <= 0.0 || !trace.is_finite() {
        return None;
    }
    // Scale to unit trace for a scale-free tolerance.
    let a = c / trace;
    let q = 1.0 / 3.0; // trace(a) / 3
    let b = a - Matrix3::from_diagonal_element(q);
    let p2 = (b.norm_squared() / 6.0).max(0.0);
    let p = p2.sqrt();
    if p < MIN_GAP {
        return None; // isotropic
    }
    let r = (b / p).determinant() / 2.0;
    let phi = r.clamp(-1.0, 1.0).acos() / 3.0;
    // Eigenvalues q + 2p cos(phi + 2πk/3); the smallest is k = 1.
    let lambda_min = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let lambda_max = q + 2.0 * p * phi.cos();
    let lambda_mid = 3.0 * q - lambda_min - lambda_max;
    if lambda_mid - lambda_min < MIN_GAP {
        return None; // a line: the normal is any direction across it
    }
    let m = a - Matrix3::from_diagonal_element(lambda_min);
    let (r0, r1, r2) = (
        m.row(0).transpose(),
        m.row(1).transpose(),
        m.row(2).transpose(),
    );
    let candidates = [r0.cross(&r1), r0.cross(&r2), r1.cross(&r2)];
    let best = candidates
        .iter()
        .max_by(|x, y| x.norm_squared().total_cmp(&y.norm_squared()))?;
    let n2 = best.norm_squared();
    (n2 > 0.0 && n2.is_finite()).then(|| best / n2.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Rotation3, SymmetricEigen};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn closed_form_agrees_with_iterative_eigen_solver() {
        let mut rng = Pcg64::seed_from_u64(1);
        for _ in 0..500 {
            let r = Rotation3::new(Vector3::new(rng.random(), rng.random(), rng.random()) * 3.0);
            let l = Vector3::new(
                rng.random::<f64>() * 0.1,
                0.2 + rng.random::<f64>(),
                1.2 + rng.random::<f64>(),
            );
            let c = r.matrix() * Matrix3::from_diagonal(&l) * r.matrix().transpose();
            let got = smallest_eigenvector(&c).unwrap();
            let eig = SymmetricEigen::new(c);
            let i = eig.eigenvalues.imin();
            let want = eig.eigenvectors.column(i).into_owned();
            assert_relative_eq!(got.dot(&want).abs(), 1.0, epsilon = 1e-9);
        }
        assert!(smallest_eigenvector(&Matrix3::identity()).is_none());
        assert!(smallest_eigenvector(&Matrix3::zeros()).is_none());
        assert!(
            smallest_eigenvector(&Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0))).is_none()
        );
    }

    #[test]
    fn plane_normals_are_exact() {
        // Random points on the plane n·x = 40 with n = (1, 2, 2)/3: every PCA normal is n
        // (to rounding), oriented toward +z by the direction rule.
        let n = Vector3::new(1.0, 2.0, 2.0) / 3.0;
        let (u, v) = (
            Vector3::new(2.0, -1.0, 0.0).normalize(),
            n.cross(&Vector3::new(2.0, -1.0, 0.0).normalize()),
        );
        let mut rng = Pcg64::seed_from_u64(3);
        let pts: Vec<Point3<f64>> = (0..2000)
            .map(|_| {
                Point3::from(
                    n * 40.0
                        + u * rng.random_range(-20.0..20.0)
                        + v * rng.random_range(-20.0..20.0),
                )
            })
            .collect();
        let tree = KdTree::new(&pts);
        let config = NormalConfig {
            k: 10,
            orientation: NormalOrientation::TowardDirection(-Vector3::z()),
        };
        for m in estimate(&pts, &tree, &config).unwrap() {
            assert_relative_eq!(m, -n, epsilon = 1e-9);
        }
    }

    #[test]
    fn sphere_normals_point_to_the_centre_viewpoint() {
        // Points on a sphere of radius 50 around c; oriented toward c they are -radial.
        let c = Point3::new(0.0, 0.0, 300.0);
        let mut rng = Pcg64::seed_from_u64(2);
        let pts: Vec<Point3<f64>> = (0..5000)
            .map(|_| {
                let v = Vector3::new(
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                );
                c + v.normalize() * 50.0
            })
            .collect();
        let config = NormalConfig {
            k: 12,
            orientation: NormalOrientation::TowardViewpoint(c),
        };
        let tree = KdTree::new(&pts);
        let normals = estimate(&pts, &tree, &config).unwrap();
        for (idx, (p, n)) in pts.iter().zip(&normals).enumerate() {
            // Independent reference: brute-force 12 nearest, nalgebra's iterative eigen-solver.
            if idx % 10 == 0 {
                let mut d: Vec<(f64, usize)> = pts
                    .iter()
                    .enumerate()
                    .map(|(i, q)| ((q - p).norm_squared(), i))
                    .collect();
                d.sort_by(|a, b| a.0.total_cmp(&b.0));
                let nb: Vec<Vector3<f64>> = d[..12].iter().map(|&(_, i)| pts[i].coords).collect();
                let mean = nb.iter().sum::<Vector3<f64>>() / 12.0;
                let cov = nb
                    .iter()
                    .map(|q| (q - mean) * (q - mean).transpose())
                    .sum::<Matrix3<f64>>();
                let eig = SymmetricEigen::new(cov);
                let want = eig.eigenvectors.column(eig.eigenvalues.imin()).into_owned();
                assert_relative_eq!(n.dot(&want).abs(), 1.0, epsilon = 1e-9);
            }
            // Orientation: toward the centre. Any PCA normal of a cap of a sphere is within a
            // few degrees of radial, so the sign test has a wide margin.
            let radial = (c - p).normalize();
            assert!(n.dot(&radial) > 0.99, "{n} vs {radial}");
        }
        assert!(estimate(&pts, &tree, &NormalConfig { k: 2, ..config }).is_err());
        assert!(estimate(&pts, &tree, &NormalConfig { k: 65, ..config }).is_err());
    }
}
