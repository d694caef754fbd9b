//! Three-frequency heterodyne unwrapping.
//!
//! With wrapped phases `f1, f2, f3` (cycles) of `P1, P2, P3` periods, the differences
//! `f12 = f1 - f2` and `f23 = f2 - f3` (mod 1) are the phases of *beat* patterns with
//! `P12 = P1 - P2` and `P23 = P2 - P3` periods, and `f123 = f12 - f23` (mod 1) that of a beat of
//! `P123 = P1 - 2 P2 + P3` periods. With `0 < |P123| <= 1` the last one is absolute; it unwraps
//! `f12`, which unwraps `f1`. Signs are kept, so any order of the three periods works.

#[cfg(test)]
use super::stage;
use super::{UnwrapScratch, absolute};
use crate::fast_math;

/// The plan: the three period counts and their beats.
#[derive(Clone, Debug)]
pub(crate) struct Heterodyne {
    p1: f32,
    p2: f32,
    p3: f32,
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
            p2: p2 as f32,
            p3: p3 as f32,
            p12: (p1 - p2) as f32,
            p123: (p1 - 2.0 * p2 + p3) as f32,
        }
    }

    /// The whole unwrapping in one pass per pixel: the beats, the two heterodyne steps, then
    /// every frequency unwrapped against the result and combined with weights `P^2` (the same
    /// arithmetic as `coarse_row` followed by the generic combination, without the intermediate
    /// passes over memory). Writes `s.t` and `s.resid`.
    #[inline(always)]
    pub(crate) fn unwrap_row(&self, fracs: &[Vec<f32>], s: &mut UnwrapScratch) {
        let (Some(f1), Some(f2), Some(f3)) = (fracs.first(), fracs.get(1), fracs.get(2)) else {
            return;
        };
        let n = s.t.len();
        let (f1, f2, f3) = (&f1[..n], &f2[..n], &f3[..n]);
        let (t_out, r_out) = (&mut s.t[..n], &mut s.resid[..n]);
        let sign = self.p123.signum();
        let p = self.p123.abs();
        let (p1, p2, p3, p12) = (self.p1, self.p2, self.p3, self.p12);
        let (inv_p1, inv_p12) = (1.0 / p1, 1.0 / p12);
        let inv_sum = 1.0 / (p1 * p1 + p2 * p2 + p3 * p3);
        let step = |t: f32, f: f32, p: f32| -> (f32, f32) {
            let predicted = p * t;
            let u = f + fast_math::round(predicted - f);
            (u, (predicted - u).abs())
        };
        for i in 0..n {
            let (a, b) = (
                fast_math::fract(f1[i] - f2[i]),
                fast_math::fract(f2[i] - f3[i]),
            );
            let t = absolute(fast_math::fract(sign * (a - b)), p);
            let (u12, r12) = step(t, a, p12);
            let (u1, r1) = step(u12 * inv_p12, f1[i], p1);
            let t = u1 * inv_p1;
            let (v1, q1) = step(t, f1[i], p1);
            let (v2, q2) = step(t, f2[i], p2);
            let (v3, q3) = step(t, f3[i], p3);
            t_out[i] = (p1 * v1 + p2 * v2 + p3 * v3) * inv_sum;
            r_out[i] = r12.max(r1).max(q1).max(q2).max(q3);
        }
    }

    /// Writes the position of each pixel into `s.t`.
    #[cfg(test)]
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

    #[test]
    fn fused_pass_matches_the_staged_one() {
        use super::super::{UnwrapScratch, combine_row};
        use super::Heterodyne;
        let periods = [64.0, 58.0, 53.0];
        let n = 997;
        let fracs: Vec<Vec<f32>> = periods
            .iter()
            .enumerate()
            .map(|(k, &p)| {
                (0..n)
                    .map(|i| {
                        ((p * (i as f64 + 0.3) / n as f64 + 0.01 * (k as f64 - 1.0))
                            .rem_euclid(1.0)) as f32
                    })
                    .collect()
            })
            .collect();
        let h = Heterodyne::new(&periods);
        let pf: Vec<f32> = periods.iter().map(|&p| p as f32).collect();
        let (mut a, mut b) = (UnwrapScratch::new(n), UnwrapScratch::new(n));
        h.unwrap_row(&fracs, &mut a);
        b.resid.fill(0.0);
        h.coarse_row(&fracs, &mut b);
        combine_row(&fracs, &pf, &mut b);
        for i in 0..n {
            assert!(
                (a.t[i] - b.t[i]).abs() < 1e-6,
                "{i}: {} vs {}",
                a.t[i],
                b.t[i]
            );
            assert!((a.resid[i] - b.resid[i]).abs() < 1e-5, "{i}");
        }
    }
}
