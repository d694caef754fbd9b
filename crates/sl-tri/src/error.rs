//! The one error type of the crate.

use sl_camera::CameraError;
use sl_cloud::CloudError;
use sl_codec::{Axis, CodecError};

/// Everything that can go wrong in `sl-tri`.
///
/// Messages name what is at fault: the calibration entry, the map and its size, the option,
/// or the file (through the errors of the lower crates).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TriError {
    /// The calibration lacks what triangulation needs.
    #[error(
        "calibration: missing `{what}` (triangulation needs a projector model and `t_cam_proj`)"
    )]
    MissingCalibration {
        /// `projector` or `t_cam_proj`.
        what: &'static str,
    },

    /// An input does not have the size of the calibrated camera.
    #[error("{what}: size {found} does not match the camera's {expected}")]
    SizeMismatch {
        /// The input (`correspondence map`, `texture`).
        what: &'static str,
        /// Size the camera calibration expects, `WxH` or a length.
        expected: String,
        /// Size found.
        found: String,
    },

    /// The method needs a projector axis that the correspondence map does not code (a
    /// column-only capture triangulated by the midpoint of two rays, or ray–plane on the
    /// axis that was not coded).
    #[error(
        "method `{method}` needs the projector {}s, but the correspondence map codes only the {}s \
         (ray_plane on the {}s, linear and optimal work with one axis)",
        missing.name(),
        present.name(),
        present.name()
    )]
    MissingAxis {
        /// The method's name ([`crate::Method::name`]).
        method: &'static str,
        /// The axis it needs and the map lacks.
        missing: Axis,
        /// The axis the map codes.
        present: Axis,
    },

    /// An option is out of range.
    #[error("option `{parameter}`: {message}")]
    InvalidParameter {
        /// The option.
        parameter: &'static str,
        /// What is wrong with it.
        message: String,
    },

    /// A least-squares fit got too few usable points, or points in a degenerate arrangement.
    #[error("{what} fit: {message}")]
    Fit {
        /// `plane` or `sphere`.
        what: &'static str,
        /// What is wrong (counts, degeneracy).
        message: String,
    },

    /// An error of `sl-camera` (calibration files, models).
    #[error(transparent)]
    Camera(#[from] CameraError),

    /// An error of `sl-codec` (writing depth maps).
    #[error(transparent)]
    Codec(#[from] CodecError),

    /// An error of `sl-cloud` (building the cloud).
    #[error(transparent)]
    Cloud(#[from] CloudError),
}

impl TriError {
    pub(crate) fn param(parameter: &'static str, message: impl Into<String>) -> Self {
        Self::InvalidParameter {
            parameter,
            message: message.into(),
        }
    }
}
