//! Binocular structured light: two calibrated cameras triangulate, the projector only labels the
//! surface. Its lens distortion, gamma and drift do not enter the geometry, and a point needs
//! both cameras to see it.
//!
//! [`Binocular::new`] rectifies the pair once (both cameras turned about their centres so that
//! their image rows are epipolar lines: the rotation of Fusiello, Trucco and Verri, split
//! between the two cameras around their mean optical axis) and precomputes, for every pixel of
//! the rectified grid, where it falls in each original image. [`Binocular::reconstruct`] then
//! samples both decoded maps on that grid, matches each left pixel to the sub-pixel position of
//! the same projector coordinate along the same rectified row of the right camera (searched
//! within the runs where the right row's code changes monotonically, so a code repeated across
//! a depth jump is told apart by its depth and by its neighbours), keeps the matches that
//! survive a left–right consistency check (and, when both axes are coded, whose projector rows
//! agree), and triangulates in the rectified frame.
//!
//! Hand-written: the per-row matching is the hot loop of the method (a 1280x1024 pair is 1.3 M
//! searches), and no crate does sub-pixel matching of decoded codes.

use nalgebra::{Isometry3, Matrix3, Point2, Point3, Vector3};
use rayon::prelude::*;
use sl_camera::CameraModel;
use sl_cloud::PointCloud;
use sl_codec::CorrespondenceMap;

use crate::grid_normals::cloud_normals;
use crate::mixed_pixels::filter_mixed_pixels;
use crate::{PointStatus, TriError};

/// Settings of [`Binocular::reconstruct`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BinocularConfig {
    /// Largest change of the decoded column between neighbouring rectified pixels of one
    /// surface (projector px): a larger one is a depth jump, where a run of the right row ends.
    pub max_code_step: f32,
    /// Largest disagreement of the left–right check (rectified px).
    pub max_lr_error_px: f64,
    /// Largest difference of the decoded projector rows of a match (projector px), when both
    /// captures code rows (otherwise unused).
    pub max_row_difference: f32,
    /// Depth range kept (mm, left camera `z`).
    pub min_depth_mm: f64,
    /// See [`BinocularConfig::min_depth_mm`].
    pub max_depth_mm: f64,
    /// Mixed-pixel filter: largest depth jump to a neighbour of the rectified grid, as a
    /// fraction of the depth (`inf` turns it off); the monocular filter's rule
    /// ([`crate::TriConfig::max_depth_jump`]).
    pub max_depth_jump: f64,
}

impl Default for BinocularConfig {
    fn default() -> Self {
        Self {
            max_code_step: 8.0,
            max_lr_error_px: 1.0,
            max_row_difference: 2.0,
            min_depth_mm: 1.0,
            max_depth_mm: f64::INFINITY,
            max_depth_jump: crate::DEFAULT_MAX_DEPTH_JUMP,
        }
    }
}

impl BinocularConfig {
    /// Checks every value.
    ///
    /// # Errors
    /// [`TriError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<(), TriError> {
        let positive = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(TriError::param(
                    name,
                    format!("{v}: must be finite and > 0"),
                ))
            }
        };
        positive("max_code_step", f64::from(self.max_code_step))?;
        positive("max_lr_error_px", self.max_lr_error_px)?;
        positive("max_row_difference", f64::from(self.max_row_difference))?;
        if !(self.max_depth_jump > 0.0) {
            return Err(TriError::param(
                "max_depth_jump",
                format!(
                    "{}: must be > 0 (inf turns the filter off)",
                    self.max_depth_jump
                ),
            ));
        }
        if !(self.min_depth_mm >= 0.0 && self.min_depth_mm < self.max_depth_mm) {
            return Err(TriError::param(
                "min_depth_mm",
                format!(
                    "{} .. {} mm: not a depth range",
                    self.min_depth_mm, self.max_depth_mm
                ),
            ));
        }
        Ok(())
    }
}

/// How the rectified left pixels fared.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BinocularCounts {
    /// Rectified left pixels with a decoded code.
    pub decoded: usize,
    /// Of those, no position of the right row carries the code (occluded in the right camera,
    /// or not decoded there).
    pub unmatched: usize,
    /// Several positions carry it and neither depth nor the neighbours tell them apart.
    pub ambiguous: usize,
    /// Matched, but the right-to-left match does not come back (or the rows disagree).
    pub inconsistent: usize,
    /// Matched, outside the depth range.
    pub out_of_depth_range: usize,
    /// Dropped by the mixed-pixel filter (a depth jump to a neighbour).
    pub mixed_pixels: usize,
    /// Dropped for having no matched 4-neighbour: a lone match is a coincidence of codes
    /// more often than a surface.
    pub isolated: usize,
    /// Points kept.
    pub valid: usize,
}

/// The result of [`Binocular::reconstruct`].
#[derive(Debug, Clone)]
pub struct BinocularResult {
    /// The points, in millimetres in the **left camera's frame**, with normals from the
    /// rectified grid where the neighbours allow.
    pub cloud: PointCloud,
    /// Disparity on the rectified left grid (px, `x_left − x_right`), NaN where no point.
    pub disparity: Vec<f32>,
    /// Size of the rectified grid (the left camera's image size).
    pub width: usize,
    /// See [`BinocularResult::width`].
    pub height: usize,
    /// How the pixels fared.
    pub counts: BinocularCounts,
}

/// A calibrated pair of cameras, rectified: [`Binocular::new`] rectifies once,
/// [`Binocular::reconstruct`] matches and triangulates a pair of decoded maps (the method step
/// by step: `docs/binocular.md`).
#[derive(Debug, Clone)]
pub struct Binocular {
    left: CameraModel,
    right: CameraModel,
    /// Rectified frame from the left camera frame: `v_rect = r_rect · v_left`.
    r_rect: Matrix3<f64>,
    /// Focal length of the rectified cameras (px).
    f: f64,
    /// Principal points of the rectified cameras: `x` each, `y` shared.
    cx_left: f64,
    cx_right: f64,
    cy: f64,
    /// Baseline (mm): the right camera's centre is at `(baseline, 0, 0)` in the rectified frame.
    baseline: f64,
    width: usize,
    height: usize,
    /// For each rectified pixel, where it falls in the left and the right image (NaN outside).
    left_map: Vec<[f32; 2]>,
    right_map: Vec<[f32; 2]>,
}

impl Binocular {
    /// Rectifies `left` and `right`, where `t_left_right` is the right camera's pose in the left
    /// camera's frame (`p_left = T_left_right · p_right`, mm). The rectified grid has the left
    /// image's size.
    ///
    /// # Errors
    /// [`TriError::InvalidParameter`] when the cameras share a centre or the baseline runs
    /// along the viewing direction (no rectification exists).
    pub fn new(
        left: &CameraModel,
        right: &CameraModel,
        t_left_right: &Isometry3<f64>,
    ) -> Result<Self, TriError> {
        let c_right = t_left_right.translation.vector;
        let baseline = c_right.norm();
        if !(baseline.is_finite() && baseline > 1e-9) {
            return Err(TriError::param(
                "t_left_right",
                format!("the cameras' centres are {baseline} mm apart: no baseline"),
            ));
        }
        let e1 = c_right / baseline;
        let r_lr = t_left_right.rotation.to_rotation_matrix().into_inner();
        let z_mean = (Vector3::z() + r_lr * Vector3::z()).normalize();
        let e2 = z_mean.cross(&e1);
        if e2.norm() < 1e-6 {
            return Err(TriError::param(
                "t_left_right",
                "the baseline runs along the cameras' viewing direction: no rectification",
            ));
        }
        let e2 = e2.normalize();
        let e3 = e1.cross(&e2);
        let r_rect = Matrix3::from_rows(&[e1.transpose(), e2.transpose(), e3.transpose()]);
        let (li, ri) = (left.intrinsics, right.intrinsics);
        let f = 0.25 * (li.fx + li.fy + ri.fx + ri.fy);
        let (width, height) = (left.size.width as usize, left.size.height as usize);
        // Each camera's image centre stays at the rectified image centre in x; the rows share
        // the mean of the two centres' rectified heights.
        let centre = |m: &CameraModel, to_rect: &Matrix3<f64>| -> Option<(f64, f64)> {
            let ray = m.unproject(&Point2::new(
                0.5 * (f64::from(m.size.width) - 1.0),
                0.5 * (f64::from(m.size.height) - 1.0),
            ))?;
            let v = to_rect * ray;
            (v.z > 0.0).then(|| {
                (
                    0.5 * (width as f64 - 1.0) - f * v.x / v.z,
                    0.5 * (height as f64 - 1.0) - f * v.y / v.z,
                )
            })
        };
        let r_rect_right = r_rect * r_lr;
        let (Some((cx_left, cy_left)), Some((cx_right, cy_right))) =
            (centre(left, &r_rect), centre(right, &r_rect_right))
        else {
            return Err(TriError::param(
                "t_left_right",
                "an image centre does not un-project in front of its camera",
            ));
        };
        let cy = 0.5 * (cy_left + cy_right);
        let mut b = Self {
            left: *left,
            right: *right,
            r_rect,
            f,
            cx_left,
            cx_right,
            cy,
            baseline,
            width,
            height,
            left_map: Vec::new(),
            right_map: Vec::new(),
        };
        b.left_map = b.remap(left, &r_rect.transpose(), cx_left);
        b.right_map = b.remap(right, &(r_rect_right.transpose()), cx_right);
        Ok(b)
    }

    /// For every rectified pixel, its position in the image of `model`, whose frame is
    /// `to_camera · rectified`.
    fn remap(&self, model: &CameraModel, to_camera: &Matrix3<f64>, cx: f64) -> Vec<[f32; 2]> {
        let (w, h) = (f64::from(model.size.width), f64::from(model.size.height));
        let mut map = vec![[f32::NAN; 2]; self.width * self.height];
        map.par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, out) in row.iter_mut().enumerate() {
                    let v =
                        Vector3::new((x as f64 - cx) / self.f, (y as f64 - self.cy) / self.f, 1.0);
                    let p = to_camera * v;
                    if p.z <= 0.0 {
                        continue;
                    }
                    if let Some(px) = model.project(&Point3::from(p))
                        && px.x > -0.5
                        && px.y > -0.5
                        && px.x < w - 0.5
                        && px.y < h - 0.5
                    {
                        *out = [px.x as f32, px.y as f32];
                    }
                }
            });
        map
    }

    /// The rectified grid's size (the left image's).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The rectified cameras: focal length (px), principal points `(cx_left, cx_right, cy)`
    /// and baseline (mm).
    pub fn rectified(&self) -> (f64, (f64, f64, f64), f64) {
        (
            self.f,
            (self.cx_left, self.cx_right, self.cy),
            self.baseline,
        )
    }

    /// Matches and triangulates the decoded maps of the left and the right camera (each of its
    /// camera's size; the columns must be decoded, the rows are used when both code them).
    ///
    /// # Errors
    /// [`TriError::SizeMismatch`] naming the map; [`TriError::InvalidParameter`] for `cfg`;
    /// [`TriError::Cloud`] building the cloud.
    pub fn reconstruct(
        &self,
        left: &CorrespondenceMap,
        right: &CorrespondenceMap,
        cfg: &BinocularConfig,
    ) -> Result<BinocularResult, TriError> {
        cfg.validate()?;
        for (what, map, model) in [
            ("left correspondence map", left, &self.left),
            ("right correspondence map", right, &self.right),
        ] {
            let (w, h) = (model.size.width as usize, model.size.height as usize);
            if map.width != w || map.height != h || map.col.len() != w * h {
                return Err(TriError::SizeMismatch {
                    what,
                    expected: format!("{w}x{h}"),
                    found: format!("{}x{}", map.width, map.height),
                });
            }
        }
        let rows =
            left.row.iter().any(|v| v.is_finite()) && right.row.iter().any(|v| v.is_finite());
        let step = cfg.max_code_step;
        // The disparity range of the depth range: z = f·b / (d − (cx_l − cx_r)).
        let shift = self.cx_left - self.cx_right;
        let d_max = self.f * self.baseline / cfg.min_depth_mm.max(1e-9) + shift;
        let d_min = if cfg.max_depth_mm.is_finite() {
            self.f * self.baseline / cfg.max_depth_mm + shift
        } else {
            shift
        };
        let w = self.width;
        let mut disparity = vec![f32::NAN; w * self.height];
        let rows_counts: Vec<BinocularCounts> = disparity
            .par_chunks_mut(w.max(1))
            .enumerate()
            // One set of row buffers per task, reused from row to row.
            .map_init(RowSamples::default, |s, (y, disparity)| {
                // Both maps sampled on this rectified row only: the row's samples stay in the
                // cache for the matching, and no full-image buffer is written and read back.
                let span = y * w..(y + 1) * w;
                let (lm, rm) = (&self.left_map[span.clone()], &self.right_map[span]);
                sample(&left.col, left.width, lm, step, &mut s.l);
                sample(&right.col, right.width, rm, step, &mut s.r);
                if rows {
                    sample(&left.row, left.width, lm, f32::INFINITY, &mut s.lr);
                    sample(&right.row, right.width, rm, f32::INFINITY, &mut s.rr);
                }
                let (l, r, lr, rr) = (&s.l[..], &s.r[..], &s.lr[..], &s.rr[..]);
                let forward = match_row(l, r, step, d_min, d_max, 1.0);
                let backward = match_row(r, l, step, -d_max, -d_min, -1.0);
                let mut counts = BinocularCounts::default();
                for (x, m) in forward.iter().enumerate() {
                    if !l[x].is_finite() {
                        continue;
                    }
                    counts.decoded += 1;
                    let xr = match *m {
                        Match::None => {
                            counts.unmatched += 1;
                            continue;
                        }
                        Match::Ambiguous => {
                            counts.ambiguous += 1;
                            continue;
                        }
                        Match::At(xr, _) => xr,
                    };
                    let consistent = back_at(&backward, xr)
                        .is_some_and(|xl| (xl - x as f64).abs() <= cfg.max_lr_error_px)
                        && (!rows || rows_agree(&lr[x], rr, xr, cfg));
                    if !consistent {
                        counts.inconsistent += 1;
                        continue;
                    }
                    let d = x as f64 - xr;
                    if !(d > d_min && d <= d_max) {
                        counts.out_of_depth_range += 1;
                        continue;
                    }
                    disparity[x] = d as f32;
                    counts.valid += 1;
                }
                counts
            })
            .collect();
        let mut counts = BinocularCounts::default();
        for c in rows_counts {
            counts.decoded += c.decoded;
            counts.unmatched += c.unmatched;
            counts.ambiguous += c.ambiguous;
            counts.inconsistent += c.inconsistent;
            counts.out_of_depth_range += c.out_of_depth_range;
            counts.valid += c.valid;
        }
        let cloud = self.points(&mut disparity, cfg.max_depth_jump, &mut counts)?;
        Ok(BinocularResult {
            cloud,
            disparity,
            width: w,
            height: self.height,
            counts,
        })
    }

    /// The left-frame point of rectified pixel `(x, y)` at disparity `d`.
    pub fn point(&self, x: f64, y: f64, d: f64) -> Point3<f64> {
        let z = self.f * self.baseline / (d - (self.cx_left - self.cx_right));
        let v = Vector3::new(
            (x - self.cx_left) * z / self.f,
            (y - self.cy) * z / self.f,
            z,
        );
        Point3::from(self.r_rect.tr_mul(&v))
    }

    /// The cloud of a disparity map after the mixed-pixel filter (the points it drops are
    /// cleared from `disparity` and counted), with normals from the grid's neighbours.
    fn points(
        &self,
        disparity: &mut [f32],
        max_depth_jump: f64,
        counts: &mut BinocularCounts,
    ) -> Result<PointCloud, TriError> {
        let w = self.width;
        let nan = Point3::new(f64::NAN, f64::NAN, f64::NAN);
        let mut xyz: Vec<Point3<f64>> = disparity
            .par_iter()
            .enumerate()
            .map(|(i, &d)| {
                if d.is_finite() {
                    self.point((i % w) as f64, (i / w) as f64, f64::from(d))
                } else {
                    nan
                }
            })
            .collect();
        // Every pass over the grid below runs on both cores: a sequential pass over 1.3 M
        // pixels costs a millisecond or two, several of them a fifth of the 60 ms target.
        let mut status: Vec<PointStatus> = xyz
            .par_iter()
            .map(|p| {
                if p.z.is_finite() {
                    PointStatus::Valid
                } else {
                    PointStatus::NotDecoded
                }
            })
            .collect();
        filter_mixed_pixels(&mut xyz, &mut status, w, max_depth_jump);
        counts.mixed_pixels += disparity
            .par_iter_mut()
            .zip(status.par_iter())
            .map(|(d, s)| {
                if *s == PointStatus::MixedPixel {
                    *d = f32::NAN;
                    1
                } else {
                    0
                }
            })
            .sum::<usize>();
        // Lone points: no 4-neighbour left after the filter.
        let h = self.height;
        let alone: Vec<bool> = (0..xyz.len())
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let has = |j: usize| xyz[j].z.is_finite();
                xyz[i].z.is_finite()
                    && !((x > 0 && has(i - 1))
                        || (x + 1 < w && has(i + 1))
                        || (y > 0 && has(i - w))
                        || (y + 1 < h && has(i + w)))
            })
            .collect();
        counts.isolated += disparity
            .par_iter_mut()
            .zip(xyz.par_iter_mut())
            .zip(alone.par_iter())
            .map(|((d, p), &a)| {
                if a {
                    *d = f32::NAN;
                    *p = nan;
                    1
                } else {
                    0
                }
            })
            .sum::<usize>();
        counts.valid -= counts.mixed_pixels + counts.isolated;
        // Normals from the rectified grid, as the one-camera triangulation's (central
        // differences; zero where a point has no neighbour pair).
        const BAND_ROWS: usize = 16;
        let counts: Vec<usize> = xyz
            .par_chunks(w * BAND_ROWS)
            .map(|band| band.iter().filter(|p| p.z.is_finite()).count())
            .collect();
        // Each band copies its points into its own slice of the cloud (a filtered parallel
        // collect gathers per-task vectors and copies them again).
        let mut positions = vec![Point3::origin(); counts.iter().sum()];
        let mut slices = Vec::with_capacity(counts.len());
        let mut rest = positions.as_mut_slice();
        for &c in &counts {
            let (head, tail) = rest.split_at_mut(c);
            slices.push(head);
            rest = tail;
        }
        xyz.par_chunks(w * BAND_ROWS)
            .zip(slices)
            .for_each(|(band, out)| {
                for (o, p) in out.iter_mut().zip(band.iter().filter(|p| p.z.is_finite())) {
                    *o = *p;
                }
            });
        let mut normals = vec![Vector3::zeros(); positions.len()];
        cloud_normals(&xyz, w, BAND_ROWS, &counts, &mut normals);
        Ok(PointCloud::from_positions(positions).with_normals(normals)?)
    }
}

/// The rows of both maps sampled on one rectified row: columns, and rows when both code them.
#[derive(Default)]
struct RowSamples {
    l: Vec<f32>,
    r: Vec<f32>,
    lr: Vec<f32>,
    rr: Vec<f32>,
}

/// The codes of a decoded map at the rectified pixels `map` (one row), into `out`: bilinear
/// where the four neighbours are decoded and within `max_step` of each other, NaN elsewhere.
fn sample(values: &[f32], width: usize, map: &[[f32; 2]], max_step: f32, out: &mut Vec<f32>) {
    let height = values.len() / width.max(1);
    out.clear();
    out.extend(map.iter().map(|&[u, v]| {
        if !(u.is_finite() && v.is_finite()) {
            return f32::NAN;
        }
        // Truncation of a non-negative value is its floor, without a libm call.
        let (x0, y0) = (u.max(0.0) as usize, v.max(0.0) as usize);
        let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
        let (fx, fy) = (
            (u - x0 as f32).clamp(0.0, 1.0),
            (v - y0 as f32).clamp(0.0, 1.0),
        );
        let q = [
            values[y0 * width + x0],
            values[y0 * width + x1],
            values[y1 * width + x0],
            values[y1 * width + x1],
        ];
        if q.iter().any(|c| !c.is_finite()) {
            return f32::NAN;
        }
        let (lo, hi) = q
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &c| {
                (a.min(c), b.max(c))
            });
        if hi - lo > max_step {
            return f32::NAN;
        }
        let top = q[0] + (q[1] - q[0]) * fx;
        let bottom = q[2] + (q[3] - q[2]) * fx;
        top + (bottom - top) * fy
    }));
}

/// What the search for a code along the other row found.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Match {
    None,
    Ambiguous,
    /// The sub-pixel position in the other row; `true` when it was the only candidate (not
    /// chosen by continuity among several).
    At(f64, bool),
}

/// A run of the other row: `[start, end]` pixels whose codes are finite and change
/// monotonically by at most the step between neighbours.
#[derive(Debug, Clone, Copy)]
struct Run {
    start: usize,
    end: usize,
    lo: f32,
    hi: f32,
    increasing: bool,
}

/// The runs of a row by code: bucket `b` lists, in row order, the runs whose code range meets
/// `[lo + b·BUCKET, lo + (b+1)·BUCKET)`. A noisy real row breaks into hundreds of short runs;
/// looking a code up among the runs of its bucket instead of all of them takes the whole
/// match-and-triangulate stage of the 2048x1536 `binocular_sdk` pair from 307 to 258 ms, with
/// the same matches.
struct RunIndex {
    lo: f32,
    /// Start of each bucket's run indices in `runs`, and the end as the last entry.
    offsets: Vec<u32>,
    runs: Vec<u32>,
}

impl RunIndex {
    /// Width of a bucket (projector pixels of code).
    const BUCKET: f32 = 8.0;

    fn new(runs: &[Run]) -> Self {
        let lo = runs.iter().map(|r| r.lo).fold(f32::INFINITY, f32::min);
        let hi = runs.iter().map(|r| r.hi).fold(f32::NEG_INFINITY, f32::max);
        if !(lo.is_finite() && hi.is_finite()) {
            return Self {
                lo: 0.0,
                offsets: vec![0],
                runs: Vec::new(),
            };
        }
        let bucket = |c: f32| ((c - lo) / Self::BUCKET) as usize;
        let count = bucket(hi) + 1;
        let mut offsets = vec![0u32; count + 1];
        for r in runs {
            for b in bucket(r.lo)..=bucket(r.hi) {
                offsets[b + 1] += 1;
            }
        }
        for b in 0..count {
            offsets[b + 1] += offsets[b];
        }
        let mut next: Vec<u32> = offsets[..count].to_vec();
        let mut entries = vec![0u32; offsets[count] as usize];
        for (k, r) in runs.iter().enumerate() {
            for b in bucket(r.lo)..=bucket(r.hi) {
                entries[next[b] as usize] = k as u32;
                next[b] += 1;
            }
        }
        Self {
            lo,
            offsets,
            runs: entries,
        }
    }

    /// The runs whose code range may hold `code`, in row order.
    fn near(&self, code: f32) -> &[u32] {
        let b = (code - self.lo) / Self::BUCKET;
        if !(b >= 0.0) || b as usize + 1 >= self.offsets.len() {
            return &[];
        }
        let b = b as usize;
        &self.runs[self.offsets[b] as usize..self.offsets[b + 1] as usize]
    }
}

/// The runs of `row`.
fn runs(row: &[f32], max_step: f32) -> Vec<Run> {
    let mut out = Vec::new();
    let mut x = 0;
    while x < row.len() {
        if !row[x].is_finite() {
            x += 1;
            continue;
        }
        let start = x;
        let mut increasing = None;
        while x + 1 < row.len() {
            let (a, b) = (row[x], row[x + 1]);
            if !b.is_finite() || (b - a).abs() > max_step || b == a {
                break;
            }
            let up = b > a;
            if *increasing.get_or_insert(up) != up {
                break;
            }
            x += 1;
        }
        let end = x;
        if end > start {
            let (a, b) = (row[start], row[end]);
            out.push(Run {
                start,
                end,
                lo: a.min(b),
                hi: a.max(b),
                increasing: increasing.unwrap_or(true),
            });
        }
        x = end + 1;
    }
    out
}

/// The sub-pixel position of `code` in `run` of `row` (linear between the two pixels that
/// bracket it), and the first of those pixels: the last pixel of the run whose code has not
/// passed `code` (the run's codes are strictly monotonic, so it is unique). The search starts
/// at `hint` (the answer for the previous pixel of the other row, which is a pixel or two away
/// along a surface: `HINT_STEPS` steps from it find most answers) and bisects what is left, so
/// the answer does not depend on the hint.
fn position(row: &[f32], run: &Run, code: f32, hint: usize) -> (f64, usize) {
    /// Steps walked from the hint before bisecting.
    const HINT_STEPS: usize = 4;
    let before = |i: usize| {
        if run.increasing {
            row[i] <= code
        } else {
            row[i] >= code
        }
    };
    // Invariant: `before(a)` (true at the run's start, whose code is the range's end on the
    // near side of `code`) and `b == run.end || !before(b)`.
    let (mut a, mut b) = (run.start, run.end);
    let h = hint.clamp(run.start, run.end - 1);
    if before(h) {
        a = h;
    } else {
        b = h;
    }
    for _ in 0..HINT_STEPS {
        if b - a <= 1 {
            break;
        }
        if before(a + 1) {
            a += 1;
        } else {
            b = a + 1;
        }
    }
    while b - a > 1 {
        let m = (a + b) / 2;
        if before(m) {
            a = m;
        } else {
            b = m;
        }
    }
    let (ca, cb) = (row[a], row[b]);
    (
        a as f64 + f64::from((code - ca) / (cb - ca)).clamp(0.0, 1.0),
        a,
    )
}

/// Matches every pixel of `from` to the sub-pixel position of its code in `to`, with the
/// disparity `sign · (x − x_to)` in `[d_min, d_max]`; several candidates are told apart by the
/// disparity of the previous match in the row, else the pixel is ambiguous.
fn match_row(
    from: &[f32],
    to: &[f32],
    max_step: f32,
    d_min: f64,
    d_max: f64,
    sign: f64,
) -> Vec<Match> {
    let runs = runs(to, max_step);
    let index = RunIndex::new(&runs);
    let mut out = vec![Match::None; from.len()];
    let mut previous: Option<f64> = None;
    let mut candidates = Vec::with_capacity(4);
    // Where each run last found a code: the next code is found a step or two from it.
    let mut hints: Vec<usize> = runs.iter().map(|r| r.start).collect();
    for (x, &code) in from.iter().enumerate() {
        if !code.is_finite() {
            previous = None;
            continue;
        }
        candidates.clear();
        for &k in index.near(code) {
            let run = &runs[k as usize];
            if !(run.lo <= code && code <= run.hi) {
                continue;
            }
            let (xt, at) = position(to, run, code, hints[k as usize]);
            hints[k as usize] = at;
            let d = sign * (x as f64 - xt);
            if d >= d_min && d <= d_max {
                candidates.push((xt, d));
            }
        }
        out[x] = match candidates.as_slice() {
            [] => Match::None,
            [(xt, _)] => Match::At(*xt, true),
            many => match previous {
                Some(p) => {
                    let (best, second) =
                        many.iter()
                            .fold((f64::INFINITY, f64::INFINITY), |(b, s), (_, d)| {
                                let e = (d - p).abs();
                                if e < b { (e, b) } else { (b, s.min(e)) }
                            });
                    // Continuity decides only when it is clear.
                    if best < 2.0 && second > 4.0 * best.max(0.5) {
                        many.iter()
                            .find(|(_, d)| (d - p).abs() == best)
                            .map_or(Match::Ambiguous, |(xt, _)| Match::At(*xt, false))
                    } else {
                        Match::Ambiguous
                    }
                }
                None => Match::Ambiguous,
            },
        };
        previous = match out[x] {
            Match::At(xt, _) => Some(sign * (x as f64 - xt)),
            _ => None,
        };
    }
    out
}

/// The backward match at the sub-pixel position `x` of the other row: linear between the two
/// pixels around it when both matched, else the nearer one's. Only matches that were the one
/// candidate count: a code that the other row carries on two surfaces, one of them occluded
/// in this camera, would otherwise confirm the wrong one.
fn back_at(backward: &[Match], x: f64) -> Option<f64> {
    let i0 = x.floor();
    if i0 < 0.0 {
        return None;
    }
    let i0 = i0 as usize;
    let at = |i: usize| match backward.get(i) {
        Some(Match::At(v, true)) => Some(*v),
        _ => None,
    };
    let t = x - i0 as f64;
    match (at(i0), at(i0 + 1)) {
        (Some(a), Some(b)) => Some(a + (b - a) * t),
        (Some(a), None) if t <= 0.5 => Some(a),
        (None, Some(b)) if t >= 0.5 => Some(b),
        _ => None,
    }
}

/// Whether the projector rows of a match agree: `row_left` against the right row's code
/// interpolated at `xr`.
fn rows_agree(row_left: &f32, right_rows: &[f32], xr: f64, cfg: &BinocularConfig) -> bool {
    let i0 = xr.floor().max(0.0) as usize;
    let (Some(&a), Some(&b)) = (
        right_rows.get(i0),
        right_rows.get(i0 + 1).or(right_rows.get(i0)),
    ) else {
        return false;
    };
    let t = (xr - i0 as f64) as f32;
    let r = a + (b - a) * t;
    row_left.is_finite() && r.is_finite() && (row_left - r).abs() <= cfg.max_row_difference
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};
    use sl_camera::{Distortion, ImageSize, Intrinsics};

    use super::*;

    fn camera(k1: f64) -> CameraModel {
        CameraModel::new(
            Intrinsics::new(900.0, 900.0, 319.5, 239.5),
            Distortion::from_opencv(&[k1, 0.01, 0.0, 0.0, 0.0]).unwrap(),
            ImageSize::new(640, 480),
        )
        .unwrap()
    }

    /// A rig as most binocular scanners are built: the right camera 120 mm to the right, toed
    /// in by 8 degrees, with a little tilt; the projector between them.
    struct Rig {
        left: CameraModel,
        right: CameraModel,
        t_left_right: Isometry3<f64>,
        projector: CameraModel,
        t_left_proj: Isometry3<f64>,
    }

    fn rig() -> Rig {
        Rig {
            left: camera(-0.08),
            right: camera(0.05),
            t_left_right: Isometry3::from_parts(
                Translation3::new(120.0, 2.0, 5.0),
                UnitQuaternion::from_euler_angles(0.01, -8f64.to_radians(), 0.005),
            ),
            projector: CameraModel::new(
                Intrinsics::new(1400.0, 1400.0, 511.5, 383.5),
                Distortion::from_opencv(&[0.1, -0.2, 0.0, 0.0, 0.0]).unwrap(),
                ImageSize::new(1024, 768),
            )
            .unwrap(),
            t_left_proj: Isometry3::from_parts(
                Translation3::new(60.0, -20.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, -4f64.to_radians(), 0.0),
            ),
        }
    }

    /// A sphere of radius 60 mm at 500 mm in front of a wall at 650 mm (left frame).
    fn hit(origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Point3<f64>> {
        let c = Point3::new(10.0, 0.0, 500.0);
        let oc = origin - c;
        let b = oc.dot(dir);
        let disc = b * b - (oc.norm_squared() - 60.0 * 60.0);
        let sphere = (disc >= 0.0).then(|| -b - disc.sqrt()).filter(|t| *t > 0.0);
        let wall = ((650.0 - origin.z) / dir.z).max(0.0);
        let t = sphere.map_or(wall, |s| s.min(wall));
        Some(origin + dir * t)
    }

    /// What each camera decodes: the projector column (and row) of the surface point its pixel
    /// sees, where the projector lights it (no shadow test: the projector sits between).
    fn decoded(
        r: &Rig,
        model: &CameraModel,
        t_left_cam: &Isometry3<f64>,
        rows: bool,
    ) -> CorrespondenceMap {
        let (w, h) = (model.size.width as usize, model.size.height as usize);
        let mut map = CorrespondenceMap::new(w, h);
        let origin = Point3::from(t_left_cam.translation.vector);
        for y in 0..h {
            for x in 0..w {
                let Some(ray) = model.unproject(&Point2::new(x as f64, y as f64)) else {
                    continue;
                };
                let dir = (t_left_cam.rotation * ray).normalize();
                let Some(p) = hit(&origin, &dir) else {
                    continue;
                };
                // Occlusion in this camera is what `hit` gives; the projector's own view is
                // taken as unobstructed.
                if let Some(q) = r.projector.project(&(r.t_left_proj.inverse() * p))
                    && q.x >= 0.0
                    && q.x <= 1023.0
                {
                    map.col[y * w + x] = q.x as f32;
                    if rows {
                        map.row[y * w + x] = q.y as f32;
                    }
                }
            }
        }
        map
    }

    /// The truth of a point: its distance from the surface (sphere or wall).
    fn error_mm(p: &Point3<f64>) -> f64 {
        let s = ((p - Point3::new(10.0, 0.0, 500.0)).norm() - 60.0).abs();
        let wall = (p.z - 650.0).abs();
        s.min(wall)
    }

    #[test]
    fn the_pair_reconstructs_the_scene_it_decoded() {
        let r = rig();
        let b = Binocular::new(&r.left, &r.right, &r.t_left_right).unwrap();
        for rows in [false, true] {
            let left = decoded(&r, &r.left, &Isometry3::identity(), rows);
            let right = decoded(&r, &r.right, &r.t_left_right, rows);
            let out = b
                .reconstruct(&left, &right, &BinocularConfig::default())
                .unwrap();
            let n = out.cloud.len();
            assert_eq!(n, out.counts.valid);
            // The sphere and the wall fill most of the overlap of the two views.
            assert!(n > 150_000, "{n} points, {:?}", out.counts);
            let errors: Vec<f64> = out.cloud.positions().iter().map(error_mm).collect();
            let rms = (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
            let worst = errors.iter().copied().fold(0.0, f64::max);
            // f32 codes (~1e-4 px) and bilinear sampling of a curved code surface: 0.003 mm at
            // the 99th percentile, 0.06 mm at worst (a pixel beside the sphere's rim).
            assert!(rms < 0.01, "rows {rows}: RMS {rms} mm");
            assert!(worst < 0.1, "rows {rows}: worst {worst} mm");
            // The points lost are the ones one camera cannot see: the sphere's shadow on the
            // wall in the right camera, and the margins outside its view.
            let c = out.counts;
            assert!(
                c.ambiguous + c.mixed_pixels + c.isolated < c.decoded / 1000,
                "{c:?}"
            );
        }
    }

    /// The rectified rows are epipolar lines: a point seen by both cameras lands on the same
    /// rectified row in each, and back-projects to itself.
    #[test]
    fn rectified_rows_are_epipolar_lines() {
        let r = rig();
        let b = Binocular::new(&r.left, &r.right, &r.t_left_right).unwrap();
        let (f, (cxl, cxr, cy), baseline) = b.rectified();
        assert!((baseline - (120f64.powi(2) + 4.0 + 25.0).sqrt()).abs() < 1e-9);
        for p in [
            Point3::new(0.0, 0.0, 500.0),
            Point3::new(-80.0, 60.0, 700.0),
        ] {
            let vl = b.r_rect * p.coords;
            let pr = r.t_left_right.inverse() * p;
            let vr = b.r_rect * (r.t_left_right.rotation * pr.coords);
            let (xl, yl) = (f * vl.x / vl.z + cxl, f * vl.y / vl.z + cy);
            let (xr, yr) = (f * vr.x / vr.z + cxr, f * vr.y / vr.z + cy);
            assert!((yl - yr).abs() < 1e-9, "{yl} {yr}");
            let q = b.point(xl, yl, xl - xr);
            assert!((q - p).norm() < 1e-9, "{q} {p}");
        }
    }

    /// A right camera that sees a different surface with the same codes (here: its map shifted
    /// by 40 px, as a wrong match would be) is caught by the checks, not triangulated.
    #[test]
    fn maps_that_do_not_belong_together_give_no_points() {
        let r = rig();
        let b = Binocular::new(&r.left, &r.right, &r.t_left_right).unwrap();
        let left = decoded(&r, &r.left, &Isometry3::identity(), true);
        let mut right = decoded(&r, &r.right, &r.t_left_right, true);
        // The rows say which projector row each pixel saw: shifted rows disagree.
        let w = right.width;
        let shifted: Vec<f32> = (0..right.row.len())
            .map(|i| {
                if i + 40 * w < right.row.len() {
                    right.row[i + 40 * w]
                } else {
                    f32::NAN
                }
            })
            .collect();
        right.row = shifted;
        let out = b
            .reconstruct(&left, &right, &BinocularConfig::default())
            .unwrap();
        assert!(
            out.counts.valid < out.counts.decoded / 20,
            "{:?}",
            out.counts
        );
    }

    #[test]
    fn a_pair_without_baseline_or_with_maps_of_the_wrong_size_is_refused() {
        let r = rig();
        let err = Binocular::new(&r.left, &r.right, &Isometry3::identity()).unwrap_err();
        assert!(err.to_string().contains("t_left_right"), "{err}");
        let b = Binocular::new(&r.left, &r.right, &r.t_left_right).unwrap();
        let small = CorrespondenceMap::new(320, 240);
        let err = b
            .reconstruct(&small, &small, &BinocularConfig::default())
            .unwrap_err();
        assert!(err.to_string().contains("left correspondence map"), "{err}");
        let cfg = BinocularConfig {
            max_code_step: f32::NAN,
            ..BinocularConfig::default()
        };
        let full = CorrespondenceMap::new(640, 480);
        let err = b.reconstruct(&full, &full, &cfg).unwrap_err();
        assert!(err.to_string().contains("max_code_step"), "{err}");
    }
}
