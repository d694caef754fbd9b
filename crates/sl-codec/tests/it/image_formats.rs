//! One file of every format a capture program commonly writes (BMP 8-bit grey and 24-bit
//! colour, PGM 8/16, PPM, PNG 8/16, JPEG, TIFF 8/16), written here with known pixel values,
//! reads back to those values through `read_image`, `read_grey8` and `CaptureSet`.
//!
//! BMP, PGM and PPM files are written byte by byte from the formats' specifications
//! (Microsoft's `BITMAPINFOHEADER`, Netpbm's `pgm(5)`/`ppm(5)`), so the test does not trust
//! the decoder's own encoder; PNG, JPEG and TIFF files are written by the `image` crate's
//! encoders, whose output other programs read.
// Helpers outside #[test] functions unwrap too: a panic there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use sl_codec::{
    CaptureSet, CodecError, Frames, GreyImage, IMAGE_EXTENSIONS, is_image_file, read_grey8,
    read_image,
};

const W: usize = 16;
const H: usize = 8;

/// Distinct 8-bit grey values over the image, 0 and 255 included.
fn grey8_at(x: usize, y: usize) -> u8 {
    match (x, y) {
        (0, 0) => 0,
        (1, 0) => 255,
        _ => ((x * 13 + y * 29 + 7) % 256) as u8,
    }
}

/// 16-bit grey values whose high and low bytes both vary, 0 and 65535 included.
fn grey16_at(x: usize, y: usize) -> u16 {
    match (x, y) {
        (0, 0) => 0,
        (1, 0) => 65535,
        _ => ((x * 4111 + y * 977 + 301) % 65536) as u16,
    }
}

/// Colour pixels: pure red, green, blue, white and a few mixtures, then a ramp.
fn rgb8_at(x: usize, y: usize) -> [u8; 3] {
    match (x, y) {
        (0, 0) => [255, 0, 0],
        (1, 0) => [0, 255, 0],
        (2, 0) => [0, 0, 255],
        (3, 0) => [255, 255, 255],
        _ => [
            ((x * 16) % 256) as u8,
            ((y * 32 + 5) % 256) as u8,
            (255 - x * 9) as u8,
        ],
    }
}

fn rgb16_at(x: usize, y: usize) -> [u16; 3] {
    match (x, y) {
        (0, 0) => [65535, 0, 0],
        (1, 0) => [0, 65535, 0],
        (2, 0) => [0, 0, 65535],
        (3, 0) => [65535, 65535, 65535],
        _ => [
            (x * 4000) as u16,
            (y * 8000 + 33) as u16,
            (65535 - x * 3001) as u16,
        ],
    }
}

/// OpenCV's `cvtColor(COLOR_RGB2GRAY)` on the primaries (OpenCV 5.0's results: red 76, green
/// 150, blue 29 at 8 bits; 19596, 38469, 7470 at 16 bits), else the exact weighted sum
/// `0.299 R + 0.587 G + 0.114 B`, which OpenCV's 15-bit fixed point reproduces to within one
/// level.
fn expected_grey(rgb: [f64; 3], max: f64) -> (f64, f64) {
    let exact = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2];
    let known = [
        ([max, 0.0, 0.0], if max > 255.0 { 19596.0 } else { 76.0 }),
        ([0.0, max, 0.0], if max > 255.0 { 38469.0 } else { 150.0 }),
        ([0.0, 0.0, max], if max > 255.0 { 7470.0 } else { 29.0 }),
    ];
    for (k, v) in known {
        if k == rgb {
            return (v, 0.0);
        }
    }
    if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
        return (rgb[0], 0.0);
    }
    (exact.round(), 1.0)
}

fn grey8_buf() -> Vec<u8> {
    (0..H)
        .flat_map(|y| (0..W).map(move |x| grey8_at(x, y)))
        .collect()
}

fn grey16_buf() -> Vec<u16> {
    (0..H)
        .flat_map(|y| (0..W).map(move |x| grey16_at(x, y)))
        .collect()
}

fn rgb8_buf() -> Vec<u8> {
    (0..H)
        .flat_map(|y| (0..W).flat_map(move |x| rgb8_at(x, y)))
        .collect()
}

fn rgb16_buf() -> Vec<u16> {
    (0..H)
        .flat_map(|y| (0..W).flat_map(move |x| rgb16_at(x, y)))
        .collect()
}

/// A Windows BMP (`BITMAPFILEHEADER` + `BITMAPINFOHEADER`), bottom-up rows padded to 4 bytes:
/// 8-bit with a 256-entry grey palette, or 24-bit BGR.
fn write_bmp(path: &Path, bits: u16) {
    let (palette, bytes_pp) = if bits == 8 { (256 * 4, 1) } else { (0, 3) };
    let row = (W * bytes_pp).div_ceil(4) * 4;
    let offset = 14 + 40 + palette;
    let size = offset + row * H;
    let mut b = Vec::with_capacity(size);
    b.extend_from_slice(b"BM");
    b.extend_from_slice(&(size as u32).to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&(offset as u32).to_le_bytes());
    b.extend_from_slice(&40u32.to_le_bytes());
    b.extend_from_slice(&(W as i32).to_le_bytes());
    b.extend_from_slice(&(H as i32).to_le_bytes()); // positive: bottom-up
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&bits.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes()); // BI_RGB
    b.extend_from_slice(&((row * H) as u32).to_le_bytes());
    b.extend_from_slice(&2835i32.to_le_bytes());
    b.extend_from_slice(&2835i32.to_le_bytes());
    b.extend_from_slice(&(if bits == 8 { 256u32 } else { 0 }).to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    if bits == 8 {
        for v in 0..=255u8 {
            b.extend_from_slice(&[v, v, v, 0]);
        }
    }
    for y in (0..H).rev() {
        let start = b.len();
        for x in 0..W {
            if bits == 8 {
                b.push(grey8_at(x, y));
            } else {
                let [r, g, bl] = rgb8_at(x, y);
                b.extend_from_slice(&[bl, g, r]);
            }
        }
        b.resize(start + row, 0);
    }
    std::fs::write(path, b).unwrap();
}

/// Binary Netpbm: `P5` (grey) or `P6` (colour), big-endian samples when maxval > 255.
fn write_pnm(path: &Path, magic: &str, maxval: u32, samples: &[u32]) {
    let mut b = format!("{magic}\n# written by sl-codec's tests\n{W} {H}\n{maxval}\n").into_bytes();
    for &s in samples {
        if maxval > 255 {
            b.extend_from_slice(&(s as u16).to_be_bytes());
        } else {
            b.push(s as u8);
        }
    }
    std::fs::write(path, b).unwrap();
}

fn save(path: &Path, bytes: &[u8], color: image::ExtendedColorType) {
    image::save_buffer(path, bytes, W as u32, H as u32, color).unwrap();
}

fn u16_bytes(v: &[u16]) -> Vec<u8> {
    // `save_buffer` takes 16-bit samples in native byte order.
    v.iter().flat_map(|s| s.to_ne_bytes()).collect()
}

fn assert_grey8(img: &GreyImage, name: &str) {
    let GreyImage::U8(f) = img else {
        panic!("{name}: expected 8 bits, got {}", img.bit_depth());
    };
    assert_eq!((f.width(), f.height()), (W, H), "{name}");
    assert_eq!(f.data(), grey8_buf().as_slice(), "{name}");
}

fn assert_grey16(img: &GreyImage, name: &str) {
    let GreyImage::U16(f) = img else {
        panic!("{name}: expected 16 bits, got {}", img.bit_depth());
    };
    assert_eq!((f.width(), f.height()), (W, H), "{name}");
    assert_eq!(f.data(), grey16_buf().as_slice(), "{name}");
}

fn assert_colour8(img: &GreyImage, name: &str) {
    let GreyImage::U8(f) = img else {
        panic!("{name}: expected 8 bits, got {}", img.bit_depth());
    };
    for y in 0..H {
        for x in 0..W {
            let rgb = rgb8_at(x, y).map(f64::from);
            let (want, tol) = expected_grey(rgb, 255.0);
            let got = f64::from(f.get(x, y).unwrap());
            assert!(
                (got - want).abs() <= tol,
                "{name} ({x}, {y}) {rgb:?}: {got} vs {want}"
            );
        }
    }
}

fn assert_colour16(img: &GreyImage, name: &str) {
    let GreyImage::U16(f) = img else {
        panic!("{name}: expected 16 bits, got {}", img.bit_depth());
    };
    for y in 0..H {
        for x in 0..W {
            let rgb = rgb16_at(x, y).map(f64::from);
            let (want, tol) = expected_grey(rgb, 65535.0);
            let got = f64::from(f.get(x, y).unwrap());
            assert!(
                (got - want).abs() <= tol,
                "{name} ({x}, {y}) {rgb:?}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn bmp_grey_and_colour() {
    let dir = tempfile::tempdir().unwrap();
    let grey = dir.path().join("grey8.bmp");
    write_bmp(&grey, 8);
    assert_grey8(&read_image(&grey).unwrap(), "8-bit palette BMP");
    let colour = dir.path().join("colour24.BMP");
    write_bmp(&colour, 24);
    assert_colour8(&read_image(&colour).unwrap(), "24-bit BMP");
}

#[test]
fn pgm_and_ppm() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("grey8.pgm");
    let g8: Vec<u32> = grey8_buf().into_iter().map(u32::from).collect();
    write_pnm(&p, "P5", 255, &g8);
    assert_grey8(&read_image(&p).unwrap(), "PGM 8");
    let p = dir.path().join("grey16.pgm");
    let g16: Vec<u32> = grey16_buf().into_iter().map(u32::from).collect();
    write_pnm(&p, "P5", 65535, &g16);
    assert_grey16(&read_image(&p).unwrap(), "PGM 16");
    let p = dir.path().join("colour.ppm");
    let c8: Vec<u32> = rgb8_buf().into_iter().map(u32::from).collect();
    write_pnm(&p, "P6", 255, &c8);
    assert_colour8(&read_image(&p).unwrap(), "PPM");
}

#[test]
fn png_8_and_16_bits_grey_and_colour() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("grey8.png");
    save(&p, &grey8_buf(), image::ExtendedColorType::L8);
    assert_grey8(&read_image(&p).unwrap(), "PNG 8");
    let p = dir.path().join("grey16.png");
    save(&p, &u16_bytes(&grey16_buf()), image::ExtendedColorType::L16);
    assert_grey16(&read_image(&p).unwrap(), "PNG 16");
    let p = dir.path().join("rgb8.png");
    save(&p, &rgb8_buf(), image::ExtendedColorType::Rgb8);
    assert_colour8(&read_image(&p).unwrap(), "PNG RGB 8");
    let p = dir.path().join("rgb16.png");
    save(
        &p,
        &u16_bytes(&rgb16_buf()),
        image::ExtendedColorType::Rgb16,
    );
    assert_colour16(&read_image(&p).unwrap(), "PNG RGB 16");
}

#[test]
fn tiff_8_and_16_bits() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("grey8.tif");
    save(&p, &grey8_buf(), image::ExtendedColorType::L8);
    assert_grey8(&read_image(&p).unwrap(), "TIFF 8");
    let p = dir.path().join("grey16.tiff");
    save(&p, &u16_bytes(&grey16_buf()), image::ExtendedColorType::L16);
    assert_grey16(&read_image(&p).unwrap(), "TIFF 16");
    let p = dir.path().join("rgb16.tiff");
    save(
        &p,
        &u16_bytes(&rgb16_buf()),
        image::ExtendedColorType::Rgb16,
    );
    assert_colour16(&read_image(&p).unwrap(), "TIFF RGB 16");
}

/// JPEG is lossy: flat 8x8 blocks (one DCT block each, only the DC term) at quality 100 come
/// back within one grey level.
#[test]
fn jpeg_flat_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("blocks.jpg");
    let block = |x: usize, y: usize| (40 + 100 * (x / 8) + 30 * (y / 8)) as u8;
    let buf: Vec<u8> = (0..H)
        .flat_map(|y| (0..W).map(move |x| block(x, y)))
        .collect();
    let mut out = std::fs::File::create(&p).unwrap();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 100)
        .encode(&buf, W as u32, H as u32, image::ExtendedColorType::L8)
        .unwrap();
    drop(out);
    let GreyImage::U8(f) = read_image(&p).unwrap() else {
        panic!("grey JPEG is 8-bit");
    };
    for y in 0..H {
        for x in 0..W {
            let (got, want) = (f.get(x, y).unwrap(), block(x, y));
            assert!(got.abs_diff(want) <= 1, "({x}, {y}): {got} vs {want}");
        }
    }
}

/// The calibration detector's 8-bit view: 16-bit files are scaled by round(v / 257).
#[test]
fn read_grey8_scales_sixteen_bits() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("grey16.png");
    save(&p, &u16_bytes(&grey16_buf()), image::ExtendedColorType::L16);
    let f = read_grey8(&p).unwrap();
    for (got, v) in f.data().iter().zip(grey16_buf()) {
        let want = (f64::from(v) / 257.0).round();
        assert_eq!(f64::from(*got), want, "{v}");
    }
}

/// A capture of BMP frames (SLStudio's format) loads as a `CaptureSet`, and a mix of 8- and
/// 16-bit frames is widened to 16 bits.
#[test]
fn capture_sets_of_bmp_and_mixed_depths() {
    let dir = tempfile::tempdir().unwrap();
    write_bmp(&dir.path().join("0.bmp"), 8);
    write_pnm(
        &dir.path().join("1.pgm"),
        "P5",
        65535,
        &grey16_buf().into_iter().map(u32::from).collect::<Vec<_>>(),
    );
    let manifest = r#"{
        "projector": {"width": 2, "height": 8},
        "blocks": [{"codec": "gray", "axis": "column", "bits": 1, "frames": ["0.bmp", "1.pgm"]}]
    }"#;
    let path = dir.path().join("manifest.json");
    std::fs::write(&path, manifest).unwrap();
    let capture = CaptureSet::load(&path).unwrap();
    let Frames::U16(frames) = &capture.frames else {
        panic!("mixed depths widen to 16 bits");
    };
    let widened: Vec<u16> = grey8_buf()
        .into_iter()
        .map(|v| u16::from(v) * 257)
        .collect();
    assert_eq!(frames[0].data(), widened.as_slice());
    assert_eq!(frames[1].data(), grey16_buf().as_slice());
}

/// Content decides, not the name: a BMP named `.png` reads; a truncated or foreign file is an
/// error naming it.
#[test]
fn misnamed_and_broken_files() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("really_a_bmp.png");
    write_bmp(&p, 8);
    assert_grey8(&read_image(&p).unwrap(), "BMP named .png");
    let broken: PathBuf = dir.path().join("broken.bmp");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&broken, &bytes[..100]).unwrap();
    let e = read_image(&broken).unwrap_err();
    assert!(matches!(e, CodecError::Image { .. }), "{e}");
    assert!(e.to_string().contains("broken.bmp"), "{e}");
    let text = dir.path().join("notes.tif");
    std::fs::write(&text, "not an image").unwrap();
    let e = read_image(&text).unwrap_err();
    assert!(e.to_string().contains("notes.tif"), "{e}");
    let missing = dir.path().join("missing.pgm");
    let e = read_image(&missing).unwrap_err();
    assert!(e.to_string().contains("missing.pgm"), "{e}");
}

#[test]
fn every_listed_extension_is_an_image_file() {
    for ext in IMAGE_EXTENSIONS {
        assert!(is_image_file(Path::new(&format!("f.{ext}"))), "{ext}");
        assert!(
            is_image_file(Path::new(&format!("f.{}", ext.to_uppercase()))),
            "{ext}"
        );
    }
}

/// Files written by another program: OpenCV 5.0's `cv2.imwrite` (palette BMP, 24-bit BMP,
/// binary PGM 8/16 and PPM, PNG 8/16 grey and colour, LZW-compressed TIFF 8/16 grey and
/// colour, JPEG), made by `benches/peers/opencv_image_files.py` from the pixel formulas above.
/// Grey files read back exactly; colour files give exactly OpenCV's own
/// `cvtColor(COLOR_BGR2GRAY)` of them (`expected_grey.txt`, written by the same script).
#[test]
fn files_written_by_opencv() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/opencv_images");
    for name in ["grey8.bmp", "grey8.pgm", "grey8.png", "grey8.tif"] {
        assert_grey8(&read_image(&dir.join(name)).unwrap(), name);
    }
    for name in ["grey16.pgm", "grey16.png", "grey16.tif"] {
        assert_grey16(&read_image(&dir.join(name)).unwrap(), name);
    }
    let expected = std::fs::read_to_string(dir.join("expected_grey.txt")).unwrap();
    let mut checked = 0;
    for line in expected.lines().filter(|l| !l.starts_with('#')) {
        let mut words = line.split_whitespace();
        let name = words.next().unwrap();
        let want: Vec<u16> = words.map(|w| w.parse().unwrap()).collect();
        let img = read_image(&dir.join(name)).unwrap();
        assert_eq!(img.bit_depth(), if name.contains("16") { 16 } else { 8 });
        let got: Vec<u16> = img.into_u16().data().to_vec();
        let want: Vec<u16> = if name.contains("16") {
            want
        } else {
            want.into_iter().map(|v| v * 257).collect()
        };
        assert_eq!(got, want, "{name}");
        checked += 1;
    }
    assert_eq!(checked, 6, "colour files listed in expected_grey.txt");
    // Quality 100, flat 8x8 blocks: within one level, as for the image crate's JPEG above.
    let GreyImage::U8(f) = read_image(&dir.join("blocks.jpg")).unwrap() else {
        panic!("grey JPEG is 8-bit");
    };
    for y in 0..H {
        for x in 0..W {
            let want = (40 + 100 * (x / 8) + 30 * (y / 8)) as u8;
            let got = f.get(x, y).unwrap();
            assert!(got.abs_diff(want) <= 1, "({x}, {y}): {got} vs {want}");
        }
    }
}

/// A manifest naming `.png` frames reads the same frames saved as `.bmp` (a capture program's
/// format, the manifest written by `slscan patterns`); a frame missing under every extension
/// is still an error naming it.
#[test]
fn manifest_frames_found_under_another_extension() {
    let dir = tempfile::tempdir().unwrap();
    write_bmp(&dir.path().join("000.bmp"), 8);
    write_pnm(
        &dir.path().join("001.PGM"),
        "P5",
        255,
        &grey8_buf().into_iter().map(u32::from).collect::<Vec<_>>(),
    );
    let manifest = r#"{
        "projector": {"width": 2, "height": 8},
        "blocks": [{"codec": "gray", "axis": "column", "bits": 1, "frames": ["000.png", "001.png"]}]
    }"#;
    std::fs::write(dir.path().join("manifest.json"), manifest).unwrap();
    let capture = CaptureSet::load(dir.path()).unwrap();
    assert!(capture.frame_names[0].ends_with("000.bmp"));
    assert!(capture.frame_names[1].ends_with("001.PGM"));
    let Frames::U8(frames) = &capture.frames else {
        panic!("8-bit frames stay 8-bit");
    };
    assert_eq!(frames[1].data(), grey8_buf().as_slice());
    std::fs::remove_file(dir.path().join("001.PGM")).unwrap();
    let e = CaptureSet::load(dir.path()).unwrap_err();
    assert!(
        matches!(e, CodecError::MissingFrame { index: 1, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("001.png"), "{e}");
}
