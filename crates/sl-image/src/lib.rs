//! The image types the structured-light crates share, and nothing else: an [`ImageSize`], a
//! grey [`Frame`] of 8- or 16-bit samples, a [`GreyImage`] holding a frame of either
//! depth, an 8-bit RGB [`ColourImage`] (the colour of a scan), and the [`ToneCurve`] of a projector's response. Cameras, projectors, pattern sequences, decoders, the simulator and the rig all
//! speak these types, so any project can take one crate (or write its own on top of these)
//! without converting images between them. The crate needs only `serde` and `thiserror`.
//!
//! ```
//! use sl_image::{Frame, GreyImage, ImageSize};
//! # fn main() -> Result<(), sl_image::ImageError> {
//! let size = ImageSize::new(4, 2);
//! size.validate()?;
//! let frame = Frame::filled(size.width as usize, size.height as usize, 200u8)?;
//! assert_eq!(frame.get(3, 1), Some(200));
//! let image = GreyImage::from(frame);
//! assert_eq!(image.into_u16().get(0, 0), Some(200 * 257));
//! assert!(size.contains(3.4, -0.5) && !size.contains(3.5, 0.0));
//! # Ok(()) }
//! ```
//!
//! # Conventions
//!
//! - Pixel coordinates: `x` to the right, `y` down, pixel `(0, 0)` is the *centre* of the
//!   top-left pixel (as OpenCV), so pixel `i` covers `[i - 0.5, i + 0.5)` and an image of
//!   [`ImageSize`] `w × h` covers `[-0.5, w - 0.5) × [-0.5, h - 0.5)`.
//! - Frames are row-major without padding: pixel `(x, y)` is sample `y * width + x`.
//! - Depths: 8 → 16 bits by `v * 257`, 16 → 8 bits by `round(v / 257)`.
#![deny(missing_docs)]

mod colour;
mod error;
mod frame;
mod grey;
mod size;
mod tone;

pub use colour::{ColourImage, luma};
pub use error::ImageError;
pub use frame::{Frame, Sample};
pub use grey::GreyImage;
pub use size::ImageSize;
pub use tone::{MAX_TONE_SAMPLES, ToneCurve};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
