//! Gray code (and plain binary) stripe patterns and their robust decoder.
//!
//! Stripe `i` covers the projector coordinates `[origin + i * stripe_width,
//! origin + (i + 1) * stripe_width)` along the axis; it shows the code word `gray(i) = i ^ (i >> 1)`
//! (or `i` itself for plain binary), one bit per pattern, most significant bit first, bit value 1
//! shown white. Stripe indices wrap modulo `2^bits`.
//!
//! Decoding reads each bit by comparing the pattern with its inverse (or with the mid-level of a
//! white and a black frame, or with the fringe mean in a hybrid block). With inverses the bits are
//! classified with the direct/global split of Nayar et al. (2006) estimated from the finest bits,
//! and Xu & Aliaga's rules where global light is strong, as in Moreno & Taubin's scanner. A bit
//! whose contrast is below [`DecodeConfig::min_contrast`] is *unread*. A pixel with no unread bit
//! decodes to its stripe; a pixel with exactly one unread bit whose two candidate stripes are
//! neighbours lies on their common edge and decodes to it (a half-stripe position); any other
//! pixel is `LowModulation`.

use crate::bits::{
    Band, BitThresholds, GrayScratch, band, direct_global_row, read_inverse_bits,
    read_threshold_bits,
};
use crate::correspondence::{AxisMap, InvalidReason};
use crate::frame::{check_block, dims};
use crate::kernel::{self, AxisRows, Kernel, fill_out};
use crate::pattern::{ceil_log2, positive, within};
use crate::{Axis, CodecError, DecodeConfig, Frame, ImageSize, Sample};

/// Largest number of bits per Gray block: codes are accumulated in `u16` lanes, and 2^16 stripes
/// cover any projector made.
pub const MAX_GRAY_BITS: u32 = 16;

/// Xu & Aliaga's weak rules keep a margin of `Lg >> 3` (one eighth of the global light) on top
/// of `min_contrast`. `Lg = 2 Lmin` is estimated from the darkest of several noisy samples of
/// fine patterns, which biases it low by one to two noise sigmas (doubled), and real fine
/// patterns never split the scene's light exactly in half; without the margin a pixel whose
/// unlit sample gathers all the global light (a coarse stripe lighting the far wall of a
/// corner) reads as lit half of the time. An eighth covered the worst case of the tests
/// (global light 1.3x the direct light) with room to spare.
pub const WEAK_RULE_MARGIN_SHIFT: u32 = 3;

/// What a Gray bit is compared with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum GrayReference {
    /// Each pattern is followed by its inverse (the default, and the only mode with the robust
    /// direct/global classification).
    #[default]
    Inverse,
    /// One all-white and one all-black frame come first; each bit is compared with their mean.
    WhiteBlack,
    /// Hybrid blocks only: each bit is compared with the mean of the block's phase-shift frames
    /// (SLMaster's convention; no extra frame at all).
    PhaseMean,
}

impl GrayReference {
    /// `"inverse"`, `"white_black"` or `"phase_mean"`, as written in manifests.
    pub fn name(self) -> &'static str {
        match self {
            Self::Inverse => "inverse",
            Self::WhiteBlack => "white_black",
            Self::PhaseMean => "phase_mean",
        }
    }

    /// Parses a manifest name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "inverse" => Some(Self::Inverse),
            "white_black" => Some(Self::WhiteBlack),
            "phase_mean" => Some(Self::PhaseMean),
            _ => None,
        }
    }
}

/// Parameters of a Gray-code block.
///
/// Frame order: with [`GrayReference::Inverse`] `[bit 0, inverse 0, bit 1, inverse 1, ...]`;
/// with `WhiteBlack` `[white, black, bit 0, bit 1, ...]`; with `PhaseMean` `[bit 0, bit 1, ...]`;
/// bit 0 is the most significant.
#[derive(Clone, Debug, PartialEq)]
pub struct GrayCodeSpec {
    /// Coded axis.
    pub axis: Axis,
    /// Projector pixels along the axis; decoded coordinates outside `[-0.5, extent - 0.5]` are
    /// `InconsistentCode`.
    pub extent: u32,
    /// Number of bit planes, 1 to [`MAX_GRAY_BITS`].
    pub bits: u32,
    /// What each bit is compared with.
    pub reference: GrayReference,
    /// Plain binary code instead of the reflected Gray code.
    pub binary: bool,
    /// Width of one stripe in projector pixels (1 for a per-pixel code).
    pub stripe_width: f64,
    /// Projector coordinate of the leading edge of stripe 0 (`-0.5` for a per-pixel code that
    /// starts at the projector's edge).
    pub origin: f64,
}

impl GrayCodeSpec {
    /// A per-pixel code of the projector's `axis`: `ceil(log2(extent))` bits with inverses,
    /// reflected Gray code, optionally centred.
    ///
    /// Centring shifts the code by `(2^bits - extent) / 2` (rounded down) stripes so that the
    /// projector shows the symmetric middle of the code, as SLStudio and Moreno & Taubin do.
    pub fn per_pixel(axis: Axis, projector: ImageSize, centered: bool) -> Self {
        let extent = axis.extent(projector);
        let bits = ceil_log2(u64::from(extent)).max(1);
        Self {
            axis,
            extent,
            bits,
            reference: GrayReference::Inverse,
            binary: false,
            stripe_width: 1.0,
            origin: Self::per_pixel_origin(extent, bits, centered),
        }
    }

    /// A code of stripes `stripe_width` projector pixels wide along `axis` (1: per pixel, as
    /// [`GrayCodeSpec::per_pixel`]): `ceil(log2(stripes))` bits (at least one), centred like
    /// the per-pixel code when `centered`.
    ///
    /// ```
    /// use sl_codec::{Axis, GrayCodeSpec, ImageSize};
    /// let p = ImageSize::new(1280, 800);
    /// let s = GrayCodeSpec::striped(Axis::Column, p, 4, true)?;
    /// assert_eq!((s.bits, s.stripe_width), (9, 4.0)); // 320 stripes in 512 codes
    /// assert_eq!(GrayCodeSpec::striped(Axis::Column, p, 1, true)?, GrayCodeSpec::per_pixel(Axis::Column, p, true));
    /// assert!(GrayCodeSpec::striped(Axis::Column, p, 0, true).is_err());
    /// # Ok::<(), sl_codec::CodecError>(())
    /// ```
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming `stripe_width` when it is 0.
    pub fn striped(
        axis: Axis,
        projector: ImageSize,
        stripe_width: u32,
        centered: bool,
    ) -> Result<Self, CodecError> {
        if stripe_width == 0 {
            return Err(CodecError::parameter(
                "stripe_width",
                "must be at least 1 projector pixel",
            ));
        }
        let mut s = Self::per_pixel(axis, projector, centered);
        if stripe_width > 1 {
            let stripes = u64::from(axis.extent(projector).div_ceil(stripe_width));
            s.bits = 64 - (stripes.max(2) - 1).leading_zeros();
            s.stripe_width = f64::from(stripe_width);
            let offset = if centered {
                ((1u64 << s.bits).saturating_sub(stripes) / 2) as f64
            } else {
                0.0
            };
            s.origin = -0.5 - offset * f64::from(stripe_width);
        }
        Ok(s)
    }

    /// The `origin` of a per-pixel code: `-0.5`, minus the centring offset if `centered`.
    pub fn per_pixel_origin(extent: u32, bits: u32, centered: bool) -> f64 {
        let offset = if centered && bits < 64 {
            ((1u64 << bits).saturating_sub(u64::from(extent)) / 2) as f64
        } else {
            0.0
        };
        -0.5 - offset
    }

    /// Number of frames of the block.
    pub fn frame_count(&self) -> usize {
        let b = self.bits as usize;
        match self.reference {
            GrayReference::Inverse => 2 * b,
            GrayReference::WhiteBlack => b + 2,
            GrayReference::PhaseMean => b,
        }
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming the bad field.
    pub fn validate(&self) -> Result<(), CodecError> {
        if self.bits == 0 || self.bits > MAX_GRAY_BITS {
            return Err(CodecError::parameter(
                "bits",
                format!("must be in 1..={MAX_GRAY_BITS}, got {}", self.bits),
            ));
        }
        if self.extent == 0 {
            return Err(CodecError::parameter(
                "extent",
                "the projector must not be empty",
            ));
        }
        positive("stripe_width", self.stripe_width)?;
        // The code's stripes start at most one code length before the first pixel and after
        // the last: further, the origin only loses precision (a hybrid code may wrap, by
        // whole periods, so the origin is not held to the projector itself).
        let code_px = (1u64 << self.bits.min(MAX_GRAY_BITS)) as f64 * self.stripe_width;
        within(
            "origin",
            self.origin,
            f64::from(self.extent) + code_px,
            "projector px",
        )?;
        Ok(())
    }

    /// Checks that the `2^bits` stripes cover every pixel centre of the projector once (a
    /// plain Gray block cannot tell a stripe from its repeat: a code that wraps decodes to
    /// the wrong stripe, or to nothing).
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming `origin`, `stripe_width` and `bits`.
    pub fn check_covers(&self) -> Result<(), CodecError> {
        let n = (1u64 << self.bits.min(MAX_GRAY_BITS)) as f64;
        let first = ((0.0 - self.origin) / self.stripe_width).floor();
        let last = ((f64::from(self.extent) - 1.0 - self.origin) / self.stripe_width).floor();
        if first >= 0.0 && last < n {
            return Ok(());
        }
        Err(CodecError::parameter(
            "origin",
            format!(
                "with stripe_width {} px and bits {} the code's stripes run from {} to {} px, \
                 which does not cover the projector's pixel centres 0 to {} once",
                self.stripe_width,
                self.bits,
                self.origin,
                self.origin + n * self.stripe_width,
                self.extent.saturating_sub(1)
            ),
        ))
    }

    /// Index of the stripe (modulo `2^bits`) that contains projector coordinate `t`.
    pub fn stripe_index(&self, t: f64) -> u32 {
        let i = ((t - self.origin) / self.stripe_width).floor();
        let n = 1i64 << self.bits.min(MAX_GRAY_BITS);
        // Saturating float->int cast, then wrap into [0, 2^bits).
        (i as i64).rem_euclid(n) as u32
    }

    /// The code word shown on stripe `index`.
    pub fn code_word(&self, index: u32) -> u32 {
        if self.binary {
            index
        } else {
            index ^ (index >> 1)
        }
    }

    /// Centre of stripe `index` (fractional indices allowed: `i + 0.5` is the edge between
    /// stripes `i` and `i + 1`).
    pub fn stripe_center(&self, index: f64) -> f64 {
        self.origin + (index + 0.5) * self.stripe_width
    }

    /// Intensity (0 or 1) of frame `frame` of the block at projector coordinate `t` along the
    /// axis, or `None` if `frame >= frame_count()`.
    pub fn pattern_value(&self, frame: usize, t: f64) -> Option<f64> {
        if frame >= self.frame_count() {
            return None;
        }
        let (bit, inverted) = match self.reference {
            GrayReference::Inverse => (frame / 2, frame % 2 == 1),
            GrayReference::WhiteBlack => match frame {
                0 => return Some(1.0),
                1 => return Some(0.0),
                f => (f - 2, false),
            },
            GrayReference::PhaseMean => (frame, false),
        };
        let code = self.code_word(self.stripe_index(t));
        let shift = self.bits - 1 - bit as u32;
        let on = ((code >> shift) & 1 == 1) != inverted;
        Some(if on { 1.0 } else { 0.0 })
    }
}

/// Decodes one Gray-code block from in-memory frames (in the block's frame order).
///
/// # Errors
/// [`CodecError::FrameCount`] if `frames.len() != spec.frame_count()`, [`CodecError::FrameSize`]
/// if the frames differ in size, [`CodecError::Parameter`] for a bad spec or config (including
/// [`GrayReference::PhaseMean`], which needs a hybrid block).
///
/// # Example
/// ```
/// use sl_codec::{decode_gray, render_pattern, Axis, DecodeConfig, Frame, GrayCodeSpec, Pattern, ImageSize};
///
/// // A 100-column projector seen by a camera of the same size, pixel for pixel.
/// let projector = ImageSize::new(100, 4);
/// let spec = GrayCodeSpec::per_pixel(Axis::Column, projector, true);
/// let pattern = Pattern::Gray(spec.clone());
/// let frames = (0..pattern.frame_count())
///     .map(|i| render_pattern::<u8>(&pattern, i, projector))
///     .collect::<Result<Vec<Frame<u8>>, _>>()?;
/// let map = decode_gray(&spec, &frames, &DecodeConfig::default())?;
/// assert_eq!(map.coord[37], 37.0);
/// # Ok::<(), sl_codec::CodecError>(())
/// ```
pub fn decode_gray<T: Sample>(
    spec: &GrayCodeSpec,
    frames: &[Frame<T>],
    config: &DecodeConfig,
) -> Result<AxisMap, CodecError> {
    let kernel = GrayKernel::new(spec, frames, config)?;
    let (w, h) = dims(frames);
    Ok(kernel::run_axis(
        Kernel::Gray(kernel),
        w,
        h,
        config.rows_per_task,
    ))
}

/// Turns an accumulated code word into a stripe position: the stripe index, or the half-integer
/// edge between two neighbouring stripes when exactly one bit is unread and its two readings
/// are neighbours. `None` if the pixel cannot be decoded. (Scalar form of
/// [`stripe_positions`], which the decoders use.)
#[cfg(test)]
pub(crate) fn resolve_stripe(code: u16, unread: u16, binary: bool) -> Option<f32> {
    let mut p = [0.0_f32];
    stripe_positions(&[code], &[unread], binary, &mut p);
    (!p[0].is_nan()).then_some(p[0])
}

/// The per-block decoder.
pub(crate) struct GrayKernel<'a, T: Sample> {
    spec: GrayCodeSpec,
    frames: &'a [Frame<T>],
    /// The same frames when `T = u8`, for the byte-wide fast path.
    frames8: Option<Vec<&'a Frame<u8>>>,
    width: usize,
    th: BitThresholds,
    /// First bit (MSB = 0) used for the direct/global estimate.
    dg_first_bit: usize,
    black: f32,
    quality_scale: f32,
}

impl<'a, T: Sample> GrayKernel<'a, T> {
    pub(crate) fn new(
        spec: &GrayCodeSpec,
        frames: &'a [Frame<T>],
        config: &DecodeConfig,
    ) -> Result<Self, CodecError> {
        spec.validate()?;
        config.validate()?;
        if spec.reference == GrayReference::PhaseMean {
            return Err(CodecError::parameter(
                "reference",
                "'phase_mean' needs phase-shift frames: use it in a hybrid block",
            ));
        }
        check_block("gray", spec.axis, spec.frame_count(), frames)?;
        let bits = spec.bits as usize;
        let dg = (config.direct_global_bits as usize).clamp(1, bits);
        let frames8 = frames
            .iter()
            .map(|f| (f as &dyn std::any::Any).downcast_ref::<Frame<u8>>())
            .collect::<Option<Vec<_>>>();
        Ok(Self {
            spec: spec.clone(),
            frames,
            frames8,
            width: dims(frames).0,
            th: BitThresholds::new::<T>(config),
            dg_first_bit: bits - dg,
            black: config.black_level,
            quality_scale: 1.0 / T::SCALE_FROM_8BIT,
        })
    }

    pub(crate) fn axis(&self) -> Axis {
        self.spec.axis
    }

    pub(crate) fn new_scratch(&self, len: usize) -> GrayScratch {
        GrayScratch::new(len)
    }

    /// Rows `y0 .. y0 + rows` of frame `frame` as one slice (empty if out of range).
    fn band(&self, frame: usize, y0: usize, rows: usize) -> &[T] {
        band(self.frames.get(frame), self.width, y0, rows)
    }

    #[inline(always)]
    pub(crate) fn decode_band(
        &self,
        y0: usize,
        rows: usize,
        out: &mut AxisRows<'_>,
        s: &mut GrayScratch,
    ) {
        let bits = self.spec.bits as usize;
        s.fit(self.width * rows);
        match self.spec.reference {
            GrayReference::Inverse => {
                if let Some(f8) = &self.frames8 {
                    // Byte-wide brightest/darkest values, widened once.
                    let ([hi8, lo8], _) = (&mut s.code8, ());
                    hi8.fill(0);
                    lo8.fill(u8::MAX);
                    for f in 2 * self.dg_first_bit..2 * bits {
                        let r = band(f8.get(f).copied(), self.width, y0, rows);
                        for ((hi, lo), &v) in hi8.iter_mut().zip(lo8.iter_mut()).zip(r) {
                            *hi = (*hi).max(v);
                            *lo = (*lo).min(v);
                        }
                    }
                    for (((h, l), &h8), &l8) in s
                        .lmax
                        .iter_mut()
                        .zip(s.lmin.iter_mut())
                        .zip(hi8.iter())
                        .zip(lo8.iter())
                    {
                        *h = u16::from(h8);
                        *l = u16::from(l8);
                    }
                } else {
                    s.lmax.fill(0);
                    s.lmin.fill(u16::MAX);
                    for f in 2 * self.dg_first_bit..2 * bits {
                        let r = self.band(f, y0, rows);
                        for ((hi, lo), v) in s.lmax.iter_mut().zip(s.lmin.iter_mut()).zip(r) {
                            let v = v.to_u16();
                            *hi = (*hi).max(v);
                            *lo = (*lo).min(v);
                        }
                    }
                }
                direct_global_row(&s.lmax, &s.lmin, &mut s.ld, &mut s.lg, self.black);
                let band = Band {
                    width: self.width,
                    y0,
                    rows,
                };
                read_inverse_bits(
                    self.frames,
                    self.frames8.as_deref(),
                    0,
                    bits,
                    band,
                    self.th,
                    s,
                );
            }
            GrayReference::WhiteBlack | GrayReference::PhaseMean => {
                let (white, black) = (self.band(0, y0, rows), self.band(1, y0, rows));
                for ((((t, d), lo), wv), bv) in s
                    .thr2
                    .iter_mut()
                    .zip(s.ld.iter_mut())
                    .zip(s.lmin.iter_mut())
                    .zip(white)
                    .zip(black)
                {
                    let (wv, bv) = (wv.to_u16(), bv.to_u16());
                    *t = u32::from(wv) + u32::from(bv);
                    *d = wv.saturating_sub(bv);
                    *lo = bv;
                }
                let band = Band {
                    width: self.width,
                    y0,
                    rows,
                };
                read_threshold_bits(self.frames, 2, bits, band, self.th.min_contrast, s);
            }
        }
        self.finish(out, s);
    }

    /// Final pass of a band: stripe positions, coordinates, reasons, outputs.
    #[inline(always)]
    fn finish(&self, out: &mut AxisRows<'_>, s: &mut GrayScratch) {
        let p = PixelRule {
            origin: self.spec.origin as f32,
            stripe: self.spec.stripe_width as f32,
            lo: -0.5,
            hi: self.spec.extent as f32 - 0.5,
            min_direct: self.th.min_direct,
            saturation: self.th.saturation,
            scale: self.quality_scale,
            binary: self.spec.binary,
        };
        let n = s.code.len();
        let (ld, lmin, code, unread) = (&s.ld[..n], &s.lmin[..n], &s.code[..n], &s.unread[..n]);
        fill_out!(out.row(0, n), n, |i| p
            .pixel(code[i], unread[i], ld[i], lmin[i]));
    }
}

/// The per-pixel decision of a Gray block, after the bits are read.
#[derive(Clone, Copy)]
struct PixelRule {
    origin: f32,
    stripe: f32,
    lo: f32,
    hi: f32,
    min_direct: u16,
    saturation: u32,
    scale: f32,
    binary: bool,
}

impl PixelRule {
    /// `(coordinate, quality, reason)` of one pixel; branch-free.
    #[inline(always)]
    fn pixel(&self, code: u16, unread: u16, ld: u16, lmin: u16) -> (f32, f32, InvalidReason) {
        let pos = stripe_position(code, unread, self.binary);
        let c = self.origin + (pos + 0.5) * self.stripe;
        let r = if (c >= self.lo) & (c <= self.hi) {
            InvalidReason::Valid
        } else {
            InvalidReason::InconsistentCode
        };
        let r = if pos.is_nan() {
            InvalidReason::LowModulation
        } else {
            r
        };
        let dark = if lmin < self.min_direct {
            InvalidReason::Shadow
        } else {
            InvalidReason::LowModulation
        };
        let r = if ld < self.min_direct { dark } else { r };
        let r = if u32::from(lmin) >= self.saturation {
            InvalidReason::Saturated
        } else {
            r
        };
        (c, f32::from(ld) * self.scale, r)
    }
}

/// Stripe positions of a row of code words (see [`stripe_position`]).
#[inline(always)]
pub(crate) fn stripe_positions(code: &[u16], unread: &[u16], binary: bool, pos: &mut [f32]) {
    let n = pos.len();
    let (code, unread) = (&code[..n], &unread[..n]);
    for i in 0..n {
        pos[i] = stripe_position(code[i], unread[i], binary);
    }
}

/// The stripe position of a code word: the stripe index, or the half-integer edge between two
/// neighbouring stripes when exactly one bit is unread and its two readings are neighbours;
/// NaN if the pixel cannot be decoded. Branch-free so that the loops calling it vectorise.
#[inline(always)]
pub(crate) fn stripe_position(c: u16, u: u16, binary: bool) -> f32 {
    let decode = |c: u16| -> u16 {
        let mut b = c;
        b ^= b >> 1;
        b ^= b >> 2;
        b ^= b >> 4;
        b ^= b >> 8;
        b
    };
    let (idx, alt) = if binary {
        (c, c ^ u)
    } else {
        (decode(c), decode(c ^ u))
    };
    let single = u & u.wrapping_sub(1) == 0;
    let (lo, hi) = (idx.min(alt), idx.max(alt));
    let ok = single & (hi - lo <= 1);
    let half = if u != 0 { 0.5 } else { 0.0 };
    if ok { f32::from(lo) + half } else { f32::NAN }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_pixel_spec_for_1920() {
        let s = GrayCodeSpec::per_pixel(Axis::Column, ImageSize::new(1920, 1080), true);
        assert_eq!(s.bits, 11);
        assert_eq!(s.origin, -0.5 - 64.0);
        assert_eq!(s.frame_count(), 22);
        // Column x sits on stripe x + 64: the centred offset (2048 - 1920) / 2.
        assert_eq!(s.stripe_index(0.0), 64);
        assert_eq!(s.stripe_index(1919.0), 1983);
        assert_eq!(s.stripe_center(64.0), 0.0);
        let r = GrayCodeSpec::per_pixel(Axis::Row, ImageSize::new(1920, 1080), false);
        assert_eq!(r.bits, 11);
        assert_eq!(r.origin, -0.5);
    }

    #[test]
    fn gray_code_changes_one_bit_between_neighbours() {
        let s = GrayCodeSpec::per_pixel(Axis::Column, ImageSize::new(800, 600), true);
        for i in 0..(1u32 << s.bits) - 1 {
            assert_eq!((s.code_word(i) ^ s.code_word(i + 1)).count_ones(), 1);
        }
    }

    #[test]
    fn pattern_values_follow_the_code_msb_first() {
        // 8 stripes, 3 bits: stripe 5 = gray 0b111.
        let s = GrayCodeSpec {
            axis: Axis::Column,
            extent: 8,
            bits: 3,
            reference: GrayReference::Inverse,
            binary: false,
            stripe_width: 1.0,
            origin: -0.5,
        };
        let bits: Vec<f64> = (0..6).map(|f| s.pattern_value(f, 5.0).unwrap()).collect();
        assert_eq!(bits, vec![1.0, 0.0, 1.0, 0.0, 1.0, 0.0]);
        // stripe 2 = gray 0b011
        let bits: Vec<f64> = (0..6).map(|f| s.pattern_value(f, 2.2).unwrap()).collect();
        assert_eq!(bits, vec![0.0, 1.0, 1.0, 0.0, 1.0, 0.0]);
        assert_eq!(s.pattern_value(6, 0.0), None);
        let wb = GrayCodeSpec {
            reference: GrayReference::WhiteBlack,
            ..s.clone()
        };
        assert_eq!(wb.pattern_value(0, 3.0), Some(1.0));
        assert_eq!(wb.pattern_value(1, 3.0), Some(0.0));
        assert_eq!(wb.pattern_value(2, 5.0), Some(1.0));
        assert_eq!(wb.frame_count(), 5);
    }

    #[test]
    fn resolve_stripe_rules() {
        // gray(5) = 7, gray(6) = 5: they differ in bit 1.
        assert_eq!(resolve_stripe(7, 0, false), Some(5.0));
        assert_eq!(resolve_stripe(7, 0b010, false), Some(5.5));
        // gray(5)=0b111 with the MSB unread: the other reading is gray^-1(0b011) = 2, not a
        // neighbour of 5.
        assert_eq!(resolve_stripe(7, 0b100, false), None);
        assert_eq!(resolve_stripe(7, 0b110, false), None);
        // Binary: 5 = 0b101 with the LSB unread -> 4 or 5 -> edge 4.5.
        assert_eq!(resolve_stripe(5, 0b001, true), Some(4.5));
    }

    #[test]
    fn frame_count_is_checked() {
        let spec = GrayCodeSpec::per_pixel(Axis::Column, ImageSize::new(16, 4), false);
        let frames = vec![Frame::filled(4, 4, 0u8).unwrap(); 7];
        let err = decode_gray(&spec, &frames, &DecodeConfig::default()).unwrap_err();
        assert!(
            matches!(
                err,
                CodecError::FrameCount {
                    expected: 8,
                    found: 7,
                    ..
                }
            ),
            "{err}"
        );
        let pm = GrayCodeSpec {
            reference: GrayReference::PhaseMean,
            ..spec
        };
        let frames = vec![Frame::filled(4, 4, 0u8).unwrap(); 4];
        assert!(decode_gray(&pm, &frames, &DecodeConfig::default()).is_err());
    }
}
