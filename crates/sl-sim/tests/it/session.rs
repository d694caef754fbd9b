//! Capture sessions on the virtual rig: interruption and resume, refusal to overwrite, and the
//! latency measurement against a camera with a known frame queue.

#![allow(clippy::unwrap_used)] // test helpers outside #[test] functions

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use sl_camera::ImageSize;
use sl_codec::{Axis, BitDepth, HybridSpec, Pattern, PatternSequence};
use sl_rig::{
    BufferedCamera, Camera, CaptureSession, GreyImage, LatencyConfig, RigError, SessionConfig,
    SessionPlan, ViewState, measure_latency,
};
use sl_sim::{RigConfig, Scene, VirtualRig};

/// The default rig at a quarter of its resolution (camera 320x180, projector 480x270), without
/// noise: with noise the virtual camera numbers its views in the order it casts them (a real
/// camera's noise never repeats either), so only a noise-free rig makes each frame a pure
/// function of (turntable angle, pattern) — which is what byte-identity between an
/// interrupted-and-resumed session and an uninterrupted one has to test.
fn small_rig() -> VirtualRig {
    let mut c = RigConfig::default().downscaled(4);
    c.render.supersampling = 1;
    c.render.effects.sensor.photon_noise = false;
    c.render.effects.sensor.read_noise_electrons = 0.0;
    VirtualRig::new(c, Scene::dumbbell()).unwrap()
}

/// The plan of `views` views a full turn apart with a column hybrid code for `rig`'s projector.
pub(crate) fn plan(rig: &VirtualRig, views: usize) -> SessionPlan {
    let s = rig.config().projector.size;
    let p = ImageSize::new(s.width, s.height);
    let sequence = PatternSequence::new(p).with(Pattern::Hybrid(HybridSpec::complementary(
        Axis::Column,
        p,
        4,
        12.0,
    )));
    SessionPlan {
        angles_deg: (0..views)
            .map(|k| 360.0 * k as f64 / views as f64)
            .collect(),
        manifest: sequence.manifest(BitDepth::Eight),
        devices: Default::default(),
        calibration: None,
        exposures: Default::default(),
        colour: false,
    }
}

/// No display latency (the virtual devices have none).
pub(crate) fn quick(overwrite: bool, flush_frames: usize) -> SessionConfig {
    SessionConfig {
        display_latency: Duration::ZERO,
        flush_frames,
        overwrite,
        check_frames: true,
    }
}

/// Every file under `dir`, relative path → bytes.
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// A camera that fails at its `fail_at`-th capture (counting from 0), like a cable pulled
/// mid-scan.
struct FailingCamera<C> {
    inner: C,
    captures: usize,
    fail_at: usize,
}

impl<C: Camera> Camera for FailingCamera<C> {
    fn frame_size(&self) -> (u32, u32) {
        self.inner.frame_size()
    }
    fn capture(&mut self) -> Result<GreyImage, RigError> {
        if self.captures == self.fail_at {
            return Err(RigError::Device {
                device: "camera".into(),
                reason: "unplugged".into(),
            });
        }
        self.captures += 1;
        self.inner.capture()
    }
}

#[test]
fn an_interrupted_session_resumes_into_the_same_files() {
    let rig = small_rig();
    let views = 4;
    let plan = plan(&rig, views);
    let frames = plan.manifest.frame_count();
    // The driver queues 2 frames; the session flushes them after each change.
    let depth = 2;

    let reference = tempfile::tempdir().unwrap();
    let (cam, mut proj, mut table) = rig.devices();
    let mut cam = BufferedCamera::new(cam, depth);
    let session =
        CaptureSession::open(reference.path(), plan.clone(), quick(false, depth)).unwrap();
    let summary = session
        .run(&mut cam, &mut proj, &mut table, |_| {})
        .unwrap();
    assert_eq!((summary.captured, summary.skipped), (views, 0));

    // Interrupted: the camera dies during view 2, at its frame 5 (each frame costs
    // 1 + depth captures, plus the queue's first fill).
    let resumed = tempfile::tempdir().unwrap();
    let fail_view = 2;
    let fail_frame = 5;
    let fail_at = depth + (fail_view * frames + fail_frame) * (depth + 1);
    let (cam, mut proj, mut table) = rig.devices();
    let mut failing = BufferedCamera::new(
        FailingCamera {
            inner: cam,
            captures: 0,
            fail_at,
        },
        depth,
    );
    let session = CaptureSession::open(resumed.path(), plan.clone(), quick(false, depth)).unwrap();
    let err = session
        .run(&mut failing, &mut proj, &mut table, |_| {})
        .unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("view 2, frame 5"), "{msg}");
    assert!(msg.contains("unplugged"), "{msg}");
    assert_eq!(
        session.view_states(),
        vec![
            ViewState::Complete,
            ViewState::Complete,
            ViewState::Partial,
            ViewState::Missing
        ]
    );

    // Resume in a new process: fresh devices, the session reopened from its folder.
    let (cam, mut proj, mut table) = rig.devices();
    let mut cam = BufferedCamera::new(cam, depth);
    let session = CaptureSession::open(resumed.path(), plan, quick(false, depth)).unwrap();
    let mut seen = Vec::new();
    let summary = session
        .run(&mut cam, &mut proj, &mut table, |v| seen.push(v.captured))
        .unwrap();
    assert_eq!(seen, vec![false, false, true, true]);
    assert_eq!((summary.captured, summary.skipped), (2, 2));

    let a = tree(reference.path());
    let b = tree(resumed.path());
    assert_eq!(a.len(), 1 + views * (frames + 1), "{:?}", a.keys());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(&b[name] == bytes, "{name} differs after resuming");
    }
}

#[test]
fn flushing_too_few_frames_captures_stale_patterns() {
    // The test above can fail: without flushing, a 2-deep queue returns the frame of the
    // pattern shown two changes earlier, and the files differ from a synchronised capture.
    let rig = small_rig();
    let plan = plan(&rig, 1);
    let run = |flush: usize| {
        let dir = tempfile::tempdir().unwrap();
        let (cam, mut proj, mut table) = rig.devices();
        let mut cam = BufferedCamera::new(cam, 2);
        let s = CaptureSession::open(dir.path(), plan.clone(), quick(false, flush)).unwrap();
        s.run(&mut cam, &mut proj, &mut table, |_| {}).unwrap();
        std::fs::read(dir.path().join("view_000").join("003.png")).unwrap()
    };
    assert_ne!(run(0), run(2));
}

#[test]
fn a_finished_session_is_not_overwritten_unless_asked() {
    let rig = small_rig();
    let dir = tempfile::tempdir().unwrap();
    let (mut cam, mut proj, mut table) = rig.devices();
    let first = plan(&rig, 2);
    let session = CaptureSession::open(dir.path(), first.clone(), quick(false, 0)).unwrap();
    session
        .run(&mut cam, &mut proj, &mut table, |_| {})
        .unwrap();
    let before = tree(dir.path());

    // Another plan in the same folder is refused, naming session.json, and nothing changes.
    let other = plan(&rig, 3);
    let err = CaptureSession::open(dir.path(), other.clone(), quick(false, 0)).unwrap_err();
    assert!(matches!(err, RigError::SessionMismatch { .. }), "{err}");
    assert!(err.to_string().contains("session.json"), "{err}");
    assert_eq!(tree(dir.path()), before);

    // The same plan again keeps every view.
    let again = CaptureSession::open(dir.path(), first.clone(), quick(false, 0)).unwrap();
    let s = again.run(&mut cam, &mut proj, &mut table, |_| {}).unwrap();
    assert_eq!((s.captured, s.skipped), (0, 2));
    assert_eq!(tree(dir.path()), before);

    // Asked to overwrite: the new plan replaces the old and every view is captured anew.
    let forced = CaptureSession::open(dir.path(), other, quick(true, 0)).unwrap();
    let s = forced.run(&mut cam, &mut proj, &mut table, |_| {}).unwrap();
    assert_eq!((s.captured, s.skipped), (3, 0));
    assert_eq!(forced.view_states(), vec![ViewState::Complete; 3]);
    // View 1 is now at 120 degrees instead of 180: its frames changed.
    let after = tree(dir.path());
    assert_ne!(after["view_001/000.png"], before["view_001/000.png"]);
}

#[test]
fn a_projector_of_another_size_is_refused_before_anything_moves() {
    let rig = small_rig();
    let mut p = plan(&rig, 1);
    let q = ImageSize::new(64, 32);
    p.manifest = PatternSequence::new(q)
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Column,
            q,
            4,
            4.0,
        )))
        .manifest(BitDepth::Eight);
    let dir = tempfile::tempdir().unwrap();
    let (mut cam, mut proj, mut table) = rig.devices();
    let s = CaptureSession::open(dir.path(), p, quick(false, 0)).unwrap();
    let err = s.run(&mut cam, &mut proj, &mut table, |_| {}).unwrap_err();
    assert!(err.to_string().contains("projector size"), "{err}");
    assert_eq!(s.view_states(), vec![ViewState::Missing]);
}

#[test]
fn measured_latency_equals_the_configured_queue_depth() {
    let rig = small_rig();
    for depth in [0, 1, 3, 7] {
        let (cam, mut proj, _) = rig.devices();
        let mut cam = BufferedCamera::new(cam, depth);
        let latency = measure_latency(&mut cam, &mut proj, &LatencyConfig::default()).unwrap();
        assert_eq!(latency.frames, depth, "{latency:?}");
        // Every one of the six transitions shows the same latency.
        assert_eq!(latency.transitions, vec![depth; 6]);
        assert!(
            latency.white_level > latency.black_level + 0.005,
            "{latency:?}"
        );
    }
    // A queue longer than the window cannot be measured: a clear error, not a wrong number.
    let (cam, mut proj, _) = rig.devices();
    let mut cam = BufferedCamera::new(cam, 20);
    let err = measure_latency(&mut cam, &mut proj, &LatencyConfig::default()).unwrap_err();
    assert!(err.to_string().contains("window_frames"), "{err}");
}

#[test]
fn a_camera_that_sees_no_flash_is_reported() {
    // The only object is behind the camera: nothing the projector lights comes back.
    let behind = sl_sim::SceneObject::in_camera(
        "behind",
        sl_sim::Shape::Sphere { radius: 10.0 },
        sl_sim::Texture::Uniform(0.5),
        nalgebra::Isometry3::translation(0.0, 0.0, -1000.0),
    );
    let rig = small_rig().with_scene(Scene::new().with(behind)).unwrap();
    let (mut cam, mut proj, _) = rig.devices();
    let err = measure_latency(&mut cam, &mut proj, &LatencyConfig::default()).unwrap_err();
    assert!(err.to_string().contains("point the camera"), "{err}");
}

/// A session with a second camera: each view holds the second camera's capture set in
/// `right/`, each frame the one the second camera's own rig renders under the same pattern; a
/// second camera that dies mid-view leaves the view partial (the first camera's frames of it
/// included) and the rerun completes it into the same files as an uninterrupted run; a
/// one-camera run of a two-camera plan, and the other way round, are refused.
#[test]
fn a_two_camera_session_captures_both_and_resumes() {
    let left = small_rig();
    let right = VirtualRig::new(
        left.config()
            .seen_from(&left.config().default_second_camera()),
        Scene::dumbbell(),
    )
    .unwrap();
    let views = 2;
    let mut plan = plan(&left, views);
    plan.devices.right_camera = Some("virtual second camera".to_owned());
    let frames = plan.manifest.frame_count();

    let reference = tempfile::tempdir().unwrap();
    let (mut cl, mut cr, mut proj, mut table) = left.binocular_devices(&right).unwrap();
    let session = CaptureSession::open(reference.path(), plan.clone(), quick(false, 0)).unwrap();
    let err = session
        .run(&mut cl, &mut proj, &mut table, |_| {})
        .unwrap_err();
    assert!(err.to_string().contains("run_binocular"), "{err}");
    let summary = session
        .run_binocular(&mut cl, &mut cr, &mut proj, &mut table, |_| {})
        .unwrap();
    assert_eq!((summary.captured, summary.skipped), (views, 0));
    let a = tree(reference.path());
    assert_eq!(a.len(), 1 + views * 2 * (frames + 1), "{:?}", a.keys());
    // Frame 3 of view 1 from the second camera is its rig's render under pattern 3.
    let images = plan.manifest.sequence();
    let pattern = images.render_image(3, plan.manifest.bit_depth).unwrap();
    let expected = right
        .view(plan.angles_deg[1], 0)
        .unwrap()
        .capture(&pattern, 0)
        .unwrap();
    let name = &plan.manifest.blocks[0].frames[3];
    let read = sl_codec::read_grey8(&reference.path().join("view_001/right").join(name)).unwrap();
    assert_eq!(GreyImage::U8(read), expected);

    // The second camera dies at view 1, frame 5.
    let resumed = tempfile::tempdir().unwrap();
    let (mut cl, cr, mut proj, mut table) = left.binocular_devices(&right).unwrap();
    let mut failing = FailingCamera {
        inner: cr,
        captures: 0,
        fail_at: frames + 5,
    };
    let session = CaptureSession::open(resumed.path(), plan.clone(), quick(false, 0)).unwrap();
    let err = session
        .run_binocular(&mut cl, &mut failing, &mut proj, &mut table, |_| {})
        .unwrap_err();
    assert!(err.to_string().contains("view 1, frame 5"), "{err}");
    assert_eq!(
        session.view_states(),
        vec![ViewState::Complete, ViewState::Partial]
    );
    let (mut cl, mut cr, mut proj, mut table) = left.binocular_devices(&right).unwrap();
    let summary = session
        .run_binocular(&mut cl, &mut cr, &mut proj, &mut table, |_| {})
        .unwrap();
    assert_eq!((summary.captured, summary.skipped), (1, 1));
    let b = tree(resumed.path());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(&b[name] == bytes, "{name} differs after resuming");
    }

    // The same folder with one camera is another session.
    let mut one = plan;
    one.devices.right_camera = None;
    let err = CaptureSession::open(resumed.path(), one, quick(false, 0)).unwrap_err();
    assert!(err.to_string().contains("2 camera(s), not 1"), "{err}");
}

/// Frames out of step on devices: a projector late with one pattern, a camera that catches
/// another half-updated and one that delivers a stale frame. With the frame checks on, the
/// session names each frame, captures it again after a longer wait (which it keeps), and the
/// view it writes passes the checks; with them off, the same faults stay in the view, where
/// the offline check finds them.
#[test]
fn frames_out_of_step_are_captured_again() {
    use sl_codec::{CaptureSet, DecodeConfig, check_frames, decode};
    use sl_sim::DeviceFaults;
    let rig = small_rig();
    let plan = plan(&rig, 1);
    let n = plan.manifest.frame_count() as u64;
    assert!(n > 12, "{n} frames");
    let faults = DeviceFaults {
        late_shows: vec![5],
        mixed_shows: vec![9],
        late_by: Duration::from_millis(300),
        stale_captures: vec![12],
    };
    let checked = |on: bool| {
        let dir = tempfile::tempdir().unwrap();
        let (mut camera, mut projector, mut table) = rig.devices();
        projector.set_faults(faults.clone());
        let config = SessionConfig {
            check_frames: on,
            ..quick(false, 0)
        };
        let session = CaptureSession::open(dir.path(), plan.clone(), config).unwrap();
        let summary = session
            .run(&mut camera, &mut projector, &mut table, |_| {})
            .unwrap();
        let set = CaptureSet::load(&session.view_dir(0).join("manifest.json")).unwrap();
        let issues = check_frames(&set, &decode(&set, &DecodeConfig::default()).unwrap());
        (summary.views[0].clone(), issues, session.settle(), dir)
    };

    let (view, issues, settle, _dir) = checked(false);
    // Offline, one pass: the pairs the late and the stale frame spoil are named; the mixed
    // frame, in a pair whose light it does not change, is left for after they are captured
    // again (a spoilt decode judges no other frame by its bands).
    let named: Vec<usize> = issues.iter().map(|i| i.frame).collect();
    assert_eq!(named, [5, 12], "{issues:#?}");
    assert!(view.recaptured.is_empty() && view.frame_issues.is_empty());
    assert_eq!(settle, Duration::ZERO);

    let (view, issues, settle, _dir) = checked(true);
    assert_eq!(issues, Vec::new(), "the view as written: {issues:#?}");
    assert!(view.frame_issues.is_empty(), "{:?}", view.frame_issues);
    // Each named by its file.
    for k in [5, 9, 12] {
        let file = session_file(&view.dir, k);
        assert!(
            view.recaptured
                .iter()
                .any(|m| m.starts_with(&format!("frame {k} ({file})"))),
            "frame {k}: {:#?}",
            view.recaptured
        );
    }
    // Rounds: 5 and 12 first, then 9, seen once their pairs are whole again. A mixed frame
    // leaves its pair's light as it is, so the decode it spoils is not known to be spoilt:
    // a frame judged on it may be captured again for nothing (frame 6 here), which costs a
    // frame's time and changes nothing else.
    assert!(view.recaptured.len() <= 4, "{:#?}", view.recaptured);
    let nine = view.recaptured.iter().find(|m| m.starts_with("frame 9 ("));
    assert!(
        nine.is_some_and(|m| m.contains("after 100 ms")),
        "{:#?}",
        view.recaptured
    );
    assert!(view.recaptured[0].contains("captured again after 50 ms"));
    assert_eq!(
        settle,
        Duration::from_millis(100),
        "the wait the session learned"
    );
}

/// The path of frame `k` of a session view in `dir`, as a message names it.
fn session_file(dir: &Path, k: usize) -> String {
    dir.join(format!("{k:03}.png")).display().to_string()
}
