//! The hardware of a structured-light rig: the device traits, the drivers, and the capture
//! code written once against the traits.
//!
//! This crate holds:
//!
//! - the **device traits** [`Camera`], [`Projector`] and [`Turntable`] that every driver
//!   implements, the grey images they exchange ([`GreyImage`]), and capture code written once
//!   against them ([`capture_sequence`], [`write_capture_set`]);
//! - **capture sessions** ([`CaptureSession`]): a turntable scan through the device traits,
//!   written view by view and atomically so that an interrupted scan resumes, with the
//!   display latency measured by flashing ([`measure_latency`]), and optionally each view's
//!   colour under full white ([`SessionPlan::colour`]);
//! - the **turntable hardware** (feature `dynamixel`, on by default): `DynamixelTurntable`
//!   drives a Dynamixel MX-64 over Protocol 2.0 and `Mx64Emulator` answers for it on a
//!   pseudo-terminal, so the driver is tested without hardware (`docs/hardware-turntable.md`).
//! - the **camera and projector hardware**: `V4lCamera` (feature `v4l`, Linux V4L2:
//!   enumeration, format, manual exposure/gain/white balance, memory-mapped streaming and the
//!   flush of stale frames) with its pixel-format conversions to grey ([`convert_frame`]) and
//!   to colour ([`convert_frame_colour`], for [`Camera::capture_colour`]) compiled and tested
//!   always, and `run_projector` / `ProjectorWindow` (feature `window`: a full-screen
//!   window on a chosen monitor, pixel for pixel) — see `docs/hardware-camera-projector.md`;
//! - **opening the real devices from a description** ([`DeviceDescription`], [`with_devices`],
//!   [`open_camera`], [`open_turntable`]): the description builds without any feature, and a
//!   device whose feature is off is [`RigError::FeatureNotBuilt`] naming it.
//!
//! ```
//! use std::{cell::RefCell, rc::Rc};
//! use sl_rig::{Camera, GreyImage, Projector, RigError, capture_sequence};
//! # fn main() -> Result<(), RigError> {
//! // Any driver fits the traits; here a 4x2 camera that sees exactly what the projector shows.
//! struct Mirror(Rc<RefCell<GreyImage>>);
//! impl Camera for Mirror {
//!     fn frame_size(&self) -> (u32, u32) { (4, 2) }
//!     fn capture(&mut self) -> Result<GreyImage, RigError> { Ok(self.0.borrow().clone()) }
//! }
//! impl Projector for Mirror {
//!     fn image_size(&self) -> (u32, u32) { (4, 2) }
//!     fn show(&mut self, image: &GreyImage) -> Result<(), RigError> {
//!         *self.0.borrow_mut() = image.clone();
//!         Ok(())
//!     }
//! }
//! let screen = Rc::new(RefCell::new(GreyImage::filled_u8(4, 2, 0)?));
//! let (mut camera, mut projector) = (Mirror(screen.clone()), Mirror(screen));
//! let patterns = [GreyImage::filled_u8(4, 2, 255)?, GreyImage::filled_u8(4, 2, 0)?];
//! let frames = capture_sequence(&mut camera, &mut projector, &patterns)?;
//! assert_eq!(frames, patterns);
//! # Ok(())
//! # }
//! ```
//!
//! # Conventions
//! - Pixel `(0, 0)` is the centre of the top-left pixel; images are row-major, pixel `(x, y)`
//!   at index `y · width + x`; camera frames and projector images are 8- or 16-bit grey, colour
//!   frames ([`ColourImage`]) 8-bit RGB.
//! - Angles in degrees at the API surface; a turntable's angle is its motor reading, in its
//!   own zero.
#![deny(missing_docs)]

mod device;
#[cfg(all(feature = "dynamixel", unix))]
mod dynamixel;
mod error;
mod exposure;
mod files;
mod latency;
mod open;
mod pixel_format;
#[cfg(feature = "window")]
mod projector_window;
mod session;
#[cfg(feature = "v4l")]
mod v4l_camera;
mod v4l_camera_controls;

pub use device::{
    Camera, CaptureTiming, Projector, Turntable, capture_sequence, flush_and_capture,
    show_and_capture,
};
#[cfg(all(feature = "dynamixel", unix))]
pub use dynamixel::{
    DEG_PER_TICK, DynamixelConfig, DynamixelError, DynamixelTurntable,
    EXTENDED_POSITION_LIMIT_TICKS, EmulatorConfig, EmulatorSnapshot, HardwareErrorStatus,
    MX64_MODEL_NUMBER, MidMoveFault, Mx64Emulator, ServoStatus, TICKS_PER_TURN, dynamixel_crc16,
};
pub use error::RigError;
pub use exposure::{MAX_EXPOSURE_MEASUREMENTS, measure_exposures};
pub use files::write_capture_set;
pub use latency::{BufferedCamera, Latency, LatencyConfig, MIN_FLASH_CONTRAST, measure_latency};
pub use open::{
    BoxedCamera, BoxedTurntable, DeviceDescription, open_camera, open_turntable, serial_ports,
    with_binocular_devices, with_camera_and_projector, with_described_devices, with_devices,
};
pub use pixel_format::{FrameLayout, PixelFormat, convert_frame, convert_frame_colour};
#[cfg(feature = "window")]
pub use projector_window::{
    DEFAULT_PRESENT_TIMEOUT, MonitorInfo, PROJECTOR_WINDOW_TITLE, ProjectorWindow,
    ProjectorWindowConfig, list_monitors, run_projector,
};
pub use session::{
    COLOUR_FILE, CaptureSession, DEFAULT_DISPLAY_LATENCY, RECAPTURE_ROUNDS, RIGHT_DIR,
    SESSION_FILE, SESSION_FORMAT, SESSION_VERSION, SessionConfig, SessionDevices, SessionExposures,
    SessionPlan, SessionSummary, ViewOutcome, ViewState, exposure_dir_name, read_session_plan,
    turntable_angles, view_dir_name,
};
/// The grey images the devices exchange (camera frames, projector images): the workspace's one
/// grey image, defined in `sl-image` and re-exported so rig users need one import.
pub use sl_image::{ColourImage, GreyImage};
#[cfg(feature = "v4l")]
pub use v4l_camera::{
    DEFAULT_FRAME_TIMEOUT, DEFAULT_IN_FLIGHT_FRAMES, DEFAULT_V4L_BUFFERS, V4lCamera,
    V4lCameraConfig, V4lControlInfo, V4lDeviceInfo, V4lFormatInfo, list_v4l_cameras,
};
pub use v4l_camera_controls::ControlKey;

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
