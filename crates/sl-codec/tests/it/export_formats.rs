//! The float maps must be readable by numpy and OpenCV. This test writes them; when
//! `SL_CHECK_PYTHON` names a Python with numpy, tifffile and cv2 (the peers venv), it also reads
//! them back there and compares, otherwise it says it skips that part.
// Helpers outside #[test] functions unwrap too: a panic there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sl_codec::{CorrespondenceMap, InvalidReason, MapFormat, write_outputs};

#[test]
fn maps_round_trip_through_numpy_and_opencv() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = CorrespondenceMap::new(5, 3);
    for (i, c) in m.col.iter_mut().enumerate() {
        *c = i as f32 * 1.25 - 3.0;
    }
    m.row[7] = 1e6;
    m.quality.iter_mut().for_each(|q| *q = 42.5);
    m.invalid[2] = InvalidReason::Saturated;
    write_outputs(&m, dir.path(), MapFormat::Tiff, None).unwrap();
    write_outputs(&m, &dir.path().join("npy"), MapFormat::Npy, None).unwrap();
    let Some(python) = std::env::var_os("SL_CHECK_PYTHON") else {
        eprintln!("SL_CHECK_PYTHON not set: skipping the numpy/OpenCV read-back");
        return;
    };
    let script = r#"
import sys, numpy as np, tifffile, cv2
d = sys.argv[1]
col = np.arange(15, dtype=np.float32).reshape(3, 5) * 1.25 - 3.0
for name, read in [("tifffile", lambda p: tifffile.imread(p)),
                   ("cv2", lambda p: cv2.imread(p, cv2.IMREAD_UNCHANGED))]:
    a = read(d + "/col.tiff")
    assert a.dtype == np.float32 and a.shape == (3, 5), (name, a.dtype, a.shape)
    assert np.array_equal(a, col), (name, a)
    r = read(d + "/row.tiff")
    assert r[1, 2] == 1e6 and np.isnan(r[0, 0]), name
n = np.load(d + "/npy/col.npy")
assert n.dtype == np.float32 and np.array_equal(n, col)
labels = cv2.imread(d + "/invalid.png", cv2.IMREAD_UNCHANGED)
assert labels.dtype == np.uint8 and labels[0, 2] == 4 and labels[0, 0] == 0
print("ok")
"#;
    let out = std::process::Command::new(python)
        .arg("-c")
        .arg(script)
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "python check failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
