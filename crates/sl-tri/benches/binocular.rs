//! Criterion bench `binocular`: one 1280×1024 pair of a binocular rig (the virtual rig's camera
//! at 1280×1024 and its default second camera, the dumbbell on the platter in front of a wall
//! 600 mm from the camera that fills the view, the recommended hybrid code on the projector's
//! columns), from frames to points:
//!
//! - `decode pair`: both cameras' frames decoded (`sl_codec::decode`, one after the other);
//! - `match and triangulate`: `Binocular::reconstruct` on the two decoded maps, the
//!   rectification precomputed once per calibration as a user's program does
//!   (`Binocular::new`, timed on its own as `rectify (Binocular::new)`);
//! - `total`: both, what the 60 ms target is about.
//!
//! `cargo bench -p sl-tri --bench binocular -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use sl_camera::{BinocularCalibration, ImageSize, Intrinsics};
use sl_codec::{
    Axis, BitDepth, CaptureSet, DecodeConfig, Frames, HybridSpec, Pattern, PatternSequence, decode,
};
use sl_sim::{RigConfig, Scene, SceneObject, Shape, Texture, VirtualRig};
use sl_tri::{Binocular, BinocularConfig};

type Setup = Result<(BinocularCalibration, CaptureSet, CaptureSet), Box<dyn std::error::Error>>;

/// The two captures and their calibration.
fn captures() -> Setup {
    let mut config = RigConfig::default();
    // 1280×1024: the same focal length, the image taller about the same centre.
    let k = config.camera.intrinsics;
    config.camera.intrinsics = Intrinsics::new(k.fx, k.fy, k.cx, k.cy + 152.0);
    config.camera.size = ImageSize::new(1280, 1024);
    config.render.supersampling = 1;
    let second = config.default_second_camera();
    let p = config.projector.size;
    let sequence = PatternSequence::new(ImageSize::new(p.width, p.height)).with(Pattern::Hybrid(
        HybridSpec::recommended(Axis::Column, ImageSize::new(p.width, p.height)),
    ));
    let manifest = sequence.manifest(BitDepth::Eight);
    let images = (0..sequence.frame_count())
        .map(|k| sequence.render_image(k, BitDepth::Eight))
        .collect::<Result<Vec<_>, _>>()?;
    let mut scene = Scene::dumbbell();
    scene.objects.push(SceneObject::in_camera(
        "wall",
        Shape::rectangle(3000.0, 3000.0),
        Texture::Uniform(0.6),
        Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 600.0),
            UnitQuaternion::identity(),
        ),
    ));
    let mut sets = Vec::new();
    for (c, scene) in [
        (config.clone(), scene.clone()),
        (config.seen_from(&second), scene.seen_from(&second)),
    ] {
        let rig = VirtualRig::new(c, scene)?;
        let frames = rig.view(30.0, 0)?.capture_all(&images)?;
        let frames = Frames::U8(frames.into_iter().map(|f| f.into_u8()).collect());
        sets.push(CaptureSet::from_frames(manifest.clone(), frames)?);
    }
    let right = sets.pop().ok_or("no right capture")?;
    let left = sets.pop().ok_or("no left capture")?;
    let pair = BinocularCalibration::new(config.camera, second.camera, second.t_cam_second);
    Ok((pair, left, right))
}

fn bench(c: &mut Criterion) {
    if let Err(e) = run(c) {
        eprintln!("bench setup failed: {e}");
    }
}

fn run(c: &mut Criterion) -> Result<(), Box<dyn std::error::Error>> {
    let (pair, left, right) = captures()?;
    let options = DecodeConfig::default();
    let cfg = BinocularConfig::default();
    let rectified = Binocular::new(&pair.left, &pair.right, &pair.t_left_right)?;
    let (lmap, rmap) = (decode(&left, &options)?, decode(&right, &options)?);
    let result = rectified.reconstruct(&lmap, &rmap, &cfg)?;
    eprintln!(
        "1280x1024 pair, {} frames each: decoded {:.1} % / {:.1} %, {} points",
        left.manifest.frame_count(),
        100.0 * lmap.valid_fraction(),
        100.0 * rmap.valid_fraction(),
        result.cloud.len()
    );

    let mut group = c.benchmark_group("binocular");
    group.sample_size(10);
    group.bench_function("rectify (Binocular::new)", |b| {
        b.iter(|| Binocular::new(&pair.left, &pair.right, &pair.t_left_right))
    });
    group.bench_function("decode pair", |b| {
        b.iter(|| {
            (
                decode(black_box(&left), &options),
                decode(black_box(&right), &options),
            )
        })
    });
    group.bench_function("match and triangulate", |b| {
        b.iter(|| rectified.reconstruct(black_box(&lmap), black_box(&rmap), &cfg))
    });
    group.bench_function("total", |b| {
        b.iter(|| -> Result<_, Box<dyn std::error::Error>> {
            let l = decode(black_box(&left), &options)?;
            let r = decode(black_box(&right), &options)?;
            Ok(rectified.reconstruct(&l, &r, &cfg)?)
        })
    });
    group.finish();
    Ok(())
}

criterion_group!(benches, bench);
criterion_main!(benches);
