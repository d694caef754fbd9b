//! Levenberg–Marquardt for least-squares problems whose unknowns are shared parameters (a
//! camera's, or a camera's and a projector's) and one 6-DoF pose per board view: the normal
//! equations split into a shared block, one 6×6 block per pose and their coupling, and each
//! damped step is solved through the Schur complement over the poses (the pose blocks are
//! inverted one by one, the shared system by Cholesky); the same split gives the covariance
//! `(JᵀJ)⁻¹` at the minimum. Zhang's calibration (`zhang.rs`) and the joint camera–projector
//! refinement (`stereo.rs`) are the two problems.

use nalgebra::{DMatrix, DVector, Matrix6, Vector3, Vector6};
use sl_camera::RvecTvec;

/// Damping at the start of Levenberg–Marquardt, relative to the diagonal (Marquardt).
pub(crate) const INITIAL_DAMPING: f64 = 1e-3;

/// Damping beyond which LM gives up: the steps are then vanishingly small.
pub(crate) const MAX_DAMPING: f64 = 1e12;

/// Normal equations of one linearisation, split into the camera block, the pose blocks and
/// their coupling.
pub(crate) struct Normal {
    /// `JcᵀJc` of the shared (camera) parameters.
    pub(crate) u: DMatrix<f64>,
    /// `Jcᵀr`.
    pub(crate) g_c: DVector<f64>,
    /// Per view `JpᵀJp` of its pose.
    pub(crate) v: Vec<Matrix6<f64>>,
    /// Per view `JcᵀJp`.
    pub(crate) w: Vec<DMatrix<f64>>,
    /// Per view `Jpᵀr`.
    pub(crate) g_p: Vec<Vector6<f64>>,
    /// Sum of squared residuals at the linearisation point.
    pub(crate) cost: f64,
}

/// Solves the damped normal equations by the Schur complement over the poses; returns the
/// camera step and the pose steps.
fn solve_step(n: &Normal, mu: f64) -> Option<(DVector<f64>, Vec<Vector6<f64>>)> {
    let mut s = n.u.clone();
    for i in 0..s.nrows() {
        s[(i, i)] += mu * n.u[(i, i)].max(1e-12);
    }
    let mut rhs = n.g_c.clone();
    let mut v_inv = Vec::with_capacity(n.v.len());
    for ((v, w), gp) in n.v.iter().zip(&n.w).zip(&n.g_p) {
        let mut vd = *v;
        for i in 0..6 {
            vd[(i, i)] += mu * v[(i, i)].max(1e-12);
        }
        let vi = vd.try_inverse()?;
        let wvi = w * DMatrix::from_column_slice(6, 6, vi.as_slice());
        s -= &wvi * w.transpose();
        rhs -= &wvi * DVector::from_column_slice(gp.as_slice());
        v_inv.push(vi);
    }
    let dc = s.cholesky()?.solve(&rhs);
    let mut dp = Vec::with_capacity(n.v.len());
    for ((vi, w), gp) in v_inv.iter().zip(&n.w).zip(&n.g_p) {
        let wtdc = w.transpose() * &dc;
        let r = gp - Vector6::from_column_slice(wtdc.as_slice());
        dp.push(vi * r);
    }
    Some((dc, dp))
}

/// Every pose moved by its step: `(Δrvec, Δtvec)`.
pub(crate) fn step_poses(poses: &[RvecTvec], dp: &[Vector6<f64>]) -> Vec<RvecTvec> {
    poses
        .iter()
        .zip(dp)
        .map(|(p, d)| {
            RvecTvec::new(
                p.rvec + Vector3::new(d[0], d[1], d[2]),
                p.tvec + Vector3::new(d[3], d[4], d[5]),
            )
        })
        .collect()
}

/// A least-squares problem whose normal equations split into shared parameters and one 6-DoF
/// pose per view ([`Normal`]), minimised by [`levenberg_marquardt`].
pub(crate) trait SchurProblem {
    /// The parameters (and the models derived from them).
    type State;
    /// Normal equations at `s`; `None` when a point does not project.
    fn normal(&self, s: &Self::State) -> Option<Normal>;
    /// Sum of squared residuals at `s`; `None` when a point does not project.
    fn cost(&self, s: &Self::State) -> Option<f64>;
    /// `s` moved by the shared step `dc` and the pose steps `dp`; `None` when the result is
    /// outside the models' valid range.
    fn step(&self, s: &Self::State, dc: &DVector<f64>, dp: &[Vector6<f64>]) -> Option<Self::State>;
}

/// The result of [`levenberg_marquardt`].
pub(crate) struct Minimum<S> {
    pub(crate) state: S,
    /// Normal equations at `state`.
    pub(crate) normal: Normal,
    pub(crate) iterations: usize,
}

/// Levenberg–Marquardt (Marquardt's diagonal damping), each step solved by the Schur
/// complement over the poses; stops when an accepted step lowers the cost by less than
/// `tolerance` (relative) or no damping gives a decrease. `None` when the start does not
/// project.
pub(crate) fn levenberg_marquardt<P: SchurProblem>(
    problem: &P,
    start: P::State,
    max_iterations: usize,
    tolerance: f64,
) -> Option<Minimum<P::State>> {
    let mut state = start;
    let mut normal = problem.normal(&state)?;
    let mut mu = INITIAL_DAMPING;
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        let mut improved = false;
        while mu < MAX_DAMPING {
            let Some((dc, dp)) = solve_step(&normal, mu) else {
                mu *= 10.0;
                continue;
            };
            let trial = problem.step(&state, &dc, &dp);
            let cost = trial.as_ref().and_then(|t| problem.cost(t));
            match (trial, cost) {
                (Some(t), Some(c)) if c <= normal.cost => {
                    let rel = (normal.cost - c) / normal.cost.max(f64::MIN_POSITIVE);
                    normal = problem.normal(&t)?;
                    state = t;
                    mu = (mu / 10.0).max(1e-12);
                    improved = rel > tolerance;
                    break;
                }
                _ => mu *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    Some(Minimum {
        state,
        normal,
        iterations,
    })
}

/// Blocks of `(JᵀJ)⁻¹` (not yet scaled by `σ²`).
pub(crate) struct Covariance {
    /// The shared parameters' block: the inverse of the Schur complement `S`.
    pub(crate) shared: DMatrix<f64>,
    /// The diagonal of each pose's block `V⁻¹ + V⁻¹ Wᵀ S⁻¹ W V⁻¹`.
    pub(crate) pose_diagonals: Vec<Vector6<f64>>,
}

/// `(JᵀJ)⁻¹` by the Schur complement over the poses; `None` when singular.
pub(crate) fn unscaled_covariance(n: &Normal) -> Option<Covariance> {
    let mut s = n.u.clone();
    let mut v_inv = Vec::with_capacity(n.v.len());
    for (v, w) in n.v.iter().zip(&n.w) {
        let vi = v.try_inverse()?;
        let vid = DMatrix::from_column_slice(6, 6, vi.as_slice());
        s -= w * &vid * w.transpose();
        v_inv.push(vid);
    }
    let s_inv = s.try_inverse()?;
    let pose_diagonals = v_inv
        .iter()
        .zip(&n.w)
        .map(|(vi, w)| {
            let a = w * vi;
            let block = vi + a.transpose() * &s_inv * &a;
            Vector6::from_fn(|i, _| block[(i, i)])
        })
        .collect();
    Some(Covariance {
        shared: s_inv,
        pose_diagonals,
    })
}

impl Covariance {
    /// The covariance of the full parameter vector, `σ² T S⁻¹ Tᵀ` without the `σ²`: the shared
    /// block mapped through `t` (column `c` maps free parameter `c` into the full vector).
    pub(crate) fn mapped(&self, t: &DMatrix<f64>) -> DMatrix<f64> {
        t * &self.shared * t.transpose()
    }

    /// The standard deviations of every pose's six parameters (`Δrvec`, `Δtvec`) for the
    /// residual variance `sigma2`.
    pub(crate) fn pose_std_devs(&self, sigma2: f64) -> Vec<[f64; 6]> {
        self.pose_diagonals
            .iter()
            .map(|diag| {
                let mut o = [0.0; 6];
                for (v, d) in o.iter_mut().zip(diag.iter()) {
                    *v = std_dev(sigma2, *d);
                }
                o
            })
            .collect()
    }
}

/// A standard deviation from a residual variance `sigma2` and an unscaled variance (0 where
/// round-off made their product negative).
pub(crate) fn std_dev(sigma2: f64, variance: f64) -> f64 {
    (sigma2 * variance).max(0.0).sqrt()
}
