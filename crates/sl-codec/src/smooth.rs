//! Spatial smoothing of a decoded map: each valid pixel's projector coordinate replaced by a
//! local plane fitted to its valid neighbours, so that the sensor noise of one pixel is
//! averaged with its neighbours' before triangulation.
//!
//! The decoded coordinate of a smooth surface varies almost linearly across a few camera
//! pixels (1–2 projector pixels per camera pixel on a typical rig), so the plane's value at
//! the centre keeps the coordinate where it is — also where some neighbours are missing,
//! where a plain average would be pulled along the slope — while the independent noise of
//! the pixels falls: by 0.375 (a 3 × 3 binomial window) or 0.27 (5 × 5). Neighbours across a
//! depth step (their coordinate further from the centre's than `max_step_px` per pixel of
//! distance) are left out, and invalid pixels stay invalid: the valid set does not change.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{CodecError, CorrespondenceMap};

/// Settings of [`smooth_correspondences`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SmoothConfig {
    /// Half-width of the window (pixels): 1 for 3 × 3, 2 for 5 × 5. The weights are binomial
    /// (`[1 2 1]`, `[1 4 6 4 1]`), a Gaussian of σ ≈ `sqrt(radius / 2)` px.
    pub radius: usize,
    /// A neighbour `d` pixels away (Chebyshev distance) enters the fit only if its coordinate
    /// is within `max_step_px · d` projector pixels of the centre's: a surface seen at a
    /// grazing angle changes by a few projector pixels per camera pixel, a depth step by more.
    pub max_step_px: f32,
}

impl Default for SmoothConfig {
    /// A 3 × 3 binomial window (noise × 0.375 on a full window, the lateral resolution
    /// widened by about half a pixel), neighbours within 4 projector pixels per pixel.
    fn default() -> Self {
        Self {
            radius: 1,
            max_step_px: 4.0,
        }
    }
}

/// Largest window half-width accepted: beyond, the map is blurred over features a
/// structured-light scan is meant to resolve.
pub const MAX_SMOOTH_RADIUS: usize = 4;

impl SmoothConfig {
    /// Checks the radius (1..=[`MAX_SMOOTH_RADIUS`]) and the step (positive, finite).
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming the field.
    pub fn validate(&self) -> Result<(), CodecError> {
        if !(1..=MAX_SMOOTH_RADIUS).contains(&self.radius) {
            return Err(CodecError::parameter(
                "smooth radius",
                format!("{} is not in 1..={MAX_SMOOTH_RADIUS}", self.radius),
            ));
        }
        if !(self.max_step_px.is_finite() && self.max_step_px > 0.0) {
            return Err(CodecError::parameter(
                "smooth max_step_px",
                format!("{} is not a positive number", self.max_step_px),
            ));
        }
        Ok(())
    }
}

/// Binomial weights of a window of half-width `r`: row `2r` of Pascal's triangle.
fn binomial(r: usize) -> Vec<f64> {
    let n = 2 * r;
    let mut w = vec![1.0f64; n + 1];
    for k in 1..n {
        w[k] = w[k - 1] * (n + 1 - k) as f64 / k as f64;
    }
    w
}

/// Smooths one coordinate plane `coord` (NaN where there is none) over the pixels `valid`.
fn smooth_plane(
    coord: &[f32],
    valid: &[bool],
    width: usize,
    height: usize,
    cfg: &SmoothConfig,
) -> Vec<f32> {
    let r = cfg.radius as isize;
    let weights = binomial(cfg.radius);
    let mut out = coord.to_vec();
    out.par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * width + x;
                let centre = coord[i];
                if !(valid[i] && centre.is_finite()) {
                    continue;
                }
                // Weighted least squares of c = a + b·dx + e·dy over the window.
                let (mut s0, mut sx, mut sy, mut sxx, mut sxy, mut syy) =
                    (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
                let (mut sc, mut sxc, mut syc) = (0.0f64, 0.0, 0.0);
                for dy in -r..=r {
                    let yy = y as isize + dy;
                    if yy < 0 || yy >= height as isize {
                        continue;
                    }
                    let wy = weights[(dy + r) as usize];
                    for dx in -r..=r {
                        let xx = x as isize + dx;
                        if xx < 0 || xx >= width as isize {
                            continue;
                        }
                        let j = yy as usize * width + xx as usize;
                        let c = coord[j];
                        if !(valid[j] && c.is_finite()) {
                            continue;
                        }
                        let d = dx.unsigned_abs().max(dy.unsigned_abs()) as f32;
                        if (c - centre).abs() > cfg.max_step_px * d {
                            continue;
                        }
                        let w = wy * weights[(dx + r) as usize];
                        let (fx, fy) = (dx as f64, dy as f64);
                        // Relative to the centre: the sums stay small and exact in f64.
                        let cv = f64::from(c - centre);
                        s0 += w;
                        sx += w * fx;
                        sy += w * fy;
                        sxx += w * fx * fx;
                        sxy += w * fx * fy;
                        syy += w * fy * fy;
                        sc += w * cv;
                        sxc += w * fx * cv;
                        syc += w * fy * cv;
                    }
                }
                // Solve [s0 sx sy; sx sxx sxy; sy sxy syy] [a b e]ᵀ = [sc sxc syc]ᵀ for a
                // (Cramer's rule); a degenerate window (neighbours on a line) keeps the value.
                let det = s0 * (sxx * syy - sxy * sxy) - sx * (sx * syy - sxy * sy)
                    + sy * (sx * sxy - sxx * sy);
                if det.abs() <= 1e-9 * s0 * s0 * s0 {
                    continue;
                }
                let a = (sc * (sxx * syy - sxy * sxy) - sx * (sxc * syy - sxy * syc)
                    + sy * (sxc * sxy - sxx * syc))
                    / det;
                *o = centre + a as f32;
            }
        });
    out
}

/// `map` with each valid pixel's projector coordinates (both axes, where decoded) replaced by
/// the value at the pixel of a plane fitted to its valid neighbours (see the module docs).
/// Quality and validity are unchanged.
///
/// ```
/// use sl_codec::{CorrespondenceMap, SmoothConfig, smooth_correspondences};
/// # fn main() -> Result<(), sl_codec::CodecError> {
/// // A ramp of 1.5 projector px per camera px with one noisy pixel.
/// let mut map = CorrespondenceMap::new(5, 5);
/// for i in 0..25 {
///     map.col[i] = 1.5 * (i % 5) as f32;
/// }
/// map.col[12] += 0.4;
/// let smooth = smooth_correspondences(&map, &SmoothConfig::default())?;
/// // The ramp stays where it was; the noise at the centre is shared with its neighbours.
/// assert!((smooth.col[12] - 3.0 - 0.4 * 4.0 / 16.0).abs() < 1e-5);
/// assert!((smooth.col[0] - 0.0).abs() < 0.1);
/// # Ok(())
/// # }
/// ```
///
/// # Errors
/// [`CodecError::Parameter`] for settings out of range ([`SmoothConfig::validate`]).
pub fn smooth_correspondences(
    map: &CorrespondenceMap,
    cfg: &SmoothConfig,
) -> Result<CorrespondenceMap, CodecError> {
    cfg.validate()?;
    let (w, h) = (map.width, map.height);
    let valid: Vec<bool> = map.invalid.iter().map(|r| r.is_valid()).collect();
    let mut out = map.clone();
    if map.col.iter().any(|c| c.is_finite()) {
        out.col = smooth_plane(&map.col, &valid, w, h, cfg);
    }
    if map.row.iter().any(|c| c.is_finite()) {
        out.row = smooth_plane(&map.row, &valid, w, h, cfg);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A smooth surface's coordinate (a ramp with a little curvature, as a sphere's) plus
    /// independent noise: the smoothed map is as close to the noise-free one as the binomial
    /// window's noise gain says (0.375 for 3 × 3, 0.273 for 5 × 5), and not biased.
    #[test]
    fn noise_falls_by_the_window_gain_without_bias() {
        let (w, h) = (200usize, 150usize);
        let truth = |x: usize, y: usize| {
            let (fx, fy) = (x as f64, y as f64);
            1.5 * fx + 0.2 * fy + 2e-4 * (fx - 100.0).powi(2)
        };
        let sigma = 0.05;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(4);
        let noise = Normal::new(0.0, sigma).unwrap();
        let mut map = CorrespondenceMap::new(w, h);
        for y in 0..h {
            for x in 0..w {
                map.col[y * w + x] = (truth(x, y) + noise.sample(&mut rng)) as f32;
            }
        }
        for (radius, gain) in [(1usize, 0.375), (2, 0.2734)] {
            let cfg = SmoothConfig {
                radius,
                ..SmoothConfig::default()
            };
            let s = smooth_correspondences(&map, &cfg).unwrap();
            let (mut sq, mut sum, mut n) = (0.0, 0.0, 0usize);
            for y in 5..h - 5 {
                for x in 5..w - 5 {
                    let e = f64::from(s.col[y * w + x]) - truth(x, y);
                    sq += e * e;
                    sum += e;
                    n += 1;
                }
            }
            let rms = (sq / n as f64).sqrt();
            // 26,000 samples: the RMS within 2 %, the mean within 5 standard errors. The
            // curvature's bias (2e-4 · mean dx², under 1e-3 px) is inside both.
            assert!(
                (rms / (sigma * gain) - 1.0).abs() < 0.03,
                "radius {radius}: rms {rms}"
            );
            assert!((sum / n as f64).abs() < 5.0 * sigma * gain / (n as f64).sqrt() + 1e-3);
        }
    }

    /// Next to a depth step the other side is left out, and next to missing pixels the plane
    /// keeps the slope: no pull towards either.
    #[test]
    fn steps_and_holes_do_not_pull_the_coordinate() {
        let (w, h) = (20usize, 10usize);
        let mut map = CorrespondenceMap::new(w, h);
        for y in 0..h {
            for x in 0..w {
                // A ramp that jumps by 30 projector px at x = 10 (a depth step).
                map.col[y * w + x] = 1.5 * x as f32 + if x >= 10 { 30.0 } else { 0.0 };
            }
        }
        // A hole left of (5, 5).
        for y in 4..=6 {
            map.col[y * w + 4] = f32::NAN;
            map.invalid[y * w + 4] = crate::InvalidReason::Shadow;
        }
        let s = smooth_correspondences(&map, &SmoothConfig::default()).unwrap();
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let i = y * w + x;
                if map.col[i].is_nan() {
                    assert!(s.col[i].is_nan());
                    assert_eq!(s.invalid[i], crate::InvalidReason::Shadow);
                    continue;
                }
                assert!(
                    (s.col[i] - map.col[i]).abs() < 1e-4,
                    "({x}, {y}): {} vs {}",
                    s.col[i],
                    map.col[i]
                );
            }
        }
        assert!(
            SmoothConfig {
                radius: 0,
                ..SmoothConfig::default()
            }
            .validate()
            .is_err()
        );
        assert!(
            SmoothConfig {
                max_step_px: f32::NAN,
                ..SmoothConfig::default()
            }
            .validate()
            .is_err()
        );
    }
}
