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

use crate::correspondence::{AxisMap, InvalidReason};
use crate::fast_math;
use crate::gray::{
    BitThresholds, GrayCodeSpec, GrayReference, check_block, dims, read_bit_inverse,
    read_bit_threshold, resolve_stripe,
};
use crate::kernel::{self, AxisRows, Kernel};
use crate::pattern::{ceil_log2, finite, positive};
use crate::phase_shift::{Fringe, MIN_PERIOD_PIXELS, PhaseRow, StepTable, validate_steps};
use crate::{Axis, CodecError, DecodeConfig, Frame, ProjectorSize, Sample, ShiftSign};

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
    /// The Gray code that locates the period; its stripes must be at most one period wide.
    pub gray: GrayCodeSpec,
}

impl HybridSpec {
    /// Phase shift with `steps` steps and `periods` periods plus the complementary Gray code:
    /// stripes of half a period aligned with the periods (`ceil(log2(ceil(2 periods)))` bits),
    /// with inverse patterns.
    pub fn complementary(axis: Axis, projector: ProjectorSize, steps: u32, periods: f64) -> Self {
        let extent = projector.extent(axis);
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
        finite("origin", self.origin)?;
        finite("phase_offset", self.phase_offset)?;
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
                    "gray.bits",
                    format!(
                        "the Gray code wraps around inside the projector but 2^bits stripes span {m} periods, not a whole number"
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

    fn fringe(&self) -> Fringe {
        Fringe {
            period: self.period_pixels(),
            origin: self.origin,
            phase_offset: self.phase_offset,
            sign: self.shift_sign.value(),
            steps: self.steps,
            gamma: self.gamma,
        }
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
    ld: Vec<u16>,
    lg: Vec<u16>,
    thr2: Vec<u32>,
    code: Vec<u16>,
    unread: Vec<u16>,
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
        Ok(Self {
            spec: spec.clone(),
            frames,
            width: dims(frames).0,
            table: StepTable::new(spec.steps, spec.shift_sign.value(), spec.phase_offset),
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

    pub(crate) fn new_scratch(&self, width: usize) -> HybridScratch {
        HybridScratch {
            acc: PhaseRow::new(width),
            frac: vec![0.0; width],
            modulation: vec![0.0; width],
            background: vec![0.0; width],
            maxv: vec![0; width],
            ld: vec![0; width],
            lg: vec![0; width],
            thr2: vec![0; width],
            code: vec![0; width],
            unread: vec![0; width],
        }
    }

    fn row(&self, frame: usize, y: usize) -> &[T] {
        self.frames.get(frame).and_then(|f| f.row(y)).unwrap_or(&[])
    }

    pub(crate) fn decode_row(
        &self,
        y: usize,
        offset: usize,
        out: &mut AxisRows<'_>,
        s: &mut HybridScratch,
    ) {
        let w = self.width;
        let n = self.spec.steps as usize;
        s.maxv.fill(0);
        s.acc
            .accumulate(&self.table, &mut s.maxv, |k| self.row(k, y));
        s.acc.finish(
            &self.table,
            &mut s.frac,
            &mut s.modulation,
            &mut s.background,
        );
        s.code.fill(0);
        s.unread.fill(0);
        let gray = &self.spec.gray;
        let bits = gray.bits as usize;
        match gray.reference {
            GrayReference::Inverse => {
                // Direct and global light from the fringes (a high-frequency pattern):
                // A = (Ld + Lg) / 2 and B = Ld / 2.
                for i in 0..w.min(s.ld.len()).min(s.lg.len()) {
                    let (b, a) = (s.modulation[i], s.background[i]);
                    s.ld[i] = (2.0 * b).clamp(0.0, 65535.0) as u16;
                    s.lg[i] = (2.0 * (a - b)).clamp(0.0, 65535.0) as u16;
                }
                for b in 0..bits {
                    let (p, q) = (self.row(n + 2 * b, y), self.row(n + 2 * b + 1, y));
                    if p.len() < w || q.len() < w {
                        return;
                    }
                    read_bit_inverse(p, q, &s.ld, &s.lg, &mut s.code, &mut s.unread, self.th);
                }
            }
            GrayReference::WhiteBlack => {
                let (white, black) = (self.row(n, y), self.row(n + 1, y));
                for ((t, wv), bv) in s.thr2.iter_mut().zip(white).zip(black) {
                    *t = u32::from(wv.to_u16()) + u32::from(bv.to_u16());
                }
                for b in 0..bits {
                    let p = self.row(n + 2 + b, y);
                    if p.len() < w {
                        return;
                    }
                    read_bit_threshold(
                        p,
                        &s.thr2,
                        &mut s.code,
                        &mut s.unread,
                        self.th.min_contrast,
                    );
                }
            }
            GrayReference::PhaseMean => {
                for (t, a) in s.thr2.iter_mut().zip(&s.background) {
                    *t = (2.0 * a).round().clamp(0.0, u32::MAX as f32) as u32;
                }
                for b in 0..bits {
                    let p = self.row(n + b, y);
                    if p.len() < w {
                        return;
                    }
                    read_bit_threshold(
                        p,
                        &s.thr2,
                        &mut s.code,
                        &mut s.unread,
                        self.th.min_contrast,
                    );
                }
            }
        }
        let lambda = self.spec.period_pixels() as f32;
        let inv_lambda = 1.0 / lambda;
        let origin = self.spec.origin as f32;
        let (lo, hi) = (-0.5_f32, self.spec.extent as f32 - 0.5);
        for x in 0..w {
            let b = s.modulation[x];
            let quality = b * self.quality_scale;
            let mut coord = f32::NAN;
            let reason = if u32::from(s.maxv[x]) >= self.th.saturation {
                InvalidReason::Saturated
            } else if !(b >= self.min_modulation) {
                if s.background[x] - b < self.min_modulation {
                    InvalidReason::Shadow
                } else {
                    InvalidReason::LowModulation
                }
            } else {
                match resolve_stripe(s.code[x], s.unread[x], gray.binary) {
                    None => InvalidReason::LowModulation,
                    Some(pos) => {
                        let xc = gray.stripe_center(f64::from(pos)) as f32;
                        let f = s.frac[x];
                        let mut k = fast_math::round((xc - origin) * inv_lambda - f);
                        if let Some(m) = self.wrap {
                            k = k.rem_euclid(m);
                        }
                        let c = origin + lambda * (k + f);
                        if (lo..=hi).contains(&c) {
                            coord = c;
                            InvalidReason::Valid
                        } else {
                            InvalidReason::InconsistentCode
                        }
                    }
                }
            };
            out.put(offset + x, coord, quality, reason);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn complementary_layout() {
        let h = HybridSpec::complementary(Axis::Column, ProjectorSize::new(1920, 1080), 4, 32.0);
        h.validate().unwrap();
        assert_eq!(h.gray.bits, 6);
        assert_eq!(h.gray.stripe_width, 30.0);
        assert_eq!(h.frame_count(), 4 + 12);
        assert!(!h.gray_wraps());
        // Non-integer periods: 20.5 periods -> 41 half-period stripes -> 6 bits.
        let h = HybridSpec::complementary(Axis::Row, ProjectorSize::new(800, 600), 3, 20.5);
        h.validate().unwrap();
        assert_eq!(h.gray.bits, 6);
    }

    #[test]
    fn stripes_wider_than_a_period_are_rejected() {
        let mut h =
            HybridSpec::complementary(Axis::Column, ProjectorSize::new(1920, 1080), 4, 32.0);
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
        let mut h =
            HybridSpec::complementary(Axis::Column, ProjectorSize::new(1920, 1024), 4, 32.0);
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
