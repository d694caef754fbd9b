//! The decoder's output: per camera pixel, the projector point that lit it.

/// Why a camera pixel has no correspondence (or [`InvalidReason::Valid`] if it has one).
///
/// Stored as one byte per pixel, with the byte values below. When several reasons apply (for
/// example on two axes), the one with the larger byte wins: `Saturated` over `Shadow` over
/// `LowModulation` over `InconsistentCode`.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
pub enum InvalidReason {
    /// Every coded axis decoded.
    #[default]
    Valid = 0,
    /// The bits or phases read but do not agree: a code the projector never emits, a temporal
    /// unwrapping residual above tolerance, or frequencies that disagree.
    InconsistentCode = 1,
    /// Light arrives but the pattern cannot be read: too little direct light or modulation
    /// against a bright (ambient / global) background, or a Gray bit that neither the contrast
    /// test nor Xu & Aliaga's rules can classify (and that is not a stripe edge).
    LowModulation = 2,
    /// Dark and unmodulated: no direct projector light reaches the pixel (Gray: direct light
    /// below `min_direct` and darkest value below it too; phase: modulation below
    /// `min_modulation` and darkest value below it too).
    Shadow = 3,
    /// Samples at the saturation level where they carry the code.
    Saturated = 4,
}

impl InvalidReason {
    /// All reasons, in byte order.
    pub const ALL: [Self; 5] = [
        Self::Valid,
        Self::InconsistentCode,
        Self::LowModulation,
        Self::Shadow,
        Self::Saturated,
    ];

    /// Lower-case name (`"valid"`, `"shadow"`, ...), as used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Valid => "valid",
            Self::Shadow => "shadow",
            Self::LowModulation => "low_modulation",
            Self::InconsistentCode => "inconsistent_code",
            Self::Saturated => "saturated",
        }
    }

    /// `true` for [`InvalidReason::Valid`].
    pub fn is_valid(self) -> bool {
        self == Self::Valid
    }

    /// Merges the reasons of two axes: the larger byte wins.
    #[inline(always)]
    pub(crate) fn merge(self, other: Self) -> Self {
        if other > self { other } else { self }
    }
}

/// One camera pixel's correspondence, as returned by [`CorrespondenceMap::get`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correspondence {
    /// Projector column (NaN if the column was not coded or not decoded).
    pub col: f32,
    /// Projector row (NaN if the row was not coded or not decoded).
    pub row: f32,
    /// Quality: the smallest modulation / direct light over the coded axes, 8-bit grey levels.
    pub quality: f32,
    /// Why the pixel is invalid, or `Valid`.
    pub invalid: InvalidReason,
}

/// Per camera pixel: projector column and row, a quality value and an invalid reason.
///
/// All vectors are row-major with `width * height` entries: pixel `(x, y)` is at index
/// `y * width + x`. `col` and `row` are NaN where that axis was not coded or failed to decode;
/// `invalid` is `Valid` only where every coded axis decoded. `quality` is in 8-bit grey levels
/// (16-bit inputs are divided by 257): the direct light `Ld` for Gray codes, the fringe
/// modulation `B` for phase codes, the smallest over the coded axes (and `+inf` if no axis is
/// coded).
#[derive(Clone, Debug, PartialEq)]
pub struct CorrespondenceMap {
    /// Camera image width.
    pub width: usize,
    /// Camera image height.
    pub height: usize,
    /// Projector column seen by each camera pixel (pixel-centre convention, see crate docs).
    pub col: Vec<f32>,
    /// Projector row seen by each camera pixel.
    pub row: Vec<f32>,
    /// Decoding quality, 8-bit grey levels.
    pub quality: Vec<f32>,
    /// Why each pixel is invalid, or `Valid`.
    pub invalid: Vec<InvalidReason>,
}

impl CorrespondenceMap {
    /// An empty map: no axis decoded, every pixel valid with infinite quality.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            col: vec![f32::NAN; n],
            row: vec![f32::NAN; n],
            quality: vec![f32::INFINITY; n],
            invalid: vec![InvalidReason::Valid; n],
        }
    }

    /// Resets to the state of [`CorrespondenceMap::new`], reusing the allocations.
    pub fn reset(&mut self, width: usize, height: usize) {
        let n = width * height;
        self.width = width;
        self.height = height;
        for (v, fill) in [
            (&mut self.col, f32::NAN),
            (&mut self.row, f32::NAN),
            (&mut self.quality, f32::INFINITY),
        ] {
            v.clear();
            v.resize(n, fill);
        }
        self.invalid.clear();
        self.invalid.resize(n, InvalidReason::Valid);
    }
    /// Sets the size to `width x height` keeping the allocations; the contents are left for the
    /// decoder to overwrite.
    pub(crate) fn resize(&mut self, width: usize, height: usize) {
        let n = width * height;
        self.width = width;
        self.height = height;
        self.col.resize(n, f32::NAN);
        self.row.resize(n, f32::NAN);
        self.quality.resize(n, f32::INFINITY);
        self.invalid.resize(n, InvalidReason::Valid);
    }

    /// The correspondence at camera pixel `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<Correspondence> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = y * self.width + x;
        Some(Correspondence {
            col: *self.col.get(i)?,
            row: *self.row.get(i)?,
            quality: *self.quality.get(i)?,
            invalid: *self.invalid.get(i)?,
        })
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// `true` for a 0-pixel map.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Fraction of valid pixels in `[0, 1]` (0 for an empty map).
    pub fn valid_fraction(&self) -> f64 {
        if self.invalid.is_empty() {
            return 0.0;
        }
        let n = self.invalid.iter().filter(|r| r.is_valid()).count();
        n as f64 / self.invalid.len() as f64
    }

    /// How many pixels carry each reason, indexed like [`InvalidReason::ALL`].
    pub fn reason_counts(&self) -> [usize; 5] {
        let mut counts = [0usize; 5];
        for r in &self.invalid {
            if let Some(c) = counts.get_mut(*r as usize) {
                *c += 1;
            }
        }
        counts
    }
}

/// One decoded axis, for the per-codec decoders ([`crate::decode_gray`] and friends).
#[derive(Clone, Debug, PartialEq)]
pub struct AxisMap {
    /// Camera image width.
    pub width: usize,
    /// Camera image height.
    pub height: usize,
    /// Decoded projector coordinate along the block's axis; NaN where invalid.
    pub coord: Vec<f32>,
    /// Quality, 8-bit grey levels.
    pub quality: Vec<f32>,
    /// Why each pixel is invalid, or `Valid`.
    pub invalid: Vec<InvalidReason>,
}

impl AxisMap {
    /// Fraction of valid pixels in `[0, 1]`.
    pub fn valid_fraction(&self) -> f64 {
        if self.invalid.is_empty() {
            return 0.0;
        }
        self.invalid.iter().filter(|r| r.is_valid()).count() as f64 / self.invalid.len() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_priority() {
        use InvalidReason::*;
        assert_eq!(Valid.merge(Shadow), Shadow);
        assert_eq!(Shadow.merge(Valid), Shadow);
        assert_eq!(InconsistentCode.merge(Saturated), Saturated);
        assert_eq!(Saturated.merge(InconsistentCode), Saturated);
        assert_eq!(LowModulation.merge(Shadow), Shadow);
    }

    #[test]
    fn map_accessors() {
        let mut m = CorrespondenceMap::new(3, 2);
        m.col[4] = 7.0;
        m.invalid[0] = InvalidReason::Shadow;
        let c = m.get(1, 1).unwrap();
        assert_eq!(c.col, 7.0);
        assert!(c.row.is_nan());
        assert!(m.get(3, 0).is_none());
        assert!((m.valid_fraction() - 5.0 / 6.0).abs() < 1e-12);
        assert_eq!(m.reason_counts(), [5, 0, 0, 1, 0]);
        m.reset(2, 2);
        assert_eq!(m.len(), 4);
        assert!(m.col.iter().all(|v| v.is_nan()));
        assert_eq!(m.valid_fraction(), 1.0);
    }
}
