//! Point clouds for structured-light scanning: the [`PointCloud`] container, PLY reading and
//! writing, voxel-grid downsampling, nearest-neighbour search, normal estimation and outlier
//! removal.
//!
//! ```
//! use nalgebra::{Point3, Vector3};
//! use sl_cloud::{
//!     estimate_normals, read_ply_from_bytes, voxel_downsample, write_ply_to_bytes, NormalConfig,
//!     NormalOrientation, PlyFormat, PointCloud, VoxelGridConfig,
//! };
//!
//! // A 40 x 40 mm patch of the plane z = 300 mm, sampled every 0.5 mm, seen from the camera.
//! let pts: Vec<_> = (0..6400)
//!     .map(|i| Point3::new((i % 80) as f64 * 0.5, (i / 80) as f64 * 0.5, 300.0))
//!     .collect();
//! let cloud = PointCloud::from_positions(pts);
//!
//! // 2 mm voxels: 20 x 20 points left.
//! let down = voxel_downsample(&cloud, &VoxelGridConfig { voxel_size: 2.0 })?.cloud;
//! assert_eq!(down.len(), 400);
//!
//! // Normals face the camera at the origin, i.e. -z.
//! let est = estimate_normals(&down, &NormalConfig::default())?;
//! assert!(est.normals.iter().all(|n| (n - (-Vector3::z())).norm() < 1e-9));
//! let down = down.with_normals(est.normals)?;
//!
//! // PLY round trip (binary little-endian, double: exact).
//! let bytes = write_ply_to_bytes(&down, PlyFormat::default());
//! assert_eq!(read_ply_from_bytes(&bytes)?, down);
//! # Ok::<(), sl_cloud::CloudError>(())
//! ```
//!
//! # Conventions
//!
//! - Geometry is `f64`: positions are [`nalgebra::Point3<f64>`], normals
//!   [`nalgebra::Vector3<f64>`] of unit length (the zero vector marks "no normal"). Colours are
//!   `[u8; 3]` RGB, quality is `f32`.
//! - Units are those of the positions: the scanner works in millimetres (camera frame: x right,
//!   y down, z forward, as OpenCV), the Stanford scans are in metres. Every length parameter
//!   (voxel size, radius) is in the cloud's units; defaults assume millimetres.
//! - Poses are [`nalgebra::Isometry3<f64>`]; [`PointCloud::transform`] with `T_world_cam` maps a
//!   cloud from the camera frame into the world frame.
//! - Points with a NaN or infinite coordinate are carried along by the container but ignored
//!   by statistics ([`PointCloud::bounding_box`], [`PointCloud::centroid`]), by the index and by
//!   the algorithms (they get zero normals and are removed as outliers).
//! - All heavy loops run on the global rayon pool.

#![deny(missing_docs)]

mod cloud;
mod degenerate;
mod error;
mod fit;
mod measure;
mod morton;
mod neighbours;
mod normals;
mod outliers;
mod ply;
mod preview;
mod sym_eigen;
mod units;
mod voxel;

pub use cloud::{Aabb, MergePolicy, PointCloud};
pub use degenerate::{CloudNeeds, Degeneracy, check_cloud, degeneracy};
pub use error::CloudError;
pub use fit::{PlaneFit, SphereFit, fit_plane, fit_sphere};
pub use measure::sample_surface;
pub use morton::morton_order;
pub use neighbours::{KdIndex, Neighbour};
pub use normals::{
    LocalPlane, NormalConfig, NormalEstimate, NormalOrientation, estimate_normals,
    estimate_normals_with_index, fit_local_plane,
};
pub use outliers::{
    FarPointConfig, FarPoints, RadiusOutlierConfig, RadiusOutliers, StatisticalOutlierConfig,
    StatisticalOutliers, remove_far_points, remove_radius_outliers, remove_statistical_outliers,
};
pub use ply::header::read_ply_header;
pub use ply::mesh::{
    RANGE_GRID_MAX_EDGE_FACTOR, TriangleMesh, read_ply_mesh, read_ply_mesh_from_bytes,
};
pub use ply::read::{read_ply, read_ply_from_bytes, read_ply_from_reader};
pub use ply::write::{write_ply, write_ply_to_bytes, write_ply_to_writer};
pub use ply::{
    PlyElement, PlyEncoding, PlyFormat, PlyHeader, PlyProperty, PlyPropertyKind, PlyScalar,
    PlyScalarType,
};
pub use preview::{
    FRAME_PERCENTILE, FRAME_SLACK, PreviewColoring, PreviewConfig, PreviewImage, colormap,
    render_preview,
};
pub use units::{check_millimetres, read_ply_scaled, with_normals_towards};
pub use voxel::{VoxelDownsample, VoxelGridConfig, voxel_downsample};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
