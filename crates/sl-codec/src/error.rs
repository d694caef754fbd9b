//! The one error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong in `sl-codec`.
///
/// Every variant names what is at fault: the file, the manifest key (as a JSON path such as
/// `blocks[2].periods`), the frame (by file name or index), or the parameter.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CodecError {
    /// The operating system refused to read or write a file.
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// What we were doing (`"read"`, `"write"`, `"create directory"`, ...).
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// An image file could not be decoded or encoded.
    #[cfg(feature = "image-files")]
    #[error("{path}: image {action} failed: {source}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// `"decode"` or `"encode"`.
        action: &'static str,
        /// The underlying error.
        #[source]
        source: image::ImageError,
    },
    /// An image file decoded to an image of no pixels.
    #[error("{path}: the image is empty (0 pixels wide or high)")]
    EmptyImage {
        /// The image file.
        path: PathBuf,
    },
    /// A frame listed in the manifest does not exist.
    #[error(
        "{manifest}: frame {index} of block {block} ('{file}') is missing: {path} does not exist \
         (nor under another image extension)"
    )]
    MissingFrame {
        /// The manifest that lists the frame.
        manifest: PathBuf,
        /// Index of the block (0-based) in `blocks`.
        block: usize,
        /// Index of the frame (0-based) inside the block.
        index: usize,
        /// The file name as written in the manifest.
        file: String,
        /// The path that was looked for.
        path: PathBuf,
    },
    /// A frame listed in the manifest names something that is not a regular file (a folder, a
    /// device, a FIFO: see [`not_a_regular_file`](crate::not_a_regular_file)).
    #[error("{manifest}: frame {index} of block {block} cannot be read: {path} {what}")]
    FrameNotAFile {
        /// The manifest that lists the frame.
        manifest: PathBuf,
        /// Index of the block (0-based) in `blocks`.
        block: usize,
        /// Index of the frame (0-based) inside the block.
        index: usize,
        /// The path looked at (the frames' folder joined with the file name the manifest
        /// gives).
        path: PathBuf,
        /// What is there: `is a directory`, `is not a regular file (a character device)`, …
        what: String,
    },
    /// A path given as an image file is not a regular file (a folder, a device, a FIFO: see
    /// [`not_a_regular_file`](crate::not_a_regular_file)); it is not opened.
    #[error("{path} {what}")]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What is there: `is a directory`, `is not a regular file (a character device)`, …
        what: String,
    },
    /// The manifest is not valid JSON.
    #[error("{path}: not valid JSON: {source}")]
    ManifestJson {
        /// The manifest file.
        path: PathBuf,
        /// The parser's error (it names the line and column).
        #[source]
        source: serde_json::Error,
    },
    /// The manifest is valid JSON but a key is missing, unknown or has a bad value.
    #[error("{path}: {key}: {message}")]
    Manifest {
        /// The manifest file (or `<memory>`).
        path: PathBuf,
        /// JSON path of the offending key, e.g. `blocks[1].steps`.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// A pattern or decoder parameter is out of its domain.
    #[error("parameter '{name}': {message}")]
    Parameter {
        /// The parameter at fault (a field name such as `steps` or `periods[2]`).
        name: String,
        /// What is wrong.
        message: String,
    },
    /// A block was given the wrong number of frames.
    #[error("{codec} block on axis {axis}: expected {expected} frames, got {found}")]
    FrameCount {
        /// The codec of the block (`"gray"`, `"phase"`, `"hybrid"`).
        codec: &'static str,
        /// The axis of the block (`"column"` or `"row"`).
        axis: &'static str,
        /// Number of frames the block's parameters imply.
        expected: usize,
        /// Number of frames given.
        found: usize,
    },
    /// A frame does not have the size of the first frame of the capture.
    #[error(
        "frame {frame}: size {found_width}x{found_height} differs from {expected_width}x{expected_height} of the first frame"
    )]
    FrameSize {
        /// The frame (file name, or `#index` for in-memory frames).
        frame: String,
        /// Width of the first frame.
        expected_width: usize,
        /// Height of the first frame.
        expected_height: usize,
        /// Width of this frame.
        found_width: usize,
        /// Height of this frame.
        found_height: usize,
    },
    /// A raw pixel buffer does not hold `width * height` samples.
    #[error("frame {frame}: buffer holds {found} samples, {width}x{height} needs {expected}")]
    FrameBuffer {
        /// The frame (file name, or `#index` for in-memory frames).
        frame: String,
        /// Width claimed.
        width: usize,
        /// Height claimed.
        height: usize,
        /// `width * height`.
        expected: usize,
        /// Length of the buffer.
        found: usize,
    },
    /// The frames of a capture mix 8-bit and 16-bit samples in a way the decoder cannot use,
    /// or a decoder was given no frames at all.
    #[error("{0}")]
    Frames(String),
}

/// A frame's dimension or buffer error becomes [`CodecError::Parameter`] or
/// [`CodecError::FrameBuffer`] (frame `<memory>`), as when `Frame` was this crate's.
impl From<sl_image::ImageError> for CodecError {
    fn from(e: sl_image::ImageError) -> Self {
        match e {
            sl_image::ImageError::InvalidParameter { name, reason } => Self::Parameter {
                name,
                message: reason,
            },
            sl_image::ImageError::BufferLength {
                width,
                height,
                expected,
                found,
            } => Self::FrameBuffer {
                frame: "<memory>".into(),
                width,
                height,
                expected,
                found,
            },
            other => Self::Parameter {
                name: "image".into(),
                message: other.to_string(),
            },
        }
    }
}

impl CodecError {
    /// Shorthand for [`CodecError::Parameter`].
    pub(crate) fn parameter(name: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Parameter {
            name: name.into(),
            message: message.into(),
        }
    }

    /// Shorthand for [`CodecError::Io`].
    pub(crate) fn io(
        path: impl Into<PathBuf>,
        action: &'static str,
        source: std::io::Error,
    ) -> Self {
        Self::Io {
            path: path.into(),
            action,
            source,
        }
    }
}
