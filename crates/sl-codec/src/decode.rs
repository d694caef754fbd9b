//! The manifest-driven decoder: every block of a capture in one row-parallel pass.

use crate::correspondence::CorrespondenceMap;
use crate::gray::GrayKernel;
use crate::hybrid::HybridKernel;
use crate::kernel::{self, Kernel};
use crate::phase_shift::PhaseKernel;
use crate::sequence::prefix_block;
use crate::{Axis, CaptureSet, CodecError, DecodeConfig, Frame, Frames, Pattern, Sample};

/// Decodes a capture set into a correspondence map.
///
/// # Errors
/// Frame-count and size errors, and parameter errors naming the block.
///
/// # Example
/// ```
/// use sl_codec::*;
///
/// let projector = ImageSize::new(128, 64);
/// let sequence = PatternSequence::new(projector)
///     .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Column, projector, true)))
///     .with(Pattern::Hybrid(HybridSpec::complementary(Axis::Row, projector, 4, 8.0)));
/// // A camera that sees the projector through a mild perspective, with noise and ambient light.
/// let scene = SyntheticScene { ambient: 20.0, noise_sigma: 1.0, ..SyntheticScene::looking_at(projector, 96, 48) };
/// let frames = scene.render::<u8>(&sequence)?;
/// let capture = CaptureSet::from_frames(sequence.manifest(BitDepth::Eight), Frames::U8(frames))?;
/// let map = decode(&capture, &DecodeConfig::default())?;
/// let (x, y) = scene.projector_point(50.0, 20.0);
/// let c = map.get(50, 20).unwrap();
/// assert!(c.invalid.is_valid());
/// assert!((f64::from(c.col) - x).abs() <= 1.0 && (f64::from(c.row) - y).abs() < 0.2);
/// # Ok::<(), CodecError>(())
/// ```
pub fn decode(
    capture: &CaptureSet,
    config: &DecodeConfig,
) -> Result<CorrespondenceMap, CodecError> {
    let mut map = CorrespondenceMap::new(0, 0);
    decode_into(capture, config, &mut map)?;
    Ok(map)
}

/// As [`decode`], reusing the allocations of `map` (for video-rate loops).
///
/// # Errors
/// As [`decode`].
pub fn decode_into(
    capture: &CaptureSet,
    config: &DecodeConfig,
    map: &mut CorrespondenceMap,
) -> Result<(), CodecError> {
    let patterns: Vec<Pattern> = capture
        .manifest
        .blocks
        .iter()
        .map(|b| b.pattern.clone())
        .collect();
    match &capture.frames {
        Frames::U8(f) => decode_frames_into(&patterns, f, config, map),
        Frames::U16(f) => decode_frames_into(&patterns, f, config, map),
    }
}

/// Decodes in-memory frames laid out block after block, as in a manifest.
///
/// # Errors
/// [`CodecError::Frames`] if the total count differs from what the blocks need or a block is
/// missing frames, [`CodecError::FrameSize`], [`CodecError::Parameter`] naming the block.
pub fn decode_frames<T: Sample>(
    patterns: &[Pattern],
    frames: &[Frame<T>],
    config: &DecodeConfig,
) -> Result<CorrespondenceMap, CodecError> {
    let mut map = CorrespondenceMap::new(0, 0);
    decode_frames_into(patterns, frames, config, &mut map)?;
    Ok(map)
}

/// As [`decode_frames`], reusing the allocations of `map`.
///
/// # Errors
/// As [`decode_frames`].
pub fn decode_frames_into<T: Sample>(
    patterns: &[Pattern],
    frames: &[Frame<T>],
    config: &DecodeConfig,
    map: &mut CorrespondenceMap,
) -> Result<(), CodecError> {
    config.validate()?;
    let need: usize = patterns.iter().map(Pattern::frame_count).sum();
    if need != frames.len() {
        return Err(CodecError::Frames(format!(
            "the blocks need {need} frames in all ({}), {} were given",
            patterns
                .iter()
                .map(|p| format!(
                    "{} {}: {}",
                    p.codec_name(),
                    p.axis().name(),
                    p.frame_count()
                ))
                .collect::<Vec<_>>()
                .join(", "),
            frames.len()
        )));
    }
    if frames.is_empty() {
        return Err(CodecError::Frames("no frames to decode".into()));
    }
    crate::frame::check_sizes(frames, None)?;
    let mut kernels = Vec::with_capacity(patterns.len());
    let mut axes: Vec<Axis> = Vec::new();
    let mut start = 0;
    for (i, p) in patterns.iter().enumerate() {
        let n = p.frame_count();
        let block = frames.get(start..start + n).unwrap_or(&[]);
        start += n;
        if axes.contains(&p.axis()) {
            return Err(CodecError::parameter(
                format!("blocks[{i}].axis"),
                format!(
                    "axis '{}' is already coded by an earlier block",
                    p.axis().name()
                ),
            ));
        }
        axes.push(p.axis());
        let k = match p {
            Pattern::Gray(s) => {
                Kernel::Gray(GrayKernel::new(s, block, config).map_err(|e| prefix_block(i, e))?)
            }
            Pattern::Phase(s) => {
                Kernel::Phase(PhaseKernel::new(s, block, config).map_err(|e| prefix_block(i, e))?)
            }
            Pattern::Hybrid(s) => {
                Kernel::Hybrid(HybridKernel::new(s, block, config).map_err(|e| prefix_block(i, e))?)
            }
        };
        kernels.push(k);
    }
    let (w, h) = frames.first().map_or((0, 0), |f| (f.width(), f.height()));
    map.resize(w, h);
    kernel::run(&kernels, map, config.rows_per_task);
    Ok(())
}
