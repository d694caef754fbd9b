//! Normals of an organised cloud from its pixel grid: the cross product of the horizontal and
//! vertical differences, central where both neighbours are valid, one-sided otherwise.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// Difference along one grid direction, given the centre and the neighbours before and
/// after (NaN depth = no point).
#[inline(always)]
fn diff(
    centre: &Point3<f64>,
    before: Option<&Point3<f64>>,
    after: Option<&Point3<f64>>,
) -> Option<Vector3<f64>> {
    let before = before.filter(|p| p.z.is_finite());
    let after = after.filter(|p| p.z.is_finite());
    match (before, after) {
        (Some(a), Some(b)) => Some(b - a),
        (None, Some(b)) => Some(b - centre),
        (Some(a), None) => Some(centre - a),
        (None, None) => None,
    }
}

/// Unit normal at column `x` of the row `here` (with the rows above and below), facing the
/// camera at the origin; zero where there is no neighbour pair.
#[inline(always)]
pub(crate) fn normal_in_rows(
    here: &[Point3<f64>],
    above: Option<&[Point3<f64>]>,
    below: Option<&[Point3<f64>]>,
    x: usize,
    p: &Point3<f64>,
) -> Vector3<f64> {
    let left = x.checked_sub(1).and_then(|l| here.get(l));
    let dx = diff(p, left, here.get(x + 1));
    let dy = diff(
        p,
        above.and_then(|a| a.get(x)),
        below.and_then(|b| b.get(x)),
    );
    let (Some(dx), Some(dy)) = (dx, dy) else {
        return Vector3::zeros();
    };
    let c = dx.cross(&dy);
    let len = c.norm();
    if !(len > 0.0 && len.is_finite()) {
        return Vector3::zeros();
    }
    let c = c / len;
    if c.dot(&p.coords) > 0.0 { -c } else { c }
}

/// The normals of the points of the organised `points` (`width` columns, NaN = no point)
/// that have one, in pixel order, into `out` (whose length is their number). Bands of
/// `band_rows` rows in parallel; `counts` holds the number of points of each band (the
/// prefix sums that place each band's normals in `out`).
///
/// Hand-written row by row over three row slices: no index division or bounds arithmetic
/// per point, and no full-image normal map is written, only the cloud's normals.
pub(crate) fn cloud_normals(
    points: &[Point3<f64>],
    width: usize,
    band_rows: usize,
    counts: &[usize],
    out: &mut [Vector3<f64>],
) {
    if width == 0 {
        return;
    }
    let rows: Vec<&[Point3<f64>]> = points.chunks(width).collect();
    let mut slices = Vec::with_capacity(counts.len());
    let mut rest = out;
    for &c in counts {
        let (head, tail) = rest.split_at_mut(c.min(rest.len()));
        slices.push(head);
        rest = tail;
    }
    slices
        .into_par_iter()
        .enumerate()
        .for_each(|(band, slice)| {
            let mut out = slice.iter_mut();
            for y in band * band_rows..(band + 1) * band_rows {
                let Some(here) = rows.get(y).copied() else {
                    break;
                };
                let above = y.checked_sub(1).and_then(|a| rows.get(a)).copied();
                let below = rows.get(y + 1).copied();
                for (x, p) in here.iter().enumerate() {
                    if !p.z.is_finite() {
                        continue;
                    }
                    let Some(o) = out.next() else {
                        return;
                    };
                    *o = normal_in_rows(here, above, below, x, p);
                }
            }
        });
}
