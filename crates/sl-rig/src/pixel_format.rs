//! Camera pixel formats and their conversion to grey frames ([`convert_frame`]) and to colour
//! ones ([`convert_frame_colour`]).
//!
//! Plain functions, compiled with or without the `v4l` feature, so that every conversion a real
//! camera needs is unit-tested on machines without a camera.

use sl_image::Frame;

use crate::{ColourImage, GreyImage, RigError};

/// A pixel format a camera delivers, as V4L2 names it (its four-character code).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum PixelFormat {
    /// `GREY`: 8-bit luminance, one byte per pixel (machine-vision cameras).
    Grey,
    /// `Y16 `: 16-bit little-endian luminance, two bytes per pixel.
    Y16,
    /// `YUYV`: packed 4:2:2, `Y0 U Y1 V` for each pair of pixels (most USB webcams).
    Yuyv,
    /// `MJPG`: one JPEG image per frame (USB webcams at high resolutions).
    Mjpg,
    /// `RGB3`: 8-bit red, green, blue, three bytes per pixel (V4L2's `RGB24`).
    Rgb3,
    /// `BGR3`: 8-bit blue, green, red, three bytes per pixel (V4L2's `BGR24`).
    Bgr3,
}

impl PixelFormat {
    /// Every format this crate converts, in order of preference for structured light
    /// (uncompressed grey first, JPEG last: its compression blurs stripe edges).
    pub const ALL: [Self; 6] = [
        Self::Grey,
        Self::Y16,
        Self::Yuyv,
        Self::Rgb3,
        Self::Bgr3,
        Self::Mjpg,
    ];

    /// The V4L2 four-character code.
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            Self::Grey => *b"GREY",
            Self::Y16 => *b"Y16 ",
            Self::Yuyv => *b"YUYV",
            Self::Mjpg => *b"MJPG",
            Self::Rgb3 => *b"RGB3",
            Self::Bgr3 => *b"BGR3",
        }
    }

    /// The format with this four-character code, or `None` when this crate cannot convert it.
    /// `JPEG` is taken as `MJPG` (some drivers name it so).
    pub fn from_fourcc(code: [u8; 4]) -> Option<Self> {
        match &code {
            b"GREY" => Some(Self::Grey),
            b"Y16 " => Some(Self::Y16),
            b"YUYV" => Some(Self::Yuyv),
            b"MJPG" | b"JPEG" => Some(Self::Mjpg),
            b"RGB3" => Some(Self::Rgb3),
            b"BGR3" => Some(Self::Bgr3),
            _ => None,
        }
    }

    /// The format named `name` (its four-character code, case-insensitive, trailing spaces
    /// optional: `grey`, `y16`, `yuyv`, `mjpg`, `rgb3`, `bgr3`).
    pub fn from_name(name: &str) -> Result<Self, RigError> {
        let upper = name.trim().to_ascii_uppercase();
        Self::ALL
            .into_iter()
            .find(|f| f.name() == upper)
            .or_else(|| (upper == "JPEG").then_some(Self::Mjpg))
            .ok_or_else(|| {
                RigError::param(
                    "pixel_format",
                    format!("`{name}` is not one of GREY, Y16, YUYV, RGB3, BGR3, MJPG"),
                )
            })
    }

    /// The four-character code as text, trailing spaces removed (`GREY`, `Y16`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::Grey => "GREY",
            Self::Y16 => "Y16",
            Self::Yuyv => "YUYV",
            Self::Mjpg => "MJPG",
            Self::Rgb3 => "RGB3",
            Self::Bgr3 => "BGR3",
        }
    }

    /// Bytes per pixel of the uncompressed formats, `None` for JPEG.
    pub fn bytes_per_pixel(self) -> Option<usize> {
        match self {
            Self::Grey => Some(1),
            Self::Y16 | Self::Yuyv => Some(2),
            Self::Rgb3 | Self::Bgr3 => Some(3),
            Self::Mjpg => None,
        }
    }
}

impl std::fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// How a raw frame is laid out in the driver's buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameLayout {
    /// Pixel format.
    pub format: PixelFormat,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Bytes from the start of one row to the start of the next (V4L2's `bytesperline`); `0`
    /// means rows are packed (`width × bytes per pixel`). Ignored for JPEG.
    pub stride: u32,
}

impl FrameLayout {
    /// A packed layout (no padding at the end of rows).
    pub fn packed(format: PixelFormat, width: u32, height: u32) -> Self {
        Self {
            format,
            width,
            height,
            stride: 0,
        }
    }
}

/// Refuses a layout of no pixel, naming `what` (the frame).
fn check_size(layout: &FrameLayout, what: &str) -> Result<(), RigError> {
    if layout.width == 0 || layout.height == 0 {
        return Err(RigError::param(
            "frame size",
            format!("{what}: {}x{} has no pixel", layout.width, layout.height),
        ));
    }
    Ok(())
}

/// Refuses an odd width for YUYV, whose pixels come in pairs.
fn check_even_width(layout: &FrameLayout, what: &str) -> Result<(), RigError> {
    if !layout.width.is_multiple_of(2) {
        return Err(RigError::param(
            "frame size",
            format!(
                "{what}: YUYV needs an even width (pixels come in pairs), got {}",
                layout.width
            ),
        ));
    }
    Ok(())
}

/// Converts one raw camera frame to a grey image: 8-bit for `GREY`, `YUYV` (the luma `Y`),
/// `MJPG` (decoded, then its luma) and `RGB3` / `BGR3` (their luma by OpenCV's
/// `COLOR_RGB2GRAY` rule, [`sl_image::luma`]), 16-bit for `Y16`.
///
/// `frame` is the part of the driver's buffer that holds the frame (V4L2's `bytesused`
/// bytes); padding at the end of rows (`stride`) is dropped. `what` names the frame in errors
/// (e.g. `/dev/video0 frame 12`).
///
/// # Errors
/// [`RigError::InvalidParameter`] for an empty size, a stride shorter than a row or an odd
/// `YUYV` width; [`RigError::FrameData`] for a buffer shorter than the layout needs or a JPEG
/// that does not decode or has another size than the layout.
///
/// ```
/// use sl_rig::{FrameLayout, PixelFormat, convert_frame};
/// # fn main() -> Result<(), sl_rig::RigError> {
/// // Two YUYV pixels: Y0=10, U=128, Y1=20, V=128.
/// let layout = FrameLayout::packed(PixelFormat::Yuyv, 2, 1);
/// let grey = convert_frame(&[10, 128, 20, 128], &layout, "frame 0")?;
/// assert_eq!(grey.get(0, 0), Some(10));
/// assert_eq!(grey.get(1, 0), Some(20));
/// # Ok(())
/// # }
/// ```
pub fn convert_frame(
    frame: &[u8],
    layout: &FrameLayout,
    what: &str,
) -> Result<GreyImage, RigError> {
    check_size(layout, what)?;
    match layout.format {
        PixelFormat::Grey => {
            let rows = packed_rows(frame, layout, 1, what)?;
            grey(layout.width, layout.height, rows)
        }
        PixelFormat::Y16 => {
            let rows = packed_rows(frame, layout, 2, what)?;
            let values = rows
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect();
            grey(layout.width, layout.height, values)
        }
        PixelFormat::Yuyv => {
            check_even_width(layout, what)?;
            let rows = packed_rows(frame, layout, 2, what)?;
            // Y0 U Y1 V: the luma of every pixel is at the even bytes.
            let luma = rows.iter().step_by(2).copied().collect();
            grey(layout.width, layout.height, luma)
        }
        PixelFormat::Mjpg => decode_mjpg(frame, layout, what),
        PixelFormat::Rgb3 | PixelFormat::Bgr3 => {
            let rgb = rgb_pixels(frame, layout, what)?;
            grey(
                layout.width,
                layout.height,
                rgb.into_iter().map(sl_image::luma).collect(),
            )
        }
    }
}

/// Converts one raw camera frame to an 8-bit RGB image: the colour of a scan.
///
/// - `YUYV`: ITU-R BT.601 limited range (`Y` in 16–235, chroma in 16–240) to RGB, as OpenCV's
///   `COLOR_YUV2RGB_YUYV` does it, in its fixed point: with `y = max(Y − 16, 0)`,
///   `u = U − 128`, `v = V − 128` (the pair of pixels sharing `U` and `V`),
///   `R = (1.164 y + 1.596 v)`, `G = (1.164 y − 0.391 u − 0.813 v)`, `B = (1.164 y + 2.018 u)`,
///   each rounded and clamped to 0–255 (coefficients scaled by 2²⁰ as OpenCV's
///   `ITUR_BT_601_*`);
/// - `MJPG`: decoded to RGB (the JPEG's own YCbCr, full range, converted by the decoder);
/// - `RGB3` / `BGR3`: the bytes, reordered for `BGR3`;
/// - `GREY`: the grey value in the three channels; `Y16`: rounded to 8 bits (`round(v / 257)`,
///   as `sl_codec::read_colour_image` reads 16-bit files).
///
/// # Errors
/// As [`convert_frame`].
///
/// ```
/// use sl_rig::{FrameLayout, PixelFormat, convert_frame_colour};
/// # fn main() -> Result<(), sl_rig::RigError> {
/// // Two YUYV pixels of BT.601's limited range: white (Y = 235) and black (Y = 16).
/// let layout = FrameLayout::packed(PixelFormat::Yuyv, 2, 1);
/// let rgb = convert_frame_colour(&[235, 128, 16, 128], &layout, "frame 0")?;
/// assert_eq!(rgb.data(), &[[255, 255, 255], [0, 0, 0]]);
/// # Ok(())
/// # }
/// ```
pub fn convert_frame_colour(
    frame: &[u8],
    layout: &FrameLayout,
    what: &str,
) -> Result<ColourImage, RigError> {
    check_size(layout, what)?;
    let data: Vec<[u8; 3]> = match layout.format {
        PixelFormat::Grey => packed_rows(frame, layout, 1, what)?
            .into_iter()
            .map(|g| [g; 3])
            .collect(),
        PixelFormat::Y16 => packed_rows(frame, layout, 2, what)?
            .chunks_exact(2)
            .map(|b| {
                let v = u32::from(u16::from_le_bytes([b[0], b[1]]));
                [((v + 128) / 257) as u8; 3]
            })
            .collect(),
        PixelFormat::Yuyv => {
            check_even_width(layout, what)?;
            packed_rows(frame, layout, 2, what)?
                .chunks_exact(4)
                .flat_map(|q| {
                    let (y0, u, y1, v) = (q[0], q[1], q[2], q[3]);
                    [yuv_to_rgb(y0, u, v), yuv_to_rgb(y1, u, v)]
                })
                .collect()
        }
        PixelFormat::Rgb3 | PixelFormat::Bgr3 => rgb_pixels(frame, layout, what)?,
        PixelFormat::Mjpg => decode_mjpg_rgb(frame, layout, what)?,
    };
    Ok(ColourImage::new(
        layout.width as usize,
        layout.height as usize,
        data,
    )?)
}

/// BT.601's coefficients scaled by 2²⁰ as OpenCV's `ITUR_BT_601_*` constants
/// (`color_yuv.simd.hpp`): 1.164 (`CY`, 255/219), 1.596 (`CVR`), −0.813 (`CVG`), −0.391
/// (`CUG`) and 2.018 (`CUB`).
const BT601_CY: i32 = 1_220_542;
const BT601_CVR: i32 = 1_673_527;
const BT601_CVG: i32 = -852_492;
const BT601_CUG: i32 = -409_993;
const BT601_CUB: i32 = 2_116_026;
/// The scale of the coefficients: 2²⁰.
const BT601_SHIFT: u32 = 20;

/// One limited-range BT.601 pixel to RGB, in OpenCV's fixed point (`yuv2rgb` of
/// `color_yuv.simd.hpp`: half of the last bit added before the shift, so the result rounds).
fn yuv_to_rgb(y: u8, u: u8, v: u8) -> [u8; 3] {
    let luma = (i32::from(y) - 16).max(0) * BT601_CY;
    let (u, v) = (i32::from(u) - 128, i32::from(v) - 128);
    let half = 1 << (BT601_SHIFT - 1);
    let channel = |chroma: i32| ((luma + half + chroma) >> BT601_SHIFT).clamp(0, 255) as u8;
    [
        channel(BT601_CVR * v),
        channel(BT601_CVG * v + BT601_CUG * u),
        channel(BT601_CUB * u),
    ]
}

/// The RGB pixels of an `RGB3` or `BGR3` frame (reordered to RGB), padding removed.
fn rgb_pixels(frame: &[u8], layout: &FrameLayout, what: &str) -> Result<Vec<[u8; 3]>, RigError> {
    let bgr = layout.format == PixelFormat::Bgr3;
    Ok(packed_rows(frame, layout, 3, what)?
        .chunks_exact(3)
        .map(|p| {
            if bgr {
                [p[2], p[1], p[0]]
            } else {
                [p[0], p[1], p[2]]
            }
        })
        .collect())
}

/// The rows of an uncompressed frame, padding removed: `height` rows of
/// `width × bytes_per_pixel` bytes.
fn packed_rows(
    frame: &[u8],
    layout: &FrameLayout,
    bytes_per_pixel: usize,
    what: &str,
) -> Result<Vec<u8>, RigError> {
    let too_big = || {
        RigError::param(
            "frame size",
            format!(
                "{what}: {}x{} overflows memory",
                layout.width, layout.height
            ),
        )
    };
    let row = (layout.width as usize)
        .checked_mul(bytes_per_pixel)
        .ok_or_else(too_big)?;
    let stride = if layout.stride == 0 {
        row
    } else {
        layout.stride as usize
    };
    if stride < row {
        return Err(RigError::param(
            "stride",
            format!(
                "{what}: {stride} bytes per line is less than a {}-pixel {} row ({row} bytes)",
                layout.width, layout.format
            ),
        ));
    }
    let height = layout.height as usize;
    // The last row needs no padding after it: drivers may end the buffer there.
    let needed = stride
        .checked_mul(height - 1)
        .and_then(|n| n.checked_add(row))
        .ok_or_else(too_big)?;
    if frame.len() < needed {
        return Err(RigError::FrameData {
            what: what.to_owned(),
            reason: format!(
                "{} bytes for a {}x{} {} frame with {stride} bytes per line (needs {needed})",
                frame.len(),
                layout.width,
                layout.height,
                layout.format
            ),
        });
    }
    let mut out = Vec::with_capacity(row * height);
    for line in frame.chunks(stride).take(height) {
        out.extend_from_slice(line.get(..row).unwrap_or(line));
    }
    Ok(out)
}

/// Decodes a JPEG frame, checking its size against the layout.
fn decode_jpeg(
    frame: &[u8],
    layout: &FrameLayout,
    what: &str,
) -> Result<::image::DynamicImage, RigError> {
    use ::image::ImageDecoder as _;
    let bad = |reason: String| RigError::FrameData {
        what: what.to_owned(),
        reason,
    };
    let decoder =
        ::image::codecs::jpeg::JpegDecoder::new(std::io::Cursor::new(frame)).map_err(|e| {
            bad(format!(
                "MJPG frame of {} bytes does not decode: {e}",
                frame.len()
            ))
        })?;
    let (width, height) = decoder.dimensions();
    if (width, height) != (layout.width, layout.height) {
        return Err(bad(format!(
            "MJPG frame is {width}x{height}, the camera was set to {}x{}",
            layout.width, layout.height
        )));
    }
    ::image::DynamicImage::from_decoder(decoder)
        .map_err(|e| bad(format!("MJPG frame does not decode: {e}")))
}

/// Decodes a JPEG frame to 8-bit luma.
fn decode_mjpg(frame: &[u8], layout: &FrameLayout, what: &str) -> Result<GreyImage, RigError> {
    let decoded = decode_jpeg(frame, layout, what)?;
    // Rec. 601 luma, as the JPEG's own Y channel (image's `to_luma8`).
    let luma = decoded.into_luma8();
    grey(layout.width, layout.height, luma.into_raw())
}

/// Decodes a JPEG frame to 8-bit RGB.
fn decode_mjpg_rgb(
    frame: &[u8],
    layout: &FrameLayout,
    what: &str,
) -> Result<Vec<[u8; 3]>, RigError> {
    let decoded = decode_jpeg(frame, layout, what)?;
    Ok(decoded.into_rgb8().pixels().map(|p| p.0).collect())
}

/// The grey image of `width × height` values (8- or 16-bit).
///
/// # Errors
/// [`RigError::Image`] when `values` does not hold `width × height` of them.
fn grey<T: sl_image::Sample>(width: u32, height: u32, values: Vec<T>) -> Result<GreyImage, RigError>
where
    GreyImage: From<Frame<T>>,
{
    Ok(Frame::new(width as usize, height as usize, values)?.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fourcc_round_trip() {
        for f in PixelFormat::ALL {
            assert_eq!(PixelFormat::from_fourcc(f.fourcc()), Some(f));
            assert_eq!(PixelFormat::from_name(&f.name().to_lowercase()).unwrap(), f);
        }
        assert_eq!(PixelFormat::from_fourcc(*b"JPEG"), Some(PixelFormat::Mjpg));
        assert_eq!(PixelFormat::from_fourcc(*b"NV12"), None);
        let err = PixelFormat::from_name("nv12").unwrap_err().to_string();
        assert!(
            err.contains("pixel_format") && err.contains("nv12"),
            "{err}"
        );
    }

    #[test]
    fn grey_with_stride_drops_padding() {
        // 3x2 image, 5 bytes per line: two bytes of padding (0xEE) after each row; the last
        // row's padding is missing, as some drivers end the buffer after the last pixel.
        let frame = [1, 2, 3, 0xEE, 0xEE, 4, 5, 6];
        let layout = FrameLayout {
            format: PixelFormat::Grey,
            width: 3,
            height: 2,
            stride: 5,
        };
        let img = convert_frame(&frame, &layout, "f").unwrap();
        assert_eq!(
            img,
            GreyImage::U8(Frame::new(3, 2, vec![1, 2, 3, 4, 5, 6]).unwrap())
        );
    }

    #[test]
    fn yuyv_takes_luma_with_odd_height() {
        // 4x3 frame: Y = 10·row + column, chroma bytes 0xAA / 0x55 that must not leak in.
        let (w, h) = (4u32, 3u32);
        let mut frame = Vec::new();
        for y in 0..h {
            for x in (0..w).step_by(2) {
                frame.extend_from_slice(&[(10 * y + x) as u8, 0xAA, (10 * y + x + 1) as u8, 0x55]);
            }
        }
        let img =
            convert_frame(&frame, &FrameLayout::packed(PixelFormat::Yuyv, w, h), "f").unwrap();
        for y in 0..h {
            for x in 0..w {
                assert_eq!(
                    img.get(x as usize, y as usize),
                    Some(u16::from((10 * y + x) as u8))
                );
            }
        }
    }

    #[test]
    fn y16_is_little_endian() {
        let frame = [0x34, 0x12, 0xFF, 0xFF];
        let img = convert_frame(&frame, &FrameLayout::packed(PixelFormat::Y16, 2, 1), "f").unwrap();
        assert_eq!(
            img,
            GreyImage::U16(Frame::new(2, 1, vec![0x1234, 0xFFFF]).unwrap())
        );
    }

    #[test]
    fn odd_yuyv_width_and_short_stride_are_parameter_errors() {
        let err = convert_frame(
            &[0; 64],
            &FrameLayout::packed(PixelFormat::Yuyv, 3, 2),
            "cam frame 7",
        )
        .unwrap_err();
        assert!(matches!(err, RigError::InvalidParameter { .. }), "{err}");
        assert!(err.to_string().contains("cam frame 7"), "{err}");
        let layout = FrameLayout {
            format: PixelFormat::Yuyv,
            width: 4,
            height: 2,
            stride: 6,
        };
        let err = convert_frame(&[0; 64], &layout, "f").unwrap_err();
        assert!(err.to_string().contains("stride"), "{err}");
        let err =
            convert_frame(&[], &FrameLayout::packed(PixelFormat::Grey, 0, 5), "f").unwrap_err();
        assert!(matches!(err, RigError::InvalidParameter { .. }), "{err}");
    }

    #[test]
    fn short_buffers_are_frame_data_errors() {
        for format in [PixelFormat::Grey, PixelFormat::Y16, PixelFormat::Yuyv] {
            let layout = FrameLayout::packed(format, 4, 4);
            let needed = 16 * format.bytes_per_pixel().unwrap();
            let err = convert_frame(&vec![0; needed - 1], &layout, "frame 3").unwrap_err();
            assert!(matches!(err, RigError::FrameData { .. }), "{format}: {err}");
            assert!(err.to_string().contains("frame 3"), "{err}");
            assert!(convert_frame(&vec![0; needed], &layout, "frame 3").is_ok());
        }
    }

    /// Encodes `pixels` (w×h grey) as a JPEG with the `image` crate's encoder: an independent
    /// producer of the frames a webcam sends.
    fn jpeg(pixels: &[u8], w: u32, h: u32, quality: u8) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = ::image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality);
        enc.encode(pixels, w, h, ::image::ExtendedColorType::L8)
            .unwrap();
        out
    }

    #[test]
    fn mjpg_decodes_to_luma() {
        // A smooth ramp survives JPEG at quality 100 within a few grey levels: the DCT
        // quantisation step is 1 at that quality and the only loss is rounding in the
        // colour transform and IDCT, a few levels at most.
        let (w, h) = (33u32, 17u32); // odd sizes: partial 8x8 blocks on both axes
        let pixels: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (4 * x + 2 * y) as u8))
            .collect();
        let frame = jpeg(&pixels, w, h, 100);
        let img =
            convert_frame(&frame, &FrameLayout::packed(PixelFormat::Mjpg, w, h), "f").unwrap();
        let GreyImage::U8(got) = &img else {
            panic!("8-bit expected")
        };
        for (i, (&a, &b)) in got.data().iter().zip(&pixels).enumerate() {
            assert!(a.abs_diff(b) <= 3, "pixel {i}: {a} vs {b}");
        }
    }

    /// BT.601 limited range in floating point, the formula OpenCV's fixed point rounds:
    /// within one level of it (the fixed point's coefficients are rounded to 2⁻²⁰).
    fn bt601(y: u8, u: u8, v: u8) -> [f64; 3] {
        let yy = 1.164 * (f64::from(y) - 16.0).max(0.0);
        let (u, v) = (f64::from(u) - 128.0, f64::from(v) - 128.0);
        [yy + 1.596 * v, yy - 0.391 * u - 0.813 * v, yy + 2.018 * u]
            .map(|c| c.round().clamp(0.0, 255.0))
    }

    #[test]
    fn yuyv_to_colour_is_bt601_limited_range() {
        // Known values: limited-range white, black, mid grey (1.164 · 112 = 130.4), and the
        // BT.601 codes of saturated red, green and blue (Y, U, V of 255·(1,0,0) etc.).
        let cases: [([u8; 3], [u8; 3]); 6] = [
            ([235, 128, 128], [255, 255, 255]),
            ([16, 128, 128], [0, 0, 0]),
            ([128, 128, 128], [130, 130, 130]),
            ([81, 90, 240], [255, 0, 0]),
            ([145, 54, 34], [0, 255, 0]),
            ([41, 240, 110], [0, 0, 255]),
        ];
        for ([y, u, v], want) in cases {
            // Both pixels of the pair share U and V; give them the same Y.
            let layout = FrameLayout::packed(PixelFormat::Yuyv, 2, 1);
            let got = convert_frame_colour(&[y, u, y, v], &layout, "f").unwrap();
            for (p, c) in got.data()[0].iter().zip(want) {
                assert!(
                    p.abs_diff(c) <= 1,
                    "YUV {y} {u} {v}: {:?} vs {want:?}",
                    got.data()[0]
                );
            }
            assert_eq!(got.data()[0], got.data()[1]);
        }
        // A sweep of the whole cube against the floating-point formula, the pair's two
        // pixels with different Y: the chroma is shared, the luma each pixel's own.
        let mut frame = Vec::new();
        let mut want = Vec::new();
        for y in (0..=255u8).step_by(17) {
            for u in (0..=255u8).step_by(15) {
                for v in (0..=255u8).step_by(15) {
                    let y1 = 255 - y;
                    frame.extend_from_slice(&[y, u, y1, v]);
                    want.push(bt601(y, u, v));
                    want.push(bt601(y1, u, v));
                }
            }
        }
        let width = want.len() as u32;
        let img = convert_frame_colour(
            &frame,
            &FrameLayout::packed(PixelFormat::Yuyv, width, 1),
            "f",
        )
        .unwrap();
        for (i, (got, want)) in img.data().iter().zip(&want).enumerate() {
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (f64::from(*g) - w).abs() <= 1.0,
                    "pixel {i}: {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn rgb_bgr_grey_and_y16_to_colour() {
        // 2x2 RGB3 with 2 bytes of padding per line (the last line's missing).
        let rgb = [1, 2, 3, 4, 5, 6, 0xEE, 0xEE, 7, 8, 9, 10, 11, 12];
        let layout = FrameLayout {
            format: PixelFormat::Rgb3,
            width: 2,
            height: 2,
            stride: 8,
        };
        let img = convert_frame_colour(&rgb, &layout, "f").unwrap();
        assert_eq!(img.data(), &[[1, 2, 3], [4, 5, 6], [7, 8, 9], [10, 11, 12]]);
        let img = convert_frame_colour(
            &rgb,
            &FrameLayout {
                format: PixelFormat::Bgr3,
                ..layout
            },
            "f",
        )
        .unwrap();
        assert_eq!(img.data(), &[[3, 2, 1], [6, 5, 4], [9, 8, 7], [12, 11, 10]]);
        // RGB3 in grey: OpenCV's RGB2GRAY, pure red 76, pure green 150, pure blue 29.
        let grey = convert_frame(
            &[255, 0, 0, 0, 255, 0, 0, 0, 255],
            &FrameLayout::packed(PixelFormat::Rgb3, 3, 1),
            "f",
        )
        .unwrap();
        assert_eq!(
            grey,
            GreyImage::U8(Frame::new(3, 1, vec![76, 150, 29]).unwrap())
        );
        let img = convert_frame_colour(
            &[0, 9, 255],
            &FrameLayout::packed(PixelFormat::Grey, 3, 1),
            "f",
        )
        .unwrap();
        assert_eq!(img.data(), &[[0; 3], [9; 3], [255; 3]]);
        // Y16 rounded to 8 bits: 4660 / 257 = 18.1, 128 / 257 = 0.498, 129 / 257 = 0.502.
        let y16: Vec<u8> = [0x1234u16, 128, 129, 65535]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let img =
            convert_frame_colour(&y16, &FrameLayout::packed(PixelFormat::Y16, 4, 1), "f").unwrap();
        assert_eq!(img.data(), &[[18; 3], [0; 3], [1; 3], [255; 3]]);
        // Short buffers and odd YUYV widths are refused, naming the frame.
        for format in [PixelFormat::Rgb3, PixelFormat::Bgr3, PixelFormat::Yuyv] {
            let layout = FrameLayout::packed(format, 4, 2);
            let needed = 8 * format.bytes_per_pixel().unwrap();
            let err = convert_frame_colour(&vec![0; needed - 1], &layout, "frame 5").unwrap_err();
            assert!(matches!(err, RigError::FrameData { .. }), "{err}");
            assert!(err.to_string().contains("frame 5"), "{err}");
        }
        let err =
            convert_frame_colour(&[0; 64], &FrameLayout::packed(PixelFormat::Yuyv, 3, 2), "f")
                .unwrap_err();
        assert!(matches!(err, RigError::InvalidParameter { .. }), "{err}");
        assert!(
            convert_frame_colour(&[], &FrameLayout::packed(PixelFormat::Rgb3, 0, 1), "f").is_err()
        );
    }

    #[test]
    fn mjpg_decodes_to_colour() {
        // A smooth colour ramp, encoded by the `image` crate (an independent producer of
        // webcam frames) at quality 100: its chroma subsampling and rounding cost a smooth
        // ramp a few levels per channel at most.
        let (w, h) = (32u32, 16u32);
        let pixels: Vec<u8> = (0..h)
            .flat_map(|y| {
                (0..w).flat_map(move |x| {
                    [
                        (40 + 5 * x) as u8,
                        (200 - 6 * y) as u8,
                        (60 + 2 * x + 3 * y) as u8,
                    ]
                })
            })
            .collect();
        let mut out = Vec::new();
        ::image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 100)
            .encode(&pixels, w, h, ::image::ExtendedColorType::Rgb8)
            .unwrap();
        let img =
            convert_frame_colour(&out, &FrameLayout::packed(PixelFormat::Mjpg, w, h), "f").unwrap();
        let mut worst = 0u8;
        for (got, want) in img.data().iter().zip(pixels.chunks_exact(3)) {
            for (g, w) in got.iter().zip(want) {
                worst = worst.max(g.abs_diff(*w));
            }
        }
        assert!(worst <= 6, "worst channel difference {worst}");
        // A frame of another size than the layout is refused, naming both.
        let err = convert_frame_colour(
            &out,
            &FrameLayout::packed(PixelFormat::Mjpg, 8, 8),
            "frame 2",
        )
        .unwrap_err();
        assert!(err.to_string().contains("32x16"), "{err}");
    }

    #[test]
    fn mjpg_refuses_garbage_and_wrong_size() {
        let layout = FrameLayout::packed(PixelFormat::Mjpg, 8, 8);
        let err = convert_frame(&[0xFF, 0xD8, 0x00, 0x01], &layout, "frame 9").unwrap_err();
        assert!(matches!(err, RigError::FrameData { .. }), "{err}");
        assert!(err.to_string().contains("frame 9"), "{err}");
        let frame = jpeg(&[128; 16 * 8], 16, 8, 90);
        let err = convert_frame(&frame, &layout, "frame 9").unwrap_err();
        assert!(err.to_string().contains("16x8"), "{err}");
        // A truncated JPEG (as a USB transfer cut short delivers) is an error, not a panic.
        let full = jpeg(&[7; 64], 8, 8, 90);
        for cut in [0, 2] {
            assert!(convert_frame(&full[..cut], &layout, "f").is_err());
        }
        // Cut in the entropy-coded data: the decoder may pad or refuse; it must not panic.
        let _ = convert_frame(&full[..full.len() / 2], &layout, "f");
    }
}
