//! A floating-point grey image with Gaussian blur and bilinear sampling: the working image of
//! the checkerboard detector.

use std::path::Path;

use rayon::prelude::*;
use sl_codec::Frame;

use crate::CalibError;

/// Loads an image file (BMP, PGM/PPM, PNG, JPEG, TIFF) as 8-bit grey, by
/// [`sl_codec::read_grey8`]: colour becomes grey by OpenCV's `COLOR_RGB2GRAY` rule and 16-bit
/// values are scaled by `round(v / 257)`, so corners are found on the same grey levels as
/// OpenCV's.
///
/// # Errors
/// [`CalibError::Codec`] naming the file when it cannot be read or decoded, or is empty.
pub fn load_grey(path: impl AsRef<Path>) -> Result<Frame<u8>, CalibError> {
    Ok(sl_codec::read_grey8(path.as_ref())?)
}

/// Row-major `f32` grey image; pixel `(x, y)` at `y · width + x`.
#[derive(Debug, Clone)]
pub(crate) struct GreyF32 {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) data: Vec<f32>,
}

/// Gaussian kernels are cut at this many standard deviations (the tail beyond holds < 0.3 %
/// of the weight).
const KERNEL_SIGMAS: f32 = 3.0;

impl GreyF32 {
    pub(crate) fn from_luma(img: &Frame<u8>) -> Self {
        Self {
            width: img.width(),
            height: img.height(),
            data: img.data().iter().map(|&v| f32::from(v)).collect(),
        }
    }

    /// Value at integer `(x, y)` clamped to the border.
    #[inline]
    pub(crate) fn at(&self, x: isize, y: isize) -> f32 {
        let xc = x.clamp(0, self.width as isize - 1) as usize;
        let yc = y.clamp(0, self.height as isize - 1) as usize;
        self.data.get(yc * self.width + xc).copied().unwrap_or(0.0)
    }

    /// Bilinear sample at `(x, y)` (pixel centres at integers), clamped to the border.
    #[inline]
    pub(crate) fn sample(&self, x: f64, y: f64) -> f64 {
        let x0 = x.floor();
        let y0 = y.floor();
        let fx = x - x0;
        let fy = y - y0;
        let (xi, yi) = (x0 as isize, y0 as isize);
        let a = f64::from(self.at(xi, yi));
        let b = f64::from(self.at(xi + 1, yi));
        let c = f64::from(self.at(xi, yi + 1));
        let d = f64::from(self.at(xi + 1, yi + 1));
        (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
    }

    /// Half resolution: each pixel the mean of a 2×2 block (an odd last row or column is
    /// dropped). Pixel `X` of the result is centred at `2X + 0.5` of this image.
    pub(crate) fn half(&self) -> Self {
        let (w, h) = (self.width / 2, self.height / 2);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (x2, y2) = (2 * x as isize, 2 * y as isize);
                data.push(
                    0.25 * (self.at(x2, y2)
                        + self.at(x2 + 1, y2)
                        + self.at(x2, y2 + 1)
                        + self.at(x2 + 1, y2 + 1)),
                );
            }
        }
        Self {
            width: w,
            height: h,
            data,
        }
    }

    /// Separable Gaussian blur with standard deviation `sigma` (pixels); `sigma <= 0` copies.
    pub(crate) fn blurred(&self, sigma: f32) -> Self {
        if sigma <= 0.0 || self.width == 0 || self.height == 0 {
            return self.clone();
        }
        let radius = (KERNEL_SIGMAS * sigma).ceil() as isize;
        let mut kernel: Vec<f32> = (-radius..=radius)
            .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
            .collect();
        let sum: f32 = kernel.iter().sum();
        kernel.iter_mut().for_each(|k| *k /= sum);
        let (w, h) = (self.width, self.height);
        let mut tmp = vec![0.0f32; w * h];
        // Horizontal pass, rows in parallel.
        let r = radius as usize;
        tmp.par_chunks_mut(w)
            .zip(self.data.par_chunks(w))
            .for_each(|(out, row)| {
                for (x, o) in out.iter_mut().enumerate() {
                    // Interior: a plain dot product (vectorises); borders: clamped indices.
                    if x >= r && x + r < w {
                        *o = kernel
                            .iter()
                            .zip(&row[x - r..=x + r])
                            .map(|(k, v)| k * v)
                            .sum();
                        continue;
                    }
                    let mut acc = 0.0;
                    for (k, &kv) in kernel.iter().enumerate() {
                        let xs =
                            (x as isize + k as isize - radius).clamp(0, w as isize - 1) as usize;
                        acc += kv * row[xs];
                    }
                    *o = acc;
                }
            });
        // Vertical pass, output rows in parallel.
        let mut data = vec![0.0f32; w * h];
        data.par_chunks_mut(w).enumerate().for_each(|(y, dst)| {
            for (k, &kv) in kernel.iter().enumerate() {
                let ys = (y as isize + k as isize - radius).clamp(0, h as isize - 1) as usize;
                let src = &tmp[ys * w..(ys + 1) * w];
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += kv * s;
                }
            }
        });
        Self {
            width: w,
            height: h,
            data,
        }
    }
}
