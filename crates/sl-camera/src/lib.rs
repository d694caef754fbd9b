//! Camera and projector models for structured light: pinhole intrinsics, lens distortion
//! exactly as OpenCV defines it, projection and unprojection with analytic Jacobians, rigid
//! poses, and calibration files (this project's JSON and OpenCV FileStorage YAML/XML).
//!
//! A calibration made with OpenCV projects to the same pixels here (checked against
//! `cv2.projectPoints` to 1e-9 px), and unprojection inverts it by Newton's method — also for
//! strong lenses where OpenCV's fixed-point `undistortPoints` fails — and refuses, rather
//! than guesses, where the lens model is not invertible.
//!
//! ```
//! use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
//! use nalgebra::{Point2, Point3};
//!
//! let camera = CameraModel::new(
//!     Intrinsics::new(1440.4, 1437.1, 667.8, 354.2),
//!     Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1])?,
//!     ImageSize::new(1280, 720),
//! )?;
//! // A point 1 m in front of the camera, in millimetres, camera frame.
//! let px = camera.project(&Point3::new(150.0, -90.0, 1000.0)).unwrap();
//! // Back to the normalised ray (x, y, 1).
//! let ray = camera.unproject(&px).unwrap();
//! assert!((ray - Point3::new(0.15, -0.09, 1.0).coords).norm() < 1e-12);
//! // Rays of every pixel, once per calibration, for triangulation.
//! let table = camera.ray_table();
//! assert_eq!(table.valid_count(), 1280 * 720);
//! # Ok::<(), sl_camera::CameraError>(())
//! ```
//!
//! # Conventions
//!
//! * **Axes** as OpenCV: x right, y down, z forward (out of the lens). Points with `z <= 0`
//!   are behind the camera and never project.
//! * **Pixels** as OpenCV: pixel (0, 0) is the *centre* of the top-left pixel, u grows to
//!   the right and v downwards; an image of `width × height` covers
//!   `[-0.5, width - 0.5) × [-0.5, height - 0.5)`.
//! * **Normalised coordinates**: `(x, y) = (X/Z, Y/Z)`, undistorted; a "ray" is `(x, y, 1)`
//!   unless documented as a unit vector. Distortion maps normalised points to *distorted*
//!   normalised points, which the intrinsics map to pixels
//!   (`u = fx·xd + skew·yd + cx`, `v = fy·yd + cy`).
//! * **Units**: millimetres for every translation and 3-D point; pixels for intrinsics and
//!   RMS errors; radians in rotation vectors; degrees where a name ends in `_deg`.
//! * **Poses** are [`nalgebra::Isometry3<f64>`] named `T_a_b`: the pose that maps
//!   coordinates expressed in frame `b` into frame `a`, `p_a = T_a_b * p_b`. So
//!   `T_cam_proj` maps projector coordinates into camera coordinates
//!   (`p_cam = T_cam_proj * p_proj`). OpenCV's `rvec`/`tvec` of a view are `T_cam_world` as
//!   [`RvecTvec`]; SLStudio's `Rp`/`Tp` are `T_proj_cam`.
//! * **Projector** = inverse camera with the same types ([`ProjectorModel`]): its pixels are
//!   those of the projected image.
//! * **f64** for all geometry.
//! * **Validity**: every distortion has a *valid region*, the disc of normalised radius
//!   [`Distortion::max_radius`] on which it is proven one-to-one (radial part strictly
//!   increasing, Jacobian determinant positive, no fold from the tangential terms).
//!   Projection and unprojection return `None` outside it.
//!
//! # Files
//!
//! [`Calibration::load`] / [`Calibration::save`] choose the format from the extension:
//! `.json` (this project's versioned format), `.yml`/`.yaml` and `.xml` (OpenCV FileStorage,
//! layouts of OpenCV's calibration sample and of SLStudio). Malformed files give errors
//! naming the file, the line and the key, e.g.
//! ``calib.yml line 7: key `Kc`: expected 9 values (3x3), found 8``; well-formed files whose
//! camera or projector makes no physical sense are refused naming the device and the key
//! ([`CameraModel::check_physical`]).
#![deny(missing_docs)]

mod binocular;
mod calibration;
mod distortion;
mod error;
mod filestorage;
mod injective;
mod intrinsics;
mod jacobians;
mod layouts;
mod model;
mod monotonic;
mod plausible;
mod pose;
mod ray_table;
mod turntable;

pub use binocular::{BINOCULAR_FORMAT_VERSION, BinocularCalibration};
pub use calibration::{
    CALIBRATION_FORMAT_VERSION, Calibration, CalibrationFormat, Metadata, RmsErrors,
};
pub use distortion::{DISTORTION_PARAMETERS, Distortion, DistortionJacobians, DistortionModel};
pub use error::CameraError;
pub use intrinsics::Intrinsics;
pub use jacobians::{INTRINSIC_PARAMETERS, PoseProjectionJacobians, ProjectionJacobians};
pub use layouts::{CalibrationLayout, LoadConfig, LoadedCalibration};
pub use model::{CameraModel, FieldOfView, PixelJacobian, ProjectorModel};
pub use plausible::{
    Implausibility, MAX_FIELD_OF_VIEW_DEG, MAX_RADIAL_SCALE, MIN_FIELD_OF_VIEW_DEG, ModelParameter,
    ROUND_TRIP_PX,
};
pub use pose::{
    RvecTvec, isometry_from_rt, pose_from_matrix, pose_to_matrix, rotation_from_rvec,
    rotation_jacobian, rvec_from_rotation,
};
pub use ray_table::RayTable;
pub use turntable::TurntableAxis;

/// Size of an image in pixels: the workspace's one image size, defined in `sl-image` and
/// re-exported so camera users need one import.
pub use sl_image::ImageSize;
/// A projector's response curve ([`Calibration::projector_response`]), from `sl-image`.
pub use sl_image::ToneCurve;

/// Re-export of the linear algebra crate used in the public API.
pub use nalgebra;

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
