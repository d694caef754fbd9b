//! Writing what the devices produce: grey images as PNG, projector images from a pattern
//! sequence, and frames as a capture set in `sl-codec`'s format.

use std::path::Path;

use sl_codec::{Frame, Manifest, PatternSequence, write_png_grey8, write_png_grey16};

use crate::{GreyImage, Pixels, RigError};

impl GreyImage {
    /// Writes the image as an 8- or 16-bit grey PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), RigError> {
        let (w, h) = (self.width as usize, self.height as usize);
        match &self.pixels {
            Pixels::U8(p) => write_png_grey8(
                path,
                &Frame::new(w, h, p.clone()).map_err(sl_codec::CodecError::from)?,
            )?,
            Pixels::U16(p) => write_png_grey16(
                path,
                &Frame::new(w, h, p.clone()).map_err(sl_codec::CodecError::from)?,
            )?,
        }
        Ok(())
    }

    /// The image `frame` of a pattern sequence, as the projector shows it (8- or 16-bit as
    /// asked).
    pub fn from_sequence(
        sequence: &PatternSequence,
        frame: usize,
        sixteen_bits: bool,
    ) -> Result<Self, RigError> {
        let (w, h) = (sequence.projector.width, sequence.projector.height);
        let pixels = if sixteen_bits {
            Pixels::U16(sequence.render::<u16>(frame)?.into_data())
        } else {
            Pixels::U8(sequence.render::<u8>(frame)?.into_data())
        };
        Self::new(w, h, pixels)
    }
}

/// Writes a capture set: `frames[k]` as the file the manifest names for frame `k` (PNG),
/// and the manifest (`manifest.json`, with a `description`) into `dir` (created if needed).
/// Fails if the number of frames differs from the manifest's.
pub fn write_capture_set(
    dir: &Path,
    manifest: &Manifest,
    frames: &[GreyImage],
    description: &str,
) -> Result<(), RigError> {
    std::fs::create_dir_all(dir).map_err(|e| RigError::io(dir, e))?;
    let names: Vec<&String> = manifest
        .blocks
        .iter()
        .flat_map(|b| b.frames.iter())
        .collect();
    if names.len() != frames.len() {
        return Err(RigError::param(
            "frames",
            format!(
                "{} frames for a manifest of {} frames",
                frames.len(),
                names.len()
            ),
        ));
    }
    for (name, frame) in names.iter().zip(frames) {
        frame.save_png(&dir.join(name.as_str()))?;
    }
    let mut m = manifest.clone();
    m.frames_dir = None;
    m.description = Some(description.to_owned());
    m.save(&dir.join(sl_codec::MANIFEST_FILE))?;
    Ok(())
}
