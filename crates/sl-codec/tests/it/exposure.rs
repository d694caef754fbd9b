//! Exposure fusion and the choice of exposures, on synthetic captures of a scene whose albedo
//! spans two decades (0.01 to 1): no single exposure both keeps the white parts unsaturated and
//! lifts the black ones out of the noise. The truth is the scene's own projector coordinate of
//! each pixel.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sl_codec::{
    AutoExposureConfig, Axis, BitDepth, CaptureSet, CodecError, CorrespondenceMap, DecodeConfig,
    ExposureChoice, ExposureFrames, Frame, Frames, FusionConfig, FusionMethod, GreyImage,
    HybridSpec, ImageSize, Pattern, PatternSequence, SATURATED_EVERYWHERE, SyntheticScene,
    choose_exposures, decode, fuse_exposures,
};

fn projector() -> ImageSize {
    ImageSize::new(640, 400)
}

fn sequence() -> PatternSequence {
    PatternSequence::new(projector()).with(Pattern::Hybrid(HybridSpec::complementary(
        Axis::Column,
        projector(),
        4,
        16.0,
    )))
}

/// The scene at an exposure `scale` times the base one: the gain (grey levels of white at
/// albedo 1) scales, the noise (2 levels, read noise) does not; each exposure its own noise.
fn scene(scale: f64, seed: u64) -> SyntheticScene {
    SyntheticScene {
        gain: 100.0 * scale,
        albedo_min: 0.01,
        albedo_max: 1.0,
        noise_sigma: 2.0,
        ambient: 2.0,
        blur: 0.5,
        seed,
        ..SyntheticScene::window(projector(), 200, 140, 1.5)
    }
}

fn frames(scale: f64, seed: u64) -> Vec<GreyImage> {
    let f: Vec<Frame<u8>> = scene(scale, seed).render(&sequence()).unwrap();
    f.into_iter().map(GreyImage::U8).collect()
}

fn decode_images(images: Vec<GreyImage>) -> CorrespondenceMap {
    let set = CaptureSet::from_frames(
        sequence().manifest(BitDepth::Eight),
        Frames::from_images(images),
    )
    .unwrap();
    decode(&set, &DecodeConfig::default()).unwrap()
}

/// Pixels decoded, and the RMS column error (projector pixels) of those decoded in `mask`
/// (every pixel when `None`), against the scene's truth.
fn score(map: &CorrespondenceMap, mask: Option<&[bool]>) -> (usize, f64) {
    let truth = scene(1.0, 0);
    let (mut n, mut sum, mut count) = (0, 0.0, 0usize);
    for y in 0..map.height {
        for x in 0..map.width {
            let c = map.get(x, y).unwrap();
            if !(c.invalid.is_valid() && c.col.is_finite()) {
                continue;
            }
            n += 1;
            if mask.is_none_or(|m| m[y * map.width + x]) {
                let (u, _) = truth.projector_point(x as f64, y as f64);
                sum += (f64::from(c.col) - u).powi(2);
                count += 1;
            }
        }
    }
    (n, (sum / count.max(1) as f64).sqrt())
}

fn valid_mask(map: &CorrespondenceMap) -> Vec<bool> {
    (0..map.height)
        .flat_map(|y| (0..map.width).map(move |x| (x, y)))
        .map(|(x, y)| map.get(x, y).unwrap().invalid.is_valid())
        .collect()
}

#[test]
fn fused_exposures_decode_more_pixels_and_no_worse_than_the_best_single_exposure() {
    // Base exposure: white at 100 levels; ×4 saturates every pixel above albedo ~0.6, ×16
    // every one above ~0.15 but lifts the darkest (0.01) to ~16 levels.
    let scales = [1.0, 4.0, 16.0];
    let stacks: Vec<ExposureFrames> = scales
        .iter()
        .enumerate()
        .map(|(i, &s)| ExposureFrames {
            exposure_ms: 5.0 * s,
            frames: frames(s, 100 + i as u64),
        })
        .collect();
    let singles: Vec<CorrespondenceMap> = stacks
        .iter()
        .map(|e| decode_images(e.frames.clone()))
        .collect();
    for method in [FusionMethod::Longest, FusionMethod::Radiance] {
        let config = FusionConfig {
            method,
            ..FusionConfig::default()
        };
        // Given longest first: the order does not matter.
        let reversed: Vec<ExposureFrames> = stacks.iter().rev().cloned().collect();
        let fused = fuse_exposures(&reversed, &config).unwrap();
        assert_eq!(fused.summary.exposures_ms, vec![5.0, 20.0, 80.0]);
        // Every exposure serves some pixels: the bright ones the shortest, the dark the longest.
        assert!(
            fused.summary.pixels.iter().all(|&n| n > 1000),
            "{method:?}: {:?}",
            fused.summary.pixels
        );
        assert_eq!(fused.summary.saturated_everywhere, 0);
        let map = decode_images(fused.frames);
        let (n_fused, rms_fused) = score(&map, None);
        // The figures of docs/performance.md ("Dark and shiny objects": the synthetic plane).
        eprintln!(
            "{method:?}: {n_fused} pixels, RMS {rms_fused:.4} px; alone: {}",
            singles
                .iter()
                .zip(&stacks)
                .map(|(m, e)| {
                    let (n, rms) = score(m, None);
                    format!("{} ms {n} pixels, RMS {rms:.4} px", e.exposure_ms)
                })
                .collect::<Vec<_>>()
                .join("; ")
        );
        for (single, e) in singles.iter().zip(&stacks) {
            let (n, _) = score(single, None);
            assert!(
                n_fused > n,
                "{method:?}: fused decodes {n_fused} pixels, {} ms alone {n}",
                e.exposure_ms
            );
            // Where the single exposure decodes too, the fused capture is as accurate.
            let mask = valid_mask(single);
            let (_, rms_single) = score(single, Some(&mask));
            let (_, rms_both) = score(&map, Some(&mask));
            assert!(
                rms_both <= rms_single * 1.05 + 0.002,
                "{method:?}: where {} ms decodes, fused {rms_both:.4} px against {rms_single:.4} px",
                e.exposure_ms
            );
        }
        assert!(rms_fused < 0.2, "{method:?}: {rms_fused}");
    }
}

#[test]
fn longest_fusion_keeps_each_pixels_samples_from_one_exposure() {
    let short = frames(1.0, 1);
    let long = frames(16.0, 2);
    let fused = fuse_exposures(
        &[
            ExposureFrames {
                exposure_ms: 1.0,
                frames: short.clone(),
            },
            ExposureFrames {
                exposure_ms: 16.0,
                frames: long.clone(),
            },
        ],
        &FusionConfig::default(),
    )
    .unwrap();
    let (w, h) = (short[0].width(), short[0].height());
    let mut seen = [0usize; 2];
    for y in 0..h {
        for x in 0..w {
            let source = fused.source[y * w + x];
            let from = if source == 1 { &long } else { &short };
            let saturated_long = long.iter().any(|f| f.get(x, y).unwrap() >= 255);
            // The long exposure exactly where none of its samples saturates.
            assert_eq!(source == 1, !saturated_long, "pixel ({x}, {y})");
            assert_ne!(source, SATURATED_EVERYWHERE);
            seen[usize::from(source)] += 1;
            for (k, f) in fused.frames.iter().enumerate() {
                assert_eq!(f.get(x, y), from[k].get(x, y), "frame {k} at ({x}, {y})");
            }
        }
    }
    assert!(seen[0] > 0 && seen[1] > 0, "{seen:?}");
}

#[test]
fn fusion_refuses_what_cannot_be_fused_by_name() {
    let a = frames(1.0, 1);
    let ok = |ms: f64, frames: Vec<GreyImage>| ExposureFrames {
        exposure_ms: ms,
        frames,
    };
    let cfg = FusionConfig::default();
    let err = |stacks: &[ExposureFrames]| fuse_exposures(stacks, &cfg).unwrap_err().to_string();
    assert!(err(&[]).contains("exposures"));
    assert!(err(&[ok(0.0, a.clone())]).contains("exposures[0].exposure_ms"));
    assert!(err(&[ok(2.0, a.clone()), ok(2.0, a.clone())]).contains("both 2 ms"));
    let short = a[..a.len() - 1].to_vec();
    let e = err(&[ok(1.0, a.clone()), ok(4.0, short)]);
    assert!(
        e.contains("exposure 1 (4 ms)") && e.contains("frames"),
        "{e}"
    );
    let mut small = a.clone();
    small[3] = GreyImage::filled_u8(10, 10, 0).unwrap();
    let e = fuse_exposures(&[ok(1.0, a.clone()), ok(4.0, small)], &cfg).unwrap_err();
    assert!(
        matches!(&e, CodecError::FrameSize { frame, .. } if frame == "#3 of exposure 1 (4 ms)"),
        "{e}"
    );
    let mut deep = a.clone();
    deep[2] = GreyImage::U16(deep[2].clone().into_u16());
    let e = err(&[ok(1.0, a.clone()), ok(4.0, deep)]);
    assert!(
        e.contains("frame #2 of exposure 1") && e.contains("16-bit"),
        "{e}"
    );
    let bad = FusionConfig {
        dark_level: 300.0,
        ..cfg
    };
    assert!(
        fuse_exposures(&[ok(1.0, a)], &bad)
            .unwrap_err()
            .to_string()
            .contains("dark_level")
    );
}

/// A white and a black frame of the scene at exposure `scale`.
fn white_black(scale: f64) -> (GreyImage, GreyImage) {
    let s = scene(scale, 7);
    let seq = PatternSequence::new(projector()).with(Pattern::Gray(sl_codec::GrayCodeSpec {
        reference: sl_codec::GrayReference::WhiteBlack,
        ..sl_codec::GrayCodeSpec::per_pixel(Axis::Column, projector(), false)
    }));
    let f: Vec<Frame<u8>> = s.render(&seq).unwrap();
    // WhiteBlack puts the white and the black reference frames first.
    (GreyImage::U8(f[0].clone()), GreyImage::U8(f[1].clone()))
}

#[test]
fn chosen_exposures_span_the_scene_from_its_white_frame() {
    let cfg = AutoExposureConfig::default();
    // At ×16 the white parts saturate: measure again, shorter.
    let (w, b) = white_black(16.0);
    match choose_exposures(&w, &b, 80.0, &cfg).unwrap() {
        ExposureChoice::MeasureAgain {
            exposure_ms,
            reason,
        } => {
            assert_eq!(exposure_ms, 20.0);
            assert!(reason.contains("saturate"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
    // At ×1 nothing saturates: the shortest puts the brightest at ~0.9 of full scale (white
    // at albedo 1 reads 100 + 2 levels, 0.4 of full scale above the black: ×2.2), the longest
    // the darkest lit at 0.5.
    let (w, b) = white_black(1.0);
    let ExposureChoice::Chosen(plan) = choose_exposures(&w, &b, 5.0, &cfg).unwrap() else {
        panic!("a choice expected");
    };
    let t = &plan.exposures_ms;
    assert!((t[0] / 5.0 - 2.2).abs() < 0.3, "{t:?}");
    assert!(t.len() >= 2 && t.len() <= cfg.max_exposures, "{t:?}");
    assert!(
        t.windows(2).all(|p| p[1] / p[0] <= cfg.step + 1e-9),
        "{t:?}"
    );
    // The longest lifts the darkest lit pixels (a quantile of `dark_share`) to about half of
    // full scale, or stops at the most the steps allow.
    let most = t[0] * cfg.step.powi(cfg.max_exposures as i32 - 1);
    let dark_at_longest = plan.dark * t[t.len() - 1] / 5.0;
    assert!(
        (dark_at_longest - cfg.dark_level).abs() < 0.05 || (t[t.len() - 1] - most).abs() < 1e-6,
        "{plan:?}"
    );
    // A scene with nothing lit asks for a longer exposure, and at the longest says why.
    let dark = GreyImage::filled_u8(w.width(), w.height(), 3).unwrap();
    assert!(matches!(
        choose_exposures(&dark, &dark, 5.0, &cfg).unwrap(),
        ExposureChoice::MeasureAgain { exposure_ms, .. } if exposure_ms == 20.0
    ));
    let e = choose_exposures(&dark, &dark, 1000.0, &cfg)
        .unwrap_err()
        .to_string();
    assert!(e.contains("projector"), "{e}");
    let e = choose_exposures(&w, &b, -1.0, &cfg)
        .unwrap_err()
        .to_string();
    assert!(e.contains("exposure_ms"), "{e}");
}
