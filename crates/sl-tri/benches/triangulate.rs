//! Criterion bench `triangulate`: a 1280×720 correspondence map of the virtual rig's default
//! geometry (a wall at 450 mm filling the view, ~0.9 M decoded pixels) to points, with each
//! method; plus the per-calibration precomputation, and a reference for the memory: a
//! parallel copy of as many bytes as one triangulation moves.
//!
//! Each method is timed three ways: `full` (filters, mixed pixels, grid normals, cloud,
//! fresh output vectors), `points` (no normals, no mixed-pixel pass, fresh vectors) and
//! `points reused` (the same into the vectors of a previous result with
//! `Triangulator::triangulate_into`: no allocation, no page faults).
//!
//! `cargo bench -p sl-tri --bench triangulate -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Point3;
use rayon::prelude::*;
use sl_codec::{Axis, CorrespondenceMap, InvalidReason};
use sl_sim::RigConfig;
use sl_tri::{Method, TriConfig, TriError, Triangulator};

/// The exact map of a wall at 450 mm seen by the default rig's camera (decoded where the
/// projector lights it).
fn wall_map(tri: &Triangulator, calibration: &sl_camera::Calibration) -> CorrespondenceMap {
    let size = calibration.camera.size;
    let (w, h) = (size.width as usize, size.height as usize);
    let mut map = CorrespondenceMap::new(w, h);
    let (Some(proj), Some(t_proj_cam)) = (calibration.projector, calibration.t_proj_cam()) else {
        return map;
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let px = tri
                .camera_rays()
                .get(x as u32, y as u32)
                .and_then(|ray| proj.project(&(t_proj_cam * Point3::from(ray * 450.0))))
                .filter(|px| proj.size.contains(px.x, px.y));
            if let (Some(px), Some(c), Some(r), Some(q)) = (
                px,
                map.col.get_mut(i),
                map.row.get_mut(i),
                map.quality.get_mut(i),
            ) {
                *c = px.x as f32;
                *r = px.y as f32;
                *q = 60.0;
            } else if let Some(inv) = map.invalid.get_mut(i) {
                *inv = InvalidReason::Shadow;
            }
        }
    }
    map
}

fn bench(c: &mut Criterion) {
    if let Err(e) = run(c) {
        eprintln!("bench setup failed: {e}");
    }
}

fn run(c: &mut Criterion) -> Result<(), TriError> {
    let calibration = RigConfig::default().calibration();
    let tri = Triangulator::new(&calibration)?;
    let map = wall_map(&tri, &calibration);
    let decoded = map.invalid.iter().filter(|r| r.is_valid()).count();
    eprintln!("1280x720 map, {decoded} decoded pixels");

    let mut group = c.benchmark_group("triangulate");
    group.sample_size(10);
    group.bench_function("precompute (Triangulator::new)", |b| {
        b.iter(|| Triangulator::new(black_box(&calibration)))
    });
    // The memory reference: a parallel copy of 160 MB (read 80 + write 80), about what a
    // ray–plane triangulation streams (inputs 27 MB, organised outputs 27 MB written and
    // read back, the cloud 30 MB, with the read-for-ownership of every written line).
    let source = vec![1.0f64; 10 << 20];
    let mut target = vec![0.0f64; 10 << 20];
    group.bench_function("memory reference: parallel copy of 80 MB", |b| {
        b.iter(|| {
            target
                .par_chunks_mut(1 << 16)
                .zip(source.par_chunks(1 << 16))
                .for_each(|(t, s)| t.copy_from_slice(s));
        })
    });
    let methods = [
        Method::RayPlane { axis: Axis::Column },
        Method::Linear,
        Method::Midpoint,
        Method::Optimal,
    ];
    for method in methods {
        // Full output: filters, mixed pixels, grid normals, cloud.
        let full = TriConfig::with_method(method);
        group.bench_function(format!("{} full", method.name()), |b| {
            b.iter(|| tri.triangulate(black_box(&map), &full))
        });
        // Points only: no normals, no mixed-pixel pass.
        let bare = TriConfig {
            normals: false,
            max_depth_jump: f64::INFINITY,
            ..TriConfig::with_method(method)
        };
        group.bench_function(format!("{} points", method.name()), |b| {
            b.iter(|| tri.triangulate(black_box(&map), &bare))
        });
        let mut reused = tri.triangulate(&map, &bare)?;
        group.bench_function(format!("{} points reused", method.name()), |b| {
            b.iter(|| tri.triangulate_into(black_box(&map), None, &bare, &mut reused))
        });
    }
    // A column-only capture (issue 15): linear on one axis (fixed point on the missing row).
    let mut columns_only = map.clone();
    columns_only.row.iter_mut().for_each(|r| *r = f32::NAN);
    let bare = TriConfig {
        normals: false,
        max_depth_jump: f64::INFINITY,
        ..TriConfig::with_method(Method::Linear)
    };
    let mut reused = tri.triangulate(&columns_only, &bare)?;
    group.bench_function("linear columns only points reused", |b| {
        b.iter(|| tri.triangulate_into(black_box(&columns_only), None, &bare, &mut reused))
    });
    group.finish();
    Ok(())
}

criterion_group!(benches, bench);
criterion_main!(benches);
