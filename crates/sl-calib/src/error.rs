//! The one error type of the crate.

use sl_camera::CameraError;

/// Everything that can go wrong while detecting a board or calibrating.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
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
    /// Too few decoded pixels around a board corner to map it into the projector.
    #[error(
        "{frame}: corner {corner}: {decoded} decoded pixels around it, {needed} needed (is the projector lighting the whole board? is the decoding threshold too strict?)"
    )]
    SparseCorner {
        /// The view (frame) name.
        frame: String,
        /// Index of the corner in board order.
        corner: usize,
        /// Decoded pixels found in its window.
        decoded: usize,
        /// Decoded pixels required.
        needed: usize,
    },
    /// One named view of a projector–camera calibration is malformed.
    #[error("{frame}: {reason}")]
    Frame {
        /// The view (frame) name.
        frame: String,
        /// What is wrong with it.
        reason: String,
    },
    /// Too few turntable views (motor readings) with a board.
    #[error(
        "turntable: {found} views with a board, at least {needed} needed (capture the board on the platter at more motor angles)"
    )]
    TooFewAngles {
        /// Views given.
        found: usize,
        /// Views required.
        needed: usize,
    },
    /// The motor readings of the turntable views span too small an angle.
    #[error(
        "turntable: the motor angles span {span_deg:.2} degrees, at least {needed_deg} needed (turn the platter further between the first and last view)"
    )]
    AngleSpan {
        /// Span of the readings (degrees).
        span_deg: f64,
        /// Span required (degrees).
        needed_deg: f64,
    },
    /// The board was not found in the image of a turntable view.
    #[error("turntable view at motor angle {motor_angle_deg} degrees: {source}")]
    BoardNotFoundAtAngle {
        /// The motor reading of the view.
        motor_angle_deg: f64,
        /// The detector's error, which names the image.
        source: Box<CalibError>,
    },
    /// An error of the camera model (e.g. an estimate outside the model's valid range).
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// An image file that `sl-codec`'s reader could not read or decode, or found empty
    /// ([`load_grey`](crate::load_grey)); the message names the file.
    #[error(transparent)]
    Codec(#[from] sl_codec::CodecError),
    /// An image built from a buffer that does not hold its `width × height` pixels
    /// (`sl_codec::Frame::new`), or of no pixel.
    #[error(transparent)]
    Image(#[from] sl_codec::ImageError),
}

impl CalibError {
    pub(crate) fn param(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            reason: reason.into(),
        }
    }
}
