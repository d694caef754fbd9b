//! Sub-pixel corners by fitting a blurred junction model (the refiner that runs after
//! [`refine_saddle`](crate::saddle::refine_saddle)).
//!
//! Around an inner corner the board is two straight edges crossing, blurred by the lens. The
//! model, on the raw (unblurred) image in a disc around the corner:
//!
//! ```text
//! I(x) = B(x) + A(x) · tanh(d₁(x) / s) · tanh(d₂(x) / s)
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
//! slow light variations that bias a symmetric fit. `tanh` instead of the Gaussian edge's
//! `erf`: both are odd, so the mismatch of edge shape is symmetric about the corner and does
//! not move it, and `tanh` is in `std`.

use nalgebra::{Point2, SMatrix, SVector};

use crate::grey::GreyF32;
use crate::saddle::SaddleFit;

/// Parameters of the model.
const N: usize = 11;

/// Levenberg–Marquardt iterations at most; the fit converges in 4–8 from the saddle start.
const MAX_ITERATIONS: usize = 30;

/// Corner step (px) below which the fit has converged: far below the 0.005 px the harness
/// resolves.
const CONVERGED_STEP_PX: f64 = 5e-4;

/// Initial blur scale `s` (px) of the `tanh` edges: a Gaussian PSF of σ ≈ 1 px plus the
/// pixel's box has a `tanh` scale of about 1.3 px; the fit adapts it.
const START_BLUR: f64 = 1.3;

/// Smallest plausible blur scale (px): sharper than a pixel's box is not an edge the pixels
/// can show; a fit that goes there is fitting noise.
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
}

/// Fits the junction model in the disc of `radius` px around `start` (the saddle point, whose
/// quadratic `saddle` gives the edge directions). Returns `None` when the fit fails, does not
/// converge, or ends implausibly (corner further than `max_shift` px from `start`, blur
/// scale outside `[MIN_BLUR, radius / 2]`, edges nearly parallel, contrast reversed to
/// nothing); the caller then keeps the saddle point.
pub(crate) fn refine_junction(
    img: &GreyF32,
    start: Point2<f64>,
    saddle: &SaddleFit,
    radius: f64,
    max_shift: f64,
) -> Option<Junction> {
    let (alpha1, alpha2) = saddle.edge_normals()?;
    // The pixels of the window, relative to the start (px).
    let r = radius.floor() as isize;
    let (sx, sy) = (start.x.round() as isize, start.y.round() as isize);
    let mut pix: Vec<(f64, f64, f64)> = Vec::with_capacity(((2 * r + 1) * (2 * r + 1)) as usize);
    for y in sy - r..=sy + r {
        for x in sx - r..=sx + r {
            let (dx, dy) = (x as f64 - start.x, y as f64 - start.y);
            if dx * dx + dy * dy > radius * radius {
                continue;
            }
            if x < 0 || y < 0 || x as usize >= img.width || y as usize >= img.height {
                continue;
            }
            pix.push((dx, dy, f64::from(img.at(x, y))));
        }
    }
    if pix.len() < MIN_PIXELS {
        return None;
    }
    // Start: offset the mean, contrast by projection on the model shape.
    let mut p = SVector::<f64, N>::zeros();
    p[2] = alpha1;
    p[3] = alpha2;
    p[4] = START_BLUR;
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
    let mut cost = cost_of(&p, &pix);
    let mut lambda = 1e-3;
    let mut converged = false;
    for _ in 0..MAX_ITERATIONS {
        let (jtj, jtr) = normal_equations(&p, &pix);
        let mut improved = false;
        // Raise the damping until a step lowers the cost.
        for _ in 0..10 {
            let mut a = jtj;
            for k in 0..N {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = chol.solve(&jtr);
            let next = p - step;
            let c = cost_of(&next, &pix);
            if c.is_finite() && c < cost {
                let moved = step[0].hypot(step[1]);
                p = next;
                cost = c;
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                converged = moved < CONVERGED_STEP_PX;
                break;
            }
            lambda *= 10.0;
        }
        if !improved || converged {
            converged = true;
            break;
        }
    }
    let corner = Point2::new(start.x + p[0], start.y + p[1]);
    let sep = angle_between(p[2], p[3]);
    let plausible = converged
        && p[0].hypot(p[1]) <= max_shift
        && (MIN_BLUR..=0.5 * radius).contains(&p[4].abs())
        && sep >= MIN_EDGE_ANGLE
        && corner.coords.iter().all(|v| v.is_finite());
    plausible.then_some(Junction { corner })
}

/// Angle between two edge normals (radians, in `[0, π/2]`): lines, so `α` and `α + π` are
/// the same edge.
fn angle_between(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// The model's `tanh · tanh` shape at `(x, y)` (relative to the start).
#[inline]
fn shape(p: &SVector<f64, N>, x: f64, y: f64) -> f64 {
    let (xr, yr) = (x - p[0], y - p[1]);
    let (s1, c1) = p[2].sin_cos();
    let (s2, c2) = p[3].sin_cos();
    ((c1 * xr + s1 * yr) / p[4]).tanh() * ((c2 * xr + s2 * yr) / p[4]).tanh()
}

fn cost_of(p: &SVector<f64, N>, pix: &[(f64, f64, f64)]) -> f64 {
    pix.iter()
        .map(|&(x, y, v)| {
            let g = shape(p, x, y);
            let m = p[5] + p[6] * x + p[7] * y + (p[8] + p[9] * x + p[10] * y) * g;
            (m - v) * (m - v)
        })
        .sum()
}

/// `JᵀJ` and `Jᵀr` of the residuals `model − image` at `p`.
fn normal_equations(
    p: &SVector<f64, N>,
    pix: &[(f64, f64, f64)],
) -> (SMatrix<f64, N, N>, SVector<f64, N>) {
    // Upper triangle of JᵀJ accumulated by hand (half the work of a full outer product),
    // mirrored at the end.
    let mut upper = [[0.0f64; N]; N];
    let mut jtr = [0.0f64; N];
    let (s1, c1) = p[2].sin_cos();
    let (s2, c2) = p[3].sin_cos();
    let s = p[4];
    for &(x, y, v) in pix {
        let (xr, yr) = (x - p[0], y - p[1]);
        let (d1, d2) = (c1 * xr + s1 * yr, c2 * xr + s2 * yr);
        let (t1, t2) = ((d1 / s).tanh(), (d2 / s).tanh());
        // dT/dd = (1 − T²) / s.
        let (e1, e2) = ((1.0 - t1 * t1) / s, (1.0 - t2 * t2) / s);
        let g = t1 * t2;
        let a = p[8] + p[9] * x + p[10] * y;
        let m = p[5] + p[6] * x + p[7] * y + a * g;
        let res = m - v;
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
        for (a, (row, &ja)) in upper.iter_mut().zip(&j).enumerate() {
            for (m, &jb) in row.iter_mut().zip(&j).skip(a) {
                *m += ja * jb;
            }
        }
        for (acc, &ja) in jtr.iter_mut().zip(&j) {
            *acc += res * ja;
        }
    }
    let jtj = SMatrix::<f64, N, N>::from_fn(|r, c| {
        let (r, c) = (r.min(c), r.max(c));
        upper[r][c]
    });
    (jtj, SVector::<f64, N>::from(jtr))
}
