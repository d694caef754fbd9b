//! The one error type of the crate.

/// Everything that can go wrong in `sl-image`: an image of no pixels, or a buffer that does
/// not hold the pixels its size claims.
///
/// The crates above convert it into their own error (`sl_camera::CameraError`,
/// `sl_codec::CodecError`, …) with `From`, so `?` carries it up; messages keep naming the
/// parameter at fault (`width`, `height`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ImageError {
    /// A dimension is out of its domain (zero, or a product that overflows `usize`).
    #[error("parameter `{name}`: {reason}")]
    InvalidParameter {
        /// The parameter at fault (`width`, `height`, or `width/height`).
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// A pixel buffer does not hold `width * height` samples.
    #[error("buffer holds {found} samples, {width}x{height} needs {expected}")]
    BufferLength {
        /// Width claimed.
        width: usize,
        /// Height claimed.
        height: usize,
        /// `width * height`.
        expected: usize,
        /// Length of the buffer.
        found: usize,
    },
}

impl ImageError {
    /// Shorthand for [`ImageError::InvalidParameter`].
    pub(crate) fn invalid(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            reason: reason.into(),
        }
    }
}
