//! What every pattern block shares: the coded axis, the projector size, and the [`Pattern`]
//! enum that ties the codecs together.

use crate::{CodecError, GrayCodeSpec, GrayReference, HybridSpec, PhaseShiftSpec};

/// Size of the projector image in pixels: the workspace's one image size, [`sl_image::ImageSize`],
/// re-exported so codec users need one import.
pub use sl_image::ImageSize;

/// The projector coordinate a block codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// The projector column `x`: vertical stripes / fringes.
    Column,
    /// The projector row `y`: horizontal stripes / fringes.
    Row,
}

impl Axis {
    /// Number of projector pixels along this axis (width for columns, height for rows).
    pub fn extent(self, size: ImageSize) -> u32 {
        match self {
            Self::Column => size.width,
            Self::Row => size.height,
        }
    }

    /// `"column"` or `"row"`, as written in manifests.
    pub fn name(self) -> &'static str {
        match self {
            Self::Column => "column",
            Self::Row => "row",
        }
    }

    /// Parses `"column"`/`"x"` or `"row"`/`"y"`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "column" | "col" | "x" => Some(Self::Column),
            "row" | "y" => Some(Self::Row),
            _ => None,
        }
    }

    /// Picks the coordinate along this axis from a projector point `(x, y)`.
    #[inline]
    pub fn pick(self, x: f64, y: f64) -> f64 {
        match self {
            Self::Column => x,
            Self::Row => y,
        }
    }
}

/// Sample depth of rendered pattern images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BitDepth {
    /// 8-bit grey (the default: what projectors take).
    #[default]
    Eight,
    /// 16-bit grey, for projectors or simulators that take more levels.
    Sixteen,
}

impl BitDepth {
    /// 8 or 16.
    pub fn bits(self) -> u32 {
        match self {
            Self::Eight => 8,
            Self::Sixteen => 16,
        }
    }

    /// Parses 8 or 16.
    pub fn from_bits(bits: u64) -> Option<Self> {
        match bits {
            8 => Some(Self::Eight),
            16 => Some(Self::Sixteen),
            _ => None,
        }
    }
}

/// One block of a pattern sequence: a codec instance for one axis.
///
/// Each block owns a contiguous run of frames whose order is fixed by the codec (see the
/// `frame_count` and `pattern_value` methods of each spec, and `docs/capture-format.md`).
#[derive(Clone, Debug, PartialEq)]
pub enum Pattern {
    /// Gray code (or plain binary) stripes.
    Gray(GrayCodeSpec),
    /// N-step phase shift at one or more frequencies, with temporal unwrapping.
    Phase(PhaseShiftSpec),
    /// Phase shift for the sub-pixel position, Gray code for the period index.
    Hybrid(HybridSpec),
}

impl Pattern {
    /// The coded axis.
    pub fn axis(&self) -> Axis {
        match self {
            Self::Gray(s) => s.axis,
            Self::Phase(s) => s.axis,
            Self::Hybrid(s) => s.axis,
        }
    }

    /// `"gray"`, `"phase"` or `"hybrid"`, as written in manifests.
    pub fn codec_name(&self) -> &'static str {
        match self {
            Self::Gray(_) => "gray",
            Self::Phase(_) => "phase",
            Self::Hybrid(_) => "hybrid",
        }
    }

    /// Number of frames of the block.
    pub fn frame_count(&self) -> usize {
        match self {
            Self::Gray(s) => s.frame_count(),
            Self::Phase(s) => s.frame_count(),
            Self::Hybrid(s) => s.frame_count(),
        }
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming the first parameter out of its domain.
    pub fn validate(&self) -> Result<(), CodecError> {
        match self {
            Self::Gray(s) => {
                s.validate()?;
                s.check_covers()?;
                // The decoder refuses it (no fringes to take the mean of): refuse it here too,
                // so that no pattern set is written, or manifest read, that cannot be decoded.
                if s.reference == GrayReference::PhaseMean {
                    return Err(CodecError::parameter(
                        "reference",
                        "'phase_mean' needs phase-shift frames: use it in a hybrid block",
                    ));
                }
                Ok(())
            }
            Self::Phase(s) => s.validate(),
            Self::Hybrid(s) => s.validate(),
        }
    }

    /// Intensity in `[0, 1]` that frame `frame` of the block shows at the continuous projector
    /// point `(x, y)` (pixel centres at integers), or `None` if `frame` is out of range.
    ///
    /// This is the exact, unquantised pattern (gamma pre-compensation included); rendered
    /// images sample it at pixel centres and round to the bit depth.
    pub fn pattern_value(&self, frame: usize, x: f64, y: f64) -> Option<f64> {
        let t = self.axis().pick(x, y);
        match self {
            Self::Gray(s) => s.pattern_value(frame, t),
            Self::Phase(s) => s.pattern_value(frame, t),
            Self::Hybrid(s) => s.pattern_value(frame, t),
        }
    }
}

/// `ceil(log2(n))` for `n >= 1` (0 for `n <= 1`).
pub(crate) fn ceil_log2(n: u64) -> u32 {
    if n <= 1 {
        0
    } else {
        64 - (n - 1).leading_zeros()
    }
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn positive(name: &str, value: f64) -> Result<(), CodecError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(CodecError::parameter(
            name,
            format!("must be a finite number > 0, got {value}"),
        ))
    }
}

/// Checks that `value` is finite.
/// Checks that `value` is finite and within `±bound` (`unit` for the message).
pub(crate) fn within(name: &str, value: f64, bound: f64, unit: &str) -> Result<(), CodecError> {
    if value.is_finite() && value.abs() <= bound {
        Ok(())
    } else {
        Err(CodecError::parameter(
            name,
            format!("must be within ±{bound} {unit}, got {value}"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ceil_log2_values() {
        assert_eq!(ceil_log2(1), 0);
        assert_eq!(ceil_log2(2), 1);
        assert_eq!(ceil_log2(3), 2);
        assert_eq!(ceil_log2(1024), 10);
        assert_eq!(ceil_log2(1080), 11);
        assert_eq!(ceil_log2(1920), 11);
        assert_eq!(ceil_log2(2049), 12);
    }

    #[test]
    fn axis_names_round_trip() {
        for a in [Axis::Column, Axis::Row] {
            assert_eq!(Axis::from_name(a.name()), Some(a));
        }
        assert_eq!(Axis::from_name("diagonal"), None);
        assert_eq!(Axis::Row.extent(ImageSize::new(1920, 1080)), 1080);
    }
}
