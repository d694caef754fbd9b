//! The frames of a capture: grey frames ([`Frame`], from `sl-image`) of one size and one depth.

use sl_image::GreyImage;
pub use sl_image::{Frame, Sample};

use crate::{Axis, CodecError};

/// The frames of a capture, all of one size and one sample depth.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Frames {
    /// 8-bit frames.
    U8(Vec<Frame<u8>>),
    /// 16-bit frames.
    U16(Vec<Frame<u16>>),
}

impl Frames {
    /// Images of one capture as frames: 8-bit when every image is, else all 16-bit (an 8-bit
    /// image promoted as [`GreyImage::into_u16`] does).
    pub fn from_images(images: Vec<GreyImage>) -> Self {
        if images.iter().any(|f| matches!(f, GreyImage::U16(_))) {
            Self::U16(images.into_iter().map(GreyImage::into_u16).collect())
        } else {
            Self::U8(
                images
                    .into_iter()
                    .filter_map(|f| match f {
                        GreyImage::U8(f) => Some(f),
                        GreyImage::U16(_) => None,
                    })
                    .collect(),
            )
        }
    }

    /// The frames as grey images, at their depth.
    pub fn into_images(self) -> Vec<GreyImage> {
        match self {
            Self::U8(f) => f.into_iter().map(GreyImage::U8).collect(),
            Self::U16(f) => f.into_iter().map(GreyImage::U16).collect(),
        }
    }

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
        if f.width() != first.width() || f.height() != first.height() {
            let frame = names
                .and_then(|n| n.get(i).cloned())
                .unwrap_or_else(|| format!("#{i}"));
            return Err(CodecError::FrameSize {
                frame,
                expected_width: first.width(),
                expected_height: first.height(),
                found_width: f.width(),
                found_height: f.height(),
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

    #[test]
    fn a_bad_buffer_keeps_its_codec_error() {
        let err = CodecError::from(Frame::<u8>::new(4, 3, vec![0; 11]).unwrap_err());
        assert!(matches!(
            err,
            CodecError::FrameBuffer {
                expected: 12,
                found: 11,
                ..
            }
        ));
        let err = CodecError::from(Frame::<u8>::new(0, 3, vec![]).unwrap_err());
        assert!(matches!(err, CodecError::Parameter { .. }), "{err}");
    }
}
