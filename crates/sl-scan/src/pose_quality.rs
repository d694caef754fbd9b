//! The quality of one checkerboard frame before it becomes a calibration pose: how much of the
//! board is saturated, how sharp its edges are, and where and how tilted the board is.
//!
//! The measures are cheap (a few thousand pixels around the corners), so they run on every
//! preview frame of `slscan calibrate capture`.

use nalgebra::{Point2, Vector3};
use serde::{Deserialize, Serialize};
use sl_calib::sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use sl_calib::{BoardCorners, CalibrationView, board_pose};
use sl_codec::Frame;

/// A pixel at or above this fraction of the full scale counts as saturated: the sensor's last
/// few codes are where its response flattens (and where 8-bit JPEG cameras clip).
pub const SATURATION_LEVEL: f64 = 0.98;

/// Half-width of the window searched around a corner for its edges, as a fraction of the
/// local square size: a third stays inside the four squares meeting at the corner.
const EDGE_WINDOW_FRACTION: f64 = 0.35;
/// Smallest half-width of that window (px): an edge needs a few pixels on each side.
const MIN_EDGE_WINDOW_PX: f64 = 3.0;
/// Largest half-width of that window (px): wider adds nothing but time.
const MAX_EDGE_WINDOW_PX: f64 = 12.0;

/// Pixels closer than this to a corner are left out of its edge gradient (px): at an
/// X-junction the gradients of two edges add up.
const JUNCTION_RADIUS_PX: f64 = 2.0;

/// Focal length of the camera before it is calibrated, as a multiple of the image width: the
/// tilt of the first poses is measured through it. 1.0 is a 53° horizontal field of view, in
/// the middle of what structured-light rigs use (40–70°); a 20 % error moves the tilt of a
/// 30° board by about 3°, well below the 10° that tells poses apart.
pub const NOMINAL_FOCAL_PER_WIDTH: f64 = 1.0;

/// Where and how the board lies in one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardGeometry {
    /// Mean of the detected inner corners (px).
    pub centre_px: Point2<f64>,
    /// Square root of the area of the inner-corner quadrilateral (px): the board's apparent
    /// size.
    pub size_px: f64,
    /// Unit normal of the board facing the camera (camera frame): `(0, 0, -1)` for a
    /// fronto-parallel board.
    pub facing: Vector3<f64>,
    /// Angle between the board normal and the camera's optical axis (degrees).
    pub tilt_deg: f64,
}

impl BoardGeometry {
    /// Measures the board of `corners` through `camera` (the camera model of the rig, or a
    /// guess of it before calibration); `None` when no pose fits (degenerate corners).
    pub fn measure(corners: &BoardCorners, square_mm: f64, camera: &CameraModel) -> Option<Self> {
        let pts = &corners.corners;
        if pts.is_empty() {
            return None;
        }
        let n = pts.len() as f64;
        let centre = pts.iter().fold(Point2::origin(), |a, p| a + p.coords / n);
        let view = CalibrationView::from_corners(corners, square_mm);
        let pose = board_pose(camera, &view, "board").ok()?;
        // The board's z axis points into the board, away from the printed side.
        let facing = -(pose.rotation * Vector3::z());
        let tilt_deg = (-facing.z).clamp(-1.0, 1.0).acos().to_degrees();
        Some(Self {
            centre_px: centre,
            size_px: quad_area(corners).sqrt(),
            facing,
            tilt_deg,
        })
    }
}

/// The camera assumed before calibration: focal length [`NOMINAL_FOCAL_PER_WIDTH`] × width,
/// principal point at the image centre, no distortion.
pub fn nominal_camera(width: u32, height: u32) -> Option<CameraModel> {
    let f = NOMINAL_FOCAL_PER_WIDTH * f64::from(width);
    CameraModel::new(
        Intrinsics::new(
            f,
            f,
            (f64::from(width) - 1.0) / 2.0,
            (f64::from(height) - 1.0) / 2.0,
        ),
        Distortion::none(),
        ImageSize::new(width, height),
    )
    .ok()
}

/// Area (px²) of the quadrilateral of the four outer inner corners.
fn quad_area(corners: &BoardCorners) -> f64 {
    let (c, r) = (corners.size.cols as usize, corners.size.rows as usize);
    let at = |i: usize, j: usize| corners.corners.get(j * c + i).copied();
    let (Some(a), Some(b), Some(d), Some(e)) =
        (at(0, 0), at(c - 1, 0), at(c - 1, r - 1), at(0, r - 1))
    else {
        return 0.0;
    };
    let quad = [a, b, d, e];
    let twice: f64 = (0..4)
        .map(|k| {
            let (p, q) = (quad[k], quad[(k + 1) % 4]);
            p.x * q.y - q.x * p.y
        })
        .sum();
    twice.abs() / 2.0
}

/// The outline of the whole board in the image (px): the inner-corner grid extended by one
/// square on each side, extrapolated from the outer corners and their neighbours.
pub fn board_outline(corners: &BoardCorners) -> Option<[Point2<f64>; 4]> {
    let (c, r) = (corners.size.cols as usize, corners.size.rows as usize);
    if c < 2 || r < 2 {
        return None;
    }
    let at = |i: usize, j: usize| corners.corners.get(j * c + i).copied();
    // Each outer corner moved away from its diagonal neighbour inside the grid.
    let out = |i: usize, j: usize, di: usize, dj: usize| -> Option<Point2<f64>> {
        let p = at(i, j)?;
        let q = at(di, dj)?;
        Some(p + (p - q))
    };
    Some([
        out(0, 0, 1, 1)?,
        out(c - 1, 0, c - 2, 1)?,
        out(c - 1, r - 1, c - 2, r - 2)?,
        out(0, r - 1, 1, r - 2)?,
    ])
}

/// Whether `p` lies inside the convex quadrilateral `quad` (either winding).
fn inside(quad: &[Point2<f64>; 4], p: &Point2<f64>) -> bool {
    let mut sign = 0.0f64;
    for k in 0..4 {
        let (a, b) = (quad[k], quad[(k + 1) % 4]);
        let cross = (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
        if cross != 0.0 {
            if sign == 0.0 {
                sign = cross.signum();
            } else if cross.signum() != sign {
                return false;
            }
        }
    }
    true
}

/// Fraction of the board's pixels (inside [`board_outline`]) at or above
/// [`SATURATION_LEVEL`] of `max_value`; 0 when the outline is empty.
pub fn saturated_fraction(image: &Frame<u8>, max_value: f64, corners: &BoardCorners) -> f64 {
    let Some(quad) = board_outline(corners) else {
        return 0.0;
    };
    let (w, h) = (image.width(), image.height());
    let lo = |v: f64, n: usize| (v.floor().max(0.0) as usize).min(n.saturating_sub(1));
    let x0 = lo(quad.iter().map(|p| p.x).fold(f64::INFINITY, f64::min), w);
    let x1 = lo(
        quad.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max),
        w,
    );
    let y0 = lo(quad.iter().map(|p| p.y).fold(f64::INFINITY, f64::min), h);
    let y1 = lo(
        quad.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max),
        h,
    );
    let level = SATURATION_LEVEL * max_value;
    let (mut total, mut saturated) = (0usize, 0usize);
    for y in y0..=y1 {
        for x in x0..=x1 {
            if inside(&quad, &Point2::new(x as f64, y as f64)) {
                total += 1;
                if f64::from(image.get(x, y).unwrap_or(0)) >= level {
                    saturated += 1;
                }
            }
        }
    }
    if total == 0 {
        0.0
    } else {
        saturated as f64 / total as f64
    }
}

/// Width of the board's edges (px), the median over the corners of the local contrast divided
/// by the steepest gradient near the corner: about 2 px for a sharp, anti-aliased edge (the
/// central difference spreads a step over two pixels) and 2.5 σ for an edge blurred by a
/// Gaussian of σ px (defocus, motion). `None` when no corner has contrast.
pub fn edge_width_px(image: &Frame<u8>, corners: &BoardCorners) -> Option<f64> {
    let (w, h) = (image.width() as i64, image.height() as i64);
    let cols = corners.size.cols as usize;
    // Clamped to the frame, so `get` always finds the pixel.
    let px = |x: i64, y: i64| -> f64 {
        let x = x.clamp(0, w - 1) as usize;
        let y = y.clamp(0, h - 1) as usize;
        f64::from(image.get(x, y).unwrap_or(0))
    };
    let mut widths = Vec::with_capacity(corners.corners.len());
    for (k, p) in corners.corners.iter().enumerate() {
        // Local square size: distance to the nearest grid neighbour.
        let neighbour = if k % cols + 1 < cols {
            k + 1
        } else {
            k.wrapping_sub(1)
        };
        let step = corners
            .corners
            .get(neighbour)
            .map_or(MAX_EDGE_WINDOW_PX, |q| (q - p).norm());
        let r = (EDGE_WINDOW_FRACTION * step).clamp(MIN_EDGE_WINDOW_PX, MAX_EDGE_WINDOW_PX) as i64;
        let (cx, cy) = (p.x.round() as i64, p.y.round() as i64);
        let (mut lo, mut hi, mut grad) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                let v = px(x, y);
                lo = lo.min(v);
                hi = hi.max(v);
                // At the junction itself two edges add up: the gradient is measured on the
                // edges around it.
                if (x as f64 - p.x).hypot(y as f64 - p.y) < JUNCTION_RADIUS_PX {
                    continue;
                }
                let gx = (px(x + 1, y) - px(x - 1, y)) / 2.0;
                let gy = (px(x, y + 1) - px(x, y - 1)) / 2.0;
                grad = grad.max(gx.hypot(gy));
            }
        }
        if grad > 0.0 && hi > lo {
            widths.push((hi - lo) / grad);
        }
    }
    if widths.is_empty() {
        return None;
    }
    widths.sort_by(f64::total_cmp);
    widths.get(widths.len() / 2).copied()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use sl_calib::{BoardSize, DetectorConfig, detect_checkerboard};

    /// A 5x4 board of 20 px squares at (40, 40), dark 30, light `light`.
    fn board(light: u8) -> Frame<u8> {
        let (w, h) = (200, 180);
        let pixels = (0..w * h).map(|k| {
            let (x, y) = ((k % w) as i32, (k / w) as i32);
            let (i, j) = ((x - 40).div_euclid(20), (y - 40).div_euclid(20));
            let inside = (0..6).contains(&i) && (0..5).contains(&j);
            if inside && (i + j) % 2 == 0 {
                30
            } else {
                light
            }
        });
        Frame::new(w, h, pixels.collect()).unwrap()
    }

    /// `img` blurred by the `image` crate's Gaussian of `sigma` px.
    fn blur(img: &Frame<u8>, sigma: f32) -> Frame<u8> {
        let (w, h) = (img.width(), img.height());
        let g = image::GrayImage::from_raw(w as u32, h as u32, img.data().to_vec()).unwrap();
        Frame::new(w, h, image::imageops::blur(&g, sigma).into_raw()).unwrap()
    }

    fn corners(img: &Frame<u8>) -> BoardCorners {
        detect_checkerboard(img, BoardSize::new(5, 4), &DetectorConfig::default(), "t").unwrap()
    }

    #[test]
    fn saturation_counts_the_light_squares_of_the_board() {
        let img = board(255);
        let c = corners(&img);
        // The outline is the 6x5 squares; half of them (15 of 30) are light, i.e. saturated.
        let f = saturated_fraction(&img, 255.0, &c);
        assert!((f - 0.5).abs() < 0.03, "{f}");
        assert!(saturated_fraction(&board(200), 255.0, &c) < 1e-9);
    }

    #[test]
    fn edge_width_grows_with_blur() {
        let sharp = board(220);
        let c = corners(&sharp);
        // A hard step: the central difference spreads it over 2 px.
        let w0 = edge_width_px(&sharp, &c).unwrap();
        assert!((w0 - 2.0).abs() < 0.1, "{w0}");
        // Gaussian blur of sigma 3: about 2.5 sigma.
        let blurred = blur(&sharp, 3.0);
        let w3 = edge_width_px(&blurred, &c).unwrap();
        assert!(w3 > 6.0 && w3 < 9.0, "{w3}");
    }

    #[test]
    fn a_fronto_parallel_board_has_no_tilt() {
        let img = board(220);
        let c = corners(&img);
        let cam = nominal_camera(200, 180).unwrap();
        let g = BoardGeometry::measure(&c, 20.0, &cam).unwrap();
        assert!(g.tilt_deg < 1.0, "{g:?}");
        // Centre of the 5x4 inner corners: (40 + 20 * 3 - 0.5, 40 + 20 * 2.5 - 0.5).
        assert!((g.centre_px.x - 99.5).abs() < 0.1 && (g.centre_px.y - 89.5).abs() < 0.1);
        // 4 x 3 squares of 20 px.
        assert!(
            (g.size_px - (80.0f64 * 60.0).sqrt()).abs() < 0.5,
            "{}",
            g.size_px
        );
    }
}
