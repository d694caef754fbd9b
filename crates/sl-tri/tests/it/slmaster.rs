//! A real column-only capture: SLMaster's three-frequency heterodyne set (`$SL_DATA/slmaster`,
//! see the data folder's `README.md`), decoded by sl-codec from the manifest kept in
//! `sl-codec/tests/data/slmaster/` and triangulated with every method.
//!
//! The capture comes without its calibration, so a nominal one of the same devices is used
//! (camera 1280x1024 with a 12 mm-class lens, `fx = 1750` px; projector 1920x1080, `fx = 2500`
//! px with a mild radial distortion; the projector 110 mm beside the camera, turned 5° towards
//! it). The points are then not metrically right, but they are a plausible surface at a
//! plausible depth, and the test checks what does not depend on the calibration's truth: the
//! one-axis methods work on real decoded maps (noise, holes, background), linear and optimal
//! meet ray–plane's exact column surface, midpoint is refused naming the rows, nothing is
//! empty. Skipped, with a note, when `SL_DATA` is not set.

// Test helpers (not `#[test]` functions) unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use approx::assert_abs_diff_eq;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use sl_codec::{Axis, CaptureSet, DecodeConfig, decode};
use sl_tri::{Method, TriConfig, TriError, Triangulator};

/// SLMaster's own tests invalidate pixels with a fringe modulation below 30 grey levels.
const SLMASTER_MIN_MODULATION: f32 = 30.0;

fn nominal_triangulator() -> Triangulator {
    let camera = CameraModel::new(
        Intrinsics::new(1750.0, 1750.0, 639.5, 511.5),
        Distortion::none(),
        ImageSize::new(1280, 1024),
    )
    .unwrap();
    let projector = CameraModel::new(
        Intrinsics::new(2500.0, 2500.0, 959.5, 539.5),
        Distortion::from_opencv(&[-0.04, 0.1, 0.0, 0.0, 0.0]).unwrap(),
        ImageSize::new(1920, 1080),
    )
    .unwrap();
    let t_cam_proj = Isometry3::from_parts(
        Translation3::new(110.0, 0.0, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -5f64.to_radians()),
    );
    Triangulator::from_models(&camera, &projector, &t_cam_proj).unwrap()
}

#[test]
fn slmaster_column_only_capture_triangulates_with_one_axis_methods() {
    let Some(root) = std::env::var_os("SL_DATA") else {
        eprintln!("SL_DATA not set: skipping the SLMaster triangulation test");
        return;
    };
    let frames = PathBuf::from(root).join("slmaster/three_frequency_heterodyne");
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../sl-codec/tests/data/slmaster/three_frequency_heterodyne.json");
    let capture = CaptureSet::load_with_frames_dir(&manifest, Some(&frames)).unwrap();
    let config = DecodeConfig {
        min_modulation: SLMASTER_MIN_MODULATION,
        ..DecodeConfig::default()
    };
    let map = decode(&capture, &config).unwrap();
    assert!(map.row.iter().all(|r| r.is_nan()), "columns only");
    let decoded = map.invalid.iter().filter(|r| r.is_valid()).count();

    let tri = nominal_triangulator();
    let options = |method| TriConfig {
        max_depth_jump: f64::INFINITY,
        ..TriConfig::with_method(method)
    };
    let reference = tri
        .triangulate(&map, &options(Method::RayPlane { axis: Axis::Column }))
        .unwrap();
    let n = reference.counts.valid;
    let mut depths: Vec<f64> = reference.cloud.positions().iter().map(|p| p.z).collect();
    depths.sort_by(f64::total_cmp);
    let median = depths[depths.len() / 2];
    eprintln!(
        "SLMaster heterodyne: {n} points of {decoded} decoded pixels, median depth {median:.0} mm"
    );
    assert!(n as f64 > 0.9 * decoded as f64, "{n} of {decoded}");
    assert!(
        (150.0..3000.0).contains(&median),
        "median depth {median} mm"
    );

    for method in [Method::Linear, Method::Optimal] {
        let result = tri.triangulate(&map, &options(method)).unwrap();
        assert_eq!(result.counts, reference.counts, "{}", method.name());
        for (a, b) in result.points.iter().zip(&reference.points) {
            if a.z.is_finite() {
                assert_abs_diff_eq!(a, b, epsilon = 1e-6);
            }
        }
    }
    let err = tri
        .triangulate(&map, &options(Method::Midpoint))
        .unwrap_err();
    assert!(
        matches!(
            err,
            TriError::MissingAxis {
                missing: Axis::Row,
                ..
            }
        ),
        "{err}"
    );
}
