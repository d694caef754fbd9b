//! OpenCV's lens distortion: the 5-coefficient model and the 8-coefficient rational model,
//! with analytic Jacobians and Newton undistortion.

use nalgebra::{Matrix2, Point2, SMatrix, Vector2};
use serde::{Deserialize, Serialize};

use crate::CameraError;
use crate::injective::injective_radius;
use crate::monotonic::{RADIUS_CAP, monotonic_limit_squared};

/// Names of the distortion coefficients in OpenCV's order, which is the order of
/// [`Distortion::coefficients`] and of the columns of [`DistortionJacobians::d_coefficients`].
pub const DISTORTION_PARAMETERS: [&str; 8] = ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"];

/// Newton iterations allowed in [`Distortion::undistort`]. Started from the radial solution,
/// realistic lenses converge in 2–4; the rest is headroom for strong tangential terms.
const MAX_NEWTON_ITERATIONS: usize = 30;

/// Step halvings that keep a Newton iterate inside the valid disc: 2⁻⁶⁰ of a step is below
/// f64 resolution of any coordinate.
const MAX_STEP_HALVINGS: usize = 60;

/// Iterations of the safeguarded 1-D solve for the radial start of the Newton iteration:
/// bisection alone halves the bracket each time, so 200 reach f64 resolution from any
/// bracket inside the search range.
const MAX_RADIAL_ITERATIONS: usize = 200;

/// Accepted residual of undistortion in normalised distorted units, relative to
/// `max(1, |distorted point|)`. Newton converges to a few ulps (≈1e-16); 1e-13 leaves room
/// for rounding in the distortion polynomials of strong lenses and is still 1e-10 px at a
/// focal length of 1000 px, i.e. far below the 1e-9 px round-trip target.
const UNDISTORT_TOLERANCE: f64 = 1e-13;

/// Residual (relative to `max(1, |distorted point|)`) at which Newton stops at once: a few
/// ulps, the rounding level of evaluating the distortion.
const ROUNDING_RESIDUAL: f64 = 4.0 * f64::EPSILON;

/// Relative step at which the radial start stops: Newton's convergence is quadratic, so the
/// radius is then exact to ~1e-18 relative; the 2-D iteration finishes the job anyway.
const RADIAL_START_TOLERANCE: f64 = 1e-9;

/// Which of OpenCV's distortion models a [`Distortion`] uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DistortionModel {
    /// No distortion (an empty OpenCV coefficient vector).
    None,
    /// OpenCV's default 5-coefficient model `k1 k2 p1 p2 k3` (ROS calls it `plumb_bob`);
    /// a 4-coefficient vector is this model with `k3 = 0`.
    PlumbBob,
    /// OpenCV's rational model (`CALIB_RATIONAL_MODEL`): `k1 k2 p1 p2 k3 k4 k5 k6`.
    Rational,
}

impl DistortionModel {
    /// Number of OpenCV coefficients the model writes: 0, 5 or 8.
    pub fn coefficient_count(self) -> usize {
        match self {
            Self::None => 0,
            Self::PlumbBob => 5,
            Self::Rational => 8,
        }
    }
}

impl std::fmt::Display for DistortionModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::None => "none",
            Self::PlumbBob => "OpenCV 5-coefficient (plumb bob)",
            Self::Rational => "OpenCV 8-coefficient rational",
        })
    }
}

/// Lens distortion exactly as OpenCV defines it (`cv::projectPoints`), acting on normalised
/// coordinates `(x, y) = (X/Z, Y/Z)`:
///
/// ```text
/// s  = x² + y²
/// f  = (1 + k1 s + k2 s² + k3 s³) / (1 + k4 s + k5 s² + k6 s³)
/// xd = x f + 2 p1 x y + p2 (s + 2 x²)
/// yd = y f + p1 (s + 2 y²) + 2 p2 x y
/// ```
///
/// The 5-coefficient model is the rational one with `k4 = k5 = k6 = 0`, exactly as OpenCV
/// evaluates it.
///
/// A `Distortion` also knows where it can be inverted. Its *valid region* is the disc of
/// normalised radius [`Distortion::max_radius`] on which the map is proven one-to-one: the
/// radial part `r·f(r²)` is strictly increasing there with a positive denominator
/// (certified by Bernstein bounds), and the tangential terms provably neither fold the map
/// (Jacobian determinant > 0) nor make two points share an image (see the proof in the
/// source, `injective.rs`). Projection refuses points outside the disc and undistortion
/// never returns them, so a pixel whose preimage is ambiguous or absent yields no ray
/// rather than a wrong one.
///
/// The value is immutable and validated: build it with [`Distortion::from_opencv`],
/// [`Distortion::new`] or [`Distortion::none`].
///
/// ```
/// use sl_camera::{Distortion, DistortionModel};
/// use nalgebra::Point2;
/// let d = Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1])?;
/// assert_eq!(d.model(), DistortionModel::PlumbBob);
/// let p = Point2::new(0.2, -0.1);
/// let back = d.undistort(&d.distort(&p)).unwrap();
/// assert!((back - p).norm() < 1e-14);
/// assert_eq!(d.to_opencv_vec(), vec![0.5466, -20.20, -0.02203, 0.008259, 211.1]);
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "DistortionRepr", into = "DistortionRepr")]
pub struct Distortion {
    model: DistortionModel,
    /// `k1 k2 p1 p2 k3 k4 k5 k6`, zeros where the model has no coefficient.
    k: [f64; 8],
    /// Squared normalised radius of the valid region (may be infinite).
    max_radius_sq: f64,
    /// `max_radius · f(max_radius²)`: the largest distorted radius of the valid region
    /// (infinite when unknown, e.g. at a pole of the rational model).
    max_distorted_radius: f64,
}

/// Value and analytic derivatives of the distortion at one normalised point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistortionJacobians {
    /// The distorted normalised point `(xd, yd)`.
    pub point: Point2<f64>,
    /// `∂(xd, yd) / ∂(x, y)`.
    pub d_point: Matrix2<f64>,
    /// `∂(xd, yd) / ∂(k1, k2, p1, p2, k3, k4, k5, k6)` (OpenCV order). Columns of coefficients
    /// the model does not use are the derivatives the rational model has at the current
    /// values (with `k4 = k5 = k6 = 0` for the 5-coefficient model), so a calibration can pick
    /// the columns it estimates.
    pub d_coefficients: SMatrix<f64, 2, 8>,
}

impl Default for Distortion {
    fn default() -> Self {
        Self::none()
    }
}

impl Distortion {
    /// No distortion.
    pub fn none() -> Self {
        Self {
            model: DistortionModel::None,
            k: [0.0; 8],
            max_radius_sq: f64::INFINITY,
            max_distorted_radius: f64::INFINITY,
        }
    }

    /// A distortion of the given model from the 8 coefficients in OpenCV order
    /// `k1 k2 p1 p2 k3 k4 k5 k6`.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] if a coefficient is not finite, or is non-zero where
    /// the model has no such coefficient (`k4..k6` for [`DistortionModel::PlumbBob`], any for
    /// [`DistortionModel::None`]).
    pub fn new(model: DistortionModel, coefficients: [f64; 8]) -> Result<Self, CameraError> {
        let used = model.coefficient_count();
        for (i, (&c, name)) in coefficients.iter().zip(DISTORTION_PARAMETERS).enumerate() {
            if !c.is_finite() {
                return Err(CameraError::invalid(
                    format!("distortion.{name}"),
                    format!("must be finite, found {c}"),
                ));
            }
            if i >= used && c != 0.0 {
                return Err(CameraError::invalid(
                    format!("distortion.{name}"),
                    format!("the {model} model has no `{name}`, found {c}"),
                ));
            }
        }
        if model == DistortionModel::None {
            return Ok(Self::none());
        }
        let radial_sq = monotonic_limit_squared(&coefficients);
        let max_radius_sq = if coefficients[2] == 0.0 && coefficients[3] == 0.0 {
            radial_sq
        } else {
            let r_hi = if radial_sq.is_finite() {
                radial_sq.sqrt()
            } else {
                RADIUS_CAP
            };
            let r = injective_radius(&coefficients, r_hi);
            (r * r).min(radial_sq)
        };
        let mut d = Self {
            model,
            k: coefficients,
            max_radius_sq,
            max_distorted_radius: f64::INFINITY,
        };
        if max_radius_sq.is_finite() {
            let (f, _) = d.radial_factor(max_radius_sq);
            let rd = max_radius_sq.sqrt() * f;
            // At a pole of the rational model the value is meaningless (huge, or negative by
            // rounding): then the shortcut in `radial_start` is simply not used.
            if rd.is_finite() && rd > 0.0 {
                d.max_distorted_radius = rd;
            }
        }
        Ok(d)
    }

    /// Reads an OpenCV coefficient vector: 0 values (no distortion), 4 (`k1 k2 p1 p2`, read as
    /// the 5-coefficient model with `k3 = 0`), 5 (`k1 k2 p1 p2 k3`) or 8 (rational). Vectors of
    /// 12 or 14 values (thin-prism and tilt terms) are accepted only when those extra terms are
    /// all zero, as OpenCV pads them.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] for another length, non-zero thin-prism or tilt
    /// terms, or non-finite values.
    pub fn from_opencv(coefficients: &[f64]) -> Result<Self, CameraError> {
        let mut k = [0.0; 8];
        let model = match coefficients.len() {
            0 => DistortionModel::None,
            4 | 5 => DistortionModel::PlumbBob,
            8 | 12 | 14 => DistortionModel::Rational,
            n => {
                return Err(CameraError::invalid(
                    "distortion",
                    format!("expected 0, 4, 5 or 8 OpenCV coefficients, found {n}"),
                ));
            }
        };
        let (head, extra) = coefficients.split_at(coefficients.len().min(8));
        k[..head.len()].copy_from_slice(head);
        const EXTRA: [&str; 6] = ["s1", "s2", "s3", "s4", "tau_x", "tau_y"];
        for (&c, name) in extra.iter().zip(EXTRA) {
            if c != 0.0 {
                return Err(CameraError::invalid(
                    format!("distortion.{name}"),
                    format!(
                        "thin-prism and tilted-sensor terms are not supported, found {name} = {c}"
                    ),
                ));
            }
        }
        Self::new(model, k)
    }

    /// The coefficients as OpenCV writes them: 0, 5 or 8 values depending on the model.
    pub fn to_opencv_vec(&self) -> Vec<f64> {
        self.k[..self.model.coefficient_count()].to_vec()
    }

    /// The model.
    pub fn model(&self) -> DistortionModel {
        self.model
    }

    /// All 8 coefficients in OpenCV order `k1 k2 p1 p2 k3 k4 k5 k6` (zeros where the model
    /// has none).
    pub fn coefficients(&self) -> [f64; 8] {
        self.k
    }

    /// Radial coefficient `k1`.
    pub fn k1(&self) -> f64 {
        self.k[0]
    }
    /// Radial coefficient `k2`.
    pub fn k2(&self) -> f64 {
        self.k[1]
    }
    /// Tangential coefficient `p1`.
    pub fn p1(&self) -> f64 {
        self.k[2]
    }
    /// Tangential coefficient `p2`.
    pub fn p2(&self) -> f64 {
        self.k[3]
    }
    /// Radial coefficient `k3`.
    pub fn k3(&self) -> f64 {
        self.k[4]
    }
    /// Rational denominator coefficient `k4`.
    pub fn k4(&self) -> f64 {
        self.k[5]
    }
    /// Rational denominator coefficient `k5`.
    pub fn k5(&self) -> f64 {
        self.k[6]
    }
    /// Rational denominator coefficient `k6`.
    pub fn k6(&self) -> f64 {
        self.k[7]
    }

    /// Radius (normalised, undistorted) of the valid region: the radial distortion is
    /// strictly increasing with a positive denominator, and the whole map one-to-one, on the
    /// disc below it. `f64::INFINITY` without any distortion. The search stops at r = 100
    /// (89.4° off-axis), so a gentle lens reports 100. The value is conservative: never
    /// beyond the true limit.
    pub fn max_radius(&self) -> f64 {
        self.max_radius_sq.sqrt()
    }

    /// Whether the normalised point `(x, y)` lies in the valid disc (radius below
    /// [`Distortion::max_radius`]; `false` for NaN). Branch-free form of
    /// [`Distortion::is_valid_at`] for hot loops: the Jacobian determinant is positive on the
    /// whole disc by construction, so the radius alone decides.
    #[inline(always)]
    pub fn in_valid_disc(&self, x: f64, y: f64) -> bool {
        x * x + y * y < self.max_radius_sq
    }

    /// Radial factor `f(s)` and its derivative `df/ds`.
    #[inline(always)]
    fn radial_factor(&self, s: f64) -> (f64, f64) {
        let [k1, k2, _, _, k3, k4, k5, k6] = self.k;
        let n = 1.0 + s * (k1 + s * (k2 + s * k3));
        let d = 1.0 + s * (k4 + s * (k5 + s * k6));
        let dn = k1 + s * (2.0 * k2 + 3.0 * k3 * s);
        let dd = k4 + s * (2.0 * k5 + 3.0 * k6 * s);
        // One division for both (the hot loops of triangulation evaluate this per pixel).
        let inv = 1.0 / d;
        let f = n * inv;
        (f, (dn - f * dd) * inv)
    }

    /// Distorts a normalised point (the formula above; no validity check — see
    /// [`Distortion::is_valid_at`]).
    #[inline]
    pub fn distort(&self, p: &Point2<f64>) -> Point2<f64> {
        if self.model == DistortionModel::None {
            return *p;
        }
        let [xd, yd] = self.distort_xy(p.x, p.y);
        Point2::new(xd, yd)
    }

    /// [`Distortion::distort`] on plain numbers, without the branch on the model (with no
    /// distortion every coefficient is zero and the formula is the identity for finite
    /// input), for hot loops that the compiler should vectorise.
    #[inline(always)]
    pub fn distort_xy(&self, x: f64, y: f64) -> [f64; 2] {
        let s = x * x + y * y;
        let (f, _) = self.radial_factor(s);
        let [_, _, p1, p2, ..] = self.k;
        [
            x * f + 2.0 * p1 * x * y + p2 * (s + 2.0 * x * x),
            y * f + p1 * (s + 2.0 * y * y) + 2.0 * p2 * x * y,
        ]
    }

    /// The distorted point `[xd, yd]` and its Jacobian `[[∂xd/∂x, ∂xd/∂y], [∂yd/∂x, ∂yd/∂y]]`
    /// on plain numbers, branch-free (see [`Distortion::distort_xy`]): the one evaluation of
    /// the formula and its point derivatives that every other path of this crate uses.
    #[inline(always)]
    pub fn distort_xy_with_jacobian(&self, x: f64, y: f64) -> ([f64; 2], [[f64; 2]; 2]) {
        let s = x * x + y * y;
        let (f, fs) = self.radial_factor(s);
        let [_, _, p1, p2, ..] = self.k;
        let xd = x * f + 2.0 * p1 * x * y + p2 * (s + 2.0 * x * x);
        let yd = y * f + p1 * (s + 2.0 * y * y) + 2.0 * p2 * x * y;
        let cross = 2.0 * x * y * fs + 2.0 * p1 * x + 2.0 * p2 * y;
        (
            [xd, yd],
            [
                [f + 2.0 * x * x * fs + 2.0 * p1 * y + 6.0 * p2 * x, cross],
                [cross, f + 2.0 * y * y * fs + 6.0 * p1 * y + 2.0 * p2 * x],
            ],
        )
    }

    /// Distorted point and its Jacobian with respect to the point.
    #[inline]
    fn distort_with_point_jacobian(&self, p: &Point2<f64>) -> (Point2<f64>, Matrix2<f64>) {
        let ([xd, yd], [[a, b], [c, d]]) = self.distort_xy_with_jacobian(p.x, p.y);
        (Point2::new(xd, yd), Matrix2::new(a, b, c, d))
    }

    /// Distorted point with its analytic derivatives with respect to the point and to the
    /// 8 coefficients.
    pub fn distort_with_jacobians(&self, p: &Point2<f64>) -> DistortionJacobians {
        let (point, d_point) = self.distort_with_point_jacobian(p);
        let (x, y) = (p.x, p.y);
        let s = x * x + y * y;
        let [_, _, _, _, _, k4, k5, k6] = self.k;
        let d = 1.0 + s * (k4 + s * (k5 + s * k6));
        let (f, _) = self.radial_factor(s);
        // ∂f/∂k_i = s^i / D for the numerator, −f s^i / D for the denominator.
        let (s1, s2, s3) = (s / d, s * s / d, s * s * s / d);
        let d_coefficients = SMatrix::<f64, 2, 8>::from_columns(&[
            Vector2::new(x * s1, y * s1),
            Vector2::new(x * s2, y * s2),
            Vector2::new(2.0 * x * y, s + 2.0 * y * y),
            Vector2::new(s + 2.0 * x * x, 2.0 * x * y),
            Vector2::new(x * s3, y * s3),
            Vector2::new(-x * f * s1, -y * f * s1),
            Vector2::new(-x * f * s2, -y * f * s2),
            Vector2::new(-x * f * s3, -y * f * s3),
        ]);
        DistortionJacobians {
            point,
            d_point,
            d_coefficients,
        }
    }

    /// Whether a normalised (undistorted) point is in the valid region: radius below
    /// [`Distortion::max_radius`] (the Jacobian determinant, positive there by construction,
    /// is checked as well).
    #[inline]
    pub fn is_valid_at(&self, p: &Point2<f64>) -> bool {
        if self.model == DistortionModel::None {
            return p.x.is_finite() && p.y.is_finite();
        }
        let s = p.x * p.x + p.y * p.y;
        if s.is_nan() || s >= self.max_radius_sq {
            return false;
        }
        let (_, j) = self.distort_with_point_jacobian(p);
        j.determinant() > 0.0
    }

    /// `distort(p)` if `p` is in the valid region (one evaluation for both).
    #[inline]
    pub(crate) fn distort_if_valid(&self, p: &Point2<f64>) -> Option<Point2<f64>> {
        if self.model == DistortionModel::None {
            return (p.x.is_finite() && p.y.is_finite()).then_some(*p);
        }
        let s = p.x * p.x + p.y * p.y;
        if s.is_nan() || s >= self.max_radius_sq {
            return None;
        }
        let (q, j) = self.distort_with_point_jacobian(p);
        (j.determinant() > 0.0).then_some(q)
    }

    /// Undistorts a normalised point: the normalised point `p` of the valid region with
    /// `distort(p) = pd`, by Newton's method with the analytic Jacobian, started from the
    /// exact solution of the radial part. `None` if `pd` is not the image of a point of the
    /// valid region (or is not finite).
    pub fn undistort(&self, pd: &Point2<f64>) -> Option<Point2<f64>> {
        if self.model == DistortionModel::None {
            return (pd.x.is_finite() && pd.y.is_finite()).then_some(*pd);
        }
        let start = self.radial_start(pd)?;
        self.newton(pd, start)
    }

    /// Like [`Distortion::undistort`] but tries Newton from `guess` (e.g. the solution at a
    /// neighbouring pixel) first, falling back to the radial start if that fails. The answer
    /// passes the same convergence and validity checks, so it is the same point (to a few
    /// ulps); a guess within ~1e-6 of it saves the radial start and most Newton steps.
    pub fn undistort_from(&self, pd: &Point2<f64>, guess: &Point2<f64>) -> Option<Point2<f64>> {
        if self.model == DistortionModel::None {
            return self.undistort(pd);
        }
        self.newton(pd, *guess).or_else(|| self.undistort(pd))
    }

    /// Start of the Newton iteration: the point on the ray through `pd` whose radius solves
    /// the radial equation `r f(r²) = |pd|` (safeguarded Newton in the monotonic range).
    fn radial_start(&self, pd: &Point2<f64>) -> Option<Point2<f64>> {
        let rd = pd.coords.norm();
        if !rd.is_finite() {
            return None;
        }
        if rd == 0.0 {
            return Some(Point2::origin());
        }
        if self.max_radius_sq.is_infinite() {
            return Some(*pd); // radial part is the identity
        }
        let r_max = self.max_radius_sq.sqrt();
        if rd >= self.max_distorted_radius {
            // Beyond the radial range; tangential terms might still bring it back. Let
            // Newton try from the edge and the validity check decide.
            return Some(pd * (r_max / rd));
        }
        let (mut lo, mut hi) = (0.0, r_max);
        let mut r = rd.min(0.5 * r_max);
        for _ in 0..MAX_RADIAL_ITERATIONS {
            let s = r * r;
            let (f, fs) = self.radial_factor(s);
            let h = r * f - rd;
            if h > 0.0 {
                hi = r;
            } else {
                lo = r;
            }
            let dh = f + 2.0 * s * fs;
            let mut next = r - h / dh;
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            if (next - r).abs() <= RADIAL_START_TOLERANCE * r {
                r = next;
                break;
            }
            r = next;
        }
        Some(pd * (r / rd))
    }

    /// Newton's method on `distort(p) − pd = 0` from `start`; `Some` only if it converges to a
    /// point of the valid region.
    fn newton(&self, pd: &Point2<f64>, start: Point2<f64>) -> Option<Point2<f64>> {
        let scale = pd.coords.norm().max(1.0);
        let tol = UNDISTORT_TOLERANCE * scale;
        let floor = ROUNDING_RESIDUAL * scale;
        let mut p = start;
        let mut previous = f64::INFINITY;
        for _ in 0..MAX_NEWTON_ITERATIONS {
            let (q, j) = self.distort_with_point_jacobian(&p);
            let r = q - pd;
            let rn = r.norm();
            if !rn.is_finite() {
                return None;
            }
            let det = j.m11 * j.m22 - j.m12 * j.m21;
            if rn <= tol && (rn <= floor || rn > 0.25 * previous) {
                // Converged: at rounding level, or no longer improving quadratically. Accept
                // only inside the valid region (same test as `is_valid_at`, reusing `j`).
                let s = p.x * p.x + p.y * p.y;
                return (det > 0.0 && s < self.max_radius_sq).then_some(p);
            }
            if det.is_nan() || det <= 0.0 {
                return None;
            }
            let mut step = Vector2::new(
                (j.m22 * r.x - j.m12 * r.y) / det,
                (j.m11 * r.y - j.m21 * r.x) / det,
            );
            // Keep the iterate inside the valid disc (near its edge a full step can leave
            // it): halve the step until it stays in.
            for _ in 0..MAX_STEP_HALVINGS {
                let next = p - step;
                if next.x * next.x + next.y * next.y < self.max_radius_sq {
                    break;
                }
                step *= 0.5;
            }
            p -= step;
            previous = rn;
        }
        None
    }
}

/// Serialised form of [`Distortion`] in the JSON calibration file.
#[derive(Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
enum DistortionRepr {
    None,
    PlumbBob {
        k1: f64,
        k2: f64,
        p1: f64,
        p2: f64,
        k3: f64,
    },
    Rational {
        k1: f64,
        k2: f64,
        p1: f64,
        p2: f64,
        k3: f64,
        k4: f64,
        k5: f64,
        k6: f64,
    },
}

impl TryFrom<DistortionRepr> for Distortion {
    type Error = CameraError;
    fn try_from(r: DistortionRepr) -> Result<Self, CameraError> {
        match r {
            DistortionRepr::None => Ok(Self::none()),
            DistortionRepr::PlumbBob { k1, k2, p1, p2, k3 } => Self::new(
                DistortionModel::PlumbBob,
                [k1, k2, p1, p2, k3, 0.0, 0.0, 0.0],
            ),
            DistortionRepr::Rational {
                k1,
                k2,
                p1,
                p2,
                k3,
                k4,
                k5,
                k6,
            } => Self::new(DistortionModel::Rational, [k1, k2, p1, p2, k3, k4, k5, k6]),
        }
    }
}

impl From<Distortion> for DistortionRepr {
    fn from(d: Distortion) -> Self {
        let [k1, k2, p1, p2, k3, k4, k5, k6] = d.k;
        match d.model {
            DistortionModel::None => Self::None,
            DistortionModel::PlumbBob => Self::PlumbBob { k1, k2, p1, p2, k3 },
            DistortionModel::Rational => Self::Rational {
                k1,
                k2,
                p1,
                p2,
                k3,
                k4,
                k5,
                k6,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn reference() -> Distortion {
        Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1]).unwrap()
    }

    #[test]
    fn opencv_vector_lengths() {
        assert_eq!(
            Distortion::from_opencv(&[]).unwrap().model(),
            DistortionModel::None
        );
        let d4 = Distortion::from_opencv(&[0.1, 0.2, 0.3, 0.4]).unwrap();
        assert_eq!(d4.model(), DistortionModel::PlumbBob);
        assert_eq!(d4.to_opencv_vec(), vec![0.1, 0.2, 0.3, 0.4, 0.0]);
        let d8 = Distortion::from_opencv(&[1., 2., 3., 4., 5., 6., 7., 8.]).unwrap();
        assert_eq!(d8.model(), DistortionModel::Rational);
        assert_eq!(d8.to_opencv_vec(), vec![1., 2., 3., 4., 5., 6., 7., 8.]);
        assert_eq!((d8.k1(), d8.k2(), d8.p1(), d8.p2()), (1., 2., 3., 4.));
        assert_eq!((d8.k3(), d8.k4(), d8.k5(), d8.k6()), (5., 6., 7., 8.));
        for n in [1, 2, 3, 6, 7, 9, 13, 15] {
            let e = Distortion::from_opencv(&vec![0.0; n])
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("found {n}")), "{e}");
        }
        let mut v14 = vec![0.0; 14];
        v14[0] = 0.1;
        assert_eq!(
            Distortion::from_opencv(&v14).unwrap().model(),
            DistortionModel::Rational
        );
        v14[12] = 1e-3;
        let e = Distortion::from_opencv(&v14).unwrap_err().to_string();
        assert!(e.contains("tau_x"), "{e}");
        let e = Distortion::from_opencv(&[0.1, f64::NAN, 0.0, 0.0])
            .unwrap_err()
            .to_string();
        assert!(e.contains("distortion.k2"), "{e}");
        let e = Distortion::new(DistortionModel::PlumbBob, [0., 0., 0., 0., 0., 1., 0., 0.])
            .unwrap_err()
            .to_string();
        assert!(e.contains("k4"), "{e}");
    }

    #[test]
    fn distort_matches_hand_evaluated_formula() {
        // Hand-evaluated OpenCV formula at x = 0.3, y = −0.2 for a rational lens.
        let k = [0.1, -0.05, 0.001, -0.002, 0.01, 0.2, 0.03, -0.004];
        let d = Distortion::new(DistortionModel::Rational, k).unwrap();
        let (x, y) = (0.3_f64, -0.2_f64);
        let s = 0.13_f64;
        let f = (1.0 + 0.1 * s - 0.05 * s * s + 0.01 * s * s * s)
            / (1.0 + 0.2 * s + 0.03 * s * s - 0.004 * s * s * s);
        let xd = x * f + 2.0 * 0.001 * x * y - 0.002 * (s + 2.0 * x * x);
        let yd = y * f + 0.001 * (s + 2.0 * y * y) + 2.0 * -0.002 * x * y;
        let q = d.distort(&Point2::new(x, y));
        // Same operations in a different order: agreement to a few ulps.
        assert_relative_eq!(q.x, xd, max_relative = 1e-14);
        assert_relative_eq!(q.y, yd, max_relative = 1e-14);
    }

    #[test]
    fn jacobians_match_central_differences() {
        let k = [0.1, -0.05, 0.001, -0.002, 0.01, 0.2, 0.03, -0.004];
        let d = Distortion::new(DistortionModel::Rational, k).unwrap();
        let p = Point2::new(0.31, -0.22);
        let j = d.distort_with_jacobians(&p);
        // Central differences: truncation O(h²) ≈ 1e-12, rounding O(ε/h) ≈ 1e-10; 1e-7 is
        // a safe bound while any real mistake in a derivative is O(1).
        let h = 1e-6;
        for c in 0..2 {
            let mut a = p;
            let mut b = p;
            a[c] += h;
            b[c] -= h;
            let fd = (d.distort(&a) - d.distort(&b)) / (2.0 * h);
            assert_relative_eq!(j.d_point.column(c).into_owned(), fd, epsilon = 1e-7);
        }
        for c in 0..8 {
            let mut ka = k;
            let mut kb = k;
            ka[c] += h;
            kb[c] -= h;
            let da = Distortion::new(DistortionModel::Rational, ka).unwrap();
            let db = Distortion::new(DistortionModel::Rational, kb).unwrap();
            let fd = (da.distort(&p) - db.distort(&p)) / (2.0 * h);
            assert_relative_eq!(j.d_coefficients.column(c).into_owned(), fd, epsilon = 1e-7);
        }
    }

    #[test]
    fn undistort_inverts_the_strong_reference_lens() {
        let d = reference();
        for &(x, y) in &[
            (0.0, 0.0),
            (0.3, 0.2),
            (-0.45, -0.26),
            (0.42, -0.25),
            (1e-9, 0.0),
        ] {
            let p = Point2::new(x, y);
            let q = d.undistort(&d.distort(&p)).unwrap();
            // Newton converges to a few ulps of the coordinates (≤ 0.5).
            assert_relative_eq!(q, p, epsilon = 1e-14);
        }
    }

    #[test]
    fn undistort_refuses_beyond_the_fold() {
        // r(1 + k1 r²) with k1 = −0.25 folds at r² = 4/3, distorted radius (2/3)·r_max.
        let d = Distortion::from_opencv(&[-0.25, 0.0, 0.0, 0.0, 0.0]).unwrap();
        let r_max = (4.0_f64 / 3.0).sqrt();
        assert_relative_eq!(d.max_radius(), r_max, max_relative = 1e-12);
        let rd_max = r_max * (1.0 - 0.25 * 4.0 / 3.0);
        assert!(d.undistort(&Point2::new(rd_max * 0.999, 0.0)).is_some());
        assert!(d.undistort(&Point2::new(rd_max * 1.001, 0.0)).is_none());
        assert!(d.undistort(&Point2::new(5.0, 5.0)).is_none());
        // Points beyond the fold distort back inside: they must not be "valid".
        assert!(!d.is_valid_at(&Point2::new(1.5 * r_max, 0.0)));
        assert!(d.undistort(&Point2::new(f64::NAN, 0.0)).is_none());
    }

    #[test]
    fn serde_round_trip() {
        for d in [
            Distortion::none(),
            reference(),
            Distortion::from_opencv(&[1., -2., 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]).unwrap(),
        ] {
            let s = serde_json::to_string(&d).unwrap();
            let back: Distortion = serde_json::from_str(&s).unwrap();
            assert_eq!(back, d);
        }
        let s = r#"{"model":"plumb_bob","k1":0.1,"k2":0,"p1":0,"p2":0,"k3":0}"#;
        let d: Distortion = serde_json::from_str(s).unwrap();
        assert_eq!(d.k1(), 0.1);
        assert!(serde_json::from_str::<Distortion>(r#"{"model":"fisheye"}"#).is_err());
    }
}
