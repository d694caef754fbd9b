//! Normal estimation by principal component analysis of the k nearest neighbours.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::cloud::is_finite;
use crate::morton::SortedIndex;
use crate::sym_eigen::smallest_eigen;
use crate::{CloudError, KdIndex, PointCloud};

/// Which way estimated normals should face (PCA alone gives a direction, not a sign).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NormalOrientation {
    /// Leave the sign as the eigen-solver returns it.
    Unoriented,
    /// Face the given point: a viewpoint or camera centre, in the cloud's frame
    /// (`n · (viewpoint - p) >= 0`).
    TowardViewpoint(Point3<f64>),
    /// Face along a direction, e.g. `Vector3::z()` for "toward +z" (`n · direction >= 0`).
    TowardDirection(Vector3<f64>),
}

impl Default for NormalOrientation {
    /// Toward the origin: for a cloud in the camera frame that is the camera centre.
    fn default() -> Self {
        Self::TowardViewpoint(Point3::origin())
    }
}

/// Settings of [`estimate_normals`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalConfig {
    /// Neighbours per point, the point itself included (as Open3D's `KDTreeSearchParamKNN`).
    /// At least 3. Default 16: enough to average out scanner noise on a smooth surface while
    /// staying local on an object scanned at about 0.1 to 0.5 mm spacing.
    pub k: usize,
    /// Which way the normals face. Default: toward the origin.
    pub orientation: NormalOrientation,
}

impl Default for NormalConfig {
    fn default() -> Self {
        Self {
            k: 16,
            orientation: NormalOrientation::default(),
        }
    }
}

/// Result of [`estimate_normals`].
#[derive(Debug, Clone, PartialEq)]
pub struct NormalEstimate {
    /// One unit normal per input point; the zero vector where none could be estimated
    /// (non-finite point, fewer than 3 neighbours, or all neighbours at one place).
    pub normals: Vec<Vector3<f64>>,
    /// Surface variation `λ0 / (λ0 + λ1 + λ2)` of the neighbourhood covariance (eigenvalues
    /// ascending): 0 on a plane, up to 1/3 for isotropic noise; 0 where the normal is zero.
    pub surface_variation: Vec<f64>,
    /// How many normals are the zero vector.
    pub degenerate: usize,
}

/// Estimates a normal for every point of `cloud`: sorts a copy of the points along a Z-order
/// curve, builds a [`KdIndex`] over it, runs [`estimate_normals_with_index`] and returns the
/// results in input order. The sorting makes consecutive queries touch neighbouring memory,
/// 2 to 3 times faster than input order on a shuffled cloud of a million points.
///
/// ```
/// use nalgebra::{Point3, Vector3};
/// use sl_cloud::{estimate_normals, NormalConfig, NormalOrientation, PointCloud};
/// // A tilted plane z = 0.5 x, sampled on a grid, seen from above.
/// let pts = (0..400).map(|i| {
///     let (x, y) = ((i % 20) as f64, (i / 20) as f64);
///     Point3::new(x, y, 0.5 * x)
/// });
/// let cloud = PointCloud::from_positions(pts.collect());
/// let config = NormalConfig { k: 8, orientation: NormalOrientation::TowardDirection(Vector3::z()) };
/// let est = estimate_normals(&cloud, &config)?;
/// let want = Vector3::new(-0.5, 0.0, 1.0).normalize();
/// assert!(est.normals.iter().all(|n| (n - want).norm() < 1e-9));
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn estimate_normals(
    cloud: &PointCloud,
    config: &NormalConfig,
) -> Result<NormalEstimate, CloudError> {
    check(config)?;
    let sorted = SortedIndex::new(cloud.positions())?;
    let est = estimate_normals_with_index(&sorted.points, &sorted.index, config)?;
    Ok(NormalEstimate {
        normals: sorted.scatter(est.normals),
        surface_variation: sorted.scatter(est.surface_variation),
        degenerate: est.degenerate,
    })
}

fn check(config: &NormalConfig) -> Result<(), CloudError> {
    if config.k < 3 {
        return Err(CloudError::invalid(
            "k",
            config.k,
            "a plane needs at least 3 neighbours",
        ));
    }
    let bad = match config.orientation {
        NormalOrientation::Unoriented => false,
        NormalOrientation::TowardViewpoint(p) => !is_finite(&p),
        NormalOrientation::TowardDirection(d) => {
            !(d.iter().all(|v| v.is_finite()) && d.norm_squared() > 0.0)
        }
    };
    if bad {
        return Err(CloudError::invalid(
            "orientation",
            format!("{:?}", config.orientation),
            "needs a finite viewpoint or a finite non-zero direction",
        ));
    }
    Ok(())
}

/// Estimates normals for `points` with an index built over these same points.
///
/// Points are processed in the given order; [`estimate_normals`] first sorts them along a
/// Z-order curve, which is much faster for large shuffled clouds.
///
/// Runs in parallel on the rayon pool. For each point: its `k` nearest neighbours, their
/// covariance about their mean, and the eigenvector of its smallest eigenvalue from a closed-form
/// symmetric 3x3 solver; then the sign is chosen by `config.orientation`.
pub fn estimate_normals_with_index(
    points: &[Point3<f64>],
    index: &KdIndex,
    config: &NormalConfig,
) -> Result<NormalEstimate, CloudError> {
    check(config)?;
    if index.len() != points.len() {
        return Err(CloudError::invalid(
            "index",
            format!("{} points", index.len()),
            "the index must be built over the same points",
        ));
    }
    let k = config.k;
    let (normals, surface_variation): (Vec<Vector3<f64>>, Vec<f64>) = points
        .par_iter()
        .map_init(
            || Vec::with_capacity(k),
            |buf, p| {
                index.knn_into(p, k, buf);
                normal_of(points, buf.iter().map(|n| n.index), p, config.orientation)
            },
        )
        .unzip();
    let degenerate = normals.iter().filter(|n| n.norm_squared() == 0.0).count();
    Ok(NormalEstimate {
        normals,
        surface_variation,
        degenerate,
    })
}

/// PCA normal of the neighbourhood `idx` of `p`, oriented, and its surface variation.
fn normal_of(
    points: &[Point3<f64>],
    idx: impl Iterator<Item = usize> + Clone,
    p: &Point3<f64>,
    orientation: NormalOrientation,
) -> (Vector3<f64>, f64) {
    let Some(plane) = fit_local_plane(points, idx) else {
        return (Vector3::zeros(), 0.0);
    };
    let normal = plane.normal;
    let flip = match orientation {
        NormalOrientation::Unoriented => false,
        NormalOrientation::TowardViewpoint(v) => normal.dot(&(v - p)) < 0.0,
        NormalOrientation::TowardDirection(d) => normal.dot(&d) < 0.0,
    };
    (if flip { -normal } else { normal }, plane.surface_variation)
}

/// The least-squares plane of a neighbourhood, found by PCA (see [`fit_local_plane`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalPlane {
    /// Unit normal: the eigenvector of the smallest eigenvalue of the covariance
    /// (unoriented: its sign is the eigen-solver's).
    pub normal: Vector3<f64>,
    /// The mean of the neighbourhood, a point of the plane.
    pub centroid: Point3<f64>,
    /// Surface variation `λ0 / (λ0 + λ1 + λ2)` (eigenvalues ascending): 0 on a plane, up to
    /// 1/3 for isotropic noise.
    pub surface_variation: f64,
}

/// Fits a plane by PCA to the points `points[i]` for `i` in `neighbours` (indices out of
/// range are skipped): the covariance about the mean and the eigenvector of its smallest
/// eigenvalue, from a closed-form symmetric 3x3 solver. `None` with fewer than 3 points or
/// when they all coincide. This is the fit behind [`estimate_normals`]; `sl-icp` uses it for
/// the normals and the overlap averaging of a merged scan.
///
/// ```
/// use nalgebra::{Point3, Vector3};
/// use sl_cloud::fit_local_plane;
/// let pts: Vec<_> = (0..9).map(|i| Point3::new((i % 3) as f64, (i / 3) as f64, 2.0)).collect();
/// let plane = fit_local_plane(&pts, 0..9).unwrap();
/// assert!((plane.normal.z.abs() - 1.0).abs() < 1e-12);
/// assert_eq!(plane.centroid, Point3::new(1.0, 1.0, 2.0));
/// ```
pub fn fit_local_plane(
    points: &[Point3<f64>],
    neighbours: impl Iterator<Item = usize> + Clone,
) -> Option<LocalPlane> {
    let mut n = 0usize;
    let mut sum = Vector3::zeros();
    for q in neighbours.clone().filter_map(|i| points.get(i)) {
        sum += q.coords;
        n += 1;
    }
    if n < 3 {
        return None;
    }
    let mean = sum / n as f64;
    let mut c = [0.0; 6];
    for q in neighbours.filter_map(|i| points.get(i)) {
        let d = q.coords - mean;
        c[0] += d.x * d.x;
        c[1] += d.x * d.y;
        c[2] += d.x * d.z;
        c[3] += d.y * d.y;
        c[4] += d.y * d.z;
        c[5] += d.z * d.z;
    }
    if c.iter().all(|v| *v == 0.0) || !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    let e = smallest_eigen(&c);
    let total = e.values[0] + e.values[1] + e.values[2];
    let surface_variation = if total > 0.0 {
        (e.values[0] / total).max(0.0)
    } else {
        0.0
    };
    Some(LocalPlane {
        normal: e.vector,
        centroid: Point3::from(mean),
        surface_variation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, StandardNormal};
    use rand_pcg::Pcg64;

    #[test]
    fn plane_normals_match_the_analytic_normal() {
        // Random points on the plane n·x = 2 with n = (1, 2, 2)/3, exact up to rounding.
        let n = Vector3::new(1.0, 2.0, 2.0) / 3.0;
        let u = n.cross(&Vector3::x()).normalize();
        let v = n.cross(&u);
        let mut rng = Pcg64::seed_from_u64(1);
        let pts: Vec<Point3<f64>> = (0..2000)
            .map(|_| {
                Point3::from(
                    n * 2.0 + u * rng.random_range(-10.0..10.0) + v * rng.random_range(-10.0..10.0),
                )
            })
            .collect();
        let cloud = PointCloud::from_positions(pts);
        let config = NormalConfig {
            k: 16,
            orientation: NormalOrientation::TowardViewpoint(Point3::origin()),
        };
        let est = estimate_normals(&cloud, &config).unwrap();
        assert_eq!(est.degenerate, 0);
        for (got, sv) in est.normals.iter().zip(&est.surface_variation) {
            // The origin is on the -n side of the plane (n·0 = 0 < 2), so normals face -n.
            // Exact data: only rounding (coordinates ~10, eps 2e-16) limits the match.
            assert_relative_eq!(*got, -n, epsilon = 1e-9);
            assert!(*sv < 1e-12);
        }
    }

    #[test]
    fn sphere_normals_are_radial() {
        // Points on a sphere of radius 50 around c, oriented toward the centre: the normals must
        // be the inward radial directions.
        let c = Point3::new(10.0, -5.0, 200.0);
        let r = 50.0;
        let mut rng = Pcg64::seed_from_u64(2);
        let pts: Vec<Point3<f64>> = (0..20000)
            .map(|_| {
                let d = Vector3::new(
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                )
                .normalize();
                c + d * r
            })
            .collect();
        let cloud = PointCloud::from_positions(pts.clone());
        let config = NormalConfig {
            k: 16,
            orientation: NormalOrientation::TowardViewpoint(c),
        };
        let est = estimate_normals(&cloud, &config).unwrap();
        let mut worst: f64 = 0.0;
        for (p, n) in pts.iter().zip(&est.normals) {
            let want = (c - p).normalize();
            worst = worst.max(n.angle(&want));
        }
        // 20000 points on a sphere of area 31416: spacing ~1.25, a 16-neighbourhood spans about
        // 2.8 units, i.e. 0.056 rad of arc. The PCA plane of a spherical cap is the tangent plane
        // at its centroid, which can be off the query point by at most about that arc; 0.05 rad
        // (2.9 degrees) bounds it with margin, and a wrong or unoriented solver is off by radians.
        assert!(worst < 0.05, "worst angle {worst}");
    }

    #[test]
    fn orientation_options() {
        let pts: Vec<Point3<f64>> = (0..100)
            .map(|i| Point3::new((i % 10) as f64, (i / 10) as f64, 5.0))
            .collect();
        let cloud = PointCloud::from_positions(pts);
        for (orientation, want_z) in [
            (NormalOrientation::TowardDirection(Vector3::z()), 1.0),
            (NormalOrientation::TowardDirection(-Vector3::z()), -1.0),
            (
                NormalOrientation::TowardViewpoint(Point3::new(0.0, 0.0, 100.0)),
                1.0,
            ),
            (NormalOrientation::TowardViewpoint(Point3::origin()), -1.0),
        ] {
            let est = estimate_normals(&cloud, &NormalConfig { k: 6, orientation }).unwrap();
            assert!(
                est.normals.iter().all(|n| (n.z - want_z).abs() < 1e-12),
                "{orientation:?}"
            );
        }
        let est = estimate_normals(
            &cloud,
            &NormalConfig {
                k: 6,
                orientation: NormalOrientation::Unoriented,
            },
        )
        .unwrap();
        assert!(est.normals.iter().all(|n| (n.z.abs() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn bad_config_and_degenerate_input() {
        let cloud = PointCloud::from_positions(vec![Point3::origin(); 2]);
        assert!(matches!(
            estimate_normals(
                &cloud,
                &NormalConfig {
                    k: 2,
                    ..Default::default()
                }
            ),
            Err(CloudError::InvalidParameter { parameter: "k", .. })
        ));
        let dir0 = NormalConfig {
            orientation: NormalOrientation::TowardDirection(Vector3::zeros()),
            ..Default::default()
        };
        assert!(estimate_normals(&cloud, &dir0).is_err());
        // Two points only, and all at one place: zero normals, no panic.
        let est = estimate_normals(&cloud, &NormalConfig::default()).unwrap();
        assert_eq!(est.degenerate, 2);
        let same = PointCloud::from_positions(vec![Point3::new(1.0, 1.0, 1.0); 50]);
        assert_eq!(
            estimate_normals(&same, &NormalConfig::default())
                .unwrap()
                .degenerate,
            50
        );
        let nan = PointCloud::from_positions(vec![Point3::new(f64::NAN, 0.0, 0.0); 5]);
        assert_eq!(
            estimate_normals(&nan, &NormalConfig::default())
                .unwrap()
                .degenerate,
            5
        );
        let empty = estimate_normals(&PointCloud::new(), &NormalConfig::default()).unwrap();
        assert!(empty.normals.is_empty());
    }
}
