//! Capture sets: a manifest plus the camera frames it lists, loaded from disk or memory.

#[cfg(feature = "image-files")]
use std::path::{Path, PathBuf};

#[cfg(feature = "image-files")]
use rayon::prelude::*;

#[cfg(feature = "image-files")]
use crate::GreyImage;
#[cfg(feature = "image-files")]
use crate::frame::check_sizes;
#[cfg(feature = "image-files")]
use crate::image_file::{find_image_file, not_a_regular_file, read_image};
#[cfg(feature = "image-files")]
use crate::manifest::MANIFEST_FILE;
use crate::{CodecError, Frames, Manifest};

/// A manifest and its frames, in manifest order (block 0's frames first).
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureSet {
    /// What was projected.
    pub manifest: Manifest,
    /// The camera frames, all of one size and depth.
    pub frames: Frames,
    /// A name per frame for messages (the path it was read from, or `#index`).
    pub frame_names: Vec<String>,
}

impl CaptureSet {
    #[cfg(feature = "image-files")]
    /// Loads `manifest.json` (or a folder holding one) and every frame it lists.
    ///
    /// Frame paths are resolved against the manifest's `frames_dir` (relative to the manifest's
    /// folder) or, without one, against the manifest's folder; absolute frame paths are used as
    /// they are. A frame missing under its listed name is looked for under the same name with
    /// each of the [`IMAGE_EXTENSIONS`](crate::IMAGE_EXTENSIONS) ([`find_image_file`]), so a
    /// manifest naming `000.png` reads a capture saved as `000.bmp`.
    ///
    /// # Errors
    /// Manifest errors, [`CodecError::MissingFrame`] naming the block and frame,
    /// [`CodecError::FrameNotAFile`] when the frame's path is a folder, a device or a FIFO,
    /// [`CodecError::Image`] for an unreadable frame, [`CodecError::FrameSize`] naming the frame
    /// whose size differs from the first.
    pub fn load(manifest_path: &Path) -> Result<Self, CodecError> {
        Self::load_with_frames_dir(manifest_path, None)
    }

    #[cfg(feature = "image-files")]
    /// As [`CaptureSet::load`], but frames are looked for in `frames_dir` when given (for
    /// manifests kept apart from read-only data, as this crate's tests do with SLMaster's
    /// captures).
    ///
    /// # Errors
    /// As [`CaptureSet::load`].
    pub fn load_with_frames_dir(
        manifest_path: &Path,
        frames_dir: Option<&Path>,
    ) -> Result<Self, CodecError> {
        let manifest_path = manifest_file(manifest_path);
        let manifest = Manifest::load(&manifest_path)?;
        let dir = resolve_frames_dir(&manifest_path, &manifest, frames_dir);
        let mut paths = Vec::with_capacity(manifest.frame_count());
        for (b, block) in manifest.blocks.iter().enumerate() {
            for (i, file) in block.frames.iter().enumerate() {
                let path = dir.join(file);
                // The frame as named, or saved under another image extension (a capture
                // program that writes BMP frames for a manifest naming PNG ones).
                let Some(found) = find_image_file(&path) else {
                    // Something is there, but not a file that can be read.
                    if let Some(what) = not_a_regular_file(&path) {
                        return Err(CodecError::FrameNotAFile {
                            manifest: manifest_path.clone(),
                            block: b,
                            index: i,
                            path,
                            what,
                        });
                    }
                    return Err(CodecError::MissingFrame {
                        manifest: manifest_path.clone(),
                        block: b,
                        index: i,
                        file: file.clone(),
                        path,
                    });
                };
                paths.push(found);
            }
        }
        let frames = load_frames(&paths)?;
        let frame_names = paths.iter().map(|p| p.display().to_string()).collect();
        Ok(Self {
            manifest,
            frames,
            frame_names,
        })
    }

    /// Pairs a manifest with frames already in memory (in manifest order).
    ///
    /// # Errors
    /// [`CodecError::Frames`] if the count differs from the manifest's, [`CodecError::FrameSize`]
    /// if the frames differ in size.
    pub fn from_frames(manifest: Manifest, frames: Frames) -> Result<Self, CodecError> {
        if frames.len() != manifest.frame_count() {
            return Err(CodecError::Frames(format!(
                "the manifest lists {} frames, {} were given",
                manifest.frame_count(),
                frames.len()
            )));
        }
        frames.check_sizes()?;
        let frame_names = (0..frames.len()).map(|i| format!("#{i}")).collect();
        Ok(Self {
            manifest,
            frames,
            frame_names,
        })
    }
}

#[cfg(feature = "image-files")]
/// `path` itself, or the `manifest.json` in it when it is a folder.
pub(crate) fn manifest_file(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join(MANIFEST_FILE)
    } else {
        path.to_path_buf()
    }
}

#[cfg(feature = "image-files")]
/// The folder a manifest's frame names are relative to: `frames_dir` when given, else the
/// manifest's `frames_dir` (relative to the manifest's folder), else the manifest's folder.
pub(crate) fn resolve_frames_dir(
    manifest_path: &Path,
    manifest: &Manifest,
    frames_dir: Option<&Path>,
) -> PathBuf {
    let base_dir = manifest_path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    match (frames_dir, &manifest.frames_dir) {
        (Some(d), _) => d.to_path_buf(),
        (None, Some(d)) => base_dir.join(d),
        (None, None) => base_dir,
    }
}

#[cfg(feature = "image-files")]
/// Reads one image file as a grey frame ([`read_image`]): 8-bit grey stays 8-bit, 16-bit
/// grey stays 16-bit, colour is converted to grey by OpenCV's `COLOR_RGB2GRAY` rule at its own
/// depth, and float images become 16-bit. BMP, PGM/PPM, PNG, JPEG and TIFF are read.
///
/// # Errors
/// [`CodecError::Image`] naming the file.
pub fn load_frame(path: &Path) -> Result<Frames, CodecError> {
    Ok(match read_image(path)? {
        GreyImage::U8(f) => Frames::U8(vec![f]),
        GreyImage::U16(f) => Frames::U16(vec![f]),
    })
}

#[cfg(feature = "image-files")]
/// Loads frames in parallel; if any is 16-bit, all become 16-bit.
fn load_frames(paths: &[PathBuf]) -> Result<Frames, CodecError> {
    let loaded: Vec<GreyImage> = paths
        .par_iter()
        .map(|p| read_image(p))
        .collect::<Result<_, _>>()?;
    let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    let frames = Frames::from_images(loaded);
    match &frames {
        Frames::U8(v) => check_sizes(v, Some(&names))?,
        Frames::U16(v) => check_sizes(v, Some(&names))?,
    }
    Ok(frames)
}
