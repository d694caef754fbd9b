//! A grey image at either depth.

use crate::{Frame, ImageError, ImageSize};

/// A grey image at the depth it was made with: read from a file, captured by a camera, or shown
/// by a projector.
///
/// The two depths convert into each other by the rules files use: 8 → 16 bits by `v * 257`
/// (255 becomes 65535), 16 → 8 bits by `round(v / 257)`, the exact inverse.
///
/// ```
/// use sl_image::{Frame, GreyImage};
/// # fn main() -> Result<(), sl_image::ImageError> {
/// let image = GreyImage::U16(Frame::new(2, 1, vec![0x1234, 0xffff])?);
/// assert_eq!((image.width(), image.height(), image.bit_depth()), (2, 1, 16));
/// assert_eq!(image.into_u8().data(), &[18, 255]); // round(0x1234 / 257) = 18
/// # Ok(()) }
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GreyImage {
    /// 8-bit samples (8-bit grey, or 8-bit colour converted to grey).
    U8(Frame<u8>),
    /// 16-bit samples (16-bit grey or colour, or float files scaled to `[0, 65535]`).
    U16(Frame<u16>),
}

impl GreyImage {
    /// An 8-bit image where every pixel has the value `value` (a flat projector image: full
    /// white, full black).
    ///
    /// # Errors
    /// As [`Frame::filled`]: a zero dimension, or a size that overflows `usize`.
    pub fn filled_u8(width: usize, height: usize, value: u8) -> Result<Self, ImageError> {
        Ok(Self::U8(Frame::filled(width, height, value)?))
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        match self {
            Self::U8(f) => f.width(),
            Self::U16(f) => f.width(),
        }
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        match self {
            Self::U8(f) => f.height(),
            Self::U16(f) => f.height(),
        }
    }

    /// Width and height as an [`ImageSize`] (a dimension beyond `u32::MAX`, which no camera
    /// or projector has, saturates to it).
    pub fn size(&self) -> ImageSize {
        let c = |v: usize| u32::try_from(v).unwrap_or(u32::MAX);
        ImageSize::new(c(self.width()), c(self.height()))
    }

    /// Bits per sample: 8 or 16.
    pub fn bit_depth(&self) -> u32 {
        match self {
            Self::U8(_) => 8,
            Self::U16(_) => 16,
        }
    }

    /// Largest value a pixel can hold: 255 or 65535.
    pub fn max_value(&self) -> u16 {
        match self {
            Self::U8(_) => u16::from(u8::MAX),
            Self::U16(_) => u16::MAX,
        }
    }

    /// The value of pixel `(x, y)` in the image's own units (0–255 or 0–65535), or `None`
    /// outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<u16> {
        match self {
            Self::U8(f) => f.get(x, y).map(u16::from),
            Self::U16(f) => f.get(x, y),
        }
    }

    /// The value of pixel `(x, y)` as a fraction of full scale in `[0, 1]`, or `None` outside
    /// the image.
    pub fn get_normalised(&self, x: usize, y: usize) -> Option<f64> {
        self.get(x, y)
            .map(|v| f64::from(v) / f64::from(self.max_value()))
    }

    /// Mean of all pixels as a fraction of full scale in `[0, 1]`.
    pub fn mean_normalised(&self) -> f64 {
        let (sum, n): (f64, usize) = match self {
            Self::U8(f) => (f.data().iter().map(|&v| f64::from(v)).sum(), f.data().len()),
            Self::U16(f) => (f.data().iter().map(|&v| f64::from(v)).sum(), f.data().len()),
        };
        sum / n.max(1) as f64 / f64::from(self.max_value())
    }

    /// The image at 8 bits: 16-bit values scaled by `round(v / 257)`.
    pub fn into_u8(self) -> Frame<u8> {
        match self {
            Self::U8(f) => f,
            Self::U16(f) => {
                let (w, h) = (f.width(), f.height());
                let data = f.into_data().into_iter().map(scale_16_to_8).collect();
                Frame::from_valid_parts(w, h, data)
            }
        }
    }

    /// The image at 16 bits: 8-bit values widened by `v * 257` (255 becomes 65535).
    pub fn into_u16(self) -> Frame<u16> {
        match self {
            Self::U8(f) => f.to_u16(),
            Self::U16(f) => f,
        }
    }
}

impl From<Frame<u8>> for GreyImage {
    fn from(frame: Frame<u8>) -> Self {
        Self::U8(frame)
    }
}

impl From<Frame<u16>> for GreyImage {
    fn from(frame: Frame<u16>) -> Self {
        Self::U16(frame)
    }
}

/// `round(v / 257)`: the 8-bit value whose widening `v8 * 257` is nearest to `v`.
pub(crate) fn scale_16_to_8(v: u16) -> u8 {
    // (v + 128) / 257 <= (65535 + 128) / 257 = 255.5, so the result fits.
    u8::try_from((u32::from(v) + 128) / 257).unwrap_or(u8::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sixteen_to_eight_inverts_the_widening() {
        for v in 0..=255u8 {
            assert_eq!(scale_16_to_8(u16::from(v) * 257), v);
        }
        assert_eq!(scale_16_to_8(128), 0);
        assert_eq!(scale_16_to_8(129), 1);
        assert_eq!(scale_16_to_8(65535), 255);
    }

    #[test]
    fn pixel_reads_in_own_units_and_normalised() {
        let img = GreyImage::from(Frame::new(2, 1, vec![0u16, 0x8000]).unwrap());
        assert_eq!(img.max_value(), 65535);
        assert_eq!(img.size(), ImageSize::new(2, 1));
        assert_eq!(img.get(1, 0), Some(0x8000));
        assert_eq!(img.get(2, 0), None);
        assert_eq!(img.get_normalised(0, 0), Some(0.0));
        let white = GreyImage::filled_u8(3, 2, 255).unwrap();
        assert_eq!(white.get_normalised(2, 1), Some(1.0));
        assert_eq!(white.get_normalised(0, 2), None);
        assert!((white.mean_normalised() - 1.0).abs() < 1e-15);
        assert!(GreyImage::filled_u8(0, 2, 0).is_err());
    }

    #[test]
    fn depths_convert_both_ways() {
        let img = GreyImage::from(Frame::new(3, 1, vec![0u8, 128, 255]).unwrap());
        assert_eq!(img.bit_depth(), 8);
        let wide = img.clone().into_u16();
        assert_eq!(wide.data(), &[0, 128 * 257, 65535]);
        assert_eq!(GreyImage::from(wide).into_u8(), img.into_u8());
    }
}
