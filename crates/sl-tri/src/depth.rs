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

/// The scales (mm per unit, smallest and largest) at which every depth of `depth_mm` (mm; NaN
/// and non-positive values are no depth) is stored in a 16-bit depth PNG without loss: the
/// farthest within 65535 units, the nearest at least 1 unit. `None` when there is no depth.
pub fn depth_png_scale_range(depth_mm: &[f32]) -> Option<(f64, f64)> {
    let (near, far) = depth_mm
        .iter()
        .map(|&d| f64::from(d))
        .filter(|d| d.is_finite() && *d > 0.0)
        .fold(None, |acc: Option<(f64, f64)>, d| {
            Some(acc.map_or((d, d), |(lo, hi)| (lo.min(d), hi.max(d))))
        })?;
    Some((far / f64::from(u16::MAX), near))
}

/// Checks that every depth of `depth_mm` fits a 16-bit depth PNG at `scale_mm` mm per unit
/// ([`depth_png_scale_range`]); a map with no depth passes.
///
/// # Errors
/// [`TriError::InvalidParameter`] naming `scale_mm`, its value, the depths and the range of
/// scales that holds them: at a larger scale the nearest depths round to 0 (no depth), at a
/// smaller one the farthest do not fit.
pub fn check_depth_png_scale(depth_mm: &[f32], scale_mm: f64) -> Result<(), TriError> {
    let Some((lo, hi)) = depth_png_scale_range(depth_mm) else {
        return Ok(());
    };
    if scale_mm.is_finite() && (lo..=hi).contains(&scale_mm) {
        return Ok(());
    }
    Err(TriError::param(
        "scale_mm",
        format!(
            "{scale_mm}: the depths from {hi:.4} to {:.4} mm fit a 16-bit depth PNG (1 to \
             65535 units) at {lo:.6} to {hi:.4} mm per unit",
            lo * f64::from(u16::MAX)
        ),
    ))
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
    fn the_scale_range_holds_every_depth() {
        let d = [f32::NAN, 0.0, 400.0, 500.0, -3.0];
        let (lo, hi) = depth_png_scale_range(&d).unwrap();
        assert!((lo - 500.0 / 65535.0).abs() < 1e-12 && (hi - 400.0).abs() < 1e-9);
        for scale in [lo, 0.02, hi] {
            check_depth_png_scale(&d, scale).unwrap();
            let u = depth_to_u16(&d, scale);
            assert!(u[2] >= 1 && u[3] >= 1, "{scale}: {u:?}");
        }
        for scale in [1e-6, 0.99 * lo, 1.01 * hi, 1e6, f64::NAN] {
            let e = check_depth_png_scale(&d, scale).unwrap_err().to_string();
            assert!(e.contains("scale_mm") && e.contains("mm per unit"), "{e}");
        }
        assert!(depth_png_scale_range(&[f32::NAN]).is_none());
    }

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
