//! Detection on OpenCV's sample chessboard images (`$SL_DATA/chessboard`).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use sl_calib::{BoardSize, DetectorConfig, detect_checkerboard, load_grey};

fn data_dir() -> Option<std::path::PathBuf> {
    match std::env::var_os("SL_DATA") {
        Some(d) => Some(std::path::PathBuf::from(d).join("chessboard")),
        None => {
            eprintln!("SL_DATA not set: skipping the real chessboard tests");
            None
        }
    }
}

const NAMES: [&str; 13] = [
    "01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14",
];

#[test]
fn all_26_images_are_detected_in_board_order() {
    let Some(dir) = data_dir() else { return };
    let size = BoardSize::new(9, 6);
    for side in ["left", "right"] {
        for n in NAMES {
            let path = dir.join(format!("{side}{n}.jpg"));
            let img = load_grey(&path).unwrap();
            let found = detect_checkerboard(
                &img,
                size,
                &DetectorConfig::default(),
                &path.display().to_string(),
            );
            let found = found.unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(found.corners.len(), 54);
            eprintln!(
                "{side}{n}: first {:?} last {:?}",
                found.corners[0], found.corners[53]
            );
        }
    }
}
