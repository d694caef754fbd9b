//! Grey camera frames: 8- or 16-bit samples in one contiguous row-major buffer.

use crate::{Axis, CodecError};

mod sealed {
    pub trait Sealed {}
    impl Sealed for u8 {}
    impl Sealed for u16 {}
}

/// A grey sample type the decoders accept: `u8` or `u16`.
///
/// The trait is sealed; its methods exist so that the decoders can be written once for both
/// depths.
pub trait Sample:
    Copy + Default + PartialOrd + Send + Sync + std::fmt::Debug + sealed::Sealed + 'static
{
    /// The largest value (`255` or `65535`).
    const MAX_VALUE: Self;
    /// Factor from 8-bit grey levels to this type's grey levels (`1` or `257`).
    ///
    /// Every threshold of the decoders is given in 8-bit grey levels and multiplied by this
    /// factor, so one configuration serves both depths.
    const SCALE_FROM_8BIT: f32;
    /// Bits per sample (8 or 16).
    const BITS: u32;
    /// The value as `f32`.
    fn to_f32(self) -> f32;
    /// The value as `u16` (exact for both types).
    fn to_u16(self) -> u16;
    /// Quantises an intensity in `[0, 1]` (clamped) to the nearest level.
    fn from_unit(value: f64) -> Self;
    /// Converts a raw `u16` saturating to this type's range (used by the synthetic renderer).
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
    /// [`CodecError::FrameBuffer`] if `data.len() != width * height`, and
    /// [`CodecError::Parameter`] if a dimension is zero.
    pub fn new(width: usize, height: usize, data: Vec<T>) -> Result<Self, CodecError> {
        if width == 0 || height == 0 {
            return Err(CodecError::parameter(
                "width/height",
                format!("a frame must not be empty, got {width}x{height}"),
            ));
        }
        let expected = width.checked_mul(height).ok_or_else(|| {
            CodecError::parameter("width/height", format!("{width}x{height} overflows usize"))
        })?;
        if data.len() != expected {
            return Err(CodecError::FrameBuffer {
                frame: "<memory>".into(),
                width,
                height,
                expected,
                found: data.len(),
            });
        }
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
    pub fn filled(width: usize, height: usize, value: T) -> Result<Self, CodecError> {
        let n = width.saturating_mul(height);
        if n == usize::MAX {
            return Err(CodecError::parameter(
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
    /// (a decoded image file); `Frame::new`'s checks are the caller's.
    #[cfg(feature = "image-files")]
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

/// The frames of a capture, all of one size and one sample depth.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Frames {
    /// 8-bit frames.
    U8(Vec<Frame<u8>>),
    /// 16-bit frames.
    U16(Vec<Frame<u16>>),
}

impl Frames {
    /// Number of frames.
    pub fn len(&self) -> usize {
        match self {
            Self::U8(f) => f.len(),
            Self::U16(f) => f.len(),
        }
    }

    /// `true` if there is no frame.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Width of the frames (0 if there is none).
    pub fn width(&self) -> usize {
        match self {
            Self::U8(f) => f.first().map_or(0, Frame::width),
            Self::U16(f) => f.first().map_or(0, Frame::width),
        }
    }

    /// Height of the frames (0 if there is none).
    pub fn height(&self) -> usize {
        match self {
            Self::U8(f) => f.first().map_or(0, Frame::height),
            Self::U16(f) => f.first().map_or(0, Frame::height),
        }
    }

    /// Bits per sample: 8 or 16.
    pub fn bit_depth(&self) -> u32 {
        match self {
            Self::U8(_) => 8,
            Self::U16(_) => 16,
        }
    }

    /// Checks that every frame has the size of the first one.
    ///
    /// # Errors
    /// [`CodecError::FrameSize`] naming the first frame (`#index`) that differs.
    pub fn check_sizes(&self) -> Result<(), CodecError> {
        match self {
            Self::U8(f) => check_sizes(f, None),
            Self::U16(f) => check_sizes(f, None),
        }
    }
}

/// Checks that all frames have one size; `names` (if given) names frames in errors.
pub(crate) fn check_sizes<T: Sample>(
    frames: &[Frame<T>],
    names: Option<&[String]>,
) -> Result<(), CodecError> {
    let Some(first) = frames.first() else {
        return Ok(());
    };
    for (i, f) in frames.iter().enumerate() {
        if f.width != first.width || f.height != first.height {
            let frame = names
                .and_then(|n| n.get(i).cloned())
                .unwrap_or_else(|| format!("#{i}"));
            return Err(CodecError::FrameSize {
                frame,
                expected_width: first.width,
                expected_height: first.height,
                found_width: f.width,
                found_height: f.height,
            });
        }
    }
    Ok(())
}

/// Width and height of the first frame (0 x 0 if none).
pub(crate) fn dims<T: Sample>(frames: &[Frame<T>]) -> (usize, usize) {
    frames.first().map_or((0, 0), |f| (f.width(), f.height()))
}

/// Checks the frame count and sizes of a block.
pub(crate) fn check_block<T: Sample>(
    codec: &'static str,
    axis: Axis,
    expected: usize,
    frames: &[Frame<T>],
) -> Result<(), CodecError> {
    if frames.len() != expected {
        return Err(CodecError::FrameCount {
            codec,
            axis: axis.name(),
            expected,
            found: frames.len(),
        });
    }
    check_sizes(frames, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_rejects_wrong_buffer_length() {
        let err = Frame::<u8>::new(4, 3, vec![0; 11]).unwrap_err();
        assert!(matches!(
            err,
            CodecError::FrameBuffer {
                expected: 12,
                found: 11,
                ..
            }
        ));
        assert!(Frame::<u8>::new(0, 3, vec![]).is_err());
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

    #[test]
    fn size_check_names_frame() {
        let frames = vec![
            Frame::filled(4, 4, 0u8).unwrap(),
            Frame::filled(4, 5, 0u8).unwrap(),
        ];
        let names = vec!["a.png".to_string(), "b.png".to_string()];
        let err = check_sizes(&frames, Some(&names)).unwrap_err();
        assert!(err.to_string().contains("b.png"), "{err}");
        let err = Frames::U8(frames).check_sizes().unwrap_err();
        assert!(err.to_string().contains("#1"), "{err}");
    }
}
