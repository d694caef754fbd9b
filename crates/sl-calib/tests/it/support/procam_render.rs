//! Board poses rendered by the virtual rig with the hybrid code on both projector axes, and
//! decoded: the input of a projector–camera calibration, with the rig's truth. Shared by
//! `tests/it/procam.rs`, `tests/it/rig_calibration_truth.rs` and `benches/procam.rs` (which
//! includes it with `#[path]`).

// The bench reads the views only; the truth is for the tests.
#![allow(dead_code)]

use std::time::Instant;

use sl_calib::ProcamView;
use sl_codec::{
    Axis, BitDepth, CaptureSet, DecodeConfig, Frame, Frames, HybridSpec, ImageSize, Pattern,
    PatternSequence, decode,
};
use sl_sim::{BoardTruth, CalibrationCaptures, CalibrationSession, RigConfig, Scene, VirtualRig};

/// Electrons per grey level of the default sensor (10 000 e⁻ full well over 255 levels):
/// read noise of this many electrons is 1 grey level, as in `tests/it/virtual_rig.rs`.
const ONE_GREY_LEVEL_E: f64 = 10_000.0 / 255.0;

/// Views, their truth and the rig.
pub(crate) struct Rendered {
    pub(crate) views: Vec<ProcamView>,
    pub(crate) truth: Vec<BoardTruth>,
    pub(crate) config: RigConfig,
}

/// `count` board poses (seeded) with the hybrid code (8-step phase shift + complementary Gray
/// code) on both projector axes, decoded.
pub(crate) fn render(count: usize, seed: u64) -> Rendered {
    let mut config = RigConfig::default();
    config.render.effects.sensor.photon_noise = false;
    config.render.effects.sensor.read_noise_electrons = ONE_GREY_LEVEL_E;
    // 8 phase steps, ~30 projector px per period on both axes.
    let p = ImageSize::new(config.projector.size.width, config.projector.size.height);
    let sequence = PatternSequence::new(p)
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Column,
            p,
            8,
            64.0,
        )))
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Row,
            p,
            8,
            36.0,
        )));
    render_with(config, Scene::sphere(), &sequence, count, seed)
}

/// `count` board poses (seeded) of the rig `config` with `scene` on the turntable under
/// `sequence`, decoded; the captures are those of `sl_sim::CalibrationCaptures` (noise key =
/// pose number), as `sl_scan::calibrate_virtual`'s.
pub(crate) fn render_with(
    config: RigConfig,
    scene: Scene,
    sequence: &PatternSequence,
    count: usize,
    seed: u64,
) -> Rendered {
    let manifest = sequence.manifest(BitDepth::Eight);
    let rig = VirtualRig::new(config.clone(), scene).unwrap();
    let session = CalibrationSession::with_poses(count, seed);
    let captures = CalibrationCaptures::new(&rig, &session).unwrap();
    let mut views = Vec::new();
    let mut truth = Vec::new();
    let t = Instant::now();
    for k in 0..captures.poses().len() {
        let cap = captures.hand_held(k, Some(sequence)).unwrap();
        let frames: Vec<Frame<u8>> = cap.frames.into_iter().map(|img| img.into_u8()).collect();
        let set = CaptureSet::from_frames(manifest.clone(), Frames::U8(frames)).unwrap();
        let map = decode(&set, &DecodeConfig::default()).unwrap();
        views.push(ProcamView {
            name: format!("pose {k}"),
            lit: cap.white.into_u8(),
            map,
        });
        truth.push(cap.board);
    }
    eprintln!(
        "rendered and decoded {count} poses x {} frames in {:.1} s",
        sequence.frame_count(),
        t.elapsed().as_secs_f64()
    );
    Rendered {
        views,
        truth,
        config,
    }
}
