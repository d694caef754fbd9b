//! The mixed-pixel filter: points at depth discontinuities, where a camera pixel sees both
//! the foreground and the background and decodes to a point between them, floating in the
//! air.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::PointStatus;

/// Rows per parallel task: ~16 k pixels at 1280 columns, enough to amortise a task.
const ROWS_PER_TASK: usize = 16;

/// Marks as [`PointStatus::MixedPixel`] every valid point whose depth differs from a valid
/// 4-neighbour's by more than `max_jump` times its own depth. Reads the depths as they were
/// before the pass (a point is never judged against an already removed neighbour), then
/// clears the removed points to NaN.
///
/// Row bands in parallel, hand-written over three row slices (above, current, below) so that
/// no per-pixel index arithmetic or bounds check is left in the loop.
pub(crate) fn filter_mixed_pixels(
    points: &mut [Point3<f64>],
    status: &mut [PointStatus],
    width: usize,
    max_jump: f64,
) {
    if width == 0 || !max_jump.is_finite() {
        return;
    }
    let mixed = mixed_flags(points, width, max_jump, |p| p.z);
    let nan = Point3::new(f64::NAN, f64::NAN, f64::NAN);
    points
        .par_chunks_mut(width * ROWS_PER_TASK)
        .zip(status.par_chunks_mut(width * ROWS_PER_TASK))
        .zip(mixed.par_chunks(width * ROWS_PER_TASK))
        .for_each(|((p, s), m)| {
            for ((p, s), &m) in p.iter_mut().zip(s.iter_mut()).zip(m) {
                if m {
                    *p = nan;
                    *s = PointStatus::MixedPixel;
                }
            }
        });
}

/// The mixed-pixel flags of a grid of `width` columns whose cells have the depth `z` (NaN: no
/// point): true where a valid cell's depth differs from a valid 4-neighbour's by more than
/// `max_jump` times its own. The grid is only read. The one-camera triangulation passes its
/// points, the binocular one a grid of depths alone (a quarter of the memory of the points).
pub(crate) fn mixed_flags<T: Sync>(
    cells: &[T],
    width: usize,
    max_jump: f64,
    z: impl Fn(&T) -> f64 + Sync,
) -> Vec<bool> {
    let mut mixed = vec![false; cells.len()];
    if width == 0 || !max_jump.is_finite() {
        return mixed;
    }
    let rows: Vec<&[T]> = cells.chunks(width).collect();
    mixed
        .par_chunks_mut(width * ROWS_PER_TASK)
        .enumerate()
        .for_each(|(band, flags)| {
            for (k, row_flags) in flags.chunks_mut(width).enumerate() {
                let y = band * ROWS_PER_TASK + k;
                let here = rows.get(y).copied().unwrap_or(&[]);
                let above = y.checked_sub(1).and_then(|a| rows.get(a)).copied();
                let below = rows.get(y + 1).copied();
                mark_row(here, above, below, max_jump, &z, row_flags);
            }
        });
    mixed
}

/// Flags of one row given its neighbours (NaN depths are no points and judge nothing).
#[inline]
fn mark_row<T>(
    here: &[T],
    above: Option<&[T]>,
    below: Option<&[T]>,
    max_jump: f64,
    z: &impl Fn(&T) -> f64,
    flags: &mut [bool],
) {
    let far = |zc: f64, limit: f64, n: Option<&T>| {
        // NaN neighbours compare false: no point, no judgement.
        n.is_some_and(|n| (z(n) - zc).abs() > limit)
    };
    for (x, (p, flag)) in here.iter().zip(flags.iter_mut()).enumerate() {
        let zc = z(p);
        if !zc.is_finite() {
            continue;
        }
        let limit = max_jump * zc;
        *flag = far(zc, limit, x.checked_sub(1).and_then(|l| here.get(l)))
            || far(zc, limit, here.get(x + 1))
            || far(zc, limit, above.and_then(|a| a.get(x)))
            || far(zc, limit, below.and_then(|b| b.get(x)));
    }
}
