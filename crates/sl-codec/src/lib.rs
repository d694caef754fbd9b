//! Structured-light codecs: the patterns a projector shows, and decoders that turn the camera
//! frames back into, for every camera pixel, the projector column and row that lit it.
//!
//! - **Gray code** ([`GrayCodeSpec`]) for columns and/or rows, MSB first, with inverse patterns
//!   (default) or a white and a black reference frame, centred on the projector or not, plain
//!   binary as an option. Decoding compares each pattern with its inverse and classifies bits
//!   with the direct/global split of Nayar et al. and Xu & Aliaga's rules (as Moreno & Taubin's
//!   scanner does); a pixel with one unreadable bit at a stripe edge decodes to that edge.
//! - **N-step phase shift** ([`PhaseShiftSpec`]) with any number of periods (non-integer
//!   allowed), optional gamma pre-compensation, and temporal unwrapping ([`Unwrap`]):
//!   multi-frequency hierarchical, three-frequency heterodyne, number-theoretic, all with
//!   cross-checks between frequencies.
//! - **Hybrid** ([`HybridSpec`]): phase shift for the sub-pixel position, a complementary Gray
//!   code (one extra bit, stripes half a period wide) for the period index, so period-jump
//!   errors at fringe edges are removed rather than filtered.
//!
//! Everything is driven by a [`Manifest`] (`manifest.json`, see `docs/capture-format.md`): the
//! same file describes the generated patterns and the captured frames, so captures from other
//! systems decode without code changes. [`decode`] turns a [`CaptureSet`] into a
//! [`CorrespondenceMap`]; [`decode_gray`], [`decode_phase`] and [`decode_hybrid`] decode single
//! blocks of in-memory frames. [`write_outputs`] writes the maps (float TIFF or `.npy`) and
//! false-colour pictures. The decoders are hand-written row-parallel loops (rayon over bands
//! of camera rows), allocate nothing per pixel, and read every frame once.
//!
//! ```
//! use sl_codec::*;
//!
//! // Patterns for a 256x128 projector: Gray code for the columns, heterodyne phase for rows.
//! let projector = ImageSize::new(256, 128);
//! let sequence = PatternSequence::new(projector)
//!     .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Column, projector, true)))
//!     .with(Pattern::Phase(PhaseShiftSpec::new(
//!         Axis::Row, projector, 4, vec![16.0, 14.5, 13.5], Unwrap::Heterodyne)));
//! // A simulated camera looking at the projection (a plane seen in perspective).
//! let scene = SyntheticScene { noise_sigma: 1.0, ambient: 10.0, ..SyntheticScene::looking_at(projector, 160, 90) };
//! let frames = scene.render::<u8>(&sequence)?;
//! let capture = CaptureSet::from_frames(sequence.manifest(BitDepth::Eight), Frames::U8(frames))?;
//! let map = decode(&capture, &DecodeConfig::default())?;
//! assert!(map.valid_fraction() > 0.9);
//! let c = map.get(80, 45).unwrap();
//! let (x, y) = scene.projector_point(80.0, 45.0);
//! assert!((f64::from(c.col) - x).abs() <= 1.0); // Gray code: the stripe (pixel) index
//! assert!((f64::from(c.row) - y).abs() < 0.1); // phase: sub-pixel
//! # Ok::<(), CodecError>(())
//! ```
//!
//! # Conventions
//!
//! - Projector and camera pixel coordinates: `x` to the right, `y` down, pixel `(0, 0)` is the
//!   *centre* of the top-left pixel (as OpenCV), so pixel `i` covers `[i - 0.5, i + 0.5)`.
//! - A decoded column value `c` means the camera pixel sees the projector point at `x = c` in
//!   that convention (rows likewise). Values are `f32`; NaN where the axis is not coded or did
//!   not decode.
//! - Gray code: stripe `i` covers `[origin + i w, origin + (i + 1) w)`; the integer decode is the
//!   stripe's centre, i.e. the projector column index for a per-pixel code; a pixel on a stripe
//!   edge (one unreadable bit, neighbouring candidates) decodes to the edge, `column + 0.5`.
//! - Phase: the absolute phase `Phi` is 0 at the block's `origin` (default `-0.5`, the leading
//!   edge of the projector, so `periods` count periods across the image) and grows by `2 pi` per
//!   period `lambda = extent / periods` towards increasing coordinates; step `k` of `N` shows
//!   `1/2 + 1/2 cos(Phi + psi - s 2 pi k / N)`. Decoded coordinate: `origin + lambda Phi / 2 pi`.
//!   Other systems' conventions map onto `origin`, `phase_offset` (`psi`) and `shift_sign` (`s`);
//!   SLMaster's are `origin = 0`, `psi = -pi`, `s = -1` (see `docs/codecs.md`).
//! - Grey levels: thresholds ([`DecodeConfig`]) and quality are in 8-bit grey levels; 16-bit
//!   frames are scaled by 257. Patterns are 8-bit by default ([`BitDepth`]).
//! - Geometry in `f64` (specs, pattern functions); per-pixel image data in `u8`/`u16`/`f32`.
#![deny(missing_docs)]

mod bits;
mod capture;
#[cfg(feature = "image-files")]
mod colour;
mod config;
mod correspondence;
mod decode;
mod error;
mod export;
mod exposure;
mod fast_math;
mod frame;
mod frame_check;
mod gray;
mod hybrid;
#[cfg(feature = "image-files")]
mod image_file;
mod kernel;
mod manifest;
mod pattern;
mod phase_shift;
mod pictures;
mod ramps;
mod response;
mod sequence;
mod smooth;
mod synthetic;
mod texture;
mod unwrap;

pub use capture::CaptureSet;
#[cfg(feature = "image-files")]
pub use capture::load_frame;
#[cfg(feature = "image-files")]
pub use colour::{CaptureColour, ColourSource, capture_in_colour, read_capture_colour};
pub use config::{
    DEFAULT_DIRECT_GLOBAL_BITS, DEFAULT_MIN_CONTRAST, DEFAULT_MIN_DIRECT, DEFAULT_MIN_MODULATION,
    DEFAULT_ROWS_PER_TASK, DEFAULT_SATURATION_LEVEL, DEFAULT_UNWRAP_TOLERANCE, DecodeConfig,
};
pub use correspondence::{AxisMap, Correspondence, CorrespondenceMap, InvalidReason};
pub use decode::{decode, decode_frames, decode_frames_into, decode_into};
pub use error::CodecError;
pub use export::{write_npy_f32, write_tiff_f32};
#[cfg(feature = "image-files")]
pub use export::{
    write_png_colour, write_png_grey, write_png_grey8, write_png_grey16, write_png_rgb8,
};
pub use exposure::{
    AutoExposureConfig, EXPOSURES_FILE, EXPOSURES_FORMAT, EXPOSURES_VERSION, ExposureChoice,
    ExposureFolder, ExposureFrames, ExposurePlan, ExposureRecord, FusedFrames, FusionConfig,
    FusionMethod, FusionSettings, FusionSummary, MAX_EXPOSURES, SATURATED_EVERYWHERE,
    choose_exposures, fuse_exposures,
};
pub use frame::{Frame, Frames, Sample};
pub use frame_check::{FrameFault, FrameIssue, check_frames};
pub use gray::{GrayCodeSpec, GrayReference, MAX_GRAY_BITS, WEAK_RULE_MARGIN_SHIFT, decode_gray};
pub use hybrid::{HybridSpec, RECOMMENDED_PERIOD_PX, RECOMMENDED_PHASE_STEPS, decode_hybrid};
#[cfg(feature = "image-files")]
pub use image_file::{
    IMAGE_EXTENSIONS, find_image_file, is_colour_image, is_image_file, not_a_regular_file,
    read_colour_image, read_grey8, read_image, read_image_size,
};
pub use manifest::{MANIFEST_FILE, MANIFEST_FORMAT, MANIFEST_VERSION, Manifest, ManifestBlock};
pub use pattern::{Axis, BitDepth, ImageSize, Pattern};
pub use phase_shift::{
    MAX_STEPS, MIN_PERIOD_PIXELS, PhaseShiftSpec, ShiftSign, WrappedPhase, decode_phase,
    wrapped_phase,
};
#[cfg(feature = "image-files")]
pub use pictures::write_outputs;
pub use pictures::{INVALID_PALETTE, MapFormat, OutputFiles, false_color, invalid_colors, turbo};
pub use ramps::ramp_stair_codes;
pub use response::PhaseCorrection;
pub use sequence::{PatternSequence, render_pattern};
/// An 8-bit RGB image, as [`read_colour_image`] returns it (the colour of a scan), from
/// `sl-image`.
pub use sl_image::ColourImage;
/// A grey image at either depth, as [`read_image`] returns it: the workspace's one grey image,
/// defined in `sl-image` and re-exported here.
pub use sl_image::GreyImage;
/// The error of `sl-image`'s types ([`Frame::new`], [`ImageSize::validate`]); it converts
/// into [`CodecError`].
pub use sl_image::ImageError;
/// A projector's response curve ([`DecodeConfig::projector_response`]), from `sl-image`.
pub use sl_image::ToneCurve;
pub use smooth::{MAX_SMOOTH_RADIUS, SmoothConfig, smooth_correspondences};
pub use synthetic::SyntheticScene;
pub use texture::{CaptureTexture, TextureSource, capture_texture};
pub use unwrap::Unwrap;

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
