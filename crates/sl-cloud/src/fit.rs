//! Least-squares fits of planes and spheres, for accuracy measurements (flatness, sphere
//! radius and spacing as in VDI/VDE 2634).

// `!(x > 0.0)` is used on purpose: it is true for NaN, which must be rejected as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use nalgebra::{Matrix3, Matrix4, Point3, SymmetricEigen, Vector3, Vector4};

use crate::CloudError;

/// Gauss–Newton iterations of the geometric sphere fit: from the algebraic start the radius
/// converges in 2–4 iterations; 50 is headroom for noisy, partial caps.
const MAX_SPHERE_ITERATIONS: usize = 50;

/// Relative step of the centre and radius (to the radius) at which the sphere fit stops.
const SPHERE_STEP_TOLERANCE: f64 = 1e-12;

/// A least-squares plane (total least squares: orthogonal distances).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneFit {
    /// A point of the plane: the centroid of the points.
    pub point: Point3<f64>,
    /// Unit normal (sign: facing the origin, i.e. the camera, for camera-frame points).
    pub normal: Vector3<f64>,
    /// RMS of the signed point-to-plane distances (the flatness RMS, mm).
    pub rms: f64,
    /// Largest absolute distance to the plane.
    pub max_abs: f64,
    /// Number of finite points used.
    pub count: usize,
}

impl PlaneFit {
    /// Signed distance of `p` from the plane (positive on the side the normal points to).
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        (p - self.point).dot(&self.normal)
    }
}

/// A least-squares sphere (geometric: distances to the surface).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereFit {
    /// Centre.
    pub centre: Point3<f64>,
    /// Radius.
    pub radius: f64,
    /// RMS of the radial residuals `|p - centre| - radius`.
    pub rms: f64,
    /// Number of finite points used.
    pub count: usize,
    /// Gauss–Newton iterations used.
    pub iterations: usize,
}

fn finite(points: &[Point3<f64>]) -> impl Iterator<Item = &Point3<f64>> {
    points
        .iter()
        .filter(|p| p.coords.iter().all(|v| v.is_finite()))
}

/// The number of finite points and their mean.
fn finite_mean(points: &[Point3<f64>]) -> (usize, Vector3<f64>) {
    let (count, sum) = finite(points).fold((0usize, Vector3::zeros()), |(n, a), p| {
        (n + 1, a + p.coords)
    });
    (count, sum / count.max(1) as f64)
}

/// Fits a plane to the finite points (non-finite ones are skipped), minimising the sum of
/// squared orthogonal distances: the normal is the eigenvector of the smallest eigenvalue of
/// the covariance.
///
/// # Errors
/// [`CloudError::Fit`] for fewer than 3 finite points or collinear points.
pub fn fit_plane(points: &[Point3<f64>]) -> Result<PlaneFit, CloudError> {
    let (count, centroid) = finite_mean(points);
    if count < 3 {
        return Err(CloudError::Fit {
            what: "plane",
            message: format!("{count} finite points, need at least 3"),
        });
    }
    let cov = finite(points).fold(Matrix3::zeros(), |a, p| {
        let d = p.coords - centroid;
        a + d * d.transpose()
    });
    let eig = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let [smallest, middle, _] = order;
    if !(eig.eigenvalues[middle] > 1e-12 * eig.eigenvalues.amax().max(f64::MIN_POSITIVE)) {
        return Err(CloudError::Fit {
            what: "plane",
            message: "the points are collinear".to_owned(),
        });
    }
    let mut normal: Vector3<f64> = eig.eigenvectors.column(smallest).into_owned().normalize();
    if normal.dot(&centroid) > 0.0 {
        normal = -normal;
    }
    let point = Point3::from(centroid);
    let (mut sum, mut max_abs) = (0.0f64, 0.0f64);
    for p in finite(points) {
        let d = (p - point).dot(&normal);
        sum += d * d;
        max_abs = max_abs.max(d.abs());
    }
    Ok(PlaneFit {
        point,
        normal,
        rms: (sum / count as f64).sqrt(),
        max_abs,
        count,
    })
}

/// Fits a sphere to the finite points: the algebraic fit (`|p|² + D·p + e = 0`, linear least
/// squares) as the start, then Gauss–Newton on the geometric residuals `|p - c| - r`.
///
/// # Errors
/// [`CloudError::Fit`] for fewer than 4 finite points or coplanar points.
pub fn fit_sphere(points: &[Point3<f64>]) -> Result<SphereFit, CloudError> {
    let (count, mean) = finite_mean(points);
    if count < 4 {
        return Err(CloudError::Fit {
            what: "sphere",
            message: format!("{count} finite points, need at least 4"),
        });
    }
    // Centre the data for conditioning.
    let mut m = Matrix4::zeros();
    let mut b = Vector4::zeros();
    for p in finite(points) {
        let d = p.coords - mean;
        let row = Vector4::new(d.x, d.y, d.z, 1.0);
        m += row * row.transpose();
        b += row * -d.norm_squared();
    }
    let degenerate = || CloudError::Fit {
        what: "sphere",
        message: "the points are coplanar or degenerate".to_owned(),
    };
    let s = m.try_inverse().ok_or_else(degenerate)? * b;
    let mut centre = Vector3::new(-s.x / 2.0, -s.y / 2.0, -s.z / 2.0);
    let r2 = centre.norm_squared() - s.w;
    if !(r2 > 0.0) {
        return Err(degenerate());
    }
    let mut radius = r2.sqrt();
    let mut iterations = 0;
    for _ in 0..MAX_SPHERE_ITERATIONS {
        iterations += 1;
        let mut h = Matrix4::zeros();
        let mut g = Vector4::zeros();
        for p in finite(points) {
            let d = p.coords - mean - centre;
            let len = d.norm();
            if len == 0.0 {
                continue;
            }
            let e = len - radius;
            let u = d / len;
            let j = Vector4::new(-u.x, -u.y, -u.z, -1.0);
            h += j * j.transpose();
            g += j * e;
        }
        let step = h.try_inverse().ok_or_else(degenerate)? * g;
        centre -= step.xyz();
        radius -= step.w;
        if step.norm() < SPHERE_STEP_TOLERANCE * radius.abs() {
            break;
        }
    }
    let c = centre + mean;
    let sum: f64 = finite(points)
        .map(|p| ((p.coords - c).norm() - radius).powi(2))
        .sum();
    Ok(SphereFit {
        centre: Point3::from(c),
        radius,
        rms: (sum / count as f64).sqrt(),
        count,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// Points on a known plane with seeded Gaussian noise σ: the fitted plane is the true one
    /// and the RMS is σ within sampling error (2000 points: relative error ~1/sqrt(2n) ≈ 1.6 %,
    /// 10 % allowed).
    #[test]
    fn plane_recovers_truth() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let normal = Vector3::new(0.2, -0.3, -1.0).normalize();
        let origin = Point3::new(10.0, -5.0, 450.0);
        let u = normal.cross(&Vector3::x()).normalize();
        let v = normal.cross(&u);
        let noise = Normal::new(0.0, 0.01).unwrap();
        let pts: Vec<_> = (0..2000)
            .map(|_| {
                origin
                    + u * rng.random_range(-50.0..50.0)
                    + v * rng.random_range(-50.0..50.0)
                    + normal * noise.sample(&mut rng)
            })
            .chain(std::iter::once(Point3::new(f64::NAN, 0.0, 0.0)))
            .collect();
        let fit = fit_plane(&pts).unwrap();
        assert_eq!(fit.count, 2000);
        assert_abs_diff_eq!(fit.normal, normal, epsilon = 1e-3);
        assert_abs_diff_eq!(fit.distance(&origin), 0.0, epsilon = 1e-3);
        assert!((fit.rms - 0.01).abs() < 0.001, "rms {}", fit.rms);
        assert!(fit_plane(&pts[..2]).is_err());
    }

    /// A cap of a sphere (a camera sees under half of it) with noise: radius and centre within
    /// a few noise σ / sqrt(n); exact data gives the exact sphere.
    #[test]
    fn sphere_recovers_truth() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(2);
        let centre = Point3::new(5.0, 20.0, 480.0);
        let radius = 50.0;
        let cap = |rng: &mut rand_pcg::Pcg64| {
            let theta: f64 = rng.random_range(0.0..1.2); // from the direction of the camera
            let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            centre
                + Vector3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    -theta.cos(),
                ) * radius
        };
        let exact: Vec<_> = (0..500).map(|_| cap(&mut rng)).collect();
        let fit = fit_sphere(&exact).unwrap();
        assert_abs_diff_eq!(fit.radius, radius, epsilon = 1e-9);
        assert_abs_diff_eq!(fit.centre, centre, epsilon = 1e-9);
        let noise = Normal::new(0.0, 0.02).unwrap();
        let noisy: Vec<_> = (0..5000)
            .map(|_| {
                let p = cap(&mut rng);
                p + (p - centre).normalize() * noise.sample(&mut rng)
            })
            .collect();
        let fit = fit_sphere(&noisy).unwrap();
        assert!((fit.radius - radius).abs() < 0.005, "radius {}", fit.radius);
        assert!((fit.rms - 0.02).abs() < 0.002, "rms {}", fit.rms);
        assert!(fit_sphere(&exact[..3]).is_err());
    }
}
