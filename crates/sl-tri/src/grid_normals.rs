//! Normals of an organised cloud from its pixel grid: the cross product of the horizontal and
//! vertical differences, central where both neighbours are valid, one-sided otherwise.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// Difference along one grid direction around `i`, given the neighbour before and after.
#[inline]
fn diff(
    points: &[Point3<f64>],
    i: usize,
    before: Option<usize>,
    after: Option<usize>,
) -> Option<Vector3<f64>> {
    let ok = |k: Option<usize>| k.and_then(|k| points.get(k)).filter(|p| p.z.is_finite());
    let centre = points.get(i)?;
    match (ok(before), ok(after)) {
        (Some(a), Some(b)) => Some(b - a),
        (None, Some(b)) => Some(b - centre),
        (Some(a), None) => Some(centre - a),
        (None, None) => None,
    }
}

/// Unit normals of the organised `points` (`width × height`, NaN = no point), facing the
/// camera at the origin; the zero vector where a pixel has no point or no neighbour pair.
pub(crate) fn grid_normals(points: &[Point3<f64>], width: usize) -> Vec<Vector3<f64>> {
    let mut normals = vec![Vector3::zeros(); points.len()];
    if width == 0 {
        return normals;
    }
    let height = points.len() / width;
    normals
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, n) in row.iter_mut().enumerate() {
                let i = y * width + x;
                let Some(p) = points.get(i).filter(|p| p.z.is_finite()) else {
                    continue;
                };
                let left = (x > 0).then(|| i - 1);
                let right = (x + 1 < width).then_some(i + 1);
                let up = (y > 0).then(|| i - width);
                let down = (y + 1 < height).then_some(i + width);
                let (Some(dx), Some(dy)) =
                    (diff(points, i, left, right), diff(points, i, up, down))
                else {
                    continue;
                };
                let c = dx.cross(&dy);
                let len = c.norm();
                if len > 0.0 && len.is_finite() {
                    let c = c / len;
                    *n = if c.dot(&p.coords) > 0.0 { -c } else { c };
                }
            }
        });
    normals
}
