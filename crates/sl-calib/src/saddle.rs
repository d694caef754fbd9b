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

/// Refines `start` (pixels) to the saddle point of `img` with a square window of half-width
/// `radius` (px). Returns `None` when the fit is not a saddle (determinant of the Hessian
/// not negative), diverges, or leaves the window it started in.
pub(crate) fn refine_saddle(
    img: &GreyF32,
    start: Point2<f64>,
    radius: usize,
) -> Option<Point2<f64>> {
    let r = radius as isize;
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
    for _ in 0..MAX_ITERATIONS {
        let (mut sxx_i, mut syy_i, mut s_i, mut sxy_i, mut sx_i, mut sy_i) =
            (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for j in -r..=r {
            let y = j as f64;
            for i in -r..=r {
                let x = i as f64;
                let v = img.sample(p.x + x, p.y + y);
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
        let step = h.try_inverse()? * -Vector2::new(d, e);
        if !step.iter().all(|s| s.is_finite()) || step.norm() > MAX_STEP_PX {
            return None;
        }
        p += step;
        if (p - start).norm() > radius as f64 {
            return None;
        }
        if step.norm() < CONVERGED_STEP_PX {
            return Some(p);
        }
    }
    Some(p)
}
