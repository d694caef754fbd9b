//! `reconstruct_binocular_capture` on a real two-camera capture: `binocular_sdk`
//! (`SL_DATA_EXTRA`; 2048x1536 cameras ~300 mm apart, a 4-step phase shift of 32 periods and a
//! 6-frame complementary Gray code thresholded at the fringe mean). There is no reference
//! cloud: coverage, the depth range of the scene and the smoothness of the disparity are what
//! can be checked.

use std::path::Path;

use sl_scan::reconstruct_binocular_capture;
use sl_tri::BinocularConfig;

/// The capture's manifest for one camera. The fringes' phase convention (shift −1, offset π)
/// is the one that leaves the fewest period jumps in the decoded columns of both cameras
/// (1,765 and 1,294 neighbours more than 20 px apart, against 50,000–120,000 for the other
/// three quarter-turn offsets and the other sign); a binocular match needs only that both
/// cameras decode the same column to the same code.
fn manifest(frames: &Path) -> String {
    let names: Vec<String> = (0..10).map(|k| format!("\"{k}.bmp\"")).collect();
    format!(
        r#"{{"format": "sl-capture", "version": 1,
  "description": "binocular_sdk phaseGray (tests only)",
  "projector": {{"width": 1920, "height": 1080}}, "bit_depth": 8,
  "frames_dir": "{}",
  "blocks": [{{"codec": "hybrid", "axis": "column", "steps": 4, "periods": 32,
    "phase_offset": 3.141592653589793, "shift_sign": -1,
    "gray": {{"bits": 6, "reference": "phase_mean", "binary": false, "stripe_width": 30,
      "origin": -0.5}},
    "frames": [{}]}}]}}"#,
        frames.display(),
        names.join(", ")
    )
}

#[test]
fn the_binocular_sdk_pair_reconstructs() {
    let Some(extra) = std::env::var_os("SL_DATA_EXTRA") else {
        eprintln!("SL_DATA_EXTRA not set: skipping binocular_sdk");
        return;
    };
    let data = Path::new(&extra).join("binocular_sdk");
    let tmp = tempfile::tempdir().unwrap();
    for side in ["L", "R"] {
        let dir = tmp.path().join(side);
        std::fs::create_dir_all(&dir).unwrap();
        let text = manifest(&data.join("phaseGray").join(side));
        std::fs::write(dir.join("manifest.json"), text).unwrap();
        // Each camera's frames show what the manifest says was projected: the frame checks
        // name none of them (a false alarm on a real capture would be one too many).
        let set = sl_codec::CaptureSet::load(&dir.join("manifest.json")).unwrap();
        let map = sl_codec::decode(&set, &sl_codec::DecodeConfig::default()).unwrap();
        let issues = sl_codec::check_frames(&set, &map);
        assert!(issues.is_empty(), "{side}: {issues:#?}");
    }
    let out = tmp.path().join("out");
    let r = reconstruct_binocular_capture(
        &tmp.path().join("L"),
        &tmp.path().join("R"),
        &data.join("cali/intrinsic.yml"),
        &BinocularConfig::default(),
        &out,
    )
    .unwrap();
    eprintln!(
        "binocular_sdk: {} points, decoded {:.3} / {:.3}, roughness {:.4} px, {:?}",
        r.points, r.decoded_fraction.0, r.decoded_fraction.1, r.roughness_px, r.counts
    );
    // Measured: 1.67 M points (53 % of the rectified pixels), 73 % / 65 % decoded.
    assert!(r.points > 1_400_000, "{} points", r.points);
    let (min, max) = r.bbox_mm.unwrap();
    // The scene stands 1.06–1.39 m from the left camera.
    assert!(
        min[2] > 1000.0 && max[2] < 1450.0,
        "depths {} .. {}",
        min[2],
        max[2]
    );
    // Measured 0.430 px: each camera's decoded columns carry ~0.1 projector px of noise, 0.14
    // camera px at this code gradient (0.73 projector px per camera px); the second difference
    // of a difference of two such maps has √12 times that spread, a median magnitude of ~0.33
    // px if the pixels' noise were independent. A regression guard: the plain OpenCV
    // rectify-and-match on the same decode (`benches/peers/binocular_rectify_match.py`) gives
    // 0.426 px over 0.80 M points.
    assert!(r.roughness_px < 0.6, "roughness {}", r.roughness_px);
    assert!(out.join("cloud.ply").is_file() && out.join("disparity.png").is_file());
}
