//! Reading capture frames and calibration images from the files capture programs write:
//! BMP, PGM/PPM (and PBM/PAM), PNG, JPEG and TIFF, at 8 or 16 bits, grey or colour.
//!
//! Decoding is done by the `image` crate (features `bmp`, `pnm`, `png`, `jpeg`, `tiff`): file
//! formats are not the point of this project and that crate's decoders are fuzzed and kept.
//! What is ours is the conversion to grey, chosen so that figures measured here match those
//! measured with OpenCV on the same files:
//!
//! - **Grey** files keep their values and their depth (8-bit stays `u8`, 16-bit stays `u16`).
//! - **Colour** becomes grey by OpenCV's `cvtColor(COLOR_RGB2GRAY)` rule,
//!   `Y = 0.299 R + 0.587 G + 0.114 B`, evaluated as OpenCV does in 15-bit fixed point
//!   (`gray_shift = 15`, weights `RY15 GY15 BY15` = 9798, 19235, 3735, rounded half up), so
//!   the result is bit-identical to OpenCV's at 8 and at 16 bits (checked against OpenCV 5.0's
//!   `cv2.cvtColor` on 20 000 random pixels of each depth: no difference; a 14-bit or a
//!   floating-point evaluation differs from it by one level on a third to half of the pixels).
//!   Alpha is ignored (as `COLOR_RGBA2GRAY` does). The `image` crate's
//!   own `to_luma8` uses Rec. 709 weights (0.2126, 0.7152, 0.0722), which differ by up to
//!   ~40 grey levels on saturated colours.
//! - **Float** files (32-bit float TIFF) are clamped to `[0, 1]` and become 16-bit.
//! - [`read_grey8`] (the calibration board detector's input) scales 16-bit values to 8 bits
//!   by `round(v / 257)`, the exact inverse of the `v * 257` widening; OpenCV's
//!   `imread(IMREAD_GRAYSCALE)` keeps the high byte (`v >> 8`) instead, at most one grey level
//!   lower.

use std::path::{Path, PathBuf};

use image::DynamicImage;

use crate::{CodecError, Frame, GreyImage};

/// File extensions (lower case, without the dot) of the image files this crate reads; a
/// folder listing filters on them (case-insensitively) with [`is_image_file`].
pub const IMAGE_EXTENSIONS: [&str; 11] = [
    "png", "jpg", "jpeg", "tif", "tiff", "bmp", "pgm", "ppm", "pnm", "pbm", "pam",
];

/// Weights of OpenCV's RGB → grey conversion in its 15-bit fixed point
/// (`imgproc/src/color_rgb.simd.hpp`: `RY15 = 9798`, `GY15 = 19235`, `BY15 = 3735`, i.e.
/// 0.299, 0.587 and 0.114 times 2¹⁵ rounded; they sum to exactly 2¹⁵, so grey stays grey).
const R2Y: u32 = 9798;
/// Green weight, see [`R2Y`].
const G2Y: u32 = 19235;
/// Blue weight, see [`R2Y`].
const B2Y: u32 = 3735;
/// Fixed-point shift of the weights (OpenCV's `gray_shift`).
const GREY_SHIFT: u32 = 15;
/// Half of the fixed-point unit, added before the shift to round half up.
const GREY_ROUND: u32 = 1 << (GREY_SHIFT - 1);

/// Whether a path names a file with one of the [`IMAGE_EXTENSIONS`] (case-insensitive). Only
/// the name is looked at, not the file.
pub fn is_image_file(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// The image file a path names, in whichever of the [`IMAGE_EXTENSIONS`] it was saved: `path`
/// itself when it is a file, else the first existing file of the same name with one of the
/// extensions (in the order of [`IMAGE_EXTENSIONS`], lower case before upper case). So a
/// folder's `white.png` is found when it was saved as `white.bmp` or `white.TIF`, and a
/// manifest written by `slscan patterns` (frames `000.png`, `001.png`, …) reads the frames a
/// capture program saved as `000.bmp`, `001.bmp`, ….
///
/// Returns `None` when no such file exists. Only the extension is replaced: a path whose name
/// has no extension gets one appended.
///
/// ```
/// # fn main() -> std::io::Result<()> {
/// let dir = tempfile::tempdir()?;
/// std::fs::write(dir.path().join("white.bmp"), b"")?;
/// let found = sl_codec::find_image_file(&dir.path().join("white.png"));
/// assert_eq!(found, Some(dir.path().join("white.bmp")));
/// assert_eq!(sl_codec::find_image_file(&dir.path().join("black.png")), None);
/// # Ok(()) }
/// ```
pub fn find_image_file(path: &Path) -> Option<PathBuf> {
    if path.is_file() {
        return Some(path.to_path_buf());
    }
    IMAGE_EXTENSIONS
        .iter()
        .flat_map(|e| [(*e).to_owned(), e.to_ascii_uppercase()])
        .map(|e| path.with_extension(e))
        .find(|p| p.is_file())
}

/// Reads an image file as grey at its own depth (see the module docs for the conversion).
/// The format is found from the file's content (its magic number), falling back to the
/// extension, so a BMP named `.png` still reads.
///
/// # Errors
/// [`CodecError::Image`] naming the file when it cannot be opened or decoded (the message of
/// the `image` crate says why, e.g. an unsupported format or a truncated file).
///
/// ```
/// # fn main() -> Result<(), sl_codec::CodecError> {
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("red.bmp");
/// // A 2x1 colour BMP: pure red and pure white.
/// image::save_buffer(&path, &[255, 0, 0, 255, 255, 255], 2, 1, image::ExtendedColorType::Rgb8)
///     .unwrap();
/// let grey = sl_codec::read_image(&path)?.into_u8();
/// assert_eq!(grey.data(), &[76, 255]); // as OpenCV's cvtColor(COLOR_RGB2GRAY)
/// # Ok(()) }
/// ```
pub fn read_image(path: &Path) -> Result<GreyImage, CodecError> {
    let img = reader(path)?.decode().map_err(decode_err(path))?;
    if img.width() == 0 || img.height() == 0 {
        return Err(CodecError::EmptyImage {
            path: path.to_path_buf(),
        });
    }
    grey_of(img)
}

/// An image file's width and height, read from its header alone (the format found from the
/// content, as [`read_image`] does): a cheap check of many files before any is decoded.
///
/// # Errors
/// [`CodecError::Image`] naming the file when it cannot be opened or its header read.
pub fn read_image_size(path: &Path) -> Result<(u32, u32), CodecError> {
    reader(path)?.into_dimensions().map_err(decode_err(path))
}

fn decode_err(path: &Path) -> impl Fn(image::ImageError) -> CodecError + '_ {
    move |source| CodecError::Image {
        path: path.to_path_buf(),
        action: "decode",
        source,
    }
}

/// A reader of `path` with its format guessed from the content.
fn reader(
    path: &Path,
) -> Result<image::ImageReader<std::io::BufReader<std::fs::File>>, CodecError> {
    let err = decode_err(path);
    image::ImageReader::open(path)
        .map_err(|e| err(image::ImageError::IoError(e)))?
        .with_guessed_format()
        .map_err(|e| err(image::ImageError::IoError(e)))
}

/// Reads an image file as 8-bit grey: [`read_image`], then 16-bit values scaled by
/// `round(v / 257)`. This is what the checkerboard detector works on.
///
/// # Errors
/// As [`read_image`].
pub fn read_grey8(path: &Path) -> Result<Frame<u8>, CodecError> {
    Ok(read_image(path)?.into_u8())
}

/// Grey of a decoded image (see the module docs).
///
/// # Errors
/// [`CodecError::Parameter`] for an image of no pixels (`read_image` refuses those first).
fn grey_of(img: DynamicImage) -> Result<GreyImage, CodecError> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let grey = match img {
        DynamicImage::ImageLuma8(b) => Frame::new(w, h, b.into_raw())?.into(),
        DynamicImage::ImageLuma16(b) => Frame::new(w, h, b.into_raw())?.into(),
        DynamicImage::ImageLumaA8(b) => {
            Frame::new(w, h, b.pixels().map(|p| p.0[0]).collect())?.into()
        }
        DynamicImage::ImageLumaA16(b) => {
            Frame::new(w, h, b.pixels().map(|p| p.0[0]).collect())?.into()
        }
        DynamicImage::ImageRgb8(b) => Frame::new(
            w,
            h,
            b.pixels().map(|p| grey8(p.0[0], p.0[1], p.0[2])).collect(),
        )?
        .into(),
        DynamicImage::ImageRgba8(b) => Frame::new(
            w,
            h,
            b.pixels().map(|p| grey8(p.0[0], p.0[1], p.0[2])).collect(),
        )?
        .into(),
        DynamicImage::ImageRgb16(b) => Frame::new(
            w,
            h,
            b.pixels().map(|p| grey16(p.0[0], p.0[1], p.0[2])).collect(),
        )?
        .into(),
        DynamicImage::ImageRgba16(b) => Frame::new(
            w,
            h,
            b.pixels().map(|p| grey16(p.0[0], p.0[1], p.0[2])).collect(),
        )?
        .into(),
        // Float images (and any variant a later `image` adds): through 16-bit RGB, which
        // clamps floats to [0, 1] and scales them to [0, 65535].
        other => {
            let b = other.to_rgb16();
            Frame::new(
                w,
                h,
                b.pixels().map(|p| grey16(p.0[0], p.0[1], p.0[2])).collect(),
            )?
            .into()
        }
    };
    Ok(grey)
}

/// OpenCV's fixed-point RGB → grey at 16 bits (the weights sum to 2¹⁵, so the result never
/// exceeds the largest input; the sum fits `u32`: 65535 · 2¹⁵ < 2³²).
fn grey16(r: u16, g: u16, b: u16) -> u16 {
    let y =
        (u32::from(r) * R2Y + u32::from(g) * G2Y + u32::from(b) * B2Y + GREY_ROUND) >> GREY_SHIFT;
    u16::try_from(y).unwrap_or(u16::MAX)
}

/// OpenCV's fixed-point RGB → grey at 8 bits.
fn grey8(r: u8, g: u8, b: u8) -> u8 {
    u8::try_from(grey16(u16::from(r), u16::from(g), u16::from(b))).unwrap_or(u8::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_size_is_read_from_the_header_and_a_bad_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("a.png");
        let frame = Frame::new(3, 2, vec![0u8; 6]).unwrap();
        crate::write_png_grey8(&png, &frame).unwrap();
        assert_eq!(read_image_size(&png).unwrap(), (3, 2));
        let bad = dir.path().join("b.png");
        std::fs::write(&bad, b"not an image").unwrap();
        let err = read_image_size(&bad).unwrap_err().to_string();
        assert!(err.contains("b.png"), "{err}");
        let err = read_image_size(&dir.path().join("none.png"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("none.png"), "{err}");
    }

    #[test]
    fn opencv_grey_of_primaries_and_greys() {
        // cv2.cvtColor(np.uint8([[[255,0,0],[0,255,0],[0,0,255]]]), cv2.COLOR_RGB2GRAY)
        // gives 76, 150, 29: 0.299·255 = 76.2, 0.587·255 = 149.7, 0.114·255 = 29.07.
        assert_eq!(grey8(255, 0, 0), 76);
        assert_eq!(grey8(0, 255, 0), 150);
        assert_eq!(grey8(0, 0, 255), 29);
        for v in 0..=255u8 {
            assert_eq!(grey8(v, v, v), v);
        }
        for v in [0u16, 1, 257, 32768, 65534, 65535] {
            assert_eq!(grey16(v, v, v), v);
        }
        // cv2.cvtColor on uint16 [65535,0,0], [0,65535,0], [0,0,65535] (OpenCV 5.0) gives
        // 19596, 38469, 7470.
        assert_eq!(grey16(65535, 0, 0), 19596);
        assert_eq!(grey16(0, 65535, 0), 38469);
        assert_eq!(grey16(0, 0, 65535), 7470);
    }

    #[test]
    fn extensions_are_matched_without_case() {
        assert!(is_image_file(Path::new("a/b/000.BMP")));
        assert!(is_image_file(Path::new("x.pgm")));
        assert!(is_image_file(Path::new("x.Tiff")));
        assert!(!is_image_file(Path::new("manifest.json")));
        assert!(!is_image_file(Path::new("noext")));
    }
}
