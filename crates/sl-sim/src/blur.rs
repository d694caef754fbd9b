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

fn convolve_rows(src: &[f32], width: usize, kernel: &[f32], radius: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; src.len()];
    out.par_chunks_mut(width)
        .zip(src.par_chunks(width))
        .for_each(|(o, row)| {
            let last = width - 1;
            for (x, ov) in o.iter_mut().enumerate() {
                let mut acc = 0.0f32;
                for (k, &w) in kernel.iter().enumerate() {
                    let xi = (x + k).saturating_sub(radius).min(last);
                    acc += w * row.get(xi).copied().unwrap_or(0.0);
                }
                *ov = acc;
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
            for (x, ov) in o.iter_mut().enumerate() {
                *ov = (acc * norm) as f32;
                let x = x as isize;
                acc += at(x + r + 1) - at(x - r);
            }
        });
    out
}

fn transpose(src: &[f32], width: usize, height: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; src.len()];
    out.par_chunks_mut(height).enumerate().for_each(|(x, col)| {
        for (y, v) in col.iter_mut().enumerate() {
            *v = src.get(y * width + x).copied().unwrap_or(0.0);
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
