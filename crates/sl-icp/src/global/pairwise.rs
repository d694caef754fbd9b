//! Global registration of one pair: descriptors, matches, RANSAC, then ICP.

use nalgebra::Isometry3;
use sl_cloud::PointCloud;

use crate::global::correspondences::{FeatureIndex, MatchConfig, match_features};
use crate::global::fpfh::{Fpfh, FpfhConfig, Neighbourhoods, fpfh_of_neighbourhoods};
use crate::global::orientation::orient_normals_outward;
use crate::global::ransac::{RansacConfig, RansacResult, ransac_pose};
use crate::{
    IcpConfig, IcpError, Metric, NormalSource, PrepareConfig, PreparedCloud, Registration, register,
};

/// Fewest points a downsampled cloud must keep to be described by [`GlobalCloud`]: a few FPFH
/// neighbourhoods' worth. Below this the cloud is a speck on the voxel grid (a cloud in metres
/// read as mm). A cloud of fewer points, downsampled or not, cannot be aligned globally.
pub const MIN_GLOBAL_POINTS: usize = 50;

/// A cloud whose bounding box diagonal is below this many voxels is taken for one in metres:
/// any object worth registering spans tens of voxels (a 2 mm voxel on a 100 mm object), while
/// the same object in metres spans 0.1 "mm", a twentieth of a voxel.
const METRES_EXTENT_VOXELS: f64 = 1.0;

/// Settings of [`register_global`] and of the clouds it describes ([`GlobalCloud`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalConfig {
    /// Voxel size of the downsampling before descriptors, mm. Default 2 mm (Open3D's
    /// examples use 5 cm for rooms; 2 mm keeps a 100 mm object's shape in ~5,000 points).
    pub voxel_size: f64,
    /// Neighbours for the normals of the downsampled cloud (the point included), taken from
    /// its FPFH neighbourhood (fewer where that holds fewer). Default 16: about a 4 mm
    /// neighbourhood on a 2 mm grid (Open3D's examples use a radius of 2 voxels).
    pub normal_neighbours: usize,
    /// The descriptors. Default radius 10 mm (5 voxels).
    pub fpfh: FpfhConfig,
    /// Matching in descriptor space.
    pub matching: MatchConfig,
    /// The robust pose estimate.
    pub ransac: RansacConfig,
    /// The final ICP from the RANSAC pose, on the downsampled clouds. Default point-to-plane
    /// with a 3 mm gate (the RANSAC inlier distance: the RANSAC pose is that good).
    pub icp: IcpConfig,
}

impl Default for GlobalConfig {
    fn default() -> Self {
        Self {
            voxel_size: 2.0,
            normal_neighbours: 16,
            fpfh: FpfhConfig::default(),
            matching: MatchConfig::default(),
            ransac: RansacConfig::default(),
            icp: IcpConfig {
                metric: Metric::PointToPlane,
                max_correspondence_distance: 3.0,
                ..IcpConfig::default()
            },
        }
    }
}

impl GlobalConfig {
    /// Checks every field, naming the first one out of range.
    ///
    /// # Errors
    /// [`IcpError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), IcpError> {
        if !(self.voxel_size.is_finite() && self.voxel_size > 0.0) {
            return Err(IcpError::invalid(
                "voxel_size",
                self.voxel_size,
                "must be finite and > 0 (mm)",
            ));
        }
        if self.normal_neighbours < 3 {
            return Err(IcpError::invalid(
                "normal_neighbours",
                self.normal_neighbours,
                "a plane needs at least 3",
            ));
        }
        self.fpfh.validate()?;
        self.matching.validate()?;
        self.ransac.validate()?;
        self.icp.validate()?;
        if self.icp.metric != Metric::PointToPoint && self.icp.metric != Metric::PointToPlane {
            return Err(IcpError::invalid(
                "icp.metric",
                self.icp.metric.name(),
                "global registration refines with point-to-point or point-to-plane",
            ));
        }
        Ok(())
    }
}

/// A cloud made ready for global registration: downsampled, with normals whose sign depends
/// on its shape only (see [`orient_normals_outward`](crate::orient_normals_outward)), its FPFH
/// descriptors and their search index ([`FeatureIndex`]). Build it once per cloud and match it
/// with any other.
#[derive(Debug, Clone)]
pub struct GlobalCloud {
    prepared: PreparedCloud,
    features: Vec<Fpfh>,
    index: FeatureIndex,
    one_sided: bool,
}

impl GlobalCloud {
    /// Downsamples `cloud`, estimates and orients normals, computes the descriptors. `name`
    /// names the cloud in errors.
    ///
    /// # Errors
    /// [`IcpError::InvalidParameter`]; [`sl_cloud::CloudError::Degenerate`] (as
    /// [`IcpError::Cloud`]) for a cloud of no finite point, of fewer than
    /// [`MIN_GLOBAL_POINTS`], or all at one place; [`IcpError::EmptyCloud`], and
    /// [`IcpError::CloudTooSmall`] when too few points remain (with a hint when the cloud
    /// looks like one in metres).
    pub fn new(cloud: &PointCloud, config: &GlobalConfig, name: &str) -> Result<Self, IcpError> {
        config.validate()?;
        // A cloud that spans nothing whatever its units is said to be that, not a speck on the
        // voxel grid in metres.
        if let Some(reason) = sl_cloud::degeneracy(cloud, MIN_GLOBAL_POINTS, "global registration")
        {
            return Err(sl_cloud::CloudError::Degenerate {
                file: name.to_owned(),
                reason,
            }
            .into());
        }
        let mut prepared = PreparedCloud::new(
            cloud,
            &PrepareConfig {
                voxel_size: Some(config.voxel_size),
                normals: NormalSource::None,
            },
        )?;
        if prepared.is_empty() {
            return Err(IcpError::EmptyCloud {
                cloud: name.to_owned(),
            });
        }
        if prepared.len() < MIN_GLOBAL_POINTS {
            let extent = cloud
                .remove_non_finite()
                .bounding_box()
                .map_or(0.0, |b| b.extent().norm());
            return Err(IcpError::CloudTooSmall {
                cloud: name.to_owned(),
                extent_mm: extent,
                points: prepared.len(),
                needed: MIN_GLOBAL_POINTS,
                voxel_size: config.voxel_size,
                hint: if extent < METRES_EXTENT_VOXELS * config.voxel_size {
                    ": it is almost surely in metres (scale it by 1000)"
                } else {
                    ""
                },
            });
        }
        // One neighbour search serves the normals and the descriptors: the 16 nearest of a
        // point lie well inside its 10 mm FPFH ball.
        let hoods = Neighbourhoods::new(prepared.points(), &config.fpfh);
        let mut normals = hoods.nearest_normals(prepared.points(), config.normal_neighbours);
        let one_sided = orient_normals_outward(prepared.points(), &mut normals);
        let features = fpfh_of_neighbourhoods(&normals, &hoods);
        prepared.replace_normals(Some(normals));
        let index = FeatureIndex::new(&features);
        Ok(Self {
            prepared,
            features,
            index,
            one_sided,
        })
    }

    /// The downsampled cloud with its oriented normals.
    pub fn prepared(&self) -> &PreparedCloud {
        &self.prepared
    }

    /// One descriptor per point of [`prepared`](Self::prepared).
    pub fn features(&self) -> &[Fpfh] {
        &self.features
    }

    /// The descriptors laid out for matching.
    pub fn feature_index(&self) -> &FeatureIndex {
        &self.index
    }

    /// Whether the cloud was taken for a one-sided view (normals made to face one side)
    /// rather than a closed model (normals facing away from the centroid).
    pub fn one_sided(&self) -> bool {
        self.one_sided
    }
}

/// Result of [`register_global`].
#[derive(Debug, Clone, PartialEq)]
pub struct GlobalRegistration {
    /// `T_target_source` after the final ICP.
    pub pose: Isometry3<f64>,
    /// The final ICP (its fitness and RMSE measure the overlap at `pose`, on the downsampled
    /// clouds).
    pub registration: Registration,
    /// The RANSAC estimate the ICP started from.
    pub ransac: RansacResult,
    /// Descriptor matches RANSAC drew from.
    pub correspondences: usize,
}

/// Registers `source` onto `target` with no initial pose: [`GlobalCloud::new`] for both (in
/// parallel), then [`register_global_prepared`].
///
/// # Errors
/// As [`GlobalCloud::new`] (naming `"source"` or `"target"`) and
/// [`register_global_prepared`].
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use sl_icp::{register_global, GlobalConfig, PointCloud};
/// // A bumpy blob (about 80 mm across) and the same blob turned by 120° and moved 50 mm.
/// let blob: Vec<Point3<f64>> = (0..20000).map(|i| {
///     let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
///     let y = 1.0 - 2.0 * (i as f64 + 0.5) / 20000.0;
///     let (r, t) = ((1.0 - y * y).sqrt(), golden * i as f64);
///     let d = Vector3::new(r * t.cos(), y, r * t.sin());
///     let bump = 6.0 * (3.0 * d.x).sin() * (2.0 * d.y + 0.5).cos() + 5.0 * (4.0 * d.z * d.x).sin() + 8.0 * (d.y - 0.6).max(0.0);
///     Point3::from(d * (40.0 + bump))
/// }).collect();
/// let truth = Isometry3::new(Vector3::new(50.0, -10.0, 5.0), Vector3::new(0.0, 2.1, 0.4));
/// let moved: Vec<Point3<f64>> = blob.iter().map(|p| truth.inverse() * p).collect();
/// let r = register_global(&PointCloud::from_positions(moved), &PointCloud::from_positions(blob), &GlobalConfig::default())?;
/// assert!(r.pose.rotation.angle_to(&truth.rotation).to_degrees() < 0.5);
/// assert!((r.pose.translation.vector - truth.translation.vector).norm() < 1.0);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
pub fn register_global(
    source: &PointCloud,
    target: &PointCloud,
    config: &GlobalConfig,
) -> Result<GlobalRegistration, IcpError> {
    let (s, t) = rayon::join(
        || GlobalCloud::new(source, config, "source"),
        || GlobalCloud::new(target, config, "target"),
    );
    register_global_prepared(&s?, &t?, config, ("source", "target"))
}

/// Registers two described clouds: descriptor matches, RANSAC, then ICP from the RANSAC pose
/// on the downsampled clouds. `names` (source, target) name the clouds in errors.
///
/// # Errors
/// [`IcpError::GlobalRegistrationFailed`] when there are too few matches or no RANSAC
/// hypothesis with enough inliers; the errors of [`register`] for the final ICP.
pub fn register_global_prepared(
    source: &GlobalCloud,
    target: &GlobalCloud,
    config: &GlobalConfig,
    names: (&str, &str),
) -> Result<GlobalRegistration, IcpError> {
    config.validate()?;
    let failed =
        |correspondences: usize, reason: &'static str| IcpError::GlobalRegistrationFailed {
            source_cloud: names.0.to_owned(),
            target_cloud: names.1.to_owned(),
            correspondences,
            reason,
        };
    let matches = match_features(
        &source.features,
        &source.index,
        &target.features,
        &target.index,
        &config.matching,
    )?;
    let n = matches.len();
    let Some(ransac) = ransac_pose(
        source.prepared.points(),
        target.prepared.points(),
        &matches,
        &config.ransac,
    )?
    else {
        return Err(failed(
            n,
            "no RANSAC hypothesis with enough inliers (too little overlap, or too few distinctive shapes)",
        ));
    };
    let registration = register(
        &source.prepared,
        &target.prepared,
        &ransac.pose,
        &config.icp,
    )?;
    Ok(GlobalRegistration {
        pose: registration.pose,
        registration,
        ransac,
        correspondences: n,
    })
}
