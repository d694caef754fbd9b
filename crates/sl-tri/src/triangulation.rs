//! The result of a triangulation: organised per-pixel points, the cloud, and counts.

use nalgebra::Point3;
use rayon::prelude::*;
use sl_cloud::PointCloud;

/// What happened to one camera pixel.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum PointStatus {
    /// A point was triangulated and passed every filter.
    Valid = 0,
    /// The pixel has no usable correspondence: the decoder marked it invalid, or a coordinate
    /// the method needs is NaN.
    #[default]
    NotDecoded = 1,
    /// The geometry has no answer: no camera ray (outside the camera's valid region), the rays
    /// are parallel or meet behind a device, or the point leaves the projector's valid region.
    NoSolution = 2,
    /// Decode quality below [`crate::TriConfig::min_quality`].
    LowQuality = 3,
    /// Depth outside `[min_depth_mm, max_depth_mm]`.
    OutOfDepthRange = 4,
    /// Reprojection error above [`crate::TriConfig::max_reprojection_px`].
    Reprojection = 5,
    /// Dropped by the mixed-pixel filter (depth discontinuity).
    MixedPixel = 6,
}

impl PointStatus {
    /// All statuses, in byte order.
    pub const ALL: [Self; 7] = [
        Self::Valid,
        Self::NotDecoded,
        Self::NoSolution,
        Self::LowQuality,
        Self::OutOfDepthRange,
        Self::Reprojection,
        Self::MixedPixel,
    ];

    /// Lower-case name, as used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Valid => "valid",
            Self::NotDecoded => "not_decoded",
            Self::NoSolution => "no_solution",
            Self::LowQuality => "low_quality",
            Self::OutOfDepthRange => "out_of_depth_range",
            Self::Reprojection => "reprojection",
            Self::MixedPixel => "mixed_pixel",
        }
    }
}

/// How many pixels ended in each [`PointStatus`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TriCounts {
    /// Camera pixels.
    pub pixels: usize,
    /// Points kept ([`PointStatus::Valid`]).
    pub valid: usize,
    /// [`PointStatus::NotDecoded`].
    pub not_decoded: usize,
    /// [`PointStatus::NoSolution`].
    pub no_solution: usize,
    /// [`PointStatus::LowQuality`].
    pub low_quality: usize,
    /// [`PointStatus::OutOfDepthRange`].
    pub out_of_depth_range: usize,
    /// [`PointStatus::Reprojection`].
    pub reprojection: usize,
    /// [`PointStatus::MixedPixel`].
    pub mixed_pixel: usize,
}

impl TriCounts {
    pub(crate) fn from_status(status: &[PointStatus]) -> Self {
        /// Statuses counted per parallel task (1 MiB of the 1-byte statuses would be one
        /// task; 64 KiB gives the two cores several each).
        const CHUNK: usize = 1 << 16;
        let n = status
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut n = [0usize; 7];
                for s in chunk {
                    if let Some(c) = n.get_mut(*s as usize) {
                        *c += 1;
                    }
                }
                n
            })
            .reduce(
                || [0usize; 7],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x += y;
                    }
                    a
                },
            );
        let [
            valid,
            not_decoded,
            no_solution,
            low_quality,
            out_of_depth_range,
            reprojection,
            mixed_pixel,
        ] = n;
        Self {
            pixels: status.len(),
            valid,
            not_decoded,
            no_solution,
            low_quality,
            out_of_depth_range,
            reprojection,
            mixed_pixel,
        }
    }

    /// Pixels with a usable correspondence (everything but [`PointStatus::NotDecoded`]).
    pub fn decoded(&self) -> usize {
        self.pixels - self.not_decoded
    }
}

/// A triangulated correspondence map.
///
/// Per-pixel vectors are row-major, `width × height`, pixel `(x, y)` at `y · width + x`.
#[derive(Clone, Debug)]
pub struct Triangulation {
    /// Camera image width.
    pub width: usize,
    /// Camera image height.
    pub height: usize,
    /// The point of every pixel, camera frame, mm (the organised cloud); NaN where
    /// [`Triangulation::status`] is not `Valid`.
    pub points: Vec<Point3<f64>>,
    /// Reprojection error of every triangulated pixel (px): the RMS over the camera and the
    /// projector of the image distance between the projected point and the observation
    /// (the pixel centre; the decoded coordinates, NaN ones left out). NaN where no point
    /// was triangulated; set also for points later dropped by a filter. Linear and midpoint
    /// compute it only when the reprojection filter is on (NaN otherwise).
    pub reprojection_px: Vec<f32>,
    /// What happened to every pixel.
    pub status: Vec<PointStatus>,
    /// The valid points as a cloud (camera frame, mm) with the decode quality, colours when a
    /// texture was given, and normals from the pixel grid when asked for (facing the camera).
    pub cloud: PointCloud,
    /// Pixel index (`y · width + x`) of every cloud point.
    pub cloud_pixels: Vec<u32>,
    /// Counts per status.
    pub counts: TriCounts,
}

impl Triangulation {
    /// An empty result (no pixels), to be filled by
    /// [`crate::Triangulator::triangulate_into`].
    pub fn empty() -> Self {
        Self {
            width: 0,
            height: 0,
            points: Vec::new(),
            reprojection_px: Vec::new(),
            status: Vec::new(),
            cloud: PointCloud::default(),
            cloud_pixels: Vec::new(),
            counts: TriCounts::default(),
        }
    }

    /// The depth map (camera `z`, mm) as `f32`, NaN where there is no point.
    pub fn depth_map(&self) -> Vec<f32> {
        self.points.iter().map(|p| p.z as f32).collect()
    }

    /// Fraction of the pixels with a valid point, in `[0, 1]`.
    pub fn valid_fraction(&self) -> f64 {
        if self.counts.pixels == 0 {
            0.0
        } else {
            self.counts.valid as f64 / self.counts.pixels as f64
        }
    }

    /// RMS reprojection error (px) over the valid points (NaN if there are none).
    pub fn rms_reprojection_px(&self) -> f64 {
        let (mut sum, mut n) = (0.0f64, 0usize);
        for (e, s) in self.reprojection_px.iter().zip(&self.status) {
            if *s == PointStatus::Valid && e.is_finite() {
                sum += f64::from(*e).powi(2);
                n += 1;
            }
        }
        if n == 0 {
            f64::NAN
        } else {
            (sum / n as f64).sqrt()
        }
    }
}
