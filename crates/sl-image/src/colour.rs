//! An 8-bit RGB image: the colour of a scan (a colour camera's frame under full white, or the
//! mean of its fringe frames).

use crate::{Frame, GreyImage, ImageError, ImageSize};

/// An 8-bit RGB image, row-major without padding: pixel `(x, y)` is `data[y * width + x]`,
/// `[red, green, blue]`.
///
/// Colours are 8-bit because that is what PLY vertex colours, OBJ textures and the pages
/// carry; a 16-bit colour frame is rounded to 8 bits (`round(v / 257)`) when read.
///
/// ```
/// use sl_image::{ColourImage, GreyImage};
/// # fn main() -> Result<(), sl_image::ImageError> {
/// let img = ColourImage::new(2, 1, vec![[255, 0, 0], [255, 255, 255]])?;
/// assert_eq!(img.get(0, 0), Some([255, 0, 0]));
/// // Grey by OpenCV's RGB2GRAY rule: pure red is 76.
/// assert_eq!(img.to_grey().get(0, 0), Some(76));
/// // A grey image as colour: the same value in the three channels.
/// let grey = ColourImage::from_grey(&GreyImage::filled_u8(1, 1, 9)?);
/// assert_eq!(grey.get(0, 0), Some([9, 9, 9]));
/// # Ok(()) }
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ColourImage {
    width: usize,
    height: usize,
    data: Vec<[u8; 3]>,
}

impl ColourImage {
    /// Wraps a row-major buffer of RGB pixels.
    ///
    /// # Errors
    /// [`ImageError::BufferLength`] if `data.len() != width * height`, and
    /// [`ImageError::InvalidParameter`] if a dimension is zero.
    pub fn new(width: usize, height: usize, data: Vec<[u8; 3]>) -> Result<Self, ImageError> {
        crate::frame::check_buffer("an image", width, height, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// An image with every pixel `rgb`.
    ///
    /// # Errors
    /// As [`ColourImage::new`].
    pub fn filled(width: usize, height: usize, rgb: [u8; 3]) -> Result<Self, ImageError> {
        let n = width.checked_mul(height).ok_or_else(|| {
            ImageError::invalid("width/height", format!("{width}x{height} overflows usize"))
        })?;
        Self::new(width, height, vec![rgb; n])
    }

    /// A grey image as colour (the grey value, at 8 bits, in the three channels).
    pub fn from_grey(image: &GreyImage) -> Self {
        let frame = image.clone().into_u8();
        Self {
            width: frame.width(),
            height: frame.height(),
            data: frame.data().iter().map(|&g| [g, g, g]).collect(),
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The image's size.
    pub fn size(&self) -> ImageSize {
        ImageSize::new(self.width as u32, self.height as u32)
    }

    /// All pixels, row-major.
    pub fn data(&self) -> &[[u8; 3]] {
        &self.data
    }

    /// Gives the buffer back.
    pub fn into_data(self) -> Vec<[u8; 3]> {
        self.data
    }

    /// The pixel at `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<[u8; 3]> {
        if x >= self.width {
            return None;
        }
        self.data
            .get(y.checked_mul(self.width)?.checked_add(x)?)
            .copied()
    }

    /// The image in grey by OpenCV's `COLOR_RGB2GRAY` rule in fixed point
    /// (`(9798 R + 19235 G + 3735 B + 2^14) >> 15`), the rule the decoders read colour
    /// frames by.
    pub fn to_grey(&self) -> GreyImage {
        let data = self.data.iter().map(|&p| luma(p)).collect();
        GreyImage::from(Frame::from_valid_parts(self.width, self.height, data))
    }
}

/// The grey value of an RGB pixel by OpenCV's `COLOR_RGB2GRAY` rule in fixed point.
#[inline]
pub fn luma([r, g, b]: [u8; 3]) -> u8 {
    ((9798 * u32::from(r) + 19235 * u32::from(g) + 3735 * u32::from(b) + (1 << 14)) >> 15) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrong_lengths_and_empty_images_are_refused() {
        assert!(matches!(
            ColourImage::new(2, 2, vec![[0; 3]; 3]),
            Err(ImageError::BufferLength {
                expected: 4,
                found: 3,
                ..
            })
        ));
        assert!(ColourImage::new(0, 2, vec![]).is_err());
        assert!(ColourImage::filled(usize::MAX, 2, [0; 3]).is_err());
    }

    #[test]
    fn luma_follows_opencv_weights() {
        // OpenCV's RGB2GRAY weights 0.299, 0.587, 0.114 (sum 1: white stays white).
        assert_eq!(luma([255, 255, 255]), 255);
        assert_eq!(luma([0, 0, 0]), 0);
        for (rgb, w) in [
            ([255, 0, 0], 0.299),
            ([0, 255, 0], 0.587),
            ([0, 0, 255], 0.114),
        ] {
            assert!((f64::from(luma(rgb)) - 255.0 * w).abs() <= 0.5, "{rgb:?}");
        }
    }

    #[test]
    fn grey_round_trip_keeps_values() {
        let grey = GreyImage::from(Frame::new(3, 1, vec![0u8, 100, 255]).unwrap());
        let colour = ColourImage::from_grey(&grey);
        assert_eq!(colour.get(1, 0), Some([100, 100, 100]));
        assert_eq!(colour.get(3, 0), None);
        assert_eq!(colour.to_grey(), grey);
    }
}
