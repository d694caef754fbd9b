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

use crate::config::level_u16;
use crate::correspondence::{AxisMap, InvalidReason};
use crate::frame::check_sizes;
use crate::kernel::{self, AxisRows, Kernel, fill_out};
use crate::pattern::{ceil_log2, finite, positive};
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
        finite("origin", self.origin)?;
        Ok(())
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

/// Width and height of the first frame (0 x 0 if none).
pub(crate) fn dims<T: Sample>(frames: &[Frame<T>]) -> (usize, usize) {
    frames.first().map_or((0, 0), |f| (f.width(), f.height()))
}

/// Checks the frame count and sizes of a block.
pub(crate) fn check_block<T: Sample>(
    codec: &'static str,
    axis: Axis,
    expected: usize,
    frames: &[Frame<T>],
) -> Result<(), CodecError> {
    if frames.len() != expected {
        return Err(CodecError::FrameCount {
            codec,
            axis: axis.name(),
            expected,
            found: frames.len(),
        });
    }
    check_sizes(frames, None)
}

/// Thresholds of the bit classifier, in the frames' grey levels.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BitThresholds {
    pub(crate) min_contrast: u16,
    pub(crate) min_direct: u16,
    pub(crate) saturation: u32,
    pub(crate) robust: bool,
}

impl BitThresholds {
    pub(crate) fn new<T: Sample>(config: &DecodeConfig) -> Self {
        let s = T::SCALE_FROM_8BIT;
        Self {
            min_contrast: level_u16(config.min_contrast, s),
            min_direct: level_u16(config.min_direct, s),
            saturation: (config.saturation_level * s)
                .round()
                .clamp(0.0, u32::MAX as f32) as u32,
            robust: config.robust,
        }
    }
}

/// Reads one bit plane against its inverse into `code`/`unread` (shifted left by one).
///
/// `ld`/`lg` are the direct and global light of each pixel. With `robust`, Xu & Aliaga's rules:
/// where `Ld > Lg` the comparison decides; elsewhere the bit is 1 only if `p >= Lg && q <= Ld`,
/// 0 only if `q >= Lg && p <= Ld`, unread otherwise. Both tests keep a margin of
/// `min_contrast + Lg / 8` (see [`WEAK_RULE_MARGIN_SHIFT`]): an unlit sample *equals* `Lg` when
/// all of the global light comes from the lit part of a coarse pattern, and `Lg` is only an
/// estimate. A contrast `|p - q|` below `min_contrast` is always unread.
#[inline(always)]
pub(crate) fn read_bit_inverse<T: Sample>(
    p: &[T],
    q: &[T],
    ld: &[u16],
    lg: &[u16],
    code: &mut [u16],
    unread: &mut [u16],
    th: BitThresholds,
) {
    let n = code.len();
    let (p, q, ld, lg, unread) = (&p[..n], &q[..n], &ld[..n], &lg[..n], &mut unread[..n]);
    let mc = th.min_contrast;
    if th.robust {
        for i in 0..n {
            let (pv, qv) = (p[i].to_u16(), q[i].to_u16());
            let (d, g) = (ld[i], lg[i]);
            let strong = d > g;
            let m = mc.saturating_add(g >> WEAK_RULE_MARGIN_SHIFT);
            let w1 = (pv >= g.saturating_add(m)) & (qv.saturating_add(m) <= d);
            let w0 = (qv >= g.saturating_add(m)) & (pv.saturating_add(m) <= d);
            let bit = (strong & (pv > qv)) | (!strong & w1);
            let read = (pv.abs_diff(qv) >= mc) & (strong | w0 | w1);
            code[i] = (code[i] << 1) | u16::from(bit);
            unread[i] = (unread[i] << 1) | u16::from(!read);
        }
    } else {
        for i in 0..n {
            let (pv, qv) = (p[i].to_u16(), q[i].to_u16());
            code[i] = (code[i] << 1) | u16::from(pv > qv);
            unread[i] = (unread[i] << 1) | u16::from(pv.abs_diff(qv) < mc);
        }
    }
}

/// Reads one bit plane against a per-pixel threshold given as twice its value (`thr2`).
#[inline(always)]
pub(crate) fn read_bit_threshold<T: Sample>(
    p: &[T],
    thr2: &[u32],
    code: &mut [u16],
    unread: &mut [u16],
    min_contrast: u16,
) {
    let n = code.len();
    let (p, thr2, unread) = (&p[..n], &thr2[..n], &mut unread[..n]);
    let mc = u32::from(min_contrast);
    for i in 0..n {
        let p2 = 2 * u32::from(p[i].to_u16());
        let t = thr2[i];
        code[i] = (code[i] << 1) | u16::from(p2 > t);
        unread[i] = (unread[i] << 1) | u16::from(p2.abs_diff(t) < mc);
    }
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

/// Direct and global light from the brightest and darkest value a pixel takes under
/// high-frequency patterns (Nayar et al. 2006): `Ld = (Lmax - Lmin) / (1 - b)`,
/// `Lg = 2 (Lmin - b Lmax) / (1 - b^2)`; exact integers for `b = 0`.
#[inline(always)]
pub(crate) fn direct_global_row(
    lmax: &[u16],
    lmin: &[u16],
    ld: &mut [u16],
    lg: &mut [u16],
    black: f32,
) {
    let n = ld.len();
    let (lmax, lmin, lg) = (&lmax[..n], &lmin[..n], &mut lg[..n]);
    if black == 0.0 {
        for i in 0..n {
            ld[i] = lmax[i].saturating_sub(lmin[i]);
            lg[i] = lmin[i].saturating_mul(2);
        }
    } else {
        let k1 = 1.0 / (1.0 - black);
        let k2 = 2.0 / (1.0 - black * black);
        for i in 0..n {
            let (hi, lo) = (f32::from(lmax[i]), f32::from(lmin[i]));
            ld[i] = ((hi - lo) * k1).clamp(0.0, 65535.0) as u16;
            lg[i] = ((lo - black * hi) * k2).clamp(0.0, 65535.0) as u16;
        }
    }
}

/// Reads one bit plane of 8-bit frames against its inverse into byte-wide code and unread
/// accumulators: the same rules as [`read_bit_inverse`], with the per-pixel thresholds
/// precomputed (`strong = Ld > Lg`, `a = Lg + margin`, `d = Ld - margin`) so that all the work
/// is done in 16-byte-wide vector lanes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn read_bit_inverse_u8(
    p: &[u8],
    q: &[u8],
    strong: &[bool],
    a: &[u8],
    d: &[u8],
    code: &mut [u8],
    unread: &mut [u8],
    min_contrast: u8,
    robust: bool,
) {
    let n = code.len();
    let (p, q, strong, a, d, unread) = (
        &p[..n],
        &q[..n],
        &strong[..n],
        &a[..n],
        &d[..n],
        &mut unread[..n],
    );
    if robust {
        // Non-short-circuit `&` / `|` keep the loop branch-free, so it vectorises.
        for i in 0..n {
            let (pv, qv, s) = (p[i], q[i], strong[i]);
            let w1 = (pv >= a[i]) & (qv <= d[i]);
            let w0 = (qv >= a[i]) & (pv <= d[i]);
            let bit = (s & (pv > qv)) | (!s & w1);
            let read = (pv.abs_diff(qv) >= min_contrast) & (s | w0 | w1);
            code[i] = code[i].wrapping_add(code[i]) | u8::from(bit);
            unread[i] = unread[i].wrapping_add(unread[i]) | u8::from(!read);
        }
    } else {
        for i in 0..n {
            let (pv, qv) = (p[i], q[i]);
            code[i] = code[i].wrapping_add(code[i]) | u8::from(pv > qv);
            unread[i] =
                unread[i].wrapping_add(unread[i]) | u8::from(pv.abs_diff(qv) < min_contrast);
        }
    }
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

/// Per-task scratch of [`GrayKernel`].
pub(crate) struct GrayScratch {
    pub(crate) lmax: Vec<u16>,
    pub(crate) lmin: Vec<u16>,
    pub(crate) ld: Vec<u16>,
    pub(crate) lg: Vec<u16>,
    pub(crate) thr2: Vec<u32>,
    pub(crate) code: Vec<u16>,
    pub(crate) unread: Vec<u16>,
    pub(crate) pos: Vec<f32>,
    pub(crate) strong: Vec<bool>,
    pub(crate) a8: Vec<u8>,
    pub(crate) d8: Vec<u8>,
    pub(crate) code8: [Vec<u8>; 2],
    pub(crate) unread8: [Vec<u8>; 2],
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

/// A band of camera rows.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Band {
    pub(crate) width: usize,
    pub(crate) y0: usize,
    pub(crate) rows: usize,
}

impl Band {
    #[inline(always)]
    pub(crate) fn of<'f, T: Sample>(&self, frame: Option<&'f Frame<T>>) -> &'f [T] {
        band(frame, self.width, self.y0, self.rows)
    }
}

/// Reads the `bits` pattern/inverse pairs starting at frame `first` into `s.code`/`s.unread`,
/// with the direct and global light already in `s.ld`/`s.lg`. 8-bit frames (`frames8`) take a
/// byte-wide path.
#[inline(always)]
pub(crate) fn read_inverse_bits<T: Sample>(
    frames: &[Frame<T>],
    frames8: Option<&[&Frame<u8>]>,
    first: usize,
    bits: usize,
    band: Band,
    th: BitThresholds,
    s: &mut GrayScratch,
) {
    let n = s.code.len();
    s.code.fill(0);
    s.unread.fill(0);
    let Some(frames8) = frames8 else {
        for b in 0..bits {
            let (p, q) = (
                band.of(frames.get(first + 2 * b)),
                band.of(frames.get(first + 2 * b + 1)),
            );
            if p.len() < n || q.len() < n {
                return;
            }
            read_bit_inverse(p, q, &s.ld, &s.lg, &mut s.code, &mut s.unread, th);
        }
        return;
    };
    let mc = u16::from(u8::try_from(th.min_contrast).unwrap_or(u8::MAX));
    for ((((&d, &g), st), a), dd) in
        s.ld.iter()
            .zip(&s.lg)
            .zip(s.strong.iter_mut())
            .zip(s.a8.iter_mut())
            .zip(s.d8.iter_mut())
    {
        let m = mc.saturating_add(g >> WEAK_RULE_MARGIN_SHIFT);
        *st = d > g;
        *a = g.saturating_add(m).min(255) as u8;
        *dd = d.saturating_sub(m).min(255) as u8;
    }
    for v in s.code8.iter_mut().chain(s.unread8.iter_mut()) {
        v.fill(0);
    }
    // The first `bits - 8` bits go to the high bytes, the last 8 to the low bytes.
    let high = bits.saturating_sub(8);
    for b in 0..bits {
        let p = band.of(frames8.get(first + 2 * b).copied());
        let q = band.of(frames8.get(first + 2 * b + 1).copied());
        if p.len() < n || q.len() < n {
            return;
        }
        let ([c0, c1], [u0, u1]) = (&mut s.code8, &mut s.unread8);
        let (code, unread) = if b < high { (c0, u0) } else { (c1, u1) };
        read_bit_inverse_u8(
            p, q, &s.strong, &s.a8, &s.d8, code, unread, mc as u8, th.robust,
        );
    }
    let [ch, cl] = &s.code8;
    let [uh, ul] = &s.unread8;
    for (((((c, u), ch), cl), uh), ul) in s
        .code
        .iter_mut()
        .zip(s.unread.iter_mut())
        .zip(ch)
        .zip(cl)
        .zip(uh)
        .zip(ul)
    {
        *c = (u16::from(*ch) << 8) | u16::from(*cl);
        *u = (u16::from(*uh) << 8) | u16::from(*ul);
    }
}

/// Reads the `bits` patterns starting at frame `first` against the doubled thresholds in
/// `s.thr2` into `s.code`/`s.unread`.
#[inline(always)]
pub(crate) fn read_threshold_bits<T: Sample>(
    frames: &[Frame<T>],
    first: usize,
    bits: usize,
    band: Band,
    min_contrast: u16,
    s: &mut GrayScratch,
) {
    let n = s.code.len();
    s.code.fill(0);
    s.unread.fill(0);
    for b in 0..bits {
        let p = band.of(frames.get(first + b));
        if p.len() < n {
            return;
        }
        read_bit_threshold(p, &s.thr2, &mut s.code, &mut s.unread, min_contrast);
    }
}

impl GrayScratch {
    /// A scratch for bands of up to `len` pixels.
    pub(crate) fn new(len: usize) -> Self {
        Self {
            lmax: vec![0; len],
            lmin: vec![0; len],
            ld: vec![0; len],
            lg: vec![0; len],
            thr2: vec![0; len],
            code: vec![0; len],
            unread: vec![0; len],
            pos: vec![0.0; len],
            strong: vec![false; len],
            a8: vec![0; len],
            d8: vec![0; len],
            code8: [vec![0; len], vec![0; len]],
            unread8: [vec![0; len], vec![0; len]],
        }
    }

    /// Sets every buffer to `n` entries (within the capacity allocated by `new`).
    pub(crate) fn fit(&mut self, n: usize) {
        self.lmax.resize(n, 0);
        self.lmin.resize(n, 0);
        self.ld.resize(n, 0);
        self.lg.resize(n, 0);
        self.thr2.resize(n, 0);
        self.code.resize(n, 0);
        self.unread.resize(n, 0);
        self.pos.resize(n, 0.0);
        self.strong.resize(n, false);
        self.a8.resize(n, 0);
        self.d8.resize(n, 0);
        for v in self.code8.iter_mut().chain(self.unread8.iter_mut()) {
            v.resize(n, 0);
        }
    }
}

/// Rows `y0 .. y0 + rows` of a frame of width `width` as one slice (empty if out of range).
#[inline(always)]
pub(crate) fn band<T: Sample>(
    frame: Option<&Frame<T>>,
    width: usize,
    y0: usize,
    rows: usize,
) -> &[T] {
    frame
        .and_then(|f| f.data().get(y0 * width..(y0 + rows) * width))
        .unwrap_or(&[])
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
    fn direct_global_closed_form() {
        // Ld = 100, Lg = 40, b = 0.2: Lmax = Ld + (1+b) Lg / 2 = 124, Lmin = b Ld + (1+b) Lg/2 = 44.
        let (mut ld, mut lg) = (vec![0u16; 1], vec![0u16; 1]);
        direct_global_row(&[124], &[44], &mut ld, &mut lg, 0.2);
        assert!((i32::from(ld[0]) - 100).abs() <= 1, "{}", ld[0]);
        assert!((i32::from(lg[0]) - 40).abs() <= 1, "{}", lg[0]);
        direct_global_row(&[150], &[30], &mut ld, &mut lg, 0.0);
        assert_eq!((ld[0], lg[0]), (120, 60));
    }

    #[test]
    fn robust_rules_of_xu_and_aliaga() {
        let th = BitThresholds {
            min_contrast: 4,
            min_direct: 8,
            saturation: 255,
            robust: true,
        };
        // Margin of the weak rules: 4 + 80 / 8 = 14.
        // Pixel 0: strong direct (Ld 100 > Lg 20): comparison.
        // Pixel 1: weak (Ld 30 < Lg 80), p = 100 >= Lg + 14, q + 14 = 24 <= Ld -> 1.
        // Pixel 2: weak, p = 60, q = 50: neither rule -> unread.
        // Pixel 3: strong but contrast 2 < 4 -> unread.
        // Pixel 4: weak, p = 85 is above Lg but inside the margin -> unread.
        // Pixel 5: weak, q = 95, p = 12 -> 0.
        let p = [120u8, 100, 60, 52, 85, 12];
        let q = [20u8, 10, 50, 50, 10, 95];
        let ld = [100u16, 30, 30, 100, 30, 30];
        let lg = [20u16, 80, 80, 20, 80, 80];
        let mut code = vec![0u16; 6];
        let mut unread = vec![0u16; 6];
        read_bit_inverse(&p, &q, &ld, &lg, &mut code, &mut unread, th);
        assert_eq!(code, vec![1, 1, 0, 1, 0, 0]);
        assert_eq!(unread, vec![0, 0, 1, 1, 1, 0]);
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
