//! Branch-free `f32` helpers that the compiler can vectorise.
//!
//! `f32::atan2` is a library call on every target, which stops the decode loops from being
//! vectorised; the polynomial below compiles to a dozen vector instructions. `floor`/`round` use
//! the standard ones, which are single instructions in the AVX2 code the decoders dispatch to.

use std::f32::consts::{FRAC_PI_2, PI};

/// Coefficients of an odd polynomial `a * (c0 + c1 a^2 + ... + c5 a^10)` approximating
/// `atan(a)` on `[0, 1]`, fitted (weighted least squares towards minimax) for this crate.
/// Maximum error 1.7e-6 rad, far below the 1e-3 rad phase noise of 8-bit fringes.
const ATAN_COEFFS: [f32; 6] = [
    0.999_977_2,
    -0.332_622_8,
    0.193_540_33,
    -0.116_426_36,
    0.052_647_22,
    -0.011_719_084,
];

/// `atan2(y, x)` in `(-pi, pi]` with a maximum error of about 2e-6 rad; `atan2(0, 0) = 0`.
#[inline(always)]
pub(crate) fn atan2(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let mx = ax.max(ay);
    let mn = ax.min(ay);
    // mx == 0 only for (0, 0); dividing by 1 then gives 0.
    let a = mn / if mx > 0.0 { mx } else { 1.0 };
    let s = a * a;
    let mut p = ATAN_COEFFS[5];
    p = p * s + ATAN_COEFFS[4];
    p = p * s + ATAN_COEFFS[3];
    p = p * s + ATAN_COEFFS[2];
    p = p * s + ATAN_COEFFS[1];
    p = p * s + ATAN_COEFFS[0];
    let mut r = p * a;
    r = if ay > ax { FRAC_PI_2 - r } else { r };
    r = if x < 0.0 { PI - r } else { r };
    if y < 0.0 { -r } else { r }
}

/// `floor(x)`.
///
/// The decode loops run inside `pulp`'s runtime dispatch, compiled for AVX2 (x86-64-v3) where the
/// CPU has it; there `f32::floor` is one `vroundps` per 8 lanes. (On the SSE2 baseline it is a
/// library call, which is correct but slow; no CPU made in the last ten years takes that path.)
#[inline(always)]
pub(crate) fn floor(x: f32) -> f32 {
    x.floor()
}

/// `x - floor(x)`: the fractional part in `[0, 1)` (up to rounding: may return exactly 1.0 for
/// tiny negative inputs, which callers treat as 0 through their own wrap).
#[inline(always)]
pub(crate) fn fract(x: f32) -> f32 {
    x - floor(x)
}

/// Round half up, `floor(x + 0.5)`; vectorisable.
#[inline(always)]
pub(crate) fn round(x: f32) -> f32 {
    floor(x + 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan2_matches_std_within_bound() {
        // The polynomial is good to 1.7e-6 rad; f32 arithmetic adds a few ulp of pi.
        let bound = 3e-6_f32;
        let mut worst = 0.0_f32;
        let n = 2000;
        for i in 0..n {
            let ang = -PI + 2.0 * PI * (i as f32 + 0.5) / n as f32;
            for r in [1e-3_f32, 0.7, 1.0, 250.0, 1e5] {
                let (y, x) = (r * ang.sin(), r * ang.cos());
                let e = (atan2(y, x) - y.atan2(x)).abs();
                let e = e.min(2.0 * PI - e); // +-pi are the same angle
                worst = worst.max(e);
            }
        }
        assert!(worst < bound, "worst error {worst}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert!((atan2(0.0, -1.0) - PI).abs() < 1e-6);
        assert!((atan2(1.0, 0.0) - FRAC_PI_2).abs() < 1e-6);
    }

    #[test]
    fn floor_round_fract() {
        for &x in &[
            -2.5_f32, -2.0, -1.2, -0.5, -0.0, 0.0, 0.3, 0.5, 1.0, 7.99, 1e6,
        ] {
            assert_eq!(floor(x), x.floor(), "floor {x}");
            assert_eq!(round(x), (x + 0.5).floor(), "round {x}");
            let f = fract(x);
            assert!((0.0..1.0).contains(&f), "fract {x} = {f}");
        }
    }
}
