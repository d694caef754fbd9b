//! Three-frequency heterodyne unwrapping.
//!
//! With wrapped phases `f1, f2, f3` (cycles) of `P1, P2, P3` periods, the differences
//! `f12 = f1 - f2` and `f23 = f2 - f3` (mod 1) are the phases of *beat* patterns with
//! `P12 = P1 - P2` and `P23 = P2 - P3` periods, and `f123 = f12 - f23` (mod 1) that of a beat of
//! `P123 = P1 - 2 P2 + P3` periods. With `0 < |P123| <= 1` the last one is absolute; it unwraps
//! `f12`, which unwraps `f1`. Signs are kept, so any order of the three periods works.

use super::{UnwrapScratch, absolute, stage};
use crate::fast_math;

/// The plan: the three period counts and their beats.
#[derive(Clone, Debug)]
pub(crate) struct Heterodyne {
    p1: f32,
    p12: f32,
    p123: f32,
}

impl Heterodyne {
    /// `periods` are validated by the spec: three, with `0 < |P1 - 2 P2 + P3| <= 1`.
    pub(crate) fn new(periods: &[f64]) -> Self {
        let p = |i: usize| periods.get(i).copied().unwrap_or(1.0);
        let (p1, p2, p3) = (p(0), p(1), p(2));
        Self {
            p1: p1 as f32,
            p12: (p1 - p2) as f32,
            p123: (p1 - 2.0 * p2 + p3) as f32,
        }
    }

    /// Writes the position of each pixel into `s.t`.
    #[inline(always)]
    pub(crate) fn coarse_row(&self, fracs: &[Vec<f32>], s: &mut UnwrapScratch) {
        let (Some(f1), Some(f2), Some(f3)) = (fracs.first(), fracs.get(1), fracs.get(2)) else {
            return;
        };
        let n = s.t.len();
        let (f1, f2, f3) = (&f1[..n], &f2[..n], &f3[..n]);
        let [b12, _, _] = &mut s.tmp;
        let b12 = &mut b12[..n];
        let t = &mut s.t[..n];
        let sign = self.p123.signum();
        let p = self.p123.abs();
        for i in 0..n {
            let a = fast_math::fract(f1[i] - f2[i]);
            let b = fast_math::fract(f2[i] - f3[i]);
            b12[i] = a;
            // fract(P123 t) = f123, so t = fract(sign * f123) / |P123|.
            t[i] = absolute(fast_math::fract(sign * (a - b)), p);
        }
        let b12: &[f32] = b12;
        stage(t, &mut s.resid[..n], b12, self.p12);
        stage(t, &mut s.resid[..n], f1, self.p1);
    }
}

#[cfg(test)]
mod tests {
    use super::super::Unwrap;
    use super::super::tests::check_plan;

    #[test]
    fn recovers_positions_with_noise() {
        // SLMaster's 64/58/53: beat ratios 6 and 64/6 = 10.7, so 0.01 cycles of noise per
        // frequency stays well inside the half-period margin of every step.
        check_plan(Unwrap::Heterodyne, &[64.0, 58.0, 53.0], 0.01);
        // Reversed order (negative beats) and non-integer counts.
        check_plan(Unwrap::Heterodyne, &[53.0, 58.0, 64.0], 0.01);
        check_plan(Unwrap::Heterodyne, &[20.5, 18.0, 16.0], 0.01);
    }
}
