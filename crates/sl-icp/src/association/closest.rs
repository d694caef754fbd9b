//! Closest-point association with the target's k-d tree.

use nalgebra::Point3;

use sl_cloud::KdIndex;

/// The closest target point to `p` strictly within squared distance `max_d2`:
/// `(index, squared distance)`.
#[inline]
pub(crate) fn find(index: &KdIndex, p: &Point3<f64>, max_d2: f64) -> Option<(u32, f64)> {
    index
        .nearest_within(p, max_d2)
        .map(|n| (n.index as u32, n.distance_squared))
}
