//! The size of an image in pixels.

use serde::{Deserialize, Serialize};

use crate::ImageError;

/// Size of an image in pixels: the workspace's one image size (cameras, projectors, pattern
/// sequences).
///
/// With OpenCV's convention (pixel (0, 0) is the centre of the top-left pixel) the image
/// covers the continuous rectangle `[-0.5, width - 0.5) × [-0.5, height - 0.5)`.
///
/// ```
/// use sl_image::ImageSize;
/// let size = ImageSize::new(1280, 720);
/// assert!(size.contains(-0.5, 719.4));
/// assert!(!size.contains(1279.5, 0.0));
/// assert_eq!(size.to_string(), "1280x720");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSize {
    /// Width in pixels (number of columns).
    pub width: u32,
    /// Height in pixels (number of rows).
    pub height: u32,
}

impl ImageSize {
    /// A size.
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height }
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether the pixel position `(u, v)` lies on the image: `-0.5 <= u < width - 0.5` and
    /// likewise for `v`. NaN is outside.
    pub fn contains(&self, u: f64, v: f64) -> bool {
        u >= -0.5
            && u < f64::from(self.width) - 0.5
            && v >= -0.5
            && v < f64::from(self.height) - 0.5
    }

    /// Checks that both dimensions are non-zero.
    ///
    /// # Errors
    /// [`ImageError::InvalidParameter`] naming `width` or `height`.
    pub fn validate(&self) -> Result<(), ImageError> {
        if self.width == 0 {
            return Err(ImageError::invalid("width", "must be at least 1 pixel"));
        }
        if self.height == 0 {
            return Err(ImageError::invalid("height", "must be at least 1 pixel"));
        }
        Ok(())
    }
}

impl std::fmt::Display for ImageSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

/// Parses `WIDTHxHEIGHT` (`1280x720`; `X` too, spaces around the numbers allowed), both at
/// least one pixel.
///
/// ```
/// use sl_image::ImageSize;
/// assert_eq!("1280x720".parse::<ImageSize>()?, ImageSize::new(1280, 720));
/// assert!("1280".parse::<ImageSize>().is_err() && "0x720".parse::<ImageSize>().is_err());
/// # Ok::<(), sl_image::ImageError>(())
/// ```
impl std::str::FromStr for ImageSize {
    type Err = ImageError;

    fn from_str(s: &str) -> Result<Self, ImageError> {
        let bad = |reason: &str| ImageError::InvalidParameter {
            name: "size".to_owned(),
            reason: format!("{s:?}: {reason}"),
        };
        let (w, h) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| bad("expected WIDTHxHEIGHT, e.g. 1280x720"))?;
        let count = |t: &str| t.trim().parse::<u32>().ok().filter(|&n| n > 0);
        match (count(w), count(h)) {
            (Some(w), Some(h)) => Ok(Self::new(w, h)),
            _ => Err(bad(
                "expected two whole numbers of pixels, at least 1, as WIDTHxHEIGHT",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_size_bounds_follow_pixel_centre_convention() {
        let s = ImageSize::new(4, 3);
        assert!(s.contains(-0.5, -0.5));
        assert!(s.contains(3.49, 2.49));
        assert!(!s.contains(3.5, 0.0));
        assert!(!s.contains(0.0, -0.51));
        assert!(!s.contains(f64::NAN, 0.0));
        assert_eq!(s.pixel_count(), 12);
        let e = ImageSize::new(0, 3).validate().unwrap_err().to_string();
        assert!(e.contains("`width`"), "{e}");
        let e = ImageSize::new(3, 0).validate().unwrap_err().to_string();
        assert!(e.contains("`height`"), "{e}");
    }

    #[test]
    fn serde_round_trip_refuses_unknown_fields() {
        let s = ImageSize::new(640, 480);
        let json = serde_json::to_string(&s).unwrap();
        assert_eq!(json, r#"{"width":640,"height":480}"#);
        assert_eq!(serde_json::from_str::<ImageSize>(&json).unwrap(), s);
        assert!(serde_json::from_str::<ImageSize>(r#"{"width":1,"height":1,"depth":8}"#).is_err());
    }
}
