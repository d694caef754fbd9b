//! Writing maps and pictures: 32-bit float TIFF, `.npy`, and PNG.
//!
//! The TIFF and `.npy` writers are tiny and dependency-free; both are read by numpy
//! (`tifffile.imread`, `numpy.load`) and OpenCV (`cv2.imread(path, cv2.IMREAD_UNCHANGED)` for the
//! TIFF) as `float32` arrays of shape `(height, width)`.

use std::io::Write;
use std::path::Path;

use crate::CodecError;
#[cfg(feature = "image-files")]
use crate::{Frame, GreyImage};

/// Writes a grey `f32` image as an uncompressed little-endian baseline TIFF (one strip,
/// `SampleFormat = IEEEFP`, `BitsPerSample = 32`).
///
/// # Errors
/// [`CodecError::Parameter`] if `data.len() != width * height` or the image exceeds 4 GB,
/// [`CodecError::Io`] naming the file.
pub fn write_tiff_f32(
    path: &Path,
    width: usize,
    height: usize,
    data: &[f32],
) -> Result<(), CodecError> {
    check_len(width, height, data.len())?;
    let bytes = data.len() * 4;
    let (w, h, n) = match (
        u32::try_from(width),
        u32::try_from(height),
        u32::try_from(bytes),
    ) {
        (Ok(w), Ok(h), Ok(n)) if bytes < (u32::MAX as usize) - 1024 => (w, h, n),
        _ => {
            return Err(CodecError::parameter(
                "data",
                "a TIFF without BigTIFF holds at most 4 GB",
            ));
        }
    };
    // Layout: 8-byte header, pixel data, then the IFD (word-aligned since n % 4 == 0).
    let ifd_offset = 8 + n;
    let mut out = Vec::with_capacity(bytes + 200);
    out.extend_from_slice(b"II");
    out.extend_from_slice(&42u16.to_le_bytes());
    out.extend_from_slice(&ifd_offset.to_le_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    const SHORT: u16 = 3;
    const LONG: u16 = 4;
    let entries: [(u16, u16, u32); 11] = [
        (256, LONG, w),   // ImageWidth
        (257, LONG, h),   // ImageLength
        (258, SHORT, 32), // BitsPerSample
        (259, SHORT, 1),  // Compression: none
        (262, SHORT, 1),  // PhotometricInterpretation: BlackIsZero
        (273, LONG, 8),   // StripOffsets
        (277, SHORT, 1),  // SamplesPerPixel
        (278, LONG, h),   // RowsPerStrip
        (279, LONG, n),   // StripByteCounts
        (284, SHORT, 1),  // PlanarConfiguration: chunky
        (339, SHORT, 3),  // SampleFormat: IEEE floating point
    ];
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, kind, value) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(&1u32.to_le_bytes());
        if kind == SHORT {
            out.extend_from_slice(&(value as u16).to_le_bytes());
            out.extend_from_slice(&[0, 0]);
        } else {
            out.extend_from_slice(&value.to_le_bytes());
        }
    }
    out.extend_from_slice(&0u32.to_le_bytes()); // no next IFD
    write_file(path, &out)
}

/// Writes a grey `f32` image as a numpy `.npy` file (version 1.0, `<f4`, C order, shape
/// `(height, width)`).
///
/// # Errors
/// [`CodecError::Parameter`] if `data.len() != width * height`, [`CodecError::Io`].
pub fn write_npy_f32(
    path: &Path,
    width: usize,
    height: usize,
    data: &[f32],
) -> Result<(), CodecError> {
    check_len(width, height, data.len())?;
    let mut header =
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({height}, {width}), }}");
    // magic (6) + version (2) + length (2) + header + '\n' must be a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * 4);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    write_file(path, &out)
}

#[cfg(feature = "image-files")]
/// Writes an 8-bit grey PNG.
///
/// # Errors
/// [`CodecError::Image`] naming the file.
pub fn write_png_grey8(path: &Path, frame: &Frame<u8>) -> Result<(), CodecError> {
    save(
        path,
        frame.width(),
        frame.height(),
        frame.data(),
        image::ExtendedColorType::L8,
    )
}

#[cfg(feature = "image-files")]
/// Writes a grey image as a PNG at its own depth: [`write_png_grey8`] or [`write_png_grey16`].
///
/// # Errors
/// [`CodecError::Image`] naming the file.
pub fn write_png_grey(path: &Path, image: &GreyImage) -> Result<(), CodecError> {
    match image {
        GreyImage::U8(f) => write_png_grey8(path, f),
        GreyImage::U16(f) => write_png_grey16(path, f),
    }
}

#[cfg(feature = "image-files")]
/// Writes a 16-bit grey PNG.
///
/// # Errors
/// [`CodecError::Image`] naming the file.
pub fn write_png_grey16(path: &Path, frame: &Frame<u16>) -> Result<(), CodecError> {
    let bytes: Vec<u8> = frame.data().iter().flat_map(|v| v.to_ne_bytes()).collect();
    save(
        path,
        frame.width(),
        frame.height(),
        &bytes,
        image::ExtendedColorType::L16,
    )
}

#[cfg(feature = "image-files")]
/// Writes an 8-bit RGB PNG from `width * height * 3` bytes.
///
/// # Errors
/// [`CodecError::Parameter`] for a wrong buffer length, [`CodecError::Image`] naming the file.
pub fn write_png_rgb8(
    path: &Path,
    width: usize,
    height: usize,
    rgb: &[u8],
) -> Result<(), CodecError> {
    check_len(width * 3, height, rgb.len())?;
    save(path, width, height, rgb, image::ExtendedColorType::Rgb8)
}

#[cfg(feature = "image-files")]
/// Writes a colour image as an 8-bit RGB PNG.
///
/// # Errors
/// [`CodecError::Image`] naming the file.
pub fn write_png_colour(path: &Path, image: &sl_image::ColourImage) -> Result<(), CodecError> {
    save(
        path,
        image.width(),
        image.height(),
        image.data().as_flattened(),
        image::ExtendedColorType::Rgb8,
    )
}

#[cfg(feature = "image-files")]
fn save(
    path: &Path,
    width: usize,
    height: usize,
    bytes: &[u8],
    color: image::ExtendedColorType,
) -> Result<(), CodecError> {
    let (Ok(w), Ok(h)) = (u32::try_from(width), u32::try_from(height)) else {
        return Err(CodecError::parameter(
            "width/height",
            "image too large for PNG",
        ));
    };
    image::save_buffer_with_format(path, bytes, w, h, color, image::ImageFormat::Png).map_err(
        |source| CodecError::Image {
            path: path.to_path_buf(),
            action: "encode",
            source,
        },
    )
}

fn check_len(width: usize, height: usize, len: usize) -> Result<(), CodecError> {
    if width.checked_mul(height) != Some(len) {
        return Err(CodecError::parameter(
            "data",
            format!("{len} values do not make a {width}x{height} image"),
        ));
    }
    Ok(())
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), CodecError> {
    let mut f = std::fs::File::create(path).map_err(|e| CodecError::io(path, "create", e))?;
    f.write_all(bytes)
        .map_err(|e| CodecError::io(path, "write", e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn u16_at(b: &[u8], i: usize) -> u16 {
        u16::from_le_bytes([b[i], b[i + 1]])
    }
    fn u32_at(b: &[u8], i: usize) -> u32 {
        u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
    }

    #[test]
    fn tiff_layout_follows_the_baseline_spec() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.tiff");
        let data = [0.0f32, 1.5, -2.0, f32::NAN, 7.25, 1e6];
        write_tiff_f32(&p, 3, 2, &data).unwrap();
        let b = std::fs::read(&p).unwrap();
        assert_eq!(&b[0..4], b"II*\0");
        let ifd = u32_at(&b, 4) as usize;
        assert_eq!(ifd, 8 + 24);
        // Pixel data at offset 8, row-major.
        assert_eq!(f32::from_le_bytes([b[12], b[13], b[14], b[15]]), 1.5);
        let n = u16_at(&b, ifd) as usize;
        let mut tags = std::collections::HashMap::new();
        for k in 0..n {
            let e = ifd + 2 + 12 * k;
            let kind = u16_at(&b, e + 2);
            let v = if kind == 3 {
                u32::from(u16_at(&b, e + 8))
            } else {
                u32_at(&b, e + 8)
            };
            tags.insert(u16_at(&b, e), v);
        }
        assert_eq!(tags[&256], 3);
        assert_eq!(tags[&257], 2);
        assert_eq!(tags[&258], 32);
        assert_eq!(tags[&339], 3);
        assert_eq!(tags[&279], 24);
        assert!(write_tiff_f32(&p, 4, 2, &data).is_err());
    }

    #[test]
    fn npy_header_is_aligned() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        write_npy_f32(&p, 3, 2, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        let b = std::fs::read(&p).unwrap();
        assert_eq!(&b[0..8], b"\x93NUMPY\x01\x00");
        let hl = u16_at(&b, 8) as usize;
        assert_eq!((10 + hl) % 64, 0);
        let header = std::str::from_utf8(&b[10..10 + hl]).unwrap();
        assert!(header.contains("'shape': (2, 3)"), "{header}");
        assert_eq!(b.len(), 10 + hl + 24);
    }
}
