//! What to triangulate with, and which points to keep.

use sl_codec::Axis;

use crate::TriError;

/// The triangulation method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Camera ray against the projector's column (or row) surface, distortion included
    /// (Newton on the distorted projection): needs only that coordinate. The fastest, and with
    /// one decoded coordinate the only choice.
    RayPlane {
        /// Which decoded coordinate to use.
        axis: Axis,
    },
    /// Linear least squares (the DLT, inhomogeneous, normal equations in closed form) from
    /// both coordinates. On a map that codes one axis only (a column-only capture), the
    /// three equations of the camera ray and the decoded coordinate, solved exactly, with the
    /// projector's distortion removed by a fixed-point iteration on the other coordinate (see
    /// `linear.rs`).
    Linear,
    /// Midpoint of the closest points of the camera and projector rays, from both
    /// coordinates: a projector ray needs both, so a one-axis map is refused
    /// ([`crate::TriError::MissingAxis`]).
    Midpoint,
    /// Minimum of the squared reprojection errors in camera and projector (Gauss–Newton with
    /// the exact distorted models, started from the ray–plane point), from both coordinates.
    /// On a one-axis map, the minimum constrained to the decoded (curved) projector surface:
    /// three residuals for three unknowns, so the exact ray–surface point, where every
    /// residual is zero.
    Optimal,
}

impl Default for Method {
    /// Ray–plane on the projector column.
    fn default() -> Self {
        Self::RayPlane { axis: Axis::Column }
    }
}

impl Method {
    /// Short name, as used in reports and benches: `ray_plane_column`, `ray_plane_row`,
    /// `linear`, `midpoint`, `optimal`.
    pub fn name(self) -> &'static str {
        match self {
            Self::RayPlane { axis: Axis::Column } => "ray_plane_column",
            Self::RayPlane { axis: Axis::Row } => "ray_plane_row",
            Self::Linear => "linear",
            Self::Midpoint => "midpoint",
            Self::Optimal => "optimal",
        }
    }

    /// Whether the method needs both projector coordinates (only [`Method::Midpoint`]: the
    /// others work on maps that code one axis).
    pub fn needs_both(self) -> bool {
        matches!(self, Self::Midpoint)
    }

    /// What the per-pixel pass runs for this method on a map that codes the given axes;
    /// `None` when no axis is coded (nothing to triangulate: every pixel is `NotDecoded`).
    ///
    /// # Errors
    /// [`TriError::MissingAxis`] when the method needs an axis the map lacks.
    pub(crate) fn solver(self, column: bool, row: bool) -> Result<Option<Solver>, TriError> {
        let one = match (column, row) {
            (true, true) => None,
            (true, false) => Some(Axis::Column),
            (false, true) => Some(Axis::Row),
            (false, false) => return Ok(None),
        };
        let other = |a: Axis| match a {
            Axis::Column => Axis::Row,
            Axis::Row => Axis::Column,
        };
        let missing = |present: Axis| TriError::MissingAxis {
            method: self.name(),
            missing: other(present),
            present,
        };
        Ok(Some(match (self, one) {
            (Self::RayPlane { axis }, Some(present)) if present != axis => {
                return Err(missing(present));
            }
            (Self::RayPlane { axis }, _) => Solver::RayPlane(axis),
            (Self::Linear, None) => Solver::Linear,
            (Self::Linear, Some(a)) => Solver::LinearOneAxis(a),
            (Self::Midpoint, None) => Solver::Midpoint,
            (Self::Midpoint, Some(present)) => return Err(missing(present)),
            (Self::Optimal, None) => Solver::Optimal,
            // Three residuals (camera u, v and the decoded coordinate) for three unknowns:
            // the constrained optimum is the exact ray–surface point.
            (Self::Optimal, Some(a)) => Solver::RayPlane(a),
        }))
    }
}

/// The computation the per-pixel pass runs: a [`Method`] resolved against the axes a map codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Solver {
    /// Ray against the exact projector surface of one coordinate.
    RayPlane(Axis),
    /// DLT with both coordinates.
    Linear,
    /// DLT with the one coded coordinate.
    LinearOneAxis(Axis),
    /// Midpoint of the two rays.
    Midpoint,
    /// Gauss–Newton on both coordinates.
    Optimal,
}

impl Solver {
    /// Whether a pixel with these decoded coordinates (finite or not) has what the solver
    /// needs.
    #[inline(always)]
    pub(crate) fn has_coordinates(self, c: f32, r: f32) -> bool {
        match self {
            Self::RayPlane(Axis::Column) | Self::LinearOneAxis(Axis::Column) => c.is_finite(),
            Self::RayPlane(Axis::Row) | Self::LinearOneAxis(Axis::Row) => r.is_finite(),
            Self::Linear | Self::Midpoint | Self::Optimal => c.is_finite() && r.is_finite(),
        }
    }
}

/// Default largest reprojection error (px): decoded coordinates of a good scan are within a
/// few tenths of a pixel (Gray code alone quantises to ±0.5 px), so 2 px keeps every honest
/// point and drops gross decoding errors.
pub const DEFAULT_MAX_REPROJECTION_PX: f64 = 2.0;

/// Default largest relative depth jump to a 4-neighbour before a pixel counts as mixed: 1 %
/// of the depth (4.5 mm at 450 mm). Neighbouring pixels of the default rig are 0.3 mm apart
/// at 450 mm, so a surface must be inclined by more than ~86° to the line of sight to be cut,
/// while the mixed pixels straddling an object's silhouette (jumps of centimetres) go.
pub const DEFAULT_MAX_DEPTH_JUMP: f64 = 0.01;

/// Default Gauss–Newton iterations of [`Method::Optimal`]: from the ray–plane start, 2 steps
/// reach the optimum to below 1e-7 mm; 5 is headroom.
pub const DEFAULT_OPTIMAL_ITERATIONS: usize = 5;

/// Options of [`crate::Triangulator::triangulate`]: the method and the filters.
#[derive(Clone, Debug, PartialEq)]
pub struct TriConfig {
    /// The triangulation method.
    pub method: Method,
    /// Pixels with a decode quality below this (8-bit grey levels, as
    /// [`sl_codec::CorrespondenceMap::quality`]) are dropped.
    pub min_quality: f32,
    /// Points nearer than this depth (camera `z`, mm) are dropped.
    pub min_depth_mm: f64,
    /// Points farther than this depth (mm) are dropped.
    pub max_depth_mm: f64,
    /// Points whose reprojection error (px, RMS over camera and projector, see
    /// [`crate::Triangulation::reprojection_px`]) exceeds this are dropped. With
    /// [`Method::RayPlane`] only the other coordinate, when decoded, can disagree.
    /// `f64::INFINITY` disables the filter; [`Method::Linear`] and [`Method::Midpoint`] then
    /// skip computing the error (it costs two distorted projections per pixel) and leave
    /// [`crate::Triangulation::reprojection_px`] NaN.
    pub max_reprojection_px: f64,
    /// Mixed-pixel filter: a point whose depth differs from a valid 4-neighbour by more than
    /// this fraction of its depth is dropped. `f64::INFINITY` disables the filter.
    pub max_depth_jump: f64,
    /// Compute normals from the pixel grid.
    pub normals: bool,
    /// Gauss–Newton iterations of [`Method::Optimal`].
    pub optimal_iterations: usize,
}

impl Default for TriConfig {
    fn default() -> Self {
        Self {
            method: Method::default(),
            min_quality: 0.0,
            min_depth_mm: 1.0,
            max_depth_mm: f64::INFINITY,
            max_reprojection_px: DEFAULT_MAX_REPROJECTION_PX,
            max_depth_jump: DEFAULT_MAX_DEPTH_JUMP,
            normals: true,
            optimal_iterations: DEFAULT_OPTIMAL_ITERATIONS,
        }
    }
}

impl TriConfig {
    /// Default options with another method.
    pub fn with_method(method: Method) -> Self {
        Self {
            method,
            ..Self::default()
        }
    }

    /// Checks every option.
    ///
    /// # Errors
    /// [`TriError::InvalidParameter`] naming the option.
    pub fn validate(&self) -> Result<(), TriError> {
        if self.min_quality.is_nan() {
            return Err(TriError::param("min_quality", "is NaN"));
        }
        if !(self.min_depth_mm >= 0.0 && self.max_depth_mm > self.min_depth_mm) {
            return Err(TriError::param(
                "min_depth_mm / max_depth_mm",
                format!(
                    "{} / {}: need 0 <= min < max",
                    self.min_depth_mm, self.max_depth_mm
                ),
            ));
        }
        if !(self.max_reprojection_px > 0.0) {
            return Err(TriError::param(
                "max_reprojection_px",
                format!("{} is not positive", self.max_reprojection_px),
            ));
        }
        if !(self.max_depth_jump > 0.0) {
            return Err(TriError::param(
                "max_depth_jump",
                format!("{} is not positive", self.max_depth_jump),
            ));
        }
        if self.optimal_iterations == 0 {
            return Err(TriError::param("optimal_iterations", "must be at least 1"));
        }
        Ok(())
    }
}

/// Colour source for the cloud: a fully lit camera frame, one value per camera pixel.
#[derive(Clone, Copy, Debug)]
pub enum Texture<'a> {
    /// 8-bit grey.
    Grey8(&'a [u8]),
    /// 16-bit grey (scaled to 8 bits by `>> 8`).
    Grey16(&'a [u16]),
    /// 8-bit RGB.
    Rgb8(&'a [[u8; 3]]),
}

impl Texture<'_> {
    pub(crate) fn len(&self) -> usize {
        match self {
            Self::Grey8(v) => v.len(),
            Self::Grey16(v) => v.len(),
            Self::Rgb8(v) => v.len(),
        }
    }

    #[inline]
    pub(crate) fn color(&self, i: usize) -> [u8; 3] {
        match self {
            Self::Grey8(v) => {
                let g = v.get(i).copied().unwrap_or(0);
                [g, g, g]
            }
            Self::Grey16(v) => {
                let g = (v.get(i).copied().unwrap_or(0) >> 8) as u8;
                [g, g, g]
            }
            Self::Rgb8(v) => v.get(i).copied().unwrap_or([0, 0, 0]),
        }
    }
}
