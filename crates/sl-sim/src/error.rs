//! The one error type of the crate.

use std::path::PathBuf;

use sl_rig::RigError;

/// Everything that can go wrong in `sl-sim`: a bad rig parameter, a bad scene, a file that
/// cannot be written or read, or an error of the device layer (`sl-rig`) below.
///
/// Messages name the parameter, object or file at fault. Through the device traits the
/// virtual devices report [`RigError`]s like real drivers do: `From<SimError> for RigError`
/// hands a device-layer error back as it was and wraps the others as
/// [`RigError::Device`] naming the virtual rig.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A configuration value is out of its valid range.
    #[error("parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Name of the parameter (as the field or command-line option is called).
        name: String,
        /// What is wrong with its value.
        reason: String,
    },
    /// A scene object cannot be built (degenerate size, bad mesh, ...).
    #[error("scene object `{object}`: {reason}")]
    InvalidScene {
        /// Name of the object.
        object: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A file could not be written or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A JSON file could not be written or parsed.
    #[error("{}: {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: serde_json::Error,
    },
    /// A camera or projector model was refused by `sl-camera`.
    #[error(transparent)]
    Camera(#[from] sl_camera::CameraError),
    /// An image of no pixels, or a pixel buffer of the wrong length (`sl-image`).
    #[error(transparent)]
    Image(#[from] sl_image::ImageError),
    /// A pattern sequence, manifest or image file was refused by `sl-codec`.
    #[error(transparent)]
    Codec(#[from] sl_codec::CodecError),
    /// A mesh file was refused by `sl-cloud`.
    #[error(transparent)]
    Cloud(#[from] sl_cloud::CloudError),
    /// The device layer refused an image or a device failed (`sl-rig`).
    #[error(transparent)]
    Rig(#[from] RigError),
}

impl SimError {
    /// Shorthand for [`SimError::InvalidParameter`].
    pub(crate) fn param(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            reason: reason.into(),
        }
    }

    /// Shorthand for [`SimError::InvalidScene`].
    pub(crate) fn scene(object: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidScene {
            object: object.into(),
            reason: reason.into(),
        }
    }

    /// Shorthand for [`SimError::Io`].
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}

impl From<SimError> for RigError {
    fn from(e: SimError) -> Self {
        match e {
            SimError::Rig(e) => e,
            other => RigError::Device {
                device: "virtual rig".to_owned(),
                reason: other.to_string(),
            },
        }
    }
}
