//! Capture sets on disk: patterns written by `PatternSequence::write` decode from their own
//! manifest (the projector seen by a camera of the same size), at 8 and 16 bits, in colour, and
//! every broken set is an error naming what is wrong.
// Helpers outside #[test] functions unwrap too: a panic there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use sl_codec::{
    Axis, BitDepth, CaptureSet, CodecError, DecodeConfig, Frames, GrayCodeSpec, HybridSpec,
    ImageSize, MANIFEST_FILE, Pattern, PatternSequence, decode,
};

fn sequence() -> PatternSequence {
    let p = ImageSize::new(200, 120);
    PatternSequence::new(p)
        .with(Pattern::Gray(GrayCodeSpec::per_pixel(
            Axis::Column,
            p,
            true,
        )))
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Row,
            p,
            4,
            6.0,
        )))
}

/// The projector's own images decode to the projector's pixel grid: columns exactly (Gray
/// code), rows to the phase precision of 8-bit fringes (0.5 level out of 127.5 is 0.004 rad,
/// 0.013 px on 20-px fringes; 0.02 px allows for the sum over 4 steps).
fn check_identity(dir: &Path) {
    let capture = CaptureSet::load(dir).unwrap();
    let map = decode(&capture, &DecodeConfig::default()).unwrap();
    assert_eq!((map.width, map.height), (200, 120));
    assert_eq!(map.valid_fraction(), 1.0);
    for y in 0..120 {
        for x in 0..200 {
            let c = map.get(x, y).unwrap();
            assert_eq!(c.col, x as f32, "({x}, {y})");
            assert!((c.row - y as f32).abs() < 0.02, "({x}, {y}): {}", c.row);
        }
    }
}

#[test]
fn patterns_decode_from_their_manifest_at_8_and_16_bits() {
    for depth in [BitDepth::Eight, BitDepth::Sixteen] {
        let dir = tempfile::tempdir().unwrap();
        let m = sequence().write(dir.path(), depth).unwrap();
        assert_eq!(m.frame_count(), 16 + 4 + 8);
        let capture = CaptureSet::load(&dir.path().join(MANIFEST_FILE)).unwrap();
        assert_eq!(capture.frames.bit_depth(), depth.bits());
        check_identity(dir.path());
    }
}

#[test]
fn colour_frames_are_converted_and_depths_unified() {
    let dir = tempfile::tempdir().unwrap();
    let m = sequence().write(dir.path(), BitDepth::Eight).unwrap();
    // Frame 0 as RGB (grey in all channels, so luma is exact), frame 1 as 16-bit grey.
    let f0 = dir.path().join(&m.blocks[0].frames[0]);
    let grey = image::open(&f0).unwrap().to_luma8();
    image::DynamicImage::ImageLuma8(grey)
        .to_rgb8()
        .save(&f0)
        .unwrap();
    let f1 = dir.path().join(&m.blocks[0].frames[1]);
    let grey = image::open(&f1).unwrap().to_luma16();
    grey.save(&f1).unwrap();
    let capture = CaptureSet::load(dir.path()).unwrap();
    assert!(matches!(capture.frames, Frames::U16(_)));
    check_identity(dir.path());
}

#[test]
fn broken_sets_name_the_fault() {
    let dir = tempfile::tempdir().unwrap();
    let m = sequence().write(dir.path(), BitDepth::Eight).unwrap();
    // A frame of another size.
    let victim = dir.path().join(&m.blocks[1].frames[2]);
    image::GrayImage::new(201, 120).save(&victim).unwrap();
    let e = CaptureSet::load(dir.path()).unwrap_err();
    assert!(matches!(e, CodecError::FrameSize { .. }), "{e}");
    assert!(
        e.to_string().contains(&m.blocks[1].frames[2]) && e.to_string().contains("201x120"),
        "{e}"
    );
    // A missing frame.
    std::fs::remove_file(&victim).unwrap();
    let e = CaptureSet::load(dir.path()).unwrap_err();
    assert!(
        matches!(
            e,
            CodecError::MissingFrame {
                block: 1,
                index: 2,
                ..
            }
        ),
        "{e}"
    );
    // A manifest with a frame too few.
    let mut m2 = m.clone();
    m2.blocks[0].frames.pop();
    let text = m2.to_json().to_string();
    std::fs::write(dir.path().join(MANIFEST_FILE), text).unwrap();
    let e = CaptureSet::load(dir.path()).unwrap_err();
    assert!(e.to_string().contains("blocks[0].frames"), "{e}");
    // Frames elsewhere: load_with_frames_dir.
    let other = tempfile::tempdir().unwrap();
    let m3 = sequence().write(other.path(), BitDepth::Eight).unwrap();
    m3.save(&dir.path().join(MANIFEST_FILE)).unwrap();
    let c = CaptureSet::load_with_frames_dir(&dir.path().join(MANIFEST_FILE), Some(other.path()))
        .unwrap();
    assert_eq!(c.frames.len(), 28);
}

/// A capture whose frames a capture program saved as BMP (SLStudio's format), 8-bit PGM,
/// 16-bit PGM or 16-bit TIFF decodes end to end, from a manifest naming them and from the
/// manifest `PatternSequence::write` made (naming `.png`) with only the converted frames left.
#[test]
fn captures_of_bmp_pgm_and_tiff_frames_decode() {
    for (depth, ext) in [
        (BitDepth::Eight, "bmp"),
        (BitDepth::Eight, "pgm"),
        (BitDepth::Sixteen, "pgm"),
        (BitDepth::Sixteen, "tif"),
    ] {
        for rename_in_manifest in [true, false] {
            let dir = tempfile::tempdir().unwrap();
            let mut m = sequence().write(dir.path(), depth).unwrap();
            for block in &mut m.blocks {
                for file in &mut block.frames {
                    let png = dir.path().join(&*file);
                    let other = png.with_extension(ext);
                    image::open(&png).unwrap().save(&other).unwrap();
                    std::fs::remove_file(&png).unwrap();
                    if rename_in_manifest {
                        *file = other.file_name().unwrap().to_string_lossy().into_owned();
                    }
                }
            }
            m.save(&dir.path().join(MANIFEST_FILE)).unwrap();
            let capture = CaptureSet::load(dir.path()).unwrap();
            assert_eq!(capture.frames.bit_depth(), depth.bits(), "{ext}");
            assert!(capture.frame_names[0].ends_with(ext), "{ext}");
            check_identity(dir.path());
        }
    }
}
