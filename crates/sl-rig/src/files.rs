//! Writing what the devices produce: frames as a capture set in `sl-codec`'s format.

use std::path::Path;

use sl_codec::{Manifest, write_png_grey};

use crate::{GreyImage, RigError};

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
        write_png_grey(&dir.join(name.as_str()), frame)?;
    }
    let mut m = manifest.clone();
    m.frames_dir = None;
    m.description = Some(description.to_owned());
    m.save(&dir.join(sl_codec::MANIFEST_FILE))?;
    Ok(())
}
