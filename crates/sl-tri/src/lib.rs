//! Triangulation of structured-light correspondences into metric point clouds.
//!
//! A decoder (`sl-codec`) tells, for every camera pixel, which projector column and row lit
//! it; with the calibration (`sl-camera`) each such pair is a 3-D point. This crate turns a
//! [`CorrespondenceMap`] into points in millimetres, as accurately as the data allows:
//!
//! - [`Triangulator`] is built once per calibration: the undistorted ray of every camera
//!   pixel and the pose both ways are precomputed (decoded projector points are undistorted
//!   per pixel, by a vectorised Newton iteration, only by the methods that need both
//!   coordinates).
//! - Four methods ([`Method`]): **ray–plane** with one decoded coordinate, intersecting the
//!   camera ray with the projector's *exact* column (or row) surface — curved by the
//!   projector's distortion — by Newton's method on the distorted projection; **linear**
//!   least squares (DLT); the **midpoint** of the two rays; and **optimal**, the minimum of
//!   the squared reprojection errors in camera and projector by Gauss–Newton.
//! - Filters ([`TriConfig`]): decode quality, depth range, reprojection error, mixed pixels
//!   at depth discontinuities.
//! - Output ([`Triangulation`]): the organised per-pixel points, reprojection errors and
//!   statuses, and an `sl-cloud` [`PointCloud`] with quality, colours from a fully lit frame
//!   ([`Texture`]) and normals from the pixel grid; depth maps as 16-bit PNG
//!   ([`write_depth_png16`]) or float TIFF ([`write_depth_tiff`]).
//! - Least-squares [`fit_plane`] and [`fit_sphere`] for accuracy measurements.
//!
//! `docs/triangulation.md` compares the methods in accuracy and speed on the virtual rig.
//!
//! ```
//! use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
//! use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
//! use sl_codec::CorrespondenceMap;
//! use sl_tri::{Method, TriConfig, Triangulator};
//!
//! // A small camera and a projector 100 mm to its right, toed in by 12 degrees.
//! let camera = CameraModel::new(
//!     Intrinsics::new(80.0, 80.0, 31.5, 23.5),
//!     Distortion::from_opencv(&[-0.05, 0.02, 0.0, 0.0, 0.0])?,
//!     ImageSize::new(64, 48),
//! )?;
//! let projector = CameraModel::new(
//!     Intrinsics::new(120.0, 120.0, 63.5, 39.5),
//!     Distortion::from_opencv(&[0.04, -0.05, 0.0, 0.0, 0.0])?,
//!     ImageSize::new(128, 80),
//! )?;
//! let t_cam_proj = Isometry3::from_parts(
//!     Translation3::new(100.0, 0.0, 0.0),
//!     UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -12f64.to_radians()),
//! );
//! let tri = Triangulator::from_models(&camera, &projector, &t_cam_proj)?;
//!
//! // What the decoder would report for a wall at z = 400 mm.
//! let mut map = CorrespondenceMap::new(64, 48);
//! let t_proj_cam = t_cam_proj.inverse();
//! for y in 0..48 {
//!     for x in 0..64 {
//!         let ray = tri.camera_rays().get(x, y).unwrap();
//!         let p_cam = Point3::from(ray * 400.0);
//!         let px = projector.project(&(t_proj_cam * p_cam)).unwrap();
//!         let i = (y * 64 + x) as usize;
//!         map.col[i] = px.x as f32;
//!         map.row[i] = px.y as f32;
//!     }
//! }
//! // Ray–plane on the columns (the default); Optimal uses both coordinates.
//! for method in [Method::default(), Method::Optimal] {
//!     let result = tri.triangulate(&map, &TriConfig::with_method(method))?;
//!     assert_eq!(result.counts.valid, 64 * 48);
//!     // f32 coordinates (6e-5 px) limit the depth to ~1e-3 mm here.
//!     assert!(result.points.iter().all(|p| (p.z - 400.0).abs() < 2e-2));
//! }
//! # Ok::<(), sl_tri::TriError>(())
//! ```
//!
//! # Conventions
//!
//! - Camera and projector frames as OpenCV: x right, y down, z forward; the projector is an
//!   inverse camera. Points and clouds are in the **camera frame**, in **millimetres**.
//! - Pixel `(0, 0)` is the centre of the top-left pixel; a decoded column `c` is the
//!   projector coordinate `x = c` in this convention (as `sl-codec` writes it).
//! - `T_cam_proj` maps projector coordinates into camera coordinates (as in
//!   `sl_camera::Calibration`); depth is the camera `z`.
//! - Per-pixel vectors are row-major, pixel `(x, y)` at `y · width + x`; NaN where there is
//!   no value.
//! - Geometry in `f64`; per-pixel maps and errors that are written to images in `f32`.
//! - Reprojection errors are in pixels: the RMS over camera and projector of the image
//!   distance between the projected point and the observation.
#![deny(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is true for NaN, which must be rejected as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// The lane kernels index several fixed-size arrays with one lane index on purpose: that is
// the form the compiler vectorises.
#![allow(clippy::needless_range_loop)]

mod binocular;
mod camera_rays;
mod depth;
mod error;
mod fit;
mod grid_normals;
mod kernel;
mod linear;
mod midpoint;
mod mixed_pixels;
mod optimal;
mod options;
mod ray_plane;
mod stereo;
mod triangulation;
mod triangulator;
mod undistort;

pub use binocular::{Binocular, BinocularConfig, BinocularCounts, BinocularResult};
pub use depth::{
    DEPTH_PNG_SCALE_MM, check_depth_png_scale, depth_png_scale_range, depth_to_u16,
    write_depth_png16, write_depth_tiff,
};
pub use error::TriError;
pub use fit::{PlaneFit, SphereFit, fit_plane, fit_sphere};
pub use options::{
    DEFAULT_MAX_DEPTH_JUMP, DEFAULT_MAX_REPROJECTION_PX, DEFAULT_OPTIMAL_ITERATIONS, Method,
    Texture, TriConfig,
};
pub use triangulation::{PointStatus, TriCounts, Triangulation};
pub use triangulator::Triangulator;

/// Re-exports of the types of the lower crates in this crate's API, so that one import does.
pub use sl_camera::{Calibration, CameraModel};
pub use sl_cloud::PointCloud;
pub use sl_codec::{Axis, CorrespondenceMap};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
