//! The radius of a disc on which the full distortion (radial and tangential) is one-to-one.
//!
//! The radial part alone is invertible up to its monotonic radius (see `monotonic.rs`).
//! Tangential terms can fold the map earlier: then a pixel has two preimages that both look
//! valid, and Newton may return the wrong one. We therefore restrict the valid region to a
//! disc `r < R` on which the map `F` is *proven* injective, by this argument:
//!
//! In polar coordinates `p = r (cos φ, sin φ)`, if on the disc (a) `det J > 0` and (b) the
//! image of every circle `r = const` turns strictly around the origin (`∂ arg F/∂φ > 0`),
//! then each image circle is star-shaped with winding number 1 (it is 1 near the centre
//! and stays an integer), and along every direction θ its radius grows strictly with `r`
//! (`∂ρ*/∂r = det_polar / θ_φ > 0`). Image circles are then nested and disjoint, so `F` is
//! one-to-one on the disc.
//!
//! With `a = f(s)`, `b = f'(s)`, `g = a + 2 s b` (the radial derivative), `|p| = |(p1, p2)|`,
//! writing `F = a p + T(p)` with the tangential part `T`, one finds exactly
//! `det J = a g + (8a + 4bs)(p1 y + p2 x) + (t1 t3 − t2²)` and bounds
//! `|p1 y + p2 x| ≤ |p| r`, `|t1 t3 − t2²| ≤ 40 |p|² s`, `|T| ≤ 3√2 |p| s`,
//! `‖∂T/∂p‖ ≤ 8 |p| r`, so that (a) and (b) hold wherever
//!
//! ```text
//! a g − |8a + 4bs| |p| r − 40 |p|² s > 0    and    a² − 12.25 a |p| r − 34 |p|² s > 0.
//! ```
//!
//! Both depend on `r` only. We scan them on [`SAMPLES`] log-spaced radii up to the radial
//! limit and bisect the first failure. They are sufficient, not necessary, conditions, so
//! `R` is conservative; for realistic lenses (|p| ≲ 0.01) it only trims a few per cent off
//! the radial limit, far outside any image.

/// Radii scanned between [`LOWEST_FRACTION`]·`r_hi` and `r_hi` (log-spaced: ratio 1.007
/// between neighbours, fine enough that a smooth bound cannot dip below zero unseen).
const SAMPLES: usize = 2048;

/// Smallest radius scanned, relative to the upper end. Below it the bounds hold for any
/// |p| < 1e4, i.e. for any coefficients anyone has calibrated.
const LOWEST_FRACTION: f64 = 1e-6;

/// Bisection steps to locate the first failure between two samples (2⁻⁶⁰ of the gap).
const BISECTIONS: usize = 60;

/// Largest radius `R ≤ r_hi` such that the sufficient injectivity conditions hold on the
/// whole disc `r < R`. `k` are the OpenCV coefficients `k1 k2 p1 p2 k3 k4 k5 k6`, `r_hi` a
/// radius up to which the radial part is strictly increasing with a positive denominator.
pub(crate) fn injective_radius(k: &[f64; 8], r_hi: f64) -> f64 {
    let pn = k[2].hypot(k[3]);
    if pn == 0.0 {
        return r_hi;
    }
    let holds = |r: f64| conditions_hold(k, pn, r);
    let r_lo = r_hi * LOWEST_FRACTION;
    if !holds(r_lo) {
        return 0.0;
    }
    let ratio = (r_hi / r_lo).ln();
    let mut last_ok = r_lo;
    for i in 1..=SAMPLES {
        let r = r_lo * (ratio * i as f64 / SAMPLES as f64).exp();
        if !holds(r) {
            let (mut lo, mut hi) = (last_ok, r);
            for _ in 0..BISECTIONS {
                let mid = 0.5 * (lo + hi);
                if holds(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return lo;
        }
        last_ok = r;
    }
    r_hi
}

fn conditions_hold(k: &[f64; 8], pn: f64, r: f64) -> bool {
    let [k1, k2, _, _, k3, k4, k5, k6] = *k;
    let s = r * r;
    let n = 1.0 + s * (k1 + s * (k2 + s * k3));
    let d = 1.0 + s * (k4 + s * (k5 + s * k6));
    let dn = k1 + s * (2.0 * k2 + 3.0 * k3 * s);
    let dd = k4 + s * (2.0 * k5 + 3.0 * k6 * s);
    let a = n / d;
    let b = (dn - a * dd) / d;
    let g = a + 2.0 * s * b;
    let det_lb = a * g - (8.0 * a + 4.0 * b * s).abs() * pn * r - 40.0 * pn * pn * s;
    let turn_lb = a * a - 12.25 * a * pn * r - 34.0 * pn * pn * s;
    d > 0.0 && a > 0.0 && det_lb > 0.0 && turn_lb > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_tangential_terms_keep_the_radial_limit() {
        assert_eq!(
            injective_radius(&[-0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1.2),
            1.2
        );
    }

    #[test]
    fn pure_tangential_closed_form() {
        // k = 0, p = (p1, 0): a = 1, b = 0, g = 1. The conditions become
        // 1 − 8 p r − 40 p² r² > 0 and 1 − 12.25 p r − 34 p² r² > 0; the second binds:
        // p r = (−12.25 + √(12.25² + 4·34)) / (2·34).
        let p = 0.05;
        let r = injective_radius(&[0.0, 0.0, p, 0.0, 0.0, 0.0, 0.0, 0.0], 100.0);
        let want = (-12.25 + (12.25_f64 * 12.25 + 4.0 * 34.0).sqrt()) / (2.0 * 34.0) / p;
        assert!(
            (r - want).abs() <= 1e-12 * want && r <= want,
            "{r} vs {want}"
        );
    }

    #[test]
    fn reference_lens_keeps_its_image() {
        // The reference design's image corners are at r ≈ 0.5; its disc is far larger.
        let r = injective_radius(
            &[0.5466, -20.20, -0.02203, 0.008259, 211.1, 0.0, 0.0, 0.0],
            100.0,
        );
        assert!(r > 1.0, "{r}");
    }
}
