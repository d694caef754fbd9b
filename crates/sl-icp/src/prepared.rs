//! A cloud made ready for registration: finite points only, optional downsampling, normals,
//! a lazily built closest-point index and, for organised clouds, the camera's pixel grid.

use std::sync::OnceLock;

use nalgebra::{Point3, Vector3};
use sl_cloud::{
    KdIndex, NormalConfig, PointCloud, VoxelGridConfig, estimate_normals_with_index,
    voxel_downsample,
};

use crate::IcpError;

/// Marks a pixel of an organised grid without a point.
const NO_POINT: u32 = u32::MAX;

/// Where the normals of a [`PreparedCloud`] come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NormalSource {
    /// No normals (enough for point-to-point ICP with closest-point or projective association).
    None,
    /// The cloud's own normals; an error names the cloud if it has none.
    FromCloud,
    /// Estimated by PCA of the `k` nearest neighbours (after downsampling).
    Estimate(NormalConfig),
    /// The cloud's own normals when it has some, else estimated.
    FromCloudOrEstimate(NormalConfig),
}

impl Default for NormalSource {
    /// Keep the cloud's normals, else estimate them from 20 neighbours (as Open3D's generalized
    /// ICP does for its covariances), facing the camera at the origin.
    fn default() -> Self {
        Self::FromCloudOrEstimate(NormalConfig {
            k: 20,
            ..NormalConfig::default()
        })
    }
}

/// Settings of [`PreparedCloud::new`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PrepareConfig {
    /// Edge of the voxel grid used to downsample first, in mm; `None` keeps every point.
    /// Default `None`. A 1 mm grid is a good start for registering scans of a 100 mm object.
    pub voxel_size: Option<f64>,
    /// Where the normals come from. Default: the cloud's, else estimated from 20 neighbours.
    pub normals: NormalSource,
}

/// The pixel grid and pinhole model of the camera that produced an organised cloud (no
/// distortion: projective association only needs the right pixel to within its search window).
///
/// Point `v * width + u` of the organised cloud is what pixel `(u, v)` saw, in the camera frame
/// (x right, y down, z forward, mm); pixel centres at integer coordinates, as OpenCV.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeGrid {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x, in pixels.
    pub cx: f64,
    /// Principal point y, in pixels.
    pub cy: f64,
}

impl PinholeGrid {
    /// The pixel `(u, v)` nearest to the projection of `p` (camera frame), if `p` is in front of
    /// the camera and inside the image.
    #[inline]
    pub fn pixel_of(&self, p: &Point3<f64>) -> Option<(usize, usize)> {
        if p.z.is_nan() || p.z <= 0.0 {
            return None;
        }
        let u = (self.fx * p.x / p.z + self.cx).round();
        let v = (self.fy * p.y / p.z + self.cy).round();
        let inside = u >= 0.0 && v >= 0.0 && u < self.width as f64 && v < self.height as f64;
        inside.then_some((u as usize, v as usize))
    }

    fn check(&self) -> Result<(), IcpError> {
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(IcpError::invalid(
                    name,
                    v,
                    "focal length must be finite and > 0",
                ));
            }
        }
        for (name, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !v.is_finite() {
                return Err(IcpError::invalid(name, v, "principal point must be finite"));
            }
        }
        Ok(())
    }
}

/// An organised target's grid and its pixel-to-point map.
#[derive(Debug, Clone)]
pub(crate) struct Organized {
    pub(crate) grid: PinholeGrid,
    /// For each pixel (row-major), the index of its point in `PreparedCloud::points`, or
    /// `NO_POINT`.
    pixel_to_point: Vec<u32>,
}

impl Organized {
    /// Index of the point seen by pixel `(u, v)`, if any.
    #[inline]
    pub(crate) fn point_at(&self, u: usize, v: usize) -> Option<u32> {
        if u >= self.grid.width {
            return None;
        }
        match self.pixel_to_point.get(v * self.grid.width + u) {
            Some(&i) if i != NO_POINT => Some(i),
            _ => None,
        }
    }
}

/// A point cloud made ready for registration, usable as source and as target.
///
/// Holds the finite points only (non-finite points are dropped), optional unit normals (zero
/// where none could be estimated), the centroid, the closest-point k-d tree (built on first use
/// as a target, then kept) and, for an organised cloud, its camera grid for projective
/// association. Prepare a cloud once and reuse it for every registration it takes part in.
///
/// ```
/// use nalgebra::Point3;
/// use sl_icp::{PrepareConfig, PreparedCloud, PointCloud};
/// let pts = (0..1000).map(|i| Point3::new((i % 10) as f64, (i / 10 % 10) as f64, (i / 100) as f64));
/// let prepared = PreparedCloud::new(&PointCloud::from_positions(pts.collect()), &PrepareConfig::default())?;
/// assert_eq!(prepared.len(), 1000);
/// assert!(prepared.normals().is_some());
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
#[derive(Debug)]
pub struct PreparedCloud {
    points: Vec<Point3<f64>>,
    normals: Option<Vec<Vector3<f64>>>,
    centroid: Point3<f64>,
    index: OnceLock<KdIndex>,
    organized: Option<Organized>,
}

impl Clone for PreparedCloud {
    fn clone(&self) -> Self {
        Self {
            points: self.points.clone(),
            normals: self.normals.clone(),
            centroid: self.centroid,
            // The index is rebuilt on demand: cheaper to rebuild than to clone-by-rebuild.
            index: OnceLock::new(),
            organized: self.organized.clone(),
        }
    }
}

fn is_finite(p: &Point3<f64>) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
}

impl PreparedCloud {
    /// Prepares an unorganised cloud: drops non-finite points, downsamples, gets normals.
    ///
    /// # Errors
    /// [`IcpError::InvalidParameter`] for a bad voxel size or normal configuration,
    /// [`IcpError::MissingNormals`] for [`NormalSource::FromCloud`] on a cloud without normals.
    /// An empty cloud is accepted (registration will refuse it, naming it).
    pub fn new(cloud: &PointCloud, config: &PrepareConfig) -> Result<Self, IcpError> {
        let finite = if cloud.positions().iter().all(is_finite) {
            None
        } else {
            Some(cloud.remove_non_finite())
        };
        let cloud = finite.as_ref().unwrap_or(cloud);
        let down = match config.voxel_size {
            None => None,
            Some(size) => {
                Some(voxel_downsample(cloud, &VoxelGridConfig { voxel_size: size })?.cloud)
            }
        };
        let cloud = down.as_ref().unwrap_or(cloud);
        Self::build(cloud, config.normals, None)
    }

    /// Prepares an organised cloud (one point per camera pixel, row-major, non-finite where the
    /// pixel saw nothing) for projective association. Downsampling would break the pixel grid,
    /// so `config.voxel_size` must be `None`.
    ///
    /// # Errors
    /// [`IcpError::GridSize`] if the cloud does not have `width * height` points,
    /// [`IcpError::InvalidParameter`] for a bad grid or a voxel size, and the errors of
    /// [`new`](Self::new).
    pub fn from_organized(
        cloud: &PointCloud,
        grid: PinholeGrid,
        config: &PrepareConfig,
    ) -> Result<Self, IcpError> {
        grid.check()?;
        if let Some(v) = config.voxel_size {
            return Err(IcpError::invalid(
                "voxel_size",
                v,
                "an organised cloud cannot be downsampled (use None)",
            ));
        }
        let expected = grid.width.saturating_mul(grid.height);
        if cloud.len() != expected {
            return Err(IcpError::GridSize {
                width: grid.width,
                height: grid.height,
                expected,
                found: cloud.len(),
            });
        }
        let mut pixel_to_point = vec![NO_POINT; expected];
        let mut keep = Vec::with_capacity(expected);
        for (pixel, p) in cloud.positions().iter().enumerate() {
            if is_finite(p) {
                if let Some(slot) = pixel_to_point.get_mut(pixel) {
                    *slot = u32::try_from(keep.len()).unwrap_or(NO_POINT);
                }
                keep.push(pixel);
            }
        }
        let cloud = cloud.select(&keep)?;
        Self::build(
            &cloud,
            config.normals,
            Some(Organized {
                grid,
                pixel_to_point,
            }),
        )
    }

    /// Finite points of `cloud` in, normals from `source` (estimating them builds the tree,
    /// which is then kept for closest-point queries).
    fn build(
        cloud: &PointCloud,
        source: NormalSource,
        organized: Option<Organized>,
    ) -> Result<Self, IcpError> {
        let points = cloud.positions().to_vec();
        if points.len() >= u32::MAX as usize {
            return Err(sl_cloud::CloudError::TooManyPoints {
                len: points.len(),
                max: u32::MAX as usize - 1,
            }
            .into());
        }
        let index = OnceLock::new();
        let estimate = |config: &NormalConfig| -> Result<Vec<Vector3<f64>>, IcpError> {
            let tree = match index.get() {
                Some(tree) => tree,
                None => {
                    let tree = KdIndex::new(&points)?;
                    index.get_or_init(|| tree)
                }
            };
            Ok(estimate_normals_with_index(&points, tree, config)?.normals)
        };
        let normals = match source {
            NormalSource::None => None,
            NormalSource::FromCloud => match cloud.normals() {
                Some(n) => Some(n.to_vec()),
                None => {
                    return Err(IcpError::MissingNormals {
                        cloud: "cloud being prepared",
                        needed_by: "NormalSource::FromCloud",
                    });
                }
            },
            NormalSource::Estimate(config) => Some(estimate(&config)?),
            NormalSource::FromCloudOrEstimate(config) => match cloud.normals() {
                Some(n) => Some(n.to_vec()),
                None => Some(estimate(&config)?),
            },
        };
        let sum = points
            .iter()
            .fold(Vector3::zeros(), |s: Vector3<f64>, p| s + p.coords);
        let centroid = Point3::from(sum / points.len().max(1) as f64);
        Ok(Self {
            points,
            normals,
            centroid,
            index,
            organized,
        })
    }

    /// Number of (finite) points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there is no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The points, in mm.
    pub fn points(&self) -> &[Point3<f64>] {
        &self.points
    }

    /// The unit normals (zero where none could be estimated), if any.
    pub fn normals(&self) -> Option<&[Vector3<f64>]> {
        self.normals.as_deref()
    }

    /// The mean of the points (the origin for an empty cloud).
    pub fn centroid(&self) -> Point3<f64> {
        self.centroid
    }

    /// The camera grid, for an organised cloud.
    pub fn grid(&self) -> Option<&PinholeGrid> {
        self.organized.as_ref().map(|o| &o.grid)
    }

    /// Builds the closest-point index now rather than on first use (e.g. to time it apart).
    pub fn build_index(&self) {
        let _ = self.index();
    }

    /// The points and normals as a [`PointCloud`].
    pub fn to_cloud(&self) -> PointCloud {
        let mut c = PointCloud::from_positions(self.points.clone());
        // Same length by construction, so this cannot fail.
        let _ = c.set_normals(self.normals.clone());
        c
    }

    pub(crate) fn index(&self) -> &KdIndex {
        // Cannot fail: `build` checked the point count, and the points are finite.
        self.index
            .get_or_init(|| KdIndex::new(&self.points).unwrap_or_default())
    }

    /// Replaces the normals (one per point; the caller guarantees the length).
    pub(crate) fn replace_normals(&mut self, normals: Option<Vec<Vector3<f64>>>) {
        self.normals = normals;
    }

    pub(crate) fn organized(&self) -> Option<&Organized> {
        self.organized.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drops_non_finite_and_downsamples() {
        let mut pts: Vec<Point3<f64>> = (0..100)
            .map(|i| Point3::new((i % 10) as f64 * 0.1, (i / 10) as f64 * 0.1, 5.0))
            .collect();
        pts.push(Point3::new(f64::NAN, 0.0, 0.0));
        let cloud = PointCloud::from_positions(pts);
        let p = PreparedCloud::new(
            &cloud,
            &PrepareConfig {
                voxel_size: None,
                normals: NormalSource::None,
            },
        )
        .unwrap();
        assert_eq!(p.len(), 100);
        assert!(p.normals().is_none());
        approx::assert_relative_eq!(p.centroid(), Point3::new(0.45, 0.45, 5.0), epsilon = 1e-12);
        let d = PreparedCloud::new(
            &cloud,
            &PrepareConfig {
                voxel_size: Some(0.5),
                normals: NormalSource::None,
            },
        )
        .unwrap();
        assert_eq!(d.len(), 4);
        assert!(matches!(
            PreparedCloud::new(
                &cloud,
                &PrepareConfig {
                    voxel_size: None,
                    normals: NormalSource::FromCloud
                }
            ),
            Err(IcpError::MissingNormals { .. })
        ));
    }

    #[test]
    fn organised_grid_maps_pixels() {
        let grid = PinholeGrid {
            width: 4,
            height: 3,
            fx: 100.0,
            fy: 100.0,
            cx: 1.5,
            cy: 1.0,
        };
        // Pixel (u, v) sees the point on the plane z = 100 that projects onto it.
        let mut pts: Vec<Point3<f64>> = (0..12)
            .map(|i| {
                let (u, v) = ((i % 4) as f64, (i / 4) as f64);
                Point3::new(u - 1.5, v - 1.0, 100.0)
            })
            .collect();
        pts[5] = Point3::new(f64::NAN, f64::NAN, f64::NAN);
        let cloud = PointCloud::from_positions(pts.clone());
        let config = PrepareConfig {
            voxel_size: None,
            normals: NormalSource::None,
        };
        let p = PreparedCloud::from_organized(&cloud, grid, &config).unwrap();
        assert_eq!(p.len(), 11);
        let org = p.organized().unwrap();
        assert_eq!(org.point_at(1, 1), None);
        for (i, q) in pts.iter().enumerate() {
            if i == 5 {
                continue;
            }
            assert_eq!(grid.pixel_of(q), Some((i % 4, i / 4)));
            let j = org.point_at(i % 4, i / 4).unwrap() as usize;
            assert_eq!(p.points()[j], *q);
        }
        assert_eq!(org.point_at(4, 0), None);
        assert_eq!(grid.pixel_of(&Point3::new(0.0, 0.0, -1.0)), None);
        let small = PointCloud::from_positions(pts[..11].to_vec());
        assert!(matches!(
            PreparedCloud::from_organized(&small, grid, &config),
            Err(IcpError::GridSize { found: 11, .. })
        ));
        let bad = PinholeGrid { fx: 0.0, ..grid };
        assert!(PreparedCloud::from_organized(&cloud, bad, &config).is_err());
    }
}
