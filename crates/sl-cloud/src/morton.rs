//! Spatial (Morton, Z-order) ordering of points, so that per-point neighbourhood queries run
//! over memory in a cache-friendly order.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::cloud::is_finite;
use crate::{CloudError, KdIndex};

/// A copy of a point set sorted in Z-order with a [`KdIndex`] over it. Per-point neighbourhood
/// loops run over `points` in this order (queries then touch neighbouring tree leaves and
/// neighbouring memory: 2 to 3 times faster on a shuffled cloud of a million points than in
/// input order), and [`scatter`](Self::scatter) puts the results back in input order.
pub(crate) struct SortedIndex {
    /// `order[j]` is the input index of `points[j]`.
    order: Vec<usize>,
    pub(crate) points: Vec<Point3<f64>>,
    pub(crate) index: KdIndex,
}

impl SortedIndex {
    pub(crate) fn new(input: &[Point3<f64>]) -> Result<Self, CloudError> {
        let order = morton_order(input);
        let points: Vec<Point3<f64>> = order
            .iter()
            .filter_map(|&i| input.get(i).copied())
            .collect();
        let index = KdIndex::new(&points)?;
        Ok(Self {
            order,
            points,
            index,
        })
    }

    /// Results computed in sorted order, back in input order.
    pub(crate) fn scatter<T: Clone + Default>(&self, sorted: Vec<T>) -> Vec<T> {
        let mut out = vec![T::default(); self.order.len()];
        for (&i, v) in self.order.iter().zip(sorted) {
            if let Some(slot) = out.get_mut(i) {
                *slot = v;
            }
        }
        out
    }
}

/// Bits per axis of the Morton code: 3 x 21 = 63 bits fit a `u64`.
const BITS: u32 = 21;

/// Spreads the low 21 bits of `v` so that bit i lands at bit 3 i.
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Indices of `points` sorted along a Z-order (Morton) curve over their bounding box, quantised
/// to 2²¹ steps per axis; ties by index, non-finite points last, in input order. Loops over
/// points or mesh vertices in this order touch neighbouring memory.
///
/// ```
/// use nalgebra::Point3;
/// let pts = [Point3::new(1.0, 1.0, 1.0), Point3::new(0.0, 0.0, 0.0)];
/// assert_eq!(sl_cloud::morton_order(&pts), vec![1, 0]);
/// ```
pub fn morton_order(points: &[Point3<f64>]) -> Vec<usize> {
    let mut lo = Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut hi = Point3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in points.iter().filter(|p| is_finite(p)) {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let extent = (hi - lo).max();
    let max_q = f64::from((1u32 << BITS) - 1);
    let scale = if extent > 0.0 && extent.is_finite() {
        max_q / extent
    } else {
        0.0
    };
    let mut keyed: Vec<(u64, usize)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            if !is_finite(p) {
                return (u64::MAX, i);
            }
            // In [0, max_q] by construction; `as` saturates anyway.
            let q = (p - lo).map(|v| (v * scale).clamp(0.0, max_q) as u64);
            (spread(q.x) | (spread(q.y) << 1) | (spread(q.z) << 2), i)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_interleaves() {
        assert_eq!(spread(0b1), 0b1);
        assert_eq!(spread(0b11), 0b1001);
        assert_eq!(spread(0x1f_ffff).count_ones(), 21);
        assert_eq!(spread(0x1f_ffff), 0x1249_2492_4924_9249);
    }

    #[test]
    fn order_is_a_permutation_following_the_z_curve() {
        // The 8 corners of a cube: Z-order is x fastest, then y, then z.
        let mut pts = Vec::new();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..2 {
                    pts.push(Point3::new(f64::from(x), f64::from(y), f64::from(z)));
                }
            }
        }
        pts.reverse();
        pts.push(Point3::new(f64::NAN, 0.0, 0.0));
        let order = morton_order(&pts);
        assert_eq!(order, vec![7, 6, 5, 4, 3, 2, 1, 0, 8]);
        assert!(morton_order(&[]).is_empty());
        assert_eq!(morton_order(&[Point3::origin(); 3]), vec![0, 1, 2]);
    }
}
