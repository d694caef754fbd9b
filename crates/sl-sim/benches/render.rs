//! Benchmarks of the virtual rig: the camera's ray cache (once per rig), casting one 1280×720
//! view (geometry cache and ground truth), and rendering a 44-frame Gray-code set (11 column bits and 11 row bits for a
//! 1920×1080 projector, each with its inverse) from the cache, camera effects included.
//!
//! `cargo bench -p sl-sim --bench render -- --warm-up-time 1 --measurement-time 3`

use criterion::{Criterion, criterion_group, criterion_main};
use sl_image::Frame;
use sl_sim::{GreyImage, RigConfig, Scene, SimError, VirtualRig};

/// Gray-code bit `bit` (MSB = 10) of every projector column (or row), and its inverse.
fn gray_set(w: u32, h: u32) -> Result<Vec<GreyImage>, SimError> {
    let mut out = Vec::with_capacity(44);
    for axis in 0..2 {
        for bit in (0..11).rev() {
            for inverse in [false, true] {
                let px: Vec<u8> = (0..h)
                    .flat_map(|y| (0..w).map(move |x| (x, y)))
                    .map(|(x, y)| {
                        let v = if axis == 0 { x } else { y };
                        let g = v ^ (v >> 1);
                        let on = (g >> bit) & 1 == 1;
                        if on != inverse { 255 } else { 0 }
                    })
                    .collect();
                out.push(GreyImage::U8(Frame::new(w as usize, h as usize, px)?));
            }
        }
    }
    Ok(out)
}

fn benches(c: &mut Criterion) -> Result<(), SimError> {
    let config = RigConfig::default();
    let (pw, ph) = (config.projector.size.width, config.projector.size.height);
    let rig = VirtualRig::new(config, Scene::sphere())?;
    let patterns = gray_set(pw, ph)?;
    let mut group = c.benchmark_group("virtual_rig");
    group.sample_size(10);
    group.bench_function("camera_rays_1280x720_ss2", |b| {
        b.iter(|| sl_sim::CameraRays::new(&rig.config().camera, 2))
    });
    // The camera rays are computed once per rig, outside this timing.
    rig.camera_rays();
    group.bench_function("cast_view_1280x720_ss2_sphere", |b| {
        b.iter(|| rig.view(0.0, 0))
    });
    let view = rig.view(0.0, 0)?;
    group.bench_function("render_44_frames_1280x720", |b| {
        b.iter(|| view.capture_all(&patterns))
    });
    group.finish();
    Ok(())
}

fn run(c: &mut Criterion) {
    if let Err(e) = benches(c) {
        eprintln!("render bench: {e}");
    }
}

criterion_group!(render, run);
criterion_main!(render);
