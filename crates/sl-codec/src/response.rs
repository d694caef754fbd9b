//! The phase error of a projector whose response is not linear, and its correction.
//!
//! A projector that gives the light `r(v)` for the value `v` turns the fringe
//! `1/2 + 1/2 cos(theta - delta_k)` into a periodic signal with harmonics. The `N`-step
//! estimate `atan2(sum I_k sin delta_k, sum I_k cos delta_k)` then misses `theta` by an error
//! that depends on `theta` alone (harmonics `N - 1` and `N + 1` alias onto the fundamental:
//! three ripples a period with 3 steps, four with 4), not on the surface's albedo, the
//! ambient light or the camera's gain, which scale and offset all steps alike. Knowing `r`,
//! the error is computed once per step count, as a table over the measured phase, and
//! subtracted from every pixel (Zhang & Yau's phase-error look-up table, built from the
//! response instead of from a flat board's capture).

use std::f64::consts::{PI, TAU};

use sl_image::ToneCurve;

use crate::{CodecError, ShiftSign};

/// Entries of the correction table over one period of the measured phase.
const BINS: usize = 1024;

/// True phases sampled to build the table.
const SAMPLES: usize = 8 * BINS;

/// The phase error a projector response causes in `N`-step fringes, and its correction.
///
/// ```
/// use sl_codec::{PhaseCorrection, ShiftSign, ToneCurve};
/// let gamma = ToneCurve::power(2.2)?;
/// let three = PhaseCorrection::new(&gamma, 3, ShiftSign::Positive, 1.0)?;
/// let four = PhaseCorrection::new(&gamma, 4, ShiftSign::Positive, 1.0)?;
/// // 3 steps suffer most (the second harmonic aliases); more steps suffer less.
/// assert!(three.max_error_rad() > four.max_error_rad());
/// // A linear projector needs no correction.
/// let linear = PhaseCorrection::new(&ToneCurve::linear(), 3, ShiftSign::Positive, 1.0)?;
/// assert!(linear.max_error_rad() < 1e-9);
/// # Ok::<(), sl_codec::CodecError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseCorrection {
    /// `true - measured` phase, in cycles, at measured phases `i / BINS` cycles; one entry
    /// more than `BINS` (the first again) so that interpolation needs no wrap.
    table: Vec<f32>,
    max_error_rad: f64,
    rms_error_rad: f64,
}

impl PhaseCorrection {
    /// The correction of `steps`-step fringes shifted by `shift_sign`, shown through
    /// `response` after the patterns' own pre-compensation of `precompensation` (the block's
    /// `gamma`: each value `p` was shown as `p^(1/gamma)`; 1 for none).
    ///
    /// # Errors
    /// [`CodecError::Parameter`] for `steps` out of `3..=64` or a `precompensation` that is not
    /// finite and positive; naming `response` when the measured phase does not grow with the
    /// true one (a response so far from the patterns' assumption that phases fold over: no
    /// table can undo it; pre-compensate the patterns, or use more steps).
    pub fn new(
        response: &ToneCurve,
        steps: u32,
        shift_sign: ShiftSign,
        precompensation: f64,
    ) -> Result<Self, CodecError> {
        Self::for_patterns(response, steps, shift_sign, precompensation, None)
    }

    /// [`Self::new`] for patterns that pre-compensate a measured curve instead of a gamma
    /// (`curve`, the block's `precompensation`, which then replaces `gamma`): the error left
    /// when the curve the patterns assumed is not quite the response the decoder knows (none
    /// when they are the same, but for the quantisation of the shown values).
    ///
    /// # Errors
    /// As [`Self::new`].
    pub fn for_patterns(
        response: &ToneCurve,
        steps: u32,
        shift_sign: ShiftSign,
        gamma: f64,
        curve: Option<&ToneCurve>,
    ) -> Result<Self, CodecError> {
        crate::phase_shift::validate_steps(steps)?;
        if !(gamma.is_finite() && gamma > 0.0) {
            return Err(CodecError::parameter(
                "gamma",
                format!("{gamma} is not a finite positive number"),
            ));
        }
        let n = f64::from(steps);
        let delta: Vec<(f64, f64, f64)> = (0..steps)
            .map(|k| {
                let d = shift_sign.value() * TAU * f64::from(k) / n;
                (d, d.sin(), d.cos())
            })
            .collect();
        let shown = |p: f64| {
            response.light(crate::phase_shift::precompensate(
                p.clamp(0.0, 1.0),
                gamma,
                curve,
            ))
        };
        // (measured phase in cycles [0, 1), error in cycles) for true phases over a period.
        let mut pairs: Vec<(f64, f64)> = Vec::with_capacity(SAMPLES);
        let mut last_unwrapped: Option<f64> = None;
        let (mut max_err, mut sum_sq) = (0.0_f64, 0.0_f64);
        for j in 0..SAMPLES {
            let theta = TAU * j as f64 / SAMPLES as f64;
            let (mut s, mut c) = (0.0, 0.0);
            for &(d, sk, ck) in &delta {
                // Step k shows cos(theta - delta_k) (the decoder's convention).
                let light = shown(0.5 + 0.5 * (theta - d).cos());
                s += light * sk;
                c += light * ck;
            }
            if s.hypot(c) < 1e-9 {
                return Err(folds(steps, "leaves no fringe at some phase"));
            }
            let measured = s.atan2(c);
            let err = wrap(theta - measured);
            // The measured phase must grow with the true one.
            let unwrapped = theta - err;
            if let Some(prev) = last_unwrapped
                && unwrapped <= prev
            {
                return Err(folds(steps, "makes the measured phase fold back"));
            }
            last_unwrapped = Some(unwrapped);
            max_err = max_err.max(err.abs());
            sum_sq += err * err;
            pairs.push((measured.rem_euclid(TAU) / TAU, err / TAU));
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut table = Vec::with_capacity(BINS + 1);
        for i in 0..BINS {
            table.push(periodic_interpolate(&pairs, i as f64 / BINS as f64) as f32);
        }
        table.push(table[0]);
        Ok(Self {
            table,
            max_error_rad: max_err,
            rms_error_rad: (sum_sq / SAMPLES as f64).sqrt(),
        })
    }

    /// The largest phase error the response causes (radians): what the correction removes.
    pub fn max_error_rad(&self) -> f64 {
        self.max_error_rad
    }

    /// The RMS phase error the response causes over a period (radians).
    pub fn rms_error_rad(&self) -> f64 {
        self.rms_error_rad
    }

    /// The corrected phase, in cycles `[0, 1)`, of the measured phase `cycles` (cycles of the
    /// fringe argument `theta`, any real value).
    #[inline]
    pub fn correct_cycles(&self, cycles: f32) -> f32 {
        let u = cycles - cycles.floor();
        let x = u * BINS as f32;
        let i = (x as usize).min(BINS - 1);
        let t = x - i as f32;
        let e = self.table[i] + t * (self.table[i + 1] - self.table[i]);
        let c = u + e;
        let f = c - c.floor();
        if f >= 1.0 { 0.0 } else { f }
    }

    /// Corrects wrapped phases given in cycles of `Phi` (the fringe argument less `offset`
    /// cycles, as the decoders keep them), in place.
    pub(crate) fn correct_fracs(&self, fracs: &mut [f32], offset_cycles: f32) {
        for f in fracs {
            let c = self.correct_cycles(*f + offset_cycles) - offset_cycles;
            let c = c - c.floor();
            *f = if c >= 1.0 { 0.0 } else { c };
        }
    }
}

fn folds(steps: u32, what: &str) -> CodecError {
    CodecError::parameter(
        "response",
        format!(
            "the projector response {what} with {steps} steps; no table can undo that: \
             pre-compensate the patterns or use more steps"
        ),
    )
}

/// `a` wrapped to `(-pi, pi]`.
fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(TAU);
    if w > PI { w - TAU } else { w }
}

/// Linear interpolation at `u` of points `(x, y)` sorted by `x` in `[0, 1)`, periodic in `x`.
fn periodic_interpolate(points: &[(f64, f64)], u: f64) -> f64 {
    let n = points.len();
    let j = points.partition_point(|p| p.0 < u);
    let (a, b) = if j == 0 {
        let (x, y) = points[n - 1];
        ((x - 1.0, y), points[0])
    } else if j == n {
        let (x, y) = points[0];
        (points[n - 1], (x + 1.0, y))
    } else {
        (points[j - 1], points[j])
    };
    if b.0 <= a.0 {
        return a.1;
    }
    a.1 + (u - a.0) / (b.0 - a.0) * (b.1 - a.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Phase of N steps of `1/2 + 1/2 cos(theta - delta_k)` shown through `f`, as the decoder
    /// computes it (cycles).
    fn measured(f: impl Fn(f64) -> f64, steps: u32, sign: f64, theta: f64) -> f64 {
        let (mut s, mut c) = (0.0, 0.0);
        for k in 0..steps {
            let d = sign * TAU * f64::from(k) / f64::from(steps);
            let v = f(0.5 + 0.5 * (theta - d).cos());
            s += v * d.sin();
            c += v * d.cos();
        }
        s.atan2(c).rem_euclid(TAU) / TAU
    }

    fn cycle_distance(a: f64, b: f64) -> f64 {
        let d = (a - b).rem_euclid(1.0);
        d.min(1.0 - d)
    }

    #[test]
    fn the_table_undoes_a_gamma_for_three_and_four_steps_both_signs() {
        let curve = ToneCurve::power(2.2).unwrap();
        for steps in [3, 4, 5] {
            for sign in [ShiftSign::Positive, ShiftSign::Negative] {
                let corr = PhaseCorrection::new(&curve, steps, sign, 1.0).unwrap();
                let (mut before, mut after) = (0.0_f64, 0.0_f64);
                for j in 0..997 {
                    let theta = TAU * f64::from(j) / 997.0 + 0.001;
                    let m = measured(|v| v.powf(2.2), steps, sign.value(), theta);
                    let truth = theta / TAU;
                    before = before.max(cycle_distance(m, truth));
                    after = after.max(cycle_distance(
                        f64::from(corr.correct_cycles(m as f32)),
                        truth,
                    ));
                }
                // Uncorrected: tens of milliradians with 3 and 4 steps (5 steps alias only
                // the 4th and 6th harmonics, a milliradian); corrected: the f32 table's
                // resolution.
                let least = if steps < 5 { 0.01 } else { 1e-3 };
                assert!(before * TAU > least, "{steps} steps {sign:?}: {before}");
                assert!(
                    after * TAU < 2e-4,
                    "{steps} steps {sign:?}: {after} (before {before})"
                );
                assert!((corr.max_error_rad() - before * TAU).abs() < 1e-3);
            }
        }
    }

    #[test]
    fn precompensated_patterns_need_no_correction() {
        // Patterns pre-compensated for the projector's own gamma: the light is a sinusoid.
        let corr =
            PhaseCorrection::new(&ToneCurve::power(2.2).unwrap(), 3, ShiftSign::Positive, 2.2)
                .unwrap();
        assert!(corr.max_error_rad() < 1e-3, "{}", corr.max_error_rad());
        // Pre-compensated for a gamma the projector does not have: the error comes back.
        let corr = PhaseCorrection::new(&ToneCurve::linear(), 3, ShiftSign::Positive, 2.2).unwrap();
        assert!(corr.max_error_rad() > 0.01);
    }

    #[test]
    fn offsets_are_kept() {
        let curve = ToneCurve::power(2.0).unwrap();
        let corr = PhaseCorrection::new(&curve, 3, ShiftSign::Positive, 1.0).unwrap();
        let psi = 0.3_f64; // cycles
        let theta = 0.55 * TAU;
        let m = measured(|v| v * v, 3, 1.0, theta);
        let mut fracs = [(m - psi).rem_euclid(1.0) as f32];
        corr.correct_fracs(&mut fracs, psi as f32);
        assert!(
            cycle_distance(f64::from(fracs[0]), 0.55 - psi) < 1e-4,
            "{}",
            fracs[0]
        );
    }

    #[test]
    fn a_response_that_folds_the_phase_is_refused() {
        // A hard threshold: every step is black or white, the phase takes N values only.
        let step =
            ToneCurve::from_samples((0..=256).map(|i| if i < 128 { 0.0 } else { 1.0 }).collect())
                .unwrap();
        let e = PhaseCorrection::new(&step, 3, ShiftSign::Positive, 1.0).unwrap_err();
        assert!(e.to_string().contains("response"), "{e}");
        assert!(PhaseCorrection::new(&ToneCurve::linear(), 2, ShiftSign::Positive, 1.0).is_err());
        assert!(PhaseCorrection::new(&ToneCurve::linear(), 3, ShiftSign::Positive, 0.0).is_err());
    }
}
