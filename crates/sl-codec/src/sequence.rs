//! A whole pattern sequence: the blocks in projection order, their rendering, and the files
//! written for a projector.

#[cfg(feature = "image-files")]
use std::path::Path;

#[cfg(feature = "image-files")]
use rayon::prelude::*;

use crate::manifest::{Manifest, ManifestBlock};
use crate::{Axis, BitDepth, CodecError, Frame, GreyImage, ImageSize, Pattern, Sample};
use sl_image::ToneCurve;

/// The blocks of a scan in projection order, for one projector.
///
/// Frames are numbered globally: block 0's frames first, then block 1's, and so on.
#[derive(Clone, Debug, PartialEq)]
pub struct PatternSequence {
    /// Projector image size.
    pub projector: ImageSize,
    /// The blocks, in projection order (at most one per axis).
    pub blocks: Vec<Pattern>,
}

impl PatternSequence {
    /// An empty sequence.
    pub fn new(projector: ImageSize) -> Self {
        Self {
            projector,
            blocks: Vec::new(),
        }
    }

    /// Appends a block (builder style).
    #[must_use]
    pub fn with(mut self, block: Pattern) -> Self {
        self.blocks.push(block);
        self
    }

    /// This sequence with the projector's measured `response` pre-compensated in every
    /// phase and hybrid block's fringes (binary blocks show black and white, which need
    /// none): what to project once `slscan calibrate response` has measured the projector.
    #[must_use]
    pub fn precompensated(mut self, response: &ToneCurve) -> Self {
        for block in &mut self.blocks {
            match block {
                Pattern::Phase(s) => s.precompensation = Some(response.clone()),
                Pattern::Hybrid(s) => s.precompensation = Some(response.clone()),
                Pattern::Gray(_) => {}
            }
        }
        self
    }

    /// Total number of frames.
    pub fn frame_count(&self) -> usize {
        self.blocks.iter().map(Pattern::frame_count).sum()
    }

    /// Block index and frame index inside the block of global frame `frame`.
    pub fn locate(&self, frame: usize) -> Option<(usize, usize)> {
        let mut start = 0;
        for (b, block) in self.blocks.iter().enumerate() {
            let n = block.frame_count();
            if frame < start + n {
                return Some((b, frame - start));
            }
            start += n;
        }
        None
    }

    /// Checks every block, that block extents match the projector, and that no axis is coded
    /// twice.
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming the block (`blocks[i].field`).
    pub fn validate(&self) -> Result<(), CodecError> {
        if self.projector.width == 0 || self.projector.height == 0 {
            return Err(CodecError::parameter(
                "projector",
                format!("must not be empty, got {}", self.projector),
            ));
        }
        let mut seen: Vec<Axis> = Vec::new();
        for (i, block) in self.blocks.iter().enumerate() {
            block.validate().map_err(|e| prefix_block(i, e))?;
            let axis = block.axis();
            let extent = match block {
                Pattern::Gray(s) => s.extent,
                Pattern::Phase(s) => s.extent,
                Pattern::Hybrid(s) => s.extent,
            };
            if extent != axis.extent(self.projector) {
                return Err(CodecError::parameter(
                    format!("blocks[{i}].extent"),
                    format!(
                        "{extent} differs from the projector's {} {}",
                        axis.name(),
                        axis.extent(self.projector)
                    ),
                ));
            }
            if seen.contains(&axis) {
                return Err(CodecError::parameter(
                    format!("blocks[{i}].axis"),
                    format!(
                        "axis '{}' is already coded by an earlier block",
                        axis.name()
                    ),
                ));
            }
            seen.push(axis);
        }
        Ok(())
    }

    /// Intensity in `[0, 1]` that global frame `frame` shows at the continuous projector point
    /// `(x, y)` (pixel centres at integers); `None` if `frame` is out of range.
    ///
    /// This is the exact function the rendered images sample at pixel centres, for simulators
    /// that need the pattern between pixels.
    pub fn pattern_value(&self, frame: usize, x: f64, y: f64) -> Option<f64> {
        let (b, f) = self.locate(frame)?;
        self.blocks.get(b)?.pattern_value(f, x, y)
    }

    /// Renders global frame `frame` at the projector's size as the grey image a projector
    /// shows, at `depth` ([`PatternSequence::render`] at `u8` or `u16`).
    ///
    /// # Errors
    /// [`CodecError::Parameter`] if `frame >= frame_count()`.
    pub fn render_image(&self, frame: usize, depth: BitDepth) -> Result<GreyImage, CodecError> {
        Ok(match depth {
            BitDepth::Eight => GreyImage::U8(self.render::<u8>(frame)?),
            BitDepth::Sixteen => GreyImage::U16(self.render::<u16>(frame)?),
        })
    }

    /// Renders global frame `frame` at the projector's size.
    ///
    /// # Errors
    /// [`CodecError::Parameter`] if `frame >= frame_count()`.
    pub fn render<T: Sample>(&self, frame: usize) -> Result<Frame<T>, CodecError> {
        let (b, f) = self.locate(frame).ok_or_else(|| {
            CodecError::parameter(
                "frame",
                format!(
                    "{frame} is out of range: the sequence has {} frames",
                    self.frame_count()
                ),
            )
        })?;
        let block = self
            .blocks
            .get(b)
            .ok_or_else(|| CodecError::parameter("frame", format!("{frame} is out of range")))?;
        render_pattern(block, f, self.projector)
    }

    /// The manifest describing this sequence, with frames named `000.png`, `001.png`, ... in
    /// projection order (the names a capture of the sequence should use too).
    pub fn manifest(&self, bit_depth: BitDepth) -> Manifest {
        let mut next = 0usize;
        let width = self
            .frame_count()
            .saturating_sub(1)
            .to_string()
            .len()
            .max(3);
        let blocks = self
            .blocks
            .iter()
            .map(|p| {
                let frames = (0..p.frame_count())
                    .map(|_| {
                        let name = format!("{next:0width$}.png");
                        next += 1;
                        name
                    })
                    .collect();
                ManifestBlock {
                    pattern: p.clone(),
                    frames,
                }
            })
            .collect();
        Manifest {
            projector: self.projector,
            bit_depth,
            frames_dir: None,
            description: None,
            colour: None,
            blocks,
        }
    }

    #[cfg(feature = "image-files")]
    /// Writes every pattern as a PNG of `bit_depth` into `dir` (created if needed) together
    /// with `manifest.json`, and returns the manifest.
    ///
    /// # Errors
    /// Validation errors, and [`CodecError::Io`] / [`CodecError::Image`] naming the file.
    pub fn write(&self, dir: &Path, bit_depth: BitDepth) -> Result<Manifest, CodecError> {
        self.validate()?;
        std::fs::create_dir_all(dir).map_err(|e| CodecError::io(dir, "create directory", e))?;
        let manifest = self.manifest(bit_depth);
        let names: Vec<&String> = manifest
            .blocks
            .iter()
            .flat_map(|b| b.frames.iter())
            .collect();
        names.par_iter().enumerate().try_for_each(|(i, name)| {
            let path = dir.join(name);
            match bit_depth {
                BitDepth::Eight => crate::export::write_png_grey8(&path, &self.render::<u8>(i)?),
                BitDepth::Sixteen => {
                    crate::export::write_png_grey16(&path, &self.render::<u16>(i)?)
                }
            }
        })?;
        manifest.save(&dir.join(crate::manifest::MANIFEST_FILE))?;
        Ok(manifest)
    }
}

/// Adds `blocks[i].` in front of a parameter name.
pub(crate) fn prefix_block(i: usize, e: CodecError) -> CodecError {
    match e {
        CodecError::Parameter { name, message } => CodecError::Parameter {
            name: format!("blocks[{i}].{name}"),
            message,
        },
        other => other,
    }
}

/// Renders frame `frame` of one block at the projector's size, sampling the pattern at pixel
/// centres and rounding to the sample type.
///
/// # Errors
/// [`CodecError::Parameter`] if `frame` is out of range for the block.
pub fn render_pattern<T: Sample>(
    pattern: &Pattern,
    frame: usize,
    projector: ImageSize,
) -> Result<Frame<T>, CodecError> {
    let profile = pattern_profile::<T>(pattern, frame, projector)?;
    let (w, h) = (projector.width as usize, projector.height as usize);
    let mut data = vec![T::default(); w * h];
    match pattern.axis() {
        Axis::Column => {
            for row in data.chunks_exact_mut(w.max(1)) {
                row.copy_from_slice(&profile[..w]);
            }
        }
        Axis::Row => {
            for (row, &v) in data.chunks_exact_mut(w.max(1)).zip(&profile) {
                row.fill(v);
            }
        }
    }
    Ok(Frame::new(w, h, data)?)
}

/// The 1-D profile of a pattern frame along its axis, quantised to `T`, one value per
/// projector pixel.
pub(crate) fn pattern_profile<T: Sample>(
    pattern: &Pattern,
    frame: usize,
    projector: ImageSize,
) -> Result<Vec<T>, CodecError> {
    if frame >= pattern.frame_count() {
        return Err(CodecError::parameter(
            "frame",
            format!(
                "{frame} is out of range: the {} block has {} frames",
                pattern.codec_name(),
                pattern.frame_count()
            ),
        ));
    }
    let extent = pattern.axis().extent(projector);
    let axis = pattern.axis();
    Ok((0..extent)
        .map(|i| {
            let t = f64::from(i);
            let (x, y) = match axis {
                Axis::Column => (t, 0.0),
                Axis::Row => (0.0, t),
            };
            T::from_unit(pattern.pattern_value(frame, x, y).unwrap_or(0.0))
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{GrayCodeSpec, HybridSpec, PhaseShiftSpec, Unwrap};

    fn sequence() -> PatternSequence {
        let p = ImageSize::new(40, 30);
        PatternSequence::new(p)
            .with(Pattern::Gray(GrayCodeSpec::per_pixel(
                Axis::Column,
                p,
                true,
            )))
            .with(Pattern::Phase(PhaseShiftSpec::new(
                Axis::Row,
                p,
                3,
                vec![1.0, 5.0],
                Unwrap::Hierarchical,
            )))
    }

    #[test]
    fn locate_and_render() {
        let s = sequence();
        s.validate().unwrap();
        assert_eq!(s.frame_count(), 12 + 6);
        assert_eq!(s.locate(0), Some((0, 0)));
        assert_eq!(s.locate(12), Some((1, 0)));
        assert_eq!(s.locate(18), None);
        let f: Frame<u8> = s.render(1).unwrap();
        assert_eq!((f.width(), f.height()), (40, 30));
        // Frame 1 is the inverse of frame 0.
        let f0: Frame<u8> = s.render(0).unwrap();
        assert!(
            f0.data()
                .iter()
                .zip(f.data())
                .all(|(a, b)| u16::from(*a) + u16::from(*b) == 255)
        );
        // Row pattern: constant along rows.
        let r: Frame<u16> = s.render(13).unwrap();
        for y in 0..30 {
            let row = r.row(y).unwrap();
            assert!(row.iter().all(|&v| v == row[0]));
        }
        assert!(s.render::<u8>(18).is_err());
        assert_eq!(
            s.pattern_value(0, 3.0, 0.0),
            s.blocks[0].pattern_value(0, 3.0, 0.0)
        );
    }

    #[test]
    fn validation_catches_duplicate_axis_and_extent() {
        let p = ImageSize::new(40, 30);
        let s = sequence().with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Column,
            p,
            4,
            4.0,
        )));
        let e = s.validate().unwrap_err();
        assert!(e.to_string().contains("blocks[2].axis"), "{e}");
        let s = PatternSequence::new(ImageSize::new(41, 30)).with(Pattern::Gray(
            GrayCodeSpec::per_pixel(Axis::Column, p, true),
        ));
        assert!(
            s.validate()
                .unwrap_err()
                .to_string()
                .contains("blocks[0].extent")
        );
    }

    #[test]
    fn manifest_names_frames_in_order() {
        let m = sequence().manifest(BitDepth::Eight);
        assert_eq!(m.blocks[0].frames[0], "000.png");
        assert_eq!(m.blocks[1].frames[0], "012.png");
        assert_eq!(m.blocks[1].frames.len(), 6);
    }
}
