//! The one error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong in `sl-rig`: a bad parameter, a device that cannot
/// do what it was asked, or a file that cannot be written or read.
///
/// Messages name the parameter, object, frame or file at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RigError {
    /// A configuration value is out of its valid range.
    #[error("parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Name of the parameter (as the field or command-line option is called).
        name: String,
        /// What is wrong with its value.
        reason: String,
    },
    /// An image handed to a device has the wrong size.
    #[error("{what}: expected {expected_width}x{expected_height} pixels, got {width}x{height}")]
    ImageSize {
        /// Which image (e.g. `projector image`, `frame 12`).
        what: String,
        /// Width the device needs.
        expected_width: u32,
        /// Height the device needs.
        expected_height: u32,
        /// Width it got.
        width: u32,
        /// Height it got.
        height: u32,
    },
    /// A pixel buffer does not hold `width × height` values.
    #[error("{what}: {len} pixel values for a {width}x{height} image")]
    BufferLength {
        /// Which image.
        what: String,
        /// Number of values in the buffer.
        len: usize,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
    },
    /// A camera frame's bytes do not hold what its pixel format and size say (a short buffer,
    /// a JPEG that does not decode).
    #[error("{what}: {reason}")]
    FrameData {
        /// Which frame (device and frame number).
        what: String,
        /// What is wrong with its bytes.
        reason: String,
    },
    /// A device could not do what it was asked (a driver's failure, or a device used
    /// out of order).
    #[error("{device}: {reason}")]
    Device {
        /// The device (`camera`, `projector`, `turntable`).
        device: String,
        /// What went wrong.
        reason: String,
    },
    /// A device cannot do what a setting needs (a camera without an exposure control asked
    /// for several exposures).
    #[error("{device} cannot {what}")]
    Unsupported {
        /// The device (`camera`, `camera /dev/video0`, …).
        device: String,
        /// What it was asked to do, and the option that asked for it.
        what: String,
    },
    /// A device was asked for whose driver this build lacks: rebuild with the named cargo
    /// feature of `sl-rig`.
    #[error(
        "{device}: needs the `{feature}` feature of sl-rig (rebuild with `--features {feature}`)"
    )]
    FeatureNotBuilt {
        /// The device (`camera /dev/video0`, `projector on monitor 1`, …).
        device: String,
        /// The cargo feature that builds its driver: `v4l`, `window` or `dynamixel`.
        feature: &'static str,
    },
    /// A file could not be written or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A camera or projector model, or the calibration file, was refused by `sl-camera`.
    #[error(transparent)]
    Camera(#[from] sl_camera::CameraError),
    /// An image of no pixels, or a pixel buffer of the wrong length (`sl-image`).
    #[error(transparent)]
    Image(#[from] sl_image::ImageError),
    /// A pattern sequence, manifest or image file was refused by `sl-codec`.
    #[error(transparent)]
    Codec(#[from] sl_codec::CodecError),
    /// The Dynamixel turntable (serial port, servo, protocol) failed.
    #[cfg(all(feature = "dynamixel", unix))]
    #[error(transparent)]
    Dynamixel(#[from] crate::DynamixelError),
    /// A step of a capture session failed: names the view (and the frame) at fault.
    #[error("capture session: view {view}{}: {source}", frame.map(|f| format!(", frame {f}")).unwrap_or_default())]
    Session {
        /// Index of the view in the session's plan.
        view: usize,
        /// Index of the frame in the view's pattern sequence, when the failure concerns one.
        frame: Option<usize>,
        /// What went wrong.
        #[source]
        source: Box<RigError>,
    },
    /// A session folder already holds a session with another plan.
    #[error("{}: {reason}", path.display())]
    SessionMismatch {
        /// The existing `session.json`.
        path: PathBuf,
        /// What differs.
        reason: String,
    },
    /// A JSON file could not be written or parsed.
    #[error("{}: {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: serde_json::Error,
    },
}

impl RigError {
    /// Shorthand for [`RigError::InvalidParameter`].
    pub(crate) fn param(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            reason: reason.into(),
        }
    }

    /// This error, raised by the second camera of a binocular rig, named as it: `device` is
    /// the right camera's record (its path). A feature it lacks stays
    /// [`RigError::FeatureNotBuilt`]; anything else becomes [`RigError::Device`] whose device
    /// begins with `right camera`, so the message says which of the two cameras failed.
    pub(crate) fn of_right_camera(self, device: &str) -> Self {
        let device = format!("right camera {device}");
        match self {
            Self::FeatureNotBuilt { feature, .. } => Self::FeatureNotBuilt { device, feature },
            other => Self::Device {
                device,
                reason: other.to_string(),
            },
        }
    }

    /// Shorthand for [`RigError::Io`].
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}
