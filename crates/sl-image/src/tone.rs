//! A response curve: the relative light a device gives for a commanded value.

use serde::{Deserialize, Serialize};

use crate::ImageError;

/// Most samples a [`ToneCurve`] holds.
pub const MAX_TONE_SAMPLES: usize = 4096;

/// Samples of the curves this module builds ([`ToneCurve::power`], the measured ones).
const TABLE_SAMPLES: usize = 257;

/// A monotone response on `[0, 1]`: the relative light `r(v)` a projector (or a projector and
/// camera together) gives for a commanded value `v`, normalised so that `r(0) = 0` and
/// `r(1) = 1`.
///
/// Stored as the light at `n` equally spaced values `v_i = i / (n - 1)`, linear in between;
/// the samples never decrease. The projector's black level and the camera's gain are not part
/// of it: they scale and offset every frame alike, which neither phase nor a binary code sees.
/// What the phase does see is the curve's shape (a gamma of 2.2 puts harmonics into the
/// fringes): `sl_codec` corrects the phase with it.
///
/// In files it is `{"samples": [0.0, …, 1.0]}`.
///
/// ```
/// use sl_image::ToneCurve;
/// # fn main() -> Result<(), sl_image::ImageError> {
/// let gamma = ToneCurve::power(2.2)?;
/// assert!((gamma.light(0.5) - 0.5f64.powf(2.2)).abs() < 1e-4);
/// assert!((gamma.value_for(gamma.light(0.3)) - 0.3).abs() < 1e-3);
/// // A measured ramp: commanded values and the camera's mean grey level over the lit area.
/// let measured = ToneCurve::from_measurements(&[0.0, 0.5, 1.0], &[12.0, 60.0, 212.0])?;
/// assert!((measured.light(0.5) - 0.24).abs() < 1e-9);
/// # Ok(()) }
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "ToneCurveRepr", into = "ToneCurveRepr")]
pub struct ToneCurve {
    samples: Vec<f64>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToneCurveRepr {
    samples: Vec<f64>,
}

impl TryFrom<ToneCurveRepr> for ToneCurve {
    type Error = ImageError;
    fn try_from(repr: ToneCurveRepr) -> Result<Self, ImageError> {
        Self::from_samples(repr.samples)
    }
}

impl From<ToneCurve> for ToneCurveRepr {
    fn from(curve: ToneCurve) -> Self {
        Self {
            samples: curve.samples,
        }
    }
}

impl ToneCurve {
    /// The linear response, `r(v) = v`.
    pub fn linear() -> Self {
        Self {
            samples: vec![0.0, 1.0],
        }
    }

    /// `r(v) = v^gamma`, tabulated at 257 values.
    ///
    /// # Errors
    /// [`ImageError::InvalidParameter`] naming `gamma` when it is not finite and positive.
    pub fn power(gamma: f64) -> Result<Self, ImageError> {
        if !(gamma.is_finite() && gamma > 0.0) {
            return Err(ImageError::invalid(
                "gamma",
                format!("{gamma} is not a finite positive number"),
            ));
        }
        Ok(Self::from_fn(|v| v.powf(gamma)))
    }

    /// A curve from the function `f` on `[0, 1]`, tabulated at 257 values and normalised by
    /// `f(0)` and `f(1)` (which must differ); where `f` decreases the curve stays flat.
    ///
    /// # Panics
    /// Never for a finite `f` with `f(1) > f(0)`; otherwise the samples are NaN-free but
    /// meaningless (all 0 then 1).
    pub fn from_fn(f: impl Fn(f64) -> f64) -> Self {
        let n = TABLE_SAMPLES;
        let raw: Vec<f64> = (0..n).map(|i| f(i as f64 / (n - 1) as f64)).collect();
        let (lo, hi) = (raw[0], raw[n - 1]);
        let span = if hi > lo { hi - lo } else { f64::INFINITY };
        let mut samples: Vec<f64> = raw.iter().map(|r| (r - lo) / span).collect();
        let mut top = 0.0_f64;
        for s in &mut samples {
            // max/min drop NaN in favour of the running value.
            top = top.max(*s).min(1.0);
            *s = top;
        }
        samples[0] = 0.0;
        samples[n - 1] = 1.0;
        Self { samples }
    }

    /// A curve from its samples (the light at `i / (n - 1)`).
    ///
    /// # Errors
    /// [`ImageError::InvalidParameter`] naming `samples` when there are fewer than 2 or more
    /// than [`MAX_TONE_SAMPLES`], a sample is not finite, the first is not 0 or the last not 1
    /// (within 1e-6), or a sample is below the one before it.
    pub fn from_samples(mut samples: Vec<f64>) -> Result<Self, ImageError> {
        let n = samples.len();
        if !(2..=MAX_TONE_SAMPLES).contains(&n) {
            return Err(ImageError::invalid(
                "samples",
                format!("{n} samples; a tone curve has 2 to {MAX_TONE_SAMPLES}"),
            ));
        }
        if let Some(i) = samples.iter().position(|s| !s.is_finite()) {
            return Err(ImageError::invalid(
                "samples",
                format!("sample {i} is {}", samples[i]),
            ));
        }
        if samples[0].abs() > 1e-6 || (samples[n - 1] - 1.0).abs() > 1e-6 {
            return Err(ImageError::invalid(
                "samples",
                format!(
                    "the curve runs from {} to {}; it is normalised to run from 0 to 1",
                    samples[0],
                    samples[n - 1]
                ),
            ));
        }
        if let Some(i) = (1..n).find(|&i| samples[i] < samples[i - 1]) {
            return Err(ImageError::invalid(
                "samples",
                format!(
                    "sample {i} ({}) is below sample {} ({}); a response never decreases",
                    samples[i],
                    i - 1,
                    samples[i - 1]
                ),
            ));
        }
        samples[0] = 0.0;
        samples[n - 1] = 1.0;
        Ok(Self { samples })
    }

    /// The curve measured by showing the commanded `values` (increasing, from 0 to 1) and
    /// reading `light` for each (a camera's grey level, in any unit and with any offset).
    ///
    /// The light is normalised by its first and last readings, made non-decreasing by
    /// pooling adjacent readings that decrease (noise at the dark end does; the least-squares
    /// monotone fit), and tabulated at 257 values, linear between the measured ones.
    ///
    /// # Errors
    /// [`ImageError::InvalidParameter`] naming `values` when there are fewer than 2, they do
    /// not increase from 0 to 1, or `light` has another length; naming `light` when a reading
    /// is not finite or the last is not above the first (the projector did not light what the
    /// camera saw).
    pub fn from_measurements(values: &[f64], light: &[f64]) -> Result<Self, ImageError> {
        let n = values.len();
        if n < 2 || light.len() != n {
            return Err(ImageError::invalid(
                "values",
                format!(
                    "{n} values and {} readings; a ramp needs 2 or more of each, as many",
                    light.len()
                ),
            ));
        }
        if values[0] != 0.0 || values[n - 1] != 1.0 || values.windows(2).any(|w| w[1] <= w[0]) {
            return Err(ImageError::invalid(
                "values",
                "the commanded values must increase from 0 to 1".to_owned(),
            ));
        }
        if let Some(i) = light.iter().position(|l| !l.is_finite()) {
            return Err(ImageError::invalid(
                "light",
                format!("reading {i} is {}", light[i]),
            ));
        }
        let (lo, hi) = (light[0], light[n - 1]);
        if hi <= lo {
            return Err(ImageError::invalid(
                "light",
                format!(
                    "white reads {hi}, black {lo}: the projector does not light what the camera sees"
                ),
            ));
        }
        let normalised: Vec<f64> = light.iter().map(|l| (l - lo) / (hi - lo)).collect();
        let fitted = monotone_fit(&normalised);
        Ok(Self::from_fn(|v| interpolate(values, &fitted, v)))
    }

    /// The samples: the light at `i / (n - 1)`.
    pub fn samples(&self) -> &[f64] {
        &self.samples
    }

    /// Whether the curve is the identity (within `1e-9` at every sample).
    pub fn is_linear(&self) -> bool {
        let n = self.samples.len();
        self.samples
            .iter()
            .enumerate()
            .all(|(i, s)| (s - i as f64 / (n - 1) as f64).abs() <= 1e-9)
    }

    /// The relative light for the commanded value `v` (clamped to `[0, 1]`).
    pub fn light(&self, v: f64) -> f64 {
        let n = self.samples.len();
        let x = v.clamp(0.0, 1.0) * (n - 1) as f64;
        let i = (x.floor() as usize).min(n - 2);
        let t = x - i as f64;
        self.samples[i] + t * (self.samples[i + 1] - self.samples[i])
    }

    /// The commanded value that gives the relative light `r` (clamped to `[0, 1]`): the inverse
    /// of [`Self::light`], the smallest such value where the curve is flat. Pre-compensating a
    /// pattern value `p` is showing `value_for(p)`.
    pub fn value_for(&self, r: f64) -> f64 {
        let r = r.clamp(0.0, 1.0);
        let n = self.samples.len();
        // First sample at or above r.
        let j = self.samples.partition_point(|&s| s < r).clamp(1, n - 1);
        let (a, b) = (self.samples[j - 1], self.samples[j]);
        let t = if b > a { (r - a) / (b - a) } else { 0.0 };
        ((j - 1) as f64 + t.clamp(0.0, 1.0)) / (n - 1) as f64
    }

    /// The exponent of the power law `v^gamma` nearest to the curve (least squares over 257
    /// values): a one-number summary of a measured response.
    pub fn equivalent_gamma(&self) -> f64 {
        let cost = |g: f64| -> f64 {
            (0..TABLE_SAMPLES)
                .map(|i| {
                    let v = i as f64 / (TABLE_SAMPLES - 1) as f64;
                    (self.light(v) - v.powf(g)).powi(2)
                })
                .sum()
        };
        // Golden-section search on log(gamma) over [0.1, 10]: the cost is unimodal there for
        // any monotone curve close to a power law.
        let (mut a, mut b) = (0.1_f64.ln(), 10.0_f64.ln());
        let phi = (5.0_f64.sqrt() - 1.0) / 2.0;
        for _ in 0..80 {
            let c = b - phi * (b - a);
            let d = a + phi * (b - a);
            if cost(c.exp()) < cost(d.exp()) {
                b = d;
            } else {
                a = c;
            }
        }
        ((a + b) / 2.0).exp()
    }

    /// The largest difference in light between this curve and `other` over 257 values.
    pub fn max_difference(&self, other: &Self) -> f64 {
        (0..TABLE_SAMPLES)
            .map(|i| {
                let v = i as f64 / (TABLE_SAMPLES - 1) as f64;
                (self.light(v) - other.light(v)).abs()
            })
            .fold(0.0, f64::max)
    }
}

/// Least-squares non-decreasing fit (pool adjacent violators).
fn monotone_fit(y: &[f64]) -> Vec<f64> {
    // Blocks of (mean, count).
    let mut blocks: Vec<(f64, usize)> = Vec::with_capacity(y.len());
    for &v in y {
        blocks.push((v, 1));
        while let [.., (m1, c1), (m2, c2)] = blocks.as_mut_slice() {
            if *m1 <= *m2 {
                break;
            }
            let c = *c1 + *c2;
            *m1 = (*m1 * *c1 as f64 + *m2 * *c2 as f64) / c as f64;
            *c1 = c;
            blocks.pop();
        }
    }
    blocks
        .into_iter()
        .flat_map(|(m, c)| std::iter::repeat_n(m, c))
        .collect()
}

/// Piecewise-linear interpolation of `(xs, ys)` at `x` (`xs` increasing, `x` within).
fn interpolate(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let j = xs.partition_point(|&a| a < x).clamp(1, xs.len() - 1);
    let (x0, x1) = (xs[j - 1], xs[j]);
    let t = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
    ys[j - 1] + t * (ys[j] - ys[j - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_curve_and_its_inverse() {
        let c = ToneCurve::power(2.2).unwrap();
        for i in 0..=100 {
            let v = f64::from(i) / 100.0;
            // Linear interpolation of v^2.2 between 1/256 steps: the error is below
            // (1/256)^2 / 8 * max |f''| ~ 1e-5 away from 0.
            assert!((c.light(v) - v.powf(2.2)).abs() < 5e-5, "v = {v}");
            assert!((c.value_for(c.light(v)) - v).abs() < 1e-9, "v = {v}");
        }
        assert!((c.equivalent_gamma() - 2.2).abs() < 1e-3);
        assert!(ToneCurve::linear().is_linear());
        assert!(!c.is_linear());
        assert!(ToneCurve::power(1.0).unwrap().is_linear());
        assert!(ToneCurve::power(0.0).is_err());
        assert!(ToneCurve::power(f64::NAN).is_err());
    }

    #[test]
    fn measurements_are_normalised_and_made_monotone() {
        // A noisy ramp with an offset, a gain and a dip at the dark end.
        let values = [0.0, 0.25, 0.5, 0.75, 1.0];
        let light = [20.0, 18.0, 60.0, 120.0, 220.0];
        let c = ToneCurve::from_measurements(&values, &light).unwrap();
        // Normalised: 0, -0.01, 0.2, 0.5, 1. The dip pools with black: both -0.005; the
        // curve is then renormalised to run from 0: r = (x + 0.005) / 1.005.
        assert_eq!(c.light(0.0), 0.0);
        assert_eq!(c.light(0.25), 0.0);
        assert_eq!(c.light(1.0), 1.0);
        assert!((c.light(0.5) - 0.205 / 1.005).abs() < 1e-9);
        assert!((c.light(0.75) - 0.505 / 1.005).abs() < 1e-9);
        assert!(c.samples().windows(2).all(|w| w[1] >= w[0]));
        // Errors name the parameter.
        let e = ToneCurve::from_measurements(&values, &[5.0; 5]).unwrap_err();
        assert!(e.to_string().contains("light"), "{e}");
        let e = ToneCurve::from_measurements(&[0.0, 0.6, 0.5, 1.0], &[0.0; 4]).unwrap_err();
        assert!(e.to_string().contains("values"), "{e}");
        let e = ToneCurve::from_measurements(&[0.0, 1.0], &[0.0]).unwrap_err();
        assert!(e.to_string().contains("values"), "{e}");
    }

    #[test]
    fn monotone_fit_pools_violators() {
        assert_eq!(
            monotone_fit(&[1.0, 3.0, 2.0, 4.0]),
            vec![1.0, 2.5, 2.5, 4.0]
        );
        assert_eq!(monotone_fit(&[3.0, 2.0, 1.0]), vec![2.0, 2.0, 2.0]);
    }

    #[test]
    fn samples_are_checked_and_round_trip_through_json() {
        assert!(ToneCurve::from_samples(vec![0.0]).is_err());
        assert!(ToneCurve::from_samples(vec![0.0, 0.6, 0.5, 1.0]).is_err());
        assert!(ToneCurve::from_samples(vec![0.1, 1.0]).is_err());
        assert!(ToneCurve::from_samples(vec![0.0, f64::NAN, 1.0]).is_err());
        let c = ToneCurve::from_samples(vec![0.0, 0.1, 0.5, 1.0]).unwrap();
        let text = serde_json::to_string(&c).unwrap();
        assert_eq!(text, r#"{"samples":[0.0,0.1,0.5,1.0]}"#);
        let back: ToneCurve = serde_json::from_str(&text).unwrap();
        assert_eq!(back, c);
        let e = serde_json::from_str::<ToneCurve>(r#"{"samples":[0.0,0.7,0.5,1.0]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sample 2"), "{e}");
        // value_for of a sample's light gives the sample's value; on a flat stretch its start.
        assert!((c.value_for(0.1) - 1.0 / 3.0).abs() < 1e-12);
        let flat = ToneCurve::from_samples(vec![0.0, 0.0, 0.0, 1.0]).unwrap();
        assert_eq!(flat.value_for(0.0), 0.0);
    }
}
