//! Grey camera frames: 8- or 16-bit samples in one contiguous row-major buffer.

use crate::ImageError;

mod sealed {
    pub trait Sealed {}
    impl Sealed for u8 {}
    impl Sealed for u16 {}
}

/// A grey sample type: `u8` or `u16`.
///
/// The trait is sealed; its methods exist so that code (the decoders of `sl-codec`, the
/// renderers) can be written once for both depths.
pub trait Sample:
    Copy + Default + PartialOrd + Send + Sync + std::fmt::Debug + sealed::Sealed + 'static
{
    /// The largest value (`255` or `65535`).
    const MAX_VALUE: Self;
    /// Factor from 8-bit grey levels to this type's grey levels (`1` or `257`).
    ///
    /// A threshold given in 8-bit grey levels (as `sl-codec`'s decoders take them) is
    /// multiplied by this factor, so one configuration serves both depths.
    const SCALE_FROM_8BIT: f32;
    /// Bits per sample (8 or 16).
    const BITS: u32;
    /// The value as `f32`.
    fn to_f32(self) -> f32;
    /// The value as `u16` (exact for both types).
    fn to_u16(self) -> u16;
    /// Quantises an intensity in `[0, 1]` (clamped) to the nearest level.
    fn from_unit(value: f64) -> Self;
    /// Converts a raw `u16` saturating to this type's range (used by `sl-codec`'s synthetic
    /// renderer).
    fn from_u16_saturating(value: u16) -> Self;
}

impl Sample for u8 {
    const MAX_VALUE: Self = u8::MAX;
    const SCALE_FROM_8BIT: f32 = 1.0;
    const BITS: u32 = 8;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    #[inline(always)]
    fn to_u16(self) -> u16 {
        u16::from(self)
    }
    #[inline]
    fn from_unit(value: f64) -> Self {
        // The clamp makes the cast exact and in range (NaN maps to 0 with `as`).
        (value.clamp(0.0, 1.0) * 255.0).round() as u8
    }
    #[inline]
    fn from_u16_saturating(value: u16) -> Self {
        value.min(255) as u8
    }
}

impl Sample for u16 {
    const MAX_VALUE: Self = u16::MAX;
    const SCALE_FROM_8BIT: f32 = 257.0;
    const BITS: u32 = 16;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    #[inline(always)]
    fn to_u16(self) -> u16 {
        self
    }
    #[inline]
    fn from_unit(value: f64) -> Self {
        (value.clamp(0.0, 1.0) * 65535.0).round() as u16
    }
    #[inline]
    fn from_u16_saturating(value: u16) -> Self {
        value
    }
}

/// Refuses an empty image (`what`: "a frame", "an image") or a buffer of `len` pixels that is
/// not `width * height`.
pub(crate) fn check_buffer(
    what: &str,
    width: usize,
    height: usize,
    len: usize,
) -> Result<(), ImageError> {
    if width == 0 || height == 0 {
        return Err(ImageError::invalid(
            "width/height",
            format!("{what} must not be empty, got {width}x{height}"),
        ));
    }
    let expected = width.checked_mul(height).ok_or_else(|| {
        ImageError::invalid("width/height", format!("{width}x{height} overflows usize"))
    })?;
    if len != expected {
        return Err(ImageError::BufferLength {
            width,
            height,
            expected,
            found: len,
        });
    }
    Ok(())
}

/// One grey frame: `width * height` samples, row-major, no padding.
///
/// Pixel `(x, y)` is at `data[y * width + x]`; `x` grows to the right and `y` downwards.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

impl<T: Sample> Frame<T> {
    /// Wraps a row-major buffer.
    ///
    /// # Errors
    /// [`ImageError::BufferLength`] if `data.len() != width * height`, and
    /// [`ImageError::InvalidParameter`] if a dimension is zero.
    pub fn new(width: usize, height: usize, data: Vec<T>) -> Result<Self, ImageError> {
        check_buffer("a frame", width, height, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// A frame with every sample equal to `value`.
    ///
    /// # Errors
    /// As [`Frame::new`].
    pub fn filled(width: usize, height: usize, value: T) -> Result<Self, ImageError> {
        let n = width.saturating_mul(height);
        if n == usize::MAX {
            return Err(ImageError::invalid(
                "width/height",
                format!("{width}x{height} overflows usize"),
            ));
        }
        Self::new(width, height, vec![value; n])
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// All samples, row-major.
    pub fn data(&self) -> &[T] {
        &self.data
    }

    /// Gives the buffer back.
    pub fn into_data(self) -> Vec<T> {
        self.data
    }

    /// The samples of row `y`, or `None` if `y >= height`.
    pub fn row(&self, y: usize) -> Option<&[T]> {
        if y >= self.height {
            return None;
        }
        self.data.get(y * self.width..(y + 1) * self.width)
    }

    /// The sample at `(x, y)`, or `None` outside the frame.
    pub fn get(&self, x: usize, y: usize) -> Option<T> {
        if x >= self.width {
            return None;
        }
        self.data
            .get(y.checked_mul(self.width)?.checked_add(x)?)
            .copied()
    }
}

impl<T> Frame<T> {
    /// Wraps a buffer the caller knows to be `width * height` samples of a non-empty image
    /// (a conversion of another frame); `Frame::new`'s checks are the caller's.
    pub(crate) fn from_valid_parts(width: usize, height: usize, data: Vec<T>) -> Self {
        debug_assert!(width > 0 && height > 0 && data.len() == width * height);
        Self {
            width,
            height,
            data,
        }
    }
}

impl Frame<u8> {
    /// Widens to 16 bits (`v * 257`, so 255 becomes 65535).
    pub fn to_u16(&self) -> Frame<u16> {
        Frame {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(|&v| u16::from(v) * 257).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_rejects_wrong_buffer_length() {
        let err = Frame::<u8>::new(4, 3, vec![0; 11]).unwrap_err();
        assert!(matches!(
            err,
            ImageError::BufferLength {
                expected: 12,
                found: 11,
                ..
            }
        ));
        assert!(Frame::<u8>::new(0, 3, vec![]).is_err());
        assert!(Frame::filled(usize::MAX, 2, 0u8).is_err());
    }

    #[test]
    fn accessors() {
        let f = Frame::new(3, 2, vec![1u16, 2, 3, 4, 5, 6]).unwrap();
        assert_eq!(f.row(1), Some(&[4u16, 5, 6][..]));
        assert_eq!(f.row(2), None);
        assert_eq!(f.get(2, 1), Some(6));
        assert_eq!(f.get(3, 0), None);
        assert_eq!(f.get(0, 2), None);
    }

    #[test]
    fn quantisation_and_widening() {
        assert_eq!(u8::from_unit(1.0), 255);
        assert_eq!(u8::from_unit(-3.0), 0);
        assert_eq!(u8::from_unit(0.5), 128);
        assert_eq!(u16::from_unit(1.0), 65535);
        let f = Frame::new(2, 1, vec![0u8, 255]).unwrap().to_u16();
        assert_eq!(f.data(), &[0, 65535]);
    }
}
