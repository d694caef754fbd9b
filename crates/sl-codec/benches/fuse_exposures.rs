//! Exposure fusion: the scan's hybrid code (column, 8 steps, 22 frames of 1280x720) captured at
//! three exposures a factor of 4 apart, fused into one sequence — longest unsaturated exposure
//! per pixel, and the radiance merge. The cost a several-exposure view adds before its decode.
#![allow(missing_docs)]

// The shared scene's projector and settings; its `render` (one exposure) is not used here.
#[allow(dead_code)]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sl_codec::{
    Axis, ExposureFrames, FusionConfig, FusionMethod, GreyImage, HybridSpec, Pattern,
    PatternSequence, SyntheticScene, fuse_exposures,
};

fn bench(c: &mut Criterion) {
    let p = common::PROJECTOR;
    let sequence = PatternSequence::new(p).with(Pattern::Hybrid(HybridSpec::complementary(
        Axis::Column,
        p,
        8,
        15.0,
    )));
    // A scene of two decades of albedo at exposures ×1, ×4 and ×16.
    let stacks: Vec<ExposureFrames> = [1.0, 4.0, 16.0]
        .iter()
        .map(|&scale| {
            let scene = SyntheticScene {
                gain: 100.0 * scale,
                albedo_min: 0.01,
                albedo_max: 1.0,
                ..common::scene()
            };
            let frames = match scene.render::<u8>(&sequence) {
                Ok(f) => f,
                Err(e) => {
                    eprintln!("rendering the benchmark frames failed: {e}");
                    std::process::exit(1)
                }
            };
            ExposureFrames {
                exposure_ms: 5.0 * scale,
                frames: frames.into_iter().map(GreyImage::U8).collect(),
            }
        })
        .collect();
    let bytes: usize = stacks
        .iter()
        .flat_map(|s| &s.frames)
        .map(|f| f.width() * f.height())
        .sum();
    let mut group = c.benchmark_group("fuse_exposures");
    group.throughput(Throughput::Bytes(bytes as u64));
    group.sample_size(20);
    for method in [FusionMethod::Longest, FusionMethod::Radiance] {
        let config = FusionConfig {
            method,
            ..FusionConfig::default()
        };
        group.bench_function(
            format!("3 exposures x 22 frames 1280x720, {}", method.name()),
            |b| b.iter(|| fuse_exposures(&stacks, &config)),
        );
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
