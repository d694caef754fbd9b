//! The mixed-pixel filter: points at depth discontinuities, where a camera pixel sees both
//! the foreground and the background and decodes to a point between them, floating in the
//! air.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::PointStatus;

/// Marks as [`PointStatus::MixedPixel`] every valid point whose depth differs from a valid
/// 4-neighbour's by more than `max_jump` times its own depth. Reads the depths as they were
/// before the pass (a point is never judged against an already removed neighbour), then
/// clears the removed points to NaN.
pub(crate) fn filter_mixed_pixels(
    points: &mut [Point3<f64>],
    status: &mut [PointStatus],
    width: usize,
    max_jump: f64,
) {
    if width == 0 || !max_jump.is_finite() {
        return;
    }
    let height = points.len() / width;
    let depths: &[Point3<f64>] = points;
    let z = |k: usize| depths.get(k).map(|p| p.z).filter(|z| z.is_finite());
    let mixed: Vec<bool> = (0..points.len())
        .into_par_iter()
        .map(|i| {
            let Some(zc) = z(i) else { return false };
            let (x, y) = (i % width, i / width);
            let limit = max_jump * zc;
            let far = |k: usize| z(k).is_some_and(|zn| (zn - zc).abs() > limit);
            (x > 0 && far(i - 1))
                || (x + 1 < width && far(i + 1))
                || (y > 0 && far(i - width))
                || (y + 1 < height && far(i + width))
        })
        .collect();
    let nan = Point3::new(f64::NAN, f64::NAN, f64::NAN);
    for ((p, s), m) in points.iter_mut().zip(status.iter_mut()).zip(mixed) {
        if m {
            *p = nan;
            *s = PointStatus::MixedPixel;
        }
    }
}
