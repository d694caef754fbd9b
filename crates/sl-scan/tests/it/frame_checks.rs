//! Frames that lie, on rendered views of the virtual rig (the dumbbell on the platter, half
//! resolution, two sides, the recommended hybrid code): every frame in turn replaced by the
//! previous one (a late projector), by the view's darkest level (a projector that showed
//! nothing) and half replaced by the previous one (the camera exposed while the projector
//! updated), each named at its frame by `sl_codec::check_frames` after the decode; the views as
//! rendered pass.
//!
//! Where two faults leave the same frame they cannot be told apart, and the test says which
//! name it expects from the frames' own light: a late copy (or the kept rows) of a frame that is
//! nearly black on the scene is named dark, and a black frame in place of a pattern that is
//! nearly black on the scene changes nothing the decode could notice (it need not be named).

use std::error::Error;

use sl_codec::{
    Axis, BitDepth, CaptureSet, DecodeConfig, Frame, FrameFault, FrameIssue, Frames, HybridSpec,
    ImageSize, Pattern, PatternSequence, check_frames, decode,
};
use sl_scan::scaled_rig_config;
use sl_sim::{Scene, VirtualRig};

type TestResult<T> = Result<T, Box<dyn Error>>;

/// The rendered view at turntable angle `angle_deg`, noise draw `index`: its capture set.
fn view(angle_deg: f64, index: u64) -> TestResult<CaptureSet> {
    let config = scaled_rig_config(2);
    let p = config.projector.size;
    let projector = ImageSize::new(p.width, p.height);
    let sequence = PatternSequence::new(projector).with(Pattern::Hybrid(HybridSpec::recommended(
        Axis::Column,
        projector,
    )));
    let images = (0..sequence.frame_count())
        .map(|k| sequence.render_image(k, BitDepth::Eight))
        .collect::<Result<Vec<_>, _>>()?;
    let rig = VirtualRig::new(config, Scene::dumbbell())?;
    let frames = rig.view(angle_deg, index)?.capture_all(&images)?;
    let frames = Frames::U8(frames.into_iter().map(|f| f.into_u8()).collect());
    Ok(CaptureSet::from_frames(
        sequence.manifest(BitDepth::Eight),
        frames,
    )?)
}

/// `set` with frame `k` replaced by `frame`, checked after its decode.
fn check_with(set: &CaptureSet, k: usize, frame: Frame<u8>) -> TestResult<Vec<FrameIssue>> {
    let mut c = set.clone();
    if let Frames::U8(f) = &mut c.frames {
        f[k] = frame;
    }
    let decoded = decode(&c, &DecodeConfig::default())?;
    Ok(check_frames(&c, &decoded))
}

#[test]
fn late_black_and_mixed_frames_of_rendered_views_are_named() -> TestResult<()> {
    // Two sides of the dumbbell, two noise draws.
    for (angle, index) in [(40.0, 0), (220.0, 7)] {
        sweep(&view(angle, index)?)?;
    }
    Ok(())
}

/// Every frame of `set` in turn made late, black and mixed, each named.
fn sweep(set: &CaptureSet) -> TestResult<()> {
    assert_eq!(
        check_frames(set, &decode(set, &DecodeConfig::default())?),
        Vec::new()
    );
    let Frames::U8(f) = &set.frames else {
        return Err("an 8-bit capture was rendered".into());
    };
    let n = f.len();
    let (w, h) = (f[0].width(), f[0].height());
    // Each pixel's darkest and brightest level over the view: what a frame the projector left
    // black shows, and the range the check measures a frame's own light in.
    let level = |pick: fn(u8, u8) -> u8| -> Vec<u8> {
        (0..w * h)
            .map(|i| f.iter().map(|fr| fr.data()[i]).reduce(pick).unwrap_or(0))
            .collect()
    };
    let (black, brightest) = (level(u8::min), level(u8::max));
    let lit: Vec<usize> = (0..w * h)
        .filter(|&i| brightest[i] - black[i] >= 40)
        .collect();
    assert!(lit.len() > w * h / 50, "{} lit pixels", lit.len());
    let light = |fr: &Frame<u8>| {
        lit.iter()
            .map(|&i| f64::from(fr.data()[i] - black[i]) / f64::from(brightest[i] - black[i]))
            .sum::<f64>()
            / lit.len() as f64
    };
    let nearly_black: Vec<bool> = f.iter().map(|fr| light(fr) < 0.1).collect();
    let dark = |i: &FrameIssue| matches!(i.fault, FrameFault::Dark { .. });
    let (mut mixed_named, mut black_judged) = (0, 0);
    for k in 1..n {
        let issues = check_with(set, k, f[k - 1].clone())?;
        assert_eq!(issues.len(), 1, "late frame {k}: {issues:#?}");
        assert_eq!(issues[0].frame, k, "late frame {k}: {issues:#?}");
        if nearly_black[k - 1] {
            assert!(dark(&issues[0]), "late frame {k}: {issues:#?}");
        } else {
            let late = FrameFault::Repeats { previous: k - 1 };
            assert_eq!(issues[0].fault, late, "late frame {k}");
        }

        // The top half of the rows still showing the previous frame (the scene is in the
        // middle rows: a top third would change the background only).
        let split = h / 2;
        let mut data = f[k].data().to_vec();
        data[..split * w].copy_from_slice(&f[k - 1].data()[..split * w]);
        let issues = check_with(set, k, Frame::new(w, h, data)?)?;
        assert_eq!(issues.len(), 1, "mixed frame {k}: {issues:#?}");
        assert_eq!(issues[0].frame, k, "mixed frame {k}: {issues:#?}");
        match issues[0].fault {
            FrameFault::Mixed { previous, rows } => {
                assert_eq!(previous, k - 1, "mixed frame {k}");
                // From the top, to a band of 16 around the split.
                assert_eq!(rows.0, 0, "mixed frame {k}: {rows:?}");
                assert!(rows.1.abs_diff(split) <= h / 8, "mixed frame {k}: {rows:?}");
                mixed_named += 1;
            }
            _ => assert!(
                nearly_black[k - 1] && dark(&issues[0]),
                "mixed frame {k}: {issues:#?}"
            ),
        }

        let issues = check_with(set, k, Frame::new(w, h, black.clone())?)?;
        if nearly_black[k] {
            assert!(issues.len() <= 1, "black frame {k}: {issues:#?}");
            assert!(
                issues.iter().all(|i| i.frame == k),
                "black frame {k}: {issues:#?}"
            );
            continue;
        }
        black_judged += 1;
        assert_eq!(issues.len(), 1, "black frame {k}: {issues:#?}");
        assert_eq!(issues[0].frame, k, "black frame {k}: {issues:#?}");
        assert!(dark(&issues[0]), "black frame {k}: {issues:#?}");
    }
    let blackish = nearly_black.iter().filter(|b| **b).count();
    eprintln!(
        "{} frames: late and black ones named at their frame ({black_judged} black ones judged, \
         {blackish} frames nearly black on the scene); mixed named mixed: {mixed_named}",
        n
    );
    // The exceptions are few: a frame or two nearly black on the scene (coarse Gray bits).
    assert!(
        blackish <= 3 && mixed_named >= n - 1 - 3,
        "{blackish}, {mixed_named}"
    );
    Ok(())
}
