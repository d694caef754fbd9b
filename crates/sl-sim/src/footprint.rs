//! Area integration of textures: the albedo a camera sub-sample sees is the texture averaged
//! over the patch of surface its square covers (its *footprint*), not the texture at its
//! centre.
//!
//! Point sampling puts every edge of a printed pattern on the sub-sample grid: with `s × s`
//! sub-samples an edge parallel to the pixel grid can only land on multiples of `1/s` px, up to
//! `1/(2s)` px from where it is (0.25 px with the default 2 × 2). A checkerboard's corners,
//! found from those edges, inherit the error, and so does every calibration made from renders.
//!
//! Here a sub-sample's footprint is the parallelogram its square maps to on the surface's
//! tangent plane (exact for a plane seen through a locally affine lens: the perspective's
//! curvature over a fraction of a pixel is below 1e-6 px). Along one texture axis, the
//! coordinate of a point drawn uniformly in the parallelogram has a *trapezoid* distribution
//! (the sum of two uniform variables, one per edge vector), whose distribution function is
//! piecewise quadratic ([`trapezoid_cdf`]); the mean of a piecewise-constant function of one
//! coordinate (the stripes of a square wave, the box of a board's printed area) is then exact.
//! Textures that vary along two or three axes (a checkerboard, a 3-D checker) are written as
//! products of one-axis square waves and averaged axis by axis: exact wherever only one edge
//! crosses the footprint, and within a fraction of a sub-sample's area next to a corner, where
//! the footprint's two axes are not independent.

use nalgebra::{Point3, Vector3};

/// Largest number of stripes a footprint may cross along one axis before its average is taken
/// as the texture's mean (`0` for a square wave): a footprint that wide is a grazing view of
/// the texture, where the exact sum would cost time for a value no detector resolves.
const MAX_STRIPES: f64 = 32.0;

/// A sub-sample's footprint on a surface, in the texture's frame (mm): the centre and the two
/// edge vectors of the parallelogram (the images of the sub-sample square's sides).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Footprint {
    /// Centre of the parallelogram.
    pub(crate) centre: Point3<f64>,
    /// Image of the sub-sample's side along the camera's `x`.
    pub(crate) edge_x: Vector3<f64>,
    /// Image of the sub-sample's side along the camera's `y`.
    pub(crate) edge_y: Vector3<f64>,
}

impl Footprint {
    /// The distribution of coordinate `axis` (0, 1, 2) over the footprint.
    pub(crate) fn axis(&self, axis: usize) -> Spread {
        Spread {
            centre: self.centre[axis],
            half_a: 0.5 * self.edge_x[axis].abs(),
            half_b: 0.5 * self.edge_y[axis].abs(),
        }
    }
}

/// One coordinate of a point drawn uniformly in a parallelogram: `centre + U(−a, a) + U(−b, b)`
/// (`a`, `b` the half-projections of the two edges on the axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Spread {
    pub(crate) centre: f64,
    pub(crate) half_a: f64,
    pub(crate) half_b: f64,
}

/// Below this ratio of the two half-widths the narrower one is taken as zero (the uniform
/// distribution of the wider): the trapezoid formula divides by their product.
const DEGENERATE_RATIO: f64 = 1e-9;

impl Spread {
    /// Half-width of the whole distribution.
    fn reach(&self) -> f64 {
        self.half_a + self.half_b
    }

    /// `P(X ≤ x)`.
    pub(crate) fn cdf(&self, x: f64) -> f64 {
        trapezoid_cdf(x - self.centre, self.half_a, self.half_b)
    }

    /// The mean of `value` over the distribution, `value` being constant between consecutive
    /// `breaks` (sorted, any that fall outside the support are ignored).
    fn mean_piecewise(&self, breaks: &[f64], value: impl Fn(f64) -> f64) -> f64 {
        let (lo, hi) = (self.centre - self.reach(), self.centre + self.reach());
        if hi <= lo {
            return value(self.centre);
        }
        let mut acc = 0.0;
        let mut start = lo;
        let mut p_start = 0.0;
        for &b in breaks.iter().filter(|&&b| b > lo && b < hi) {
            let p = self.cdf(b);
            acc += value(0.5 * (start + b)) * (p - p_start);
            start = b;
            p_start = p;
        }
        acc + value(0.5 * (start + hi)) * (1.0 - p_start)
    }

    /// The mean of the square wave that is `+1` on `[2k·s, (2k+1)·s)` and `−1` on the other
    /// half-periods (`s = square`), times the indicator of `[box_lo, box_hi)` when a box is
    /// given. `0` (the wave's mean) when the spread covers more than [`MAX_STRIPES`] squares.
    pub(crate) fn mean_square_wave(&self, square: f64, bounds: Option<(f64, f64)>) -> f64 {
        let inside = |x: f64| bounds.is_none_or(|(lo, hi)| x >= lo && x < hi);
        let wave = |x: f64| {
            if !inside(x) {
                0.0
            } else if (x / square).floor().rem_euclid(2.0) < 0.5 {
                1.0
            } else {
                -1.0
            }
        };
        let reach = self.reach();
        if reach > MAX_STRIPES * square {
            return 0.0;
        }
        let (lo, hi) = (self.centre - reach, self.centre + reach);
        let first = (lo / square).ceil() as i64;
        let last = (hi / square).floor() as i64;
        let mut breaks: Vec<f64> = (first..=last).map(|k| k as f64 * square).collect();
        if let Some((b0, b1)) = bounds {
            breaks.extend([b0, b1]);
            breaks.sort_by(f64::total_cmp);
        }
        self.mean_piecewise(&breaks, wave)
    }

    /// The share of the distribution inside `[lo, hi)`.
    pub(crate) fn mean_box(&self, lo: f64, hi: f64) -> f64 {
        (self.cdf(hi) - self.cdf(lo)).clamp(0.0, 1.0)
    }
}

/// `P(U_a + U_b ≤ x)` for independent `U_a ~ U(−a, a)`, `U_b ~ U(−b, b)`: the area of the part
/// of the rectangle `[−a, a] × [−b, b]` below the line `u + v = x`, by inclusion–exclusion of
/// the four corner quadrants (each a right triangle of area `max(0, x − corner)² / 2`).
pub(crate) fn trapezoid_cdf(x: f64, a: f64, b: f64) -> f64 {
    let (a, b) = if a >= b { (a, b) } else { (b, a) };
    if a <= 0.0 {
        return if x >= 0.0 { 1.0 } else { 0.0 };
    }
    if b <= DEGENERATE_RATIO * a {
        return ((x + a) / (2.0 * a)).clamp(0.0, 1.0);
    }
    let r = |z: f64| if z > 0.0 { z * z } else { 0.0 };
    let area = r(x + a + b) - r(x - a + b) - r(x + a - b) + r(x - a - b);
    (area / (8.0 * a * b)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// The closed form against a Monte-Carlo count of `U_a + U_b ≤ x`.
    #[test]
    fn trapezoid_cdf_matches_sampling() {
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        let n = 200_000;
        for (a, b) in [(1.0, 0.3), (0.2, 0.7), (0.5, 0.5), (1.0, 0.0)] {
            let samples: Vec<f64> = (0..n)
                .map(|_| {
                    rng.random_range(-a..=a)
                        + if b > 0.0 {
                            rng.random_range(-b..=b)
                        } else {
                            0.0
                        }
                })
                .collect();
            for x in [-1.2, -0.9, -0.4, -0.1, 0.0, 0.25, 0.6, 1.1, 1.5] {
                let count = samples.iter().filter(|&&s| s <= x).count() as f64 / n as f64;
                // Binomial standard error at n = 2e5 is at most 0.0011; 5 of them.
                assert_abs_diff_eq!(trapezoid_cdf(x, a, b), count, epsilon = 0.0056);
            }
        }
        // Symmetric, and the degenerate cases.
        assert_abs_diff_eq!(trapezoid_cdf(0.0, 0.3, 0.8), 0.5, epsilon = 1e-15);
        assert_abs_diff_eq!(trapezoid_cdf(0.1, 0.0, 0.0), 1.0);
        assert_abs_diff_eq!(trapezoid_cdf(-0.1, 0.0, 0.0), 0.0);
    }

    /// The footprint's mean of a square wave equals a brute-force average over a fine grid of
    /// points of the parallelogram.
    #[test]
    fn square_wave_mean_matches_a_dense_average() {
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        for _ in 0..200 {
            let fp = Footprint {
                centre: Point3::new(rng.random_range(-30.0..30.0), 0.0, 0.0),
                edge_x: Vector3::new(rng.random_range(-3.0..3.0), 0.0, 0.0),
                edge_y: Vector3::new(rng.random_range(-3.0..3.0), 0.0, 0.0),
            };
            let square = 2.0;
            let bounds = Some((-11.0, 13.0));
            let got = fp.axis(0).mean_square_wave(square, bounds);
            let m = 400;
            let mut acc = 0.0;
            for i in 0..m {
                for j in 0..m {
                    let t = (i as f64 + 0.5) / m as f64 - 0.5;
                    let u = (j as f64 + 0.5) / m as f64 - 0.5;
                    let x = fp.centre.x + t * fp.edge_x.x + u * fp.edge_y.x;
                    let inside = (-11.0..13.0).contains(&x);
                    let s = if (x / square).floor().rem_euclid(2.0) < 0.5 {
                        1.0
                    } else {
                        -1.0
                    };
                    acc += if inside { s } else { 0.0 };
                }
            }
            let want = acc / (m * m) as f64;
            // A 400 × 400 grid resolves an edge to 1/400 of the footprint: 2 / 400 of the mean.
            assert_abs_diff_eq!(got, want, epsilon = 0.006);
        }
    }

    /// A straight printed edge at any angle and sub-pixel position lands where the truth puts
    /// it: on every camera row that crosses the edge between a light and a dark square, the
    /// edge's position recovered from the row's summed albedo (light on one side, dark on the
    /// other, so the sum is linear in the position) is within 0.01 px of the true edge
    /// projected by the lens (distortion included). With point sampling (the texture read at
    /// each sub-sample's centre) the same rows are up to 1/(2s) px off: 0.25 px with 2 × 2
    /// sub-samples, checked by hand with `footprint_albedo` returning `hit.albedo`.
    #[test]
    fn printed_edges_land_where_the_truth_says() {
        use crate::{Checkerboard, Mount, RigConfig, Scene, SceneObject, VirtualRig};
        use nalgebra::{Isometry3, Translation3, UnitQuaternion};
        use sl_camera::{ImageSize, Intrinsics};

        let mut config = RigConfig::default();
        // A small camera with the default lens's distortion (normalised coefficients).
        config.camera.size = ImageSize::new(240, 180);
        config.camera.intrinsics = Intrinsics::new(300.0, 300.0, 119.5, 89.5);
        config.render.supersampling = 2;
        let board = Checkerboard {
            inner_cols: 3,
            inner_rows: 3,
            square_mm: 60.0,
            ..Checkerboard::default()
        };
        let (light, dark) = (board.light_albedo, board.dark_albedo);
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let mut worst = 0.0f64;
        let mut rows = 0;
        for trial in 0..20 {
            // In-plane angle up to 40°, a tilt up to 35°, a random sub-pixel placement; the
            // first trial is axis-aligned, point sampling's worst case.
            let roll = if trial == 0 {
                0.0
            } else {
                rng.random_range(-40.0f64..40.0)
            };
            let tilt = if trial == 0 {
                0.0
            } else {
                rng.random_range(-35.0f64..35.0)
            };
            let rotation = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt.to_radians())
                * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll.to_radians());
            let centre = Vector3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(480.0..520.0),
            );
            // The grid's centre (60, 60) at `centre`.
            let t = centre - rotation * Vector3::new(60.0, 60.0, 0.0);
            let pose = Isometry3::from_parts(Translation3::from(t), rotation);
            let scene = Scene::new().with(SceneObject::board("board", board, Mount::Camera, pose));
            let rig = VirtualRig::new(config.clone(), scene).unwrap();
            let view = rig.view(0.0, 0).unwrap();
            let g = &view.geometry;
            let (w, per) = (
                g.width as usize,
                (g.supersampling * g.supersampling) as usize,
            );
            let mean_albedo = |x: usize, y: usize| -> f64 {
                let i = (y * w + x) * per;
                g.ambient_weight[i..i + per]
                    .iter()
                    .map(|&a| f64::from(a))
                    .sum::<f64>()
                    / per as f64
            };
            // The edge x = 60 mm between square (0, 1) (x < 60, dark: 0 + 1 odd? see below)
            // and square (1, 1): the board's square (i, j) is dark when i + j is even, so
            // (0, 1) is light and (1, 1) dark. Walk it from y = 75 to 105 mm (away from corners).
            let project = |v: f64| {
                config
                    .camera
                    .project(&(pose * Point3::new(60.0, v, 0.0)))
                    .unwrap()
            };
            let (a, b) = (project(75.0), project(105.0));
            let (y0, y1) = (a.y.min(b.y).ceil() as usize, a.y.max(b.y).floor() as usize);
            for row in y0..=y1 {
                // The true edge at this row's centre: bisect v along the projected edge.
                let (mut lo, mut hi) = (75.0, 105.0);
                let increasing = b.y > a.y;
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if (project(mid).y < row as f64) == increasing {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let xe = project(0.5 * (lo + hi)).x;
                let (x0, x1) = ((xe - 8.0).round() as usize, (xe + 8.0).round() as usize);
                let sum: f64 = (x0..=x1).map(|x| mean_albedo(x, row)).sum();
                // Light on [x0 − ½, xe), dark on [xe, x1 + ½).
                let got =
                    (sum - dark * (x1 as f64 + 0.5) + light * (x0 as f64 - 0.5)) / (light - dark);
                worst = worst.max((got - xe).abs());
                rows += 1;
            }
        }
        eprintln!("worst {worst:.5} px over {rows} rows");
        assert!(rows > 250, "{rows} rows measured");
        assert!(
            worst <= 0.01,
            "worst edge position error {worst:.4} px over {rows} rows"
        );
    }
}
