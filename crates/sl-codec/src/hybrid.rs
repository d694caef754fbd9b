//! Hybrid code: phase shift gives the sub-pixel position inside a period, Gray code gives the
//! period index.
//!
//! The classic hybrid reads the period index `k` from a Gray code whose stripes are exactly one
//! period wide and computes `t = lambda (k + f)`; where the Gray edges and the phase wraps
//! (both at period boundaries) disagree by a pixel, `k` is off by one and a whole period is lost:
//! the well-known "period-jump" errors that are usually filtered afterwards. Here the Gray code
//! only has to locate the pixel to within half a period: the decoder takes the centre `x_c` of
//! the decoded stripe and picks the period index that puts the phase position nearest to it,
//!
//! ```text
//! k = round((x_c - origin) / lambda - f),    t = origin + lambda (k + f)
//! ```
//!
//! which is right whenever `|x_c - t| < lambda / 2`. With the *complementary* Gray code (the
//! default: one extra bit, so stripes are half a period wide and aligned with the periods)
//! the stripe centre is within `lambda / 4` of the truth, and within `lambda / 4` plus a hair
//! when a Gray edge is misread by one stripe, so period jumps are removed, not filtered.
//! SLMaster's shifted Gray code (period-wide stripes offset by half a period) is the same rule
//! with no margin left at the stripe edges; it decodes too, from its manifest.

use crate::bits::{Band, BitThresholds, GrayScratch, read_inverse_bits, read_threshold_bits};
use crate::correspondence::{AxisMap, InvalidReason};
use crate::fast_math;
use crate::frame::{check_block, dims};
use crate::gray::{GrayCodeSpec, GrayReference, stripe_positions};
use crate::kernel::{self, AxisRows, Kernel, fill_out};
use crate::pattern::{ceil_log2, positive, within};
use crate::phase_shift::{
    Fringe, MAX_STEPS, MIN_PERIOD_PIXELS, PhaseRow, StepTable, fused_pass, validate_steps,
};
use crate::{Axis, CodecError, DecodeConfig, Frame, ImageSize, Sample, ShiftSign};
use sl_image::ToneCurve;

/// Phase steps of the capture the toolkit recommends and scans with (`slscan patterns --codec
/// hybrid` and `slscan capture`/`scan` by default). 8 rather than 4: with
/// [`RECOMMENDED_PERIOD_PX`] fringes the rendered plane's flatness error falls from 0.0416 to
/// 0.0159 mm against 4 steps of 30 px (issue 15), phase noise falling as `1/sqrt(N)`, for 4
/// more frames per axis (`docs/codecs.md`, `docs/triangulation.md`).
pub const RECOMMENDED_PHASE_STEPS: u32 = 8;

/// Fringe period in projector pixels of the recommended capture: the finest period the
/// rendered projector blur still resolves with good modulation (phase noise in pixels scales
/// with the period), i.e. 128 periods across a 1920-px projector.
pub const RECOMMENDED_PERIOD_PX: f64 = 15.0;

/// Parameters of a hybrid block.
///
/// Frame order: the `steps` phase-shift frames first, then the Gray frames in the order of
/// [`GrayCodeSpec`].
#[derive(Clone, Debug, PartialEq)]
pub struct HybridSpec {
    /// Coded axis (the Gray part must code the same axis).
    pub axis: Axis,
    /// Projector pixels along the axis.
    pub extent: u32,
    /// Phase steps, `N >= 3`.
    pub steps: u32,
    /// Periods across the projector extent (non-integer allowed).
    pub periods: f64,
    /// Projector coordinate where the phase is 0 (default `-0.5`).
    pub origin: f64,
    /// Constant phase `psi` added to the pattern, radians.
    pub phase_offset: f64,
    /// Direction of the phase steps.
    pub shift_sign: ShiftSign,
    /// Projector gamma pre-compensated in the rendered fringes.
    pub gamma: f64,
    /// The projector's measured response pre-compensated in the rendered fringes (as
    /// [`crate::PhaseShiftSpec::precompensation`]; the Gray code's black and white need
    /// none). Default `None`.
    pub precompensation: Option<ToneCurve>,
    /// The Gray code that locates the period; its stripes must be at most one period wide.
    pub gray: GrayCodeSpec,
}

impl HybridSpec {
    /// The capture the toolkit recommends on `axis`: [`RECOMMENDED_PHASE_STEPS`] steps,
    /// fringes [`RECOMMENDED_PERIOD_PX`] projector pixels wide, complementary Gray code.
    pub fn recommended(axis: Axis, projector: ImageSize) -> Self {
        let extent = f64::from(axis.extent(projector));
        Self::complementary(
            axis,
            projector,
            RECOMMENDED_PHASE_STEPS,
            extent / RECOMMENDED_PERIOD_PX,
        )
    }

    /// Phase shift with `steps` steps and `periods` periods plus the complementary Gray code:
    /// stripes of half a period aligned with the periods (`ceil(log2(ceil(2 periods)))` bits),
    /// with inverse patterns.
    pub fn complementary(axis: Axis, projector: ImageSize, steps: u32, periods: f64) -> Self {
        let extent = axis.extent(projector);
        let lambda = f64::from(extent) / periods;
        let stripes = (2.0 * periods - 1e-9).ceil().max(1.0) as u64;
        let origin = -0.5;
        Self {
            axis,
            extent,
            steps,
            periods,
            origin,
            phase_offset: 0.0,
            shift_sign: ShiftSign::Positive,
            gamma: 1.0,
            precompensation: None,
            gray: GrayCodeSpec {
                axis,
                extent,
                bits: ceil_log2(stripes).max(1),
                reference: GrayReference::Inverse,
                binary: false,
                stripe_width: lambda / 2.0,
                origin,
            },
        }
    }

    /// Period width in projector pixels.
    pub fn period_pixels(&self) -> f64 {
        f64::from(self.extent) / self.periods
    }

    /// Number of frames: the phase steps plus the Gray frames.
    pub fn frame_count(&self) -> usize {
        self.steps as usize + self.gray.frame_count()
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming the bad field (Gray fields as `gray.bits` etc.).
    pub fn validate(&self) -> Result<(), CodecError> {
        validate_steps(self.steps)?;
        if self.extent == 0 {
            return Err(CodecError::parameter(
                "extent",
                "the projector must not be empty",
            ));
        }
        positive("periods", self.periods)?;
        if self.periods < 1.0 {
            return Err(CodecError::parameter(
                "periods",
                format!(
                    "{} periods across {} px: a hybrid code needs one period at least (its \
                     Gray code counts whole periods; a longer fringe is a phase-shift block's)",
                    self.periods, self.extent
                ),
            ));
        }
        let lambda = self.period_pixels();
        if lambda < MIN_PERIOD_PIXELS {
            return Err(CodecError::parameter(
                "periods",
                format!(
                    "{} periods across {} px is {lambda:.2} px per period, below {MIN_PERIOD_PIXELS}",
                    self.periods, self.extent
                ),
            ));
        }
        // As a phase-shift block's: beyond, the values only lose precision.
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
        self.gray.validate().map_err(|e| match e {
            CodecError::Parameter { name, message } => CodecError::Parameter {
                name: format!("gray.{name}"),
                message,
            },
            other => other,
        })?;
        if self.gray.axis != self.axis || self.gray.extent != self.extent {
            return Err(CodecError::parameter(
                "gray.axis",
                "the Gray code must code the block's axis and extent",
            ));
        }
        if self.gray.stripe_width > lambda * (1.0 + 1e-9) {
            return Err(CodecError::parameter(
                "gray.stripe_width",
                format!(
                    "{} px is wider than the period ({lambda} px): the period index would be ambiguous",
                    self.gray.stripe_width
                ),
            ));
        }
        if self.gray_wraps() {
            let m = self.wrap_periods();
            if (m - m.round()).abs() > 1e-6 || m < 1.0 {
                return Err(CodecError::parameter(
                    "gray",
                    format!(
                        "the Gray code wraps around inside the projector but its 2^bits stripes \
                         (bits {}, stripe_width {} px) span {m} periods, not a whole number",
                        self.gray.bits, self.gray.stripe_width
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Does the Gray stripe index wrap (modulo `2^bits`) inside the projector?
    fn gray_wraps(&self) -> bool {
        let g = &self.gray;
        // Stripes of the first and last projector pixel centres.
        let first = ((0.0 - g.origin) / g.stripe_width).floor();
        let last = ((f64::from(self.extent) - 1.0 - g.origin) / g.stripe_width).floor();
        first < 0.0 || last >= (1u64 << g.bits.min(63)) as f64
    }

    /// Periods spanned by the `2^bits` Gray stripes.
    fn wrap_periods(&self) -> f64 {
        (1u64 << self.gray.bits.min(63)) as f64 * self.gray.stripe_width / self.period_pixels()
    }

    fn fringe(&self) -> Fringe<'_> {
        Fringe {
            period: self.period_pixels(),
            origin: self.origin,
            phase_offset: self.phase_offset,
            sign: self.shift_sign.value(),
            steps: self.steps,
            gamma: self.gamma,
            precompensation: self.precompensation.as_ref(),
        }
    }

    /// This block with the projector's measured `response` pre-compensated in its fringes
    /// ([`Self::precompensation`]).
    #[must_use]
    pub fn precompensated(mut self, response: ToneCurve) -> Self {
        self.precompensation = Some(response);
        self
    }

    /// Intensity in `[0, 1]` of frame `frame` of the block at coordinate `t`, or `None` if
    /// `frame >= frame_count()`.
    pub fn pattern_value(&self, frame: usize, t: f64) -> Option<f64> {
        let n = self.steps as usize;
        if frame < n {
            Some(self.fringe().value(frame as u32, t))
        } else {
            self.gray.pattern_value(frame - n, t)
        }
    }
}

/// Decodes one hybrid block from in-memory frames (in the block's frame order).
///
/// # Errors
/// [`CodecError::FrameCount`], [`CodecError::FrameSize`], or [`CodecError::Parameter`] for a
/// bad spec or config.
pub fn decode_hybrid<T: Sample>(
    spec: &HybridSpec,
    frames: &[Frame<T>],
    config: &DecodeConfig,
) -> Result<AxisMap, CodecError> {
    let kernel = HybridKernel::new(spec, frames, config)?;
    let (w, h) = dims(frames);
    Ok(kernel::run_axis(
        Kernel::Hybrid(kernel),
        w,
        h,
        config.rows_per_task,
    ))
}

/// The per-block decoder.
pub(crate) struct HybridKernel<'a, T: Sample> {
    spec: HybridSpec,
    frames: &'a [Frame<T>],
    /// The same frames when `T = u8`, for the byte-wide Gray reader.
    frames8: Option<Vec<&'a Frame<u8>>>,
    width: usize,
    table: StepTable,
    th: BitThresholds,
    min_modulation: f32,
    quality_scale: f32,
    /// Period count of the Gray wrap, if the Gray code wraps inside the projector.
    wrap: Option<f32>,
}

/// Per-task scratch of [`HybridKernel`].
pub(crate) struct HybridScratch {
    acc: PhaseRow,
    frac: Vec<f32>,
    modulation: Vec<f32>,
    background: Vec<f32>,
    maxv: Vec<u16>,
    gray: GrayScratch,
}

impl HybridScratch {
    fn fit(&mut self, n: usize) {
        self.acc.fit(n);
        self.frac.resize(n, 0.0);
        self.modulation.resize(n, 0.0);
        self.background.resize(n, 0.0);
        self.maxv.resize(n, 0);
        self.gray.fit(n);
    }
}

impl<'a, T: Sample> HybridKernel<'a, T> {
    pub(crate) fn new(
        spec: &HybridSpec,
        frames: &'a [Frame<T>],
        config: &DecodeConfig,
    ) -> Result<Self, CodecError> {
        spec.validate()?;
        config.validate()?;
        check_block("hybrid", spec.axis, spec.frame_count(), frames)?;
        let scale = T::SCALE_FROM_8BIT;
        let frames8 = frames
            .iter()
            .map(|f| (f as &dyn std::any::Any).downcast_ref::<Frame<u8>>())
            .collect::<Option<Vec<_>>>();
        Ok(Self {
            spec: spec.clone(),
            frames,
            frames8,
            width: dims(frames).0,
            table: StepTable::for_block(
                spec.steps,
                spec.shift_sign,
                spec.phase_offset,
                (spec.gamma, spec.precompensation.as_ref()),
                config,
            )?,
            th: BitThresholds::new::<T>(config),
            min_modulation: config.min_modulation * scale,
            quality_scale: 1.0 / scale,
            wrap: spec
                .gray_wraps()
                .then(|| spec.wrap_periods().round() as f32),
        })
    }

    pub(crate) fn axis(&self) -> Axis {
        self.spec.axis
    }

    pub(crate) fn new_scratch(&self, len: usize) -> HybridScratch {
        HybridScratch {
            acc: PhaseRow::new(len),
            frac: vec![0.0; len],
            modulation: vec![0.0; len],
            background: vec![0.0; len],
            maxv: vec![0; len],
            gray: GrayScratch::new(len),
        }
    }

    #[inline(always)]
    pub(crate) fn decode_band(
        &self,
        y0: usize,
        rows: usize,
        out: &mut AxisRows<'_>,
        s: &mut HybridScratch,
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
        s.modulation.fill(f32::INFINITY);
        s.background.fill(f32::INFINITY);
        let mut rows: [&[T]; MAX_STEPS as usize] = [&[]; MAX_STEPS as usize];
        for (k, r) in rows.iter_mut().take(n).enumerate() {
            *r = band.of(self.frames.get(k));
        }
        // One frequency: the merged minimum is the modulation B itself, and the darkest level
        // A - B; turn the latter into the background A.
        fused_pass(
            rows.get(..n).unwrap_or(&[]),
            &self.table,
            &mut s.frac,
            &mut s.modulation,
            &mut s.background,
            &mut s.maxv,
            &mut s.acc,
        );
        self.table.correct(&mut s.frac);
        for (a, &b) in s.background.iter_mut().zip(&s.modulation) {
            *a += b;
        }
        let gray = &self.spec.gray;
        let bits = gray.bits as usize;
        let g = &mut s.gray;
        match gray.reference {
            GrayReference::Inverse => {
                // Direct and global light from the fringes (a high-frequency pattern):
                // A = (Ld + Lg) / 2 and B = Ld / 2.
                for (((ld, lg), &b), &a) in
                    g.ld.iter_mut()
                        .zip(g.lg.iter_mut())
                        .zip(&s.modulation)
                        .zip(&s.background)
                {
                    *ld = (2.0 * b).clamp(0.0, 65535.0) as u16;
                    *lg = (2.0 * (a - b)).clamp(0.0, 65535.0) as u16;
                }
                read_inverse_bits(
                    self.frames,
                    self.frames8.as_deref(),
                    n,
                    bits,
                    band,
                    self.th,
                    g,
                );
            }
            GrayReference::WhiteBlack => {
                let (white, black) = (band.of(self.frames.get(n)), band.of(self.frames.get(n + 1)));
                for ((t, wv), bv) in g.thr2.iter_mut().zip(white).zip(black) {
                    *t = u32::from(wv.to_u16()) + u32::from(bv.to_u16());
                }
                read_threshold_bits(self.frames, n + 2, bits, band, self.th.min_contrast, g);
            }
            GrayReference::PhaseMean => {
                for (t, a) in g.thr2.iter_mut().zip(&s.background) {
                    *t = (2.0 * a).round().clamp(0.0, u32::MAX as f32) as u32;
                }
                read_threshold_bits(self.frames, n, bits, band, self.th.min_contrast, g);
            }
        }
        stripe_positions(&g.code, &g.unread, gray.binary, &mut g.pos);
        let lambda = self.spec.period_pixels() as f32;
        let inv_lambda = 1.0 / lambda;
        let origin = self.spec.origin as f32;
        let (g_origin, g_stripe) = (gray.origin as f32, gray.stripe_width as f32);
        let (wrap, inv_wrap) = match self.wrap {
            Some(m) => (m, 1.0 / m),
            None => (0.0, 0.0),
        };
        let (lo, hi) = (-0.5_f32, self.spec.extent as f32 - 0.5);
        let (min_mod, sat, scale) = (self.min_modulation, self.th.saturation, self.quality_scale);
        let n = len;
        let (b, a, f, pos, maxv) = (
            &s.modulation[..n],
            &s.background[..n],
            &s.frac[..n],
            &g.pos[..n],
            &s.maxv[..n],
        );
        fill_out!(out.row(0, n), n, |i| {
            // Centre of the decoded stripe, then the period index that puts the phase position
            // nearest to it (modulo the Gray code's wrap, if it wraps inside the projector).
            let xc = g_origin + (pos[i] + 0.5) * g_stripe;
            let k = fast_math::round((xc - origin) * inv_lambda - f[i]);
            let k = k - wrap * fast_math::floor(k * inv_wrap);
            let c = origin + lambda * (k + f[i]);
            let r = if (c >= lo) & (c <= hi) {
                InvalidReason::Valid
            } else {
                InvalidReason::InconsistentCode
            };
            let r = if pos[i].is_nan() {
                InvalidReason::LowModulation
            } else {
                r
            };
            let dark = if a[i] - b[i] < min_mod {
                InvalidReason::Shadow
            } else {
                InvalidReason::LowModulation
            };
            let r = if b[i] < min_mod { dark } else { r };
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

    #[test]
    fn recommended_is_8_steps_of_15_px() {
        let h = HybridSpec::recommended(Axis::Column, ImageSize::new(1920, 1080));
        h.validate().unwrap();
        assert_eq!(h.steps, 8);
        assert_eq!(h.periods, 128.0);
        let r = HybridSpec::recommended(Axis::Row, ImageSize::new(1920, 1080));
        assert_eq!(r.periods, 72.0);
    }

    #[test]
    fn complementary_layout() {
        let h = HybridSpec::complementary(Axis::Column, ImageSize::new(1920, 1080), 4, 32.0);
        h.validate().unwrap();
        assert_eq!(h.gray.bits, 6);
        assert_eq!(h.gray.stripe_width, 30.0);
        assert_eq!(h.frame_count(), 4 + 12);
        assert!(!h.gray_wraps());
        // Non-integer periods: 20.5 periods -> 41 half-period stripes -> 6 bits.
        let h = HybridSpec::complementary(Axis::Row, ImageSize::new(800, 600), 3, 20.5);
        h.validate().unwrap();
        assert_eq!(h.gray.bits, 6);
    }

    #[test]
    fn stripes_wider_than_a_period_are_rejected() {
        let mut h = HybridSpec::complementary(Axis::Column, ImageSize::new(1920, 1080), 4, 32.0);
        h.gray.stripe_width = 61.0;
        let e = h.validate().unwrap_err();
        assert!(e.to_string().contains("gray.stripe_width"), "{e}");
        h.gray.stripe_width = 30.0;
        h.gray.bits = 0;
        let e = h.validate().unwrap_err();
        assert!(e.to_string().contains("gray.bits"), "{e}");
    }

    #[test]
    fn slmaster_shifted_code_wraps_by_whole_periods() {
        // SLMaster: 32 periods of 60 px, 5 Gray bits of 60-px stripes shifted by half a period.
        let mut h = HybridSpec::complementary(Axis::Column, ImageSize::new(1920, 1024), 4, 32.0);
        h.origin = 0.0;
        h.gray.bits = 5;
        h.gray.stripe_width = 60.0;
        h.gray.origin = -30.5;
        h.gray.reference = GrayReference::PhaseMean;
        h.validate().unwrap();
        assert!(h.gray_wraps());
        assert_eq!(h.wrap_periods(), 32.0);
        // The right-most 30 columns show stripe 32 = stripe 0 again.
        assert_eq!(h.gray.stripe_index(1890.0), 0);
        assert_eq!(h.gray.stripe_index(1889.0), 31);
        assert_eq!(h.gray.stripe_index(29.0), 0);
        assert_eq!(h.gray.stripe_index(30.0), 1);
    }
}
