//! Outlier removal: statistical (mean distance to the k nearest neighbours) and by radius count.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::morton::SortedIndex;
use crate::{CloudError, PointCloud};

/// Settings of [`remove_statistical_outliers`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatisticalOutlierConfig {
    /// Neighbours per point, the point itself excluded (as PCL). Default 20 (Open3D's and PCL's
    /// tutorials use 20 and 50): enough for a stable mean, local enough to keep thin parts.
    pub k: usize,
    /// A point is an outlier when its mean neighbour distance exceeds
    /// `mean + std_ratio * std` over the cloud. Default 2.0, the usual choice in both libraries.
    pub std_ratio: f64,
}

impl Default for StatisticalOutlierConfig {
    fn default() -> Self {
        Self {
            k: 20,
            std_ratio: 2.0,
        }
    }
}

/// Result of [`remove_statistical_outliers`].
#[derive(Debug, Clone, PartialEq)]
pub struct StatisticalOutliers {
    /// The kept points, with their attributes, in input order.
    pub cloud: PointCloud,
    /// Input indices of the kept points (ascending).
    pub inliers: Vec<usize>,
    /// Input indices of the removed points (ascending), non-finite points included.
    pub outliers: Vec<usize>,
    /// The distance threshold `mean + std_ratio * std` that was applied.
    pub threshold: f64,
}

/// Removes points whose mean distance to their `k` nearest neighbours is unusually large,
/// like PCL's `StatisticalOutlierRemoval` and Open3D's `remove_statistical_outlier`: with `d_i`
/// the mean distance of point `i` to its `k` nearest other points, `μ` and `σ` (sample standard
/// deviation) the mean and spread of the `d_i`, point `i` is kept when `d_i <= μ + std_ratio σ`.
///
/// Unlike Open3D, the point itself is not counted among its neighbours (PCL's convention), so
/// `k` means `k` other points. Non-finite points are always removed.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{remove_statistical_outliers, PointCloud, StatisticalOutlierConfig};
/// let mut pts: Vec<_> = (0..400).map(|i| Point3::new((i % 20) as f64, (i / 20) as f64, 0.0)).collect();
/// pts.push(Point3::new(10.0, 10.0, 30.0));
/// let r = remove_statistical_outliers(&PointCloud::from_positions(pts), &StatisticalOutlierConfig::default())?;
/// assert_eq!(r.outliers, vec![400]);
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn remove_statistical_outliers(
    cloud: &PointCloud,
    config: &StatisticalOutlierConfig,
) -> Result<StatisticalOutliers, CloudError> {
    if config.k == 0 {
        return Err(CloudError::invalid(
            "k",
            config.k,
            "needs at least one neighbour",
        ));
    }
    if !config.std_ratio.is_finite() {
        return Err(CloudError::invalid(
            "std_ratio",
            config.std_ratio,
            "must be finite",
        ));
    }
    let sorted = SortedIndex::new(cloud.positions())?;
    let index = &sorted.index;
    let k = config.k;
    // Mean distance to the k nearest others; None for points that have none (non-finite, or a
    // cloud of one point).
    let means: Vec<Option<f64>> = sorted
        .points
        .par_iter()
        .enumerate()
        .map_init(
            || Vec::with_capacity(k + 1),
            |buf, (i, p)| {
                index.knn_into(p, k + 1, buf);
                // Drop the point itself; with duplicates it may not come first, so remove by index
                // and otherwise drop the farthest.
                match buf.iter().position(|n| n.index == i) {
                    Some(pos) => {
                        buf.remove(pos);
                    }
                    None => {
                        buf.truncate(k);
                    }
                }
                (!buf.is_empty()).then(|| {
                    buf.iter().map(|n| n.distance_squared.sqrt()).sum::<f64>() / buf.len() as f64
                })
            },
        )
        .collect();
    let means = sorted.scatter(means);
    let valid: Vec<f64> = means.iter().flatten().copied().collect();
    let n = valid.len() as f64;
    let mu = valid.iter().sum::<f64>() / n.max(1.0);
    let var = if valid.len() > 1 {
        valid.iter().map(|d| (d - mu).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    let threshold = mu + config.std_ratio * var.sqrt();
    let (inliers, outliers): (Vec<usize>, Vec<usize>) = (0..means.len()).partition(|&i| {
        means
            .get(i)
            .copied()
            .flatten()
            .is_some_and(|d| d <= threshold)
    });
    Ok(StatisticalOutliers {
        cloud: cloud.select_unchecked(&inliers),
        inliers,
        outliers,
        threshold,
    })
}

/// Settings of [`remove_radius_outliers`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadiusOutlierConfig {
    /// Search radius in the cloud's units. Default 2.0: a few times the 0.1 to 0.5 mm spacing of
    /// a scanner cloud in millimetres.
    pub radius: f64,
    /// Fewest other points within `radius` for a point to be kept (the point itself is not
    /// counted). Default 4.
    pub min_neighbours: usize,
}

impl Default for RadiusOutlierConfig {
    fn default() -> Self {
        Self {
            radius: 2.0,
            min_neighbours: 4,
        }
    }
}

/// Result of [`remove_radius_outliers`].
#[derive(Debug, Clone, PartialEq)]
pub struct RadiusOutliers {
    /// The kept points, with their attributes, in input order.
    pub cloud: PointCloud,
    /// Input indices of the kept points (ascending).
    pub inliers: Vec<usize>,
    /// Input indices of the removed points (ascending), non-finite points included.
    pub outliers: Vec<usize>,
}

/// Removes points with fewer than `min_neighbours` other points within `radius` (boundary
/// included). Non-finite points are always removed.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{remove_radius_outliers, PointCloud, RadiusOutlierConfig};
/// let mut pts: Vec<_> = (0..100).map(|i| Point3::new((i % 10) as f64, (i / 10) as f64, 0.0)).collect();
/// pts.push(Point3::new(50.0, 0.0, 0.0));
/// let config = RadiusOutlierConfig { radius: 1.5, min_neighbours: 3 };
/// let r = remove_radius_outliers(&PointCloud::from_positions(pts), &config)?;
/// assert_eq!(r.outliers, vec![100]);
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn remove_radius_outliers(
    cloud: &PointCloud,
    config: &RadiusOutlierConfig,
) -> Result<RadiusOutliers, CloudError> {
    if !(config.radius > 0.0 && config.radius.is_finite()) {
        return Err(CloudError::invalid(
            "radius",
            config.radius,
            "must be finite and > 0",
        ));
    }
    let sorted = SortedIndex::new(cloud.positions())?;
    let index = &sorted.index;
    let keep: Vec<bool> = sorted
        .points
        .par_iter()
        .map(|p| {
            let found = index.radius_unsorted(p, config.radius).len();
            // `found` includes the point itself when it is finite (distance 0).
            found > config.min_neighbours
        })
        .collect();
    let keep = sorted.scatter(keep);
    let (inliers, outliers): (Vec<usize>, Vec<usize>) =
        (0..keep.len()).partition(|&i| keep.get(i).copied().unwrap_or(false));
    Ok(RadiusOutliers {
        cloud: cloud.select_unchecked(&inliers),
        inliers,
        outliers,
    })
}

/// Settings of [`remove_far_points`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FarPointConfig {
    /// Fraction of the points the robust radius holds (see [`remove_far_points`]). Default 0.99:
    /// a far group of up to 1 % of the points cannot move the radius, and on any compact object
    /// the 99th percentile of the distances is within a few per cent of the largest.
    pub quantile: f64,
    /// A point is far when its distance from the median centre exceeds `factor` times the
    /// robust radius. Default 10: no point of a scanned object is that far (the corner of a
    /// cube is 1.1 times the 99th percentile, the end of a rod 1.02 times), while a point 10
    /// times farther than the rest makes the bounding box, and every octree or voxel grid
    /// sized to it, at least 10 times coarser for the sake of at most 1 % of the samples.
    pub factor: f64,
}

impl Default for FarPointConfig {
    fn default() -> Self {
        Self {
            quantile: 0.99,
            factor: 10.0,
        }
    }
}

/// Result of [`remove_far_points`].
#[derive(Debug, Clone, PartialEq)]
pub struct FarPoints {
    /// The kept points, with their attributes, in input order.
    pub cloud: PointCloud,
    /// Input indices of the kept points (ascending).
    pub inliers: Vec<usize>,
    /// Input indices of the removed points (ascending), non-finite points included.
    pub outliers: Vec<usize>,
    /// The median of the finite points, axis by axis.
    pub centre: Point3<f64>,
    /// The robust radius: the `quantile` of the finite points' distances from `centre`.
    pub radius: f64,
    /// The distance beyond which a point was removed, `factor * radius` (infinite when the
    /// radius is 0: a cloud whose points mostly coincide has no scale to judge by).
    pub threshold: f64,
    /// The largest distance from `centre` of a removed finite point (0 when none was).
    pub farthest: f64,
}

/// Removes the points far from the rest of the cloud, judged by a robust extent that they
/// cannot inflate: with `c` the axis-wise median of the points and `r` the `quantile` of their
/// distances from `c`, a point is far when its distance exceeds `factor * r`. Meant to run
/// before anything is sized to the cloud's bounding box (an octree, a voxel grid, a preview):
/// two stray points at ±1e30 mm would otherwise size it to them. Non-finite points are
/// always removed. O(n).
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{remove_far_points, FarPointConfig, PointCloud};
/// let mut pts: Vec<_> = (0..400).map(|i| Point3::new((i % 20) as f64, (i / 20) as f64, 0.0)).collect();
/// pts.push(Point3::new(1e30, 0.0, 0.0));
/// let r = remove_far_points(&PointCloud::from_positions(pts), &FarPointConfig::default())?;
/// assert_eq!(r.outliers, vec![400]);
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
///
/// # Errors
/// [`CloudError::InvalidParameter`] for a `quantile` outside (0, 1] or a `factor` that is not
/// a finite number ≥ 1.
pub fn remove_far_points(
    cloud: &PointCloud,
    config: &FarPointConfig,
) -> Result<FarPoints, CloudError> {
    if !(config.quantile > 0.0 && config.quantile <= 1.0) {
        return Err(CloudError::invalid(
            "quantile",
            config.quantile,
            "must be in (0, 1]",
        ));
    }
    if !(config.factor.is_finite() && config.factor >= 1.0) {
        return Err(CloudError::invalid(
            "factor",
            config.factor,
            "must be a finite number >= 1",
        ));
    }
    let positions = cloud.positions();
    let finite: Vec<&Point3<f64>> = positions
        .iter()
        .filter(|p| p.iter().all(|c| c.is_finite()))
        .collect();
    let median = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return 0.0;
        }
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let centre = Point3::new(
        median(finite.iter().map(|p| p.x).collect()),
        median(finite.iter().map(|p| p.y).collect()),
        median(finite.iter().map(|p| p.z).collect()),
    );
    let mut distances: Vec<f64> = finite.iter().map(|p| (*p - centre).norm()).collect();
    let radius = if distances.is_empty() {
        0.0
    } else {
        // The smallest distance that at least `quantile` of the points do not exceed.
        let k = ((config.quantile * distances.len() as f64).ceil() as usize)
            .clamp(1, distances.len())
            - 1;
        *distances.select_nth_unstable_by(k, f64::total_cmp).1
    };
    let threshold = if radius > 0.0 {
        config.factor * radius
    } else {
        f64::INFINITY
    };
    let mut farthest = 0.0f64;
    let (inliers, outliers): (Vec<usize>, Vec<usize>) = (0..positions.len()).partition(|&i| {
        let d = (positions[i] - centre).norm();
        if d.is_finite() && d > threshold {
            farthest = farthest.max(d);
        }
        d <= threshold
    });
    Ok(FarPoints {
        cloud: cloud.select_unchecked(&inliers),
        inliers,
        outliers,
        centre,
        radius,
        threshold,
        farthest,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// A noisy 60x60 plane (spacing 1, noise 0.05) plus 30 outliers 5 to 20 units above it.
    fn plane_with_outliers() -> (PointCloud, Vec<usize>) {
        let mut rng = Pcg64::seed_from_u64(3);
        let mut pts: Vec<Point3<f64>> = (0..3600)
            .map(|i| {
                Point3::new(
                    (i % 60) as f64,
                    (i / 60) as f64,
                    rng.random_range(-0.05..0.05),
                )
            })
            .collect();
        let mut injected = Vec::new();
        for _ in 0..30 {
            injected.push(pts.len());
            pts.push(Point3::new(
                rng.random_range(0.0..60.0),
                rng.random_range(0.0..60.0),
                rng.random_range(5.0..20.0) * if rng.random_bool(0.5) { 1.0 } else { -1.0 },
            ));
        }
        (PointCloud::from_positions(pts), injected)
    }

    #[test]
    fn statistical_removes_injected_outliers() {
        let (cloud, injected) = plane_with_outliers();
        let r = remove_statistical_outliers(&cloud, &StatisticalOutlierConfig::default()).unwrap();
        // Every injected point is far from the plane: its mean distance to 20 neighbours is
        // several units while plane points sit at about 1.9; all must go.
        for i in &injected {
            assert!(r.outliers.contains(i), "outlier {i} kept");
        }
        // Only plane points on the border/corners may also exceed mu + 2 sigma; bound them.
        let extra = r.outliers.len() - injected.len();
        assert!(extra < 120, "{extra} plane points removed");
        assert_eq!(r.inliers.len() + r.outliers.len(), cloud.len());
        assert_eq!(r.cloud.len(), r.inliers.len());
    }

    #[test]
    fn radius_removes_injected_outliers_and_keeps_the_plane() {
        let (cloud, injected) = plane_with_outliers();
        // Within 1.5 a plane point has at least 3 others (a corner: 3), an outlier 5 units away none.
        let r = remove_radius_outliers(
            &cloud,
            &RadiusOutlierConfig {
                radius: 1.5,
                min_neighbours: 3,
            },
        )
        .unwrap();
        assert_eq!(r.outliers, injected);
        assert_eq!(r.cloud.len(), 3600);
    }

    #[test]
    fn statistical_threshold_by_hand() {
        // Points on a line at 0, 1, 2, 3 and 10, k = 1: nearest-other distances 1, 1, 1, 1, 7.
        // mean 2.2, sample std sqrt((4*1.44 + 23.04) / 4) = sqrt(7.2); threshold with ratio 1:
        // 2.2 + 2.683 = 4.883, so only the point at 10 goes.
        let cloud = PointCloud::from_positions(
            [0.0, 1.0, 2.0, 3.0, 10.0]
                .iter()
                .map(|&x| Point3::new(x, 0.0, 0.0))
                .collect(),
        );
        let r = remove_statistical_outliers(
            &cloud,
            &StatisticalOutlierConfig {
                k: 1,
                std_ratio: 1.0,
            },
        )
        .unwrap();
        approx::assert_relative_eq!(r.threshold, 2.2 + 7.2f64.sqrt(), epsilon = 1e-12);
        assert_eq!(r.outliers, vec![4]);
    }

    #[test]
    fn edge_cases() {
        let empty = PointCloud::new();
        assert!(
            remove_statistical_outliers(&empty, &StatisticalOutlierConfig::default())
                .unwrap()
                .cloud
                .is_empty()
        );
        assert!(
            remove_radius_outliers(&empty, &RadiusOutlierConfig::default())
                .unwrap()
                .cloud
                .is_empty()
        );
        let one = PointCloud::from_positions(vec![Point3::origin()]);
        assert_eq!(
            remove_statistical_outliers(&one, &StatisticalOutlierConfig::default())
                .unwrap()
                .outliers,
            vec![0]
        );
        let nan = PointCloud::from_positions(vec![
            Point3::new(f64::NAN, 0.0, 0.0),
            Point3::origin(),
            Point3::origin(),
        ]);
        let r = remove_statistical_outliers(
            &nan,
            &StatisticalOutlierConfig {
                k: 1,
                std_ratio: 1.0,
            },
        )
        .unwrap();
        assert_eq!(r.outliers, vec![0]);
        let r = remove_radius_outliers(
            &nan,
            &RadiusOutlierConfig {
                radius: 1.0,
                min_neighbours: 1,
            },
        )
        .unwrap();
        assert_eq!(r.outliers, vec![0]);
        assert!(
            remove_statistical_outliers(
                &one,
                &StatisticalOutlierConfig {
                    k: 0,
                    std_ratio: 1.0
                }
            )
            .is_err()
        );
        assert!(
            remove_radius_outliers(
                &one,
                &RadiusOutlierConfig {
                    radius: -1.0,
                    min_neighbours: 1
                }
            )
            .is_err()
        );
    }

    /// The far-point test keeps every point of compact and elongated shapes (a cube's
    /// corners, a rod's ends, a plane's rim) and removes a few stray points however far, and
    /// non-finite ones; the removed points cannot move the robust radius.
    #[test]
    fn far_points_are_stray_points_only() {
        let (plane, _) = plane_with_outliers();
        let rod = PointCloud::from_positions(
            (0..1000)
                .map(|i| Point3::new(f64::from(i), 0.0, 0.0))
                .collect(),
        );
        let cube = PointCloud::from_positions(
            (0..1000)
                .map(|i| {
                    Point3::new(
                        f64::from(i % 10),
                        f64::from(i / 10 % 10),
                        f64::from(i / 100),
                    )
                })
                .collect(),
        );
        for c in [&plane, &rod, &cube] {
            let r = remove_far_points(c, &FarPointConfig::default()).unwrap();
            assert!(r.outliers.is_empty(), "{:?}", r.outliers);
            assert_eq!(r.cloud.len(), c.len());
        }
        let mut pts = plane.positions().to_vec();
        let radius = remove_far_points(&plane, &FarPointConfig::default())
            .unwrap()
            .radius;
        pts.extend([
            Point3::new(1e30, 1e30, 1e30),
            Point3::new(-1e30, -1e30, -1e30),
            Point3::new(f64::NAN, 0.0, 0.0),
            Point3::new(30.0, 30.0, 600.0),
        ]);
        let r = remove_far_points(&PointCloud::from_positions(pts), &FarPointConfig::default())
            .unwrap();
        let n = plane.len();
        assert_eq!(r.outliers, vec![n, n + 1, n + 2, n + 3]);
        assert_eq!(r.cloud.positions(), plane.positions());
        assert!(
            (r.radius - radius).abs() < 0.05 * radius,
            "{} vs {radius}",
            r.radius
        );
        assert!(
            (r.farthest - 3f64.sqrt() * 1e30).abs() < 1e27,
            "{}",
            r.farthest
        );
        for bad in [
            FarPointConfig {
                quantile: 0.0,
                ..FarPointConfig::default()
            },
            FarPointConfig {
                factor: f64::NAN,
                ..FarPointConfig::default()
            },
        ] {
            assert!(remove_far_points(&plane, &bad).is_err());
        }
    }
}
