//! Sub-pixel refinement of checkerboard corners by saddle-point fitting.
//!
//! Around an X-junction of two straight edges the image is centrally symmetric: opposite
//! sectors have the same colour, so `I(c + d) = I(c - d)`, and any blur keeps that symmetry.
//! A quadratic `a x² + b xy + c y² + d x + e y + f` fitted by least squares on a window
//! *resampled symmetrically around the current estimate* has `d = e = 0` exactly when the
//! estimate is the junction (odd moments of an even function vanish); elsewhere its stationary
//! point is the Newton step towards it. Iterating therefore converges to the junction without
//! the drift of gradient-based refiners whose window reaches the neighbouring corners.

use nalgebra::{Matrix2, Point2, Vector2};

use crate::grey::GreyF32;

/// Iterations of the resample-and-fit loop; convergence is usually reached in 3–4.
const MAX_ITERATIONS: usize = 12;

/// Step (px) below which the estimate has converged: far below the 0.05 px target.
const CONVERGED_STEP_PX: f64 = 1e-3;

/// Largest step (px) accepted from one fit: a larger one means the window does not see a
/// saddle and the fit is extrapolating.
const MAX_STEP_PX: f64 = 1.5;

/// The converged saddle point and the second-order part `a x² + b xy + c y²` of the last
/// quadratic fitted around it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SaddleFit {
    /// The saddle point (px).
    pub(crate) point: Point2<f64>,
    /// Coefficient of `x²`.
    pub(crate) a: f64,
    /// Coefficient of `xy`.
    pub(crate) b: f64,
    /// Coefficient of `y²`.
    pub(crate) c: f64,
}

impl SaddleFit {
    /// The normals `(α₁, α₂)` (radians) of the quadratic's two zero lines
    /// `a x² + b xy + c y² = 0`: near a blurred X-junction of two edges, `I − I(c)` is about
    /// `k · d₁ · d₂` (product of the distances to the edges), so these are the edges.
    /// `None` when the quadratic is not a saddle.
    pub(crate) fn edge_normals(&self) -> Option<(f64, f64)> {
        // Along the direction θ: a cos²θ + b cosθ sinθ + c sin²θ
        //   = (a + c)/2 + R cos(2θ − φ), R cos φ = (a − c)/2, R sin φ = b/2.
        let (half_diff, half_b) = (0.5 * (self.a - self.c), 0.5 * self.b);
        let r = half_diff.hypot(half_b);
        if r <= 0.0 {
            return None;
        }
        let cos = -0.5 * (self.a + self.c) / r;
        if !(-1.0..=1.0).contains(&cos) {
            return None;
        }
        let phi = half_b.atan2(half_diff);
        let spread = cos.acos();
        // Directions θ = (φ ± spread) / 2; the normals are a quarter turn further.
        let quarter = std::f64::consts::FRAC_PI_2;
        Some((
            0.5 * (phi + spread) + quarter,
            0.5 * (phi - spread) + quarter,
        ))
    }
}

/// Largest step (samples) of the coarse fit: its window is 4 samples wide each side, and a
/// step of half of it is still inside what the fit has seen.
const COARSE_MAX_STEP: f64 = 2.5;

/// Refines `start` (pixels) to the saddle point of `img` with a square window of half-width
/// `radius` (px). Returns `None` when the fit is not a saddle (determinant of the Hessian
/// not negative), diverges, or leaves the window it started in.
pub(crate) fn refine_saddle(img: &GreyF32, start: Point2<f64>, radius: usize) -> Option<SaddleFit> {
    saddle_fit(img, start, radius, 1.0)
}

/// [`refine_saddle`] on a coarse grid: samples `spacing` px apart, so the window is
/// `spacing · radius` px wide. The start of the fine refinement when the grid point is too
/// far off for it (a strong light ripple can move the detector's saddle-response maximum by
/// a tenth of a big square).
pub(crate) fn refine_saddle_coarse(
    img: &GreyF32,
    start: Point2<f64>,
    radius: usize,
    spacing: f64,
) -> Option<SaddleFit> {
    saddle_fit(img, start, radius, spacing)
}

fn saddle_fit(img: &GreyF32, start: Point2<f64>, radius: usize, spacing: f64) -> Option<SaddleFit> {
    let r = radius as isize;
    // Each coarse sample averages a box of `spacing` px (else a fine ripple aliases).
    let taps = (spacing.round() as usize).max(1);
    // Least-squares normal equations of the quadratic on the symmetric grid: with offsets
    // symmetric about 0 the odd moments vanish, so the system splits into
    // {a, c, f} (even) and {b}, {d}, {e} (odd), each solved in closed form.
    let n = (2 * r + 1) as f64;
    let mut s2 = 0.0; // Σ x² over one axis
    let mut s4 = 0.0; // Σ x⁴ over one axis
    for i in -r..=r {
        let x = i as f64;
        s2 += x * x;
        s4 += x * x * x * x;
    }
    // Moments over the 2-D window.
    let m_xx = s2 * n; // Σ x²
    let m_xxxx = s4 * n; // Σ x⁴
    let m_xxyy = s2 * s2; // Σ x² y²
    let count = n * n;
    // Even block: [Σx⁴ Σx²y² Σx²; Σx²y² Σy⁴ Σy²; Σx² Σy² N] (a, c, f).
    let even = nalgebra::Matrix3::new(
        m_xxxx, m_xxyy, m_xx, m_xxyy, m_xxxx, m_xx, m_xx, m_xx, count,
    );
    let even_inv = even.try_inverse()?;
    let mut p = start;
    let mut last = SaddleFit {
        point: p,
        a: 0.0,
        b: 0.0,
        c: 0.0,
    };
    for _ in 0..MAX_ITERATIONS {
        let (mut sxx_i, mut syy_i, mut s_i, mut sxy_i, mut sx_i, mut sy_i) =
            (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for j in -r..=r {
            let y = j as f64;
            for i in -r..=r {
                let x = i as f64;
                let v = box_sample(img, p.x + spacing * x, p.y + spacing * y, taps);
                sxx_i += x * x * v;
                syy_i += y * y * v;
                s_i += v;
                sxy_i += x * y * v;
                sx_i += x * v;
                sy_i += y * v;
            }
        }
        let acf = even_inv * nalgebra::Vector3::new(sxx_i, syy_i, s_i);
        let (a, c) = (acf.x, acf.y);
        let b = sxy_i / m_xxyy;
        let d = sx_i / m_xx;
        let e = sy_i / m_xx;
        // Gradient of the quadratic: [2a b; b 2c] (x, y) + (d, e) = 0.
        let h = Matrix2::new(2.0 * a, b, b, 2.0 * c);
        if h.determinant() >= 0.0 {
            return None;
        }
        // In sample units, then pixels.
        let step = h.try_inverse()? * -Vector2::new(d, e);
        // The coarse fit sees a wider window in samples of several px, and its start may be
        // further off: it may step further (in samples) before the step means extrapolation.
        let max_step = if taps > 1 {
            COARSE_MAX_STEP
        } else {
            MAX_STEP_PX
        };
        if !step.iter().all(|s| s.is_finite()) || step.norm() > max_step {
            return None;
        }
        let step = step * spacing;
        p += step;
        if (p - start).norm() > spacing * radius as f64 {
            return None;
        }
        last = SaddleFit { point: p, a, b, c };
        if step.norm() < CONVERGED_STEP_PX * spacing {
            return Some(last);
        }
    }
    Some(last)
}

/// Mean of `taps × taps` bilinear samples 1 px apart centred on `(x, y)`: one sample when
/// `taps` is 1.
fn box_sample(img: &GreyF32, x: f64, y: f64, taps: usize) -> f64 {
    if taps <= 1 {
        return img.sample(x, y);
    }
    let half = 0.5 * (taps - 1) as f64;
    let mut sum = 0.0;
    for j in 0..taps {
        for i in 0..taps {
            sum += img.sample(x + i as f64 - half, y + j as f64 - half);
        }
    }
    sum / (taps * taps) as f64
}
