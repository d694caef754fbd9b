//! Pictures of a calibration, drawn with `imageproc`: the detected corners on each image
//! (first corner and order visible), per-view RMS error bars, and a residual vector plot.

use std::path::Path;

use image::{Rgb, RgbImage};
use imageproc::drawing::{
    draw_antialiased_line_segment_mut, draw_filled_circle_mut, draw_filled_rect_mut,
    draw_hollow_circle_mut, draw_line_segment_mut, draw_polygon_mut,
};
use imageproc::pixelops::interpolate;
use imageproc::point::Point;
use imageproc::rect::Rect;
use nalgebra::{Point2, Vector2};
use sl_codec::Frame;

use crate::{BoardCorners, CalibError};

/// Colours cycled through by board rows (corner pictures) and views (residual plots): the
/// eight-colour palette of Okabe and Ito, distinguishable with the common colour-vision
/// deficiencies.
pub const PALETTE: [Rgb<u8>; 8] = [
    Rgb([0, 114, 178]),
    Rgb([230, 159, 0]),
    Rgb([0, 158, 115]),
    Rgb([204, 121, 167]),
    Rgb([86, 180, 233]),
    Rgb([213, 94, 0]),
    Rgb([240, 228, 66]),
    Rgb([0, 0, 0]),
];

/// Colour of the disc marking the first corner (corner 0).
pub const FIRST_CORNER: Rgb<u8> = Rgb([255, 0, 0]);

/// Colour of the bars of views whose RMS is above [`OUTLIER_FACTOR`] times the median.
pub const OUTLIER_BAR: Rgb<u8> = Rgb([213, 94, 0]);

/// Colour of the other bars.
pub const BAR: Rgb<u8> = Rgb([0, 114, 178]);

/// A view whose RMS exceeds this multiple of the median RMS is drawn as an outlier: twice the
/// median is well outside the spread of views of one session with the same detector.
pub const OUTLIER_FACTOR: f64 = 2.0;

const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const GRID: Rgb<u8> = Rgb([220, 220, 220]);
const FRAME: Rgb<u8> = Rgb([96, 96, 96]);
const MEAN_LINE: Rgb<u8> = Rgb([200, 0, 0]);

/// Corner markers are this fraction of the smaller image side (≥ 2 px): visible on a
/// 640×480 phone picture and on a 1280×720 render alike.
const MARKER_FRACTION: f64 = 1.0 / 160.0;

/// With an automatic magnification, the residual at [`ARROW_PERCENTILE`] is drawn this
/// fraction of the smaller image side long: long enough to read directions, short enough not
/// to cross the neighbouring corners' arrows.
const ARROW_FRACTION: f64 = 0.06;

/// The percentile of the residual norms that sets the automatic magnification: the 95th
/// ignores a few outliers, which then stand out as long arrows.
const ARROW_PERCENTILE: f64 = 0.95;

/// Widest bar drawn (px): wider is no more legible and keeps the picture's size in `u32`.
const MAX_BAR_WIDTH: u32 = 256;

/// Tallest plot area drawn (px), for the same reasons.
const MAX_CHART_HEIGHT: u32 = 4096;

/// Most bars drawn (views beyond are left out): 4096 views of 256 px stay within `u32`.
const MAX_BARS: u32 = 4096;

/// Options of the pictures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PictureConfig {
    /// Height of the bar chart's plot area (px; clamped to 10–4096).
    pub bar_chart_height: u32,
    /// Width of one bar (px, clamped to 1–256); bars are separated by half a bar.
    pub bar_width: u32,
    /// Residual arrows are drawn this many times longer than the residual; `None` picks a
    /// round value (1, 2 or 5 × 10ⁿ) that makes the 95th-percentile residual about 6 % of
    /// the smaller image side.
    pub magnification: Option<f64>,
}

impl Default for PictureConfig {
    fn default() -> Self {
        Self {
            bar_chart_height: 240,
            bar_width: 16,
            magnification: None,
        }
    }
}

/// The per-view error bar chart and its scale.
#[derive(Debug, Clone, PartialEq)]
pub struct BarChart {
    /// The picture.
    pub image: RgbImage,
    /// Bar height in pixels per pixel of RMS error.
    pub px_per_unit: f64,
    /// Light horizontal grid lines are drawn every `grid_step` px of RMS error.
    pub grid_step: f64,
    /// Bottom row of the plot area (bars grow upward from the row above it).
    pub baseline_y: u32,
    /// Horizontal centre of each bar (px), in view order.
    pub bar_centres: Vec<u32>,
}

/// The residual vector plot and its magnification.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualPlot {
    /// The picture, of the calibrated image's size.
    pub image: RgbImage,
    /// Arrow length over residual length.
    pub magnification: f64,
    /// The scale arrow in the bottom-left corner stands for a residual of this many pixels
    /// (a round value drawn at most a fifth of the image width long).
    pub scale_arrow_px: f64,
}

/// `(x, y)` of a point as the `f32` pair `imageproc` takes.
fn xy(p: &Point2<f64>) -> (f32, f32) {
    (p.x as f32, p.y as f32)
}

/// Whether a point lies within `margin` px of a `w × h` image (finite and drawable).
fn near_image(p: &Point2<f64>, w: u32, h: u32, margin: f64) -> bool {
    p.x >= -margin && p.y >= -margin && p.x <= f64::from(w) + margin && p.y <= f64::from(h) + margin
}

/// Nearest pixel of a point, saturating far outside any image.
fn ixy(p: &Point2<f64>) -> (i32, i32) {
    (p.x.round() as i32, p.y.round() as i32)
}

fn marker_radius(width: u32, height: u32) -> i32 {
    ((f64::from(width.min(height)) * MARKER_FRACTION).round() as i32).max(2)
}

/// The grey image in colour with the detected corners drawn over it, OpenCV style: the
/// corners of each row joined in order in the row's colour, rows joined last to first,
/// every corner circled, corner 0 a filled red disc and the last corner a filled disc of
/// its row's colour.
///
/// ```
/// use sl_calib::{BoardCorners, BoardSize, draw_corners};
/// use nalgebra::Point2;
/// let img = sl_calib::sl_codec::Frame::filled(100, 80, 128)?;
/// let corners = BoardCorners {
///     size: BoardSize::new(2, 2),
///     corners: vec![Point2::new(20.0, 20.0), Point2::new(60.0, 20.0),
///                   Point2::new(20.0, 50.0), Point2::new(60.0, 50.0)],
/// };
/// let pic = draw_corners(&img, &corners);
/// assert_eq!(pic.get_pixel(20, 20).0, [255, 0, 0]); // corner 0 in red
/// # Ok::<(), sl_calib::CalibError>(())
/// ```
pub fn draw_corners(image: &Frame<u8>, corners: &BoardCorners) -> RgbImage {
    // A side beyond u32 (4·10⁹ px, more than any camera's) is drawn cut at u32::MAX.
    let side = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    let (w, h) = (side(image.width()), side(image.height()));
    let mut out = RgbImage::from_fn(w, h, |x, y| {
        let v = image.get(x as usize, y as usize).unwrap_or(0);
        Rgb([v, v, v])
    });
    let r = marker_radius(w, h);
    let cols = (corners.size.cols as usize).max(1);
    let colour = |k: usize| PALETTE[(k / cols) % PALETTE.len()];
    for (k, pair) in corners.corners.windows(2).enumerate() {
        if let [a, b] = pair
            && let Some((t0, t1)) = clip(a, b, f64::from(w), f64::from(h))
        {
            let d = b - a;
            draw_line_segment_mut(
                &mut out,
                xy(&(a + d * t0)),
                xy(&(a + d * t1)),
                colour(k + 1),
            );
        }
    }
    let near = |p: &Point2<f64>| near_image(p, w, h, f64::from(r + 2));
    for (k, p) in corners.corners.iter().enumerate().filter(|(_, p)| near(p)) {
        draw_hollow_circle_mut(&mut out, ixy(p), r, colour(k));
        draw_hollow_circle_mut(&mut out, ixy(p), r + 1, colour(k));
    }
    if let Some(last) = corners.corners.last().filter(|p| near(p)) {
        let k = corners.corners.len() - 1;
        draw_filled_circle_mut(&mut out, ixy(last), r, colour(k));
    }
    if let Some(first) = corners.corners.first().filter(|p| near(p)) {
        draw_filled_circle_mut(&mut out, ixy(first), r + 1, FIRST_CORNER);
    }
    out
}

/// The round value (1, 2 or 5 × 10ⁿ) at or below `x > 0`.
fn round_down_125(x: f64) -> f64 {
    let e = x.log10().floor();
    let base = 10f64.powf(e);
    let m = x / base;
    let f = if m >= 5.0 {
        5.0
    } else if m >= 2.0 {
        2.0
    } else {
        1.0
    };
    f * base
}

/// A bar per view, of height proportional to its RMS error, on light grid lines, with the
/// overall RMS as a red horizontal line; views above [`OUTLIER_FACTOR`] × the median are
/// drawn in [`OUTLIER_BAR`]. The vertical scale puts the largest of the bars and the overall
/// RMS at 90 % of the plot height. Non-finite or negative values are drawn as empty bars.
///
/// ```
/// use sl_calib::{PictureConfig, error_bars};
/// let chart = error_bars(&[0.1, 0.2, 0.15], 0.16, &PictureConfig::default());
/// assert_eq!(chart.bar_centres.len(), 3);
/// ```
pub fn error_bars(view_rms: &[f64], overall_rms: f64, config: &PictureConfig) -> BarChart {
    let bar_w = config.bar_width.clamp(1, MAX_BAR_WIDTH);
    let gap = (bar_w / 2).max(1);
    let margin = 2 * bar_w;
    let plot_h = config.bar_chart_height.clamp(10, MAX_CHART_HEIGHT);
    let n = u32::try_from(view_rms.len())
        .unwrap_or(u32::MAX)
        .min(MAX_BARS);
    let width = 2 * margin + n * bar_w + n.saturating_sub(1) * gap;
    let height = plot_h + 2 * margin;
    let mut img = RgbImage::from_pixel(width, height, WHITE);
    let clean = |v: f64| if v.is_finite() && v > 0.0 { v } else { 0.0 };
    let top = view_rms
        .iter()
        .copied()
        .map(clean)
        .chain(std::iter::once(clean(overall_rms)))
        .fold(0.0, f64::max);
    let top = if top > 0.0 { top } else { 1.0 };
    let px_per_unit = 0.9 * f64::from(plot_h) / top;
    let grid_step = round_down_125(top / 4.0);
    let baseline_y = margin + plot_h;
    let mut g = grid_step;
    while g <= top * 1.1 {
        let y = f64::from(baseline_y) - g * px_per_unit;
        draw_line_segment_mut(
            &mut img,
            (margin as f32, y as f32),
            ((width - margin) as f32, y as f32),
            GRID,
        );
        g += grid_step;
    }
    let mut sorted: Vec<f64> = view_rms.iter().copied().map(clean).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let mut bar_centres = Vec::with_capacity(view_rms.len());
    for (k, &v) in view_rms.iter().enumerate().take(n as usize) {
        let x = margin + k as u32 * (bar_w + gap);
        bar_centres.push(x + bar_w / 2);
        let h = (clean(v) * px_per_unit).round() as u32;
        if h > 0 {
            let colour = if median > 0.0 && clean(v) > OUTLIER_FACTOR * median {
                OUTLIER_BAR
            } else {
                BAR
            };
            draw_filled_rect_mut(
                &mut img,
                Rect::at(x as i32, (baseline_y - h) as i32).of_size(bar_w, h),
                colour,
            );
        }
    }
    // Axes, then the overall RMS on top of the bars.
    draw_line_segment_mut(
        &mut img,
        (margin as f32 - 1.0, baseline_y as f32),
        ((width - margin) as f32, baseline_y as f32),
        FRAME,
    );
    draw_line_segment_mut(
        &mut img,
        (margin as f32 - 1.0, baseline_y as f32),
        (margin as f32 - 1.0, margin as f32),
        FRAME,
    );
    let y = (f64::from(baseline_y) - clean(overall_rms) * px_per_unit) as f32;
    draw_line_segment_mut(
        &mut img,
        (margin as f32 / 2.0, y),
        ((width - margin / 2) as f32, y),
        MEAN_LINE,
    );
    BarChart {
        image: img,
        px_per_unit,
        grid_step,
        baseline_y: baseline_y - 1,
        bar_centres,
    }
}

/// The part of the segment `a → b` inside `[-1, w] × [-1, h]` (Liang–Barsky), as the
/// parameters `(t0, t1)` of its ends; `None` if it misses the box or is not finite. Drawing
/// only that part keeps the time bounded whatever the residuals.
fn clip(a: &Point2<f64>, b: &Point2<f64>, w: f64, h: f64) -> Option<(f64, f64)> {
    let d = b - a;
    if !(d.x.is_finite() && d.y.is_finite() && a.x.is_finite() && a.y.is_finite()) {
        return None;
    }
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d.x, a.x + 1.0),
        (d.x, w - a.x),
        (-d.y, a.y + 1.0),
        (d.y, h - a.y),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// An arrow from `a` to `b` with a small filled head (the part inside the image).
fn arrow(img: &mut RgbImage, a: &Point2<f64>, b: &Point2<f64>, colour: Rgb<u8>, head: f64) {
    let (w, h) = (f64::from(img.width()), f64::from(img.height()));
    let Some((t0, t1)) = clip(a, b, w, h) else {
        return;
    };
    let d = b - a;
    let (ca, cb) = (a + d * t0, a + d * t1);
    draw_antialiased_line_segment_mut(img, ixy(&ca), ixy(&cb), colour, interpolate);
    let len = d.norm();
    if t1 < 1.0 || len < 2.0 * head {
        return; // the tip is outside the image, or the arrow too short for a head
    }
    let u = d / len;
    let n = Vector2::new(-u.y, u.x);
    let base = b - u * head;
    let p1 = base + n * (head * 0.5);
    let p2 = base - n * (head * 0.5);
    let ib = ixy(b);
    let poly = [
        Point::new(ib.0, ib.1),
        Point::new(p1.x.round() as i32, p1.y.round() as i32),
        Point::new(p2.x.round() as i32, p2.y.round() as i32),
    ];
    if poly[0] != poly[1] && poly[1] != poly[2] && poly[0] != poly[2] {
        draw_polygon_mut(img, &poly, colour);
    }
}

/// Every corner's residual (observed − predicted, px) as an arrow from the corner, magnified,
/// over a white picture of the image area (`width × height`, the calibrated image's size)
/// framed in grey; one colour per view (cycling through [`PALETTE`]). A scale arrow of
/// [`ResidualPlot::scale_arrow_px`] pixels of residual is drawn in the bottom-left corner.
/// Views and residuals are matched by index; extra entries of either are ignored; arrows
/// are clipped to the image and non-finite ones left out.
///
/// ```
/// use sl_calib::{PictureConfig, residual_plot};
/// use nalgebra::{Point2, Vector2};
/// let plot = residual_plot(
///     200, 100,
///     &[vec![Point2::new(50.0, 50.0)]],
///     &[vec![Vector2::new(0.5, 0.0)]],
///     &PictureConfig { magnification: Some(40.0), ..PictureConfig::default() },
/// );
/// assert_eq!(plot.image.get_pixel(60, 50).0, [0, 114, 178]); // on the arrow
/// ```
pub fn residual_plot(
    width: u32,
    height: u32,
    corners: &[Vec<Point2<f64>>],
    residuals: &[Vec<Vector2<f64>>],
    config: &PictureConfig,
) -> ResidualPlot {
    let (w, h) = (width.max(1), height.max(1));
    let mut img = RgbImage::from_pixel(w, h, WHITE);
    let mut norms: Vec<f64> = residuals
        .iter()
        .flatten()
        .map(|r| r.norm())
        .filter(|v| v.is_finite())
        .collect();
    norms.sort_by(f64::total_cmp);
    // A high percentile, not the maximum: one outlier must not shrink every other arrow.
    let typical_long = norms
        .get(((norms.len().saturating_sub(1)) as f64 * ARROW_PERCENTILE) as usize)
        .copied()
        .unwrap_or(0.0);
    let target = ARROW_FRACTION * f64::from(w.min(h));
    let magnification = match config.magnification {
        Some(m) if m.is_finite() && m > 0.0 => m,
        _ if typical_long > 0.0 => round_down_125(target / typical_long),
        _ => 1.0,
    };
    let head = f64::from(marker_radius(w, h)) * 1.5;
    for (k, (view, res)) in corners.iter().zip(residuals).enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        for (p, r) in view.iter().zip(res) {
            let tip = p + r * magnification;
            if near_image(p, w, h, 2.0) {
                draw_filled_circle_mut(&mut img, ixy(p), 1, colour);
            }
            arrow(&mut img, p, &tip, colour, head);
        }
    }
    // Frame of the image area and the scale arrow (1 px of residual).
    let frame = Rect::at(0, 0).of_size(w, h);
    imageproc::drawing::draw_hollow_rect_mut(&mut img, frame, FRAME);
    let y = f64::from(h) - 3.0 * head;
    let a = Point2::new(3.0 * head, y);
    let scale_arrow_px = round_down_125(f64::from(w) / 5.0 / magnification);
    let b = Point2::new(3.0 * head + magnification * scale_arrow_px, y);
    arrow(&mut img, &a, &b, FRAME, head);
    ResidualPlot {
        image: img,
        magnification,
        scale_arrow_px,
    }
}

/// Writes a picture as PNG (through `sl_codec::write_png_rgb8`, the workspace's one PNG writer).
///
/// # Errors
/// [`CalibError::Codec`] naming the file when it cannot be written.
pub fn save_png(image: &RgbImage, path: impl AsRef<Path>) -> Result<(), CalibError> {
    sl_codec::write_png_rgb8(
        path.as_ref(),
        image.width() as usize,
        image.height() as usize,
        image.as_raw(),
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_values() {
        assert_eq!(round_down_125(0.37), 0.2);
        assert_eq!(round_down_125(7.0), 5.0);
        assert_eq!(round_down_125(19.0), 10.0);
    }
}
