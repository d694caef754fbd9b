//! Several exposures through the scan library: a device session with automatic exposures on a
//! glossy object (chosen once, kept when the session resumes), and the fusion of a capture
//! folder laid out by hand, as another system's captures would be.

#![allow(clippy::unwrap_used)] // test helpers outside #[test] functions

use std::path::Path;

use sl_codec::{
    CaptureSet, EXPOSURES_FILE, ExposureFolder, ExposureRecord, FusionMethod, FusionSettings,
    MANIFEST_FILE,
};
use sl_rig::{exposure_dir_name, read_session_plan, view_dir_name};
use sl_scan::{
    DeviceCaptureConfig, Exposures, ScanError, capture_device_session, fuse_exposure_folder,
    scaled_rig_config,
};
use sl_sim::{Finish, Scene, VirtualRig};

fn frames_of(dir: &Path) -> Vec<sl_codec::GreyImage> {
    CaptureSet::load(&dir.join(MANIFEST_FILE))
        .unwrap()
        .frames
        .into_images()
}

#[test]
fn automatic_exposures_are_chosen_once_and_a_folder_fuses_as_the_session_did() {
    let tmp = tempfile::tempdir().unwrap();
    let rig = VirtualRig::new(
        scaled_rig_config(4),
        Scene::dumbbell().finished(Finish::Glossy),
    )
    .unwrap();
    let cfg = DeviceCaptureConfig {
        views: 2,
        display_latency: std::time::Duration::ZERO,
        exposures: Exposures::Auto(Default::default()),
        ..DeviceCaptureConfig::default()
    };
    let session = tmp.path().join("session");
    let (mut camera, mut projector, mut table) = rig.devices();
    let mut capture_once = || {
        capture_device_session(
            &cfg,
            None,
            &session,
            &mut camera,
            &mut projector,
            &mut table,
            |_| {},
        )
        .unwrap()
    };
    let capture = capture_once();
    let chosen = capture.exposures.clone().unwrap();
    assert!(chosen.exposures_ms.len() >= 2, "{chosen:?}");
    assert!(
        capture.stages.iter().any(|s| s.name == "choose exposures"),
        "{:?}",
        capture.stages
    );
    let plan = read_session_plan(&session).unwrap();
    assert_eq!(plan.exposures.times_ms, chosen.exposures_ms);

    // Resumed: nothing measured again, nothing captured again.
    let again = capture_once();
    assert!(again.exposures.is_none());
    assert_eq!(again.summary.captured, 0);

    // The exposure folders of view 0 laid out by hand (another system's capture): an
    // `exposures.json`, no manifest at the top. Fused, they are the session's fused frames.
    let view = session.join(view_dir_name(0));
    let by_hand = tmp.path().join("by_hand");
    let mut folders = Vec::new();
    for (i, &ms) in chosen.exposures_ms.iter().enumerate().rev() {
        let name = format!("at_{i}");
        let to = by_hand.join(&name);
        std::fs::create_dir_all(&to).unwrap();
        for e in std::fs::read_dir(view.join(exposure_dir_name(i))).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
        }
        folders.push(ExposureFolder {
            dir: name,
            exposure_ms: ms,
        });
    }
    ExposureRecord::new(folders, FusionSettings::default())
        .save(&by_hand.join(EXPOSURES_FILE))
        .unwrap();
    let summary = fuse_exposure_folder(&by_hand).unwrap();
    assert_eq!(summary.exposures_ms, chosen.exposures_ms);
    assert_eq!(frames_of(&by_hand), frames_of(&view));
    let record = ExposureRecord::load(&by_hand.join(EXPOSURES_FILE)).unwrap();
    assert_eq!(record.summary.as_ref(), Some(&summary));

    // The radiance merge, asked for in the file, writes 16-bit frames.
    let mut record = record;
    record.fusion.method = FusionMethod::Radiance;
    record.save(&by_hand.join(EXPOSURES_FILE)).unwrap();
    fuse_exposure_folder(&by_hand).unwrap();
    assert!(frames_of(&by_hand).iter().all(|f| f.bit_depth() == 16));
}

#[test]
fn a_folder_that_cannot_be_fused_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    // No exposures.json.
    let e = fuse_exposure_folder(tmp.path()).unwrap_err().to_string();
    assert!(e.contains(EXPOSURES_FILE), "{e}");
    // The error of a capture whose `exposures.json` lists one folder, `dir`.
    let fused_with = |dir: &str| {
        let folder = ExposureFolder {
            dir: dir.to_owned(),
            exposure_ms: 4.0,
        };
        ExposureRecord::new(vec![folder], FusionSettings::default())
            .save(&tmp.path().join(EXPOSURES_FILE))
            .unwrap();
        fuse_exposure_folder(tmp.path()).unwrap_err().to_string()
    };
    // A folder that climbs out of the capture.
    let e = fused_with("../elsewhere");
    assert!(e.contains("exposures[0].dir"), "{e}");
    // A listed folder with no frames: the manifest it needs is named.
    let e = fused_with("short");
    assert!(e.contains("short") && e.contains(MANIFEST_FILE), "{e}");
}

#[test]
fn exposures_are_read_as_a_user_types_them() {
    assert_eq!(
        "auto".parse::<Exposures>().unwrap(),
        Exposures::Auto(Default::default())
    );
    assert_eq!("camera".parse::<Exposures>().unwrap(), Exposures::Camera);
    assert_eq!(
        " 2, 8,32 ".parse::<Exposures>().unwrap(),
        Exposures::Fixed(vec![2.0, 8.0, 32.0])
    );
    for bad in ["2,x", "0", "-1,4", "4,4", ""] {
        let e = bad.parse::<Exposures>().unwrap_err();
        assert!(
            matches!(&e, ScanError::InvalidParameter { name, .. } if name == "exposures")
                || e.to_string().contains("exposures"),
            "{bad}: {e}"
        );
    }
}
