//! OpenCV's `structured_light::GrayCodePattern` (the code of kamino410/procam-calibration and of
//! many OpenCV capture programs) described by a manifest alone, and decoded as OpenCV decodes it.
//!
//! `tests/data/opencv_graycode/` holds the patterns OpenCV 5.0 generates for a 40x24 projector,
//! the manifest that describes them (`"centered": false`), and OpenCV's own reading of them
//! (`GrayCodePattern::getProjPixel` with the patterns as the captured images), all written by
//! `benches/peers/opencv_graycode_patterns.py`. The ground truth is OpenCV's, not ours.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use sl_codec::{CaptureSet, CorrespondenceMap, DecodeConfig, Manifest, decode};

fn data() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/opencv_graycode")
}

/// OpenCV's `[column, row]` per pixel.
fn opencv_decoded() -> Vec<Vec<[f32; 2]>> {
    let text = std::fs::read_to_string(data().join("opencv_decoded.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["projector_pixel"]
        .as_array()
        .unwrap()
        .iter()
        .map(|row| {
            row.as_array()
                .unwrap()
                .iter()
                .map(|p| {
                    let p = p.as_array().expect("OpenCV decoded every pixel");
                    [p[0].as_f64().unwrap() as f32, p[1].as_f64().unwrap() as f32]
                })
                .collect()
        })
        .collect()
}

fn decode_with(manifest_text: &str) -> CorrespondenceMap {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("manifest.json");
    std::fs::write(&path, manifest_text).unwrap();
    let set = CaptureSet::load_with_frames_dir(&path, Some(&data())).unwrap();
    decode(&set, &DecodeConfig::default()).unwrap()
}

#[test]
fn opencv_gray_code_patterns_decode_to_opencvs_projector_pixels() {
    let text = std::fs::read_to_string(data().join("manifest.json")).unwrap();
    let manifest = Manifest::from_json_str(&text, &data().join("manifest.json")).unwrap();
    assert_eq!(
        (manifest.projector.width, manifest.projector.height),
        (40, 24)
    );
    let map = decode_with(&text);
    let truth = opencv_decoded();
    assert_eq!((map.width, map.height), (40, 24));
    for (y, row) in truth.iter().enumerate() {
        for (x, [c, r]) in row.iter().enumerate() {
            let i = y * map.width + x;
            assert_eq!((map.col[i], map.row[i]), (*c, *r), "pixel ({x}, {y})");
        }
    }
}

/// The key is what makes the difference: read with sl-codec's default, centred code, the same
/// patterns land `(2^6 − 40) / 2 = 12` columns and `(2^5 − 24) / 2 = 4` rows off OpenCV's
/// pixels (docs/capture-format.md's `origin = −0.5 − floor((2^bits − extent) / 2)`); the
/// pixels that would fall before the projector's first column or row are not decoded.
#[test]
fn without_centered_false_the_code_is_read_shifted() {
    let text = std::fs::read_to_string(data().join("manifest.json"))
        .unwrap()
        .replace("\"centered\": false", "\"centered\": true");
    let map = decode_with(&text);
    let truth = opencv_decoded();
    for (y, row) in truth.iter().enumerate() {
        for (x, [c, r]) in row.iter().enumerate() {
            let i = y * map.width + x;
            let (col, row) = (map.col[i], map.row[i]);
            if *c >= 12.0 {
                assert_eq!(col, c - 12.0, "column at ({x}, {y})");
            } else {
                assert!(col.is_nan(), "column {col} at ({x}, {y})");
            }
            if *r >= 4.0 {
                assert_eq!(row, r - 4.0, "row at ({x}, {y})");
            } else {
                assert!(row.is_nan(), "row {row} at ({x}, {y})");
            }
        }
    }
}
