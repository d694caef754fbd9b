//! Image blurs used by the camera effects: a separable Gaussian for the lens and defocus and a
//! three-pass box blur (a close, O(1)-per-pixel approximation of a wide Gaussian) for the
//! global-illumination term.

use rayon::prelude::*;

/// Kernel half-width in standard deviations: the Gaussian's tail beyond 3σ holds 0.27 % of its
/// weight, below what an 8-bit camera resolves.
const GAUSS_TRUNCATE_SIGMAS: f64 = 3.0;

/// Blurs with the discrete kernel of a lens point spread of standard deviation `sigma` pixels:
/// a sampled Gaussian whose width parameter is chosen so that the kernel's variance is exactly
/// `sigma²` (a Gaussian sampled at integer taps has a smaller variance than its parameter's
/// square below σ ≈ 0.7 px, 0.18 against 0.25 px² at σ = 0.5). The image it blurs already holds
/// each pixel's area integral, so the pixel's own box is not added again.
pub(crate) fn point_spread(src: &[f32], width: usize, height: usize, sigma: f64) -> Vec<f32> {
    if sigma <= 0.0 || width == 0 || height == 0 {
        return src.to_vec();
    }
    let kernel = point_spread_kernel(sigma);
    separable(src, width, height, &kernel)
}

/// The kernel of [`point_spread`]: normalised, variance `sigma²` to 1e-9 (bisection on the
/// sampled Gaussian's parameter, whose variance grows monotonically with it).
pub(crate) fn point_spread_kernel(sigma: f64) -> Vec<f32> {
    let radius = (GAUSS_TRUNCATE_SIGMAS * sigma).ceil().max(1.0) as usize;
    let taps = |t: f64| -> Vec<f64> {
        let mut k: Vec<f64> = (0..=2 * radius)
            .map(|i| {
                let d = i as f64 - radius as f64;
                (-(d * d) / (2.0 * t * t)).exp()
            })
            .collect();
        let sum: f64 = k.iter().sum();
        k.iter_mut().for_each(|v| *v /= sum);
        k
    };
    let variance = |k: &[f64]| -> f64 {
        k.iter()
            .enumerate()
            .map(|(i, v)| v * (i as f64 - radius as f64).powi(2))
            .sum()
    };
    let want = sigma * sigma;
    let (mut lo, mut hi) = (1e-3, 2.0 * sigma + 1.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if variance(&taps(mid)) < want {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    taps(0.5 * (lo + hi))
        .into_iter()
        .map(|v| v as f32)
        .collect()
}

/// Convolves a `width × height` row-major image with `kernel` (odd length `2 r + 1`, centred)
/// along both axes, borders clamped.
pub(crate) fn separable(src: &[f32], width: usize, height: usize, kernel: &[f32]) -> Vec<f32> {
    if width == 0 || height == 0 || kernel.is_empty() {
        return src.to_vec();
    }
    let radius = kernel.len() / 2;
    let tmp = convolve_rows(src, width, kernel, radius);
    let t = transpose(&tmp, width, height);
    let t = convolve_rows(&t, height, kernel, radius);
    transpose(&t, height, width)
}

/// Three passes of a box blur whose combined standard deviation is close to `sigma` pixels
/// (borders clamped). `sigma <= 0` returns a copy.
pub(crate) fn box3(src: &[f32], width: usize, height: usize, sigma: f64) -> Vec<f32> {
    if sigma <= 0.0 || width == 0 || height == 0 {
        return src.to_vec();
    }
    // Three boxes of width w = 2r + 1 have variance 3 (w² - 1) / 12 = r (r + 1).
    let r = ((0.25 + sigma * sigma).sqrt() - 0.5).round().max(1.0) as usize;
    let mut img = src.to_vec();
    for _ in 0..3 {
        img = box_rows(&img, width, r);
    }
    let mut t = transpose(&img, width, height);
    for _ in 0..3 {
        t = box_rows(&t, height, r);
    }
    transpose(&t, height, width)
}

/// One pass of `kernel` along each row, borders clamped. The interior, where no tap reaches past
/// a border, runs on plain windows (no clamping or bounds checks in the inner loop); the sums are
/// taken in the same order at the borders and inside, so the result does not depend on the split.
fn convolve_rows(src: &[f32], width: usize, kernel: &[f32], radius: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; src.len()];
    out.par_chunks_mut(width)
        .zip(src.par_chunks(width))
        .for_each(|(o, row)| {
            let last = width - 1;
            let clamped = |x: usize| -> f32 {
                let mut acc = 0.0f32;
                for (k, &w) in kernel.iter().enumerate() {
                    let xi = (x + k).saturating_sub(radius).min(last);
                    acc += w * row.get(xi).copied().unwrap_or(0.0);
                }
                acc
            };
            // Interior: x - radius >= 0 and x + radius <= last.
            let inner = radius..width.saturating_sub(radius).max(radius);
            for (x, ov) in o.iter_mut().enumerate() {
                if inner.contains(&x) {
                    break;
                }
                *ov = clamped(x);
            }
            if !inner.is_empty() {
                let windows = row.windows(kernel.len());
                for (ov, win) in o[inner.clone()].iter_mut().zip(windows) {
                    *ov = win
                        .iter()
                        .zip(kernel)
                        .fold(0.0f32, |acc, (&v, &w)| acc + w * v);
                }
            }
            for (x, ov) in o.iter_mut().enumerate().skip(inner.end.max(inner.start)) {
                *ov = clamped(x);
            }
        });
    out
}

fn box_rows(src: &[f32], width: usize, r: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; src.len()];
    let norm = 1.0 / (2 * r + 1) as f64;
    out.par_chunks_mut(width)
        .zip(src.par_chunks(width))
        .for_each(|(o, row)| {
            let last = width - 1;
            let at = |i: isize| -> f64 {
                let i = i.clamp(0, last as isize) as usize;
                f64::from(row.get(i).copied().unwrap_or(0.0))
            };
            let r = r as isize;
            let mut acc: f64 = (-r..=r).map(at).sum();
            // Where x - r >= 0 and x + r + 1 <= last the two samples need no clamping: the
            // same sums in the same order, without the clamps in the hot middle.
            let inner = (r as usize)..(width.saturating_sub(r as usize + 1));
            for (x, ov) in o.iter_mut().enumerate() {
                *ov = (acc * norm) as f32;
                if inner.contains(&x) {
                    let (add, sub) = (row[x + r as usize + 1], row[x - r as usize]);
                    acc += f64::from(add) - f64::from(sub);
                } else {
                    let x = x as isize;
                    acc += at(x + r + 1) - at(x - r);
                }
            }
        });
    out
}

/// `src` (`height` rows of `width`) transposed, in tiles so that both the reads and the writes
/// stay in cache (a column-at-a-time transpose misses on every read of a large frame).
fn transpose(src: &[f32], width: usize, height: usize) -> Vec<f32> {
    const TILE: usize = 32;
    let mut out = vec![0.0f32; src.len()];
    if width == 0 || height == 0 {
        return out;
    }
    // Each task owns TILE output rows (TILE source columns) and walks the source in TILE-row steps.
    out.par_chunks_mut(height * TILE)
        .enumerate()
        .for_each(|(band, cols)| {
            let x0 = band * TILE;
            let nx = cols.len() / height;
            for y0 in (0..height).step_by(TILE) {
                let y1 = (y0 + TILE).min(height);
                for dx in 0..nx {
                    let x = x0 + dx;
                    let col = &mut cols[dx * height + y0..dx * height + y1];
                    for (y, v) in (y0..y1).zip(col) {
                        *v = src.get(y * width + x).copied().unwrap_or(0.0);
                    }
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// Variance of a blurred impulse = the blur's variance (for a normalised kernel).
    fn impulse_variance(blurred: &[f32], w: usize, cx: usize) -> f64 {
        let row = &blurred[(w / 2) * w..(w / 2 + 1) * w];
        let sum: f64 = row.iter().map(|&v| f64::from(v)).sum();
        row.iter()
            .enumerate()
            .map(|(x, &v)| f64::from(v) * (x as f64 - cx as f64).powi(2))
            .sum::<f64>()
            / sum
    }

    /// The lens kernel's variance is σ² for narrow and wide spreads alike (a plain sampled
    /// Gaussian misses it by 28 % at σ = 0.5), and it sums to 1.
    #[test]
    fn point_spread_kernel_has_the_asked_variance() {
        for sigma in [0.3, 0.5, 0.8, 1.2, 2.0] {
            let k = point_spread_kernel(sigma);
            let r = (k.len() / 2) as f64;
            let sum: f64 = k.iter().map(|&v| f64::from(v)).sum();
            let var: f64 = k
                .iter()
                .enumerate()
                .map(|(i, &v)| f64::from(v) * (i as f64 - r).powi(2))
                .sum();
            assert_abs_diff_eq!(sum, 1.0, epsilon = 1e-6);
            // f32 taps: 1e-6 relative.
            assert_abs_diff_eq!(var, sigma * sigma, epsilon = 1e-5);
        }
    }

    /// The tiled transpose and the windowed convolution give the plain per-pixel definitions,
    /// bit for bit, on images narrower and wider than the kernel and than a tile.
    #[test]
    fn fast_passes_equal_the_plain_definitions() {
        let kernel = point_spread_kernel(1.3);
        let radius = kernel.len() / 2;
        for (w, h) in [
            (1, 1),
            (3, 2),
            (radius * 2, 5),
            (radius * 2 + 1, 7),
            (33, 65),
            (100, 37),
        ] {
            let img: Vec<f32> = (0..w * h)
                .map(|i| ((i * 7919) % 1013) as f32 / 1013.0)
                .collect();
            let t = transpose(&img, w, h);
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(t[x * h + y].to_bits(), img[y * w + x].to_bits());
                }
            }
            for r in [1, 2, 5] {
                let b = box_rows(&img, w, r);
                for y in 0..h {
                    let row = &img[y * w..(y + 1) * w];
                    let at = |i: isize| f64::from(row[i.clamp(0, w as isize - 1) as usize]);
                    let r = r as isize;
                    let mut acc: f64 = (-r..=r).map(at).sum();
                    for x in 0..w {
                        let want = (acc * (1.0 / (2 * r + 1) as f64)) as f32;
                        assert_eq!(
                            b[y * w + x].to_bits(),
                            want.to_bits(),
                            "box {r} {w}x{h} at {x},{y}"
                        );
                        let x = x as isize;
                        acc += at(x + r + 1) - at(x - r);
                    }
                }
            }
            let c = convolve_rows(&img, w, &kernel, radius);
            for y in 0..h {
                let row = &img[y * w..(y + 1) * w];
                for x in 0..w {
                    let mut acc = 0.0f32;
                    for (k, &kw) in kernel.iter().enumerate() {
                        acc += kw * row[(x + k).saturating_sub(radius).min(w - 1)];
                    }
                    assert_eq!(c[y * w + x].to_bits(), acc.to_bits(), "{w}x{h} at {x},{y}");
                }
            }
        }
    }

    #[test]
    fn blurs_preserve_mean_and_have_the_right_width() {
        let w = 101;
        let mut img = vec![0.0f32; w * w];
        img[50 * w + 50] = 1.0;
        let g = point_spread(&img, w, w, 4.0);
        let total: f64 = g.iter().map(|&v| f64::from(v)).sum();
        // f32 accumulation over ~600 taps: 1e-5 is a few hundred ulps of 1.
        assert_abs_diff_eq!(total, 1.0, epsilon = 1e-5);
        // The kernel's variance is made exact (the truncation at 3σ is compensated).
        assert_abs_diff_eq!(impulse_variance(&g, w, 50), 16.0, epsilon = 1e-3);
        let b = box3(&img, w, w, 4.0);
        let total: f64 = b.iter().map(|&v| f64::from(v)).sum();
        assert_abs_diff_eq!(total, 1.0, epsilon = 1e-5);
        // r = round(sqrt(16.25) - 0.5) = 4 -> variance r (r + 1) = 20 (the closest a box3 gets).
        assert_abs_diff_eq!(impulse_variance(&b, w, 50), 20.0, epsilon = 0.05);
    }
}
