//! Gray code with inverses, columns and rows: 44 frames of 1280x720 (40 MB), decoded into a
//! correspondence map. Target: <= 8 ms on 2 cores.
#![allow(missing_docs)]

mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sl_codec::{
    Axis, CorrespondenceMap, DecodeConfig, GrayCodeSpec, Pattern, PatternSequence,
    decode_frames_into,
};

fn bench(c: &mut Criterion) {
    let p = common::PROJECTOR;
    let sequence = PatternSequence::new(p)
        .with(Pattern::Gray(GrayCodeSpec::per_pixel(
            Axis::Column,
            p,
            true,
        )))
        .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Row, p, true)));
    let frames = common::render(&sequence);
    let bytes: usize = frames.iter().map(|f| f.data().len()).sum();
    let config = DecodeConfig::default();
    let mut map = CorrespondenceMap::new(0, 0);
    let mut group = c.benchmark_group("decode_gray");
    group.throughput(Throughput::Bytes(bytes as u64));
    group.bench_function("44 frames 1280x720, reused map", |b| {
        b.iter(|| decode_frames_into(&sequence.blocks, &frames, &config, &mut map))
    });
    group.bench_function("44 frames 1280x720, fresh map", |b| {
        b.iter(|| sl_codec::decode_frames(&sequence.blocks, &frames, &config))
    });
    // Baseline: read every byte of the 44 frames once, with the same band-parallel structure
    // (the floor any decoder of these frames has on this machine, right now).
    group.bench_function("baseline: read 44 frames once", |b| {
        b.iter(|| read_all(&frames))
    });
    group.finish();
    if decode_frames_into(&sequence.blocks, &frames, &config, &mut map).is_ok() {
        eprintln!("valid fraction {:.3}", map.valid_fraction());
    }
}

fn read_all(frames: &[sl_codec::Frame<u8>]) -> u64 {
    use rayon::prelude::*;
    let band = 8 * 1280;
    let n = frames.first().map_or(0, |f| f.data().len());
    (0..n.div_ceil(band))
        .into_par_iter()
        .map(|i| {
            let mut acc = [0u64; 1];
            for f in frames {
                let chunk = f
                    .data()
                    .get(i * band..((i + 1) * band).min(n))
                    .unwrap_or(&[]);
                acc[0] += chunk.iter().map(|&v| u64::from(v)).sum::<u64>();
            }
            acc[0]
        })
        .sum()
}

criterion_group!(benches, bench);
criterion_main!(benches);
