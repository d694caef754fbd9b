//! Normal shooting (Chen & Medioni 1992): the target point where the source point's normal
//! line meets the target surface, found by intersecting the line with the tangent plane of
//! the current target point and taking the target point closest to that intersection.

use nalgebra::{Point3, Vector3};

use sl_cloud::KdIndex;

/// Line-plane intersection steps: the first lands on the surface to first order, the second
/// corrects for curvature; more changed nothing on the bunny.
const STEPS: usize = 2;

/// `|cos|` of the angle between the source normal and the target normal below which the line
/// is taken to graze the surface (beyond ~84°) and the closest point is kept.
const MIN_COS: f64 = 0.1;

/// The target point hit by the normal line of `p` (unit normal `n`, target frame):
/// `(index, squared distance to p)`, searched within squared distance `max_d2` of `p` (and of
/// each intersection). Falls back to the closest point where normals are missing (zero), the
/// line grazes the surface or leaves the target.
#[inline]
pub(crate) fn find(
    index: &KdIndex,
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    p: &Point3<f64>,
    n: &Vector3<f64>,
    max_d2: f64,
) -> Option<(u32, f64)> {
    let (mut j, mut d2) = super::closest::find(index, p, max_d2)?;
    for _ in 0..STEPS {
        let (Some(q), Some(nq)) = (points.get(j as usize), normals.get(j as usize)) else {
            break;
        };
        let cos = n.dot(nq);
        if cos.abs() < MIN_COS {
            break;
        }
        let s = (q - p).dot(nq) / cos;
        let x = p + n * s;
        let Some((k, _)) = super::closest::find(index, &x, max_d2) else {
            break;
        };
        if k == j {
            break;
        }
        j = k;
        d2 = points
            .get(k as usize)
            .map_or(f64::INFINITY, |q| (q - p).norm_squared());
    }
    Some((j, d2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_the_normal_not_the_closest_point() {
        // Target: the plane z = 0 sampled every 0.1 on [-5, 5]^2. Source point above (1, 0)
        // at height 3 with a normal tilted 30° in x: the normal line meets the plane at
        // x = 1 - 3 tan 30° = -0.732, while the closest point is (1, 0, 0).
        let mut pts = Vec::new();
        for i in -50..=50 {
            for j in -50..=50 {
                pts.push(Point3::new(i as f64 * 0.1, j as f64 * 0.1, 0.0));
            }
        }
        let normals = vec![Vector3::z(); pts.len()];
        let index = KdIndex::new(&pts).unwrap();
        let p = Point3::new(1.0, 0.0, 3.0);
        let (a, b) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
        let n = Vector3::new(a, 0.0, b);
        let (j, _) = find(&index, &pts, &normals, &p, &n, 100.0).unwrap();
        let hit = pts[j as usize];
        assert!((hit.x - (1.0 - 3.0 * 30f64.to_radians().tan())).abs() <= 0.05 + 1e-12);
        assert_eq!(hit.y, 0.0);
        // A grazing normal keeps the closest point.
        let (j, d2) = find(&index, &pts, &normals, &p, &Vector3::x(), 100.0).unwrap();
        assert_eq!(pts[j as usize], Point3::new(1.0, 0.0, 0.0));
        assert!((d2 - 9.0).abs() < 1e-12);
    }
}
