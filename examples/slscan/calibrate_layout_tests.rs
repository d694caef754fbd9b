//! `slscan calibrate … --layout`: sessions laid out by another program, read where they are.
//!
//! The self-contained test renders a session on the virtual rig and rewrites it the way
//! kamino410/procam-calibration lays out its captures: pose folders of another name
//! (`take_K`), frames of other names, the white and black frames named by the layout, no
//! manifest in the pose folders (the one manifest and the layout file live elsewhere), no
//! turntable. It is calibrated through `slscan calibrate all --layout` and compared with the
//! rig's truth. The real set (`$SL_DATA_EXTRA/procam_kamino`) is calibrated against the figures
//! of its own program, OpenCV's, re-run by `benches/peers/procam_kamino.py`.

use std::path::{Path, PathBuf};

use sl_calib::CalibError;
use sl_calib::sl_camera::Calibration;
use sl_codec::{Frame, write_png_grey8};
use sl_scan::LayoutError;

use super::tests::{SESSION_POSES, rendered_session, slscan};

/// Board poses of the shared rendered session taken; one of them loses its board (a blank
/// white frame).
const POSES: usize = 9;
const _: () = assert!(POSES <= SESSION_POSES);

/// The pose whose white frame is blanked.
const BLANK_POSE: usize = 4;

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every file below `dir`, relative to it, sorted.
fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut all: Vec<PathBuf> = crate::common::files_below(dir)
        .into_iter()
        .map(|p| p.strip_prefix(dir).unwrap().to_path_buf())
        .collect();
    all.sort();
    all
}

/// Rewrites the `board/pose_NNN` folders of an `slscan simulate` session under `session` as
/// `take_K/img_NN.png` with `img_white.png` and `img_black.png`, writes the one manifest and the
/// layout file into `layout_dir`, and returns the layout file.
fn kamino_like(rendered: &Path, session: &Path, layout_dir: &Path) -> PathBuf {
    std::fs::create_dir_all(layout_dir).unwrap();
    let mut manifest = None;
    for k in 0..POSES {
        let src = rendered.join(format!("board/pose_{k:03}"));
        let dst = session.join(format!("take_{k}"));
        std::fs::create_dir_all(&dst).unwrap();
        let mut m = read_json(&src.join("manifest.json"));
        let mut n = 0;
        for block in m["blocks"].as_array_mut().unwrap() {
            for frame in block["frames"].as_array_mut().unwrap() {
                let name = format!("img_{n:02}.png");
                std::fs::copy(src.join(frame.as_str().unwrap()), dst.join(&name)).unwrap();
                *frame = serde_json::Value::String(name);
                n += 1;
            }
        }
        let white = sl_calib::load_grey(src.join("white.png")).unwrap();
        let (w, h) = (white.width(), white.height());
        if k == BLANK_POSE {
            let blank = Frame::filled(w, h, 128).unwrap();
            write_png_grey8(&dst.join("img_white.png"), &blank).unwrap();
        } else {
            write_png_grey8(&dst.join("img_white.png"), &white).unwrap();
        }
        let black = Frame::filled(w, h, 0).unwrap();
        write_png_grey8(&dst.join("img_black.png"), &black).unwrap();
        manifest = Some(m);
    }
    std::fs::write(
        layout_dir.join("their-manifest.json"),
        manifest.unwrap().to_string(),
    )
    .unwrap();
    // Not poses: a file the pattern matches, a folder it does not.
    std::fs::write(session.join("take_notes.txt"), "board 9x6, 20 mm").unwrap();
    std::fs::create_dir_all(session.join("patterns")).unwrap();
    let layout = layout_dir.join("layout.json");
    std::fs::write(
        &layout,
        r#"{
  "format": "sl-calibration-layout",
  "version": 1,
  "description": "a virtual-rig session laid out as kamino410/procam-calibration lays out its own",
  "poses": "take_*",
  "manifest": "their-manifest.json",
  "white": "img_white.png",
  "black": "img_black.png"
}"#,
    )
    .unwrap();
    layout
}

/// `calibrate all --layout` on the rewritten session: camera and projector near the rig's
/// truth, the blank pose skipped with its reason, no turntable step, nothing written into the
/// session; then `calibrate camera --layout` on its white frames, and `calibrate projector
/// --layout` with a projector size other than the manifest's refused.
#[test]
fn calibrate_all_reads_another_programs_layout_where_it_is() {
    let tmp = tempfile::tempdir().unwrap();
    let rendered = tmp.path().join("rendered");
    let rig = rendered_session(&rendered);
    // Glob characters in the session's own path are taken literally.
    let session = tmp.path().join("their session [v2]");
    let layout = kamino_like(&rendered, &session, &tmp.path().join("layout"));
    let before = listing(&session);
    assert!(!before.iter().any(|p| p.ends_with("manifest.json")));

    let out = tmp.path().join("calib");
    slscan(&[
        "calibrate",
        "all",
        session.to_str().unwrap(),
        "--layout",
        layout.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap();
    assert_eq!(listing(&session), before, "files written into the session");

    // No turntable folder: camera and projector only, in OUT itself.
    assert!(!out.join("projector").exists());
    let c = Calibration::load(out.join("calibration.json")).unwrap();
    assert!(c.turntable.is_none());
    let truth = rig.config();
    // As the rig tests of `calibrate all` (quarter resolution: 0.5 % on the camera's fx, 1 %
    // on the projector's, 2 mm on the baseline), here from 8 poses.
    let fx = c.camera.intrinsics.fx;
    assert!(
        (fx / truth.camera.intrinsics.fx - 1.0).abs() < 0.005,
        "camera fx {fx} vs {}",
        truth.camera.intrinsics.fx
    );
    let proj = c.projector.unwrap();
    assert_eq!(
        (proj.size.width, proj.size.height),
        (truth.projector.size.width, truth.projector.size.height),
        "the projector size comes from the manifest"
    );
    let pfx = proj.intrinsics.fx;
    assert!(
        (pfx / truth.projector.intrinsics.fx - 1.0).abs() < 0.01,
        "projector fx {pfx} vs {}",
        truth.projector.intrinsics.fx
    );
    let t = c.t_cam_proj.unwrap().translation.vector - truth.t_cam_proj.translation.vector;
    assert!(t.norm() < 2.0, "baseline off by {t:?} mm");

    let report = read_json(&out.join("report.json"));
    let f = &report["figures"];
    let views: Vec<&str> = f["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap())
        .collect();
    let expected: Vec<String> = (0..POSES)
        .filter(|&k| k != BLANK_POSE)
        .map(|k| format!("take_{k}"))
        .collect();
    assert_eq!(views, expected);
    let skipped = f["skipped"].as_array().unwrap();
    assert_eq!(skipped.len(), 1, "{skipped:?}");
    assert_eq!(
        skipped[0]["name"].as_str(),
        Some(format!("take_{BLANK_POSE}").as_str())
    );
    let reason = skipped[0]["reason"].as_str().unwrap();
    assert!(reason.contains("not found"), "{reason}");
    for b in f["board_images"].as_array().unwrap() {
        assert_eq!(b["board_image"].as_str(), Some("img_white.png"), "{b}");
    }
    assert_eq!(
        f["session"]["layout"].as_str(),
        Some(layout.to_str().unwrap())
    );

    // The camera alone from the same layout: the white frames.
    let cam_out = tmp.path().join("camera");
    slscan(&[
        "calibrate",
        "camera",
        session.to_str().unwrap(),
        "--layout",
        layout.to_str().unwrap(),
        "--out",
        cam_out.to_str().unwrap(),
    ])
    .unwrap();
    let cam = read_json(&cam_out.join("report.json"));
    assert_eq!(
        cam["figures"]["views_used"].as_u64(),
        Some(POSES as u64 - 1)
    );
    let names: Vec<&str> = cam["figures"]["view_rms_px"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["image"].as_str().unwrap())
        .collect();
    assert_eq!(names[0], "take_0/img_white.png", "{names:?}");
    let cfx = Calibration::load(cam_out.join("calibration.json"))
        .unwrap()
        .camera
        .intrinsics
        .fx;
    assert!(
        (cfx / truth.camera.intrinsics.fx - 1.0).abs() < 0.01,
        "camera alone fx {cfx}"
    );

    // A projector size other than the manifest's is refused before anything is decoded.
    let bad_out = tmp.path().join("bad");
    let err = slscan(&[
        "calibrate",
        "projector",
        session.to_str().unwrap(),
        "--layout",
        layout.to_str().unwrap(),
        "--projector",
        "1920x1080",
        "--out",
        bad_out.to_str().unwrap(),
    ])
    .unwrap_err();
    assert!(
        matches!(
            err.downcast_ref::<LayoutError>(),
            Some(LayoutError::ProjectorSize { .. })
        ),
        "{err:#}"
    );
    assert!(!bad_out.join("calibration.json").exists());
}

/// Three poses whose boards cannot be found (blank frames): each is skipped with its reason,
/// and the calibration stops with a typed error naming them, writing nothing.
#[test]
fn too_few_poses_left_is_an_error_naming_the_skipped_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let session = tmp.path().join("session");
    // A 16x8 projector, Gray codes on both axes (4 + 3 bits with inverses: 14 frames).
    let frames: Vec<String> = (0..14).map(|i| format!("f{i:02}.png")).collect();
    for k in 0..3 {
        let dir = session.join(format!("capture_{k}"));
        std::fs::create_dir_all(&dir).unwrap();
        for (i, name) in frames
            .iter()
            .chain(["white.png".to_owned()].iter())
            .enumerate()
        {
            let frame = Frame::filled(64, 48, 40 + i as u8).unwrap();
            write_png_grey8(&dir.join(name), &frame).unwrap();
        }
    }
    let manifest = serde_json::json!({
        "projector": {"width": 16, "height": 8},
        "blocks": [
            {"codec": "gray", "axis": "column", "centered": false, "frames": frames[..8]},
            {"codec": "gray", "axis": "row", "centered": false, "frames": frames[8..]},
        ]
    });
    std::fs::write(tmp.path().join("manifest.json"), manifest.to_string()).unwrap();
    let layout = tmp.path().join("layout.json");
    std::fs::write(
        &layout,
        r#"{"poses": "capture_*", "manifest": "manifest.json", "white": "white.png"}"#,
    )
    .unwrap();
    let out = tmp.path().join("out");
    let err = slscan(&[
        "calibrate",
        "all",
        session.to_str().unwrap(),
        "--layout",
        layout.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap_err();
    assert!(
        matches!(
            err.chain().find_map(|e| e.downcast_ref::<CalibError>()),
            Some(CalibError::Degenerate(_))
        ),
        "{err:#}"
    );
    let text = format!("{err:#}");
    for k in 0..3 {
        assert!(text.contains(&format!("capture_{k} left out")), "{text}");
    }
    assert!(text.contains("not found"), "{text}");
    assert!(!out.join("calibration.json").exists());
}

/// The real set: `$SL_DATA_EXTRA/procam_kamino` with the layout and manifest of
/// `tests/data/procam_kamino/`, against the figures of its own `calibrate.py` on OpenCV 5.0.
#[test]
fn the_kamino_set_calibrates_beside_its_own_programs_figures() {
    let Some(root) = std::env::var_os("SL_DATA_EXTRA") else {
        eprintln!("SL_DATA_EXTRA not set: skipping the procam_kamino calibration");
        return;
    };
    let data = PathBuf::from(root).join("procam_kamino");
    let layout =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/procam_kamino/layout.json");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("kamino");
    slscan(&[
        "calibrate",
        "all",
        data.to_str().unwrap(),
        "--layout",
        layout.to_str().unwrap(),
        "--board",
        "9x7",
        "--square",
        "75",
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap();
    let c = Calibration::load(out.join("calibration.json")).unwrap();
    let f = read_json(&out.join("report.json"))["figures"].clone();
    // Every pose and every corner is used, as by the peer.
    assert_eq!(f["views"].as_array().unwrap().len(), 5);
    assert!(f["skipped"].as_array().unwrap().is_empty());
    for v in f["views"].as_array().unwrap() {
        assert_eq!(v["projector_corners"].as_u64(), Some(63), "{v}");
    }
    check_against_peer(&c, &f);
}

/// The peer's figures (`benches/peers/procam_kamino.py`): its `calibrateCamera` RMS on the
/// camera and projector, and its `stereoCalibrate` re-run with free intrinsics (its own run
/// fixes them; ours refines everything jointly), from which the parameters below are taken.
struct Peer;

impl Peer {
    const RMS_CAMERA: f64 = 0.3163;
    const RMS_PROJECTOR: f64 = 0.2030;
    const RMS_STEREO_FREE: f64 = 0.2712;
    const CAMERA_FX: f64 = 3444.7;
    const CAMERA_CX_CY: [f64; 2] = [590.71, 530.91];
    const PROJECTOR_FX: f64 = 1893.1;
    const PROJECTOR_CX_CY: [f64; 2] = [502.27, 852.16];
    /// `T_proj_cam`'s translation (camera into projector coordinates), in board units.
    const T_PROJ_CAM: [f64; 3] = [95.07, -624.29, -239.59];
}

/// Our calibration beside the peer's: the RMS no worse than the peer's by more than 5 % (our
/// corners and projector corners differ from OpenCV's, the models are the same), and the
/// parameters within 3 of the standard deviations we report (the two are fits of five poses
/// with different corners, so they differ by about the parameters' uncertainty, not less).
fn check_against_peer(c: &Calibration, f: &serde_json::Value) {
    let rms = |k: &str| f[k].as_f64().unwrap();
    eprintln!(
        "procam_kamino: RMS camera {:.4} / projector {:.4} / stereo {:.4} px (peer {} / {} / {} with free intrinsics)",
        rms("rms_camera_px"),
        rms("rms_projector_px"),
        rms("rms_stereo_px"),
        Peer::RMS_CAMERA,
        Peer::RMS_PROJECTOR,
        Peer::RMS_STEREO_FREE
    );
    assert!(rms("rms_camera_px") < 1.05 * Peer::RMS_CAMERA);
    assert!(rms("rms_projector_px") < 1.05 * Peer::RMS_PROJECTOR);
    assert!(rms("rms_stereo_px") < 1.05 * Peer::RMS_STEREO_FREE);
    let within = |what: &str, ours: f64, peer: f64, sd: f64| {
        eprintln!("  {what}: {ours:.2} vs {peer:.2} (σ {sd:.2})");
        assert!(
            (ours - peer).abs() < 3.0 * sd,
            "{what}: {ours} vs the peer's {peer}, σ {sd}"
        );
    };
    let sd = |dev: &str, i: usize| f[dev]["std_dev"]["intrinsics"][i].as_f64().unwrap();
    let cam = &c.camera.intrinsics;
    within("camera fx", cam.fx, Peer::CAMERA_FX, sd("camera", 0));
    within("camera cx", cam.cx, Peer::CAMERA_CX_CY[0], sd("camera", 2));
    within("camera cy", cam.cy, Peer::CAMERA_CX_CY[1], sd("camera", 3));
    let proj = c.projector.unwrap().intrinsics;
    within(
        "projector fx",
        proj.fx,
        Peer::PROJECTOR_FX,
        sd("projector", 0),
    );
    within(
        "projector cx",
        proj.cx,
        Peer::PROJECTOR_CX_CY[0],
        sd("projector", 2),
    );
    within(
        "projector cy",
        proj.cy,
        Peer::PROJECTOR_CX_CY[1],
        sd("projector", 3),
    );
    let t_proj_cam = c.t_cam_proj.unwrap().inverse().translation.vector;
    let t_sd = f["T_cam_proj"]["T_proj_cam_std_dev"].as_array().unwrap();
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        within(
            &format!("T_proj_cam {axis}"),
            t_proj_cam[i],
            Peer::T_PROJ_CAM[i],
            t_sd[3 + i].as_f64().unwrap(),
        );
    }
}

/// The same set through the library (`sl_scan::CalibrationLayout`, `sl_calib::calibrate_procam`)
/// with each corner refiner the detector offers: the saddle points (the default) and the
/// junction-model fit. Both against the peer as above; the figures are printed for the docs.
#[test]
fn the_kamino_set_with_each_corner_refiner() {
    let Some(root) = std::env::var_os("SL_DATA_EXTRA") else {
        eprintln!("SL_DATA_EXTRA not set: skipping the procam_kamino corner refiners");
        return;
    };
    let data = PathBuf::from(root).join("procam_kamino");
    let layout = sl_scan::CalibrationLayout::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/procam_kamino/layout.json"),
    )
    .unwrap();
    let views: Vec<sl_calib::ProcamView> = layout
        .poses(&data)
        .unwrap()
        .iter()
        .map(|p| {
            p.load(&sl_calib::sl_codec::DecodeConfig::default())
                .unwrap()
                .view
        })
        .collect();
    for (name, detector) in [
        ("saddle (default)", sl_calib::DetectorConfig::default()),
        (
            "junction fit",
            sl_calib::DetectorConfig::with_junction_fit(),
        ),
    ] {
        let mut cfg = sl_calib::ProcamConfig::new(
            sl_calib::BoardSize::new(9, 7),
            75.0,
            layout.projector_size(),
        );
        cfg.detector = detector;
        let cal = sl_calib::calibrate_procam(&views, &cfg).unwrap();
        let sd = |c: &sl_calib::CameraCalibration| serde_json::json!({ "intrinsics": c.std_dev.intrinsics });
        let f = serde_json::json!({
            "rms_camera_px": cal.rms_camera,
            "rms_projector_px": cal.rms_projector,
            "rms_stereo_px": cal.rms_stereo,
            "camera": { "std_dev": sd(&cal.camera) },
            "projector": { "std_dev": sd(&cal.projector) },
            "T_cam_proj": { "T_proj_cam_std_dev": cal.t_proj_cam_std_dev },
        });
        let c = cal.to_calibration();
        let i = &c.camera.intrinsics;
        let p = c.projector.unwrap().intrinsics;
        let t = cal.t_cam_proj.inverse().translation.vector;
        eprintln!(
            "{name}: camera fx {:.1} fy {:.1} cx {:.1} cy {:.1} {:?}; projector fx {:.1} fy {:.1} cx {:.1} cy {:.1} {:?}; T_proj_cam ({:.2}, {:.2}, {:.2}), |T| {:.2}, rotation {:.3} deg",
            i.fx,
            i.fy,
            i.cx,
            i.cy,
            c.camera.distortion.to_opencv_vec(),
            p.fx,
            p.fy,
            p.cx,
            p.cy,
            c.projector.unwrap().distortion.to_opencv_vec(),
            t.x,
            t.y,
            t.z,
            t.norm(),
            cal.t_cam_proj.rotation.angle().to_degrees()
        );
        check_against_peer(&c, &f);
    }
}
