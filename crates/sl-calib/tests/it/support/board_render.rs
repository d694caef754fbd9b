//! Checkerboard images that look like real captures, with exact corner truth: the corner
//! harness (`examples/corner_harness.rs`) and `benches/calib.rs` include this file with
//! `#[path]`; `tests/it/realistic_corners.rs` uses it as `support::board_render`.
//!
//! The image formation, in order:
//! 1. a pinhole camera sees a planar board (`cols × rows` inner corners, one white square of
//!    margin, grey background) under a pose with perspective tilt; each pixel is the exact
//!    area average of the board's albedo over the pixel's square (convex polygon clipping of
//!    every dark square's image quadrilateral, which a homography keeps straight), so the
//!    truth is the homography's image of the board's corners, with no sampling error;
//! 2. the illumination: uniform, or one of three phase-shifted fringes (with a third
//!    harmonic, which survives the mean of three shifts as a ripple, as a projector's
//!    non-linearity does), multiplied in at the pixel centre;
//! 3. lens blur: a Gaussian of `blur_sigma` px (centrally symmetric, so the blurred corner
//!    stays at the geometric junction);
//! 4. vignetting: a `1 − v·r²` fall-off with `r` the distance from the image centre relative
//!    to the half-diagonal;
//! 5. camera response `x^(1/gamma)`, shot-like sensor noise, 8-bit quantisation;
//! 6. for fringe captures, the board image is the rounded mean of the three 8-bit captures
//!    (what a capture without a white frame gives).

// The example uses the rendering only, the test also the statistics.
#![allow(dead_code)]

use nalgebra::{Matrix3, Point2, Rotation3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64Mcg;

/// Albedo of the dark squares (printed black reflects a few per cent).
const DARK_ALBEDO: f64 = 0.08;
/// Albedo of the white squares and margin.
const LIGHT_ALBEDO: f64 = 0.9;
/// Albedo of the background around the board.
const BACKGROUND_ALBEDO: f64 = 0.35;
/// Ambient light added to the projector's fringes (relative to the fringes' peak): real
/// rooms are never dark.
const AMBIENT: f64 = 0.1;

/// Fringes of a projector lighting the board: the capture is the mean of three shifts.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fringes {
    /// Fringe period in the image (px).
    pub(crate) period_px: f64,
    /// Fringe direction in the image (degrees; 0: vertical fringes, phase along x).
    pub(crate) angle_deg: f64,
    /// Peak-to-peak ripple of the mean of the three shifts relative to its mean (the
    /// projector's third harmonic; 0.16 is 16 %).
    pub(crate) ripple: f64,
}

/// One rendering: image size, board, pose, optics and sensor.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RenderSpec {
    /// Image width (px).
    pub(crate) width: u32,
    /// Image height (px).
    pub(crate) height: u32,
    /// Inner corners along a row.
    pub(crate) cols: u32,
    /// Inner corners along a column.
    pub(crate) rows: u32,
    /// Square size in the image at the board's centre (px).
    pub(crate) square_px: f64,
    /// In-plane rotation of the board (degrees).
    pub(crate) rotation_deg: f64,
    /// Tilt of the board about the image's x axis (degrees).
    pub(crate) tilt_x_deg: f64,
    /// Tilt of the board about the image's y axis (degrees).
    pub(crate) tilt_y_deg: f64,
    /// Offset of the board's centre from the image centre (px).
    pub(crate) offset: (f64, f64),
    /// Focal length (px).
    pub(crate) focal_px: f64,
    /// Lens blur: standard deviation of the Gaussian PSF (px).
    pub(crate) blur_sigma: f64,
    /// Vignetting: brightness lost at the image corners (0.3: 30 %).
    pub(crate) vignetting: f64,
    /// Camera response exponent: output = input^(1/gamma).
    pub(crate) gamma: f64,
    /// Sensor noise: standard deviation (grey levels) at mid grey, scaling like shot noise
    /// (with the square root of the signal), and a floor of a quarter of it (read noise).
    pub(crate) noise: f64,
    /// Grey level of the white squares under full light before vignetting and noise.
    pub(crate) exposure: f64,
    /// `None`: one frame under uniform light; `Some`: the mean of three fringe captures.
    pub(crate) fringes: Option<Fringes>,
    /// Radial lens distortion `k₁` of the normalised image coordinates (`x_d = x (1 + k₁ r²)`,
    /// OpenCV's model; negative is barrel): the board's straight edges are curved in the
    /// image, as through a real lens.
    pub(crate) k1: f64,
    /// Seed of the noise.
    pub(crate) seed: u64,
}

impl RenderSpec {
    /// A 13x9 board of `square_px` squares centred in a `width × height` image, seen
    /// square-on, sharp and noiseless; the fields are then set per condition.
    pub(crate) fn new(width: u32, height: u32, square_px: f64) -> Self {
        Self {
            width,
            height,
            cols: 13,
            rows: 9,
            square_px,
            rotation_deg: 0.0,
            tilt_x_deg: 0.0,
            tilt_y_deg: 0.0,
            offset: (0.0, 0.0),
            focal_px: 1.2 * f64::from(width.max(height)),
            blur_sigma: 0.0,
            vignetting: 0.0,
            gamma: 1.0,
            noise: 0.0,
            exposure: 235.0,
            fringes: None,
            k1: 0.0,
            seed: 1,
        }
    }
}

/// A rendered board: the 8-bit image and its inner corners in board order (corner `(i, j)`
/// at index `j · cols + i`), pixel `(0, 0)` being the centre of the top-left pixel.
pub(crate) struct RenderedBoard {
    /// The image.
    pub(crate) image: sl_calib::sl_codec::Frame<u8>,
    /// The true inner corners (px).
    pub(crate) corners: Vec<Point2<f64>>,
}

/// The homography from board coordinates in squares (inner corner `(i, j)` at `(i, j)`) to
/// pixels.
pub(crate) fn board_homography(spec: &RenderSpec) -> Matrix3<f64> {
    let f = spec.focal_px;
    let (cx, cy) = (
        0.5 * f64::from(spec.width) - 0.5,
        0.5 * f64::from(spec.height) - 0.5,
    );
    let k = Matrix3::new(f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0);
    let rot = Rotation3::from_euler_angles(
        spec.tilt_x_deg.to_radians(),
        spec.tilt_y_deg.to_radians(),
        spec.rotation_deg.to_radians(),
    );
    // Distance at which one square (unit) is `square_px` pixels: 1 / z · f = square_px.
    let z = f / spec.square_px;
    let centre = Vector3::new(
        0.5 * f64::from(spec.cols - 1),
        0.5 * f64::from(spec.rows - 1),
        0.0,
    );
    let t = Vector3::new(
        spec.offset.0 / spec.square_px,
        spec.offset.1 / spec.square_px,
        z,
    ) - rot * centre;
    let r = rot.matrix();
    let m = Matrix3::from_columns(&[r.column(0).into_owned(), r.column(1).into_owned(), t]);
    k * m
}

fn apply(h: &Matrix3<f64>, x: f64, y: f64) -> Point2<f64> {
    let v = h * Vector3::new(x, y, 1.0);
    Point2::new(v.x / v.z, v.y / v.z)
}

/// The lens: the ideal (pinhole) pixel `p` to the distorted pixel (radial `k1` about the
/// principal point, the image centre).
fn distort(spec: &RenderSpec, p: Point2<f64>) -> Point2<f64> {
    let (f, c) = (spec.focal_px, principal_point(spec));
    let (x, y) = ((p.x - c.x) / f, (p.y - c.y) / f);
    let g = 1.0 + spec.k1 * (x * x + y * y);
    Point2::new(c.x + f * x * g, c.y + f * y * g)
}

/// The inverse of [`distort`], by fixed-point iteration to 1e-12 of a normalised coordinate
/// (a contraction for the distortions of the harness: `|k₁| r² < 0.3`).
fn undistort(spec: &RenderSpec, p: Point2<f64>) -> Point2<f64> {
    let (f, c) = (spec.focal_px, principal_point(spec));
    let (xd, yd) = ((p.x - c.x) / f, (p.y - c.y) / f);
    let (mut x, mut y) = (xd, yd);
    for _ in 0..100 {
        let g = 1.0 + spec.k1 * (x * x + y * y);
        let (nx, ny) = (xd / g, yd / g);
        let done = (nx - x).abs().max((ny - y).abs()) < 1e-12;
        (x, y) = (nx, ny);
        if done {
            break;
        }
    }
    Point2::new(c.x + f * x, c.y + f * y)
}

/// The principal point: the image centre.
fn principal_point(spec: &RenderSpec) -> Point2<f64> {
    Point2::new(
        0.5 * f64::from(spec.width) - 0.5,
        0.5 * f64::from(spec.height) - 0.5,
    )
}

/// Area of a simple polygon (shoelace).
fn polygon_area(poly: &[Point2<f64>]) -> f64 {
    let n = poly.len();
    let mut s = 0.0;
    for k in 0..n {
        let (a, b) = (poly[k], poly[(k + 1) % n]);
        s += a.x * b.y - b.x * a.y;
    }
    0.5 * s.abs()
}

/// Area of the convex polygon `poly` inside the axis-aligned square `[x0, x1] × [y0, y1]`
/// (Sutherland–Hodgman clipping, then the shoelace formula).
fn clipped_area(poly: &[Point2<f64>], x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let mut cur: Vec<Point2<f64>> = poly.to_vec();
    // (axis, bound, keep values >= bound?)
    for (axis, bound, keep_above) in [(0, x0, true), (0, x1, false), (1, y0, true), (1, y1, false)]
    {
        if cur.is_empty() {
            return 0.0;
        }
        let inside = |p: &Point2<f64>| {
            let v = if axis == 0 { p.x } else { p.y };
            if keep_above { v >= bound } else { v <= bound }
        };
        let mut next = Vec::with_capacity(cur.len() + 2);
        for k in 0..cur.len() {
            let a = cur[k];
            let b = cur[(k + 1) % cur.len()];
            let (ia, ib) = (inside(&a), inside(&b));
            if ia {
                next.push(a);
            }
            if ia != ib {
                let (va, vb) = if axis == 0 { (a.x, b.x) } else { (a.y, b.y) };
                let t = (bound - va) / (vb - va);
                next.push(a + (b - a) * t);
            }
        }
        cur = next;
    }
    polygon_area(&cur)
}

/// Albedo of the board in board coordinates (squares), background outside.
fn albedo_at(spec: &RenderSpec, u: f64, v: f64) -> f64 {
    let (i, j) = (u.floor() as i64, v.floor() as i64);
    let (c, r) = (i64::from(spec.cols), i64::from(spec.rows));
    // Squares -1..c × -1..r; one white square of margin around them.
    if i < -2 || j < -2 || i > c || j > r {
        BACKGROUND_ALBEDO
    } else if (-1..c).contains(&i) && (-1..r).contains(&j) && (i + j) % 2 == 0 {
        DARK_ALBEDO
    } else {
        LIGHT_ALBEDO
    }
}

/// The exact pixel-area average of the albedo: the board (squares plus one square of white
/// margin) over a grey background.
fn albedo_image(spec: &RenderSpec, h: &Matrix3<f64>) -> Vec<f64> {
    let hinv = h.try_inverse().expect("a board seen edge-on has no image");
    let (w, ht) = (spec.width as usize, spec.height as usize);
    let (c, r) = (i64::from(spec.cols), i64::from(spec.rows));
    let quad = |u0: f64, v0: f64, u1: f64, v1: f64| {
        [
            apply(h, u0, v0),
            apply(h, u1, v0),
            apply(h, u1, v1),
            apply(h, u0, v1),
        ]
    };
    // The board with its margin covers squares -2..=c × -2..=r.
    let outline = quad(-2.0, -2.0, c as f64 + 1.0, r as f64 + 1.0);
    let mut out = vec![0.0; w * ht];
    for y in 0..ht {
        for x in 0..w {
            let (x0, x1, y0, y1) = (
                x as f64 - 0.5,
                x as f64 + 0.5,
                y as f64 - 0.5,
                y as f64 + 0.5,
            );
            // The pixel's square on the board (through the lens first when it distorts).
            let to_board = |x: f64, y: f64| {
                if spec.k1 == 0.0 {
                    apply(&hinv, x, y)
                } else {
                    let u = undistort(spec, Point2::new(x, y));
                    apply(&hinv, u.x, u.y)
                }
            };
            let pre = [
                to_board(x0, y0),
                to_board(x1, y0),
                to_board(x1, y1),
                to_board(x0, y1),
            ];
            let (mut umin, mut umax, mut vmin, mut vmax) = (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            );
            for p in &pre {
                umin = umin.min(p.x);
                umax = umax.max(p.x);
                vmin = vmin.min(p.y);
                vmax = vmax.max(p.y);
            }
            let (i0, i1, j0, j1) = (
                umin.floor() as i64,
                umax.floor() as i64,
                vmin.floor() as i64,
                vmax.floor() as i64,
            );
            let value = if i0 == i1 && j0 == j1 {
                albedo_at(spec, umin, vmin)
            } else if spec.k1 != 0.0 {
                board_area_average(spec, &pre, (i0, i1, j0, j1))
            } else {
                // Start from the background, add the board (light), remove the dark squares.
                let on_board = clipped_area(&outline, x0, x1, y0, y1);
                let mut v = BACKGROUND_ALBEDO + (LIGHT_ALBEDO - BACKGROUND_ALBEDO) * on_board;
                for j in j0.max(-1)..=j1.min(r - 1) {
                    for i in i0.max(-1)..=i1.min(c - 1) {
                        if (i + j) % 2 != 0 {
                            continue;
                        }
                        let q = quad(i as f64, j as f64, i as f64 + 1.0, j as f64 + 1.0);
                        v -= (LIGHT_ALBEDO - DARK_ALBEDO) * clipped_area(&q, x0, x1, y0, y1);
                    }
                }
                v
            };
            out[y * w + x] = value;
        }
    }
    out
}

/// The albedo averaged over the pixel whose preimage on the board is the quadrilateral
/// `pre` (board units; squares `i0..=i1 × j0..=j1` cover it): the areas of the board and of
/// each dark square inside it, clipped on the board. The lens bends the pixel's sides by
/// ~1e-4 px over a pixel at the harness's distortions, so the straight-sided preimage is
/// exact to far below the corner errors measured.
fn board_area_average(
    spec: &RenderSpec,
    pre: &[Point2<f64>; 4],
    span: (i64, i64, i64, i64),
) -> f64 {
    let (i0, i1, j0, j1) = span;
    let (c, r) = (i64::from(spec.cols), i64::from(spec.rows));
    let area = polygon_area(pre);
    let on_board = clipped_area(pre, -2.0, c as f64 + 1.0, -2.0, r as f64 + 1.0) / area;
    let mut v = BACKGROUND_ALBEDO + (LIGHT_ALBEDO - BACKGROUND_ALBEDO) * on_board;
    for j in j0.max(-1)..=j1.min(r - 1) {
        for i in i0.max(-1)..=i1.min(c - 1) {
            if (i + j) % 2 != 0 {
                continue;
            }
            let (u, w) = (i as f64, j as f64);
            v -= (LIGHT_ALBEDO - DARK_ALBEDO) * clipped_area(pre, u, u + 1.0, w, w + 1.0) / area;
        }
    }
    v
}

/// Separable Gaussian blur of a row-major image, kernel cut at 4 σ, borders clamped.
fn gaussian_blur(data: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    if sigma <= 0.0 {
        return data.to_vec();
    }
    let radius = (4.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f64> = (-radius..=radius)
        .map(|i| (-((i * i) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= sum);
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (k, kv) in kernel.iter().enumerate() {
                let xs = (x as isize + k as isize - radius).clamp(0, w as isize - 1) as usize;
                acc += kv * data[y * w + xs];
            }
            tmp[y * w + x] = acc;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for (k, kv) in kernel.iter().enumerate() {
            let ys = (y as isize + k as isize - radius).clamp(0, h as isize - 1) as usize;
            for x in 0..w {
                out[y * w + x] += kv * tmp[ys * w + x];
            }
        }
    }
    out
}

/// Renders the board of `spec`.
pub(crate) fn render(spec: &RenderSpec) -> RenderedBoard {
    let h = board_homography(spec);
    let (w, ht) = (spec.width as usize, spec.height as usize);
    let albedo = albedo_image(spec, &h);
    let mut rng = Pcg64Mcg::seed_from_u64(spec.seed);
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let (cx, cy) = (0.5 * w as f64 - 0.5, 0.5 * ht as f64 - 0.5);
    let half_diag2 = cx * cx + cy * cy;
    // One 8-bit capture under the illumination `light(x, y)` (relative, mean ~1).
    let mut capture = |light: &dyn Fn(f64, f64) -> f64| -> Vec<f64> {
        let lit: Vec<f64> = albedo
            .iter()
            .enumerate()
            .map(|(k, a)| a * light((k % w) as f64, (k / w) as f64))
            .collect();
        let blurred = gaussian_blur(&lit, w, ht, spec.blur_sigma);
        blurred
            .iter()
            .enumerate()
            .map(|(k, &v)| {
                let (x, y) = ((k % w) as f64, (k / w) as f64);
                let r2 = ((x - cx).powi(2) + (y - cy).powi(2)) / half_diag2;
                let lin = (v / LIGHT_ALBEDO * (1.0 - spec.vignetting * r2)).max(0.0);
                let grey = spec.exposure * lin.powf(1.0 / spec.gamma);
                let sd = spec.noise * (0.0625 + grey / 128.0).sqrt();
                (grey + sd * unit.sample(&mut rng))
                    .round()
                    .clamp(0.0, 255.0)
            })
            .collect()
    };
    let pixels: Vec<f64> = match spec.fringes {
        None => capture(&|_, _| 1.0),
        Some(fr) => {
            let (s, c) = fr.angle_deg.to_radians().sin_cos();
            let mut sum = vec![0.0; w * ht];
            for shift in 0..3 {
                let delta = std::f64::consts::TAU * f64::from(shift) / 3.0;
                let light = move |x: f64, y: f64| {
                    let phi = std::f64::consts::TAU * (x * c + y * s) / fr.period_px + delta;
                    // Fringe (mean 0.5) with its third harmonic, plus ambient; the mean
                    // of the three shifts is 0.5 + ripple/4 · cos 3φ: a ripple of
                    // `ripple` peak to peak over the mean.
                    let fringe = 0.5 + 0.5 * phi.cos() + 0.25 * fr.ripple * (3.0 * phi).cos();
                    // Peak light 1 (the projector's white), so the board image of the
                    // mean is about half as bright as a white frame, as in real captures.
                    (fringe + AMBIENT) / (1.0 + 0.25 * fr.ripple + AMBIENT)
                };
                for (acc, v) in sum.iter_mut().zip(capture(&light)) {
                    *acc += v;
                }
            }
            sum.iter().map(|v| (v / 3.0).round()).collect()
        }
    };
    let image = sl_calib::sl_codec::Frame::new(
        spec.width as usize,
        spec.height as usize,
        pixels.iter().map(|&v| v as u8).collect(),
    )
    .expect("buffer of width × height");
    let mut corners = Vec::with_capacity((spec.cols * spec.rows) as usize);
    for j in 0..spec.rows {
        for i in 0..spec.cols {
            corners.push(distort(spec, apply(&h, f64::from(i), f64::from(j))));
        }
    }
    RenderedBoard { image, corners }
}

/// Errors of `found` against `truth` (px), each found corner matched to its nearest true
/// corner (so a board order turned by 180° — both dimensions odd or both even — does not
/// count as an error).
pub(crate) fn corner_errors(found: &[Point2<f64>], truth: &[Point2<f64>]) -> Vec<f64> {
    found
        .iter()
        .map(|p| {
            truth
                .iter()
                .map(|t| (p - t).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Root mean square of `errors`.
pub(crate) fn rms(errors: &[f64]) -> f64 {
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt()
}

/// Mean of `errors`.
pub(crate) fn mean(errors: &[f64]) -> f64 {
    errors.iter().sum::<f64>() / errors.len().max(1) as f64
}

/// The 95th percentile of `errors` (nearest rank), as numpy's `percentile(.., 95,
/// method="inverted_cdf")` in the peer script.
pub(crate) fn p95(errors: &[f64]) -> f64 {
    let mut v = errors.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    let rank = (0.95 * v.len() as f64).ceil() as usize;
    v[rank.clamp(1, v.len()) - 1]
}
