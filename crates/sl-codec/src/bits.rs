//! Reading the bits of stripe patterns, shared by the Gray decoder (`gray.rs`) and the hybrid
//! one (`hybrid.rs`): one bit per pixel per pattern, against the pattern's inverse (with the
//! direct/global light split of Nayar et al. and Xu & Aliaga's rules) or against a per-pixel
//! threshold, accumulated into code words with the bits that could not be read; 8-bit frames
//! take a byte-wide path. The frames are read in bands of camera rows ([`Band`]).

use crate::config::level_u16;
use crate::gray::WEAK_RULE_MARGIN_SHIFT;
use crate::{DecodeConfig, Frame, Sample};

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

/// Per-task buffers of the bit readers: the scratch of
/// [`GrayKernel`](crate::gray::GrayKernel) and of the hybrid decoder.
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
