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
//! - **Float** files (32- or 64-bit float TIFF, grey or colour) are clamped to `[0, 1]` and
//!   become 16-bit, `round(v · 65535)` (NaN becomes 0): a float frame holds light as a fraction
//!   of full scale, so `v / 255` of an 8-bit frame reads as that frame widened (`257 v`). Grey
//!   float TIFF, which the `image` crate's decoder refuses, is read with the `tiff` crate.
//! - [`read_grey8`] (the calibration board detector's input) scales 16-bit values to 8 bits
//!   by `round(v / 257)`, the exact inverse of the `v * 257` widening; OpenCV's
//!   `imread(IMREAD_GRAYSCALE)` keeps the high byte (`v >> 8`) instead, at most one grey level
//!   lower.

use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageFormat};

use crate::{CodecError, Frame, GreyImage};
use sl_image::ColourImage;

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

/// What is at `path` when something is there that is not a regular file, following symbolic
/// links: `"is a directory"`, `"is not a regular file (a character device)"` (a device, a FIFO or
/// a socket, which are never read: `/dev/zero` would never end, a FIFO blocks), with the link's
/// target for a symbolic link (`"is a symbolic link to /dev/zero, which is not a regular file
/// (a character device)"`). `None` when `path` is a regular file or nothing is there (a missing
/// file, or a link to nothing).
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// assert_eq!(sl_codec::not_a_regular_file(dir.path()).as_deref(), Some("is a directory"));
/// assert_eq!(sl_codec::not_a_regular_file(&dir.path().join("none.png")), None);
/// ```
pub fn not_a_regular_file(path: &Path) -> Option<String> {
    let meta = std::fs::metadata(path).ok()?;
    let kind = file_kind(&meta.file_type())?;
    let what = if kind == "directory" {
        "a directory".to_owned()
    } else {
        format!("not a regular file (a {kind})")
    };
    let link = std::fs::symlink_metadata(path)
        .is_ok_and(|m| m.file_type().is_symlink())
        .then(|| std::fs::read_link(path).ok())
        .flatten();
    Some(match link {
        Some(target) => format!(
            "is a symbolic link to {}, which is {what}",
            target.display()
        ),
        None => format!("is {what}"),
    })
}

/// What a file type other than a regular file is, in words; `None` for a regular file.
fn file_kind(t: &std::fs::FileType) -> Option<&'static str> {
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() {
            return Some("character device");
        }
        if t.is_block_device() {
            return Some("block device");
        }
        if t.is_fifo() {
            return Some("FIFO");
        }
        if t.is_socket() {
            return Some("socket");
        }
    }
    Some("special file")
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
    let reader = reader(path)?;
    if reader.format() == Some(ImageFormat::Tiff)
        && let Some(grey) = read_float_grey_tiff(path)?
    {
        return Ok(grey);
    }
    let img = reader.decode().map_err(decode_err(path))?;
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
    let reader = reader(path)?;
    if reader.format() == Some(ImageFormat::Tiff) {
        // The `tiff` crate's header reader takes every TIFF, the grey float ones included.
        return tiff_decoder(path)?.dimensions().map_err(tiff_err(path));
    }
    reader.into_dimensions().map_err(decode_err(path))
}

/// Whether an image file holds colour channels, from its header alone (a grey file, or a
/// colour one, whatever its pixels): a cheap check before reading a capture in colour.
///
/// # Errors
/// [`CodecError::Image`] naming the file when it cannot be opened or its header read.
pub fn is_colour_image(path: &Path) -> Result<bool, CodecError> {
    let reader = reader(path)?;
    if reader.format() == Some(ImageFormat::Tiff) {
        // The `tiff` crate reads every TIFF's header, the grey float ones included.
        let colour = tiff_decoder(path)?.colortype().map_err(tiff_err(path))?;
        return Ok(!matches!(colour, tiff::ColorType::Gray(_)));
    }
    use image::ImageDecoder;
    let decoder = reader.into_decoder().map_err(decode_err(path))?;
    Ok(decoder.color_type().has_color())
}

/// A `tiff` decoder of `path` (a regular file: [`reader`] checked it).
fn tiff_decoder(
    path: &Path,
) -> Result<tiff::decoder::Decoder<std::io::BufReader<std::fs::File>>, CodecError> {
    let file =
        std::fs::File::open(path).map_err(|e| decode_err(path)(image::ImageError::IoError(e)))?;
    tiff::decoder::Decoder::new(std::io::BufReader::new(file)).map_err(tiff_err(path))
}

/// A `tiff` error as [`CodecError::Image`] naming the file.
fn tiff_err(path: &Path) -> impl Fn(tiff::TiffError) -> CodecError + '_ {
    move |e| {
        decode_err(path)(image::ImageError::Decoding(
            image::error::DecodingError::new(ImageFormat::Tiff.into(), e),
        ))
    }
}

/// A grey TIFF of 32- or 64-bit floats (`SampleFormat = IEEEFP`, `BlackIsZero`), which the
/// `image` crate's TIFF decoder refuses, read with the `tiff` crate and turned into 16 bits as
/// `image` turns its float colour images: clamped to [0, 1] and scaled to [0, 65535], rounded
/// (NaN, no light measured, is 0). `None` for any other TIFF, left to `image`.
fn read_float_grey_tiff(path: &Path) -> Result<Option<GreyImage>, CodecError> {
    use tiff::ColorType;
    use tiff::decoder::DecodingResult;
    use tiff::tags::{PhotometricInterpretation, SampleFormat, Tag};

    let mut decoder = tiff_decoder(path)?;
    let err = tiff_err(path);
    let grey = matches!(decoder.colortype().map_err(&err)?, ColorType::Gray(32 | 64));
    let float = decoder
        .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
        .map_err(&err)?
        .is_some_and(|f| !f.is_empty() && f.iter().all(|&f| f == SampleFormat::IEEEFP.to_u16()));
    let black_is_zero = decoder
        .find_tag_unsigned::<u16>(Tag::PhotometricInterpretation)
        .map_err(&err)?
        == Some(PhotometricInterpretation::BlackIsZero.to_u16());
    if !(grey && float && black_is_zero) {
        return Ok(None);
    }
    let (w, h) = decoder.dimensions().map_err(&err)?;
    let scaled: Vec<u16> = match decoder.read_image().map_err(&err)? {
        DecodingResult::F32(v) => v.into_iter().map(|x| unit_to_u16(f64::from(x))).collect(),
        DecodingResult::F64(v) => v.into_iter().map(unit_to_u16).collect(),
        _ => return Ok(None),
    };
    if w == 0 || h == 0 {
        return Err(CodecError::EmptyImage {
            path: path.to_path_buf(),
        });
    }
    Ok(Some(Frame::new(w as usize, h as usize, scaled)?.into()))
}

/// A float sample in [0, 1] (clamped; NaN as 0) as a 16-bit one, `round(v · 65535)`.
fn unit_to_u16(v: f64) -> u16 {
    if v.is_nan() {
        return 0;
    }
    // In [0, 65535] after the clamp: the conversion neither truncates nor saturates.
    (v.clamp(0.0, 1.0) * f64::from(u16::MAX)).round() as u16
}

fn decode_err(path: &Path) -> impl Fn(image::ImageError) -> CodecError + '_ {
    move |source| CodecError::Image {
        path: path.to_path_buf(),
        action: "decode",
        source,
    }
}

/// A reader of `path` with its format guessed from the content; a folder, device, FIFO or
/// socket is refused before it is opened ([`not_a_regular_file`]).
fn reader(
    path: &Path,
) -> Result<image::ImageReader<std::io::BufReader<std::fs::File>>, CodecError> {
    if let Some(what) = not_a_regular_file(path) {
        return Err(CodecError::NotAFile {
            path: path.to_path_buf(),
            what,
        });
    }
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

/// Reads an image file in colour, 8-bit RGB: grey files give the same value in the three
/// channels; 16-bit and float files are rounded to 8 bits (`round(v / 257)`, floats through
/// 16 bits as [`read_image`] reads them); alpha is ignored. The colour of a scan comes from
/// such a frame under full white.
///
/// # Errors
/// [`CodecError::Image`] naming the file when it cannot be opened or decoded;
/// [`CodecError::EmptyImage`] for an image of no pixels.
///
/// ```
/// # fn main() -> Result<(), sl_codec::CodecError> {
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("red.png");
/// image::save_buffer(&path, &[255, 0, 0, 255, 255, 255], 2, 1, image::ExtendedColorType::Rgb8)
///     .unwrap();
/// let colour = sl_codec::read_colour_image(&path)?;
/// assert_eq!(colour.data(), &[[255, 0, 0], [255, 255, 255]]);
/// # Ok(()) }
/// ```
pub fn read_colour_image(path: &Path) -> Result<ColourImage, CodecError> {
    let reader = reader(path)?;
    if reader.format() == Some(ImageFormat::Tiff)
        && let Some(grey) = read_float_grey_tiff(path)?
    {
        return Ok(ColourImage::from_grey(&grey));
    }
    let img = reader.decode().map_err(decode_err(path))?;
    if img.width() == 0 || img.height() == 0 {
        return Err(CodecError::EmptyImage {
            path: path.to_path_buf(),
        });
    }
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data = match img {
        DynamicImage::ImageLuma8(_) | DynamicImage::ImageLumaA8(_) => img
            .to_luma8()
            .into_raw()
            .into_iter()
            .map(|g| [g; 3])
            .collect(),
        DynamicImage::ImageRgb8(b) => b.pixels().map(|p| p.0).collect(),
        DynamicImage::ImageRgba8(b) => b.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect(),
        // 16-bit and float images: through 16-bit RGB (floats clamped to [0, 1]), then
        // `round(v / 257)`, the inverse of the 8 → 16 widening.
        other => other
            .to_rgb16()
            .pixels()
            .map(|p| p.0.map(|v| ((u32::from(v) + 128) / 257) as u8))
            .collect(),
    };
    Ok(ColourImage::new(w, h, data)?)
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
        // Float colour images (and any variant a later `image` adds): through 16-bit RGB,
        // which clamps floats to [0, 1] and scales them to [0, 65535] (grey float TIFF, which
        // `image` refuses, is read by `read_float_grey_tiff` the same way).
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

    /// Grey float TIFF (the `tiff` crate's encoder, 32 and 64 bits, and this crate's own
    /// `write_tiff_f32`) reads as 16 bits: `round(clamp(v, 0, 1) · 65535)`, NaN as 0; the
    /// header gives the size.
    #[test]
    fn grey_float_tiff_is_read_as_sixteen_bits() {
        use tiff::encoder::{TiffEncoder, colortype};
        let dir = tempfile::tempdir().unwrap();
        let values = [0.0, 0.5, 1.0, 2.0, -1.0, f64::NAN, 100.0 / 255.0, 1e-6];
        let expected: Vec<u16> = vec![0, 32768, 65535, 65535, 0, 0, 25700, 0];
        let f32s: Vec<f32> = values.iter().map(|&v| v as f32).collect();
        let p32 = dir.path().join("a32.tif");
        TiffEncoder::new(std::fs::File::create(&p32).unwrap())
            .unwrap()
            .write_image::<colortype::Gray32Float>(4, 2, &f32s)
            .unwrap();
        let p64 = dir.path().join("a64.tif");
        TiffEncoder::new(std::fs::File::create(&p64).unwrap())
            .unwrap()
            .write_image::<colortype::Gray64Float>(4, 2, &values)
            .unwrap();
        let ours = dir.path().join("ours.tiff");
        crate::write_tiff_f32(&ours, 4, 2, &f32s).unwrap();
        for p in [&p32, &p64, &ours] {
            let GreyImage::U16(f) = read_image(p).unwrap() else {
                panic!("{}: not 16-bit", p.display());
            };
            assert_eq!((f.width(), f.height()), (4, 2));
            assert_eq!(f.data(), expected.as_slice(), "{}", p.display());
            assert_eq!(read_image_size(p).unwrap(), (4, 2));
        }
    }

    /// A folder or a device given as an image is named for what it is, and never opened.
    #[test]
    fn what_is_not_a_regular_file_is_refused_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_image(dir.path()).unwrap_err().to_string();
        assert!(err.ends_with("is a directory"), "{err}");
        #[cfg(unix)]
        {
            let err = read_image(Path::new("/dev/zero")).unwrap_err().to_string();
            assert_eq!(err, "/dev/zero is not a regular file (a character device)");
            let link = dir.path().join("zero.png");
            std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
            let err = read_image_size(&link).unwrap_err().to_string();
            assert!(
                err.ends_with(
                    "zero.png is a symbolic link to /dev/zero, which is not a regular file \
                     (a character device)"
                ),
                "{err}"
            );
        }
        assert_eq!(not_a_regular_file(&dir.path().join("none.png")), None);
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
