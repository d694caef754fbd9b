//! Phase shift, 3 frequencies x 4 steps (heterodyne 64/58/53, 12 frames of 1280x720), target
//! <= 6 ms on 2 cores; and the hybrid code (4 steps + complementary Gray code with inverses, one
//! axis: 16 frames), target <= 10 ms.
#![allow(missing_docs)]

mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sl_codec::{
    Axis, CorrespondenceMap, DecodeConfig, HybridSpec, Pattern, PatternSequence, PhaseShiftSpec,
    Unwrap, decode_frames_into,
};

fn run(c: &mut Criterion, name: &str, sequence: &PatternSequence) {
    let frames = common::render(sequence);
    let bytes: usize = frames.iter().map(|f| f.data().len()).sum();
    let config = DecodeConfig::default();
    let mut map = CorrespondenceMap::new(0, 0);
    let mut group = c.benchmark_group(name);
    group.throughput(Throughput::Bytes(bytes as u64));
    group.bench_function(format!("{} frames 1280x720", frames.len()), |b| {
        b.iter(|| decode_frames_into(&sequence.blocks, &frames, &config, &mut map))
    });
    group.finish();
    if decode_frames_into(&sequence.blocks, &frames, &config, &mut map).is_ok() {
        eprintln!("{name}: valid fraction {:.3}", map.valid_fraction());
    }
}

fn bench(c: &mut Criterion) {
    let p = common::PROJECTOR;
    let heterodyne = PatternSequence::new(p).with(Pattern::Phase(PhaseShiftSpec::new(
        Axis::Column,
        p,
        4,
        vec![64.0, 58.0, 53.0],
        Unwrap::Heterodyne,
    )));
    run(c, "decode_phase", &heterodyne);
    let hybrid = PatternSequence::new(p).with(Pattern::Hybrid(HybridSpec::complementary(
        Axis::Column,
        p,
        4,
        32.0,
    )));
    run(c, "decode_hybrid", &hybrid);
}

criterion_group!(benches, bench);
criterion_main!(benches);
