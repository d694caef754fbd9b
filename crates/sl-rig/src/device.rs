//! The device traits that every driver implements, and capture code written once against
//! them.

use crate::{ColourImage, GreyImage, RigError};

/// A camera that captures grey frames.
pub trait Camera {
    /// Frame size in pixels, `(width, height)`.
    fn frame_size(&self) -> (u32, u32);

    /// Captures one frame of what the camera sees now.
    fn capture(&mut self) -> Result<GreyImage, RigError>;

    /// Sets the exposure time (milliseconds) of the frames captured from now on, with auto
    /// exposure off. A driver that queues frames may still deliver a few exposed before the
    /// change: the session drops them as it drops those of an earlier pattern
    /// ([`SessionConfig::flush_frames`](crate::SessionConfig::flush_frames)).
    ///
    /// # Errors
    /// [`RigError::Unsupported`] for a camera without an exposure control (the default), or
    /// the driver's refusal.
    fn set_exposure_ms(&mut self, exposure_ms: f64) -> Result<(), RigError> {
        Err(RigError::Unsupported {
            device: "camera".to_owned(),
            what: format!(
                "set its exposure (to {exposure_ms} ms): capturing at several exposures needs a camera with a manual exposure control"
            ),
        })
    }

    /// The exposure time (milliseconds) the camera captures at, when it knows it: the one
    /// last set, or the one it was opened with. Default `None`.
    fn exposure_ms(&self) -> Option<f64> {
        None
    }

    /// Captures one frame in colour (8-bit RGB) of what the camera sees now: the colour of a
    /// scan, taken under full white. Patterns are captured grey ([`Camera::capture`]).
    ///
    /// # Errors
    /// [`RigError::Unsupported`] for a grey camera (the default), or the driver's failure.
    fn capture_colour(&mut self) -> Result<ColourImage, RigError> {
        Err(RigError::Unsupported {
            device: "camera".to_owned(),
            what: "capture in colour: a colour scan needs a colour camera".to_owned(),
        })
    }
}

/// A projector that shows grey images full screen.
pub trait Projector {
    /// Size of the projector's frame buffer in pixels, `(width, height)`.
    fn image_size(&self) -> (u32, u32);

    /// Shows `image` until the next call. The image must have the projector's size.
    fn show(&mut self, image: &GreyImage) -> Result<(), RigError>;
}

/// A turntable that rotates the objects standing on it about its axis.
pub trait Turntable {
    /// Rotates to `angle_deg` degrees (absolute, in the turntable's own zero) and returns the
    /// angle actually reached, as the turntable reports it.
    fn rotate_to(&mut self, angle_deg: f64) -> Result<f64, RigError>;

    /// The current angle in degrees, as the turntable reports it.
    fn angle_deg(&mut self) -> Result<f64, RigError>;
}

/// How a capture waits for what the projector shows to reach the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CaptureTiming {
    /// The wait after showing an image: the projector's display latency
    /// ([`SessionConfig::display_latency`](crate::SessionConfig::display_latency)).
    pub settle: std::time::Duration,
    /// Frames captured and dropped before the one kept: those the camera's driver queued
    /// before the change (and, after an exposure change, exposed with the old exposure).
    pub flush_frames: usize,
}

/// Shows `image`, waits `timing.settle`, drops `timing.flush_frames` frames and captures one:
/// a frame of what the projector shows now.
///
/// # Errors
/// The devices' errors.
pub fn show_and_capture<C, P>(
    camera: &mut C,
    projector: &mut P,
    image: &GreyImage,
    timing: CaptureTiming,
) -> Result<GreyImage, RigError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
{
    projector.show(image)?;
    if !timing.settle.is_zero() {
        std::thread::sleep(timing.settle);
    }
    flush_and_capture(camera, timing.flush_frames)
}

/// Drops `flush_frames` frames and captures one.
///
/// # Errors
/// The camera's errors.
pub fn flush_and_capture<C: Camera + ?Sized>(
    camera: &mut C,
    flush_frames: usize,
) -> Result<GreyImage, RigError> {
    for _ in 0..flush_frames {
        camera.capture()?;
    }
    camera.capture()
}

/// Shows each image of `patterns` in turn and captures one camera frame under each: the core of
/// every structured-light capture, written once for every device.
///
/// Returns the frames in the order of `patterns`.
pub fn capture_sequence<C, P>(
    camera: &mut C,
    projector: &mut P,
    patterns: &[GreyImage],
) -> Result<Vec<GreyImage>, RigError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
{
    let mut frames = Vec::with_capacity(patterns.len());
    for pattern in patterns {
        projector.show(pattern)?;
        frames.push(camera.capture()?);
    }
    Ok(frames)
}
