//! Dark and shiny objects on the virtual rig: the camera's exposure, the finishes that need
//! several exposures, sessions that capture and fuse them, and the automatic choice.

#![allow(clippy::unwrap_used)] // test helpers outside #[test] functions

use std::path::Path;
use std::time::Duration;

use sl_codec::{
    AutoExposureConfig, CaptureSet, DecodeConfig, EXPOSURES_FILE, ExposureRecord, FusionSettings,
    MANIFEST_FILE, decode,
};
use sl_rig::{
    Camera, CaptureSession, CaptureTiming, GreyImage, Projector, RigError, SessionConfig,
    SessionExposures, SessionPlan, Turntable, ViewState, measure_exposures,
};
use sl_sim::{Finish, RigConfig, Scene, VIRTUAL_EXPOSURE_MS, VirtualRig};

/// The default rig at a quarter of its resolution, with its noise, looking at the dumbbell of
/// `finish`.
fn rig(finish: Finish) -> VirtualRig {
    let mut c = RigConfig::default().downscaled(4);
    c.render.supersampling = 1;
    VirtualRig::new(c, Scene::dumbbell().finished(finish)).unwrap()
}

/// One view, at angle 0, at `exposures`.
fn plan(rig: &VirtualRig, exposures: SessionExposures) -> SessionPlan {
    SessionPlan {
        exposures,
        ..super::session::plan(rig, 1)
    }
}

fn quick() -> SessionConfig {
    super::session::quick(false, 0)
}

/// The frame under full white at the camera's exposure.
fn white_frame(rig: &VirtualRig, exposure_ms: f64) -> Vec<u16> {
    let (mut camera, mut projector, _) = rig.devices();
    camera.set_exposure_ms(exposure_ms).unwrap();
    let (w, h) = projector.image_size();
    projector
        .show(&GreyImage::filled_u8(w as usize, h as usize, 255).unwrap())
        .unwrap();
    let f = camera.capture().unwrap();
    (0..f.height())
        .flat_map(|y| (0..f.width()).map(move |x| (x, y)))
        .map(|(x, y)| f.get(x, y).unwrap())
        .collect()
}

fn decoded_pixels(manifest_dir: &Path) -> usize {
    let set = CaptureSet::load(&manifest_dir.join(MANIFEST_FILE)).unwrap();
    let map = decode(&set, &DecodeConfig::default()).unwrap();
    (map.valid_fraction() * map.len() as f64).round() as usize
}

#[test]
fn the_virtual_cameras_exposure_scales_the_light_it_collects() {
    let rig = rig(Finish::Matte);
    let base = white_frame(&rig, VIRTUAL_EXPOSURE_MS);
    let double = white_frame(&rig, 2.0 * VIRTUAL_EXPOSURE_MS);
    // The sensor's black level (5 levels) does not scale; the light above it does, photon
    // noise aside: compare means over pixels well lit and unsaturated in both.
    let dark = 5.0;
    let (mut a, mut b) = (0.0, 0.0);
    for (&x, &y) in base.iter().zip(&double) {
        if x > 40 && y < 250 {
            a += f64::from(x) - dark;
            b += f64::from(y) - dark;
        }
    }
    assert!(a > 0.0);
    let ratio = b / a;
    assert!((ratio - 2.0).abs() < 0.03, "{ratio}");
    // The camera reports what it was set to, and refuses what it cannot take.
    let (mut camera, _, _) = rig.devices();
    assert_eq!(camera.exposure_ms(), Some(VIRTUAL_EXPOSURE_MS));
    camera.set_exposure_ms(3.0).unwrap();
    assert_eq!(camera.exposure_ms(), Some(3.0));
    let e = camera.set_exposure_ms(-1.0).unwrap_err();
    assert!(e.to_string().contains("exposure_ms"), "{e}");
}

#[test]
fn a_glossy_object_saturates_where_a_matte_one_does_not_and_a_dark_one_is_faint() {
    let saturated = |f: &[u16]| f.iter().filter(|&&v| v >= 255).count();
    let matte = white_frame(&rig(Finish::Matte), VIRTUAL_EXPOSURE_MS);
    let glossy = white_frame(&rig(Finish::Glossy), VIRTUAL_EXPOSURE_MS);
    let dark = white_frame(&rig(Finish::Dark), VIRTUAL_EXPOSURE_MS);
    assert_eq!(saturated(&matte), 0);
    // The highlights: over a hundred pixels of the 320x180 frame.
    assert!(saturated(&glossy) > 100, "{}", saturated(&glossy));
    // Black plastic under full white: the light above the black level (5 levels) is the
    // albedos' ratio, 0.04 / 0.8, on the pixels where the plaster is well exposed.
    let (mut m, mut d) = (0.0, 0.0);
    for (&a, &b) in matte.iter().zip(&dark) {
        if a > 40 && a < 250 {
            m += f64::from(a) - 5.0;
            d += f64::from(b) - 5.0;
        }
    }
    let ratio = d / m;
    assert!((ratio - 0.05).abs() < 0.01, "{ratio}");
}

#[test]
fn a_session_at_several_exposures_keeps_each_and_decodes_more_from_the_fused_frames() {
    let rig = rig(Finish::Glossy);
    let dir = tempfile::tempdir().unwrap();
    let times = vec![1.25, 5.0, 20.0];
    let exposures = SessionExposures::new(times.clone(), FusionSettings::default()).unwrap();
    let session = CaptureSession::open(dir.path(), plan(&rig, exposures), quick()).unwrap();
    let (mut camera, mut projector, mut table) = rig.devices();
    let summary = session
        .run(&mut camera, &mut projector, &mut table, |_| {})
        .unwrap();
    assert_eq!(summary.captured, 1);
    assert_eq!(session.view_state(0), ViewState::Complete);
    // Devices that do not lie: nothing named, nothing captured again (the checks judge the
    // fused frames, not a pass that is mostly saturated or mostly dark).
    assert!(
        summary.views[0].recaptured.is_empty(),
        "{:?}",
        summary.views[0]
    );
    assert!(
        summary.views[0].frame_issues.is_empty(),
        "{:?}",
        summary.views[0]
    );
    // The camera is back at its own exposure.
    assert_eq!(camera.exposure_ms(), Some(VIRTUAL_EXPOSURE_MS));
    let view = session.view_dir(0);
    let record = ExposureRecord::load(&view.join(EXPOSURES_FILE)).unwrap();
    let listed: Vec<f64> = record.exposures.iter().map(|e| e.exposure_ms).collect();
    assert_eq!(listed, times);
    let fused_summary = record.summary.unwrap();
    assert_eq!(fused_summary.exposures_ms, times);
    let fused = decoded_pixels(&view);
    for e in &record.exposures {
        let alone = decoded_pixels(&view.join(&e.dir));
        assert!(
            fused > alone,
            "fused {fused} pixels, {} ms alone {alone}",
            e.exposure_ms
        );
    }
    // The session file records the exposures; a plan with other exposures is another plan.
    let other = SessionExposures::new(vec![2.0, 8.0], FusionSettings::default()).unwrap();
    let e = CaptureSession::open(dir.path(), plan(&rig, other), quick()).unwrap_err();
    assert!(e.to_string().contains("exposures"), "{e}");
}

#[test]
fn a_late_frame_in_one_exposure_is_captured_again() {
    let rig = rig(Finish::Glossy);
    let dir = tempfile::tempdir().unwrap();
    let exposures =
        SessionExposures::new(vec![1.25, 5.0, 20.0], FusionSettings::default()).unwrap();
    let session = CaptureSession::open(dir.path(), plan(&rig, exposures), quick()).unwrap();
    let frames = session.plan().manifest.frame_count() as u64;
    let (mut camera, mut projector, mut table) = rig.devices();
    // Frame 8 of the 5 ms pass, the one the checks judge (nearest the camera's own 10 ms, with
    // 20 ms as near: the first is taken): the projector is still showing frame 7's pattern
    // when the camera exposes.
    projector.set_faults(sl_sim::DeviceFaults {
        late_shows: vec![frames + 8],
        late_by: Duration::from_secs(5),
        ..Default::default()
    });
    let summary = session
        .run(&mut camera, &mut projector, &mut table, |_| {})
        .unwrap();
    let view = &summary.views[0];
    assert!(
        view.recaptured.iter().any(|r| r.contains("frame 8 ")),
        "{view:?}"
    );
    assert!(view.frame_issues.is_empty(), "{view:?}");
}

/// A camera with no exposure control (the trait's default).
struct FixedCamera<C>(C);

impl<C: Camera> Camera for FixedCamera<C> {
    fn frame_size(&self) -> (u32, u32) {
        self.0.frame_size()
    }
    fn capture(&mut self) -> Result<GreyImage, RigError> {
        self.0.capture()
    }
}

#[test]
fn a_camera_without_an_exposure_control_is_refused_and_the_view_left_incomplete() {
    let rig = rig(Finish::Matte);
    let dir = tempfile::tempdir().unwrap();
    let exposures = SessionExposures::new(vec![5.0, 20.0], FusionSettings::default()).unwrap();
    let session = CaptureSession::open(dir.path(), plan(&rig, exposures), quick()).unwrap();
    let (camera, mut projector, mut table) = rig.devices();
    let mut camera = FixedCamera(camera);
    let e = session
        .run(&mut camera, &mut projector, &mut table, |_| {})
        .unwrap_err();
    let text = format!("{e}: {:?}", std::error::Error::source(&e));
    assert!(text.contains("cannot set its exposure"), "{text}");
    assert_ne!(session.view_state(0), ViewState::Complete);
}

#[test]
fn automatic_exposures_lengthen_for_a_dark_object_and_span_a_glossy_one() {
    let cfg = AutoExposureConfig::default();
    let choose = |finish: Finish| {
        let rig = rig(finish);
        let (mut camera, mut projector, mut table) = rig.devices();
        table.rotate_to(0.0).unwrap();
        let mut measured = Vec::new();
        let plan = measure_exposures(
            &mut camera,
            &mut projector,
            &cfg,
            CaptureTiming {
                settle: Duration::ZERO,
                flush_frames: 0,
            },
            VIRTUAL_EXPOSURE_MS,
            |ms, why| measured.push((ms, why.map(str::to_owned))),
        )
        .unwrap();
        // The camera is left at its own exposure.
        assert_eq!(camera.exposure_ms(), Some(VIRTUAL_EXPOSURE_MS));
        (plan, measured)
    };
    let (matte, _) = choose(Finish::Matte);
    let (dark, _) = choose(Finish::Dark);
    let (glossy, measured) = choose(Finish::Glossy);
    // Plaster: the shortest exposure near the rig's own (its brightest pixels are at ~0.65 of
    // full scale); longer ones only for the spheres' grazing rims.
    assert!(
        (0.5..=2.0).contains(&(matte.exposures_ms[0] / VIRTUAL_EXPOSURE_MS)),
        "{matte:?}"
    );
    // Black plastic: every exposure several times the rig's own.
    assert!(dark.exposures_ms[0] > 4.0 * VIRTUAL_EXPOSURE_MS, "{dark:?}");
    // Gloss: measured again shorter first (the highlights saturate), then from below the rig's
    // own exposure up past it.
    assert!(
        measured
            .first()
            .is_some_and(|(_, why)| why.as_deref().is_some_and(|w| w.contains("saturate"))),
        "{measured:?}"
    );
    assert!(glossy.exposures_ms.len() >= 2, "{glossy:?}");
    assert!(glossy.exposures_ms[0] < VIRTUAL_EXPOSURE_MS, "{glossy:?}");
}

/// Sessions of devices that do not lie name no frame, whatever the exposures: before the checks
/// judged one pass (the one nearest the camera's own exposure), a pass mostly saturated or
/// mostly dark had true frames taken for late ones, captured again with ever longer waits.
#[test]
fn devices_that_do_not_lie_have_no_frame_named_at_any_exposures() {
    for finish in [Finish::Glossy, Finish::Matte, Finish::Dark] {
        for times in [vec![1.25, 5.0, 20.0], vec![10.0, 40.0, 160.0]] {
            let rig = rig(finish);
            let dir = tempfile::tempdir().unwrap();
            let exposures =
                SessionExposures::new(times.clone(), FusionSettings::default()).unwrap();
            let session = CaptureSession::open(dir.path(), plan(&rig, exposures), quick()).unwrap();
            let (mut camera, mut projector, mut table) = rig.devices();
            let summary = session
                .run(&mut camera, &mut projector, &mut table, |_| {})
                .unwrap();
            let view = &summary.views[0];
            assert!(
                view.recaptured.is_empty() && view.frame_issues.is_empty(),
                "{finish:?} at {times:?} ms: {view:?}"
            );
        }
    }
}
