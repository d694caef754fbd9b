//! Image blurs used by the camera effects: an exact separable Gaussian for defocus and a
//! three-pass box blur (a close, O(1)-per-pixel approximation of a wide Gaussian) for the
//! global-illumination term.

use rayon::prelude::*;

/// Kernel half-width in standard deviations: the Gaussian's tail beyond 3σ holds 0.27 % of its
/// weight, below what an 8-bit camera resolves.
const GAUSS_TRUNCATE_SIGMAS: f64 = 3.0;

/// Blurs a `width × height` row-major image with a Gaussian of standard deviation `sigma`
/// pixels (separable, borders clamped). `sigma <= 0` returns a copy.
pub(crate) fn gaussian(src: &[f32], width: usize, height: usize, sigma: f64) -> Vec<f32> {
    if sigma <= 0.0 || width == 0 || height == 0 {
        return src.to_vec();
    }
    let radius = (GAUSS_TRUNCATE_SIGMAS * sigma).ceil() as usize;
    let mut kernel: Vec<f32> = (0..=2 * radius)
        .map(|i| {
            let d = i as f64 - radius as f64;
            (-(d * d) / (2.0 * sigma * sigma)).exp() as f32
        })
        .collect();
    let sum: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= sum);
    separable(src, width, height, &kernel)
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

    #[test]
    fn blurs_preserve_mean_and_have_the_right_width() {
        let w = 101;
        let mut img = vec![0.0f32; w * w];
        img[50 * w + 50] = 1.0;
        let g = gaussian(&img, w, w, 4.0);
        let total: f64 = g.iter().map(|&v| f64::from(v)).sum();
        // f32 accumulation over ~600 taps: 1e-5 is a few hundred ulps of 1.
        assert_abs_diff_eq!(total, 1.0, epsilon = 1e-5);
        // Truncation at 3 sigma removes 0.3 % of the weight mostly from the tails: variance
        // within 3 % of 16.
        assert_abs_diff_eq!(impulse_variance(&g, w, 50), 16.0, epsilon = 0.5);
        let b = box3(&img, w, w, 4.0);
        let total: f64 = b.iter().map(|&v| f64::from(v)).sum();
        assert_abs_diff_eq!(total, 1.0, epsilon = 1e-5);
        // r = round(sqrt(16.25) - 0.5) = 4 -> variance r (r + 1) = 20 (the closest a box3 gets).
        assert_abs_diff_eq!(impulse_variance(&b, w, 50), 20.0, epsilon = 0.05);
    }
}
