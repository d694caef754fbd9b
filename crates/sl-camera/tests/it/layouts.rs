//! The calibration layouts of other systems (scan3d-capture, SLMaster, OpenCV's stereo
//! sample, SLStudio, OpenCV's calibration sample) and ours: files written as each peer writes
//! them (`tests/data/layouts/`, by `tests/data/gen_peer_layouts.py` with `cv2.FileStorage`) read
//! with the peers' frame convention, checked against `cv2.projectPoints` with the file's `R`,
//! `T`; every layout round-trips; detection, missing sizes and impossible writes are named
//! errors. With `SL_DATA` set, real files of these layouts found there must load.
// Test helpers outside #[test] functions may unwrap too: a panic is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use sl_camera::{
    Calibration, CalibrationLayout, CameraModel, Distortion, ImageSize, Intrinsics, LoadConfig,
    Metadata, RmsErrors, TurntableAxis,
};

fn data(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/layouts")
        .join(path)
}

fn truth() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(data("truth.json")).unwrap()).unwrap()
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn size(v: &serde_json::Value) -> ImageSize {
    let s = floats(v);
    ImageSize::new(s[0] as u32, s[1] as u32)
}

/// The sizes the generator's rig has and the files (but SLMaster's `S`) do not store.
fn sizes(truth: &serde_json::Value) -> LoadConfig {
    LoadConfig {
        camera_size: Some(size(&truth["camera_size"])),
        projector_size: Some(size(&truth["projector_size"])),
        ..LoadConfig::default()
    }
}

/// The rig of `truth.json`: intrinsics and distortion exactly (doubles written with 17
/// digits), the projector centre in camera coordinates, and the projector pixels of points
/// given in camera coordinates as `cv2.projectPoints(X, rvec(R), T, K_proj, D_proj)` computes
/// them, i.e. as the peers use their `R`, `T` (0.1 µpx: OpenCV's and our distortion agree to
/// 1e-12 px, the rotation went through Rodrigues and 17-digit text).
fn check_rig(c: &Calibration, truth: &serde_json::Value, distortion: &str, what: &str) {
    let k = |v: &serde_json::Value| {
        let m: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(floats).collect();
        Intrinsics::new(m[0][0], m[1][1], m[0][2], m[1][2])
    };
    assert_eq!(c.camera.intrinsics, k(&truth["camera_K"]), "{what}");
    let proj = c.projector.as_ref().unwrap();
    assert_eq!(proj.intrinsics, k(&truth["projector_K"]), "{what}");
    assert_eq!(
        c.camera.distortion.to_opencv_vec(),
        floats(&truth[format!("camera_{distortion}")]),
        "{what}"
    );
    assert_eq!(
        proj.distortion.to_opencv_vec(),
        floats(&truth[format!("projector_{distortion}")]),
        "{what}"
    );
    assert_eq!(c.camera.size, size(&truth["camera_size"]), "{what}");
    assert_eq!(proj.size, size(&truth["projector_size"]), "{what}");
    let t_cam_proj = c.t_cam_proj.unwrap();
    let centre = t_cam_proj * Point3::origin();
    let want = Vector3::from_column_slice(&floats(&truth["projector_centre_mm"]));
    assert_relative_eq!(centre.coords, want, epsilon = 1e-9);
    let points = truth["points_cam_mm"].as_array().unwrap();
    let pixels = truth[format!("projector_px_{distortion}")]
        .as_array()
        .unwrap();
    for (p, px) in points.iter().zip(pixels) {
        let p_cam = Point3::from_slice(&floats(p));
        let p_proj = t_cam_proj.inverse() * p_cam;
        let got = proj.project(&p_proj).unwrap();
        let px = floats(px);
        assert_relative_eq!(got, Point2::new(px[0], px[1]), epsilon = 1e-7);
    }
}

#[test]
fn scan3d_capture_calibration_yml() {
    let truth = truth();
    let path = data("scan3d_capture/calibration.yml");
    let loaded = Calibration::load_with(&path, &sizes(&truth)).unwrap();
    assert_eq!(loaded.layout, CalibrationLayout::Scan3dCapture);
    assert_eq!(loaded.files, vec![path.clone()]);
    check_rig(&loaded.calibration, &truth, "d5", "scan3d-capture");
    let rms = loaded.calibration.rms;
    assert_eq!(
        (rms.camera, rms.projector, rms.stereo),
        (Some(0.183), Some(0.241), Some(0.297))
    );
    // Without the sizes, which the layout does not store, the error says how to give them.
    let e = Calibration::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("calibration.yml") && e.contains("camera_width") && e.contains("--camera-size"),
        "{e}"
    );
    let only_camera = LoadConfig {
        camera_size: Some(ImageSize::new(1280, 1024)),
        ..LoadConfig::default()
    };
    let e = Calibration::load_with(&path, &only_camera)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--projector-size"), "{e}");
}

#[test]
fn slmaster_cali_info_yml() {
    let truth = truth();
    let path = data("slmaster/caliInfo.yml");
    // S holds the camera size; the projector's is not in the file.
    let options = LoadConfig {
        projector_size: Some(size(&truth["projector_size"])),
        ..LoadConfig::default()
    };
    let loaded = Calibration::load_with(&path, &options).unwrap();
    assert_eq!(loaded.layout, CalibrationLayout::SlMaster);
    check_rig(&loaded.calibration, &truth, "d5", "SLMaster");
    assert_eq!(loaded.calibration.rms, RmsErrors::default());
    // A camera size in the options that contradicts S is an error naming S.
    let wrong = LoadConfig {
        camera_size: Some(ImageSize::new(640, 480)),
        ..options
    };
    let e = Calibration::load_with(&path, &wrong)
        .unwrap_err()
        .to_string();
    assert!(e.contains("key `S`") && e.contains("1280x1024"), "{e}");
}

#[test]
fn opencv_stereo_sample_intrinsics_and_extrinsics() {
    let truth = truth();
    let intrinsics = data("opencv_stereo/intrinsics.yml");
    let extrinsics = data("opencv_stereo/extrinsics.yml");
    for named in [&intrinsics, &extrinsics] {
        let loaded = Calibration::load_with(named, &sizes(&truth)).unwrap();
        assert_eq!(loaded.layout, CalibrationLayout::OpenCvStereo);
        assert_eq!(loaded.files.len(), 2, "{:?}", loaded.files);
        assert_eq!(&loaded.files[0], named);
        check_rig(&loaded.calibration, &truth, "d8", "OpenCV stereo sample");
    }
    // The intrinsics alone: camera and projector, no extrinsics.
    let dir = tempfile::tempdir().unwrap();
    let alone = dir.path().join("intrinsics.yml");
    std::fs::copy(&intrinsics, &alone).unwrap();
    let loaded = Calibration::load_with(&alone, &sizes(&truth)).unwrap();
    assert!(loaded.calibration.t_cam_proj.is_none());
    assert_eq!(loaded.files, vec![alone]);
    // The extrinsics alone: an error naming where the intrinsics were looked for.
    let lone = dir.path().join("rig_extrinsics.yml");
    std::fs::copy(&extrinsics, &lone).unwrap();
    let e = Calibration::load_with(&lone, &sizes(&truth))
        .unwrap_err()
        .to_string();
    assert!(e.contains("rig_intrinsics.yml") && e.contains("M1"), "{e}");
}

#[test]
fn layouts_are_detected_by_their_keys() {
    let truth = truth();
    for (file, layout) in [
        (
            "scan3d_capture/calibration.yml",
            CalibrationLayout::Scan3dCapture,
        ),
        ("slmaster/caliInfo.yml", CalibrationLayout::SlMaster),
        (
            "opencv_stereo/intrinsics.yml",
            CalibrationLayout::OpenCvStereo,
        ),
        (
            "opencv_stereo/extrinsics.yml",
            CalibrationLayout::OpenCvStereo,
        ),
    ] {
        let loaded = Calibration::load_with(data(file), &sizes(&truth)).unwrap();
        assert_eq!(loaded.layout, layout, "{file}");
    }
    let fixtures = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    for (file, layout) in [
        ("slstudio_calibration.xml", CalibrationLayout::SlStudio),
        ("slstudio_calibration.yml", CalibrationLayout::SlStudio),
        (
            "opencv_calibration_sample.yml",
            CalibrationLayout::OpenCvCamera,
        ),
    ] {
        let loaded = Calibration::load_with(fixtures.join(file), &LoadConfig::default()).unwrap();
        assert_eq!(loaded.layout, layout, "{file}");
    }
    let e = Calibration::from_opencv_yaml("%YAML:1.0\nfoo: 1\n", "odd.yml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("odd.yml") && e.contains("no known layout"),
        "{e}"
    );
    for layout in CalibrationLayout::ALL {
        assert_eq!(layout.name().parse::<CalibrationLayout>().unwrap(), layout);
    }
    let e = "scan3d"
        .parse::<CalibrationLayout>()
        .unwrap_err()
        .to_string();
    assert!(e.contains("scan3d-capture"), "{e}");
}

fn full_calibration() -> Calibration {
    let camera = CameraModel::new(
        Intrinsics {
            fx: 1440.4,
            fy: 1437.1,
            cx: 667.8,
            cy: 354.2,
            skew: 0.25,
        },
        Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1]).unwrap(),
        ImageSize::new(1280, 720),
    )
    .unwrap();
    let projector = CameraModel::new(
        Intrinsics::new(2210.0, 2208.5, 955.0, 1102.0),
        Distortion::from_opencv(&[0.041, -0.162, 0.0006, -0.0011, 0.21, 0.01, -0.02, 0.003])
            .unwrap(),
        ImageSize::new(1920, 1080),
    )
    .unwrap();
    let mut turntable = TurntableAxis::new(
        Vector3::new(0.01, -0.999, 0.02),
        Point3::new(12.5, 40.0, 610.0),
    )
    .unwrap();
    turntable.angle_offset_deg = 3.25;
    Calibration {
        camera,
        projector: Some(projector),
        t_cam_proj: Some(Isometry3::from_parts(
            Translation3::new(-160.2, 8.7, 25.1),
            UnitQuaternion::from_scaled_axis(Vector3::new(-0.03, 0.31, 0.01)),
        )),
        turntable: Some(turntable),
        projector_response: None,
        rms: RmsErrors {
            camera: Some(0.187),
            projector: Some(0.241),
            stereo: Some(0.27),
        },
        metadata: Metadata {
            tool_version: "sl-camera test".into(),
            created: Some("2024-06-11T10:21:07+02:00".into()),
            notes: "rig A\nsecond line".into(),
        },
    }
}

fn assert_same(a: &Calibration, b: &Calibration, what: &str) {
    assert_eq!(a.camera, b.camera, "{what}");
    assert_eq!(a.projector, b.projector, "{what}");
    assert_eq!(a.turntable, b.turntable, "{what}");
    assert_eq!(a.rms, b.rms, "{what}");
    assert_eq!(a.metadata, b.metadata, "{what}");
    match (&a.t_cam_proj, &b.t_cam_proj) {
        // Rotation matrix ↔ quaternion conversions lose a few ulps.
        (Some(x), Some(y)) => {
            assert_relative_eq!(x.to_homogeneous(), y.to_homogeneous(), epsilon = 1e-12);
        }
        (None, None) => {}
        _ => panic!("{what}: extrinsics differ"),
    }
}

/// Every layout writes what it reads back, in YAML and XML, with nothing lost (the keys a
/// layout lacks go under extra keys), and the written file is detected as its layout.
#[test]
fn every_layout_round_trips() {
    let full = full_calibration();
    let camera_only = Calibration::new(full.camera);
    let dir = tempfile::tempdir().unwrap();
    for layout in CalibrationLayout::ALL {
        let calib = if layout == CalibrationLayout::OpenCvCamera {
            &camera_only
        } else {
            &full
        };
        let exts: &[&str] = if layout == CalibrationLayout::Json {
            &["json"]
        } else {
            &["yml", "xml"]
        };
        for ext in exts {
            let path = dir.path().join(format!("{layout}_intrinsics.{ext}"));
            let files = calib.save_as(&path, layout).unwrap();
            let want_files = if layout == CalibrationLayout::OpenCvStereo {
                2
            } else {
                1
            };
            assert_eq!(files.len(), want_files, "{layout}: {files:?}");
            let loaded = Calibration::load_with(&path, &LoadConfig::default()).unwrap();
            assert_eq!(loaded.layout, layout, "{layout} .{ext}");
            assert_same(calib, &loaded.calibration, &format!("{layout} .{ext}"));
        }
    }
    // SLMaster and SLStudio also hold a camera alone.
    for layout in [CalibrationLayout::SlMaster, CalibrationLayout::SlStudio] {
        let path = dir.path().join(format!("alone_{layout}.yml"));
        camera_only.save_as(&path, layout).unwrap();
        let loaded = Calibration::load_with(&path, &LoadConfig::default()).unwrap();
        assert_eq!(loaded.layout, layout);
        assert_same(&camera_only, &loaded.calibration, layout.name());
    }
}

/// The files we write in a peer's layout have the peer's keys and OpenCV's YAML shape, so the
/// peer's `fs["key"] >> mat` reads them.
#[test]
fn written_files_have_the_peers_keys() {
    let full = full_calibration();
    let dir = tempfile::tempdir().unwrap();
    let text = |layout: CalibrationLayout, name: &str| {
        let path = dir.path().join(name);
        let files = full.save_as(&path, layout).unwrap();
        files
            .iter()
            .map(|f| std::fs::read_to_string(f).unwrap())
            .collect::<Vec<_>>()
    };
    let scan3d = text(CalibrationLayout::Scan3dCapture, "calibration.yml");
    assert!(scan3d[0].starts_with("%YAML:1.0\n"));
    for key in ["cam_K", "cam_kc", "proj_K", "proj_kc", "R", "T"] {
        assert!(
            scan3d[0].contains(&format!("\n{key}: !!opencv-matrix\n")),
            "{key}"
        );
    }
    for key in [
        "cam_error: 0.187",
        "proj_error: 0.241",
        "stereo_error: 0.27",
    ] {
        assert!(scan3d[0].contains(key), "{key}");
    }
    let slmaster = text(CalibrationLayout::SlMaster, "caliInfo.yml");
    for key in ["M1", "D1", "S", "M4", "D4", "Rlp", "Tlp"] {
        assert!(
            slmaster[0].contains(&format!("\n{key}: !!opencv-matrix\n")),
            "{key}"
        );
    }
    assert!(slmaster[0].contains("rows: 2\n   cols: 1\n   dt: d\n   data: [ 1280.0, 720.0 ]"));
    let stereo = text(CalibrationLayout::OpenCvStereo, "intrinsics.yml");
    for key in ["M1", "D1", "M2", "D2"] {
        assert!(
            stereo[0].contains(&format!("\n{key}: !!opencv-matrix\n")),
            "{key}"
        );
    }
    assert!(stereo[1].contains("\nR: !!opencv-matrix\n") && stereo[1].contains("\nT: !!"));
    assert!(dir.path().join("extrinsics.yml").is_file());
}

#[test]
fn layouts_refuse_what_they_cannot_hold() {
    let dir = tempfile::tempdir().unwrap();
    let camera_only = Calibration::new(full_calibration().camera);
    for layout in [
        CalibrationLayout::Scan3dCapture,
        CalibrationLayout::OpenCvStereo,
    ] {
        let e = camera_only
            .save_as(dir.path().join("c_intrinsics.yml"), layout)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no projector"), "{layout}: {e}");
    }
    let e = full_calibration()
        .save_as(dir.path().join("c.yml"), CalibrationLayout::OpenCvCamera)
        .unwrap_err()
        .to_string();
    assert!(e.contains("camera alone"), "{e}");
    let e = full_calibration()
        .save_as(dir.path().join("c.yml"), CalibrationLayout::Json)
        .unwrap_err()
        .to_string();
    assert!(e.contains(".json"), "{e}");
    let e = full_calibration()
        .save_as(dir.path().join("c.json"), CalibrationLayout::SlMaster)
        .unwrap_err()
        .to_string();
    assert!(e.contains(".yml"), "{e}");
    assert!(!dir.path().join("c.yml").exists() && !dir.path().join("c.json").exists());
}

/// Real calibration files of the other systems under `SL_DATA` (any folder), by the names the
/// systems give them, must load (with the sizes they lack: the scan3d-capture and stereo
/// sample files there must come with a `sizes.json` `{"camera": [w, h], "projector": [w, h]}`
/// beside them, or are reported as needing one).
#[test]
fn real_files_under_sl_data() {
    let Some(root) = std::env::var_os("SL_DATA") else {
        eprintln!("SL_DATA not set: skipping the real calibration files");
        return;
    };
    let mut found = Vec::new();
    walk(Path::new(&root), &mut found);
    if found.is_empty() {
        eprintln!(
            "SL_DATA={}: no calibration.yml, calibration.xml, caliInfo.yml or intrinsics.yml \
             there; nothing to check",
            Path::new(&root).display()
        );
    }
    for path in found {
        let mut options = LoadConfig::default();
        let sizes = path.with_file_name("sizes.json");
        if sizes.is_file() {
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&sizes).unwrap()).unwrap();
            options.camera_size = Some(size(&v["camera"]));
            options.projector_size = Some(size(&v["projector"]));
        }
        match Calibration::load_with(&path, &options) {
            Ok(loaded) => eprintln!("{}: {}", path.display(), loaded.layout),
            Err(e) if !sizes.is_file() && e.to_string().contains("image size") => {
                eprintln!("{}: needs sizes.json ({e})", path.display());
            }
            Err(e) => panic!("{}: {e}", path.display()),
        }
    }
}

fn walk(dir: &Path, found: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, found);
        } else if p.file_name().is_some_and(|n| {
            [
                "calibration.yml",
                "calibration.xml",
                "caliInfo.yml",
                "intrinsics.yml",
            ]
            .contains(&n.to_string_lossy().as_ref())
        }) {
            found.push(p);
        }
    }
}
