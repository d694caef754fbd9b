//! Checkerboard detection: saddle-point candidates, a grid grown from them, a board-fixed
//! corner order, and sub-pixel saddle refinement.

use std::collections::{HashMap, VecDeque};

use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};
use sl_codec::Frame;

use crate::CalibError;
use crate::grey::GreyF32;
use crate::junction::{BinnedImage, JunctionStart, refine_junction};
use crate::saddle::{refine_saddle, refine_saddle_coarse};
use rayon::prelude::*;

/// The inner-corner grid of a checkerboard: `cols` corners along a row (the board's `x`),
/// `rows` corners along a column (the board's `y`). OpenCV's `patternSize = (cols, rows)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoardSize {
    /// Inner corners along a row.
    pub cols: u32,
    /// Inner corners along a column.
    pub rows: u32,
}

/// `COLSxROWS`, as [`BoardSize`] parses it.
impl std::fmt::Display for BoardSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.cols, self.rows)
    }
}

/// Parses `COLSxROWS` (`9x6`; `X` too, spaces around the numbers allowed): at least 2×2 inner
/// corners, the smallest grid a board pose can be told from.
///
/// ```
/// use sl_calib::BoardSize;
/// assert_eq!("9x6".parse::<BoardSize>()?, BoardSize::new(9, 6));
/// assert_eq!(BoardSize::new(9, 6).to_string(), "9x6");
/// assert!("9".parse::<BoardSize>().is_err() && "1x6".parse::<BoardSize>().is_err());
/// # Ok::<(), sl_calib::CalibError>(())
/// ```
impl std::str::FromStr for BoardSize {
    type Err = CalibError;

    fn from_str(s: &str) -> Result<Self, CalibError> {
        let bad = |reason: &str| CalibError::InvalidParameter {
            name: "board".to_owned(),
            reason: format!("{s:?}: {reason}"),
        };
        let (c, r) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| bad("expected inner corners as COLSxROWS, e.g. 9x6"))?;
        let count = |t: &str| t.trim().parse::<u32>().ok();
        let (Some(cols), Some(rows)) = (count(c), count(r)) else {
            return Err(bad("expected inner corners as COLSxROWS, e.g. 9x6"));
        };
        if cols < 2 || rows < 2 {
            return Err(bad("at least 2x2 inner corners"));
        }
        Ok(Self::new(cols, rows))
    }
}

impl BoardSize {
    /// A board of `cols × rows` inner corners.
    pub fn new(cols: u32, rows: u32) -> Self {
        Self { cols, rows }
    }

    /// Number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.cols as usize * self.rows as usize
    }

    /// The inner corners in the board frame for squares of `square` units (mm or any unit),
    /// row by row: corner `(i, j)` at index `j · cols + i` is `(i · square, j · square, 0)`.
    pub fn object_points(&self, square: f64) -> Vec<nalgebra::Point3<f64>> {
        let mut out = Vec::with_capacity(self.corner_count());
        for j in 0..self.rows {
            for i in 0..self.cols {
                out.push(nalgebra::Point3::new(
                    f64::from(i) * square,
                    f64::from(j) * square,
                    0.0,
                ));
            }
        }
        out
    }
}

/// Settings of [`detect_checkerboard`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DetectorConfig {
    /// Gaussian blur (px) before the saddle response: wide enough to bridge JPEG noise and
    /// blur, narrow enough to keep neighbouring corners apart (squares of ≥ 8 px).
    pub detect_sigma: f64,
    /// Radius (px) of the circle sampled around a candidate; a corner must show exactly two
    /// dark and two bright sectors on it.
    pub ring_radius: f64,
    /// Smallest grey-level difference between the bright and dark sectors on the ring.
    pub min_contrast: f64,
    /// Strongest candidates kept after non-maximum suppression (bounds the time on cluttered
    /// images).
    pub max_candidates: usize,
    /// Candidates tried as the seed of the grid before giving up (bounds the time on images
    /// without a board).
    pub max_seeds: usize,
    /// Gaussian blur (px) of the image the saddle fit is made on.
    pub refine_sigma: f64,
    /// Half-width of the saddle-fit window as a fraction of the distance to the nearest
    /// grid neighbour: below one half, the window never reaches the neighbouring corners
    /// (the cause of `cornerSubPix`'s drift). Measured: 0.15 beats 0.22 and 0.3 both on the
    /// virtual rig (mean error 0.039 px) and on OpenCV's sample images (RMS 0.165 px): the
    /// saddle model holds best close to the junction.
    pub refine_fraction: f64,
    /// Smallest half-width (px) of the saddle-fit window.
    pub min_refine_radius: usize,
    /// Largest half-width (px) of the saddle-fit window (bounds the time on big squares).
    pub max_refine_radius: usize,
    /// Radius of the junction-model fit (a second refinement, on the raw image) as a
    /// fraction of the distance to the nearest grid neighbour: 0.6 by default
    /// ([`CornerRefiner::Junction`]); `0` turns the junction fit off and keeps the saddle
    /// points ([`CornerRefiner::Saddle`]). The model (two blurred straight edges with an
    /// offset and a contrast that vary linearly) holds up to the neighbouring corners, so the
    /// window can be wide and average much noise; less than one half keeps the neighbours'
    /// blurred junctions out of it. It gives the lower calibration RMS on the real board sets
    /// (OpenCV's samples, `procam_kamino`'s white frames and fringe means) and corners closer
    /// to the truth on renders whose pixels integrate the light over their area (see
    /// `docs/performance.md`, "The corner default").
    pub junction_fraction: f64,
    /// Smallest radius (px) of the junction-fit window.
    pub min_junction_radius: f64,
    /// Largest radius (px) of the junction-fit window: bounds the time on big squares, and
    /// keeps the window small enough that lens distortion leaves the edges straight in it.
    pub max_junction_radius: f64,
}

impl Default for DetectorConfig {
    /// Tuned on 640×480 images with squares of 20–60 px.
    fn default() -> Self {
        Self {
            detect_sigma: 1.5,
            ring_radius: 5.0,
            min_contrast: 12.0,
            max_candidates: 600,
            max_seeds: 60,
            refine_sigma: 1.0,
            refine_fraction: 0.15,
            min_refine_radius: 2,
            max_refine_radius: 10,
            junction_fraction: JUNCTION_FRACTION,
            min_junction_radius: 4.0,
            max_junction_radius: 24.0,
        }
    }
}

impl DetectorConfig {
    /// The defaults with the junction-model fit on (`junction_fraction` 0.6, windows of 4–24
    /// px; the default since 2026-11-28): 1.5–16 times more accurate than OpenCV's
    /// `cornerSubPix` on realistic renders and up to 7 times more than the saddle points
    /// (`docs/performance.md`).
    pub fn with_junction_fit() -> Self {
        Self {
            junction_fraction: JUNCTION_FRACTION,
            ..Self::default()
        }
    }

    /// The defaults with the corners refined by `refiner`.
    pub fn with_refiner(refiner: CornerRefiner) -> Self {
        match refiner {
            CornerRefiner::Saddle => Self {
                junction_fraction: 0.0,
                ..Self::default()
            },
            CornerRefiner::Junction => Self::with_junction_fit(),
        }
    }

    /// The refinement these settings run: the junction fit when its window is on.
    pub fn refiner(&self) -> CornerRefiner {
        if self.junction_fraction > 0.0 {
            CornerRefiner::Junction
        } else {
            CornerRefiner::Saddle
        }
    }
}

/// How the corners of a checkerboard are refined to sub-pixel positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CornerRefiner {
    /// The saddle point of a quadratic fitted to the blurred image in a small window around
    /// the corner (`refine_fraction` of the grid step).
    Saddle,
    /// The saddle point, then a model of two blurred straight edges crossing, fitted to the
    /// raw image in a wide window (`junction_fraction` of the grid step).
    #[default]
    Junction,
}

impl CornerRefiner {
    /// Both refiners, in the order the command line lists them.
    pub const ALL: [CornerRefiner; 2] = [CornerRefiner::Saddle, CornerRefiner::Junction];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Saddle => "saddle",
            Self::Junction => "junction",
        }
    }
}

impl std::fmt::Display for CornerRefiner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for CornerRefiner {
    type Err = CalibError;

    /// `saddle` or `junction`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|r| r.name() == s)
            .ok_or_else(|| CalibError::InvalidParameter {
                name: "corner refiner".to_owned(),
                reason: format!("{s:?} is neither \"saddle\" nor \"junction\""),
            })
    }
}

/// Junction-fit radius as a fraction of the grid step in [`DetectorConfig::with_junction_fit`]:
/// measured best on the corner harness (0.6 of the step, up to the 24 px cap).
const JUNCTION_FRACTION: f64 = 0.6;

/// The detected inner corners of a board, in the board's own order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardCorners {
    /// The grid searched for.
    pub size: BoardSize,
    /// Sub-pixel corner positions (px), row by row: corner `(i, j)` at index `j · cols + i`,
    /// matching [`BoardSize::object_points`].
    pub corners: Vec<Point2<f64>>,
}

/// Samples on the ring test circle (every 11.25°): enough for four sectors of at least two
/// samples each under 60° of perspective shear.
const RING_SAMPLES: usize = 32;

/// Largest mean difference between opposite ring samples, relative to the ring's contrast:
/// a sharp X-junction scores ~0.05 (blur and sampling), a T-junction ≥ 0.5.
const MAX_ASYMMETRY: f64 = 0.3;

/// Half-width of the non-maximum suppression window (px): about the blur's reach.
const NMS_RADIUS: isize = 3;

/// Candidates must have a response above this fraction of the strongest one; low enough for
/// dim corners under uneven light, high enough to drop JPEG noise.
const RELATIVE_RESPONSE: f32 = 0.01;

/// A predicted grid neighbour is accepted within this fraction of the local grid step:
/// perspective changes the step by far less between neighbours.
const MATCH_TOLERANCE: f64 = 0.3;

/// Number of nearest candidates looked at to pick the seed's two grid directions.
const SEED_NEIGHBOURS: usize = 8;

#[derive(Debug, Clone, Copy)]
struct Candidate {
    p: Point2<f64>,
    response: f32,
}

/// Finds the inner corners of a `size` checkerboard in a grey image and refines them to
/// sub-pixel precision.
///
/// The order is fixed by the board, not by the image: corner 0 is the inner corner whose
/// diagonal outer square is dark, rows run along the `cols` direction, and going from row
/// to column turns clockwise in the image (the board is seen from its printed side). On
/// boards where one dimension is even and the other odd this makes the order unique, so a
/// camera and a projector, or two cameras, always agree; on boards with both dimensions even
/// or both odd a 180° turn is indistinguishable and the colour test picks one of the two.
///
/// `label` names the image in errors (e.g. its file name).
///
/// # Errors
/// [`CalibError::BoardNotFound`] with the reason (no corner-like points, no grid of the
/// requested size, ...); [`CalibError::InvalidParameter`] for a board smaller than 2×2.
///
/// ```
/// use sl_calib::{BoardSize, DetectorConfig, detect_checkerboard};
/// use sl_calib::sl_codec::Frame;
/// // A synthetic 4x3 board of 20 px squares.
/// let (w, h) = (160, 140);
/// let pixels = (0..w * h).map(|k| {
///     let (x, y) = ((k % w) as i32, (k / w) as i32);
///     let (i, j) = ((x - 30).div_euclid(20), (y - 30).div_euclid(20));
///     let inside = (0..5).contains(&i) && (0..4).contains(&j);
///     if inside && (i + j) % 2 == 0 { 30 } else { 220 }
/// });
/// let img = Frame::new(w, h, pixels.collect())?;
/// let found = detect_checkerboard(&img, BoardSize::new(4, 3), &DetectorConfig::default(), "synthetic")?;
/// // The first inner corner sits between the squares at (30..50, 30..50) and its neighbours.
/// assert!((found.corners[0].x - 49.5).abs() < 0.05 && (found.corners[0].y - 49.5).abs() < 0.05);
/// # Ok::<(), sl_calib::CalibError>(())
/// ```
pub fn detect_checkerboard(
    image: &Frame<u8>,
    size: BoardSize,
    config: &DetectorConfig,
    label: &str,
) -> Result<BoardCorners, CalibError> {
    if size.cols < 2 || size.rows < 2 {
        return Err(CalibError::param(
            "board size",
            format!("{}x{}: at least 2x2 inner corners", size.cols, size.rows),
        ));
    }
    let not_found = |reason: String| CalibError::BoardNotFound {
        image: label.to_owned(),
        cols: size.cols,
        rows: size.rows,
        reason,
    };
    let grey = GreyF32::from_luma(image);
    let detect = grey.blurred(config.detect_sigma as f32);
    let ordered = match find_grid(&detect, size, config) {
        Ok(ordered) => ordered,
        Err(reason) => {
            // A large, defocused image: the blur spreads the corners beyond the fixed ring
            // and the saddle response. Halving the image halves the blur (in pixels) and the
            // squares: retry at half, quarter, ... resolution while the squares can still be
            // resolved, and scale the grid back up; the refinement runs on the full image.
            let mut level = grey.clone();
            let mut scale = 1.0f64;
            let mut found = None;
            while level.width.min(level.height) / 2 >= MIN_PYRAMID_SIDE {
                level = level.half();
                scale *= 2.0;
                if let Ok(pts) = find_grid(&level.blurred(config.detect_sigma as f32), size, config)
                {
                    // Level pixel X covers full pixels scale·X .. scale·X + scale − 1.
                    let shift = 0.5 * (scale - 1.0);
                    found = Some(
                        pts.iter()
                            .map(|p| Point2::new(scale * p.x + shift, scale * p.y + shift))
                            .collect::<Vec<_>>(),
                    );
                    break;
                }
            }
            found.ok_or_else(|| not_found(reason))?
        }
    };
    let refine = grey.blurred(config.refine_sigma as f32);
    let binned = grey.half();
    let (cols, rows) = (size.cols as usize, size.rows as usize);
    let refined: Vec<Option<Point2<f64>>> = ordered
        .par_iter()
        .enumerate()
        .map(|(k, p)| {
            let (step, grid) = grid_context(&ordered, cols, rows, k, *p);
            refine_corner(&grey, &binned, &refine, &detect, *p, step, grid, config)
        })
        .collect();
    // A grid point far from its corner (the detection took a point on an edge, where fringe
    // ripple crosses it, for the corner) does not refine: retry from the refined neighbours'
    // prediction.
    let mut corners = Vec::with_capacity(refined.len());
    for (k, r) in refined.iter().enumerate() {
        let c = match r {
            Some(c) => *c,
            None => {
                let p = ordered[k];
                let retry = predict_from_neighbours(&refined, cols, rows, k).and_then(|q| {
                    let (step, grid) = grid_context(&ordered, cols, rows, k, q);
                    refine_corner(&grey, &binned, &refine, &detect, q, step, grid, config)
                });
                retry.ok_or_else(|| {
                    not_found(format!(
                        "corner {k} at ({:.1}, {:.1}) is not a saddle point under refinement",
                        p.x, p.y
                    ))
                })?
            }
        };
        corners.push(c);
    }
    Ok(BoardCorners { size, corners })
}

/// Images (or pyramid levels) whose short side is below this are not halved further: a
/// board of at least 3×3 squares of ≥ 8 px needs about this many pixels.
const MIN_PYRAMID_SIDE: usize = 160;

/// Largest distance (px) the junction fit may move a corner from the saddle point: the
/// saddle is biased by uneven light by a few tenths of a pixel at most; a larger move means
/// the fit has locked onto something else.
const JUNCTION_MAX_SHIFT_PX: f64 = 1.0;

/// The directions (px, not normalised) of the grid's row and column through a corner.
#[derive(Debug, Clone, Copy)]
struct GridDirections {
    row: nalgebra::Vector2<f64>,
    column: nalgebra::Vector2<f64>,
}

impl GridDirections {
    /// The angles (radians) of the normals of the two board edges through the corner.
    fn edge_normals(&self) -> Option<(f64, f64)> {
        let normal = |d: nalgebra::Vector2<f64>| (d.norm() > 0.0).then(|| d.x.atan2(-d.y));
        Some((normal(self.row)?, normal(self.column)?))
    }
}

/// The distance (px) from grid point `k` (at `p`) to its nearest grid neighbour, and the
/// grid's row and column directions there (from the neighbours on both sides where there
/// are two).
fn grid_context(
    points: &[Point2<f64>],
    cols: usize,
    rows: usize,
    k: usize,
    p: Point2<f64>,
) -> (f64, GridDirections) {
    let (i, j) = (k % cols, k / cols);
    let neighbours = [
        (i > 0).then(|| k - 1),
        (i + 1 < cols).then(|| k + 1),
        (j > 0).then(|| k - cols),
        (j + 1 < rows).then(|| k + cols),
    ];
    let step = neighbours
        .iter()
        .flatten()
        .filter_map(|&n| points.get(n))
        .map(|q| (q - p).norm())
        .fold(f64::INFINITY, f64::min);
    let along = |before: Option<usize>, after: Option<usize>| {
        let a = before.and_then(|n| points.get(n)).copied().unwrap_or(p);
        let b = after.and_then(|n| points.get(n)).copied().unwrap_or(p);
        b - a
    };
    let grid = GridDirections {
        row: along(neighbours[0], neighbours[1]),
        column: along(neighbours[2], neighbours[3]),
    };
    (step, grid)
}

/// Where corner `k` should be from its refined neighbours: the mean of the midpoints of
/// opposite neighbours and of the straight-line extrapolations of two neighbours in a row
/// or column (exact under an affine view; under perspective off by a small fraction of a
/// square, well inside the saddle fit's reach).
fn predict_from_neighbours(
    refined: &[Option<Point2<f64>>],
    cols: usize,
    rows: usize,
    k: usize,
) -> Option<Point2<f64>> {
    let (i, j) = (k as isize % cols as isize, k as isize / cols as isize);
    let at = |di: isize, dj: isize| -> Option<Point2<f64>> {
        let (a, b) = (i + di, j + dj);
        if a < 0 || b < 0 || a >= cols as isize || b >= rows as isize {
            return None;
        }
        refined
            .get(b as usize * cols + a as usize)
            .copied()
            .flatten()
    };
    let mut guesses = Vec::new();
    for (di, dj) in [(1, 0), (0, 1)] {
        if let (Some(a), Some(b)) = (at(-di, -dj), at(di, dj)) {
            guesses.push(a + 0.5 * (b - a));
        }
        for s in [-1, 1] {
            if let (Some(a), Some(b)) = (at(s * di, s * dj), at(2 * s * di, 2 * s * dj)) {
                guesses.push(a + (a - b));
            }
        }
    }
    let n = guesses.len();
    (n > 0).then(|| {
        Point2::from(
            guesses
                .iter()
                .map(|g| g.coords)
                .sum::<nalgebra::Vector2<f64>>()
                / n as f64,
        )
    })
}

/// Refines the grid point `p` (px) whose nearest grid neighbour is `step` px away: the saddle
/// point on the `refine` image (retried on the more blurred `detect` image), then the
/// junction model on the raw `grey` image when it is on and succeeds; without a saddle
/// point, the junction model from `p` and the `grid` directions.
// The images of the three stages and the corner's grid context: one call per corner.
#[allow(clippy::too_many_arguments)]
fn refine_corner(
    grey: &GreyF32,
    binned: &GreyF32,
    refine: &GreyF32,
    detect: &GreyF32,
    p: Point2<f64>,
    step: f64,
    grid: GridDirections,
    config: &DetectorConfig,
) -> Option<Point2<f64>> {
    let radius = ((config.refine_fraction * step).floor() as usize).clamp(
        config.min_refine_radius,
        config.max_refine_radius.max(config.min_refine_radius),
    );
    let saddle = refine_saddle(refine, p, radius)
        .or_else(|| refine_saddle(detect, p, radius))
        .or_else(|| {
            // Coarse to fine: a window of a fifth of the step seen through samples
            // `spacing` apart, then the fine fit from there.
            let spacing = (step / COARSE_SAMPLES_PER_STEP).max(1.0);
            let coarse = refine_saddle_coarse(detect, p, COARSE_RADIUS, spacing)?;
            refine_saddle(refine, coarse.point, radius)
                .or_else(|| refine_saddle(detect, coarse.point, radius))
        });
    if config.junction_fraction <= 0.0 {
        return saddle.map(|s| s.point);
    }
    let jr = (config.junction_fraction * step).clamp(
        config.min_junction_radius,
        config.max_junction_radius.max(config.min_junction_radius),
    );
    let Some(s) = saddle else {
        // No saddle point (fringe ripple or noise has more curvature than the corner at the
        // saddle fit's scale): the junction model alone, started from the grid point and the
        // grid's directions, over the whole window. It may move further: the grid point
        // is only as good as the detection level (a pyramid level's pixel).
        let (a1, a2) = grid.edge_normals()?;
        let full = BinnedImage { grey, scale: 1.0 };
        let j = refine_junction(
            &full,
            p,
            JunctionStart::Normals(a1, a2),
            jr,
            GRID_START_MAX_SHIFT_PX,
        )?;
        return Some(j.corner);
    };
    // First the full-resolution fit in a window of at most BIN_RADIUS_PX, then, where the
    // window should be larger, the wide fit from there: on the 2×2-binned image when the
    // edges are blurred enough.
    let full = BinnedImage { grey, scale: 1.0 };
    let Some(near) = refine_junction(
        &full,
        s.point,
        JunctionStart::Saddle(&s),
        jr.min(BIN_RADIUS_PX),
        JUNCTION_MAX_SHIFT_PX,
    ) else {
        return Some(s.point);
    };
    if jr <= BIN_RADIUS_PX {
        return Some(near.corner);
    }
    let wide_image = if near.blur >= BIN_MIN_BLUR {
        BinnedImage {
            grey: binned,
            scale: 2.0,
        }
    } else {
        full
    };
    let wide = refine_junction(
        &wide_image,
        s.point,
        JunctionStart::Fit(&near),
        jr,
        JUNCTION_MAX_SHIFT_PX,
    );
    Some(wide.map_or(near.corner, |j| j.corner))
}

/// Largest distance (px) the junction fit started from a grid point (no saddle point) may
/// move it: the grid point comes from the detection image, blurred and possibly a pyramid
/// level of 2–4 px pixels, so it may be a few pixels off the corner.
const GRID_START_MAX_SHIFT_PX: f64 = 4.0;

/// Fitted edge scale (px, of the junction model's `tanh` profile, about 1.25 σ of a Gaussian
/// blur plus the pixel's box) from which the wide junction window is fitted on the
/// 2×2-binned image (a quarter of the samples, the same noise averaging): a lens blur of
/// σ ≈ 1.5 px. Sharper edges lose their position to the binning's coarser sampling
/// (measured on the harness: 0.003 px → 0.025 px on sharp renders, 0.0065 → 0.0122 px at
/// σ = 1) and are fitted at full resolution.
const BIN_MIN_BLUR: f64 = 2.0;

/// Junction windows of a larger radius (px) are fitted in two stages: this radius at full
/// resolution, then the whole window (on the 2×2-binned image when the edges are blurred:
/// a quarter of the samples with the same noise averaging).
const BIN_RADIUS_PX: f64 = 12.0;

/// Grid steps are sampled this many times by the coarse saddle fit.
const COARSE_SAMPLES_PER_STEP: f64 = 20.0;

/// Half-width (samples) of the coarse saddle fit's window: 4 of 20 samples per step make a
/// window of ±0.2 step, which sees the junction's shape but not the neighbouring corners.
const COARSE_RADIUS: usize = 4;

/// The grid of `size` in the (blurred) image `detect`, in board order, at the candidates'
/// whole-pixel positions; or why not.
fn find_grid(
    detect: &GreyF32,
    size: BoardSize,
    config: &DetectorConfig,
) -> Result<Vec<Point2<f64>>, String> {
    let candidates = saddle_candidates(detect, config);
    if candidates.len() < size.corner_count() {
        return Err(format!(
            "only {} corner-like points (two dark and two bright sectors, contrast >= {}) in the image",
            candidates.len(),
            config.min_contrast
        ));
    }
    let mut best_found = 0usize;
    // Candidates already part of a grid that failed are not tried again as seeds: growing
    // from them finds the same grid (this keeps the time bounded on cluttered images).
    let mut tried = vec![false; candidates.len()];
    for seed in 0..candidates.len().min(config.max_seeds) {
        if tried.get(seed).copied().unwrap_or(true) {
            continue;
        }
        let Some(grid) = grow_grid(&candidates, seed) else {
            continue;
        };
        for &k in grid.values() {
            if let Some(t) = tried.get_mut(k) {
                *t = true;
            }
        }
        best_found = best_found.max(grid.len());
        if let Some(ordered) = order_grid(&grid, &candidates, size, detect) {
            return Ok(ordered);
        }
    }
    Err(format!(
        "{} candidate corners, but the largest regular grid grown from the {} strongest has {} corners, not {}",
        candidates.len(),
        candidates.len().min(config.max_seeds),
        best_found,
        size.corner_count()
    ))
}

/// Local maxima of the saddle response `Ixy² − Ixx·Iyy` that pass the ring test, strongest
/// first.
fn saddle_candidates(img: &GreyF32, config: &DetectorConfig) -> Vec<Candidate> {
    let (w, h) = (img.width, img.height);
    let margin = (config.ring_radius.ceil() as usize + 2).max(NMS_RADIUS as usize + 1);
    if w <= 2 * margin || h <= 2 * margin {
        return Vec::new();
    }
    let mut response = vec![0.0f32; w * h];
    let mut max_r = 0.0f32;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let c = img.data[i];
            let ixx = img.data[i + 1] - 2.0 * c + img.data[i - 1];
            let iyy = img.data[i + w] - 2.0 * c + img.data[i - w];
            let ixy = 0.25
                * (img.data[i + w + 1] - img.data[i + w - 1] - img.data[i - w + 1]
                    + img.data[i - w - 1]);
            let r = ixy * ixy - ixx * iyy;
            response[i] = r;
            max_r = max_r.max(r);
        }
    }
    if max_r <= 0.0 {
        return Vec::new();
    }
    let threshold = RELATIVE_RESPONSE * max_r;
    let mut out = Vec::new();
    for y in margin..h - margin {
        'px: for x in margin..w - margin {
            let r = response[y * w + x];
            if r <= threshold {
                continue;
            }
            for dy in -NMS_RADIUS..=NMS_RADIUS {
                for dx in -NMS_RADIUS..=NMS_RADIUS {
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let j = (y as isize + dy) as usize * w + (x as isize + dx) as usize;
                    let o = response[j];
                    // Ties broken by index so that a plateau keeps exactly one maximum.
                    if o > r || (o == r && j < y * w + x) {
                        continue 'px;
                    }
                }
            }
            let p = Point2::new(x as f64, y as f64);
            if ring_test(img, p, config.ring_radius, config.min_contrast) {
                out.push(Candidate { p, response: r });
            }
        }
    }
    out.sort_by(|a, b| b.response.total_cmp(&a.response));
    out.truncate(config.max_candidates);
    out
}

/// `true` when the circle of `radius` around `p` crosses exactly four dark/bright sectors
/// with enough contrast.
fn ring_test(img: &GreyF32, p: Point2<f64>, radius: f64, min_contrast: f64) -> bool {
    let mut values = [0.0f64; RING_SAMPLES];
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (k, v) in values.iter_mut().enumerate() {
        let a = std::f64::consts::TAU * k as f64 / RING_SAMPLES as f64;
        *v = img.sample(p.x + radius * a.cos(), p.y + radius * a.sin());
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if hi - lo < min_contrast {
        return false;
    }
    let mid = 0.5 * (lo + hi);
    let mut transitions = 0;
    let mut run = 0usize;
    let mut shortest = usize::MAX;
    // Start just after a transition so that runs are counted whole.
    let start = (0..RING_SAMPLES)
        .find(|&k| (values[k] > mid) != (values[(k + RING_SAMPLES - 1) % RING_SAMPLES] > mid));
    let Some(start) = start else { return false };
    for step in 0..RING_SAMPLES {
        let k = (start + step) % RING_SAMPLES;
        let next = (k + 1) % RING_SAMPLES;
        run += 1;
        if (values[k] > mid) != (values[next] > mid) {
            transitions += 1;
            shortest = shortest.min(run);
            run = 0;
        }
    }
    if transitions != 4 || shortest < 2 {
        return false;
    }
    // An X-junction is centrally symmetric (opposite sectors have the same colour); T- and
    // L-junctions at the board's outline and clutter are not.
    let half = RING_SAMPLES / 2;
    let asym: f64 = (0..half)
        .map(|k| (values[k] - values[k + half]).abs())
        .sum::<f64>()
        / half as f64;
    asym < MAX_ASYMMETRY * (hi - lo)
}

/// Grows a grid of candidates from `seed`: grid cell → candidate index. `None` when the seed
/// has no two independent neighbours.
fn grow_grid(cands: &[Candidate], seed: usize) -> Option<HashMap<(i32, i32), usize>> {
    let s = cands.get(seed)?.p;
    let mut near: Vec<(f64, usize)> = cands
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != seed)
        .map(|(k, c)| ((c.p - s).norm(), k))
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near.truncate(SEED_NEIGHBOURS);
    let (_, first) = *near.first()?;
    let v1 = cands.get(first)?.p - s;
    let (_, second) = *near.iter().find(|(_, k)| {
        cands
            .get(*k)
            .map(|c| (c.p - s).normalize().dot(&v1.normalize()).abs() < 0.5)
            .unwrap_or(false)
    })?;
    let v2 = cands.get(second)?.p - s;
    let mut grid: HashMap<(i32, i32), usize> = HashMap::new();
    let mut used = vec![false; cands.len()];
    grid.insert((0, 0), seed);
    *used.get_mut(seed)? = true;
    let mut queue = VecDeque::from([(0i32, 0i32)]);
    let pos = |grid: &HashMap<(i32, i32), usize>, c: (i32, i32)| -> Option<Point2<f64>> {
        grid.get(&c).and_then(|&k| cands.get(k)).map(|c| c.p)
    };
    // Bound the growth: a board bigger than 64 corners per side is outside the scope.
    const MAX_EXTENT: i32 = 64;
    while let Some((i, j)) = queue.pop_front() {
        let p = pos(&grid, (i, j))?;
        for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            let target = (i + di, j + dj);
            if grid.contains_key(&target)
                || target.0.abs() > MAX_EXTENT
                || target.1.abs() > MAX_EXTENT
            {
                continue;
            }
            // Predict the step from the known neighbours, second order when possible.
            let back = pos(&grid, (i - di, j - dj));
            let back2 = pos(&grid, (i - 2 * di, j - 2 * dj));
            let step: Vector2<f64> = match (back, back2) {
                (Some(b), Some(b2)) => (p - b) + ((p - b) - (b - b2)),
                (Some(b), None) => p - b,
                _ => {
                    // A parallel step from a side neighbour, else the seed's vectors.
                    let side = [(dj, di), (-dj, -di)].iter().find_map(|&(si, sj)| {
                        let a = pos(&grid, (i + si, j + sj))?;
                        let b = pos(&grid, (i + si + di, j + sj + dj))?;
                        Some(b - a)
                    });
                    side.unwrap_or(match (di, dj) {
                        (1, 0) => v1,
                        (-1, 0) => -v1,
                        (0, 1) => v2,
                        _ => -v2,
                    })
                }
            };
            let predicted = p + step;
            let tol = MATCH_TOLERANCE * step.norm();
            let best = cands
                .iter()
                .enumerate()
                .filter(|(k, _)| !used.get(*k).copied().unwrap_or(true))
                .map(|(k, c)| ((c.p - predicted).norm(), k))
                .filter(|(d, _)| *d < tol)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((_, k)) = best {
                grid.insert(target, k);
                if let Some(u) = used.get_mut(k) {
                    *u = true;
                }
                queue.push_back(target);
            }
        }
    }
    Some(grid)
}

/// Checks that `grid` is exactly a `size` board and returns its corners in board order.
fn order_grid(
    grid: &HashMap<(i32, i32), usize>,
    cands: &[Candidate],
    size: BoardSize,
    img: &GreyF32,
) -> Option<Vec<Point2<f64>>> {
    if grid.len() < size.corner_count() {
        return None;
    }
    let (gi0, gi1) = (
        grid.keys().map(|c| c.0).min()?,
        grid.keys().map(|c| c.0).max()?,
    );
    let (gj0, gj1) = (
        grid.keys().map(|c| c.1).min()?,
        grid.keys().map(|c| c.1).max()?,
    );
    // Every fully populated window of the board's size, in either orientation: stray
    // matches beyond the board's outline are tolerated, an ambiguous grid is not.
    let mut windows = Vec::new();
    for (w, h, transpose) in [(size.cols, size.rows, false), (size.rows, size.cols, true)] {
        if transpose && size.cols == size.rows {
            break;
        }
        let (w, h) = (w as i32, h as i32);
        for i0 in gi0..=gi1 - w + 1 {
            for j0 in gj0..=gj1 - h + 1 {
                let full = (0..h).all(|j| (0..w).all(|i| grid.contains_key(&(i0 + i, j0 + j))));
                if full {
                    windows.push((i0, j0, transpose));
                }
            }
        }
    }
    let &[(i0, j0, transpose)] = windows.as_slice() else {
        return None;
    };
    let (cols, rows) = (size.cols as i32, size.rows as i32);
    // Board (i, j) → grid cell, before the orientation fixes.
    let cell = |i: i32, j: i32| {
        if transpose {
            (i0 + j, j0 + i)
        } else {
            (i0 + i, j0 + j)
        }
    };
    let mut pts = Vec::with_capacity(size.corner_count());
    for j in 0..rows {
        for i in 0..cols {
            let k = *grid.get(&cell(i, j))?;
            pts.push(cands.get(k)?.p);
        }
    }
    let at = |pts: &[Point2<f64>], i: i32, j: i32| pts.get((j * cols + i) as usize).copied();
    // Handedness: x → y must turn clockwise in the image (y down), i.e. a positive cross.
    let o = at(&pts, 0, 0)?;
    let dx = at(&pts, 1, 0)? - o;
    let dy = at(&pts, 0, 1)? - o;
    if dx.x * dy.y - dx.y * dy.x < 0.0 {
        pts = (0..rows)
            .rev()
            .flat_map(|j| (0..cols).map(move |i| (i, j)))
            .filter_map(|(i, j)| at(&pts, i, j))
            .collect();
    }
    // Colour: corner 0's outer diagonal square must be the dark one.
    let o = at(&pts, 0, 0)?;
    // Diagonal squares of a corner share their colour, so compare the outer square with its
    // neighbour along the first row (square (0, -1), light on a board whose square (-1, -1)
    // is dark).
    let hx = (at(&pts, 1, 0)? - o) * 0.5;
    let hy = (at(&pts, 0, 1)? - o) * 0.5;
    let outer = img.sample(o.x - hx.x - hy.x, o.y - hx.y - hy.y);
    let beside = img.sample(o.x + hx.x - hy.x, o.y + hx.y - hy.y);
    if outer > beside {
        pts.reverse();
    }
    Some(pts)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 9x6 board of `square` px squares, origin square's top-left at `(ox, oy)`, each
    /// pixel the exact area average of the board over its square (perfect box-filter
    /// rendering), so the corners sit at exact sub-pixel positions.
    fn board(w: usize, h: usize, ox: f64, oy: f64, square: f64) -> Frame<u8> {
        let pixels = (0..w * h).map(|k| {
            let (x0, y0) = ((k % w) as f64 - 0.5, (k / w) as f64 - 0.5);
            let cell = |v: f64, o: f64| ((v - o) / square).floor() as i64;
            let mut dark_area = 0.0f64;
            for j in cell(y0, oy)..=cell(y0 + 1.0, oy) {
                for i in cell(x0, ox)..=cell(x0 + 1.0, ox) {
                    let dark = (0..10).contains(&i) && (0..7).contains(&j) && (i + j) % 2 == 0;
                    if !dark {
                        continue;
                    }
                    let (cx0, cy0) = (ox + i as f64 * square, oy + j as f64 * square);
                    let ovx = ((x0 + 1.0).min(cx0 + square) - x0.max(cx0)).max(0.0);
                    let ovy = ((y0 + 1.0).min(cy0 + square) - y0.max(cy0)).max(0.0);
                    dark_area += ovx * ovy;
                }
            }
            (220.0 - 190.0 * dark_area).round() as u8
        });
        Frame::new(w, h, pixels.collect()).unwrap()
    }

    #[test]
    fn sub_pixel_corners_on_an_exact_board() {
        let (ox, oy, s) = (100.3, 80.7, 30.0);
        let img = board(480, 360, ox, oy, s);
        let found =
            detect_checkerboard(&img, BoardSize::new(9, 6), &DetectorConfig::default(), "t")
                .unwrap();
        for (k, p) in found.corners.iter().enumerate() {
            let (i, j) = ((k % 9) as f64, (k / 9) as f64);
            let truth = Point2::new(ox + (i + 1.0) * s, oy + (j + 1.0) * s);
            // 8-bit rounding of the edge pixels (190 levels per pixel of edge shift) is
            // ~0.003 px of edge position; 0.02 px leaves room for the blur's border effects.
            assert!((p - truth).norm() < 0.02, "corner {k}: {p} vs {truth}");
        }
    }

    #[test]
    fn order_is_fixed_by_the_board_not_the_image() {
        let img = board(480, 360, 100.3, 80.7, 30.0);
        let cfg = DetectorConfig::default();
        let a = detect_checkerboard(&img, BoardSize::new(9, 6), &cfg, "a").unwrap();
        // The same board turned by 180° in the image: corner k must be the same board corner.
        let rotated = Frame::new(480, 360, img.data().iter().rev().copied().collect()).unwrap();
        let b = detect_checkerboard(&rotated, BoardSize::new(9, 6), &cfg, "b").unwrap();
        for (p, q) in a.corners.iter().zip(&b.corners) {
            // Rotation by 180° about the image centre: (x, y) -> (w - 1 - x, h - 1 - y).
            let back = Point2::new(479.0 - q.x, 359.0 - q.y);
            assert!((p - back).norm() < 0.05, "{p} vs {back}");
        }
    }

    #[test]
    fn no_board_is_a_clear_error() {
        let img = Frame::filled(640, 480, 128).unwrap();
        let err = detect_checkerboard(
            &img,
            BoardSize::new(9, 6),
            &DetectorConfig::default(),
            "blank.png",
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("blank.png") && msg.contains("not found"),
            "{msg}"
        );
        // A board of another size is not taken for the one asked for.
        let img = board(480, 360, 100.3, 80.7, 30.0);
        let err = detect_checkerboard(
            &img,
            BoardSize::new(8, 6),
            &DetectorConfig::default(),
            "b.png",
        )
        .unwrap_err();
        assert!(err.to_string().contains("8x6"), "{err}");
    }
}
