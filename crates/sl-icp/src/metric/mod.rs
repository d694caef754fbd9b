//! The error metrics: per-correspondence accumulation into fixed-size sums (no allocation),
//! merged across rayon threads, then one small solve per iteration.

pub(crate) mod generalized;
pub(crate) mod point_to_plane;
pub(crate) mod point_to_point;

use nalgebra::{Matrix6, SymmetricEigen, Vector6};

/// Ratio of the smallest to the largest eigenvalue of a 6x6 normal matrix below which it is
/// called singular: 1e-12 is ~1e4 times the f64 rounding of the sums, so only geometry that
/// truly leaves a motion free (a plane, a sphere, a line) trips it.
const SINGULAR_RATIO: f64 = 1e-12;

/// Solves `H δ = -g` for a symmetric positive (semi-)definite `H`; `None` if it is singular.
pub(crate) fn solve6(h: &Matrix6<f64>, g: &Vector6<f64>) -> Option<Vector6<f64>> {
    let eig = SymmetricEigen::new(*h);
    let max = eig.eigenvalues.max();
    let min = eig.eigenvalues.min();
    if max.is_nan() || max <= 0.0 || min <= max * SINGULAR_RATIO {
        return None;
    }
    let delta = -h.cholesky()?.solve(g);
    delta.iter().all(|v| v.is_finite()).then_some(delta)
}
