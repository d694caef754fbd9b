//! Where the radial distortion stops being invertible.
//!
//! OpenCV's radial factor is `f(s) = N(s) / D(s)` with `s = r²`,
//! `N = 1 + k1 s + k2 s² + k3 s³` and `D = 1 + k4 s + k5 s² + k6 s³`. The distorted radius
//! `r·f(r²)` is strictly increasing — so the radial part can be inverted — as long as
//! `D > 0` and
//!
//! ```text
//! d(r f)/dr = [N D + 2 s (N' D − N D')] / D²  > 0,
//! ```
//!
//! i.e. as long as the degree-6 polynomial `P(s) = N D + 2 s (N' D − N D')` stays positive.
//! Both `P` and `D` equal 1 at `s = 0`. We look for the first `s` where either is no longer
//! positive, with a *certified* test: a polynomial whose Bernstein coefficients on an
//! interval are all positive is positive on the whole interval, and subdividing the interval
//! makes the test sharp. When the test cannot decide (within [`RELATIVE_RESOLUTION`]), we
//! report the left end of the undecided interval, so the limit we give is never beyond the
//! true one.

/// Search range for `r`: tan(89.4°). No lens described by these polynomial models images
/// rays that oblique, the polynomial was never fitted there, and the powers of `r²` up to
/// the 6th stay far from overflow; beyond this radius we make no claim and refuse.
pub(crate) const RADIUS_CAP: f64 = 100.0;

/// Width (relative to its right end) below which an undecided interval is not split again:
/// near f64 resolution, where Bernstein signs are decided by rounding.
const RELATIVE_RESOLUTION: f64 = 1e-13;

/// Bisection depth limit: 2⁻¹⁰⁰ of the search range is far below [`RELATIVE_RESOLUTION`],
/// so this only guards against a pathological loop.
const MAX_DEPTH: u32 = 100;

/// Polynomial of degree ≤ 6 in ascending powers.
type Poly = [f64; 7];

/// Squared normalised radius `s_max` up to which the radial distortion with OpenCV
/// coefficients `k = [k1, k2, p1, p2, k3, k4, k5, k6]` is strictly increasing with a positive
/// denominator, searched up to [`RADIUS_CAP`]². `f64::INFINITY` when the radial part is the
/// identity (all radial coefficients zero).
pub(crate) fn monotonic_limit_squared(k: &[f64; 8]) -> f64 {
    let [k1, k2, _, _, k3, k4, k5, k6] = *k;
    if [k1, k2, k3, k4, k5, k6].iter().all(|&c| c == 0.0) {
        return f64::INFINITY;
    }
    let n = [1.0, k1, k2, k3];
    let d = [1.0, k4, k5, k6];
    let dn = [k1, 2.0 * k2, 3.0 * k3];
    let dd = [k4, 2.0 * k5, 3.0 * k6];
    let mut p: Poly = [0.0; 7];
    for (i, ni) in n.iter().enumerate() {
        for (j, dj) in d.iter().enumerate() {
            p[i + j] += ni * dj;
        }
    }
    // + 2 s (N' D − N D'): degrees 0..=5 shifted by one.
    for (i, dni) in dn.iter().enumerate() {
        for (j, dj) in d.iter().enumerate() {
            p[i + j + 1] += 2.0 * dni * dj;
        }
    }
    for (i, ni) in n.iter().enumerate() {
        for (j, ddj) in dd.iter().enumerate() {
            p[i + j + 1] -= 2.0 * ni * ddj;
        }
    }
    let mut den: Poly = [0.0; 7];
    den[..4].copy_from_slice(&d);
    let cap = RADIUS_CAP * RADIUS_CAP;
    let a = first_nonpositive(&p, 0.0, cap, 0).unwrap_or(cap);
    let b = first_nonpositive(&den, 0.0, cap, 0).unwrap_or(cap);
    a.min(b)
}

/// Smallest `s` in `[lo, hi]` (up to resolution, never overestimated) where `poly(s) <= 0`,
/// or `None` if `poly` is positive on the whole interval.
fn first_nonpositive(poly: &Poly, lo: f64, hi: f64, depth: u32) -> Option<f64> {
    let beta = bernstein(poly, lo, hi);
    if beta.iter().all(|&b| b > 0.0) {
        return None;
    }
    if beta[0].is_nan()
        || beta[0] <= 0.0
        || depth >= MAX_DEPTH
        || hi - lo <= RELATIVE_RESOLUTION * hi
    {
        return Some(lo);
    }
    let mid = 0.5 * (lo + hi);
    first_nonpositive(poly, lo, mid, depth + 1)
        .or_else(|| first_nonpositive(poly, mid, hi, depth + 1))
}

/// Bernstein coefficients of `poly` on `[lo, hi]`.
fn bernstein(poly: &Poly, lo: f64, hi: f64) -> Poly {
    const N: usize = 6;
    // Taylor shift: coefficients of q(t) = poly(lo + t).
    let mut c = *poly;
    for i in 0..N {
        for j in (i..N).rev() {
            c[j] += lo * c[j + 1];
        }
    }
    // Scale: t = (hi − lo) τ, τ in [0, 1].
    let h = hi - lo;
    let mut hp = 1.0;
    for cj in &mut c {
        *cj *= hp;
        hp *= h;
    }
    // Power basis on [0, 1] -> Bernstein: β_i = Σ_{j≤i} C(i,j)/C(n,j) c_j.
    const BINOM: [[f64; 7]; 7] = [
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [1.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        [1.0, 3.0, 3.0, 1.0, 0.0, 0.0, 0.0],
        [1.0, 4.0, 6.0, 4.0, 1.0, 0.0, 0.0],
        [1.0, 5.0, 10.0, 10.0, 5.0, 1.0, 0.0],
        [1.0, 6.0, 15.0, 20.0, 15.0, 6.0, 1.0],
    ];
    let mut beta = [0.0; 7];
    for (i, b) in beta.iter_mut().enumerate() {
        *b = (0..=i).map(|j| BINOM[i][j] / BINOM[N][j] * c[j]).sum();
    }
    beta
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn eval(p: &Poly, s: f64) -> f64 {
        p.iter().rev().fold(0.0, |acc, c| acc * s + c)
    }

    #[test]
    fn bernstein_end_coefficients_are_the_end_values() {
        let p: Poly = [1.0, -3.0, 0.5, 2.0, -0.1, 0.01, 0.002];
        let b = bernstein(&p, 0.3, 1.7);
        assert_relative_eq!(b[0], eval(&p, 0.3), max_relative = 1e-12);
        assert_relative_eq!(b[6], eval(&p, 1.7), max_relative = 1e-12);
    }

    #[test]
    fn finds_first_root_of_known_polynomial() {
        // (s − 0.3)(s − 2)·(−1/0.6) has value 1 at 0 and its first root at 0.3.
        let p: Poly = [1.0, -2.3 / 0.6, 1.0 / 0.6, 0.0, 0.0, 0.0, 0.0];
        let r = first_nonpositive(&p, 0.0, 10.0, 0).unwrap();
        assert!(r <= 0.3 && r > 0.3 * (1.0 - 1e-12), "{r}");
        // Positive everywhere: none.
        let q: Poly = [1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0];
        assert!(first_nonpositive(&q, 0.0, 1e4, 0).is_none());
    }

    #[test]
    fn single_k1_barrel_limit_is_closed_form() {
        // r(1 + k1 r²) has derivative 1 + 3 k1 r², zero at r² = −1/(3 k1).
        let k1 = -0.25;
        let s = monotonic_limit_squared(&[k1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_relative_eq!(s, -1.0 / (3.0 * k1), max_relative = 1e-12);
        assert!(s <= -1.0 / (3.0 * k1));
    }

    #[test]
    fn pole_of_the_denominator_limits_the_range() {
        // f = 1 / (1 − s): derivative numerator D + 2 s·(−D')·... stays positive, the pole at
        // s = 1 is the limit.
        let s = monotonic_limit_squared(&[0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0]);
        assert_relative_eq!(s, 1.0, max_relative = 1e-12);
        assert!(s <= 1.0);
    }

    #[test]
    fn identity_and_always_monotonic_lenses() {
        assert!(monotonic_limit_squared(&[0.0; 8]).is_infinite());
        // Pincushion k1 > 0 is increasing everywhere: the cap.
        let s = monotonic_limit_squared(&[0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(s, RADIUS_CAP * RADIUS_CAP);
    }
}
