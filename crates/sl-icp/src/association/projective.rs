//! Projective data association for organised targets (as `KinectFusion` and the seed's scanner):
//! project the source point into the target camera and look only at the pixels around where
//! it lands.

use nalgebra::Point3;

use crate::prepared::Organized;

/// The closest target point among the pixels within `window` (Chebyshev distance) of the
/// projection of `p` (target camera frame): `(index, squared distance)`.
#[inline]
pub(crate) fn find(
    grid: &Organized,
    points: &[Point3<f64>],
    p: &Point3<f64>,
    window: usize,
) -> Option<(u32, f64)> {
    let (u, v) = grid.grid.pixel_of(p)?;
    let mut best: Option<(u32, f64)> = None;
    for y in v.saturating_sub(window)..=v.saturating_add(window) {
        for x in u.saturating_sub(window)..=u.saturating_add(window) {
            let Some(i) = grid.point_at(x, y) else {
                continue;
            };
            let Some(q) = points.get(i as usize) else {
                continue;
            };
            let d2 = (q - p).norm_squared();
            if best.is_none_or(|(_, b)| d2 < b) {
                best = Some((i, d2));
            }
        }
    }
    best
}
