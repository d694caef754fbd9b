//! Voxel-grid downsampling: one point per occupied voxel, at the centroid of its points.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::cloud::is_finite;
use crate::{CloudError, PointCloud};

/// Largest voxel index magnitude we accept along an axis: 2^52 keeps `floor(x / size)` exact in
/// an `f64` and the `i64` key far from overflow. Exceeding it means the voxel is absurdly small
/// for the cloud's coordinates.
const MAX_VOXEL_INDEX: f64 = (1u64 << 52) as f64;

/// Settings of [`voxel_downsample`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelGridConfig {
    /// Edge length of the cubic voxels, in the cloud's units (must be finite and > 0).
    /// Default 1.0: 1 mm for a scanner cloud in millimetres, a common density for merging scans.
    pub voxel_size: f64,
}

impl Default for VoxelGridConfig {
    fn default() -> Self {
        Self { voxel_size: 1.0 }
    }
}

/// Result of [`voxel_downsample`].
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelDownsample {
    /// One point per occupied voxel, ordered by voxel index (x, then y, then z).
    pub cloud: PointCloud,
    /// Number of input points merged into each output point.
    pub counts: Vec<usize>,
}

/// Downsamples `cloud` on a grid of cubic voxels with a corner at the origin: every occupied
/// voxel `[i s, (i + 1) s) x [j s, ...) x [k s, ...)` gives one point at the centroid of its
/// points. Attributes are averaged: normals are summed and renormalised (zero if they cancel),
/// colours averaged and rounded, quality averaged. Non-finite points are ignored.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{voxel_downsample, PointCloud, VoxelGridConfig};
/// let cloud = PointCloud::from_positions(vec![
///     Point3::new(0.1, 0.1, 0.1),
///     Point3::new(0.3, 0.5, 0.7),
///     Point3::new(1.5, 0.5, 0.5),
/// ]);
/// let down = voxel_downsample(&cloud, &VoxelGridConfig { voxel_size: 1.0 })?;
/// assert_eq!(down.cloud.len(), 2);
/// assert_eq!(down.counts, vec![2, 1]);
/// assert!((down.cloud.positions()[0] - Point3::new(0.2, 0.3, 0.4)).norm() < 1e-12);
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn voxel_downsample(
    cloud: &PointCloud,
    config: &VoxelGridConfig,
) -> Result<VoxelDownsample, CloudError> {
    let size = config.voxel_size;
    if !(size > 0.0 && size.is_finite()) {
        return Err(CloudError::invalid(
            "voxel_size",
            size,
            "must be finite and > 0",
        ));
    }
    let pos = cloud.positions();
    let mut keyed: Vec<([i64; 3], u32)> = Vec::with_capacity(pos.len());
    for (i, p) in pos.iter().enumerate() {
        if !is_finite(p) {
            continue;
        }
        let f = p.coords.map(|v| (v / size).floor());
        if f.iter().any(|v| v.abs() > MAX_VOXEL_INDEX) {
            return Err(CloudError::invalid(
                "voxel_size",
                size,
                "too small for the cloud's coordinates (voxel index beyond 2^52)",
            ));
        }
        let i = u32::try_from(i).map_err(|_| CloudError::TooManyPoints {
            len: pos.len(),
            max: u32::MAX as usize,
        })?;
        keyed.push(([f.x as i64, f.y as i64, f.z as i64], i));
    }
    keyed.par_sort_unstable();

    let (normals, colors, quality) = (cloud.normals(), cloud.colors(), cloud.quality());
    let mut out_p = Vec::new();
    let mut out_n = normals.map(|_| Vec::new());
    let mut out_c = colors.map(|_| Vec::new());
    let mut out_q = quality.map(|_| Vec::new());
    let mut counts = Vec::new();
    for run in keyed.chunk_by(|a, b| a.0 == b.0) {
        let m = run.len() as f64;
        let idx = || run.iter().map(|&(_, i)| i as usize);
        let sum = idx()
            .filter_map(|i| pos.get(i))
            .fold(Vector3::zeros(), |s, p| s + p.coords);
        out_p.push(Point3::from(sum / m));
        if let (Some(out), Some(src)) = (&mut out_n, normals) {
            let s: Vector3<f64> = idx().filter_map(|i| src.get(i)).sum();
            let len = s.norm();
            out.push(if len > 0.0 { s / len } else { Vector3::zeros() });
        }
        if let (Some(out), Some(src)) = (&mut out_c, colors) {
            let s = idx().filter_map(|i| src.get(i)).fold([0.0f64; 3], |a, c| {
                [
                    a[0] + f64::from(c[0]),
                    a[1] + f64::from(c[1]),
                    a[2] + f64::from(c[2]),
                ]
            });
            out.push(s.map(|v| (v / m).round().clamp(0.0, 255.0) as u8));
        }
        if let (Some(out), Some(src)) = (&mut out_q, quality) {
            let s: f64 = idx()
                .filter_map(|i| src.get(i))
                .map(|&q| f64::from(q))
                .sum();
            out.push((s / m) as f32);
        }
        counts.push(run.len());
    }
    let cloud = PointCloud::from_parts(out_p, out_n, out_c, out_q)?;
    Ok(VoxelDownsample { cloud, counts })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn known_grid() {
        // A 4x4x4 lattice of spacing 0.5 starting at 0.25: with 1.0 voxels each voxel gets a
        // 2x2x2 block whose centroid is the voxel centre (i + 0.5, ...).
        let mut pts = Vec::new();
        for i in 0..4 {
            for j in 0..4 {
                for k in 0..4 {
                    pts.push(Point3::new(
                        0.25 + 0.5 * i as f64,
                        0.25 + 0.5 * j as f64,
                        0.25 + 0.5 * k as f64,
                    ));
                }
            }
        }
        let n = pts.len();
        let colors: Vec<[u8; 3]> = (0..n).map(|i| [(i % 2) as u8 * 10, 100, 255]).collect();
        let quality: Vec<f32> = (0..n).map(|i| i as f32).collect();
        let normals = vec![Vector3::new(1.0, 1.0, 0.0).normalize(); n];
        let cloud = PointCloud::from_parts(pts, Some(normals), Some(colors), Some(quality.clone()))
            .unwrap();
        let d = voxel_downsample(&cloud, &VoxelGridConfig { voxel_size: 1.0 }).unwrap();
        assert_eq!(d.cloud.len(), 8);
        assert_eq!(d.counts, vec![8; 8]);
        let mut k = 0;
        for i in 0..2 {
            for j in 0..2 {
                for l in 0..2 {
                    // Sorted by (x, y, z) voxel index.
                    let want = Point3::new(i as f64 + 0.5, j as f64 + 0.5, l as f64 + 0.5);
                    assert_relative_eq!(d.cloud.positions()[k], want, epsilon = 1e-12);
                    // Colours alternate 0/10 in red: mean 5.
                    assert_eq!(d.cloud.colors().unwrap()[k], [5, 100, 255]);
                    assert_relative_eq!(d.cloud.normals().unwrap()[k].norm(), 1.0, epsilon = 1e-12);
                    k += 1;
                }
            }
        }
        // Mean quality over all voxels equals the mean over all points (equal counts).
        let mean_q: f32 = d.cloud.quality().unwrap().iter().sum::<f32>() / 8.0;
        assert_relative_eq!(
            mean_q,
            quality.iter().sum::<f32>() / n as f32,
            epsilon = 1e-4
        );
    }

    #[test]
    fn negative_coordinates_use_floor() {
        // -0.2 and -0.9 share voxel -1; 0.2 is in voxel 0.
        let cloud = PointCloud::from_positions(vec![
            Point3::new(-0.2, 0.0, 0.0),
            Point3::new(-0.9, 0.0, 0.0),
            Point3::new(0.2, 0.0, 0.0),
        ]);
        let d = voxel_downsample(&cloud, &VoxelGridConfig::default()).unwrap();
        assert_eq!(d.counts, vec![2, 1]);
        assert_relative_eq!(d.cloud.positions()[0].x, -0.55, epsilon = 1e-15);
    }

    #[test]
    fn opposite_normals_cancel_to_zero_and_bad_inputs() {
        let cloud = PointCloud::from_positions(vec![Point3::origin(), Point3::new(0.1, 0.1, 0.1)])
            .with_normals(vec![Vector3::z(), -Vector3::z()])
            .unwrap();
        let d = voxel_downsample(&cloud, &VoxelGridConfig::default()).unwrap();
        assert_eq!(d.cloud.normals().unwrap()[0], Vector3::zeros());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(voxel_downsample(&cloud, &VoxelGridConfig { voxel_size: bad }).is_err());
        }
        let far = PointCloud::from_positions(vec![Point3::new(1e300, 0.0, 0.0)]);
        assert!(voxel_downsample(&far, &VoxelGridConfig { voxel_size: 1e-9 }).is_err());
        let nan =
            PointCloud::from_positions(vec![Point3::new(f64::NAN, 0.0, 0.0), Point3::origin()]);
        assert_eq!(
            voxel_downsample(&nan, &VoxelGridConfig::default())
                .unwrap()
                .cloud
                .len(),
            1
        );
    }
}
