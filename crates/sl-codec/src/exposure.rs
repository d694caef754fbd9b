//! Exposure fusion: one capture made of the same pattern sequence captured at several
//! exposures, for scenes whose light spans more than one exposure holds — a black part next
//! to a white one, a shiny part whose highlight saturates the camera.
//!
//! **Per pixel, one exposure for the whole sequence.** A pixel's codes come from its own
//! samples only: the phase from their ratios, a Gray bit from a pattern against its inverse.
//! So every frame of a pixel is taken from the *same* exposure — the longest at which none of
//! the pixel's samples saturates (the most signal, so the least noise, with nothing clipped).
//! A per-pixel factor changes no phase and no comparison, and the decoder's thresholds
//! (modulation, contrast, saturation) keep their meaning: they see the chosen exposure's own
//! grey levels and its own noise. It also holds on a camera whose output is not linear in
//! light (most webcams apply a gamma): no sample is ever rescaled from one exposure to another.
//!
//! [`FusionMethod::Radiance`] adds the shorter exposures' samples of the same pixel, scaled by
//! the exposure ratio to the chosen one and weighted by the square of their exposure (the
//! inverse of their variance once scaled, where read noise dominates): never more noise than
//! the chosen exposure alone, a little less where a pixel is unsaturated in several exposures,
//! but it assumes a linear camera with a known black level
//! ([`FusionConfig::dark_level`]). The set of exposures is still chosen per pixel for the whole
//! sequence, so a pixel's samples stay comparable with each other.
//!
//! [`choose_exposures`] picks the exposures from a frame under full white: the shortest keeps
//! the brightest lit pixels below saturation, the longest lifts the darkest lit ones to half of
//! full scale, and the exposures in between are spaced by at most [`AutoExposureConfig::step`].

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{CodecError, DEFAULT_SATURATION_LEVEL, Frame, GreyImage, Sample};

/// How the exposures of a pixel are combined ([`fuse_exposures`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FusionMethod {
    /// The samples of the longest exposure at which none of the pixel's samples saturates,
    /// unchanged (the frames keep their bit depth). Holds on cameras that are not linear.
    #[default]
    Longest,
    /// The samples of every unsaturated exposure up to that one, scaled to it and averaged,
    /// weighted by the square of their exposure (16-bit frames, in the chosen exposure's grey levels scaled by
    /// 257 for 8-bit captures). Needs a linear camera.
    Radiance,
}

impl FusionMethod {
    /// The method's name as `--fusion` and `exposures.json` spell it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Longest => "longest",
            Self::Radiance => "radiance",
        }
    }
}

impl std::str::FromStr for FusionMethod {
    type Err = CodecError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "longest" => Ok(Self::Longest),
            "radiance" => Ok(Self::Radiance),
            other => Err(CodecError::Parameter {
                name: "fusion".to_owned(),
                message: format!("'{other}' is not a fusion method: longest or radiance"),
            }),
        }
    }
}

/// Settings of [`fuse_exposures`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FusionConfig {
    /// How a pixel's exposures are combined. Default [`FusionMethod::Longest`].
    pub method: FusionMethod,
    /// A sample at or above this level (8-bit grey levels, scaled by 257 for 16-bit frames) is
    /// saturated. Default [`DEFAULT_SATURATION_LEVEL`], the decoder's.
    pub saturation_level: f32,
    /// The camera's black level (8-bit grey levels, scaled for 16-bit frames): what a pixel
    /// reads in the dark, subtracted before [`FusionMethod::Radiance`] scales a sample and
    /// added back after. Default 0. [`FusionMethod::Longest`] does not use it.
    pub dark_level: f32,
}

impl Default for FusionConfig {
    fn default() -> Self {
        Self {
            method: FusionMethod::Longest,
            saturation_level: DEFAULT_SATURATION_LEVEL,
            dark_level: 0.0,
        }
    }
}

/// One exposure of a capture: its exposure time and its frames, in the sequence's order.
#[derive(Debug, Clone, PartialEq)]
pub struct ExposureFrames {
    /// Exposure time in milliseconds (any unit will do, as long as every exposure uses it).
    pub exposure_ms: f64,
    /// The frames, one per pattern.
    pub frames: Vec<GreyImage>,
}

/// Marks a pixel of [`FusedFrames::source`] that saturates at every exposure: its samples are
/// the shortest exposure's, and the decoder rejects them as saturated.
pub const SATURATED_EVERYWHERE: u8 = u8::MAX;

/// The result of [`fuse_exposures`].
#[derive(Debug, Clone, PartialEq)]
pub struct FusedFrames {
    /// One frame per pattern.
    pub frames: Vec<GreyImage>,
    /// For each pixel (row-major), the index into [`FusionSummary::exposures_ms`] of the
    /// exposure its samples come from (the longest unsaturated one), or
    /// [`SATURATED_EVERYWHERE`].
    pub source: Vec<u8>,
    /// Pixels per exposure, and how many saturate everywhere.
    pub summary: FusionSummary,
}

/// What [`fuse_exposures`] did, for reports and `exposures.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FusionSummary {
    /// The method used.
    pub method: FusionMethod,
    /// The exposures, shortest first (milliseconds).
    pub exposures_ms: Vec<f64>,
    /// Pixels whose samples come from each exposure (same order).
    pub pixels: Vec<usize>,
    /// Pixels saturated at every exposure (kept from the shortest).
    pub saturated_everywhere: usize,
}

/// Most exposures [`fuse_exposures`] combines.
pub const MAX_EXPOSURES: usize = 16;

/// Fuses the same pattern sequence captured at several exposures into one sequence. The
/// exposures may come in any order.
///
/// Every frame of a pixel comes from one exposure, the longest at which none of the pixel's
/// samples saturates: a per-pixel factor changes no phase and no Gray bit, and the decoder's
/// thresholds see that exposure's own grey levels and noise ([`FusionMethod::Longest`], which
/// holds on cameras that are not linear). [`FusionMethod::Radiance`] averages the shorter
/// unsaturated exposures of the pixel in, scaled to it and weighted by `t²`.
///
/// # Errors
/// [`CodecError::Parameter`] naming `exposures` (none, more than [`MAX_EXPOSURES`], two of the
/// same time) or `exposures[i].exposure_ms` (not positive); [`CodecError::FrameCount`]-like
/// [`CodecError::Frames`] when an exposure has another number of frames than the first, or mixes
/// bit depths; [`CodecError::FrameSize`] naming the exposure and the frame whose size differs;
/// [`CodecError::Parameter`] naming `saturation_level` or `dark_level`.
pub fn fuse_exposures(
    exposures: &[ExposureFrames],
    config: &FusionConfig,
) -> Result<FusedFrames, CodecError> {
    check_exposures(exposures, config)?;
    let mut order: Vec<usize> = (0..exposures.len()).collect();
    order.sort_by(|&a, &b| {
        exposures[a]
            .exposure_ms
            .total_cmp(&exposures[b].exposure_ms)
    });
    let times: Vec<f64> = order.iter().map(|&i| exposures[i].exposure_ms).collect();
    let first = &exposures[0].frames[0];
    let size = (first.width(), first.height());
    let eight_bit = matches!(first, GreyImage::U8(_));
    let (frames, source) = if eight_bit {
        let stacks = typed_stacks(exposures, &order, |g| match g {
            GreyImage::U8(f) => Some(f),
            GreyImage::U16(_) => None,
        })?;
        fuse_typed(&stacks, &times, config, size, GreyImage::U8)?
    } else {
        let stacks = typed_stacks(exposures, &order, |g| match g {
            GreyImage::U16(f) => Some(f),
            GreyImage::U8(_) => None,
        })?;
        fuse_typed(&stacks, &times, config, size, GreyImage::U16)?
    };
    let mut pixels = vec![0; times.len()];
    let mut saturated_everywhere = 0;
    for &s in &source {
        match pixels.get_mut(usize::from(s)) {
            Some(n) => *n += 1,
            None => saturated_everywhere += 1,
        }
    }
    Ok(FusedFrames {
        frames,
        source,
        summary: FusionSummary {
            method: config.method,
            exposures_ms: times,
            pixels,
            saturated_everywhere,
        },
    })
}

fn check_exposures(exposures: &[ExposureFrames], config: &FusionConfig) -> Result<(), CodecError> {
    let param = |name: &str, message: String| CodecError::Parameter {
        name: name.to_owned(),
        message,
    };
    if exposures.is_empty() || exposures.len() > MAX_EXPOSURES {
        return Err(param(
            "exposures",
            format!(
                "{} exposures given: fusion takes 1 to {MAX_EXPOSURES}",
                exposures.len()
            ),
        ));
    }
    if !(config.saturation_level.is_finite() && config.saturation_level > 0.0) {
        return Err(param(
            "saturation_level",
            format!("{} is not a positive grey level", config.saturation_level),
        ));
    }
    if !(config.dark_level.is_finite()
        && config.dark_level >= 0.0
        && config.dark_level < config.saturation_level)
    {
        return Err(param(
            "dark_level",
            format!(
                "{} is not a grey level between 0 and the saturation level {}",
                config.dark_level, config.saturation_level
            ),
        ));
    }
    for (i, e) in exposures.iter().enumerate() {
        if !(e.exposure_ms.is_finite() && e.exposure_ms > 0.0) {
            return Err(param(
                &format!("exposures[{i}].exposure_ms"),
                format!("{} is not a positive exposure time", e.exposure_ms),
            ));
        }
        if let Some(j) = exposures[..i]
            .iter()
            .position(|o| o.exposure_ms == e.exposure_ms)
        {
            return Err(param(
                "exposures",
                format!(
                    "exposures {j} and {i} are both {} ms: each exposure once",
                    e.exposure_ms
                ),
            ));
        }
    }
    let first = &exposures[0];
    let Some(f0) = first.frames.first() else {
        return Err(CodecError::Frames(format!(
            "exposure 0 ({} ms) has no frames",
            first.exposure_ms
        )));
    };
    let (w, h, bits) = (f0.width(), f0.height(), f0.bit_depth());
    for (i, e) in exposures.iter().enumerate() {
        if e.frames.len() != first.frames.len() {
            return Err(CodecError::Frames(format!(
                "exposure {i} ({} ms) has {} frames, exposure 0 ({} ms) {}: every exposure captures the whole sequence",
                e.exposure_ms,
                e.frames.len(),
                first.exposure_ms,
                first.frames.len()
            )));
        }
        for (k, f) in e.frames.iter().enumerate() {
            if (f.width(), f.height()) != (w, h) {
                return Err(CodecError::FrameSize {
                    frame: format!("#{k} of exposure {i} ({} ms)", e.exposure_ms),
                    expected_width: w,
                    expected_height: h,
                    found_width: f.width(),
                    found_height: f.height(),
                });
            }
            if f.bit_depth() != bits {
                return Err(CodecError::Frames(format!(
                    "frame #{k} of exposure {i} ({} ms) is {}-bit, frame #0 of exposure 0 {bits}-bit: fuse frames of one depth",
                    e.exposure_ms,
                    f.bit_depth()
                )));
            }
        }
    }
    Ok(())
}

/// The frames of each exposure in `order`, all of depth `T` (checked by `check_exposures`).
fn typed_stacks<'a, T: Sample>(
    exposures: &'a [ExposureFrames],
    order: &[usize],
    typed: impl Fn(&'a GreyImage) -> Option<&'a Frame<T>>,
) -> Result<Vec<Vec<&'a [T]>>, CodecError> {
    order
        .iter()
        .map(|&i| {
            exposures[i]
                .frames
                .iter()
                .map(|f| {
                    typed(f)
                        .map(Frame::data)
                        .ok_or_else(|| CodecError::Frames(format!("exposure {i} mixes bit depths")))
                })
                .collect()
        })
        .collect()
}

/// Pixels per parallel task of the exposure choice.
const PIXELS_PER_TASK: usize = 16 * 1024;

fn fuse_typed<T: Sample>(
    stacks: &[Vec<&[T]>],
    times: &[f64],
    config: &FusionConfig,
    (width, height): (usize, usize),
    wrap: impl Fn(Frame<T>) -> GreyImage,
) -> Result<(Vec<GreyImage>, Vec<u8>), CodecError> {
    let (n_frames, n_pixels) = (stacks[0].len(), stacks[0][0].len());
    let saturation = config.saturation_level * T::SCALE_FROM_8BIT;
    // Per pixel, the exposures at which every sample is below saturation (bit `e` for
    // exposure `e`, shortest first), in one pass over the frames; the pixel's source is the
    // longest of them.
    let mut usable = vec![0u16; n_pixels];
    let chunk = PIXELS_PER_TASK;
    usable
        .par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(c, out)| {
            let start = c * chunk;
            let mut peak = vec![0.0f32; out.len()];
            for (e, stack) in stacks.iter().enumerate() {
                peak.iter_mut().for_each(|p| *p = 0.0);
                for frame in stack {
                    for (p, &v) in peak.iter_mut().zip(&frame[start..start + out.len()]) {
                        *p = p.max(v.to_f32());
                    }
                }
                for (m, &p) in out.iter_mut().zip(&peak) {
                    if p < saturation {
                        *m |= 1 << e;
                    }
                }
            }
        });
    let source: Vec<u8> = usable
        .iter()
        .map(|&m| match m {
            0 => SATURATED_EVERYWHERE,
            // The highest bit set: below 16, so it fits.
            _ => (15 - m.leading_zeros()) as u8,
        })
        .collect();
    let frames = match config.method {
        FusionMethod::Longest => (0..n_frames)
            .map(|k| {
                let data: Vec<T> = source
                    .par_iter()
                    .enumerate()
                    .map(|(p, &s)| {
                        let e = if s == SATURATED_EVERYWHERE {
                            0
                        } else {
                            usize::from(s)
                        };
                        stacks[e][k][p]
                    })
                    .collect();
                Ok(wrap(Frame::new(width, height, data)?))
            })
            .collect::<Result<_, CodecError>>()?,
        FusionMethod::Radiance => {
            let scale = 65535.0 / T::MAX_VALUE.to_f32();
            let dark = config.dark_level * T::SCALE_FROM_8BIT;
            (0..n_frames)
                .map(|k| {
                    let data: Vec<u16> = source
                        .par_iter()
                        .zip(&usable)
                        .enumerate()
                        .map(|(p, (&s, &mask))| {
                            let Some(&chosen) = times.get(usize::from(s)) else {
                                return (stacks[0][k][p].to_f32() * scale).round() as u16;
                            };
                            // Each sample scaled to the chosen exposure, `v·chosen/t`, weighted
                            // by `t²`, the inverse of its variance once scaled when the
                            // camera's read noise dominates (as it does in the dark pixels that
                            // several exposures serve): `chosen · Σ t·v / Σ t²`, never noisier
                            // than the chosen exposure alone.
                            let (mut sum, mut weight) = (0.0f64, 0.0f64);
                            for (e, stack) in stacks.iter().enumerate().take(usize::from(s) + 1) {
                                if mask & (1 << e) != 0 {
                                    let t = times[e];
                                    sum += t * f64::from(stack[k][p].to_f32() - dark);
                                    weight += t * t;
                                }
                            }
                            let v = (chosen * sum / weight + f64::from(dark)) * f64::from(scale);
                            v.round().clamp(0.0, 65535.0) as u16
                        })
                        .collect();
                    Ok(GreyImage::U16(Frame::new(width, height, data)?))
                })
                .collect::<Result<_, CodecError>>()?
        }
    };
    Ok((frames, source))
}

/// Settings of [`choose_exposures`]. Levels are fractions of full scale unless they say
/// otherwise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AutoExposureConfig {
    /// A pixel is lit when the white frame is brighter than the black one by more than this
    /// (8-bit grey levels). Default 5: a black object (albedo 0.04) at an exposure that puts
    /// white paper at three quarters of full scale reads ~9 levels, a camera's noise 1–3.
    pub min_lit: f32,
    /// Share of the lit pixels the shortest exposure may let saturate (specular glints that
    /// no exposure of the set would save). Default 0.001.
    pub bright_share: f64,
    /// Where the shortest exposure puts the brightest lit pixels (the `1 − bright_share`
    /// quantile) under full white. Default 0.9.
    pub bright_level: f64,
    /// Share of the lit pixels the longest exposure may leave below `dark_level`. Default 0.02.
    pub dark_share: f64,
    /// Where the longest exposure puts the darkest lit pixels (the `dark_share` quantile)
    /// under full white. Default 0.5: fringes of half of full scale.
    pub dark_level: f64,
    /// Largest ratio between consecutive exposures: every pixel then has an exposure that
    /// puts it within this factor below saturation. Default 4 (two stops).
    pub step: f64,
    /// Most exposures chosen. Default 4 (a ratio of 64 with `step` 4).
    pub max_exposures: usize,
    /// The camera's shortest and longest exposures (milliseconds). Default 0.1 and 1000.
    pub min_exposure_ms: f64,
    /// See `min_exposure_ms`.
    pub max_exposure_ms: f64,
}

impl Default for AutoExposureConfig {
    fn default() -> Self {
        Self {
            min_lit: 5.0,
            bright_share: 0.001,
            bright_level: 0.9,
            dark_share: 0.02,
            dark_level: 0.5,
            step: 4.0,
            max_exposures: 4,
            min_exposure_ms: 0.1,
            max_exposure_ms: 1000.0,
        }
    }
}

/// What [`choose_exposures`] makes of a white and a black frame.
#[derive(Debug, Clone, PartialEq)]
pub enum ExposureChoice {
    /// The frames cannot tell: capture them again at `exposure_ms` (shorter when too many lit
    /// pixels saturate, longer when nothing is lit).
    MeasureAgain {
        /// The exposure to measure at.
        exposure_ms: f64,
        /// Why, for the log.
        reason: String,
    },
    /// The exposures to capture at.
    Chosen(ExposurePlan),
}

/// The exposures [`choose_exposures`] chose, and what it saw.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ExposurePlan {
    /// Exposure times, shortest first (milliseconds).
    pub exposures_ms: Vec<f64>,
    /// The exposure the white and black frames were captured at.
    pub measured_at_ms: f64,
    /// Pixels lit by the projector.
    pub lit_pixels: usize,
    /// Share of the lit pixels saturated in the white frame.
    pub saturated_share: f64,
    /// The brightest and the darkest lit pixels' light (white minus black, fraction of full
    /// scale) at `measured_at_ms`: the quantiles `1 − bright_share` and `dark_share`.
    pub bright: f64,
    /// See `bright`.
    pub dark: f64,
}

/// Chooses the exposures of a scene from a frame captured under full white and one under
/// black, both at `exposure_ms`: the shortest keeps the brightest lit pixels below saturation
/// ([`AutoExposureConfig::bright_level`]), the longest lifts the darkest lit ones to
/// [`AutoExposureConfig::dark_level`], and the exposures in between are spaced by at most
/// [`AutoExposureConfig::step`]. Too many lit pixels saturated, or none lit, asks for another
/// measurement ([`ExposureChoice::MeasureAgain`]).
///
/// # Errors
/// [`CodecError::FrameSize`] when the frames differ in size, [`CodecError::Parameter`] naming
/// `exposure_ms` or the field of `config` out of range, and [`CodecError::Frames`] when nothing
/// is lit even at the longest exposure, or too much saturates at the shortest (the message
/// says which, and what to do).
pub fn choose_exposures(
    white: &GreyImage,
    black: &GreyImage,
    exposure_ms: f64,
    config: &AutoExposureConfig,
) -> Result<ExposureChoice, CodecError> {
    check_auto(config, exposure_ms)?;
    if (white.width(), white.height()) != (black.width(), black.height()) {
        return Err(CodecError::FrameSize {
            frame: "black frame".to_owned(),
            expected_width: white.width(),
            expected_height: white.height(),
            found_width: black.width(),
            found_height: black.height(),
        });
    }
    // Both at 16 bits (an 8-bit value `v` as `257 v`: the same fraction of full scale).
    let (white, black) = (white.clone().into_u16(), black.clone().into_u16());
    let full = f64::from(u16::MAX);
    let saturation = f64::from(DEFAULT_SATURATION_LEVEL) / 255.0 * full;
    let min_lit = f64::from(config.min_lit) / 255.0;
    // Light (fraction of full scale) of each lit pixel, its black level, and the saturated.
    let (mut light, mut blacks, mut saturated) = (Vec::new(), Vec::new(), 0usize);
    for (&w, &b) in white.data().iter().zip(black.data()) {
        let (w, b) = (f64::from(w), f64::from(b));
        let l = (w - b) / full;
        if l > min_lit {
            light.push(l);
            blacks.push(b / full);
            if w >= saturation {
                saturated += 1;
            }
        }
    }
    let longest = config.max_exposure_ms;
    if light.is_empty() {
        let longer = (exposure_ms * config.step).min(longest);
        if longer > exposure_ms {
            return Ok(ExposureChoice::MeasureAgain {
                exposure_ms: longer,
                reason: format!("nothing is lit at {exposure_ms} ms"),
            });
        }
        return Err(CodecError::Frames(format!(
            "the white frame at {exposure_ms} ms is no brighter than the black one by more than {} grey levels anywhere, and no longer exposure is allowed (max_exposure_ms {longest}): is the projector on and pointed at the object?",
            config.min_lit
        )));
    }
    let share = saturated as f64 / light.len() as f64;
    if share > config.bright_share {
        let shorter = (exposure_ms / config.step).max(config.min_exposure_ms);
        if shorter < exposure_ms {
            return Ok(ExposureChoice::MeasureAgain {
                exposure_ms: shorter,
                reason: format!(
                    "{:.1} % of the lit pixels saturate at {exposure_ms} ms",
                    100.0 * share
                ),
            });
        }
    }
    let n = light.len();
    let bright = quantile(&mut light, 1.0 - config.bright_share);
    let dark = quantile(&mut light, config.dark_share).max(min_lit);
    let pedestal = quantile(&mut blacks, 0.5);
    // Light scales with the exposure; the black level does not.
    let shortest = (exposure_ms * (config.bright_level - pedestal).max(0.0) / bright)
        .clamp(config.min_exposure_ms, longest);
    let most = shortest
        * config
            .step
            .powi(i32::try_from(config.max_exposures - 1).unwrap_or(0));
    let long = (exposure_ms * (config.dark_level - pedestal).max(0.0) / dark)
        .min(most)
        .min(longest)
        .max(shortest);
    let ratio = long / shortest;
    let count = if ratio <= 1.0 + 1e-9 {
        1
    } else {
        ((ratio.ln() / config.step.ln()).ceil() as usize + 1).min(config.max_exposures)
    };
    let exposures_ms = if count == 1 {
        vec![shortest]
    } else {
        let r = ratio.powf(1.0 / (count - 1) as f64);
        (0..count)
            .map(|i| shortest * r.powi(i32::try_from(i).unwrap_or(0)))
            .collect()
    };
    Ok(ExposureChoice::Chosen(ExposurePlan {
        exposures_ms,
        measured_at_ms: exposure_ms,
        lit_pixels: n,
        saturated_share: share,
        bright,
        dark,
    }))
}

fn check_auto(config: &AutoExposureConfig, exposure_ms: f64) -> Result<(), CodecError> {
    let bad = |name: &str, value: f64, what: &str| CodecError::Parameter {
        name: name.to_owned(),
        message: format!("{value} is not {what}"),
    };
    let share = |v: f64| (0.0..0.5).contains(&v);
    let level = |v: f64| v > 0.0 && v <= 1.0;
    if !(exposure_ms.is_finite() && exposure_ms > 0.0) {
        return Err(bad("exposure_ms", exposure_ms, "a positive exposure time"));
    }
    let min_lit = f64::from(config.min_lit);
    for (name, value, ok, what) in [
        (
            "min_lit",
            min_lit,
            min_lit.is_finite() && min_lit >= 0.0,
            "a grey level ≥ 0",
        ),
        (
            "bright_share",
            config.bright_share,
            share(config.bright_share),
            "a share in [0, 0.5)",
        ),
        (
            "dark_share",
            config.dark_share,
            share(config.dark_share),
            "a share in [0, 0.5)",
        ),
        (
            "bright_level",
            config.bright_level,
            level(config.bright_level),
            "a level in (0, 1]",
        ),
        (
            "dark_level",
            config.dark_level,
            level(config.dark_level),
            "a level in (0, 1]",
        ),
    ] {
        if !ok {
            return Err(bad(name, value, what));
        }
    }
    if !(config.step.is_finite() && config.step > 1.0) {
        return Err(bad("step", config.step, "a ratio above 1"));
    }
    if !(1..=MAX_EXPOSURES).contains(&config.max_exposures) {
        return Err(CodecError::Parameter {
            name: "max_exposures".to_owned(),
            message: format!("{} is not in 1..={MAX_EXPOSURES}", config.max_exposures),
        });
    }
    if !(config.min_exposure_ms.is_finite()
        && config.min_exposure_ms > 0.0
        && config.max_exposure_ms.is_finite()
        && config.max_exposure_ms >= config.min_exposure_ms)
    {
        return Err(CodecError::Parameter {
            name: "min_exposure_ms".to_owned(),
            message: format!(
                "{}..{} ms is not a range of positive exposure times",
                config.min_exposure_ms, config.max_exposure_ms
            ),
        });
    }
    Ok(())
}

/// The `q` quantile of `values` (not empty), by selection.
fn quantile(values: &mut [f64], q: f64) -> f64 {
    let i = ((values.len() - 1) as f64 * q).round() as usize;
    let (_, v, _) = values.select_nth_unstable_by(i.min(values.len() - 1), f64::total_cmp);
    *v
}

/// The file that says a capture folder's frames were fused from several exposures.
pub const EXPOSURES_FILE: &str = "exposures.json";
/// `format` of [`EXPOSURES_FILE`].
pub const EXPOSURES_FORMAT: &str = "sl-exposures";
/// `version` of [`EXPOSURES_FILE`].
pub const EXPOSURES_VERSION: u32 = 1;

/// One exposure's capture folder, in an [`ExposureRecord`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExposureFolder {
    /// The folder of its frames (same file names as the fused capture's), relative to the
    /// folder holding `exposures.json`.
    pub dir: String,
    /// Its exposure time (milliseconds).
    pub exposure_ms: f64,
}

/// `exposures.json`: a capture folder whose frames are fused from the captures of
/// sub-folders at several exposures (docs/capture-format.md). Written by a capture session
/// with exposures; written by hand, it lets `slscan fuse` fuse another system's captures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExposureRecord {
    /// [`EXPOSURES_FORMAT`].
    pub format: String,
    /// [`EXPOSURES_VERSION`].
    pub version: u32,
    /// The exposures' folders, in any order.
    pub exposures: Vec<ExposureFolder>,
    /// How they were (or are to be) fused; the defaults when absent.
    #[serde(default)]
    pub fusion: FusionSettings,
    /// What the fusion did, once done.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub summary: Option<FusionSummary>,
}

/// The fusion settings of an [`ExposureRecord`] (every key optional).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FusionSettings {
    /// [`FusionConfig::method`].
    pub method: FusionMethod,
    /// [`FusionConfig::dark_level`].
    pub dark_level: f32,
}

impl FusionSettings {
    /// The fusion configuration these settings give (the decoder's saturation level).
    pub fn config(&self) -> FusionConfig {
        FusionConfig {
            method: self.method,
            dark_level: self.dark_level,
            ..FusionConfig::default()
        }
    }
}

impl ExposureRecord {
    /// A record of `exposures` (folder, milliseconds) fused with `fusion`.
    pub fn new(exposures: Vec<ExposureFolder>, fusion: FusionSettings) -> Self {
        Self {
            format: EXPOSURES_FORMAT.to_owned(),
            version: EXPOSURES_VERSION,
            exposures,
            fusion,
            summary: None,
        }
    }

    /// Reads `path`.
    ///
    /// # Errors
    /// [`CodecError::Io`], [`CodecError::ManifestJson`] (JSON that does not parse, or keys
    /// that are missing or unknown: serde names them), [`CodecError::Manifest`] naming
    /// `format`, `version` or `exposures` when they are not this format's.
    pub fn load(path: &std::path::Path) -> Result<Self, CodecError> {
        let text = std::fs::read_to_string(path).map_err(|e| CodecError::io(path, "read", e))?;
        let record: Self =
            serde_json::from_str(&text).map_err(|source| CodecError::ManifestJson {
                path: path.to_path_buf(),
                source,
            })?;
        let bad = |key: &str, message: String| CodecError::Manifest {
            path: path.to_path_buf(),
            key: key.to_owned(),
            message,
        };
        if record.format != EXPOSURES_FORMAT {
            return Err(bad(
                "format",
                format!("'{}' is not '{EXPOSURES_FORMAT}'", record.format),
            ));
        }
        if record.version != EXPOSURES_VERSION {
            return Err(bad(
                "version",
                format!(
                    "{} is not a version this build reads ({EXPOSURES_VERSION})",
                    record.version
                ),
            ));
        }
        if record.exposures.is_empty() {
            return Err(bad("exposures", "lists no exposure".to_owned()));
        }
        for (i, e) in record.exposures.iter().enumerate() {
            if !(e.exposure_ms.is_finite() && e.exposure_ms > 0.0) {
                return Err(bad(
                    &format!("exposures[{i}].exposure_ms"),
                    format!("{} is not a positive exposure time", e.exposure_ms),
                ));
            }
            let p = std::path::Path::new(&e.dir);
            if e.dir.is_empty() || p.is_absolute() || p.components().any(|c| c.as_os_str() == "..")
            {
                return Err(bad(
                    &format!("exposures[{i}].dir"),
                    format!("'{}' is not a sub-folder of the capture", e.dir),
                ));
            }
        }
        Ok(record)
    }

    /// Writes the record to `path` (pretty JSON).
    ///
    /// # Errors
    /// [`CodecError::Io`].
    pub fn save(&self, path: &std::path::Path) -> Result<(), CodecError> {
        let text =
            serde_json::to_string_pretty(self).map_err(|source| CodecError::ManifestJson {
                path: path.to_path_buf(),
                source,
            })?;
        std::fs::write(path, text + "\n").map_err(|e| CodecError::io(path, "write", e))
    }
}
