//! Robust finding of a feature whose position is not given: RANSAC for a sphere of known
//! radius (three points and the radius fix the centre, up to a mirror image) and for a plane,
//! then least-squares refinement on the inliers.

use nalgebra::{Matrix3, Point3, Vector3};

/// A small deterministic generator (SplitMix64): RANSAC draws reproducible samples without a
/// dependency, so a report is the same on every run.
pub(crate) struct SplitMix(u64);

impl SplitMix {
    pub(crate) fn new(seed: u64) -> Self {
        Self(seed)
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform index below `n` (`n > 0`).
    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Up to `max` points spread evenly over `points` (a fixed stride): RANSAC scores its
/// hypotheses on these.
pub(crate) fn subsample(points: &[Point3<f64>], max: usize) -> Vec<Point3<f64>> {
    if points.len() <= max {
        return points.to_vec();
    }
    let stride = points.len() as f64 / max as f64;
    (0..max)
        .filter_map(|k| points.get((k as f64 * stride) as usize).copied())
        .collect()
}

/// The two centres of the spheres of radius `r` through `a`, `b`, `c` (none when the points
/// are collinear or their circumcircle is wider than the sphere).
fn sphere_centres(
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
    r: f64,
) -> Option<[Point3<f64>; 2]> {
    let (u, v) = (b - a, c - a);
    let n = u.cross(&v);
    let n2 = n.norm_squared();
    if n2.is_nan() || n2 <= 1e-12 * u.norm_squared() * v.norm_squared() {
        return None;
    }
    // Circumcentre of the triangle.
    let offset = (v * u.norm_squared() - u * v.norm_squared()).cross(&n) / (2.0 * n2);
    let rho2 = offset.norm_squared();
    let h2 = r * r - rho2;
    if h2.is_nan() || h2 < 0.0 {
        return None;
    }
    let centre = a + offset;
    let up = n / n2.sqrt() * h2.sqrt();
    Some([centre + up, centre - up])
}

/// RANSAC: the centre of the sphere of radius `r` with the most `candidates` within `band` of
/// its surface, and that support.
pub(crate) fn ransac_sphere(
    candidates: &[Point3<f64>],
    r: f64,
    band: f64,
    iterations: usize,
    rng: &mut SplitMix,
) -> Option<(Point3<f64>, usize)> {
    let n = candidates.len();
    if n < 3 {
        return None;
    }
    let mut best: Option<(Point3<f64>, usize)> = None;
    for _ in 0..iterations {
        let (a, b, c) = (
            candidates[rng.below(n)],
            candidates[rng.below(n)],
            candidates[rng.below(n)],
        );
        let Some(centres) = sphere_centres(&a, &b, &c, r) else {
            continue;
        };
        for centre in centres {
            let support = candidates
                .iter()
                .filter(|p| ((*p - centre).norm() - r).abs() <= band)
                .count();
            if best.is_none_or(|(_, s)| support > s) {
                best = Some((centre, support));
            }
        }
    }
    best
}

/// RANSAC: the plane (unit normal, offset) with the most `candidates` within `band`, and that
/// support.
pub(crate) fn ransac_plane(
    candidates: &[Point3<f64>],
    band: f64,
    iterations: usize,
    rng: &mut SplitMix,
) -> Option<(Vector3<f64>, f64, usize)> {
    let n = candidates.len();
    if n < 3 {
        return None;
    }
    let mut best: Option<(Vector3<f64>, f64, usize)> = None;
    for _ in 0..iterations {
        let (a, b, c) = (
            candidates[rng.below(n)],
            candidates[rng.below(n)],
            candidates[rng.below(n)],
        );
        let (u, v) = (b - a, c - a);
        let normal = u.cross(&v);
        let n2 = normal.norm_squared();
        if n2.is_nan() || n2 <= 1e-12 * u.norm_squared() * v.norm_squared() {
            continue;
        }
        let normal = normal.normalize();
        let offset = normal.dot(&a.coords);
        let support = candidates
            .iter()
            .filter(|p| (normal.dot(&p.coords) - offset).abs() <= band)
            .count();
        if best.is_none_or(|(_, _, s)| support > s) {
            best = Some((normal, offset, support));
        }
    }
    best
}

/// Gauss–Newton steps of a sphere with a fixed radius: the centre that minimises the squared
/// radial residuals of `points`, from `centre`. Returns `centre` unchanged when the normal
/// equations are singular.
pub(crate) fn refine_centre(
    points: &[Point3<f64>],
    r: f64,
    mut centre: Point3<f64>,
) -> Point3<f64> {
    /// From a RANSAC start within the selection band the centre settles in 3–5 steps.
    const STEPS: usize = 10;
    for _ in 0..STEPS {
        let mut h = Matrix3::zeros();
        let mut g = Vector3::zeros();
        for p in points {
            let d = p - centre;
            let len = d.norm();
            if len == 0.0 {
                continue;
            }
            let u = d / len;
            // residual e = |p − c| − r, de/dc = −u
            h += u * u.transpose();
            g += u * (len - r);
        }
        let Some(inv) = h.try_inverse() else {
            return centre;
        };
        let step = inv * g;
        centre += step;
        if step.norm() < 1e-12 * r {
            break;
        }
    }
    centre
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// Three points of a known sphere: one of the two centres is the true one, and the other
    /// is its mirror image in the points' plane.
    #[test]
    fn three_points_and_the_radius_give_the_centre() {
        let c = Point3::new(3.0, -2.0, 400.0);
        let r = 25.0;
        let on =
            |t: f64, p: f64| c + Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), -t.cos()) * r;
        let (a, b, d) = (on(0.3, 0.0), on(0.9, 2.0), on(1.2, 4.0));
        let [c1, c2] = sphere_centres(&a, &b, &d, r).unwrap();
        let found = if (c1 - c).norm() < (c2 - c).norm() {
            c1
        } else {
            c2
        };
        assert_abs_diff_eq!(found, c, epsilon = 1e-9);
        for p in [a, b, d] {
            assert_abs_diff_eq!((p - c1).norm(), r, epsilon = 1e-9);
            assert_abs_diff_eq!((p - c2).norm(), r, epsilon = 1e-9);
        }
        // Collinear points, or a radius smaller than the circumcircle: no sphere.
        assert!(sphere_centres(&a, &(a + Vector3::x()), &(a + Vector3::x() * 2.0), r).is_none());
        assert!(sphere_centres(&a, &b, &d, 1.0).is_none());
    }
}
