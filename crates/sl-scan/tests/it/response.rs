//! The projector's response measured from a grey ramp on the virtual rig, against the rig's
//! true response; the ramp folder read back; what a user can get wrong with one.
// Test helpers may unwrap: a panic is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sl_codec::ToneCurve;
use sl_scan::{RAMP_FILE, capture_virtual_ramp, measure_ramp_folder, scaled_rig_config};
use sl_sim::ResponseShape;

/// A gamma of 2.2 and the measured-like curve, on the rig at a quarter resolution (its sensor
/// noise, 8-bit camera): the ramp of 33 levels gives the true curve back within a percent of
/// white, and the folder it wrote gives the same curve again.
#[test]
fn a_ramp_on_the_virtual_rig_measures_its_true_response() {
    for (shape, gamma) in [(ResponseShape::Power, 2.2), (ResponseShape::Measured, 1.0)] {
        let mut config = scaled_rig_config(4);
        config.render.illumination.gamma = gamma;
        config.render.illumination.response = shape;
        let truth = config.render.illumination.response_curve().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let m = capture_virtual_ramp(&config, dir.path(), 33).unwrap();
        let diff = m.curve.max_difference(&truth);
        eprintln!(
            "{shape:?}: {} pixels, contrast {:.3}, equivalent gamma {:.3} (truth {:.3}), largest difference {diff:.4}",
            m.pixels,
            m.contrast,
            m.curve.equivalent_gamma(),
            truth.equivalent_gamma()
        );
        // Linear interpolation between levels 1/32 apart bends a gamma-2.2 curve by 3e-4 and
        // the measured curve's toe (black crushed below 3 %) by about 1e-3; the sensor noise,
        // averaged over thousands of pixels, by less.
        assert!(diff < 0.01, "{shape:?}: {diff}");
        assert!(
            m.curve.max_difference(&ToneCurve::linear()) > 0.1,
            "{shape:?}"
        );
        assert!(dir.path().join(RAMP_FILE).is_file());
        let again = measure_ramp_folder(dir.path()).unwrap();
        assert_eq!(again.curve, m.curve);
    }
}

/// A ramp folder with a capture missing, a ramp.json of another format or none at all is
/// named, file and all.
#[test]
fn a_broken_ramp_folder_is_named() {
    let mut config = scaled_rig_config(8);
    config.render.illumination.gamma = 2.2;
    let dir = tempfile::tempdir().unwrap();
    capture_virtual_ramp(&config, dir.path(), 5).unwrap();
    std::fs::remove_file(dir.path().join("level_02.png")).unwrap();
    let e = measure_ramp_folder(dir.path()).unwrap_err().to_string();
    assert!(e.contains("level_02.png") && e.contains("missing"), "{e}");
    let ramp = dir.path().join(RAMP_FILE);
    let text = std::fs::read_to_string(&ramp).unwrap();
    // Levels out of order: the measurement's error, with the folder named.
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["files"][2] = serde_json::json!("level_01.png");
    value["levels"][1] = serde_json::json!(0.9);
    std::fs::write(&ramp, value.to_string()).unwrap();
    let e = measure_ramp_folder(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains(&dir.path().display().to_string()) && e.contains("increase"),
        "{e}"
    );
    std::fs::write(&ramp, &text).unwrap();
    std::fs::write(&ramp, text.replace("sl-response-ramp", "something-else")).unwrap();
    let e = measure_ramp_folder(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("ramp.json") && e.contains("something-else"),
        "{e}"
    );
    std::fs::remove_file(&ramp).unwrap();
    let e = measure_ramp_folder(dir.path()).unwrap_err().to_string();
    assert!(e.contains("ramp.json"), "{e}");
}
