//! The projector's response, measured from a grey ramp.
//!
//! The projector shows flat images of increasing grey values `v_0 = 0 < … < v_n = 1` on a
//! matte surface (a wall, the back of the board, the virtual rig's plate) and the camera
//! captures each. On the pixels the projector lights well and the camera does not saturate,
//! the mean grey level of each capture, normalised between the black and the white one, is
//! the response `r(v)` that the camera sees ([`sl_codec::ToneCurve`]): the projector's curve
//! and the camera's together, which is what bends the decoded phase.

use sl_codec::{GreyImage, ImageSize, ToneCurve};

use crate::CalibError;

/// Grey levels of the ramp [`ramp_levels`] gives by default: 33 (steps of 1/32), enough to
/// follow a measured curve's toe and shoulder within a few tenths of a percent.
pub const RESPONSE_LEVELS: usize = 33;

/// Smallest lit range (white minus black, as a fraction of the camera's full scale) of a
/// pixel the measurement uses.
const MIN_LIT_RANGE: f64 = 0.08;

/// A pixel is used only if its lit range is at least this share of the 99th percentile's.
const LIT_SHARE: f64 = 0.25;

/// A white sample at or above this fraction of full scale is saturated.
const SATURATED: f64 = 0.98;

/// The ramp's commanded values: `count` values `i / (count - 1)`.
///
/// # Errors
/// [`CalibError::InvalidParameter`] naming `levels` for fewer than 3 or more than 1024.
pub fn ramp_levels(count: usize) -> Result<Vec<f64>, CalibError> {
    if !(3..=1024).contains(&count) {
        return Err(CalibError::InvalidParameter {
            name: "levels".into(),
            reason: format!("{count} grey levels; a ramp has 3 to 1024"),
        });
    }
    Ok((0..count).map(|i| i as f64 / (count - 1) as f64).collect())
}

/// A response measured from a ramp ([`measure_response`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseMeasurement {
    /// The response, normalised from the black capture to the white one.
    pub curve: ToneCurve,
    /// The commanded values.
    pub levels: Vec<f64>,
    /// The mean grey level (fraction of the camera's full scale) of each level's capture over
    /// the pixels used.
    pub light: Vec<f64>,
    /// Pixels used: lit by the projector, not saturated in the white capture.
    pub pixels: usize,
    /// The lit range of those pixels: mean white minus mean black (fraction of full scale).
    pub contrast: f64,
}

/// Measures the projector's response from `frames[i]`, the capture of the flat grey image of
/// value `levels[i]` (increasing from 0 to 1).
///
/// # Errors
/// [`CalibError::InvalidParameter`] naming `levels` when they do not increase from 0 to 1 or
/// their count is not the frames'; [`CalibError::Frame`] naming the frame whose size is not
/// the first's, or the white frame when no pixel is lit well enough and unsaturated (the
/// projector does not reach what the camera sees, or the exposure is too long).
pub fn measure_response(
    levels: &[f64],
    frames: &[GreyImage],
) -> Result<ResponseMeasurement, CalibError> {
    let n = levels.len();
    if n != frames.len() || n < 3 {
        return Err(CalibError::InvalidParameter {
            name: "levels".into(),
            reason: format!(
                "{n} grey levels for {} captures; a ramp has 3 or more, one capture each",
                frames.len()
            ),
        });
    }
    if levels[0] != 0.0 || levels[n - 1] != 1.0 || levels.windows(2).any(|w| w[1] <= w[0]) {
        return Err(CalibError::InvalidParameter {
            name: "levels".into(),
            reason: "the grey levels must increase from 0 to 1".into(),
        });
    }
    let size = frames[0].size();
    if let Some(i) = frames.iter().position(|f| f.size() != size) {
        return Err(CalibError::Frame {
            frame: format!("ramp level {i} (value {:.4})", levels[i]),
            reason: format!(
                "{} pixels, the black capture {size}: the ramp's captures differ in size",
                frames[i].size()
            ),
        });
    }
    let normalised: Vec<Vec<f32>> = frames.iter().map(normalised_samples).collect();
    let (black, white) = (&normalised[0], &normalised[n - 1]);
    let mut ranges: Vec<f32> = black
        .iter()
        .zip(white)
        .map(|(&b, &w)| w - b)
        .filter(|r| r.is_finite())
        .collect();
    let p99 = if ranges.is_empty() {
        0.0
    } else {
        let k = ((ranges.len() - 1) as f64 * 0.99) as usize;
        *ranges.select_nth_unstable_by(k, f32::total_cmp).1
    };
    let min_range = (LIT_SHARE * f64::from(p99)).max(MIN_LIT_RANGE) as f32;
    let used: Vec<usize> = (0..black.len())
        .filter(|&i| white[i] - black[i] >= min_range && f64::from(white[i]) < SATURATED)
        .collect();
    if used.is_empty() {
        return Err(CalibError::Frame {
            frame: format!("ramp level {} (white)", n - 1),
            reason: format!(
                "no pixel of the {} is lit by at least {:.0} % of full scale over the black \
                 capture without saturating: point the projector at a matte surface the camera \
                 sees, and shorten the exposure if the white capture saturates",
                ImageSize::new(size.width, size.height),
                100.0 * f64::from(min_range)
            ),
        });
    }
    let light: Vec<f64> = normalised
        .iter()
        .map(|f| used.iter().map(|&i| f64::from(f[i])).sum::<f64>() / used.len() as f64)
        .collect();
    let curve = ToneCurve::from_measurements(levels, &light)?;
    Ok(ResponseMeasurement {
        curve,
        levels: levels.to_vec(),
        contrast: light[n - 1] - light[0],
        light,
        pixels: used.len(),
    })
}

/// The samples of `image` as fractions of full scale.
fn normalised_samples(image: &GreyImage) -> Vec<f32> {
    match image {
        GreyImage::U8(f) => f.data().iter().map(|&v| f32::from(v) / 255.0).collect(),
        GreyImage::U16(f) => f.data().iter().map(|&v| f32::from(v) / 65535.0).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_codec::Frame;

    /// Captures of a ramp through `curve` on an 8-bit camera with a grey level of noise (as
    /// real sensors have: it dithers the quantisation, which averaging then removes): the lit
    /// part (albedo varying across it), a band the projector does not reach, a saturated
    /// spot.
    fn ramp(levels: &[f64], curve: impl Fn(f64) -> f64) -> Vec<GreyImage> {
        let (w, h) = (64usize, 48usize);
        levels
            .iter()
            .map(|&v| {
                let data = (0..w * h)
                    .map(|i| {
                        let (x, y) = ((i % w) as f64, (i / w) as f64);
                        let ambient = 10.0;
                        let lit = x > 8.0;
                        let albedo = 0.5 + 0.3 * (x / w as f64) + 0.1 * (y / h as f64);
                        let gain = if x > 60.0 && y < 4.0 { 600.0 } else { 220.0 };
                        // Uniform noise of unit variance from a hash of the pixel and level.
                        let h = (i as u64 ^ ((v * 1e6) as u64 * 0x9E37_79B9))
                            .wrapping_mul(0x2545_F491_4F6C_DD1D);
                        let noise = ((h >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 12f64.sqrt();
                        let value = ambient
                            + noise
                            + if lit {
                                gain * albedo * (0.002 + 0.998 * curve(v))
                            } else {
                                0.0
                            };
                        value.round().clamp(0.0, 255.0) as u8
                    })
                    .collect();
                GreyImage::U8(Frame::new(w, h, data).unwrap())
            })
            .collect()
    }

    #[test]
    fn a_gamma_ramp_gives_the_gamma_back() {
        let levels = ramp_levels(RESPONSE_LEVELS).unwrap();
        let m = measure_response(&levels, &ramp(&levels, |v| v.powf(2.2))).unwrap();
        let truth = ToneCurve::power(2.2).unwrap();
        // 8-bit quantisation averaged over ~2,600 pixels, linear between 33 levels: the
        // interpolation error of v^2.2 between levels 1/32 apart is below 2e-3.
        assert!(
            m.curve.max_difference(&truth) < 3e-3,
            "{}",
            m.curve.max_difference(&truth)
        );
        assert!((m.curve.equivalent_gamma() - 2.2).abs() < 0.03);
        // The dark band (x <= 8) and the saturated spot are not used.
        assert!(
            m.pixels < 64 * 48 - 9 * 48 && m.pixels > 2000,
            "{}",
            m.pixels
        );
        assert!(m.contrast > 0.3);
    }

    #[test]
    fn mistakes_are_named() {
        let levels = ramp_levels(5).unwrap();
        let mut frames = ramp(&levels, |v| v);
        // Too few captures.
        let e = measure_response(&levels, &frames[..4])
            .unwrap_err()
            .to_string();
        assert!(e.contains("levels"), "{e}");
        // A capture of another size.
        frames[2] = GreyImage::U8(Frame::filled(32, 24, 0).unwrap());
        let e = measure_response(&levels, &frames).unwrap_err().to_string();
        assert!(e.contains("ramp level 2"), "{e}");
        // The projector does not light the scene: every capture the same.
        let flat: Vec<GreyImage> = (0..5)
            .map(|_| GreyImage::U8(Frame::filled(32, 24, 40).unwrap()))
            .collect();
        let e = measure_response(&levels, &flat).unwrap_err().to_string();
        assert!(e.contains("white") && e.contains("matte surface"), "{e}");
        // Levels that do not increase.
        let e = measure_response(&[0.0, 0.7, 0.5, 0.9, 1.0], &ramp(&levels, |v| v))
            .unwrap_err()
            .to_string();
        assert!(e.contains("increase"), "{e}");
        assert!(ramp_levels(2).is_err());
    }
}
