//! Round trips on synthetic captures: encode -> simulated camera (noise, blur, ambient light,
//! low albedo, global illumination, shadow) -> decode, compared with the camera's ground-truth
//! projector coordinates, for every codec.
// Helpers outside #[test] functions unwrap too: a panic there is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sl_codec::{
    Axis, BitDepth, CaptureSet, CorrespondenceMap, DecodeConfig, Frames, GrayCodeSpec,
    GrayReference, HybridSpec, ImageSize, InvalidReason, Pattern, PatternSequence, PhaseShiftSpec,
    Sample, SyntheticScene, Unwrap, decode,
};

/// Errors of one decoded axis against the scene's ground truth.
struct Stats {
    /// Pixels lit by the projector (ground truth), excluding a border of 2 pixels.
    lit: usize,
    /// Of those, pixels decoded valid.
    valid: usize,
    /// Absolute errors of the valid pixels, sorted.
    errors: Vec<f64>,
    /// Valid pixels where the projector does not reach (must be 0).
    valid_unlit: usize,
}

impl Stats {
    fn valid_fraction(&self) -> f64 {
        self.valid as f64 / self.lit.max(1) as f64
    }
    fn quantile(&self, q: f64) -> f64 {
        if self.errors.is_empty() {
            return f64::NAN;
        }
        self.errors[((self.errors.len() - 1) as f64 * q).round() as usize]
    }
    fn max(&self) -> f64 {
        self.errors.last().copied().unwrap_or(0.0)
    }
    fn rms(&self) -> f64 {
        (self.errors.iter().map(|e| e * e).sum::<f64>() / self.errors.len().max(1) as f64).sqrt()
    }
}

fn stats(scene: &SyntheticScene, map: &CorrespondenceMap, axis: Axis) -> Stats {
    let mut s = Stats {
        lit: 0,
        valid: 0,
        errors: Vec::new(),
        valid_unlit: 0,
    };
    for y in 2..map.height - 2 {
        for x in 2..map.width - 2 {
            let c = map.get(x, y).unwrap();
            let value = match axis {
                Axis::Column => c.col,
                Axis::Row => c.row,
            };
            // A pixel is "lit" when its whole 5x5 neighbourhood is: the edges of the shadow
            // and of the projector are shared between lit and unlit.
            let lit = (0..5).all(|dy| (0..5).all(|dx| scene.is_lit(x + dx - 2, y + dy - 2)));
            let unlit = !scene.is_lit(x, y);
            if lit {
                s.lit += 1;
            }
            if c.invalid.is_valid() && value.is_finite() {
                if unlit {
                    s.valid_unlit += 1;
                }
                if lit {
                    s.valid += 1;
                    let (u, v) = scene.projector_point(x as f64, y as f64);
                    let truth = match axis {
                        Axis::Column => u,
                        Axis::Row => v,
                    };
                    s.errors.push((f64::from(value) - truth).abs());
                }
            }
        }
    }
    s.errors.sort_by(f64::total_cmp);
    s
}

fn run<T: Sample>(
    sequence: &PatternSequence,
    scene: &SyntheticScene,
    config: &DecodeConfig,
) -> CorrespondenceMap
where
    Vec<sl_codec::Frame<T>>: Into<FramesOf>,
{
    let frames: Vec<sl_codec::Frame<T>> = scene.render(sequence).unwrap();
    let capture =
        CaptureSet::from_frames(sequence.manifest(BitDepth::Eight), frames.into().0).unwrap();
    decode(&capture, config).unwrap()
}

/// Lets `run` build `Frames` from either depth.
struct FramesOf(Frames);
impl From<Vec<sl_codec::Frame<u8>>> for FramesOf {
    fn from(v: Vec<sl_codec::Frame<u8>>) -> Self {
        Self(Frames::U8(v))
    }
}
impl From<Vec<sl_codec::Frame<u16>>> for FramesOf {
    fn from(v: Vec<sl_codec::Frame<u16>>) -> Self {
        Self(Frames::U16(v))
    }
}

/// The hard scene: 2 grey levels of noise, 1 px of defocus, ambient light, albedo from 0.3 to
/// 1, 30% global illumination, and a cast shadow.
fn hard_scene(projector: ImageSize, scale: f64) -> SyntheticScene {
    SyntheticScene {
        noise_sigma: 2.0,
        blur: 1.0,
        ambient: 15.0,
        albedo_min: 0.3,
        albedo_max: 1.0,
        global: 0.3,
        global_radius: 60.0,
        shadow: Some([40, 30, 90, 70]),
        seed: 42,
        ..SyntheticScene::window(projector, 240, 160, scale)
    }
}

/// Phase noise predicted for the darkest pixels: `sigma_phi = sqrt(2/N) sigma / B` with
/// `B = albedo_min * gain / 2` reduced by the blur's attenuation (a box of width w attenuates a
/// sinusoid of period L by sinc(w / L)); returned in projector pixels for period `lambda`.
fn predicted_sigma_px(scene: &SyntheticScene, steps: u32, lambda: f64, footprint: f64) -> f64 {
    let w = footprint + scene.blur;
    let x = std::f64::consts::PI * w / lambda;
    let sinc = x.sin() / x;
    let b = scene.albedo_min * scene.gain / 2.0 * sinc;
    let sigma_phi = (2.0 / f64::from(steps)).sqrt() * scene.noise_sigma / b;
    lambda * sigma_phi / std::f64::consts::TAU
}

#[test]
fn gray_code_both_axes_on_a_hard_scene() {
    let p = ImageSize::new(1920, 1080);
    let seq = PatternSequence::new(p)
        .with(Pattern::Gray(GrayCodeSpec::per_pixel(
            Axis::Column,
            p,
            true,
        )))
        .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Row, p, true)));
    let scene = hard_scene(p, 1.2);
    let map = run::<u8>(&seq, &scene, &DecodeConfig::default());
    for axis in [Axis::Column, Axis::Row] {
        let s = stats(&scene, &map, axis);
        eprintln!(
            "gray {axis:?}: valid {:.3}, p50 {:.3} p95 {:.3} max {:.3}",
            s.valid_fraction(),
            s.quantile(0.5),
            s.quantile(0.95),
            s.max()
        );
        // Gray precision: the stripe centre is within 0.5 px of the truth, the footprint
        // (1.2 px) and defocus (1 px) widen that to ~1.1 px at an edge read by majority;
        // anything past 1.6 px would be a wrongly read bit.
        assert!(s.max() <= 1.6, "{axis:?}: max error {}", s.max());
        assert!(
            s.quantile(0.5) <= 0.5,
            "{axis:?}: median error {}",
            s.quantile(0.5)
        );
        assert!(
            s.valid_fraction() > 0.75,
            "{axis:?}: valid {}",
            s.valid_fraction()
        );
        assert_eq!(s.valid_unlit, 0, "{axis:?}: valid pixels in the shadow");
    }
    // The shadow shows up as Shadow or LowModulation (ambient + global light, no direct light).
    let c = map.get(65, 50).unwrap();
    assert!(
        matches!(
            c.invalid,
            InvalidReason::Shadow | InvalidReason::LowModulation
        ),
        "{:?}",
        c.invalid
    );
}

#[test]
fn gray_code_variants() {
    // White/black references, plain binary, not centred, 16-bit frames, non-power-of-two sizes.
    let p = ImageSize::new(1824, 1140);
    let mut col = GrayCodeSpec::per_pixel(Axis::Column, p, false);
    col.reference = GrayReference::WhiteBlack;
    let mut row = GrayCodeSpec::per_pixel(Axis::Row, p, true);
    row.binary = true;
    let seq = PatternSequence::new(p)
        .with(Pattern::Gray(col))
        .with(Pattern::Gray(row));
    let scene = SyntheticScene {
        noise_sigma: 1.5,
        ambient: 10.0,
        albedo_min: 0.5,
        ..SyntheticScene::window(p, 200, 150, 1.1)
    };
    let map = run::<u16>(&seq, &scene, &DecodeConfig::default());
    for axis in [Axis::Column, Axis::Row] {
        let s = stats(&scene, &map, axis);
        eprintln!(
            "gray variants {axis:?}: valid {:.3} max {:.3}",
            s.valid_fraction(),
            s.max()
        );
        assert!(s.max() <= 1.6, "{axis:?}: max error {}", s.max());
        // Plain binary flips several bits at once at some edges, so it loses more pixels.
        assert!(
            s.valid_fraction() > 0.6,
            "{axis:?}: valid {}",
            s.valid_fraction()
        );
    }
}

#[test]
fn robust_classification_rejects_what_global_light_corrupts() {
    // An inter-reflection brings 1.3x the direct light from a 200-px region 100 projector pixels
    // away (a concave corner). Where a coarse bit lights that region but not the pixel, the
    // "unlit" sample is brighter than the "lit" one, and plain comparison reads the bit wrong.
    // Xu & Aliaga's rules must turn those pixels into "unreadable" instead of wrong codes.
    let p = ImageSize::new(1920, 1080);
    let seq = PatternSequence::new(p).with(Pattern::Gray(GrayCodeSpec::per_pixel(
        Axis::Column,
        p,
        true,
    )));
    let scene = SyntheticScene {
        global: 1.3,
        global_radius: 100.0,
        global_offset: 100.0,
        noise_sigma: 1.0,
        gain: 100.0,
        // 240 px at 1.2 px each: columns 816..1104, so the far wall (u .. u + 200) stays
        // inside the projector.
        ..SyntheticScene::window(p, 240, 160, 1.2)
    };
    let robust = stats(
        &scene,
        &run::<u8>(&seq, &scene, &DecodeConfig::default()),
        Axis::Column,
    );
    let plain_cfg = DecodeConfig {
        robust: false,
        ..DecodeConfig::default()
    };
    let plain = stats(&scene, &run::<u8>(&seq, &scene, &plain_cfg), Axis::Column);
    let gross = |s: &Stats| s.errors.iter().filter(|&&e| e > 2.0).count();
    eprintln!(
        "global 1.3 from 100 px away: robust valid {:.3} gross {}; plain valid {:.3} gross {}",
        robust.valid_fraction(),
        gross(&robust),
        plain.valid_fraction(),
        gross(&plain)
    );
    assert_eq!(gross(&robust), 0);
    assert!(
        gross(&plain) > 0,
        "the scene should defeat plain comparison somewhere"
    );
    // A deliberately hostile scene: only pixels whose far wall is lit with them by every coarse
    // bit can be read at all (about a tenth).
    assert!(
        robust.valid_fraction() > 0.05,
        "valid {}",
        robust.valid_fraction()
    );
}

fn check_phase(
    name: &str,
    seq: &PatternSequence,
    scene: &SyntheticScene,
    axis: Axis,
    lambda: f64,
    steps: u32,
    footprint: f64,
) {
    let map = run::<u8>(seq, scene, &DecodeConfig::default());
    let s = stats(scene, &map, axis);
    let sigma = predicted_sigma_px(scene, steps, lambda, footprint);
    eprintln!(
        "{name}: valid {:.3}, rms {:.3} (predicted worst-pixel sigma {sigma:.3}), p99 {:.3}, max {:.3}",
        s.valid_fraction(),
        s.rms(),
        s.quantile(0.99),
        s.max()
    );
    // The predicted sigma is that of the darkest pixels, so the rms over all pixels must be
    // below it (plus 0.05 px for 8-bit pattern quantisation and the projector's pixel steps);
    // the maximum below 6 sigma means no period was lost.
    assert!(s.rms() <= sigma + 0.05, "{name}: rms {} > {sigma}", s.rms());
    assert!(
        s.max() <= 6.0 * sigma + 0.1,
        "{name}: max {} > 6 sigma ({sigma})",
        s.max()
    );
    assert!(
        s.valid_fraction() > 0.9,
        "{name}: valid {}",
        s.valid_fraction()
    );
    assert_eq!(s.valid_unlit, 0, "{name}: valid pixels in the shadow");
}

#[test]
fn heterodyne_phase_on_a_hard_scene() {
    let p = ImageSize::new(1920, 1080);
    let seq = PatternSequence::new(p).with(Pattern::Phase(PhaseShiftSpec::new(
        Axis::Column,
        p,
        4,
        vec![64.0, 58.0, 53.0],
        Unwrap::Heterodyne,
    )));
    check_phase(
        "heterodyne",
        &seq,
        &hard_scene(p, 1.2),
        Axis::Column,
        30.0,
        4,
        1.2,
    );
}

#[test]
fn hierarchical_phase_rows() {
    let p = ImageSize::new(800, 600);
    let seq = PatternSequence::new(p).with(Pattern::Phase(PhaseShiftSpec::new(
        Axis::Row,
        p,
        5,
        vec![1.0, 6.0, 37.5],
        Unwrap::Hierarchical,
    )));
    check_phase(
        "hierarchical",
        &seq,
        &hard_scene(p, 1.3),
        Axis::Row,
        600.0 / 37.5,
        5,
        1.3,
    );
}

#[test]
fn number_theoretic_phase() {
    // Coprime 11 and 13 periods locate the pixel; 48 periods refine. The pair tolerates
    // 0.25 / (11 + 13) cycles of phase error: less noise than the hard scene.
    let p = ImageSize::new(800, 600);
    let seq = PatternSequence::new(p).with(Pattern::Phase(PhaseShiftSpec::new(
        Axis::Column,
        p,
        6,
        vec![11.0, 13.0, 48.0],
        Unwrap::NumberTheoretic,
    )));
    let scene = SyntheticScene {
        noise_sigma: 1.0,
        albedo_min: 0.6,
        ..hard_scene(p, 1.2)
    };
    check_phase(
        "number-theoretic",
        &seq,
        &scene,
        Axis::Column,
        800.0 / 48.0,
        6,
        1.2,
    );
}

#[test]
fn hybrid_complementary_on_a_hard_scene() {
    let p = ImageSize::new(1920, 1080);
    let seq = PatternSequence::new(p)
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Column,
            p,
            4,
            48.0,
        )))
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Row,
            p,
            4,
            27.5,
        )));
    let scene = hard_scene(p, 1.2);
    check_phase("hybrid column", &seq, &scene, Axis::Column, 40.0, 4, 1.2);
    check_phase("hybrid row", &seq, &scene, Axis::Row, 1080.0 / 27.5, 4, 1.2);
}

#[test]
fn hybrid_with_white_black_and_phase_mean_references() {
    let p = ImageSize::new(800, 600);
    let mut col = HybridSpec::complementary(Axis::Column, p, 3, 16.0);
    col.gray.reference = GrayReference::WhiteBlack;
    let mut row = HybridSpec::complementary(Axis::Row, p, 4, 12.0);
    row.gray.reference = GrayReference::PhaseMean;
    let seq = PatternSequence::new(p)
        .with(Pattern::Hybrid(col))
        .with(Pattern::Hybrid(row));
    let scene = SyntheticScene {
        global: 0.1,
        ..hard_scene(p, 1.2)
    };
    check_phase(
        "hybrid white/black",
        &seq,
        &scene,
        Axis::Column,
        50.0,
        3,
        1.2,
    );
    check_phase("hybrid phase-mean", &seq, &scene, Axis::Row, 50.0, 4, 1.2);
}

#[test]
fn gamma_pre_compensation_removes_the_harmonic_error() {
    // A projector with gamma 2.2 distorts the fringes; 3-step phase shift, which aliases the
    // second harmonic onto the fundamental, then shows a ripple at three times the fringe
    // frequency. Pre-compensating the patterns removes it.
    let p = ImageSize::new(800, 600);
    let spec = PhaseShiftSpec::new(
        Axis::Column,
        p,
        3,
        vec![1.0, 8.0, 40.0],
        Unwrap::Hierarchical,
    );
    let scene = SyntheticScene {
        projector_gamma: 2.2,
        pattern_depth: BitDepth::Sixteen,
        ..SyntheticScene::window(p, 160, 120, 1.2)
    };
    let rms = |gamma: f64| {
        let seq = PatternSequence::new(p).with(Pattern::Phase(PhaseShiftSpec {
            gamma,
            ..spec.clone()
        }));
        stats(
            &scene,
            &run::<u16>(&seq, &scene, &DecodeConfig::default()),
            Axis::Column,
        )
        .rms()
    };
    let (raw, compensated) = (rms(1.0), rms(2.2));
    eprintln!("gamma 2.2: rms {raw:.4} px uncompensated, {compensated:.4} px compensated");
    // 0.05 px: the floor of pattern quantisation and of the projector's pixel steps seen
    // through a 1.2-px footprint, as in the other phase tests.
    assert!(compensated < 0.05, "{compensated}");
    assert!(raw > 5.0 * compensated, "{raw} vs {compensated}");
}

#[test]
fn a_known_response_corrects_the_phase() {
    // A projector with a gamma of 2.2, its response known (`slscan calibrate response`):
    // corrected by the decoder (`DecodeConfig::projector_response`), or pre-compensated in
    // the patterns (`precompensation`, the decoder told as well: it must not correct twice),
    // against a linear projector's decode of the same scene (noise, ambient light, albedo
    // from 0.3 to 1, the camera's 1.2-px footprint and 1 px of blur). 3 and 4 steps, a phase
    // block and the scan's hybrid code.
    let p = ImageSize::new(800, 600);
    let gamma = sl_codec::ToneCurve::power(2.2).unwrap();
    for steps in [3, 4] {
        let phase = Pattern::Phase(PhaseShiftSpec::new(
            Axis::Column,
            p,
            steps,
            vec![1.0, 8.0, 40.0],
            Unwrap::Hierarchical,
        ));
        let hybrid = Pattern::Hybrid(HybridSpec::complementary(Axis::Column, p, steps, 40.0));
        for (name, pattern) in [("phase", phase), ("hybrid", hybrid)] {
            let plain = PatternSequence::new(p).with(pattern);
            let compensated = plain.clone().precompensated(&gamma);
            let rms = |seq: &PatternSequence, projector: f64, known: bool| {
                let scene = SyntheticScene {
                    projector_gamma: projector,
                    noise_sigma: 1.0,
                    ambient: 15.0,
                    albedo_min: 0.3,
                    blur: 1.0,
                    seed: 7,
                    ..SyntheticScene::window(p, 240, 160, 1.2)
                };
                let config = DecodeConfig {
                    projector_response: known.then(|| gamma.clone()),
                    ..DecodeConfig::default()
                };
                stats(&scene, &run::<u8>(seq, &scene, &config), Axis::Column).rms()
            };
            let linear = rms(&plain, 1.0, false);
            let raw = rms(&plain, 2.2, false);
            let corrected = rms(&plain, 2.2, true);
            let precompensated = rms(&compensated, 2.2, true);
            eprintln!(
                "{name}, {steps} steps: rms {linear:.4} px linear projector; gamma 2.2: {raw:.4} px raw, {corrected:.4} px corrected at decode, {precompensated:.4} px pre-compensated"
            );
            // Pre-compensated: within 10 % of the linear projector (plus 2 thousandths of a
            // pixel for the 8-bit patterns' coarser steps in the dark half).
            assert!(
                precompensated <= 1.1 * linear + 0.002,
                "{name} {steps}: {precompensated} vs {linear}"
            );
            // Corrected at decode: most of the error gone. Not all: the table assumes the
            // harmonics reach the camera whole, and the blur after the projector's response
            // damps them (the higher, the more), so the table over-corrects a little.
            assert!(
                corrected - linear <= 0.2 * (raw - linear),
                "{name} {steps}: {corrected} vs {raw} and {linear}"
            );
            // What there is to correct: 3 steps alias the 2nd harmonic (a tenfold error), 4
            // steps only the 3rd and 5th (about a tenth more than a linear projector's).
            let worse = if steps == 3 { 3.0 } else { 1.05 };
            assert!(raw > worse * linear, "{name} {steps}: {raw} vs {linear}");
        }
    }
}

#[test]
fn wrong_frame_count_and_size_are_named() {
    let p = ImageSize::new(64, 32);
    let seq = PatternSequence::new(p).with(Pattern::Gray(GrayCodeSpec::per_pixel(
        Axis::Column,
        p,
        true,
    )));
    let scene = SyntheticScene::window(p, 32, 16, 1.0);
    let mut frames: Vec<sl_codec::Frame<u8>> = scene.render(&seq).unwrap();
    let manifest = seq.manifest(BitDepth::Eight);
    let last = frames.pop().unwrap();
    let e = CaptureSet::from_frames(manifest.clone(), Frames::U8(frames.clone())).unwrap_err();
    assert!(e.to_string().contains("12 frames, 11 were given"), "{e}");
    frames.push(sl_codec::Frame::filled(33, 16, 0u8).unwrap());
    let e = CaptureSet::from_frames(manifest.clone(), Frames::U8(frames.clone())).unwrap_err();
    assert!(
        e.to_string().contains("#11") && e.to_string().contains("33x16"),
        "{e}"
    );
    frames.pop();
    frames.push(last);
    assert!(CaptureSet::from_frames(manifest, Frames::U8(frames)).is_ok());
}

#[test]
fn saturation_is_reported() {
    // Phase: a gain of 400 grey levels clips the bright half of every fringe, which distorts the
    // phase; those pixels must be Saturated, not decoded wrongly.
    let p = ImageSize::new(800, 600);
    let seq = PatternSequence::new(p).with(Pattern::Phase(PhaseShiftSpec::new(
        Axis::Column,
        p,
        4,
        vec![1.0, 8.0, 40.0],
        Unwrap::Hierarchical,
    )));
    let scene = SyntheticScene {
        gain: 400.0,
        albedo_min: 0.2,
        ..SyntheticScene::window(p, 120, 90, 1.2)
    };
    let map = run::<u8>(&seq, &scene, &DecodeConfig::default());
    let counts = map.reason_counts();
    let saturated = counts[InvalidReason::Saturated as usize];
    assert!(saturated > 1000, "{counts:?}");
    // Where the albedo keeps the peak below 255 the pixels still decode, and correctly.
    let s = stats(&scene, &map, Axis::Column);
    assert!(s.valid > 200, "{counts:?}");
    assert!(s.max() < 0.2, "max error {}", s.max());
    // Gray code: ambient light alone at the top level leaves no bit readable.
    let seq = PatternSequence::new(p).with(Pattern::Gray(GrayCodeSpec::per_pixel(
        Axis::Column,
        p,
        true,
    )));
    let scene = SyntheticScene {
        ambient: 300.0,
        ..SyntheticScene::window(p, 60, 40, 1.2)
    };
    let map = run::<u8>(&seq, &scene, &DecodeConfig::default());
    assert!(map.invalid.iter().all(|&r| r == InvalidReason::Saturated));
}
