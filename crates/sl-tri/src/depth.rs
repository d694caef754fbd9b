//! Depth maps as files: 16-bit PNG with a stated scale, and 32-bit float TIFF.

use std::path::Path;

use sl_codec::{CodecError, Frame, write_png_grey16, write_tiff_f32};

use crate::TriError;

/// Default scale of 16-bit depth PNGs: 0.02 mm per unit, so that 1 unit is finer than the
/// scanner's noise and 65535 units reach 1310 mm, beyond any working distance of a desktop rig.
pub const DEPTH_PNG_SCALE_MM: f64 = 0.02;

/// Depths (mm, NaN = none) as 16-bit units of `scale_mm`; 0 where there is no depth or it
/// does not fit (`depth / scale_mm` rounds outside `1..=65535`).
pub fn depth_to_u16(depth_mm: &[f32], scale_mm: f64) -> Vec<u16> {
    depth_mm
        .iter()
        .map(|&d| {
            let units = (f64::from(d) / scale_mm).round();
            if units >= 1.0 && units <= f64::from(u16::MAX) {
                units as u16
            } else {
                0
            }
        })
        .collect()
}

/// Writes a depth map (mm, NaN = none) as a 16-bit grey PNG: value = depth / `scale_mm`,
/// rounded; 0 = no depth.
///
/// # Errors
/// [`TriError::InvalidParameter`] for a scale that is not positive;
/// [`TriError::Codec`] for a wrong length or a failed write (naming the file).
pub fn write_depth_png16(
    path: &Path,
    width: usize,
    height: usize,
    depth_mm: &[f32],
    scale_mm: f64,
) -> Result<(), TriError> {
    if !(scale_mm > 0.0 && scale_mm.is_finite()) {
        return Err(TriError::param(
            "scale_mm",
            format!("{scale_mm} is not a positive number"),
        ));
    }
    let frame =
        Frame::new(width, height, depth_to_u16(depth_mm, scale_mm)).map_err(CodecError::from)?;
    Ok(write_png_grey16(path, &frame)?)
}

/// Writes a depth map (mm, NaN = none) as a 32-bit float TIFF (read by
/// `tifffile.imread` and `cv2.imread(path, cv2.IMREAD_UNCHANGED)`).
///
/// # Errors
/// [`TriError::Codec`] for a wrong length or a failed write (naming the file).
pub fn write_depth_tiff(
    path: &Path,
    width: usize,
    height: usize,
    depth_mm: &[f32],
) -> Result<(), TriError> {
    Ok(write_tiff_f32(path, width, height, depth_mm)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_round_and_refuse_what_does_not_fit() {
        let d = [f32::NAN, 0.0, 450.013, 1310.7, 1400.0, -3.0];
        // 450.013 / 0.02 = 22500.65 -> 22501; 1310.7 / 0.02 = 65535 exactly fits.
        assert_eq!(depth_to_u16(&d, 0.02), vec![0, 0, 22501, 65535, 0, 0]);
    }

    #[test]
    fn png_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("depth.png");
        let depth = [450.0f32, f32::NAN, 451.5, 300.02];
        write_depth_png16(&path, 2, 2, &depth, DEPTH_PNG_SCALE_MM).unwrap();
        assert!(path.exists());
        let tiff = dir.path().join("depth.tiff");
        write_depth_tiff(&tiff, 2, 2, &depth).unwrap();
        assert!(write_depth_tiff(&tiff, 3, 2, &depth).is_err());
        assert!(write_depth_png16(&path, 2, 2, &depth, 0.0).is_err());
    }
}
