//! N-step phase-shift fringes at one or more frequencies, and their decoder.
//!
//! Frame `k` (0-based) of frequency `i` shows, at projector coordinate `t` along the axis,
//!
//! ```text
//! I_k(t) = ( 1/2 + 1/2 cos(Phi_i(t) + psi - s 2 pi k / N) )^(1/gamma)
//! Phi_i(t) = 2 pi (t - origin) / lambda_i,    lambda_i = extent / periods[i]
//! ```
//!
//! where `psi` is `phase_offset`, `s` the `shift_sign` (+1 or -1) and `gamma` the projector gamma
//! being pre-compensated (1 for none). With `delta_k = s 2 pi k / N` the least-squares solution
//! over the `N` steps is `Phi + psi = atan2(sum I_k sin delta_k, sum I_k cos delta_k)`, the
//! modulation `B = (2/N) |sum I_k e^(i delta_k)|` and the background `A = (1/N) sum I_k`.
//! Frames are ordered frequency-major: all steps of `periods[0]`, then of `periods[1]`, ...
//!
//! The absolute phase `Phi` is 0 at `origin` (by default `-0.5`, the leading edge of the
//! projector, so `periods` count whole periods across the image) and grows with the
//! coordinate; a decoded pixel's coordinate is `origin + lambda * Phi / (2 pi)`.

use std::f64::consts::TAU;

use crate::bits::Band;
use crate::correspondence::{AxisMap, InvalidReason};
use crate::fast_math;
use crate::frame::{check_block, dims};
use crate::kernel::{self, AxisRows, Kernel, fill_out};
use crate::pattern::{positive, within};
use crate::response::PhaseCorrection;
use crate::unwrap::{Plan, Unwrap, UnwrapScratch, gcd};
use crate::{Axis, CodecError, DecodeConfig, Frame, ImageSize, Sample};
use sl_image::ToneCurve;

/// Smallest fringe period in projector pixels: below 2 pixels a sinusoid cannot be displayed
/// (Nyquist), and the decoder would see aliases.
pub const MIN_PERIOD_PIXELS: f64 = 2.0;

/// Largest number of phase steps: more than 64 buys nothing (noise falls as `1/sqrt(N)`) and
/// bounds the step tables.
pub const MAX_STEPS: u32 = 64;

/// Direction in which successive phase steps move the fringes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ShiftSign {
    /// `delta_k = +2 pi k / N`: step `k` shows `cos(Phi - delta_k)`, fringes move towards
    /// increasing coordinates.
    #[default]
    Positive,
    /// `delta_k = -2 pi k / N`: step `k` shows `cos(Phi + 2 pi k / N)` (SLMaster, OpenCV's
    /// `SinusoidalPattern`).
    Negative,
}

impl ShiftSign {
    /// `+1.0` or `-1.0`.
    pub fn value(self) -> f64 {
        match self {
            Self::Positive => 1.0,
            Self::Negative => -1.0,
        }
    }

    /// From `+1` / `-1`.
    pub fn from_value(v: i64) -> Option<Self> {
        match v {
            1 => Some(Self::Positive),
            -1 => Some(Self::Negative),
            _ => None,
        }
    }
}

/// The sinusoid shared by phase and hybrid blocks (one frequency).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fringe<'a> {
    pub(crate) period: f64,
    pub(crate) origin: f64,
    pub(crate) phase_offset: f64,
    pub(crate) sign: f64,
    pub(crate) steps: u32,
    pub(crate) gamma: f64,
    pub(crate) precompensation: Option<&'a ToneCurve>,
}

impl Fringe<'_> {
    /// Pattern intensity of step `k` at coordinate `t`.
    pub(crate) fn value(&self, k: u32, t: f64) -> f64 {
        let phi = TAU * (t - self.origin) / self.period;
        let delta = self.sign * TAU * f64::from(k) / f64::from(self.steps);
        precompensate(
            0.5 + 0.5 * (phi + self.phase_offset - delta).cos(),
            self.gamma,
            self.precompensation,
        )
    }
}

/// The value a block shows for the light `v` it wants: through the measured response's
/// inverse when the block pre-compensates one, else `v^(1/gamma)`.
pub(crate) fn precompensate(v: f64, gamma: f64, curve: Option<&ToneCurve>) -> f64 {
    match curve {
        Some(c) => c.value_for(v),
        None if gamma == 1.0 => v,
        None => v.clamp(0.0, 1.0).powf(1.0 / gamma),
    }
}

/// Parameters of a phase-shift block.
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseShiftSpec {
    /// Coded axis.
    pub axis: Axis,
    /// Projector pixels along the axis.
    pub extent: u32,
    /// Phase steps per frequency, `N >= 3`.
    pub steps: u32,
    /// Periods across the projector extent, one entry per frequency (non-integer allowed,
    /// except where the unwrapping method says otherwise).
    pub periods: Vec<f64>,
    /// Temporal unwrapping method.
    pub unwrap: Unwrap,
    /// Projector coordinate where the absolute phase is 0 (default `-0.5`).
    pub origin: f64,
    /// Constant phase `psi` added to the pattern, radians (default 0).
    pub phase_offset: f64,
    /// Direction of the phase steps.
    pub shift_sign: ShiftSign,
    /// Projector gamma pre-compensated in the rendered patterns (1 = linear projector).
    pub gamma: f64,
    /// The projector's measured response pre-compensated in the rendered patterns (each
    /// value `p` shown as `response.value_for(p)`, so that the light is a sinusoid); when
    /// given it replaces `gamma`. Manifest key `precompensation`. Default `None`.
    pub precompensation: Option<ToneCurve>,
}

impl PhaseShiftSpec {
    /// A block with default conventions (origin `-0.5`, no offset, positive shifts, gamma 1).
    pub fn new(
        axis: Axis,
        projector: ImageSize,
        steps: u32,
        periods: Vec<f64>,
        unwrap: Unwrap,
    ) -> Self {
        Self {
            axis,
            extent: axis.extent(projector),
            steps,
            periods,
            unwrap,
            origin: -0.5,
            phase_offset: 0.0,
            shift_sign: ShiftSign::Positive,
            gamma: 1.0,
            precompensation: None,
        }
    }

    /// This block with the projector's measured `response` pre-compensated in its patterns
    /// ([`Self::precompensation`]).
    #[must_use]
    pub fn precompensated(mut self, response: ToneCurve) -> Self {
        self.precompensation = Some(response);
        self
    }

    /// Three frequencies for heterodyne unwrapping whose finest period is `finest_period_px`
    /// projector pixels across an `extent` of pixels: `p1 = extent / finest_period_px`
    /// periods, `p2 = 7/8 p1` (their beat: `p1 / 8` periods) and `p3 = 2 p2 − p1 + 0.9`, so
    /// that the beat of the two beats is 0.9 period across the projector — one unambiguous
    /// phase from edge to edge.
    ///
    /// ```
    /// let p = sl_codec::PhaseShiftSpec::heterodyne_periods(1280.0, 20.0);
    /// assert_eq!(p[0], 64.0);
    /// // The beat of the beats, (p1 - p2) - (p2 - p3), is 0.9 period across.
    /// assert!(((p[0] - p[1]) - (p[1] - p[2]) - 0.9).abs() < 1e-12);
    /// ```
    #[must_use]
    pub fn heterodyne_periods(extent: f64, finest_period_px: f64) -> Vec<f64> {
        let p1 = extent / finest_period_px;
        let p2 = p1 * 7.0 / 8.0;
        vec![p1, p2, 2.0 * p2 - p1 + 0.9]
    }

    /// Number of frames: `steps * periods.len()`.
    pub fn frame_count(&self) -> usize {
        self.steps as usize * self.periods.len()
    }

    /// Period width in projector pixels of frequency `i`.
    pub fn period_pixels(&self, i: usize) -> Option<f64> {
        self.periods.get(i).map(|p| f64::from(self.extent) / p)
    }

    /// Checks every parameter, including what the unwrapping method needs of `periods`.
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming the bad field.
    pub fn validate(&self) -> Result<(), CodecError> {
        validate_steps(self.steps)?;
        if self.extent == 0 {
            return Err(CodecError::parameter(
                "extent",
                "the projector must not be empty",
            ));
        }
        if self.periods.is_empty() {
            return Err(CodecError::parameter(
                "periods",
                "needs at least one frequency",
            ));
        }
        for (i, &p) in self.periods.iter().enumerate() {
            let name = format!("periods[{i}]");
            positive(&name, p)?;
            let px = f64::from(self.extent) / p;
            if px < MIN_PERIOD_PIXELS {
                return Err(CodecError::parameter(
                    name,
                    format!(
                        "{p} periods across {} px is {px:.2} px per period, below {MIN_PERIOD_PIXELS}",
                        self.extent
                    ),
                ));
            }
        }
        // The fringes repeat: an origin beyond the projector or an offset beyond a turn says
        // nothing more, and only loses precision.
        within(
            "origin",
            self.origin,
            f64::from(self.extent),
            "projector px",
        )?;
        within(
            "phase_offset",
            self.phase_offset,
            std::f64::consts::TAU,
            "rad",
        )?;
        positive("gamma", self.gamma)?;
        let n = self.periods.len();
        let p = &self.periods;
        match self.unwrap {
            Unwrap::None => {
                if n != 1 || p[0] > 1.0 {
                    return Err(CodecError::parameter(
                        "unwrap",
                        format!(
                            "'none' needs one frequency of at most 1 period, got periods {p:?}: choose an unwrapping method"
                        ),
                    ));
                }
            }
            Unwrap::Hierarchical => {
                let min = p.iter().copied().fold(f64::INFINITY, f64::min);
                if n < 2 || min > 1.0 {
                    return Err(CodecError::parameter(
                        "periods",
                        format!(
                            "hierarchical unwrapping needs >= 2 frequencies, the coarsest with at most 1 period; got {p:?}"
                        ),
                    ));
                }
            }
            Unwrap::Heterodyne => {
                if n != 3 {
                    return Err(CodecError::parameter(
                        "periods",
                        format!("heterodyne unwrapping needs exactly 3 frequencies, got {n}"),
                    ));
                }
                let (p12, p23) = (p[0] - p[1], p[1] - p[2]);
                let p123 = p12 - p23;
                if p12 == 0.0 || p23 == 0.0 || p123 == 0.0 || p123.abs() > 1.0 + 1e-9 {
                    return Err(CodecError::parameter(
                        "periods",
                        format!(
                            "heterodyne needs P1 != P2 != P3 and 0 < |P1 - 2 P2 + P3| <= 1; {p:?} gives beats {p12}, {p23} and {p123}"
                        ),
                    ));
                }
            }
            Unwrap::NumberTheoretic => {
                if n < 2 {
                    return Err(CodecError::parameter(
                        "periods",
                        "number-theoretic unwrapping needs >= 2 frequencies",
                    ));
                }
                let (a, b) = (p[0], p[1]);
                let int = |v: f64| (v - v.round()).abs() < 1e-9 && (1.0..1e6).contains(&v);
                if !int(a) || !int(b) || gcd(a.round() as u64, b.round() as u64) != 1 {
                    return Err(CodecError::parameter(
                        "periods",
                        format!(
                            "number-theoretic unwrapping needs periods[0] and periods[1] to be coprime integers, got {a} and {b}"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    pub(crate) fn fringe(&self, i: usize) -> Option<Fringe<'_>> {
        Some(Fringe {
            period: self.period_pixels(i)?,
            origin: self.origin,
            phase_offset: self.phase_offset,
            sign: self.shift_sign.value(),
            steps: self.steps,
            gamma: self.gamma,
            precompensation: self.precompensation.as_ref(),
        })
    }

    /// Intensity in `[0, 1]` of frame `frame` of the block at coordinate `t`, or `None` if
    /// `frame >= frame_count()`.
    pub fn pattern_value(&self, frame: usize, t: f64) -> Option<f64> {
        if self.steps == 0 {
            return None;
        }
        let n = self.steps as usize;
        let fringe = self.fringe(frame / n)?;
        Some(fringe.value((frame % n) as u32, t))
    }
}

pub(crate) fn validate_steps(steps: u32) -> Result<(), CodecError> {
    if !(3..=MAX_STEPS).contains(&steps) {
        return Err(CodecError::parameter(
            "steps",
            format!("must be in 3..={MAX_STEPS}, got {steps}"),
        ));
    }
    Ok(())
}

/// Wrapped phase, modulation and background of one camera row at one frequency.
///
/// Reusable by the decoders and by callers that want the raw maps ([`wrapped_phase`]).
pub(crate) struct StepTable {
    sin: Vec<f32>,
    cos: Vec<f32>,
    inv_n: f32,
    two_over_n: f32,
    /// `psi / (2 pi)`
    offset_cycles: f32,
    /// The correction of a projector response that is not linear.
    correction: Option<PhaseCorrection>,
}

impl StepTable {
    pub(crate) fn new(steps: u32, sign: f64, phase_offset: f64) -> Self {
        let n = f64::from(steps);
        let delta = |k: u32| sign * TAU * f64::from(k) / n;
        Self {
            sin: (0..steps).map(|k| delta(k).sin() as f32).collect(),
            cos: (0..steps).map(|k| delta(k).cos() as f32).collect(),
            inv_n: (1.0 / n) as f32,
            two_over_n: (2.0 / n) as f32,
            offset_cycles: (phase_offset / TAU) as f32,
            correction: None,
        }
    }

    /// The table of a block's fringes (`steps`, `sign`, `phase_offset`, pre-compensated
    /// `gamma`) decoded with `config`: with a phase correction when `config` gives a projector
    /// response that is not linear.
    pub(crate) fn for_block(
        steps: u32,
        sign: ShiftSign,
        phase_offset: f64,
        shown: (f64, Option<&ToneCurve>),
        config: &DecodeConfig,
    ) -> Result<Self, CodecError> {
        let mut table = Self::new(steps, sign.value(), phase_offset);
        let (gamma, precompensation) = shown;
        if let Some(response) = &config.projector_response
            && !(response.is_linear() && gamma == 1.0 && precompensation.is_none())
        {
            table.correction = Some(PhaseCorrection::for_patterns(
                response,
                steps,
                sign,
                gamma,
                precompensation,
            )?);
        }
        Ok(table)
    }

    /// Corrects wrapped phases (cycles of `Phi`) for the projector's response, if known.
    #[inline]
    pub(crate) fn correct(&self, fracs: &mut [f32]) {
        if let Some(c) = &self.correction {
            c.correct_fracs(fracs, self.offset_cycles);
        }
    }
}

/// Per-row accumulators of one frequency.
pub(crate) struct PhaseRow {
    pub(crate) s: Vec<f32>,
    pub(crate) c: Vec<f32>,
    pub(crate) a: Vec<f32>,
}

impl PhaseRow {
    pub(crate) fn new(width: usize) -> Self {
        Self {
            s: vec![0.0; width],
            c: vec![0.0; width],
            a: vec![0.0; width],
        }
    }

    /// Sets the accumulators to `n` entries.
    pub(crate) fn fit(&mut self, n: usize) {
        self.s.resize(n, 0.0);
        self.c.resize(n, 0.0);
        self.a.resize(n, 0.0);
    }

    /// Accumulates the `N` step rows given by `row(k)`; tracks the largest sample in `maxv`.
    #[inline(always)]
    pub(crate) fn accumulate<'r, T: Sample>(
        &mut self,
        table: &StepTable,
        maxv: &mut [u16],
        mut row: impl FnMut(usize) -> &'r [T],
    ) {
        self.s.fill(0.0);
        self.c.fill(0.0);
        self.a.fill(0.0);
        let n = self.s.len();
        for (k, (&sk, &ck)) in table.sin.iter().zip(&table.cos).enumerate() {
            let r = row(k);
            if r.len() < n {
                continue;
            }
            let (r, s, c, a, m) = (
                &r[..n],
                &mut self.s[..n],
                &mut self.c[..n],
                &mut self.a[..n],
                &mut maxv[..n],
            );
            for i in 0..n {
                let v = r[i].to_f32();
                s[i] += v * sk;
                c[i] += v * ck;
                a[i] += v;
                m[i] = m[i].max(r[i].to_u16());
            }
        }
    }

    /// Writes the wrapped phase in cycles `[0, 1)` (of `Phi`, offset removed), the modulation
    /// `B` and the background `A`.
    #[inline(always)]
    pub(crate) fn finish(
        &self,
        table: &StepTable,
        frac: &mut [f32],
        modulation: &mut [f32],
        background: &mut [f32],
    ) {
        let n = frac.len();
        let (s, c, a, modulation, background) = (
            &self.s[..n],
            &self.c[..n],
            &self.a[..n],
            &mut modulation[..n],
            &mut background[..n],
        );
        let inv_tau = 1.0 / std::f32::consts::TAU;
        for i in 0..n {
            let theta = fast_math::atan2(s[i], c[i]);
            let f = fast_math::fract(theta * inv_tau - table.offset_cycles);
            // fract may return 1.0 for tiny negative inputs; fold it to 0.
            frac[i] = if f >= 1.0 { 0.0 } else { f };
            modulation[i] = table.two_over_n * (s[i] * s[i] + c[i] * c[i]).sqrt();
            background[i] = a[i] * table.inv_n;
        }
    }
}

/// One frequency of a band in a single pass over its `N` step rows: writes the wrapped phase
/// (cycles) into `frac`, and merges the modulation into `bmin` (min), the darkest level `A - B`
/// into `dark` (min) and the largest sample into `maxv` (max). Step counts 3-6 and 8 have
/// unrolled loops that keep everything in registers; others go through [`PhaseRow`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fused_pass<T: Sample>(
    rows: &[&[T]],
    table: &StepTable,
    frac: &mut [f32],
    bmin: &mut [f32],
    dark: &mut [f32],
    maxv: &mut [u16],
    acc: &mut PhaseRow,
) {
    let n = frac.len();
    if rows.iter().any(|r| r.len() < n) || bmin.len() < n || dark.len() < n || maxv.len() < n {
        return;
    }
    match rows.len() {
        3 => fused::<T, 3>(rows, table, frac, bmin, dark, maxv),
        4 => fused::<T, 4>(rows, table, frac, bmin, dark, maxv),
        5 => fused::<T, 5>(rows, table, frac, bmin, dark, maxv),
        6 => fused::<T, 6>(rows, table, frac, bmin, dark, maxv),
        8 => fused::<T, 8>(rows, table, frac, bmin, dark, maxv),
        _ => {
            acc.fit(n);
            acc.accumulate(table, maxv, |k| rows.get(k).copied().unwrap_or(&[]));
            // Reuse the accumulators as outputs: s -> modulation, c -> background.
            let (s, c, a) = (&mut acc.s[..n], &mut acc.c[..n], &acc.a[..n]);
            let inv_tau = 1.0 / std::f32::consts::TAU;
            for i in 0..n {
                let theta = fast_math::atan2(s[i], c[i]);
                let f = fast_math::fract(theta * inv_tau - table.offset_cycles);
                frac[i] = if f >= 1.0 { 0.0 } else { f };
                let b = table.two_over_n * (s[i] * s[i] + c[i] * c[i]).sqrt();
                let bg = a[i] * table.inv_n;
                bmin[i] = bmin[i].min(b);
                dark[i] = dark[i].min(bg - b);
                s[i] = b;
                c[i] = bg;
            }
        }
    }
}

#[inline(always)]
fn fused<T: Sample, const N: usize>(
    rows: &[&[T]],
    table: &StepTable,
    frac: &mut [f32],
    bmin: &mut [f32],
    dark: &mut [f32],
    maxv: &mut [u16],
) {
    let n = frac.len();
    let r: [&[T]; N] = std::array::from_fn(|k| rows.get(k).map_or(&[][..], |r| &r[..n]));
    let sin: [f32; N] = std::array::from_fn(|k| table.sin.get(k).copied().unwrap_or(0.0));
    let cos: [f32; N] = std::array::from_fn(|k| table.cos.get(k).copied().unwrap_or(0.0));
    let (bmin, dark, maxv) = (&mut bmin[..n], &mut dark[..n], &mut maxv[..n]);
    let inv_tau = 1.0 / std::f32::consts::TAU;
    for i in 0..n {
        let (mut s, mut c, mut a, mut m) = (0.0_f32, 0.0_f32, 0.0_f32, maxv[i]);
        for k in 0..N {
            let v = r[k][i];
            let vf = v.to_f32();
            s += vf * sin[k];
            c += vf * cos[k];
            a += vf;
            m = m.max(v.to_u16());
        }
        let theta = fast_math::atan2(s, c);
        let f = fast_math::fract(theta * inv_tau - table.offset_cycles);
        frac[i] = if f >= 1.0 { 0.0 } else { f };
        let b = table.two_over_n * (s * s + c * c).sqrt();
        bmin[i] = bmin[i].min(b);
        dark[i] = dark[i].min(a * table.inv_n - b);
        maxv[i] = m;
    }
}

/// Raw per-pixel maps of one frequency of a phase block, from [`wrapped_phase`].
#[derive(Clone, Debug, PartialEq)]
pub struct WrappedPhase {
    /// Camera image width.
    pub width: usize,
    /// Camera image height.
    pub height: usize,
    /// Wrapped absolute phase `Phi mod 2 pi` in `[0, 2 pi)` radians (offset `psi` removed).
    pub phase: Vec<f32>,
    /// Fringe modulation `B`, in the frames' grey levels.
    pub modulation: Vec<f32>,
    /// Background `A` (mean over the steps), in the frames' grey levels.
    pub background: Vec<f32>,
}

/// Wrapped phase, modulation and background of `steps` frames of one frequency.
///
/// # Errors
/// [`CodecError::Parameter`] for `steps` out of `3..=64` or `frames.len() != steps`,
/// [`CodecError::FrameSize`] if the frames differ in size.
///
/// # Example
/// ```
/// use sl_codec::{wrapped_phase, Frame, ShiftSign};
/// // 4 steps of one pixel with Phi = 1 rad, A = 100, B = 50.
/// let frames: Vec<Frame<u8>> = (0..4)
///     .map(|k| {
///         let v = 100.0 + 50.0 * (1.0_f64 - std::f64::consts::FRAC_PI_2 * k as f64).cos();
///         Frame::new(1, 1, vec![v.round() as u8]).unwrap()
///     })
///     .collect();
/// let w = wrapped_phase(&frames, ShiftSign::Positive, 0.0)?;
/// assert!((w.phase[0] - 1.0).abs() < 0.02);
/// assert!((w.modulation[0] - 50.0).abs() < 1.0);
/// # Ok::<(), sl_codec::CodecError>(())
/// ```
pub fn wrapped_phase<T: Sample>(
    frames: &[Frame<T>],
    shift_sign: ShiftSign,
    phase_offset: f64,
) -> Result<WrappedPhase, CodecError> {
    let steps = u32::try_from(frames.len()).unwrap_or(u32::MAX);
    validate_steps(steps)?;
    crate::frame::check_sizes(frames, None)?;
    let (w, h) = dims(frames);
    let table = StepTable::new(steps, shift_sign.value(), phase_offset);
    let mut out = WrappedPhase {
        width: w,
        height: h,
        phase: vec![0.0; w * h],
        modulation: vec![0.0; w * h],
        background: vec![0.0; w * h],
    };
    let mut acc = PhaseRow::new(w);
    let mut maxv = vec![0u16; w];
    for y in 0..h {
        acc.accumulate(&table, &mut maxv, |k| {
            frames.get(k).and_then(|f| f.row(y)).unwrap_or(&[])
        });
        let r = y * w..(y + 1) * w;
        let (Some(p), Some(m), Some(b)) = (
            out.phase.get_mut(r.clone()),
            out.modulation.get_mut(r.clone()),
            out.background.get_mut(r),
        ) else {
            break;
        };
        acc.finish(&table, p, m, b);
        for v in p.iter_mut() {
            *v *= std::f32::consts::TAU;
        }
    }
    Ok(out)
}

/// Decodes one phase-shift block from in-memory frames (in the block's frame order).
///
/// # Errors
/// [`CodecError::FrameCount`], [`CodecError::FrameSize`], or [`CodecError::Parameter`] for a
/// bad spec or config.
pub fn decode_phase<T: Sample>(
    spec: &PhaseShiftSpec,
    frames: &[Frame<T>],
    config: &DecodeConfig,
) -> Result<AxisMap, CodecError> {
    let kernel = PhaseKernel::new(spec, frames, config)?;
    let (w, h) = dims(frames);
    Ok(kernel::run_axis(
        Kernel::Phase(kernel),
        w,
        h,
        config.rows_per_task,
    ))
}

/// The per-block decoder.
pub(crate) struct PhaseKernel<'a, T: Sample> {
    spec: PhaseShiftSpec,
    frames: &'a [Frame<T>],
    width: usize,
    table: StepTable,
    plan: Plan,
    periods: Vec<f32>,
    min_modulation: f32,
    saturation: u32,
    tolerance: f32,
    quality_scale: f32,
}

/// Per-task scratch of [`PhaseKernel`].
pub(crate) struct PhaseScratch {
    acc: PhaseRow,
    fracs: Vec<Vec<f32>>,
    bmin: Vec<f32>,
    modulation: Vec<f32>,
    background: Vec<f32>,
    dark: Vec<f32>,
    maxv: Vec<u16>,
    unwrap: UnwrapScratch,
}

impl PhaseScratch {
    fn fit(&mut self, n: usize) {
        self.acc.fit(n);
        for f in &mut self.fracs {
            f.resize(n, 0.0);
        }
        self.bmin.resize(n, 0.0);
        self.modulation.resize(n, 0.0);
        self.background.resize(n, 0.0);
        self.dark.resize(n, 0.0);
        self.maxv.resize(n, 0);
        self.unwrap.fit(n);
    }
}

impl<'a, T: Sample> PhaseKernel<'a, T> {
    pub(crate) fn new(
        spec: &PhaseShiftSpec,
        frames: &'a [Frame<T>],
        config: &DecodeConfig,
    ) -> Result<Self, CodecError> {
        spec.validate()?;
        config.validate()?;
        check_block("phase", spec.axis, spec.frame_count(), frames)?;
        let scale = T::SCALE_FROM_8BIT;
        Ok(Self {
            spec: spec.clone(),
            frames,
            width: dims(frames).0,
            table: StepTable::for_block(
                spec.steps,
                spec.shift_sign,
                spec.phase_offset,
                (spec.gamma, spec.precompensation.as_ref()),
                config,
            )?,
            plan: Plan::new(spec.unwrap, &spec.periods),
            periods: spec.periods.iter().map(|&p| p as f32).collect(),
            min_modulation: config.min_modulation * scale,
            saturation: (config.saturation_level * scale)
                .round()
                .clamp(0.0, u32::MAX as f32) as u32,
            tolerance: config.unwrap_tolerance,
            quality_scale: 1.0 / scale,
        })
    }

    pub(crate) fn axis(&self) -> Axis {
        self.spec.axis
    }

    pub(crate) fn new_scratch(&self, len: usize) -> PhaseScratch {
        PhaseScratch {
            acc: PhaseRow::new(len),
            fracs: vec![vec![0.0; len]; self.spec.periods.len()],
            bmin: vec![0.0; len],
            modulation: vec![0.0; len],
            background: vec![0.0; len],
            dark: vec![0.0; len],
            maxv: vec![0; len],
            unwrap: UnwrapScratch::new(len),
        }
    }

    #[inline(always)]
    pub(crate) fn decode_band(
        &self,
        y0: usize,
        rows: usize,
        out: &mut AxisRows<'_>,
        s: &mut PhaseScratch,
    ) {
        let len = self.width * rows;
        let band = Band {
            width: self.width,
            y0,
            rows,
        };
        let n = self.spec.steps as usize;
        s.fit(len);
        s.maxv.fill(0);
        s.bmin.fill(f32::INFINITY);
        s.dark.fill(f32::INFINITY);
        let mut rows: [&[T]; MAX_STEPS as usize] = [&[]; MAX_STEPS as usize];
        for (i, frac) in s.fracs.iter_mut().enumerate() {
            for (k, r) in rows.iter_mut().take(n).enumerate() {
                *r = band.of(self.frames.get(i * n + k));
            }
            let rows = rows.get(..n).unwrap_or(&[]);
            fused_pass(
                rows,
                &self.table,
                frac,
                &mut s.bmin,
                &mut s.dark,
                &mut s.maxv,
                &mut s.acc,
            );
            self.table.correct(frac);
        }
        self.plan.unwrap_row(&s.fracs, &self.periods, &mut s.unwrap);
        let extent = self.spec.extent as f32;
        let origin = self.spec.origin as f32;
        let (lo, hi) = (-0.5_f32, extent - 0.5);
        let (min_mod, sat, tol, scale) = (
            self.min_modulation,
            self.saturation,
            self.tolerance,
            self.quality_scale,
        );
        let n = len;
        let (b, dark, maxv) = (&s.bmin[..n], &s.dark[..n], &s.maxv[..n]);
        let (t, resid) = (&s.unwrap.t[..n], &s.unwrap.resid[..n]);
        fill_out!(out.row(0, n), n, |i| {
            let c = origin + t[i] * extent;
            let r = if (c >= lo) & (c <= hi) & (resid[i] <= tol) {
                InvalidReason::Valid
            } else {
                InvalidReason::InconsistentCode
            };
            let d = if dark[i] < min_mod {
                InvalidReason::Shadow
            } else {
                InvalidReason::LowModulation
            };
            let r = if b[i] < min_mod { d } else { r };
            let r = if u32::from(maxv[i]) >= sat {
                InvalidReason::Saturated
            } else {
                r
            };
            (c, b[i] * scale, r)
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn spec(periods: Vec<f64>, unwrap: Unwrap) -> PhaseShiftSpec {
        PhaseShiftSpec::new(Axis::Column, ImageSize::new(1920, 1080), 4, periods, unwrap)
    }

    #[test]
    fn validation_names_the_field() {
        spec(vec![64.0, 58.0, 53.0], Unwrap::Heterodyne)
            .validate()
            .unwrap();
        spec(vec![1.0, 8.0, 64.0], Unwrap::Hierarchical)
            .validate()
            .unwrap();
        spec(vec![13.0, 16.0], Unwrap::NumberTheoretic)
            .validate()
            .unwrap();
        spec(vec![1.0], Unwrap::None).validate().unwrap();
        let e = spec(vec![64.0, 58.0, 50.0], Unwrap::Heterodyne)
            .validate()
            .unwrap_err();
        assert!(e.to_string().contains("periods"), "{e}");
        let e = spec(vec![12.0, 16.0], Unwrap::NumberTheoretic)
            .validate()
            .unwrap_err();
        assert!(e.to_string().contains("coprime"), "{e}");
        let e = spec(vec![8.0, 64.0], Unwrap::Hierarchical)
            .validate()
            .unwrap_err();
        assert!(e.to_string().contains("coarsest"), "{e}");
        let e = spec(vec![32.0], Unwrap::None).validate().unwrap_err();
        assert!(e.to_string().contains("unwrap"), "{e}");
        let e = spec(vec![1000.0], Unwrap::None).validate().unwrap_err();
        assert!(e.to_string().contains("periods[0]"), "{e}");
        let mut s = spec(vec![1.0], Unwrap::None);
        s.steps = 2;
        assert!(s.validate().unwrap_err().to_string().contains("steps"));
    }

    #[test]
    fn pattern_closed_form() {
        let s = spec(vec![64.0, 58.0, 53.0], Unwrap::Heterodyne);
        assert_eq!(s.frame_count(), 12);
        // Phase 0 at the origin: step 0 is at its maximum there.
        assert_abs_diff_eq!(s.pattern_value(0, -0.5).unwrap(), 1.0, epsilon = 1e-12);
        // Half a period further: minimum.
        assert_abs_diff_eq!(
            s.pattern_value(0, -0.5 + 15.0).unwrap(),
            0.0,
            epsilon = 1e-12
        );
        // Step 1 of 4 (delta = pi/2) at Phi = pi/2: cos(0) = 1.
        assert_abs_diff_eq!(
            s.pattern_value(1, -0.5 + 7.5).unwrap(),
            1.0,
            epsilon = 1e-12
        );
        // Frame 4 is step 0 of the second frequency (1920/58 px per period).
        let l2 = 1920.0 / 58.0;
        assert_abs_diff_eq!(s.pattern_value(4, -0.5 + l2).unwrap(), 1.0, epsilon = 1e-12);
        assert!(s.pattern_value(12, 0.0).is_none());
        // Gamma pre-compensation: value^(1/gamma).
        let g = PhaseShiftSpec {
            gamma: 2.0,
            ..s.clone()
        };
        let t = 3.3;
        assert_abs_diff_eq!(
            g.pattern_value(2, t).unwrap(),
            s.pattern_value(2, t).unwrap().sqrt(),
            epsilon = 1e-12
        );
    }

    #[test]
    fn wrapped_phase_of_exact_samples() {
        // Float samples quantised to u16 for every phase on a grid: error bound from
        // quantisation (0.5 / (N/2 * B) rad with B = 20000) plus atan2's 2e-6.
        for sign in [ShiftSign::Positive, ShiftSign::Negative] {
            let n = 5u32;
            let width = 64;
            let frames: Vec<Frame<u16>> = (0..n)
                .map(|k| {
                    let data = (0..width)
                        .map(|x| {
                            let phi = TAU * x as f64 / width as f64;
                            let d = sign.value() * TAU * f64::from(k) / f64::from(n);
                            (30000.0 + 20000.0 * (phi + 0.3 - d).cos()).round() as u16
                        })
                        .collect();
                    Frame::new(width, 1, data).unwrap()
                })
                .collect();
            let w = wrapped_phase(&frames, sign, 0.3).unwrap();
            for x in 0..width {
                let phi = TAU * x as f64 / width as f64;
                let d = (f64::from(w.phase[x]) - phi).rem_euclid(TAU);
                let d = d.min(TAU - d);
                assert!(d < 1e-4, "x {x}: {} vs {phi}", w.phase[x]);
                assert_abs_diff_eq!(w.modulation[x], 20000.0, epsilon = 2.0);
                assert_abs_diff_eq!(w.background[x], 30000.0, epsilon = 1.0);
            }
        }
    }
}
