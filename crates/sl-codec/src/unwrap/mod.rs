//! Temporal phase unwrapping: from wrapped phases at several frequencies to one absolute
//! projector position.
//!
//! Phases are handled in *cycles*: a wrapped phase `f` in `[0, 1)` is the fractional part of
//! `P * t`, where `P` is the number of periods across the projector and `t` in `[0, 1)` the
//! position as a fraction of the projector extent (from the block's `origin`). Every method
//! first produces a coarse absolute `t`, then all frequencies are unwrapped against it and
//! combined; each rounding step records how far the prediction was from an integer (the
//! *residual*), and the decoder rejects pixels whose largest residual exceeds
//! [`crate::DecodeConfig::unwrap_tolerance`].

mod heterodyne;
mod hierarchical;
mod number_theoretic;

use crate::fast_math;

pub(crate) use heterodyne::Heterodyne;
pub(crate) use hierarchical::Hierarchical;
pub(crate) use number_theoretic::{NumberTheoretic, gcd};

/// How a multi-frequency phase block is unwrapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Unwrap {
    /// One frequency with at most one period across the projector: already absolute.
    #[default]
    None,
    /// Multi-frequency hierarchical: the coarsest frequency (at most one period) is absolute and
    /// each finer one is unwrapped from the previous, in increasing order of `periods`.
    Hierarchical,
    /// Three-frequency heterodyne: `periods = [P1, P2, P3]` whose beat `P1 - 2 P2 + P3` is at
    /// most one period across the projector (for example 64, 58, 53: beats 6 and 5, then 1).
    Heterodyne,
    /// Number-theoretic: the first two `periods` are coprime integers; the pair of period
    /// indices is found from `P1 f2 - P2 f1` with a lookup table. Further frequencies refine.
    NumberTheoretic,
}

impl Unwrap {
    /// `"none"`, `"hierarchical"`, `"heterodyne"` or `"number_theoretic"`.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Hierarchical => "hierarchical",
            Self::Heterodyne => "heterodyne",
            Self::NumberTheoretic => "number_theoretic",
        }
    }

    /// Parses a manifest name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "none" => Some(Self::None),
            "hierarchical" | "multi_frequency" => Some(Self::Hierarchical),
            "heterodyne" | "three_frequency_heterodyne" => Some(Self::Heterodyne),
            "number_theoretic" | "coprime" => Some(Self::NumberTheoretic),
            _ => None,
        }
    }
}

/// Per-task buffers of the unwrapping step (one row each).
pub(crate) struct UnwrapScratch {
    pub(crate) t: Vec<f32>,
    pub(crate) resid: Vec<f32>,
    pub(crate) tmp: [Vec<f32>; 3],
}

impl UnwrapScratch {
    /// Sets every buffer to `n` entries.
    pub(crate) fn fit(&mut self, n: usize) {
        self.t.resize(n, 0.0);
        self.resid.resize(n, 0.0);
        for v in &mut self.tmp {
            v.resize(n, 0.0);
        }
    }

    pub(crate) fn new(width: usize) -> Self {
        Self {
            t: vec![0.0; width],
            resid: vec![0.0; width],
            tmp: [vec![0.0; width], vec![0.0; width], vec![0.0; width]],
        }
    }
}

/// A validated unwrapping plan for one block.
#[derive(Clone, Debug)]
pub(crate) enum Plan {
    /// Single absolute frequency of `periods` (<= 1) cycles.
    Single(f32),
    Hierarchical(Hierarchical),
    Heterodyne(Heterodyne),
    NumberTheoretic(NumberTheoretic),
}

impl Plan {
    /// Builds the plan; `periods` are already validated by the spec.
    pub(crate) fn new(method: Unwrap, periods: &[f64]) -> Self {
        match method {
            Unwrap::None => Self::Single(periods.first().copied().unwrap_or(1.0) as f32),
            Unwrap::Hierarchical => Self::Hierarchical(Hierarchical::new(periods)),
            Unwrap::Heterodyne => Self::Heterodyne(Heterodyne::new(periods)),
            Unwrap::NumberTheoretic => Self::NumberTheoretic(NumberTheoretic::new(periods)),
        }
    }

    /// Unwraps one row: `fracs[i]` are the wrapped phases (cycles) of frequency `i`, `periods`
    /// their period counts. Writes `s.t` (position as a fraction of the extent) and `s.resid`
    /// (largest rounding residual, cycles). All frequencies are then combined, weighted by
    /// `P^2` (inverse phase variance), and cross-checked.
    #[inline(always)]
    pub(crate) fn unwrap_row(&self, fracs: &[Vec<f32>], periods: &[f32], s: &mut UnwrapScratch) {
        s.resid.fill(0.0);
        match self {
            Self::Single(p) => {
                if let Some(f) = fracs.first() {
                    for (t, &f) in s.t.iter_mut().zip(f) {
                        *t = absolute(f, *p);
                    }
                }
            }
            Self::Hierarchical(h) => h.coarse_row(fracs, s),
            Self::Heterodyne(h) => return h.unwrap_row(fracs, s),
            Self::NumberTheoretic(n) => n.coarse_row(fracs, s),
        }
        combine_row(fracs, periods, s);
    }
}

/// Position from the wrapped phase `f` of a frequency with `p <= 1` periods: `f / p`, except
/// that phases that no position in `[0, 1)` produces (when `p < 1`) are mapped to the nearer
/// edge, so that noise around `t = 0` does not throw a pixel to `t = 1 / p`.
#[inline(always)]
pub(crate) fn absolute(f: f32, p: f32) -> f32 {
    let inv = 1.0 / p;
    let t = f * inv;
    if t > 0.5 + 0.5 * inv { t - inv } else { t }
}

/// One unwrapping step: `t` is a position estimate; the measured wrapped phase `f` of a
/// frequency with `p` periods is unwrapped to `U = f + round(p t - f)`, the residual
/// `|p t - U|` is folded into `resid`, and `t` becomes `U / p`.
#[inline(always)]
pub(crate) fn stage(t: &mut [f32], resid: &mut [f32], f: &[f32], p: f32) {
    let inv = 1.0 / p;
    let n = t.len();
    let (resid, f) = (&mut resid[..n], &f[..n]);
    for i in 0..n {
        let predicted = p * t[i];
        let u = f[i] + fast_math::round(predicted - f[i]);
        resid[i] = resid[i].max((predicted - u).abs());
        t[i] = u * inv;
    }
}

/// Unwraps every frequency against the coarse `t`, replaces `t` by the `P^2`-weighted mean
/// of the unwrapped positions, and folds each frequency's disagreement into `resid`.
#[inline(always)]
pub(crate) fn combine_row(fracs: &[Vec<f32>], periods: &[f32], s: &mut UnwrapScratch) {
    let n = s.t.len();
    let sum_p2: f32 = periods.iter().map(|p| p * p).sum();
    if fracs.len() <= 1 || sum_p2 <= 0.0 {
        return;
    }
    let inv_sum = 1.0 / sum_p2;
    let acc = &mut s.tmp[0][..n];
    acc.fill(0.0);
    for (f, &p) in fracs.iter().zip(periods) {
        let (f, t, resid) = (&f[..n], &s.t[..n], &mut s.resid[..n]);
        for i in 0..n {
            let predicted = p * t[i];
            let u = f[i] + fast_math::round(predicted - f[i]);
            resid[i] = resid[i].max((predicted - u).abs());
            // P^2 * (U / P) = P * U
            acc[i] += p * u;
        }
    }
    for (t, a) in s.t.iter_mut().zip(acc.iter()) {
        *t = a * inv_sum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact wrapped phases of position `t` for `periods`.
    pub(crate) fn fracs_of(t: &[f64], periods: &[f64]) -> Vec<Vec<f32>> {
        periods
            .iter()
            .map(|&p| t.iter().map(|&t| (p * t).rem_euclid(1.0) as f32).collect())
            .collect()
    }

    pub(crate) fn check_plan(method: Unwrap, periods: &[f64], noise_cycles: f64) {
        // Positions within the noise of the projector's edges may wrap to the other edge (the
        // coarsest phase, at most one period, is only defined modulo one period; a heterodyne
        // beat f1 - 2 f2 + f3 carries up to 4x the noise): keep 5x the noise clear of them.
        let margin = 5.0 * noise_cycles;
        let n = 4001;
        let t: Vec<f64> = (0..n)
            .map(|i| margin + (1.0 - 2.0 * margin) * (i as f64 + 0.5) / n as f64)
            .collect();
        let mut fr = fracs_of(&t, periods);
        // deterministic "noise": alternating +-noise on each frequency
        for (k, f) in fr.iter_mut().enumerate() {
            for (i, v) in f.iter_mut().enumerate() {
                let s = if (i + k) % 2 == 0 { 1.0 } else { -1.0 };
                *v = (f64::from(*v) + s * noise_cycles).rem_euclid(1.0) as f32;
            }
        }
        let plan = Plan::new(method, periods);
        let mut s = UnwrapScratch::new(n);
        let pf: Vec<f32> = periods.iter().map(|&p| p as f32).collect();
        plan.unwrap_row(&fr, &pf, &mut s);
        // The combined position is sum(P_i U_i) / sum(P_i^2); a phase error of at most `noise`
        // cycles on each frequency moves it by at most noise * sum(P) / sum(P^2); 2e-6 covers
        // f32 rounding of t in [0, 1).
        let sum_p: f64 = periods.iter().sum();
        let sum_p2: f64 = periods.iter().map(|p| p * p).sum();
        let bound = if periods.len() == 1 {
            noise_cycles / periods[0]
        } else {
            noise_cycles * sum_p / sum_p2
        };
        for ((&got, &truth), &resid) in s.t.iter().zip(&t).zip(&s.resid) {
            let err = (f64::from(got) - truth).abs();
            assert!(
                err <= bound * 1.01 + 2e-6,
                "{method:?} {periods:?}: t {truth} got {got} (err {err})"
            );
            assert!(resid < 0.25, "resid {resid}");
        }
    }

    #[test]
    fn names_round_trip() {
        for m in [
            Unwrap::None,
            Unwrap::Hierarchical,
            Unwrap::Heterodyne,
            Unwrap::NumberTheoretic,
        ] {
            assert_eq!(Unwrap::from_name(m.name()), Some(m));
        }
    }

    #[test]
    fn single_frequency() {
        check_plan(Unwrap::None, &[1.0], 0.001);
    }

    #[test]
    fn stage_detects_inconsistency() {
        let mut t = vec![0.5_f32];
        let mut r = vec![0.0_f32];
        // 10 periods: prediction 5.0, measured 0.4 -> U = 5.4, residual 0.4.
        stage(&mut t, &mut r, &[0.4], 10.0);
        assert!((t[0] - 0.54).abs() < 1e-6);
        assert!((r[0] - 0.4).abs() < 1e-5);
    }
}
