//! Colour scans through the library: a session captured in colour on the virtual devices
//! (the coloured dumbbell), reconstructed, merged and meshed in colour, its colours measured
//! against the scene's true albedo; and a grey session that stays without colour unless asked.

#![allow(clippy::unwrap_used)] // test helpers outside #[test] functions

use std::path::Path;
use std::time::Duration;

use sl_codec::{MANIFEST_FILE, Manifest};
use sl_rig::{COLOUR_FILE, view_dir_name};
use sl_scan::{
    ColourMode, DeviceCaptureConfig, MergeStageConfig, SessionScan, SessionScanConfig,
    capture_device_session, colour_accuracy, full_turn_motor_angles, mesh_stage_coloured,
    scaled_rig_config, scan_poisson_config, scan_session,
};
use sl_sim::{Finish, Scene, VirtualRig};

const VIEWS: usize = 8;

/// Captures `VIEWS` views of the dumbbell with `finish` (in colour when `colour`) into
/// `dir/session` at a quarter of the resolution, and reconstructs and merges them with the
/// rig's exact calibration (the colour is under test, not the calibration) in `mode`.
fn scan(dir: &Path, finish: Finish, colour: bool, mode: ColourMode) -> (VirtualRig, SessionScan) {
    let rig = VirtualRig::new(scaled_rig_config(4), Scene::dumbbell().finished(finish)).unwrap();
    let calibration = rig.config().calibration();
    let angles = full_turn_motor_angles(calibration.turntable.as_ref(), VIEWS).unwrap();
    let cfg = DeviceCaptureConfig {
        views: angles.len(),
        display_latency: Duration::ZERO,
        colour,
        ..DeviceCaptureConfig::default()
    };
    let session = dir.join("session");
    let (mut camera, mut projector, mut table) = rig.devices();
    capture_device_session(
        &cfg,
        calibration.turntable.as_ref(),
        &session,
        &mut camera,
        &mut projector,
        &mut table,
        |_| {},
    )
    .unwrap();
    let mut config = SessionScanConfig {
        merge: MergeStageConfig {
            icp_refinement: false,
            ..MergeStageConfig::default()
        },
        ..SessionScanConfig::default()
    };
    config.reconstruct.colour = mode;
    let scan = scan_session(&session, &calibration, &config, |_| {}).unwrap();
    (rig, scan)
}

/// The true albedo at `p` (camera frame of view 0, motor angle 0) when `p` is within 1 mm of
/// the surface.
fn truth(rig: &VirtualRig) -> impl Fn(&nalgebra::Point3<f64>) -> Option<[f64; 3]> + Sync + '_ {
    move |p| {
        rig.true_colour(0.0, p)
            .filter(|t| t.distance_mm <= 1.0)
            .map(|t| t.rgb)
    }
}

#[test]
fn a_coloured_object_is_scanned_and_meshed_in_its_colours() {
    let tmp = tempfile::tempdir().unwrap();
    let (rig, scan) = scan(tmp.path(), Finish::Coloured, true, ColourMode::Auto);

    // Each view holds its colour frame, named by its manifest.
    for k in 0..VIEWS {
        let view = tmp.path().join("session").join(view_dir_name(k));
        let manifest = Manifest::load(&view.join(MANIFEST_FILE)).unwrap();
        assert_eq!(manifest.colour.as_deref(), Some(COLOUR_FILE));
        assert!(view.join(COLOUR_FILE).is_file());
    }

    // The merged cloud's colours against the true albedo. The patches are red, green, blue
    // and yellow: a grey or a wrong colour is tens of degrees from them (checked below with
    // the channels swapped), the shading of the white frame is not an angle at all.
    let colours = scan.colours.as_ref().unwrap();
    assert_eq!(colours.views.len(), VIEWS);
    let merged = &scan.merged;
    let acc = colour_accuracy(merged.positions(), merged.colors().unwrap(), truth(&rig)).unwrap();
    eprintln!("merged cloud: {acc:?}");
    assert!(acc.points > merged.len() * 9 / 10, "{acc:?}");
    assert!(acc.angle_median_deg < 8.0, "{acc:?}");
    let swapped: Vec<[u8; 3]> = merged
        .colors()
        .unwrap()
        .iter()
        .map(|&[r, g, b]| [g, b, r])
        .collect();
    let wrong = colour_accuracy(merged.positions(), &swapped, truth(&rig)).unwrap();
    assert!(
        wrong.angle_median_deg > 3.0 * acc.angle_median_deg,
        "{wrong:?}"
    );

    // The mesh: vertex colours in mesh.ply, a textured OBJ beside it, as accurate as the
    // cloud where the views see it.
    let out = tmp.path().join("mesh");
    std::fs::create_dir_all(&out).unwrap();
    let poisson = scan_poisson_config(merged, Some(1.0), 7);
    let (summary, files) = mesh_stage_coloured(
        merged,
        None,
        None,
        &poisson,
        &sl_scan::MeshConfig::default(),
        Some(colours),
        &out,
    )
    .unwrap();
    let c = summary.colour.unwrap();
    assert_eq!(c.views, VIEWS);
    assert!(c.unseen_vertices < summary.vertices / 3, "{c:?}");
    for f in [
        files.obj.unwrap(),
        "mesh.mtl".into(),
        files.texture.unwrap(),
    ] {
        assert!(out.join(&f).is_file(), "{f}");
    }
    let mesh = sl_cloud::read_ply(&out.join(&files.ply)).unwrap();
    let normals = mesh.normals().unwrap();
    let seen: Vec<usize> = (0..mesh.len())
        .filter(|&i| {
            colours
                .colour_at(&mesh.positions()[i], &normals[i].normalize())
                .is_some()
        })
        .collect();
    let seen = mesh.select(&seen).unwrap();
    let mesh_acc = colour_accuracy(seen.positions(), seen.colors().unwrap(), truth(&rig)).unwrap();
    eprintln!("mesh vertices seen: {mesh_acc:?}");
    assert!(mesh_acc.angle_median_deg < 10.0, "{mesh_acc:?}");
}

#[test]
fn a_grey_session_has_colour_only_when_asked() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, auto) = scan(
        &tmp.path().join("a"),
        Finish::Matte,
        false,
        ColourMode::Auto,
    );
    assert!(auto.colours.is_none() && auto.merged.colors().is_none());
    let (_, always) = scan(
        &tmp.path().join("b"),
        Finish::Matte,
        false,
        ColourMode::Always,
    );
    // From the fringes' mean: grey, every channel alike.
    let c = always.merged.colors().unwrap();
    assert!(c.iter().all(|&[r, g, b]| r == g && g == b), "{:?}", &c[..3]);
    assert!(
        c.iter().any(|&[r, _, _]| r > 20),
        "lit points are not black"
    );
    let views = &always.colours.as_ref().unwrap().views;
    assert_eq!(views[0].source, sl_codec::ColourSource::FringeMean);
}
