//! Sub-pixel corners by fitting a blurred junction model (the refiner that runs after
//! [`refine_saddle`](crate::saddle::refine_saddle)).
//!
//! Around an inner corner the board is two straight edges crossing, blurred by the lens. The
//! model, on the raw (unblurred) image in a disc around the corner:
//!
//! ```text
//! I(x) = B(x) + A(x) · E(d₁(x) / s) · E(d₂(x) / s)
//! dₖ(x) = nₖ · (x − c),  nₖ = (cos αₖ, sin αₖ)
//! B(x) = b₀ + b · (x − p₀),  A(x) = a₀ + a · (x − p₀)
//! ```
//!
//! eleven parameters: the corner `c`, the two edge normals `α₁, α₂`, the blur `s`, and an
//! offset `B` and contrast `A` that may each vary linearly across the window (vignetting,
//! uneven light, the ripple of a fringe mean). They are fitted by Levenberg–Marquardt with
//! analytic derivatives, started from the saddle point and the saddle quadratic's asymptotes.
//!
//! Why it beats a saddle or gradient fit on defocused, noisy images: every pixel of the
//! window counts with the weight its edge slope gives it, so the window can be wide (most of
//! the way to the neighbouring corners, where the model still holds: the same two lines run
//! through them) and average far more noise; the offset and contrast gradients absorb the
//! slow light variations that bias a symmetric fit.
//!
//! The edge profile `E(u) = tanh u` instead of the Gaussian edge's `erf`: both are odd, so
//! the mismatch of edge shape is symmetric about the corner and does not move it, and `tanh`
//! is in `std`. (An odd quintic smooth step, cheaper, measured worse on sharp edges:
//! 0.0057 px against 0.0021 px.) Its slope at the edge matches a Gaussian blur of σ when
//! `s ≈ 1.25 σ`.
//!
//! Straight edges, although a lens's distortion bends them across a wide window: a
//! curvature per edge (two more parameters, each edge a parabola through the corner) was
//! measured on the corner harness and lost everywhere, the distorted boards included
//! (`k₁ = −0.3`, fringe mean: RMS 0.029 → 0.038 px; undistorted fringe mean 0.016 → 0.031
//! px): the bow over the window is a few hundredths of a pixel, less than the extra
//! parameters cost in noise.

use nalgebra::{Point2, SMatrix, SVector};

use crate::grey::GreyF32;
use crate::saddle::SaddleFit;

/// Parameters of the model.
const N: usize = 11;

/// The first parameters are the geometry (corner, edge normals, edge width); the others the
/// offset and contrast, linear in the model.
const GEOMETRY: usize = 5;

/// Levenberg–Marquardt iterations at most; the fit converges in 4–8 from the saddle start.
const MAX_ITERATIONS: usize = 30;

/// Corner step (px) below which the fit has converged: far below the 0.005 px the harness
/// resolves.
const CONVERGED_STEP_PX: f64 = 5e-4;

/// Initial scale `s` (px) of the edge profile: a Gaussian PSF of σ ≈ 1 px plus the pixel's
/// box (σ ≈ 1.04 px) is matched by `s ≈ 1.3 px`; the fit adapts it.
const START_BLUR: f64 = 1.3;

/// Smallest plausible edge scale (px): a perfectly sharp edge is still spread over a pixel's
/// box (σ ≈ 0.29 px, `s ≈ 0.36 px`); a fit that goes much below is fitting noise.
const MIN_BLUR: f64 = 0.25;

/// Smallest angle (radians) between the two edges: at 60° of perspective shear a board's
/// edges still cross at 30°; below ~10° they are not a corner.
const MIN_EDGE_ANGLE: f64 = 0.17;

/// Fewest pixels in the window: eleven parameters need a good many more samples.
const MIN_PIXELS: usize = 40;

/// The fitted corner and the model's fit.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Junction {
    /// The corner (px).
    pub(crate) corner: Point2<f64>,
    /// The fitted blur scale `s` of the edges (full-resolution px).
    pub(crate) blur: f64,
    /// All parameters, relative to the start point of the fit.
    params: SVector<f64, N>,
}

/// Where a fit starts.
#[derive(Debug, Clone, Copy)]
pub(crate) enum JunctionStart<'a> {
    /// From the saddle point and its quadratic's asymptotes.
    Saddle(&'a SaddleFit),
    /// From an earlier fit around the same start point (a smaller window).
    Fit(&'a Junction),
    /// From the edge normals' angles (radians) alone, when there is no saddle fit: the
    /// directions of the grid's rows and columns through the corner.
    Normals(f64, f64),
}

/// Fits the junction model in the disc of `radius` px around `start` (the saddle point, whose
/// quadratic `saddle` gives the edge directions). Returns `None` when the fit fails, does not
/// converge, or ends implausibly (corner further than `max_shift` px from `start`, blur
/// scale outside `[MIN_BLUR, radius]`, edges nearly parallel, contrast reversed to
/// nothing); the caller then keeps the saddle point.
pub(crate) fn refine_junction(
    img: &BinnedImage<'_>,
    start: Point2<f64>,
    from: JunctionStart<'_>,
    radius: f64,
    max_shift: f64,
) -> Option<Junction> {
    let pix = window(img, start, radius);
    if pix.len() < MIN_PIXELS {
        return None;
    }
    let mut p = match from {
        JunctionStart::Fit(j) => j.params,
        JunctionStart::Saddle(_) | JunctionStart::Normals(..) => {
            let (alpha1, alpha2) = match from {
                JunctionStart::Saddle(saddle) => saddle.edge_normals()?,
                JunctionStart::Normals(a1, a2) => (a1, a2),
                JunctionStart::Fit(_) => return None,
            };
            // Offset the mean, contrast by projection on the model shape.
            let mut p = SVector::<f64, N>::zeros();
            p[2] = alpha1;
            p[3] = alpha2;
            p[4] = START_BLUR * img.scale;
            let mean = pix.iter().map(|q| q.2).sum::<f64>() / pix.len() as f64;
            let (mut num, mut den) = (0.0, 0.0);
            for &(x, y, v) in &pix {
                let g = shape(&p, x, y);
                num += (v - mean) * g;
                den += g * g;
            }
            if den <= 0.0 {
                return None;
            }
            p[5] = mean;
            p[8] = num / den;
            p
        }
    };
    let mut current = evaluate(&p, &pix);
    let mut lambda = 1e-3;
    let mut converged = false;
    'outer: for _ in 0..MAX_ITERATIONS {
        // Raise the damping until a step lowers the cost; each try is one pass over the
        // window, which also yields the normal equations at the new point.
        for _ in 0..MAX_DAMPING_RAISES {
            let mut a = current.jtj;
            for k in 0..N {
                a[(k, k)] += lambda * current.jtj[(k, k)].max(1e-12);
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = chol.solve(&current.jtr);
            let next = p - step;
            let e = evaluate(&next, &pix);
            if e.cost.is_finite() && e.cost < current.cost {
                p = next;
                current = e;
                lambda = (lambda * 0.3).max(1e-9);
                if step[0].hypot(step[1]) < CONVERGED_STEP_PX {
                    converged = true;
                    break 'outer;
                }
                continue 'outer;
            }
            lambda *= 10.0;
        }
        // No step lowers the cost: at the minimum (to the precision of the arithmetic).
        converged = true;
        break;
    }
    let corner = Point2::new(start.x + p[0], start.y + p[1]);
    let sep = angle_between(p[2], p[3]);
    let plausible = converged
        && p[0].hypot(p[1]) <= max_shift
        && (MIN_BLUR..=radius).contains(&p[4].abs())
        && sep >= MIN_EDGE_ANGLE
        && corner.coords.iter().all(|v| v.is_finite());
    plausible.then_some(Junction {
        corner,
        blur: p[4].abs(),
        params: p,
    })
}

/// Tries of a larger damping per iteration before the fit counts as converged.
const MAX_DAMPING_RAISES: usize = 10;

/// The samples of the disc of `radius` px around `start`: `(dx, dy, value)` with the offset
/// from `start` in full-resolution px. On a binned image a sample's centre is
/// `scale · X + (scale − 1) / 2`.
fn window(img: &BinnedImage<'_>, start: Point2<f64>, radius: f64) -> Vec<(f64, f64, f64)> {
    let sc = img.scale;
    let off = 0.5 * (sc - 1.0);
    // Binned pixel range covering the disc.
    let lo = |c: f64| ((c - radius - off) / sc).floor() as isize;
    let hi = |c: f64| ((c + radius - off) / sc).ceil() as isize;
    let mut pix = Vec::new();
    for y in lo(start.y).max(0)..=hi(start.y).min(img.grey.height as isize - 1) {
        for x in lo(start.x).max(0)..=hi(start.x).min(img.grey.width as isize - 1) {
            let (dx, dy) = (sc * x as f64 + off - start.x, sc * y as f64 + off - start.y);
            if dx * dx + dy * dy <= radius * radius {
                pix.push((dx, dy, f64::from(img.grey.at(x, y))));
            }
        }
    }
    pix
}

/// A grey image, possibly binned: pixel `X` is centred at `scale · X + (scale − 1) / 2` of
/// the full-resolution image.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BinnedImage<'a> {
    /// The (binned) image.
    pub(crate) grey: &'a GreyF32,
    /// Full-resolution pixels per binned pixel (1 or 2).
    pub(crate) scale: f64,
}

/// Angle between two edge normals (radians, in `[0, π/2]`): lines, so `α` and `α + π` are
/// the same edge.
fn angle_between(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// The edge profile `E(u) = tanh u` and its derivative `1 − tanh² u`; beyond
/// `|u| > EDGE_CUTOFF` exactly `±1` and `0` (the difference is below 5·10⁻⁴ of the
/// contrast), so such pixels skip the geometry block of the normal equations.
#[inline]
fn edge(u: f64) -> (f64, f64) {
    if u > EDGE_CUTOFF {
        (1.0, 0.0)
    } else if u < -EDGE_CUTOFF {
        (-1.0, 0.0)
    } else {
        let t = u.tanh();
        (t, 1.0 - t * t)
    }
}

/// See [`edge`]: `1 − tanh² 4.5 ≈ 5·10⁻⁴`.
const EDGE_CUTOFF: f64 = 4.5;

/// The model's `E · E` shape at `(x, y)` (relative to the start).
#[inline]
fn shape(p: &SVector<f64, N>, x: f64, y: f64) -> f64 {
    let (xr, yr) = (x - p[0], y - p[1]);
    let (s1, c1) = p[2].sin_cos();
    let (s2, c2) = p[3].sin_cos();
    edge((c1 * xr + s1 * yr) / p[4]).0 * edge((c2 * xr + s2 * yr) / p[4]).0
}

/// The cost (sum of squared residuals `model − image`), `JᵀJ` and `Jᵀr` at `p`: one pass.
struct Evaluation {
    cost: f64,
    jtj: SMatrix<f64, N, N>,
    jtr: SVector<f64, N>,
}

// Index loops over the fixed-size Jacobian: the bounds are constants the compiler checks.
#[allow(clippy::needless_range_loop)]
fn evaluate(p: &SVector<f64, N>, pix: &[(f64, f64, f64)]) -> Evaluation {
    // Upper triangle of JᵀJ accumulated by hand (half the work of a full outer product),
    // mirrored at the end.
    let mut upper = [[0.0f64; N]; N];
    let mut jtr = [0.0f64; N];
    let mut cost = 0.0;
    let (s1, c1) = p[2].sin_cos();
    let (s2, c2) = p[3].sin_cos();
    let s = p[4];
    for &(x, y, v) in pix {
        let (xr, yr) = (x - p[0], y - p[1]);
        let (d1, d2) = (c1 * xr + s1 * yr, c2 * xr + s2 * yr);
        let ((t1, e1), (t2, e2)) = (edge(d1 / s), edge(d2 / s));
        // d E(d / s) / dd = E'(d / s) / s.
        let (e1, e2) = (e1 / s, e2 / s);
        let g = t1 * t2;
        let a = p[8] + p[9] * x + p[10] * y;
        let m = p[5] + p[6] * x + p[7] * y + a * g;
        let res = m - v;
        cost += res * res;
        let j = [
            -a * (t2 * e1 * c1 + t1 * e2 * c2),
            -a * (t2 * e1 * s1 + t1 * e2 * s2),
            a * t2 * e1 * (-s1 * xr + c1 * yr),
            a * t1 * e2 * (-s2 * xr + c2 * yr),
            -a * (t2 * e1 * d1 + t1 * e2 * d2) / s,
            1.0,
            x,
            y,
            g,
            x * g,
            y * g,
        ];
        // Pixels beyond both edge profiles have no edge derivatives (the first five): only
        // the offset and contrast block is touched.
        let first = if e1 == 0.0 && e2 == 0.0 { GEOMETRY } else { 0 };
        for a in first..N {
            let ja = j[a];
            for b in a..N {
                upper[a][b] += ja * j[b];
            }
            jtr[a] += res * ja;
        }
    }
    let jtj = SMatrix::<f64, N, N>::from_fn(|r, c| {
        let (r, c) = (r.min(c), r.max(c));
        upper[r][c]
    });
    Evaluation {
        cost,
        jtj,
        jtr: SVector::<f64, N>::from(jtr),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tilted, offset junction with a contrast gradient, sampled on a disc: the analytic
    /// gradient `2 Jᵀr` of the cost against central differences.
    #[test]
    fn gradient_matches_finite_differences() {
        let truth = SVector::<f64, N>::from_column_slice(&[
            0.3, -0.2, 0.4, 2.1, 1.6, 120.0, 0.5, -0.3, 80.0, 0.2, 0.1,
        ]);
        let mut pix = Vec::new();
        for y in -10..=10 {
            for x in -10..=10 {
                let (x, y) = (f64::from(x), f64::from(y));
                let g = shape(&truth, x, y);
                let v = truth[5] + truth[6] * x + truth[7] * y
                    + (truth[8] + truth[9] * x + truth[10] * y) * g
                    // A deterministic "noise" so the residuals are not zero.
                    + 3.0 * (0.7 * x + 1.3 * y).sin();
                pix.push((x, y, v));
            }
        }
        let at = truth
            + SVector::<f64, N>::from_column_slice(&[
                0.1, 0.05, -0.03, 0.02, 0.2, 2.0, 0.1, 0.1, -3.0, 0.05, 0.02,
            ]);
        let e = evaluate(&at, &pix);
        for k in 0..N {
            let h = 1e-6 * at[k].abs().max(1e-2);
            let (mut lo, mut hi) = (at, at);
            lo[k] -= h;
            hi[k] += h;
            let fd = (evaluate(&hi, &pix).cost - evaluate(&lo, &pix).cost) / (2.0 * h);
            let analytic = 2.0 * e.jtr[k];
            approx::assert_relative_eq!(analytic, fd, max_relative = 1e-5, epsilon = 1e-3);
        }
    }

    /// A junction rendered by the model itself: the fit started from the grid's directions
    /// alone (no saddle fit), 0.7 px off, recovers the corner.
    #[test]
    fn fit_from_grid_directions_recovers_the_corner() {
        let truth = SVector::<f64, N>::from_column_slice(&[
            0.0, 0.0, 0.3, 1.9, 1.5, 110.0, 0.0, 0.0, 80.0, 0.0, 0.0,
        ]);
        let (w, h) = (61usize, 61usize);
        let data: Vec<f32> = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f64 - 30.0, (k / w) as f64 - 30.0);
                (truth[5] + truth[8] * shape(&truth, x, y)) as f32
            })
            .collect();
        let grey = GreyF32 {
            width: w,
            height: h,
            data,
        };
        let img = BinnedImage {
            grey: &grey,
            scale: 1.0,
        };
        let start = Point2::new(30.6, 29.7);
        let j = refine_junction(&img, start, JunctionStart::Normals(0.35, 1.8), 24.0, 1.0)
            .expect("the fit converges");
        assert!(
            (j.corner - Point2::new(30.0, 30.0)).norm() < 1e-3,
            "{}",
            j.corner
        );
    }
}
