//! Board corners in the projector image by local homographies (Moreno & Taubin 2012): around
//! every camera corner, a homography from the decoded camera pixels to their projector
//! coordinates, fitted robustly (RANSAC, then least squares on the inliers), maps the corner
//! into the projector with sub-pixel precision.

use nalgebra::{Matrix3, Point2};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use sl_codec::CorrespondenceMap;

use crate::homography::homography_dlt;
use crate::{BoardCorners, CalibError};

/// Options of [`projector_corners`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LocalHomographyConfig {
    /// Half-width of the square window around each corner (camera px): the window is
    /// `2 · half_window + 1` pixels wide. Wide enough to average the decoding noise over
    /// hundreds of pixels, narrow enough that lens distortion leaves the map a homography.
    pub half_window: u32,
    /// Fewest decoded pixels (and inliers) a window needs; corners with fewer are skipped
    /// (or refused, see `skip_sparse`).
    pub min_pixels: usize,
    /// Pixels decoded with a quality below this (8-bit grey levels, see `sl-codec`) are left
    /// out of the fit.
    pub min_quality: f32,
    /// Largest distance (projector px) between a decoded projector point and the
    /// homography's prediction for the pixel to count as an inlier.
    pub inlier_threshold: f64,
    /// Largest number of RANSAC samples per corner (the loop stops earlier once an all-inlier
    /// sample has been drawn with `confidence`).
    pub max_ransac_iterations: usize,
    /// Probability of having drawn at least one all-inlier sample at which RANSAC stops.
    pub confidence: f64,
    /// `true`: corners with fewer than `min_pixels` decoded pixels are left out and listed
    /// in [`ProjectorCorners::skipped`]; `false`: they are an error
    /// ([`CalibError::SparseCorner`]).
    pub skip_sparse: bool,
    /// Seed of the RANSAC draws (results are reproducible).
    pub seed: u64,
}

impl Default for LocalHomographyConfig {
    /// A 41×41 window (M&T's scan3d-capture uses a similar size), at least 100 decoded
    /// pixels, inliers within 1.5 projector px (above the ±0.5 px quantisation of a Gray
    /// code plus noise; period jumps and edge errors are tens of pixels), 1000 samples at most,
    /// 99.9 % confidence, sparse corners skipped.
    fn default() -> Self {
        Self {
            half_window: 20,
            min_pixels: 100,
            min_quality: 0.0,
            inlier_threshold: 1.5,
            max_ransac_iterations: 1000,
            confidence: 0.999,
            skip_sparse: true,
            seed: 0x5eed,
        }
    }
}

/// The fit of one corner that was mapped into the projector.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CornerFit {
    /// The corner in the projector image (projector px).
    pub projector: Point2<f64>,
    /// Decoded pixels in the window.
    pub decoded: usize,
    /// Inliers of the final homography.
    pub inliers: usize,
    /// RMS distance of the inliers from the homography (projector px).
    pub rms: f64,
}

/// A corner left out, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedCorner {
    /// Index of the corner in board order.
    pub corner: usize,
    /// Decoded pixels in its window.
    pub decoded: usize,
    /// Why it was left out.
    pub reason: String,
}

/// The result of [`projector_corners`]: per board corner, its projector pixel or `None`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProjectorCorners {
    /// The frame (view) name.
    pub frame: String,
    /// Per corner in board order: the fit, or `None` when skipped.
    pub fits: Vec<Option<CornerFit>>,
    /// The corners left out, with the reason.
    pub skipped: Vec<SkippedCorner>,
}

impl ProjectorCorners {
    /// Per corner in board order: the projector pixel, or `None` when skipped.
    pub fn points(&self) -> Vec<Option<Point2<f64>>> {
        self.fits.iter().map(|f| f.map(|f| f.projector)).collect()
    }

    /// Number of corners mapped into the projector.
    pub fn mapped_count(&self) -> usize {
        self.fits.iter().filter(|f| f.is_some()).count()
    }
}

/// Maps every corner of `board` (camera px) into the projector through a local homography
/// fitted to the decoded correspondences `map` in a window around it. `frame` names the view
/// in messages.
///
/// # Errors
/// [`CalibError::InvalidParameter`] for a bad option, [`CalibError::SparseCorner`] when a
/// window has too few decoded pixels and `skip_sparse` is off.
///
/// ```
/// use sl_calib::{BoardCorners, BoardSize, LocalHomographyConfig, projector_corners};
/// use sl_codec::CorrespondenceMap;
/// use nalgebra::Point2;
/// // A projector that sees the camera image scaled by 1.5 and shifted.
/// let mut map = CorrespondenceMap::new(200, 150);
/// for y in 0..150 {
///     for x in 0..200 {
///         map.col[y * 200 + x] = (1.5 * x as f64 + 10.0) as f32;
///         map.row[y * 200 + x] = (1.5 * y as f64 + 4.0) as f32;
///     }
/// }
/// let board = BoardCorners { size: BoardSize::new(2, 1), corners: vec![Point2::new(60.3, 70.7), Point2::new(120.25, 70.5)] };
/// let p = projector_corners(&board, &map, &LocalHomographyConfig::default(), "demo")?;
/// let q = p.fits[0].unwrap().projector;
/// assert!((q.x - (1.5 * 60.3 + 10.0)).abs() < 1e-3 && (q.y - (1.5 * 70.7 + 4.0)).abs() < 1e-3);
/// # Ok::<(), sl_calib::CalibError>(())
/// ```
pub fn projector_corners(
    board: &BoardCorners,
    map: &CorrespondenceMap,
    cfg: &LocalHomographyConfig,
    frame: &str,
) -> Result<ProjectorCorners, CalibError> {
    validate(cfg, map)?;
    let mut rng = Pcg64Mcg::seed_from_u64(cfg.seed);
    let mut fits = Vec::with_capacity(board.corners.len());
    let mut skipped = Vec::new();
    let mut cam = Vec::new();
    let mut proj = Vec::new();
    for (k, c) in board.corners.iter().enumerate() {
        window_samples(map, c, cfg, &mut cam, &mut proj);
        let decoded = cam.len();
        if decoded < cfg.min_pixels {
            if !cfg.skip_sparse {
                return Err(CalibError::SparseCorner {
                    frame: frame.to_owned(),
                    corner: k,
                    decoded,
                    needed: cfg.min_pixels,
                });
            }
            skipped.push(SkippedCorner {
                corner: k,
                decoded,
                reason: format!(
                    "{decoded} decoded pixels in the {0}x{0} window, {1} needed",
                    2 * cfg.half_window + 1,
                    cfg.min_pixels
                ),
            });
            fits.push(None);
            continue;
        }
        match robust_homography(&cam, &proj, cfg, &mut rng) {
            Ok((h, inliers, rms)) => {
                let mapped = Point2::from_homogeneous(h * c.to_homogeneous())
                    .filter(|q| q.coords.iter().all(|v| v.is_finite()));
                match mapped {
                    Some(projector) => fits.push(Some(CornerFit {
                        projector,
                        decoded,
                        inliers,
                        rms,
                    })),
                    None => {
                        skipped.push(SkippedCorner {
                            corner: k,
                            decoded,
                            reason: "the local homography maps the corner to infinity".to_owned(),
                        });
                        fits.push(None);
                    }
                }
            }
            Err(reason) => {
                skipped.push(SkippedCorner {
                    corner: k,
                    decoded,
                    reason,
                });
                fits.push(None);
            }
        }
    }
    Ok(ProjectorCorners {
        frame: frame.to_owned(),
        fits,
        skipped,
    })
}

fn validate(cfg: &LocalHomographyConfig, map: &CorrespondenceMap) -> Result<(), CalibError> {
    if cfg.half_window < 2 {
        return Err(CalibError::param(
            "half_window",
            format!(
                "{} px: a homography needs a window of at least 5x5",
                cfg.half_window
            ),
        ));
    }
    if cfg.min_pixels < MIN_SAMPLE {
        return Err(CalibError::param(
            "min_pixels",
            format!(
                "{}: a homography needs at least {MIN_SAMPLE}",
                cfg.min_pixels
            ),
        ));
    }
    if !(cfg.inlier_threshold.is_finite() && cfg.inlier_threshold > 0.0) {
        return Err(CalibError::param(
            "inlier_threshold",
            format!("{} is not a positive distance", cfg.inlier_threshold),
        ));
    }
    if !(cfg.confidence > 0.0 && cfg.confidence < 1.0) {
        return Err(CalibError::param(
            "confidence",
            format!("{} is not in (0, 1)", cfg.confidence),
        ));
    }
    if cfg.max_ransac_iterations == 0 {
        return Err(CalibError::param(
            "max_ransac_iterations",
            "0: at least one sample is needed",
        ));
    }
    let n = map.width * map.height;
    if map.col.len() != n || map.row.len() != n || map.quality.len() != n || map.invalid.len() != n
    {
        return Err(CalibError::param(
            "map",
            format!(
                "a {}x{} correspondence map must hold {n} values per channel",
                map.width, map.height
            ),
        ));
    }
    Ok(())
}

/// Points of a minimal homography sample.
const MIN_SAMPLE: usize = 4;

/// Fills `cam` (camera px) and `proj` (projector px) with the decoded pixels of the window
/// around `c`.
fn window_samples(
    map: &CorrespondenceMap,
    c: &Point2<f64>,
    cfg: &LocalHomographyConfig,
    cam: &mut Vec<Point2<f64>>,
    proj: &mut Vec<Point2<f64>>,
) {
    cam.clear();
    proj.clear();
    if !(c.x.is_finite() && c.y.is_finite()) {
        return;
    }
    let h = f64::from(cfg.half_window);
    let (w, ht) = (map.width as f64, map.height as f64);
    // Pixel centres within half_window of the corner, clamped to the image.
    let x0 = (c.x - h).ceil().max(0.0);
    let x1 = (c.x + h).floor().min(w - 1.0);
    let y0 = (c.y - h).ceil().max(0.0);
    let y1 = (c.y + h).floor().min(ht - 1.0);
    if x1 < x0 || y1 < y0 {
        return;
    }
    let (x0, x1, y0, y1) = (x0 as usize, x1 as usize, y0 as usize, y1 as usize);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let i = y * map.width + x;
            let (Some(col), Some(row), Some(q), Some(inv)) = (
                map.col.get(i),
                map.row.get(i),
                map.quality.get(i),
                map.invalid.get(i),
            ) else {
                continue;
            };
            if inv.is_valid() && col.is_finite() && row.is_finite() && *q >= cfg.min_quality {
                cam.push(Point2::new(x as f64, y as f64));
                proj.push(Point2::new(f64::from(*col), f64::from(*row)));
            }
        }
    }
}

/// Squared transfer error of `p → q` under `h`; infinite when `p` maps to infinity.
fn transfer_error2(h: &Matrix3<f64>, p: &Point2<f64>, q: &Point2<f64>) -> f64 {
    let v = h * p.to_homogeneous();
    if v.z.abs() < f64::MIN_POSITIVE {
        return f64::INFINITY;
    }
    let (u, w) = (v.x / v.z, v.y / v.z);
    (u - q.x).powi(2) + (w - q.y).powi(2)
}

fn inliers_of(
    h: &Matrix3<f64>,
    cam: &[Point2<f64>],
    proj: &[Point2<f64>],
    t2: f64,
    out: &mut Vec<usize>,
) {
    out.clear();
    out.extend(
        cam.iter()
            .zip(proj)
            .enumerate()
            .filter(|(_, (p, q))| transfer_error2(h, p, q) <= t2)
            .map(|(i, _)| i),
    );
}

/// Rounds of "least squares on the inliers, then re-select the inliers" after RANSAC: the
/// second round catches pixels the minimal sample's model wrongly accepted or refused.
const REFIT_ROUNDS: usize = 2;

/// RANSAC over 4-point samples, then least squares on the inliers. Returns the homography,
/// the inlier count and their RMS transfer error, or why no fit was found.
fn robust_homography(
    cam: &[Point2<f64>],
    proj: &[Point2<f64>],
    cfg: &LocalHomographyConfig,
    rng: &mut Pcg64Mcg,
) -> Result<(Matrix3<f64>, usize, f64), String> {
    let n = cam.len();
    let t2 = cfg.inlier_threshold * cfg.inlier_threshold;
    let mut best: Vec<usize> = Vec::new();
    let mut current = Vec::with_capacity(n);
    let mut needed = cfg.max_ransac_iterations;
    let mut it = 0;
    let mut sc = [Point2::origin(); MIN_SAMPLE];
    let mut sp = [Point2::origin(); MIN_SAMPLE];
    while it < needed.min(cfg.max_ransac_iterations) {
        it += 1;
        let mut idx = [0usize; MIN_SAMPLE];
        for k in 0..MIN_SAMPLE {
            // Distinct indices (n ≥ min_pixels ≥ 4).
            loop {
                let i = rng.random_range(0..n);
                if !idx[..k].contains(&i) {
                    idx[k] = i;
                    break;
                }
            }
        }
        for (k, &i) in idx.iter().enumerate() {
            sc[k] = cam[i];
            sp[k] = proj[i];
        }
        let Some(h) = homography_dlt(&sc, &sp) else {
            continue;
        };
        inliers_of(&h, cam, proj, t2, &mut current);
        if current.len() > best.len() {
            std::mem::swap(&mut best, &mut current);
            let w = best.len() as f64 / n as f64;
            let p_good = w.powi(MIN_SAMPLE as i32);
            needed = if p_good >= 1.0 {
                0
            } else {
                let k = (1.0 - cfg.confidence).ln() / (1.0 - p_good).ln();
                if k.is_finite() {
                    k.ceil() as usize
                } else {
                    cfg.max_ransac_iterations
                }
            };
        }
    }
    if best.len() < MIN_SAMPLE {
        return Err(format!(
            "no homography found among {n} decoded pixels ({it} RANSAC samples)"
        ));
    }
    let mut h = Matrix3::identity();
    for _ in 0..REFIT_ROUNDS {
        let (c, p): (Vec<_>, Vec<_>) = best
            .iter()
            .filter_map(|&i| Some((*cam.get(i)?, *proj.get(i)?)))
            .unzip();
        h = homography_dlt(&c, &p)
            .ok_or_else(|| format!("the {} inliers do not determine a homography", best.len()))?;
        inliers_of(&h, cam, proj, t2, &mut best);
        if best.len() < cfg.min_pixels {
            return Err(format!(
                "{} inliers within {} px of {n} decoded pixels, {} needed",
                best.len(),
                cfg.inlier_threshold,
                cfg.min_pixels
            ));
        }
    }
    let sum: f64 = best
        .iter()
        .filter_map(|&i| Some(transfer_error2(&h, cam.get(i)?, proj.get(i)?)))
        .sum();
    let rms = (sum / best.len() as f64).sqrt();
    Ok((h, best.len(), rms))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BoardSize;

    fn map_from(h: &Matrix3<f64>, w: usize, ht: usize) -> CorrespondenceMap {
        let mut map = CorrespondenceMap::new(w, ht);
        for y in 0..ht {
            for x in 0..w {
                let q =
                    Point2::from_homogeneous(h * Point2::new(x as f64, y as f64).to_homogeneous())
                        .unwrap();
                map.col[y * w + x] = q.x as f32;
                map.row[y * w + x] = q.y as f32;
            }
        }
        map
    }

    #[test]
    fn sparse_windows_are_skipped_or_refused() {
        let h = Matrix3::new(1.5, 0.1, 10.0, -0.05, 1.4, 5.0, 0.0, 0.0, 1.0);
        let mut map = map_from(&h, 120, 100);
        // Nothing decoded left of x = 50.
        for y in 0..100 {
            for x in 0..50 {
                map.col[y * 120 + x] = f32::NAN;
            }
        }
        let board = BoardCorners {
            size: BoardSize::new(2, 1),
            corners: vec![Point2::new(20.0, 50.0), Point2::new(80.0, 50.0)],
        };
        let p = projector_corners(&board, &map, &LocalHomographyConfig::default(), "v7").unwrap();
        assert!(p.fits[0].is_none() && p.fits[1].is_some());
        assert_eq!(p.skipped.len(), 1);
        assert_eq!(p.skipped[0].corner, 0);
        assert_eq!(p.skipped[0].decoded, 0);
        let err = projector_corners(
            &board,
            &map,
            &LocalHomographyConfig {
                skip_sparse: false,
                ..LocalHomographyConfig::default()
            },
            "v7",
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("v7") && msg.contains("corner 0"), "{msg}");
    }
}

#[cfg(test)]
mod laws {
    use super::*;
    use crate::BoardSize;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// A plane seen by camera and projector gives a camera-to-projector map that is a
        /// homography: without noise, the local fit maps the corner exactly, wherever it is
        /// between pixel centres, even with a fifth of the window's pixels decoded wrongly.
        #[test]
        fn local_homography_is_exact_for_a_plane(
            a in 1.2f64..1.8, b in -0.2f64..0.2, c in -0.2f64..0.2, d in 1.2f64..1.8,
            g in -4e-4f64..4e-4, h in -4e-4f64..4e-4,
            cx in 30.0f64..90.0, cy in 30.0f64..70.0,
            outliers in 0usize..5,
        ) {
            let hm = Matrix3::new(a, b, 12.0, c, d, -7.0, g, h, 1.0);
            let (w, ht) = (120usize, 100usize);
            let mut map = CorrespondenceMap::new(w, ht);
            for y in 0..ht {
                for x in 0..w {
                    let q = Point2::from_homogeneous(hm * Point2::new(x as f64, y as f64).to_homogeneous()).unwrap();
                    let i = y * w + x;
                    map.col[i] = q.x as f32;
                    map.row[i] = q.y as f32;
                    // Every fifth pixel (when asked) decoded to garbage tens of pixels off.
                    if outliers > 0 && (x * 7 + y * 3) % 5 == 0 && (x + y) % outliers == 0 {
                        map.col[i] += 37.0;
                        map.row[i] -= 23.0;
                    }
                }
            }
            let corner = Point2::new(cx, cy);
            let board = BoardCorners { size: BoardSize::new(1, 1), corners: vec![corner] };
            let p = projector_corners(&board, &map, &LocalHomographyConfig::default(), "law").unwrap();
            let fit = p.fits[0].unwrap();
            let truth = Point2::from_homogeneous(hm * corner.to_homogeneous()).unwrap();
            // The decoded values are stored as f32 (≈1e-4 px at these magnitudes): the fit
            // is exact to that rounding.
            prop_assert!((fit.projector - truth).norm() < 1e-3, "{:?} vs {:?}", fit.projector, truth);
            prop_assert!(fit.rms < 1e-3);
        }
    }
}
