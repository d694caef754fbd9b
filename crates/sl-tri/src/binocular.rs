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

use crate::TriError;
use crate::grid_normals::normal_in_rows;
use crate::mixed_pixels::mixed_flags;

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
    /// For each rectified pixel, where it samples the left and the right camera's maps.
    left_taps: Vec<Tap>,
    right_taps: Vec<Tap>,
}

/// Where one rectified pixel samples a camera's decoded map: the index of the top-left of its
/// four neighbours, the offsets to the others and the bilinear weights, worked out once per
/// calibration. Sampling from the rectified positions themselves (a floor, two clamps and two
/// weights per pixel and map) took 12 of the 28 ms of matching a 1280x1024 pair.
#[derive(Debug, Clone, Copy)]
struct Tap {
    /// Index of the top-left neighbour; [`Tap::OUTSIDE`] when the pixel falls outside the image.
    index: u32,
    /// Offset to the lower neighbours (0 on the last row), with [`Tap::NO_RIGHT`] set on the
    /// last column (the right neighbours are the left ones).
    down: u32,
    /// Bilinear weights along x and y, in `[0, 1]`.
    fx: f32,
    fy: f32,
}

impl Tap {
    const OUTSIDE: u32 = u32::MAX;
    const NO_RIGHT: u32 = 1 << 31;
    const NONE: Self = Self {
        index: Self::OUTSIDE,
        down: 0,
        fx: 0.0,
        fy: 0.0,
    };

    /// The tap of image position `(u, v)` in a `width × height` image (`u, v > −0.5`).
    fn new(u: f32, v: f32, width: usize, height: usize) -> Self {
        // Truncation of a non-negative value is its floor, without a libm call.
        let (x0, y0) = (u.max(0.0) as usize, v.max(0.0) as usize);
        let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
        let right = if x1 > x0 { 0 } else { Self::NO_RIGHT };
        Self {
            index: (y0 * width + x0) as u32,
            down: ((y1 - y0) * width) as u32 | right,
            fx: (u - x0 as f32).clamp(0.0, 1.0),
            fy: (v - y0 as f32).clamp(0.0, 1.0),
        }
    }
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
        for (what, m) in [("left", left), ("right", right)] {
            let pixels = u64::from(m.size.width) * u64::from(m.size.height);
            if pixels >= u64::from(Tap::NO_RIGHT) {
                return Err(TriError::param(
                    what,
                    format!("{pixels} pixels: the pair is rectified for images below 2^31 pixels"),
                ));
            }
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
            left_taps: Vec::new(),
            right_taps: Vec::new(),
        };
        b.left_taps = b.remap(left, &r_rect.transpose(), cx_left);
        b.right_taps = b.remap(right, &(r_rect_right.transpose()), cx_right);
        Ok(b)
    }

    /// For every rectified pixel, where it samples the image of `model`, whose frame is
    /// `to_camera · rectified`.
    fn remap(&self, model: &CameraModel, to_camera: &Matrix3<f64>, cx: f64) -> Vec<Tap> {
        let (width, height) = (model.size.width as usize, model.size.height as usize);
        let (w, h) = (f64::from(model.size.width), f64::from(model.size.height));
        let mut map = vec![Tap::NONE; self.width * self.height];
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
                        *out = Tap::new(px.x as f32, px.y as f32, width, height);
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
                let (lt, rt) = (&self.left_taps[span.clone()], &self.right_taps[span]);
                sample(&left.col, lt, step, &mut s.l);
                sample(&right.col, rt, step, &mut s.r);
                if rows {
                    sample(&left.row, lt, f32::INFINITY, &mut s.lr);
                    sample(&right.row, rt, f32::INFINITY, &mut s.rr);
                }
                let (l, r, lr, rr) = (&s.l[..], &s.r[..], &s.lr[..], &s.rr[..]);
                let (forward, backward) = (&mut s.forward, &mut s.backward);
                match_row((l, r), step, (d_min, d_max), 1.0, &mut s.scratch, forward);
                match_row(
                    (r, l),
                    step,
                    (-d_max, -d_min),
                    -1.0,
                    &mut s.scratch,
                    backward,
                );
                let (forward, backward) = (&forward[..], &backward[..]);
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
                    let consistent = back_at(backward, xr)
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
    #[inline]
    pub fn point(&self, x: f64, y: f64, d: f64) -> Point3<f64> {
        // z = f b / (d − (cx_l − cx_r)); one division: s = z / f.
        let s = self.baseline / (d - (self.cx_left - self.cx_right));
        let v = [(x - self.cx_left) * s, (y - self.cy) * s, self.f * s];
        // p_left = r_rectᵀ · v, each coordinate as `depth` computes z.
        let r = &self.r_rect;
        Point3::new(
            r[(0, 0)] * v[0] + r[(1, 0)] * v[1] + r[(2, 0)] * v[2],
            r[(0, 1)] * v[0] + r[(1, 1)] * v[1] + r[(2, 1)] * v[2],
            r[(0, 2)] * v[0] + r[(1, 2)] * v[1] + r[(2, 2)] * v[2],
        )
    }

    /// The left-frame depth of [`Binocular::point`], bit for bit, without the other two
    /// coordinates.
    #[inline]
    fn depth(&self, x: f64, y: f64, d: f64) -> f64 {
        let s = self.baseline / (d - (self.cx_left - self.cx_right));
        let v = [(x - self.cx_left) * s, (y - self.cy) * s, self.f * s];
        let r = &self.r_rect;
        r[(0, 2)] * v[0] + r[(1, 2)] * v[1] + r[(2, 2)] * v[2]
    }

    /// The cloud of a disparity map after the mixed-pixel filter (the points it drops are
    /// cleared from `disparity` and counted) and the lone-point filter, with normals from the
    /// grid's neighbours.
    ///
    /// The filters judge a grid of depths (8 bytes a pixel); the points themselves are made
    /// band by band, three rows at a time, straight into the cloud with their normals. A grid
    /// of points (24 bytes a pixel, 31 MB at 1280x1024) written and read by every pass took
    /// 16–18 ms of the 60 ms budget; the points and normals are the same, bit for bit.
    fn points(
        &self,
        disparity: &mut [f32],
        max_depth_jump: f64,
        counts: &mut BinocularCounts,
    ) -> Result<PointCloud, TriError> {
        let w = self.width;
        if w == 0 {
            return Ok(PointCloud::from_positions(Vec::new()));
        }
        let h = self.height;
        // Rows of the point of each pixel with a disparity (NaN elsewhere).
        let row_points = |y: usize, d: &[f32], out: &mut Vec<Point3<f64>>| {
            out.clear();
            out.extend(d.iter().enumerate().map(|(x, &d)| {
                if d.is_finite() {
                    self.point(x as f64, y as f64, f64::from(d))
                } else {
                    Point3::new(f64::NAN, f64::NAN, f64::NAN)
                }
            }));
        };
        // The depth in the left camera's frame, as the points have it.
        let mut depth = vec![f64::NAN; disparity.len()];
        depth
            .par_chunks_mut(w)
            .zip(disparity.par_chunks(w))
            .enumerate()
            .for_each(|(y, (z, d))| {
                for (x, (z, &d)) in z.iter_mut().zip(d).enumerate() {
                    if d.is_finite() {
                        *z = self.depth(x as f64, y as f64, f64::from(d));
                    }
                }
            });
        // Every pass over the grid below runs on both cores: a sequential pass over 1.3 M
        // pixels costs a millisecond or two, several of them a fifth of the 60 ms target.
        let mixed = mixed_flags(&depth, w, max_depth_jump, |z| *z);
        counts.mixed_pixels += clear(disparity, &mut depth, &mixed);
        // Lone points: no 4-neighbour left after the filter.
        let mut alone = vec![false; depth.len()];
        let depth_rows: Vec<&[f64]> = depth.chunks(w).collect();
        alone.par_chunks_mut(w).enumerate().for_each(|(y, flags)| {
            let here = depth_rows[y];
            let above = y.checked_sub(1).map(|a| depth_rows[a]);
            let below = depth_rows.get(y + 1).copied();
            let has = |row: Option<&[f64]>, x: usize| row.is_some_and(|r| r[x].is_finite());
            for (x, flag) in flags.iter_mut().enumerate() {
                *flag = here[x].is_finite()
                    && !((x > 0 && here[x - 1].is_finite())
                        || (x + 1 < w && here[x + 1].is_finite())
                        || has(above, x)
                        || has(below, x));
            }
        });
        counts.isolated += clear(disparity, &mut depth, &alone);
        counts.valid -= counts.mixed_pixels + counts.isolated;

        // Each band of rows makes its points and their normals (central differences on the
        // rectified grid, as the one-camera triangulation's; zero where a point has no
        // neighbour pair) into its own slice of the cloud.
        const BAND_ROWS: usize = 32;
        let band_counts: Vec<usize> = depth
            .par_chunks(w * BAND_ROWS)
            .map(|band| band.iter().filter(|z| z.is_finite()).count())
            .collect();
        let total = band_counts.iter().sum();
        let mut positions = vec![Point3::origin(); total];
        let mut normals = vec![Vector3::zeros(); total];
        let mut slices = Vec::with_capacity(band_counts.len());
        let (mut rest_p, mut rest_n) = (positions.as_mut_slice(), normals.as_mut_slice());
        for &c in &band_counts {
            let (head_p, tail_p) = rest_p.split_at_mut(c);
            let (head_n, tail_n) = rest_n.split_at_mut(c);
            slices.push((head_p, head_n));
            (rest_p, rest_n) = (tail_p, tail_n);
        }
        let disparity: &[f32] = disparity;
        let row_of = |y: usize| disparity.get(y * w..(y + 1) * w);
        slices
            .into_par_iter()
            .enumerate()
            .for_each(|(band, (out_p, out_n))| {
                let (y0, y1) = (band * BAND_ROWS, ((band + 1) * BAND_ROWS).min(h));
                let mut rows = [Vec::new(), Vec::new(), Vec::new()];
                let fill = |y: Option<usize>, buf: &mut Vec<Point3<f64>>| match y
                    .and_then(|y| row_of(y).map(|d| (y, d)))
                {
                    Some((y, d)) => {
                        row_points(y, d, buf);
                        true
                    }
                    None => false,
                };
                let [above, here, below] = &mut rows;
                let mut has_above = fill(y0.checked_sub(1), above);
                fill(Some(y0), here);
                let mut has_below = fill(Some(y0 + 1), below);
                let mut out = out_p.iter_mut().zip(out_n.iter_mut());
                for y in y0..y1 {
                    for (x, p) in here.iter().enumerate() {
                        if !p.z.is_finite() {
                            continue;
                        }
                        let Some((op, on)) = out.next() else {
                            return;
                        };
                        *op = *p;
                        *on = normal_in_rows(
                            here,
                            has_above.then_some(above.as_slice()),
                            has_below.then_some(below.as_slice()),
                            x,
                            p,
                        );
                    }
                    // Slide the window down a row.
                    std::mem::swap(above, here);
                    std::mem::swap(here, below);
                    has_above = true;
                    has_below = fill(Some(y + 2), below);
                }
            });
        Ok(PointCloud::from_positions(positions).with_normals(normals)?)
    }
}

/// Clears (NaN) the disparity and the depth of each flagged pixel; the number cleared.
fn clear(disparity: &mut [f32], depth: &mut [f64], flags: &[bool]) -> usize {
    disparity
        .par_iter_mut()
        .zip(depth.par_iter_mut())
        .zip(flags.par_iter())
        .map(|((d, z), &f)| {
            if f {
                *d = f32::NAN;
                *z = f64::NAN;
                1
            } else {
                0
            }
        })
        .sum()
}

/// The rows of both maps sampled on one rectified row: columns, and rows when both code them.
#[derive(Default)]
struct RowSamples {
    l: Vec<f32>,
    r: Vec<f32>,
    lr: Vec<f32>,
    rr: Vec<f32>,
    forward: Vec<Match>,
    backward: Vec<Match>,
    scratch: MatchScratch,
}

/// The codes of a decoded map at the rectified pixels of `taps` (one row), into `out`:
/// bilinear where the four neighbours are decoded and within `max_step` of each other, NaN
/// elsewhere.
fn sample(values: &[f32], taps: &[Tap], max_step: f32, out: &mut Vec<f32>) {
    out.clear();
    out.extend(taps.iter().map(|t| {
        if t.index == Tap::OUTSIDE {
            return f32::NAN;
        }
        let i = t.index as usize;
        let right = usize::from(t.down & Tap::NO_RIGHT == 0);
        let below = i + (t.down & !Tap::NO_RIGHT) as usize;
        let (Some(&q0), Some(&q1), Some(&q2), Some(&q3)) = (
            values.get(i),
            values.get(i + right),
            values.get(below),
            values.get(below + right),
        ) else {
            return f32::NAN;
        };
        if !(q0.is_finite() && q1.is_finite() && q2.is_finite() && q3.is_finite()) {
            return f32::NAN;
        }
        let (lo, hi) = (q0.min(q1).min(q2.min(q3)), q0.max(q1).max(q2.max(q3)));
        if hi - lo > max_step {
            return f32::NAN;
        }
        let top = q0 + (q1 - q0) * t.fx;
        let bottom = q2 + (q3 - q2) * t.fx;
        top + (bottom - top) * t.fy
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
#[derive(Default)]
struct RunIndex {
    lo: f32,
    /// Start of each bucket's run indices in `runs`, and the end as the last entry.
    offsets: Vec<u32>,
    runs: Vec<u32>,
    /// Where the next entry of each bucket goes, while building.
    next: Vec<u32>,
}

impl RunIndex {
    /// Width of a bucket (projector pixels of code).
    const BUCKET: f32 = 8.0;

    /// Indexes `runs`, in the buffers of the previous row's index.
    fn build(&mut self, runs: &[Run]) {
        let lo = runs.iter().map(|r| r.lo).fold(f32::INFINITY, f32::min);
        let hi = runs.iter().map(|r| r.hi).fold(f32::NEG_INFINITY, f32::max);
        self.offsets.clear();
        self.runs.clear();
        if !(lo.is_finite() && hi.is_finite()) {
            self.lo = 0.0;
            self.offsets.push(0);
            return;
        }
        self.lo = lo;
        let bucket = |c: f32| ((c - lo) / Self::BUCKET) as usize;
        let count = bucket(hi) + 1;
        let offsets = &mut self.offsets;
        offsets.resize(count + 1, 0);
        for r in runs {
            for b in bucket(r.lo)..=bucket(r.hi) {
                offsets[b + 1] += 1;
            }
        }
        for b in 0..count {
            offsets[b + 1] += offsets[b];
        }
        self.next.clear();
        self.next.extend_from_slice(&offsets[..count]);
        self.runs.resize(offsets[count] as usize, 0);
        for (k, r) in runs.iter().enumerate() {
            for b in bucket(r.lo)..=bucket(r.hi) {
                self.runs[self.next[b] as usize] = k as u32;
                self.next[b] += 1;
            }
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

/// The runs of `row`, into `out`.
fn runs(row: &[f32], max_step: f32, out: &mut Vec<Run>) {
    out.clear();
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
///
/// The matches go to `out`; `scratch` holds the buffers, kept from row to row.
fn match_row(
    (from, to): (&[f32], &[f32]),
    max_step: f32,
    (d_min, d_max): (f64, f64),
    sign: f64,
    scratch: &mut MatchScratch,
    out: &mut Vec<Match>,
) {
    let MatchScratch {
        runs: row_runs,
        index,
        hints,
        candidates,
    } = scratch;
    runs(to, max_step, row_runs);
    let runs = &row_runs[..];
    index.build(runs);
    out.clear();
    out.resize(from.len(), Match::None);
    let mut previous: Option<f64> = None;
    // Where each run last found a code: the next code is found a step or two from it.
    hints.clear();
    hints.extend(runs.iter().map(|r| r.start));
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
}

/// The buffers of [`match_row`], kept from row to row.
#[derive(Default)]
struct MatchScratch {
    runs: Vec<Run>,
    index: RunIndex,
    hints: Vec<usize>,
    candidates: Vec<(f64, f64)>,
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

    /// The banded point stage gives the cloud the grid of points gives — the one-camera
    /// triangulation's mixed-pixel filter and grid normals over every pixel's point, the lone
    /// points dropped — bit for bit, with the same counts; on a map with depth jumps, holes,
    /// lone pixels and a height that is no multiple of the band.
    #[test]
    fn banded_points_equal_the_grid_of_points() {
        use crate::PointStatus;
        use crate::grid_normals::cloud_normals;
        use crate::mixed_pixels::filter_mixed_pixels;
        let r = rig();
        // 470 rows: the last band of 32 rows is a partial one.
        let sized = |k1: f64| {
            CameraModel::new(
                Intrinsics::new(900.0, 900.0, 319.5, 234.5),
                Distortion::from_opencv(&[k1, 0.01, 0.0, 0.0, 0.0]).unwrap(),
                ImageSize::new(640, 470),
            )
            .unwrap()
        };
        let b = Binocular::new(&sized(-0.08), &sized(0.05), &r.t_left_right).unwrap();
        let (w, h) = b.size();
        assert_ne!(h % 32, 0, "{w}x{h}");
        // A smooth surface 500-650 mm away (z = f b / (d - shift)), with holes, a step of
        // 8 px of disparity over bands of columns in the lower half, and a lone pixel.
        let (f, (cx_l, cx_r, _), baseline) = b.rectified();
        let mut disparity = vec![f32::NAN; w * h];
        for (i, d) in disparity.iter_mut().enumerate() {
            let (x, y) = (i % w, i / w);
            let z = 500.0 + 150.0 * (x as f64 / w as f64) + 10.0 * (y as f64 / 37.0).sin();
            let mut v = (f * baseline / z + cx_l - cx_r) as f32;
            if (x / 40) % 3 == 0 && y > h / 2 {
                v += 8.0;
            }
            if (x / 7 + y / 5) % 23 != 0 {
                *d = v;
            }
        }
        disparity[w * 10 + 10] = 300.0;
        for i in [w * 10 + 9, w * 10 + 11, w * 9 + 10, w * 11 + 10] {
            disparity[i] = f32::NAN;
        }
        let jump = BinocularConfig::default().max_depth_jump;

        let mut want_counts = BinocularCounts::default();
        let mut xyz: Vec<Point3<f64>> = disparity
            .iter()
            .enumerate()
            .map(|(i, &d)| {
                if d.is_finite() {
                    want_counts.valid += 1;
                    b.point((i % w) as f64, (i / w) as f64, f64::from(d))
                } else {
                    Point3::new(f64::NAN, f64::NAN, f64::NAN)
                }
            })
            .collect();
        let mut status: Vec<PointStatus> = xyz
            .iter()
            .map(|p| {
                if p.z.is_finite() {
                    PointStatus::Valid
                } else {
                    PointStatus::NotDecoded
                }
            })
            .collect();
        filter_mixed_pixels(&mut xyz, &mut status, w, jump);
        want_counts.mixed_pixels = status
            .iter()
            .filter(|s| **s == PointStatus::MixedPixel)
            .count();
        let alone: Vec<bool> = (0..xyz.len())
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let has = |j: usize| xyz[j].z.is_finite();
                has(i)
                    && !((x > 0 && has(i - 1))
                        || (x + 1 < w && has(i + 1))
                        || (y > 0 && has(i - w))
                        || (y + 1 < h && has(i + w)))
            })
            .collect();
        for (p, &a) in xyz.iter_mut().zip(&alone) {
            if a {
                *p = Point3::new(f64::NAN, f64::NAN, f64::NAN);
            }
        }
        want_counts.isolated = alone.iter().filter(|a| **a).count();
        want_counts.valid -= want_counts.mixed_pixels + want_counts.isolated;
        let band_counts: Vec<usize> = xyz
            .chunks(w * 16)
            .map(|band| band.iter().filter(|p| p.z.is_finite()).count())
            .collect();
        let want_positions: Vec<Point3<f64>> =
            xyz.iter().filter(|p| p.z.is_finite()).copied().collect();
        let mut want_normals = vec![Vector3::zeros(); want_positions.len()];
        cloud_normals(&xyz, w, 16, &band_counts, &mut want_normals);
        assert!(
            want_counts.mixed_pixels > 100 && want_counts.isolated >= 1,
            "{want_counts:?}"
        );

        let mut counts = BinocularCounts {
            valid: disparity.iter().filter(|d| d.is_finite()).count(),
            ..BinocularCounts::default()
        };
        let mut got_disparity = disparity.clone();
        let cloud = b.points(&mut got_disparity, jump, &mut counts).unwrap();
        assert_eq!(counts, want_counts);
        assert_eq!(cloud.len(), want_positions.len());
        let bits = |v: &[f64]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
        for (k, (p, q)) in cloud.positions().iter().zip(&want_positions).enumerate() {
            assert_eq!(
                bits(p.coords.as_slice()),
                bits(q.coords.as_slice()),
                "point {k}"
            );
        }
        let normals = cloud.normals().unwrap();
        for (k, (n, m)) in normals.iter().zip(&want_normals).enumerate() {
            assert_eq!(bits(n.as_slice()), bits(m.as_slice()), "normal {k}");
        }
        // The disparity map keeps exactly the points of the cloud.
        let kept = got_disparity.iter().filter(|d| d.is_finite()).count();
        assert_eq!(kept, cloud.len());
    }

    /// Sampling through taps is bilinear: it gives a plane's value anywhere in the image,
    /// clamped to the last column and row on their outer half pixel, and NaN where a
    /// neighbour is undecoded or the neighbours are further apart than the step.
    #[test]
    fn taps_sample_bilinearly_up_to_the_edges() {
        let (w, h) = (5, 4);
        let plane = |x: f32, y: f32| 10.0 + 3.0 * x + 7.0 * y;
        let mut values: Vec<f32> = (0..w * h)
            .map(|i| plane((i % w) as f32, (i / w) as f32))
            .collect();
        let at = [
            (1.25, 2.5),
            (0.0, 0.0),
            (-0.4, -0.3),
            (4.3, 1.5),
            (2.5, 3.4),
            (4.45, 3.45),
            (3.75, 0.5),
        ];
        let taps: Vec<Tap> = at.iter().map(|&(u, v)| Tap::new(u, v, w, h)).collect();
        let mut out = Vec::new();
        sample(&values, &taps, 100.0, &mut out);
        for (&(u, v), &got) in at.iter().zip(&out) {
            let want = plane(u.clamp(0.0, (w - 1) as f32), v.clamp(0.0, (h - 1) as f32));
            assert!((got - want).abs() < 1e-4, "at ({u}, {v}): {got} vs {want}");
        }
        // Steps of 3 along x and 7 along y: a step of 8 rejects every interior sample.
        sample(&values, &taps[..1], 8.0, &mut out);
        assert!(out[0].is_nan());
        // One undecoded neighbour, (2, 3), spoils the samples that use it and only those.
        values[3 * w + 2] = f32::NAN;
        sample(&values, &taps, 100.0, &mut out);
        let spoilt: Vec<bool> = out.iter().map(|v| v.is_nan()).collect();
        assert_eq!(spoilt, [true, false, false, false, true, false, false]);
        // A pixel outside the image samples nothing.
        sample(&values, &[Tap::NONE], 100.0, &mut out);
        assert!(out[0].is_nan());
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
