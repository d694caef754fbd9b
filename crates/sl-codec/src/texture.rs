//! The texture of a capture: an evenly lit picture of the scene computed from the coded frames
//! themselves, for captures that have no frame under full white light (SLStudio's calibration
//! sequences, SLMaster's captures).
//!
//! Every block of a capture holds frames that add up to an evenly lit scene:
//! - a **phase-shift** block (or the phase part of a hybrid block): the `N` frames of one
//!   frequency show `1/2 + 1/2 cos(Phi - 2 pi k / N)`; over a full cycle of equally spaced
//!   steps the cosines cancel, so their mean is `A`, the scene under half the projector's
//!   light plus the ambient (the *fringe mean*; with a projector gamma, its harmonics up to
//!   order `N - 1` cancel as well);
//! - a **Gray** block with inverses: each pattern plus its inverse is the scene under full
//!   light, so the mean of the block's frames is the same half-lit scene;
//! - a Gray block with a **white and a black** reference frame: the white frame itself.
//!
//! SLStudio shows its calibration board through the fringes' modulation `B` instead; the
//! fringe mean is preferred here because it is the less noisy of the two (an average of `N`
//! samples rather than the amplitude of their first harmonic) and it is what the corner
//! figures of issue 15 were measured on. The first block of the capture that gives a
//! texture is used, preferring phase blocks (whose mean cancels exactly) to Gray ones.

use crate::{CaptureSet, CodecError, Frames, GrayReference, Pattern};

/// Where a [`CaptureTexture`] comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureSource {
    /// The mean of the `steps` phase-shift frames of one frequency of a phase or hybrid block.
    FringeMean {
        /// Index of the block in the manifest.
        block: usize,
        /// Frames averaged.
        frames: usize,
    },
    /// The mean of a Gray block's patterns and inverses.
    GrayPairMean {
        /// Index of the block in the manifest.
        block: usize,
        /// Frames averaged.
        frames: usize,
    },
    /// The white reference frame of a Gray block.
    WhiteFrame {
        /// Index of the block in the manifest.
        block: usize,
    },
}

impl std::fmt::Display for TextureSource {
    /// `"fringe mean of block 0 (8 frames)"` and the like, for messages and reports.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::FringeMean { block, frames } => {
                write!(f, "fringe mean of block {block} ({frames} frames)")
            }
            Self::GrayPairMean { block, frames } => write!(
                f,
                "mean of the Gray patterns and inverses of block {block} ({frames} frames)"
            ),
            Self::WhiteFrame { block } => write!(f, "white frame of block {block}"),
        }
    }
}

/// An evenly lit picture of the scene computed from a capture's coded frames.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureTexture {
    /// Width (px).
    pub width: usize,
    /// Height (px).
    pub height: usize,
    /// Row-major grey values in 8-bit grey levels (16-bit frames divided by 257), not rounded.
    pub values: Vec<f32>,
    /// The frames it was computed from.
    pub source: TextureSource,
}

impl CaptureTexture {
    /// The texture as 8-bit grey values (rounded, clamped), row-major.
    pub fn to_u8(&self) -> Vec<u8> {
        self.values
            .iter()
            .map(|v| v.round().clamp(0.0, 255.0) as u8)
            .collect()
    }
}

/// The texture of `capture` (see the module docs for which frames are used).
///
/// ```
/// use sl_codec::*;
/// let projector = ImageSize::new(64, 32);
/// let sequence = PatternSequence::new(projector)
///     .with(Pattern::Hybrid(HybridSpec::complementary(Axis::Column, projector, 4, 4.0)));
/// let scene = SyntheticScene::looking_at(projector, 40, 30);
/// let frames = scene.render::<u8>(&sequence)?;
/// let capture = CaptureSet::from_frames(sequence.manifest(BitDepth::Eight), Frames::U8(frames))?;
/// let texture = capture_texture(&capture)?;
/// assert_eq!(texture.source, TextureSource::FringeMean { block: 0, frames: 4 });
/// assert_eq!(texture.values.len(), 40 * 30);
/// # Ok::<(), CodecError>(())
/// ```
///
/// # Errors
/// [`CodecError::Frames`] when the capture has no frames or its frames do not match the
/// manifest's count.
pub fn capture_texture(capture: &CaptureSet) -> Result<CaptureTexture, CodecError> {
    let blocks = &capture.manifest.blocks;
    let expected: usize = blocks.iter().map(|b| b.pattern.frame_count()).sum();
    if capture.frames.is_empty() || capture.frames.len() != expected {
        return Err(CodecError::Frames(format!(
            "no texture: the capture has {} frames, its manifest lists {expected}",
            capture.frames.len()
        )));
    }
    // (first frame, frame count, source) of every block that gives a texture, phase first.
    let mut phase = None;
    let mut gray = None;
    let mut first = 0;
    for (b, block) in blocks.iter().enumerate() {
        let n = block.pattern.frame_count();
        match &block.pattern {
            Pattern::Phase(s) => {
                let k = s.steps as usize;
                phase.get_or_insert((
                    first,
                    k,
                    TextureSource::FringeMean {
                        block: b,
                        frames: k,
                    },
                ));
            }
            Pattern::Hybrid(s) => {
                let k = s.steps as usize;
                phase.get_or_insert((
                    first,
                    k,
                    TextureSource::FringeMean {
                        block: b,
                        frames: k,
                    },
                ));
            }
            Pattern::Gray(s) => match s.reference {
                GrayReference::Inverse => {
                    gray.get_or_insert((
                        first,
                        n,
                        TextureSource::GrayPairMean {
                            block: b,
                            frames: n,
                        },
                    ));
                }
                // The white frame comes first, then the black one.
                GrayReference::WhiteBlack => {
                    gray.get_or_insert((first, 1, TextureSource::WhiteFrame { block: b }));
                }
                // Only valid inside hybrid blocks; nothing evenly lit here.
                GrayReference::PhaseMean => {}
            },
        }
        first += n;
    }
    let Some((start, count, source)) = phase.or(gray) else {
        return Err(CodecError::Frames(
            "no texture: no block of the capture has frames that average to an evenly lit \
             scene"
                .into(),
        ));
    };
    let (width, height) = (capture.frames.width(), capture.frames.height());
    let mut sum = vec![0f32; width * height];
    let scale = match &capture.frames {
        Frames::U8(frames) => {
            for f in &frames[start..start + count] {
                sum.iter_mut()
                    .zip(f.data())
                    .for_each(|(s, &v)| *s += f32::from(v));
            }
            1.0
        }
        Frames::U16(frames) => {
            for f in &frames[start..start + count] {
                sum.iter_mut()
                    .zip(f.data())
                    .for_each(|(s, &v)| *s += f32::from(v));
            }
            1.0 / 257.0
        }
    };
    let k = scale / count as f32;
    sum.iter_mut().for_each(|s| *s *= k);
    Ok(CaptureTexture {
        width,
        height,
        values: sum,
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{
        Axis, BitDepth, Frame, GrayCodeSpec, HybridSpec, ImageSize, PatternSequence,
        PhaseShiftSpec, Unwrap,
    };

    /// A capture of constant frames: frame `i` has the value `values[i]` everywhere.
    fn capture(sequence: &PatternSequence, values: &[u8]) -> CaptureSet {
        let frames = values
            .iter()
            .map(|&v| Frame::filled(4, 3, v).unwrap())
            .collect();
        CaptureSet::from_frames(sequence.manifest(BitDepth::Eight), Frames::U8(frames)).unwrap()
    }

    /// Gray with inverses first, phase second: the phase block's first frequency is
    /// averaged (frames 2k.. of the Gray block are skipped), to the exact mean.
    #[test]
    fn phase_blocks_are_preferred_and_averaged_exactly() {
        let p = ImageSize::new(64, 32);
        let gray = GrayCodeSpec::per_pixel(Axis::Column, p, true);
        let phase = PhaseShiftSpec::new(Axis::Row, p, 3, vec![1.0, 2.0], Unwrap::Hierarchical);
        let seq = PatternSequence::new(p)
            .with(Pattern::Gray(gray.clone()))
            .with(Pattern::Phase(phase));
        let g = gray.frame_count();
        let mut values = vec![7u8; g];
        values.extend([10, 20, 60, 200, 200, 200]);
        let t = capture_texture(&capture(&seq, &values)).unwrap();
        assert_eq!(
            t.source,
            TextureSource::FringeMean {
                block: 1,
                frames: 3
            }
        );
        assert!(t.values.iter().all(|&v| v == 30.0));
        assert_eq!(t.to_u8(), vec![30u8; 12]);
        assert_eq!(t.source.to_string(), "fringe mean of block 1 (3 frames)");
    }

    /// Without a phase block: the mean of the Gray patterns and inverses, or the white frame
    /// of a white/black block.
    #[test]
    fn gray_blocks_give_their_pair_mean_or_white_frame() {
        let p = ImageSize::new(8, 4);
        let mut gray = GrayCodeSpec::per_pixel(Axis::Column, p, true);
        let seq = PatternSequence::new(p).with(Pattern::Gray(gray.clone()));
        let values: Vec<u8> = (0..gray.frame_count() as u8).map(|i| 10 * i).collect();
        let t = capture_texture(&capture(&seq, &values)).unwrap();
        let mean = values.iter().map(|&v| f32::from(v)).sum::<f32>() / values.len() as f32;
        assert!(t.values.iter().all(|&v| (v - mean).abs() < 1e-4));
        assert!(matches!(
            t.source,
            TextureSource::GrayPairMean { block: 0, .. }
        ));

        gray.reference = GrayReference::WhiteBlack;
        let seq = PatternSequence::new(p).with(Pattern::Gray(gray.clone()));
        let mut values = vec![250u8, 3];
        values.extend(vec![100u8; gray.bits as usize]);
        let t = capture_texture(&capture(&seq, &values)).unwrap();
        assert_eq!(t.source, TextureSource::WhiteFrame { block: 0 });
        assert!(t.values.iter().all(|&v| v == 250.0));
    }

    /// 16-bit frames are scaled to 8-bit grey levels; a hybrid block averages its phase frames.
    #[test]
    fn sixteen_bit_hybrid() {
        let p = ImageSize::new(64, 32);
        let seq = PatternSequence::new(p).with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Column,
            p,
            4,
            4.0,
        )));
        let n = seq.frame_count();
        let frames = (0..n)
            .map(|i| Frame::filled(2, 2, if i < 4 { 257 * 100 } else { 0u16 }).unwrap())
            .collect();
        let c =
            CaptureSet::from_frames(seq.manifest(BitDepth::Sixteen), Frames::U16(frames)).unwrap();
        let t = capture_texture(&c).unwrap();
        assert_eq!(
            t.source,
            TextureSource::FringeMean {
                block: 0,
                frames: 4
            }
        );
        assert!(t.values.iter().all(|&v| (v - 100.0).abs() < 1e-3));
    }
}
