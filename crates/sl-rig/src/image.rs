//! Grey images exchanged with the devices: camera frames and projector images.

use crate::RigError;

/// Pixel values of a [`GreyImage`], row-major, top-left first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Pixels {
    /// 8-bit values.
    U8(Vec<u8>),
    /// 16-bit values.
    U16(Vec<u16>),
}

impl Pixels {
    /// Number of pixel values.
    pub fn len(&self) -> usize {
        match self {
            Self::U8(v) => v.len(),
            Self::U16(v) => v.len(),
        }
    }

    /// `true` when there is no pixel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Largest value a pixel can hold (255 or 65535).
    pub fn max_value(&self) -> u16 {
        match self {
            Self::U8(_) => u16::from(u8::MAX),
            Self::U16(_) => u16::MAX,
        }
    }
}

/// A grey image: a camera frame, or an image shown by a projector.
///
/// Pixel `(x, y)` is at index `y * width + x`; pixel `(0, 0)` is the top-left one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GreyImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The values, `width × height` of them.
    pub pixels: Pixels,
}

impl GreyImage {
    /// Builds an image, checking that `pixels` holds `width × height` values.
    pub fn new(width: u32, height: u32, pixels: Pixels) -> Result<Self, RigError> {
        let expected = (width as usize).checked_mul(height as usize);
        if expected != Some(pixels.len()) {
            return Err(RigError::BufferLength {
                what: "grey image".to_owned(),
                len: pixels.len(),
                width,
                height,
            });
        }
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// An 8-bit image where every pixel has the value `value`.
    pub fn filled_u8(width: u32, height: u32, value: u8) -> Self {
        Self {
            width,
            height,
            pixels: Pixels::U8(vec![value; width as usize * height as usize]),
        }
    }

    /// The value of pixel `(x, y)` as a fraction of full scale in `[0, 1]`, or `None` outside
    /// the image.
    pub fn get_normalised(&self, x: u32, y: u32) -> Option<f64> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = y as usize * self.width as usize + x as usize;
        match &self.pixels {
            Pixels::U8(v) => v.get(i).map(|&p| f64::from(p) / f64::from(u8::MAX)),
            Pixels::U16(v) => v.get(i).map(|&p| f64::from(p) / f64::from(u16::MAX)),
        }
    }

    /// The image as an 8-bit `image::GrayImage`, the input of `sl-calib`'s checkerboard
    /// detector: 8-bit pixels as they are (no copy), 16-bit pixels by their high byte
    /// (`v >> 8`).
    ///
    /// ```
    /// use sl_rig::{GreyImage, Pixels};
    /// # fn main() -> Result<(), sl_rig::RigError> {
    /// let frame = GreyImage::new(2, 1, Pixels::U16(vec![0x1234, 0xff00]))?;
    /// assert_eq!(frame.into_gray8()?.into_raw(), [0x12, 0xff]);
    /// # Ok(())
    /// # }
    /// ```
    ///
    /// # Errors
    /// [`RigError::BufferLength`] when the pixels are not `width × height` values (the
    /// fields are public, so the image may have been built without [`GreyImage::new`]).
    pub fn into_gray8(self) -> Result<::image::GrayImage, RigError> {
        let len = self.pixels.len();
        let px = match self.pixels {
            Pixels::U8(p) => p,
            Pixels::U16(p) => p.into_iter().map(|v| (v >> 8) as u8).collect(),
        };
        ::image::GrayImage::from_raw(self.width, self.height, px).ok_or_else(|| {
            RigError::BufferLength {
                what: "grey image".to_owned(),
                len,
                width: self.width,
                height: self.height,
            }
        })
    }

    /// The image as an 8-bit `sl_codec::Frame`, the decoder's input, by the rule of
    /// [`GreyImage::into_gray8`] (16-bit pixels by their high byte).
    ///
    /// # Errors
    /// Those of [`GreyImage::into_gray8`]; [`RigError::Codec`] for an image without pixels.
    pub fn into_frame8(self) -> Result<sl_codec::Frame<u8>, RigError> {
        let (w, h) = (self.width as usize, self.height as usize);
        let grey = self.into_gray8()?;
        Ok(sl_codec::Frame::new(w, h, grey.into_raw()).map_err(sl_codec::CodecError::from)?)
    }

    /// The value of pixel `(x, y)` in the image's own units (0–255 or 0–65535), or `None`
    /// outside the image.
    pub fn get(&self, x: u32, y: u32) -> Option<u16> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = y as usize * self.width as usize + x as usize;
        match &self.pixels {
            Pixels::U8(v) => v.get(i).map(|&p| u16::from(p)),
            Pixels::U16(v) => v.get(i).copied(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn into_gray8_keeps_8_bit_pixels_and_names_a_wrong_length() {
        let img = GreyImage::new(3, 1, Pixels::U8(vec![0, 128, 255])).unwrap();
        let g = img.into_gray8().unwrap();
        assert_eq!((g.width(), g.height()), (3, 1));
        assert_eq!(g.into_raw(), [0, 128, 255]);
        let bad = GreyImage {
            width: 2,
            height: 2,
            pixels: Pixels::U16(vec![0; 3]),
        };
        let e = bad.clone().into_gray8().unwrap_err();
        assert!(
            matches!(
                e,
                RigError::BufferLength {
                    len: 3,
                    width: 2,
                    height: 2,
                    ..
                }
            ),
            "{e}"
        );
        assert!(matches!(
            bad.into_frame8(),
            Err(RigError::BufferLength { len: 3, .. })
        ));
    }

    #[test]
    fn into_frame8_keeps_size_and_values() {
        let img = GreyImage::new(2, 2, Pixels::U16(vec![0, 0x0100, 0x8000, 0xffff])).unwrap();
        let f = img.into_frame8().unwrap();
        assert_eq!((f.width(), f.height()), (2, 2));
        assert_eq!(f.into_data(), [0, 1, 0x80, 0xff]);
        assert!(matches!(
            GreyImage::new(0, 0, Pixels::U8(Vec::new()))
                .unwrap()
                .into_frame8(),
            Err(RigError::Codec(_))
        ));
    }
}
