//! What an ICP run is asked to do: metric, association, outlier handling and stopping rules.

use crate::IcpError;

/// The error that each iteration minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Metric {
    /// Squared distances between corresponding points; each iteration solves it in closed form
    /// (weighted Kabsch/Horn by SVD of the 3x3 cross-covariance). Needs no normals.
    PointToPoint,
    /// Squared distances of the source points to the tangent planes of their target points,
    /// linearised in the pose and solved as a 6x6 system (Chen & Medioni). Needs target normals.
    /// The default: fast, and accurate on smooth scanned surfaces.
    #[default]
    PointToPlane,
    /// Generalized ICP, plane-to-plane (Segal, Haehnel & Thrun 2009): each point is a Gaussian
    /// flattened along its normal (variances `epsilon, 1, 1`), the residual is weighted by the
    /// inverse of the summed covariances, Gauss-Newton on the pose. Needs normals on both sides.
    Generalized,
}

impl Metric {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Self::PointToPoint => "point-to-point",
            Self::PointToPlane => "point-to-plane",
            Self::Generalized => "generalized ICP",
        }
    }
}

/// How each source point finds its target point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Association {
    /// The closest target point (k-d tree). The default.
    #[default]
    ClosestPoint,
    /// Projective data association for an organised target: project the source point into the
    /// target camera's pixel grid and take the closest 3-D point among the pixels within
    /// `window` pixels (Chebyshev) of where it lands. No search tree, so the fastest.
    Projective {
        /// Search radius in pixels around the projected pixel (0 = that pixel only).
        window: usize,
    },
    /// Normal shooting: follow the source point's normal line to where it meets the target
    /// surface (two steps of intersecting the line with the tangent plane of the closest target
    /// point). Needs normals on both sides; falls back to the closest point where the line
    /// grazes the surface.
    NormalShooting,
}

/// A robust kernel: the weight of a correspondence as a function of its residual `r` (mm), for
/// iteratively reweighted least squares. The residual is the plane distance for
/// point-to-plane, the Euclidean distance otherwise.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum RobustKernel {
    /// Plain least squares: every correspondence weighs 1. The default.
    #[default]
    L2,
    /// Huber: weight 1 up to `k`, then `k / |r|` (quadratic near zero, linear in the tails).
    Huber {
        /// Threshold in mm, > 0; about 1.5 times the noise of the residuals.
        k: f64,
    },
    /// Tukey's biweight: `(1 - (r / c)^2)^2` inside `c`, 0 outside (ignores gross outliers).
    Tukey {
        /// Cut-off in mm, > 0; about 4.7 times the noise of the residuals.
        c: f64,
    },
}

impl RobustKernel {
    /// The IRLS weight of a residual `r` (mm).
    ///
    /// ```
    /// use sl_icp::RobustKernel;
    /// assert_eq!(RobustKernel::L2.weight(10.0), 1.0);
    /// assert_eq!(RobustKernel::Huber { k: 1.0 }.weight(0.5), 1.0);
    /// assert_eq!(RobustKernel::Huber { k: 1.0 }.weight(-4.0), 0.25);
    /// assert_eq!(RobustKernel::Tukey { c: 2.0 }.weight(1.0), 0.5625);
    /// assert_eq!(RobustKernel::Tukey { c: 2.0 }.weight(3.0), 0.0);
    /// ```
    #[inline]
    pub fn weight(&self, r: f64) -> f64 {
        let a = r.abs();
        match *self {
            Self::L2 => 1.0,
            Self::Huber { k } => {
                if a <= k {
                    1.0
                } else {
                    k / a
                }
            }
            Self::Tukey { c } => {
                if a < c {
                    let u = 1.0 - (a / c) * (a / c);
                    u * u
                } else {
                    0.0
                }
            }
        }
    }

    fn check(&self) -> Result<(), IcpError> {
        let (name, v) = match *self {
            Self::L2 => return Ok(()),
            Self::Huber { k } => ("kernel.k", k),
            Self::Tukey { c } => ("kernel.c", c),
        };
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(IcpError::invalid(name, v, "must be finite and > 0 (mm)"))
        }
    }
}

/// Trimmed ICP (Chetverikov, Svirko, Stepanov & Krsek 2002): only the best fraction of the
/// correspondences (smallest distances) enters each iteration, so parts of the source that the
/// target never saw do not pull the pose.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Trimming {
    /// Keep every correspondence within the maximum distance. The default.
    #[default]
    None,
    /// Keep the `overlap * N` closest correspondences, `N` the number of source points.
    Fixed {
        /// Expected overlap of the source with the target, in (0, 1].
        overlap: f64,
    },
    /// Estimate the overlap at each iteration as `TrICP` does: the `ξ` in
    /// `[min_overlap, 1]` that minimises `e(ξ) / ξ^3`, `e(ξ)` the mean squared distance of the
    /// `ξN` closest correspondences (λ = 2 in the paper's `ξ^-(1+λ)`).
    Auto {
        /// Lower bound of the overlap search, in (0, 1].
        min_overlap: f64,
    },
}

impl Trimming {
    fn check(&self) -> Result<(), IcpError> {
        let (name, v) = match *self {
            Self::None => return Ok(()),
            Self::Fixed { overlap } => ("trimming.overlap", overlap),
            Self::Auto { min_overlap } => ("trimming.min_overlap", min_overlap),
        };
        if v > 0.0 && v <= 1.0 {
            Ok(())
        } else {
            Err(IcpError::invalid(name, v, "must be in (0, 1]"))
        }
    }
}

/// Settings of [`register`](crate::register) and [`Icp`](crate::Icp). Lengths in mm, angles in
/// radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpConfig {
    /// The error minimised. Default [`Metric::PointToPlane`].
    pub metric: Metric,
    /// How correspondences are found. Default [`Association::ClosestPoint`].
    pub association: Association,
    /// Correspondences farther apart than this (mm) are ignored. Default 5 mm: several times
    /// the 0.5–1 mm point spacing of a downsampled scan, and larger than the few-mm error of
    /// poses from a calibrated turntable, yet small enough to keep non-overlapping parts out.
    pub max_correspondence_distance: f64,
    /// Robust kernel of the residuals. Default [`RobustKernel::L2`].
    pub kernel: RobustKernel,
    /// Trimming of the worst correspondences. Default [`Trimming::None`].
    pub trimming: Trimming,
    /// Maximum number of iterations. Default 50: point-to-plane and generalized ICP converge
    /// in 5 to 15 from a few degrees; point-to-point needs more.
    pub max_iterations: usize,
    /// Converged when one iteration (or the last two together, which catches a pose hopping
    /// between two sets of correspondences) rotates by less than this (rad) *and* moves the
    /// source centroid by less than `translation_tolerance`. Default 1e-5 rad (0.0006°, far
    /// below the 0.1° accuracy of a good registration).
    pub rotation_tolerance: f64,
    /// See `rotation_tolerance`; mm. Default 1e-3 mm (1 µm, 1/50 of the 0.05 mm accuracy
    /// of a good registration).
    pub translation_tolerance: f64,
    /// Also converged when the mean squared distance changes by less than this fraction between
    /// two iterations. Default 1e-7 (tight: it only stops iterations that no longer move).
    pub relative_error_tolerance: f64,
    /// Variance of a point's Gaussian along its normal for generalized ICP, relative to the
    /// unit variances along the surface. Default 1e-3, as Segal et al., Open3D and `small_gicp`.
    pub gicp_epsilon: f64,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            metric: Metric::default(),
            association: Association::default(),
            max_correspondence_distance: 5.0,
            kernel: RobustKernel::default(),
            trimming: Trimming::default(),
            max_iterations: 50,
            rotation_tolerance: 1e-5,
            translation_tolerance: 1e-3,
            relative_error_tolerance: 1e-7,
            gicp_epsilon: 1e-3,
        }
    }
}

impl IcpConfig {
    /// Checks every field, naming the first one out of range.
    ///
    /// # Errors
    /// [`IcpError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), IcpError> {
        let d = self.max_correspondence_distance;
        if d.is_nan() || d <= 0.0 {
            return Err(IcpError::invalid(
                "max_correspondence_distance",
                d,
                "must be > 0 (mm; infinity allowed)",
            ));
        }
        for (name, v) in [
            ("rotation_tolerance", self.rotation_tolerance),
            ("translation_tolerance", self.translation_tolerance),
            ("relative_error_tolerance", self.relative_error_tolerance),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(IcpError::invalid(name, v, "must be finite and >= 0"));
            }
        }
        let e = self.gicp_epsilon;
        if !(e > 0.0 && e <= 1.0) {
            return Err(IcpError::invalid("gicp_epsilon", e, "must be in (0, 1]"));
        }
        self.kernel.check()?;
        self.trimming.check()
    }
}
