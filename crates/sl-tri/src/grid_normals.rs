//! Normals of an organised cloud from its pixel grid: the cross product of the horizontal and
//! vertical differences, central where both neighbours are valid, one-sided otherwise.

use nalgebra::{Point3, Vector3};

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

/// Unit normal of the organised `points` (`width` columns, NaN = no point) at pixel `i`,
/// facing the camera at the origin; `None` where the pixel has no point or no neighbour pair.
/// Evaluated only at the cloud's points, so no full-image normal map is written.
#[inline]
pub(crate) fn normal_at(points: &[Point3<f64>], width: usize, i: usize) -> Option<Vector3<f64>> {
    if width == 0 {
        return None;
    }
    let height = points.len() / width;
    let p = points.get(i).filter(|p| p.z.is_finite())?;
    let (x, y) = (i % width, i / width);
    let left = (x > 0).then(|| i - 1);
    let right = (x + 1 < width).then_some(i + 1);
    let up = (y > 0).then(|| i - width);
    let down = (y + 1 < height).then_some(i + width);
    let dx = diff(points, i, left, right)?;
    let dy = diff(points, i, up, down)?;
    let c = dx.cross(&dy);
    let len = c.norm();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    let c = c / len;
    Some(if c.dot(&p.coords) > 0.0 { -c } else { c })
}
