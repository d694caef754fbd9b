//! The error heat map: a cloud coloured by its signed distance to the truth.

use sl_cloud::{PointCloud, PreviewColoring, PreviewConfig, PreviewImage, render_preview};

use crate::MetrologyError;

/// Default range of the heat map (mm): blue at −this, red at +this. Twice the 0.05 mm
/// probing target of the scanner, so a scan that meets it shows in the middle colours.
pub const DEFAULT_HEAT_MAP_RANGE_MM: f32 = 0.1;

/// Renders `cloud` (sl-cloud's shaded preview) coloured by `signed_mm` (one value per point,
/// as [`crate::Report::signed_distances_mm`]): blue at `−range_mm`, green at 0, red at
/// `+range_mm`, clamped beyond; points of no feature (NaN) are grey.
///
/// # Errors
/// [`MetrologyError::InvalidParameter`] for a range that is not positive, and the errors of
/// [`render_preview`] (a zero image size, a value count that is not the point count).
pub fn heat_map(
    cloud: &PointCloud,
    signed_mm: &[f32],
    range_mm: f32,
    view: &PreviewConfig,
) -> Result<PreviewImage, MetrologyError> {
    if !(range_mm.is_finite() && range_mm > 0.0) {
        return Err(MetrologyError::InvalidParameter {
            parameter: "range_mm",
            reason: format!("{range_mm} is not a positive length"),
        });
    }
    Ok(render_preview(
        cloud,
        PreviewColoring::Scalar {
            values: signed_mm,
            min: -range_mm,
            max: range_mm,
        },
        view,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// A flat patch whose left half is +range and right half −range: red on one side, blue on
    /// the other; unmeasured (NaN) points grey; a bad range is refused.
    #[test]
    fn colours_follow_the_sign() {
        let pts: Vec<_> = (0..400)
            .map(|k| Point3::new(f64::from(k % 20), f64::from(k / 20), 300.0))
            .collect();
        let values: Vec<f32> = (0..400)
            .map(|k| if k % 20 < 10 { -0.1 } else { 0.1 })
            .collect();
        let cloud = PointCloud::from_positions(pts);
        let view = PreviewConfig {
            width: 64,
            height: 64,
            ..PreviewConfig::default()
        };
        let img = heat_map(&cloud, &values, 0.1, &view).unwrap();
        let (mut reds, mut blues) = (0, 0);
        for y in 0..64 {
            for x in 0..64 {
                if img.is_background(x, y) {
                    continue;
                }
                let Some([r, _, b]) = img.pixel(x, y) else {
                    continue;
                };
                if r > b + 50 {
                    reds += 1;
                } else if b > r + 50 {
                    blues += 1;
                }
            }
        }
        assert!(reds > 100 && blues > 100, "{reds} red, {blues} blue");
        assert!(heat_map(&cloud, &values, 0.0, &view).is_err());
        assert!(heat_map(&cloud, &values[..3], 0.1, &view).is_err());
    }
}
