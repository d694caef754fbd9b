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
