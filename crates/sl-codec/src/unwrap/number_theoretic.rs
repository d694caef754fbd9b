//! Number-theoretic (coprime periods) unwrapping.
//!
//! With `Pa` and `Pb` coprime integer period counts and `t` in `[0, 1)`, the period indices
//! `ka = floor(Pa t)`, `kb = floor(Pb t)` satisfy `Pb ka - Pa kb = Pa fb - Pb fa =: e`, an integer
//! in `(-Pb, Pa)` that differs for every pair `(ka, kb)` met along the projector (coprimality).
//! Rounding the measured `e` and looking it up gives `ka` directly, with no coarse frequency at
//! all; the rounding residual measures the agreement of the two phases. Further frequencies, if
//! any, refine in increasing order of period count.

use super::{UnwrapScratch, stage};
use crate::fast_math;

/// The plan: the coprime pair, a lookup table from `e` to `ka`, and the refining frequencies.
#[derive(Clone, Debug)]
pub(crate) struct NumberTheoretic {
    pa: f32,
    pb: f32,
    /// `lut[e + pb]` = `ka`, or -1 where no position produces `e`.
    lut: Vec<i32>,
    /// Indices of the frequencies after the first two, increasing period count.
    rest: Vec<usize>,
    periods: Vec<f32>,
}

/// Greatest common divisor.
pub(crate) fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

impl NumberTheoretic {
    /// `periods` are validated by the spec: the first two are coprime integers >= 1.
    pub(crate) fn new(periods: &[f64]) -> Self {
        let pa = periods.first().copied().unwrap_or(1.0).round() as i64;
        let pb = periods.get(1).copied().unwrap_or(1.0).round() as i64;
        let mut lut = vec![-1i32; (pa + pb + 1).max(1) as usize];
        for ka in 0..pa {
            for kb in 0..pb {
                // [ka/pa, (ka+1)/pa) and [kb/pb, (kb+1)/pb) overlap
                if ka * pb < (kb + 1) * pa && kb * pa < (ka + 1) * pb {
                    let e = pb * ka - pa * kb;
                    if let Some(slot) = usize::try_from(e + pb).ok().and_then(|i| lut.get_mut(i)) {
                        *slot = ka as i32;
                    }
                }
            }
        }
        let mut rest: Vec<usize> = (2..periods.len()).collect();
        rest.sort_by(|&a, &b| periods[a].total_cmp(&periods[b]));
        Self {
            pa: pa as f32,
            pb: pb as f32,
            lut,
            rest,
            periods: periods.iter().map(|&p| p as f32).collect(),
        }
    }

    /// Writes the position of each pixel into `s.t`.
    #[inline(always)]
    pub(crate) fn coarse_row(&self, fracs: &[Vec<f32>], s: &mut UnwrapScratch) {
        let (Some(fa), Some(fb)) = (fracs.first(), fracs.get(1)) else {
            return;
        };
        let n = s.t.len();
        let (fa, fb) = (&fa[..n], &fb[..n]);
        let inv_pa = 1.0 / self.pa;
        for i in 0..n {
            let e = self.pa * fb[i] - self.pb * fa[i];
            let er = fast_math::round(e);
            let ka = self.lut.get((er + self.pb) as usize).copied().unwrap_or(-1);
            if ka < 0 {
                // No position yields this e: mark the pixel as inconsistent.
                s.resid[i] = 1.0;
                s.t[i] = fa[i] * inv_pa;
            } else {
                s.resid[i] = s.resid[i].max((e - er).abs());
                s.t[i] = (ka as f32 + fa[i]) * inv_pa;
            }
        }
        stage(&mut s.t, &mut s.resid, fb, self.pb);
        for &k in &self.rest {
            if let (Some(f), Some(&p)) = (fracs.get(k), self.periods.get(k)) {
                stage(&mut s.t, &mut s.resid, f, p);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::Unwrap;
    use super::super::tests::check_plan;
    use super::*;

    #[test]
    fn recovers_positions_with_noise() {
        // The residual of e is Pa*dfb - Pb*dfa: 0.01 cycles on 13 and 16 periods gives 0.29 at
        // worst... keep the noise at 0.005 (0.145) to stay inside the 0.25 tolerance.
        check_plan(Unwrap::NumberTheoretic, &[13.0, 16.0], 0.005);
        check_plan(Unwrap::NumberTheoretic, &[16.0, 13.0, 64.0], 0.003);
        check_plan(Unwrap::NumberTheoretic, &[7.0, 9.0], 0.01);
    }

    #[test]
    fn gcd_values() {
        assert_eq!(gcd(12, 18), 6);
        assert_eq!(gcd(13, 16), 1);
        assert_eq!(gcd(5, 0), 5);
    }
}
