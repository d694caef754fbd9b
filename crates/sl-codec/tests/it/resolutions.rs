//! decode(capture(encode(x))) = x, to the codec's precision, for any projector resolution:
//! powers of two or not (800x600, 1824x1140, 1920x1080 and random sizes), any camera window.
// Helpers outside #[test] functions unwrap too: a panic there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use proptest::prelude::*;
use sl_codec::{
    Axis, CorrespondenceMap, DecodeConfig, Frame, GrayCodeSpec, HybridSpec, ImageSize, Pattern,
    PatternSequence, PhaseShiftSpec, SyntheticScene, Unwrap, decode_frames,
};

fn projector() -> impl Strategy<Value = ImageSize> {
    prop_oneof![
        Just(ImageSize::new(800, 600)),
        Just(ImageSize::new(1824, 1140)),
        Just(ImageSize::new(1920, 1080)),
        (200u32..2200, 150u32..1300).prop_map(|(w, h)| ImageSize::new(w, h)),
    ]
}

/// A 48x36 camera, `scale` projector pixels per camera pixel, its centre moved by a fraction
/// `(fx, fy)` of the room left on each side; no noise; 1 projector pixel of defocus, without
/// which a camera finer than the projector sees the projector's pixel steps (a sub-pixel phase
/// code then reads the centre of the projector pixel, up to 0.5 px off).
fn scene(p: ImageSize, scale: f64, fx: f64, fy: f64) -> SyntheticScene {
    let mut s = SyntheticScene {
        blur: 1.0,
        ..SyntheticScene::window(p, 48, 36, scale)
    };
    let room_x = (f64::from(p.width) - 60.0 * scale).max(0.0) / 2.0;
    let room_y = (f64::from(p.height) - 45.0 * scale).max(0.0) / 2.0;
    s.camera_to_projector[2] += fx * room_x;
    s.camera_to_projector[5] += fy * room_y;
    s
}

/// Largest error and number of invalid pixels over the pixels that see the projector with
/// their whole footprint (2 px clear of its border).
fn max_error(scene: &SyntheticScene, map: &CorrespondenceMap) -> (f64, usize) {
    let mut worst = 0.0_f64;
    let mut invalid = 0;
    let (w, h) = (
        f64::from(scene.projector.width),
        f64::from(scene.projector.height),
    );
    for y in 0..map.height {
        for x in 0..map.width {
            let (u, v) = scene.projector_point(x as f64, y as f64);
            if !(2.0..w - 3.0).contains(&u) || !(2.0..h - 3.0).contains(&v) {
                continue;
            }
            let c = map.get(x, y).unwrap();
            if !c.invalid.is_valid() {
                invalid += 1;
                continue;
            }
            worst = worst
                .max((f64::from(c.col) - u).abs())
                .max((f64::from(c.row) - v).abs());
        }
    }
    (worst, invalid)
}

fn decode_scene(seq: &PatternSequence, scene: &SyntheticScene) -> CorrespondenceMap {
    let frames: Vec<Frame<u8>> = scene.render(seq).unwrap();
    decode_frames(&seq.blocks, &frames, &DecodeConfig::default()).unwrap()
}

/// Precision of a noise-free phase code with fringes of `lambda` projector pixels, 8-bit
/// patterns and an 8-bit camera: each sample is off by at most 0.5 level of camera rounding plus
/// 0.5/255 of the pattern's range (0.4 level at gain 200), so the phase is off by at most
/// `N * 0.9 / (N/2 * B) = 1.8 / B` rad with a modulation `B` of about 95 levels: 0.019 rad, i.e.
/// `0.003 lambda` px. The projector's pixel steps, seen through a 0.8-2.5 px footprint, add up to
/// 0.08 px (measured with 16-bit patterns and camera, where quantisation is negligible).
fn phase_bound(lambda: f64) -> f64 {
    0.003 * lambda + 0.1
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn gray_code_recovers_the_pixel(p in projector(), scale in 0.8f64..1.5, fx in -1.0f64..1.0, fy in -1.0f64..1.0, centered in any::<bool>()) {
        let seq = PatternSequence::new(p)
            .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Column, p, centered)))
            .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Row, p, centered)));
        let s = scene(p, scale, fx, fy);
        let (worst, invalid) = max_error(&s, &decode_scene(&seq, &s));
        // Noise-free: a pixel decodes to the stripe (projector pixel) under most of its
        // footprint (scale, plus 1 px of defocus), or to an edge inside it: within half a pixel
        // plus half the footprint.
        prop_assert!(worst <= 0.5 + 0.5 * (scale * 1.05 + 1.0) + 1e-3, "worst {worst}");
        // Only pixels with two stripe edges under the footprint may be lost.
        prop_assert!(invalid * 20 <= 48 * 36, "{invalid} invalid");
    }

    #[test]
    fn heterodyne_recovers_sub_pixel(p in projector(), scale in 0.8f64..1.5, fx in -1.0f64..1.0, fy in -1.0f64..1.0) {
        // Fringes of ~16 px: P1 = extent / 16, beats P1 / 8 and P1 / 8 - 0.9, so P123 = 0.9:
        // the absolute beat spans 1.11 projector widths, which keeps pixels at the projector's
        // edges clear of its wrap (with P123 = 1 they sit on it and may be flagged).
        let periods = |extent: u32| {
            let p1 = f64::from(extent) / 16.0;
            let p12 = p1 / 8.0;
            vec![p1, p1 - p12, p1 - 2.0 * p12 + 0.9]
        };
        let seq = PatternSequence::new(p)
            .with(Pattern::Phase(PhaseShiftSpec::new(Axis::Column, p, 4, periods(p.width), Unwrap::Heterodyne)))
            .with(Pattern::Phase(PhaseShiftSpec::new(Axis::Row, p, 4, periods(p.height), Unwrap::Heterodyne)));
        let s = scene(p, scale, fx, fy);
        let (worst, invalid) = max_error(&s, &decode_scene(&seq, &s));
        prop_assert!(worst <= phase_bound(16.0), "worst {worst}");
        prop_assert_eq!(invalid, 0);
    }

    #[test]
    fn hybrid_recovers_sub_pixel(p in projector(), scale in 0.8f64..1.5, fx in -1.0f64..1.0, fy in -1.0f64..1.0, lambda in 12.0f64..64.0) {
        let seq = PatternSequence::new(p)
            .with(Pattern::Hybrid(HybridSpec::complementary(Axis::Column, p, 4, f64::from(p.width) / lambda)))
            .with(Pattern::Hybrid(HybridSpec::complementary(Axis::Row, p, 3, f64::from(p.height) / lambda)));
        let s = scene(p, scale, fx, fy);
        let (worst, invalid) = max_error(&s, &decode_scene(&seq, &s));
        prop_assert!(worst <= phase_bound(lambda), "worst {worst}");
        prop_assert_eq!(invalid, 0);
    }
}
