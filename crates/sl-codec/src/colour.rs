//! The colour of a capture: which of its frames show the object under full light, read in
//! colour.
//!
//! A capture's colour comes, in this order, from
//! 1. the manifest's `colour` frame (a colour frame under full white, taken after the
//!    patterns: what `sl-rig`'s sessions write as `colour.png`);
//! 2. the white frame of a Gray block with the `white_black` reference;
//! 3. the mean of the first phase-shift frames (the `steps` frames of a phase or hybrid block
//!    at its first frequency: the fringes' offset, about half of full light);
//! 4. the per-pixel maximum of a Gray block's first two frames (a stripe and its inverse with
//!    the `inverse` reference: every pixel is lit in one of them), or of all its frames.
//!
//! Each frame is read in colour ([`read_colour_image`]): a grey capture gives grey colours.

use std::path::{Path, PathBuf};

use sl_image::ColourImage;

use crate::capture::{manifest_file, resolve_frames_dir};
use crate::image_file::{find_image_file, read_colour_image};
use crate::{CodecError, GrayReference, Manifest, Pattern};

/// Where a capture's colour came from (see the module documentation for the order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ColourSource {
    /// The manifest's `colour` frame.
    ColourFrame,
    /// A Gray block's white frame.
    WhiteFrame,
    /// The mean of the first phase-shift frames.
    FringeMean,
    /// The per-pixel maximum of Gray frames.
    Brightest,
}

impl ColourSource {
    /// `"colour_frame"`, `"white_frame"`, `"fringe_mean"` or `"brightest"`, as reports write
    /// it.
    pub fn name(self) -> &'static str {
        match self {
            Self::ColourFrame => "colour_frame",
            Self::WhiteFrame => "white_frame",
            Self::FringeMean => "fringe_mean",
            Self::Brightest => "brightest",
        }
    }
}

/// A capture's colour image and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureColour {
    /// The colour (8-bit RGB, the capture's frame size).
    pub image: ColourImage,
    /// Which frames made it.
    pub source: ColourSource,
    /// The files read.
    pub files: Vec<PathBuf>,
}

impl CaptureColour {
    /// Whether the image holds colour: some pixel whose channels differ (a grey camera's
    /// capture gives none).
    pub fn has_chroma(&self) -> bool {
        self.image.data().iter().any(|&[r, g, b]| r != g || g != b)
    }
}

/// Reads the colour of the capture whose `manifest.json` is `manifest_path` (or a folder
/// holding one), frames resolved as [`CaptureSet::load`](crate::CaptureSet::load) resolves
/// them.
///
/// # Errors
/// The manifest's errors; [`CodecError::MissingFrame`] naming the frame (block `usize::MAX`
/// for the `colour` frame, which belongs to no block); [`CodecError::Image`] naming an
/// unreadable file; [`CodecError::FrameSize`] when the frames read differ in size.
///
/// ```
/// # fn main() -> Result<(), sl_codec::CodecError> {
/// use sl_codec::{
///     Axis, BitDepth, ColourSource, HybridSpec, ImageSize, Pattern, PatternSequence,
///     read_capture_colour,
/// };
/// let dir = tempfile::tempdir().unwrap();
/// // Hybrid patterns written as a "capture" (the projector's own images).
/// let size = ImageSize::new(64, 32);
/// let seq = PatternSequence::new(size)
///     .with(Pattern::Hybrid(HybridSpec::recommended(Axis::Column, size)));
/// seq.write(dir.path(), BitDepth::Eight)?;
/// let colour = read_capture_colour(dir.path())?;
/// assert_eq!(colour.source, ColourSource::FringeMean);
/// assert!(!colour.has_chroma());
/// # Ok(()) }
/// ```
pub fn read_capture_colour(manifest_path: &Path) -> Result<CaptureColour, CodecError> {
    let manifest_path = manifest_file(manifest_path);
    let manifest = Manifest::load(&manifest_path)?;
    let dir = resolve_frames_dir(&manifest_path, &manifest, None);
    let find = |block: usize, index: usize, file: &str| -> Result<PathBuf, CodecError> {
        let path = dir.join(file);
        find_image_file(&path).ok_or_else(|| CodecError::MissingFrame {
            manifest: manifest_path.clone(),
            block,
            index,
            file: file.to_owned(),
            path,
        })
    };
    let (source, block, indices, combine) = match colour_frames(&manifest) {
        Some(choice) => choice,
        None => {
            let file = manifest.colour.clone().unwrap_or_default();
            let path = find(usize::MAX, 0, &file)?;
            let image = read_colour_image(&path)?;
            return Ok(CaptureColour {
                image,
                source: ColourSource::ColourFrame,
                files: vec![path],
            });
        }
    };
    let names = &manifest.blocks[block].frames;
    let mut files = Vec::with_capacity(indices.len());
    let mut images = Vec::with_capacity(indices.len());
    for i in indices {
        let path = find(block, i, &names[i])?;
        let image = read_colour_image(&path)?;
        if let Some(first) = images.first().map(ColourImage::size)
            && image.size() != first
        {
            return Err(CodecError::FrameSize {
                frame: path.display().to_string(),
                expected_width: first.width as usize,
                expected_height: first.height as usize,
                found_width: image.width(),
                found_height: image.height(),
            });
        }
        files.push(path);
        images.push(image);
    }
    let image = combine_images(&images, combine)?;
    Ok(CaptureColour {
        image,
        source,
        files,
    })
}

/// Whether the capture whose `manifest.json` is `manifest_path` (or a folder holding one) was
/// taken in colour: it names a `colour` frame, or its first frame is a colour file (its header
/// alone is read, [`is_colour_image`](crate::is_colour_image)). A grey capture answers `false`
/// without a pixel read.
///
/// # Errors
/// The manifest's errors; [`CodecError::MissingFrame`] or [`CodecError::Image`] naming the
/// first frame.
pub fn capture_in_colour(manifest_path: &Path) -> Result<bool, CodecError> {
    let manifest_path = manifest_file(manifest_path);
    let manifest = Manifest::load(&manifest_path)?;
    if manifest.colour.is_some() {
        return Ok(true);
    }
    let Some(first) = manifest.blocks.first().and_then(|b| b.frames.first()) else {
        return Ok(false);
    };
    let path = resolve_frames_dir(&manifest_path, &manifest, None).join(first);
    let found = find_image_file(&path).ok_or_else(|| CodecError::MissingFrame {
        manifest: manifest_path.clone(),
        block: 0,
        index: 0,
        file: first.clone(),
        path: path.clone(),
    })?;
    crate::is_colour_image(&found)
}

/// How several frames become one colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Combine {
    Mean,
    Max,
}

/// The frames the colour comes from: `None` for the manifest's `colour` frame, else the
/// source, the block and its frame indices, and how they combine.
fn colour_frames(manifest: &Manifest) -> Option<(ColourSource, usize, Vec<usize>, Combine)> {
    if manifest.colour.is_some() {
        return None;
    }
    let blocks = &manifest.blocks;
    let white = blocks.iter().position(
        |b| matches!(&b.pattern, Pattern::Gray(g) if g.reference == GrayReference::WhiteBlack),
    );
    if let Some(b) = white {
        return Some((ColourSource::WhiteFrame, b, vec![0], Combine::Max));
    }
    let fringes = blocks
        .iter()
        .enumerate()
        .find_map(|(b, block)| match &block.pattern {
            Pattern::Phase(p) => Some((b, p.steps)),
            Pattern::Hybrid(h) => Some((b, h.steps)),
            Pattern::Gray(_) => None,
        });
    if let Some((b, steps)) = fringes {
        return Some((
            ColourSource::FringeMean,
            b,
            (0..steps as usize).collect(),
            Combine::Mean,
        ));
    }
    // Only Gray blocks, none with a white frame: a stripe and its inverse, or every frame.
    let block = &blocks[0];
    let indices = match &block.pattern {
        Pattern::Gray(g) if g.reference == GrayReference::Inverse => vec![0, 1],
        _ => (0..block.frames.len()).collect(),
    };
    Some((ColourSource::Brightest, 0, indices, Combine::Max))
}

/// The per-pixel mean (rounded) or maximum of `images`, all of one size.
fn combine_images(images: &[ColourImage], how: Combine) -> Result<ColourImage, CodecError> {
    let Some(first) = images.first() else {
        return Err(CodecError::Frames(
            "no frame to take the colour from".into(),
        ));
    };
    if images.len() == 1 {
        return Ok(first.clone());
    }
    let n = images.len() as u32;
    let data = (0..first.data().len())
        .map(|i| {
            let mut out = [0u32; 3];
            for img in images {
                let p = img.data()[i];
                for c in 0..3 {
                    out[c] = match how {
                        Combine::Mean => out[c] + u32::from(p[c]),
                        Combine::Max => out[c].max(u32::from(p[c])),
                    };
                }
            }
            match how {
                Combine::Mean => out.map(|v| ((v + n / 2) / n) as u8),
                Combine::Max => out.map(|v| v as u8),
            }
        })
        .collect();
    Ok(ColourImage::new(first.width(), first.height(), data)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{
        Axis, BitDepth, GrayCodeSpec, HybridSpec, ImageSize, MANIFEST_FILE, PatternSequence,
    };

    fn hybrid(size: ImageSize) -> PatternSequence {
        PatternSequence::new(size)
            .with(Pattern::Hybrid(HybridSpec::recommended(Axis::Column, size)))
    }

    fn gray(size: ImageSize, reference: GrayReference) -> PatternSequence {
        let spec = GrayCodeSpec {
            reference,
            ..GrayCodeSpec::per_pixel(Axis::Column, size, false)
        };
        PatternSequence::new(size).with(Pattern::Gray(spec))
    }

    fn write_rgb(path: &Path, w: u32, h: u32, rgb: [u8; 3]) {
        let bytes: Vec<u8> = (0..w * h).flat_map(|_| rgb).collect();
        image::save_buffer(path, &bytes, w, h, image::ExtendedColorType::Rgb8).unwrap();
    }

    #[test]
    fn the_colour_frame_comes_first_and_must_exist() {
        let dir = tempfile::tempdir().unwrap();
        let seq = hybrid(ImageSize::new(32, 16));
        let mut manifest = seq.write(dir.path(), BitDepth::Eight).unwrap();
        manifest.colour = Some("colour.png".into());
        manifest.save(&dir.path().join(MANIFEST_FILE)).unwrap();
        let err = read_capture_colour(dir.path()).unwrap_err();
        assert!(
            err.to_string().contains("colour.png"),
            "the message names the file: {err}"
        );
        write_rgb(&dir.path().join("colour.png"), 32, 16, [200, 40, 10]);
        let c = read_capture_colour(dir.path()).unwrap();
        assert_eq!(c.source, ColourSource::ColourFrame);
        assert_eq!(c.image.get(5, 5), Some([200, 40, 10]));
        assert!(c.has_chroma());
    }

    #[test]
    fn white_frame_then_fringe_mean_then_brightest() {
        let size = ImageSize::new(32, 16);
        // A Gray code with white and black frames: the white frame (all 255 on the projector).
        let dir = tempfile::tempdir().unwrap();
        gray(size, GrayReference::WhiteBlack)
            .write(dir.path(), BitDepth::Eight)
            .unwrap();
        let c = read_capture_colour(dir.path()).unwrap();
        assert_eq!(c.source, ColourSource::WhiteFrame);
        assert!(c.image.data().iter().all(|&p| p == [255; 3]));
        // The recommended hybrid sequence: the fringes' mean, mid grey within rounding.
        let dir = tempfile::tempdir().unwrap();
        hybrid(size).write(dir.path(), BitDepth::Eight).unwrap();
        let c = read_capture_colour(dir.path()).unwrap();
        assert_eq!(c.source, ColourSource::FringeMean);
        assert!(
            c.image
                .data()
                .iter()
                .all(|p| p.iter().all(|&v| (126..=129).contains(&v))),
            "{:?}",
            &c.image.data()[..4]
        );
        // A Gray code with inverses: a stripe or its inverse lights every pixel.
        let dir = tempfile::tempdir().unwrap();
        gray(size, GrayReference::Inverse)
            .write(dir.path(), BitDepth::Eight)
            .unwrap();
        let c = read_capture_colour(dir.path()).unwrap();
        assert_eq!(c.source, ColourSource::Brightest);
        assert_eq!(c.files.len(), 2);
        assert!(c.image.data().iter().all(|&p| p == [255; 3]));
    }

    #[test]
    fn a_capture_is_in_colour_by_its_colour_frame_or_its_files() {
        let size = ImageSize::new(32, 16);
        let dir = tempfile::tempdir().unwrap();
        let mut manifest = hybrid(size).write(dir.path(), BitDepth::Eight).unwrap();
        assert!(!capture_in_colour(dir.path()).unwrap(), "grey PNGs");
        // The first frame saved in colour (grey content: the header says colour).
        let first = dir.path().join(&manifest.blocks[0].frames[0]);
        let grey = crate::read_image(&first).unwrap().into_u8();
        let rgb: Vec<u8> = grey.data().iter().flat_map(|&g| [g, g, g]).collect();
        image::save_buffer(&first, &rgb, 32, 16, image::ExtendedColorType::Rgb8).unwrap();
        assert!(capture_in_colour(dir.path()).unwrap());
        // A colour frame named by the manifest.
        let dir2 = tempfile::tempdir().unwrap();
        manifest = hybrid(size).write(dir2.path(), BitDepth::Eight).unwrap();
        manifest.colour = Some("colour.png".into());
        manifest.save(&dir2.path().join(MANIFEST_FILE)).unwrap();
        assert!(capture_in_colour(dir2.path()).unwrap());
    }

    #[test]
    fn frames_of_other_sizes_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let size = ImageSize::new(32, 16);
        let manifest = hybrid(size).write(dir.path(), BitDepth::Eight).unwrap();
        let second = &manifest.blocks[0].frames[1];
        write_rgb(&dir.path().join(second), 8, 8, [1, 2, 3]);
        let err = read_capture_colour(dir.path()).unwrap_err();
        assert!(matches!(err, CodecError::FrameSize { .. }), "{err}");
        assert!(err.to_string().contains(second.as_str()), "{err}");
    }
}
