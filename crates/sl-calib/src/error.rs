//! The one error type of the crate.

use sl_camera::CameraError;

/// Everything that can go wrong while detecting a board or calibrating.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    /// An image file could not be read or decoded.
    #[error("image {file}: {source}")]
    Image {
        /// The file at fault.
        file: String,
        /// What the decoder said.
        source: image::ImageError,
    },
    /// The checkerboard was not found in an image; `reason` says why.
    #[error("{image}: checkerboard {cols}x{rows} not found: {reason}")]
    BoardNotFound {
        /// The image (file name or view label).
        image: String,
        /// Inner corners per row that were searched for.
        cols: u32,
        /// Inner corners per column that were searched for.
        rows: u32,
        /// Why the search failed.
        reason: String,
    },
    /// A parameter of a configuration or an input is out of range.
    #[error("parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Name of the parameter.
        name: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The calibration input cannot determine the parameters; the message says what to
    /// capture instead.
    #[error("degenerate calibration input: {0}")]
    Degenerate(String),
    /// One view of a calibration is malformed (wrong corner count, non-finite values, ...).
    #[error("view {view}: {reason}")]
    View {
        /// Index of the view.
        view: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// An error of the camera model (e.g. an estimate outside the model's valid range).
    #[error(transparent)]
    Camera(#[from] CameraError),
}

impl CalibError {
    pub(crate) fn param(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            reason: reason.into(),
        }
    }
}
