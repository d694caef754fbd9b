//! The bunny table: bun045 registered onto bun000 with each method, timed and compared with
//! the reference poses of `bun.conf` (errors as [`sl_icp::PoseError`]).
//!
//! ```sh
//! SL_DATA=/work/shared/data cargo run --release -p sl-icp --example bunny
//! ```
//! Times are medians over repeated runs on the global rayon pool (all cores).

use std::time::Instant;

use nalgebra::Isometry3;
use sl_icp::{
    IcpConfig, IcpError, Metric, NormalConfig, NormalSource, PoseError, PrepareConfig,
    PreparedCloud, register,
};

#[path = "../tests/it/support/bunny.rs"]
mod bunny;

/// Runs per figure; the median is reported.
const RUNS: usize = 21;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

struct Case {
    name: &'static str,
    voxel: f64,
    metric: Metric,
    max_distance: f64,
    from_raw: bool,
}

/// Neighbours for the normals: 20 as Open3D's defaults, 10 for generalized ICP as `small_gicp`.
fn neighbours(metric: Metric) -> usize {
    if metric == Metric::Generalized {
        10
    } else {
        20
    }
}

fn main() -> Result<(), IcpError> {
    let Some(dir) = bunny::bunny_dir("the bunny table") else {
        return Ok(());
    };
    let target = bunny::load(&dir, "bun000");
    let source = bunny::load(&dir, "bun045");
    let reference = bunny::reference(&target, &source);
    let centroid = source.cloud.centroid().unwrap_or_default();
    let start = bunny::perturbed(&reference, &centroid);
    let e0 = PoseError::between(&start, &reference, source.cloud.positions());
    let raw = PoseError::between(&Isometry3::identity(), &reference, source.cloud.positions());
    println!(
        "start: {:.2} deg / {:.2} mm (rms {:.2} mm); raw poses: {:.2} deg / {:.2} mm (rms {:.2} mm)",
        e0.rotation_deg,
        e0.translation_mm,
        e0.rms_displacement_mm,
        raw.rotation_deg,
        raw.translation_mm,
        raw.rms_displacement_mm
    );
    println!("threads: {}", rayon::current_num_threads());
    let cases = [
        Case {
            name: "point-to-plane 1 mm, 5 mm",
            voxel: 1.0,
            metric: Metric::PointToPlane,
            max_distance: 5.0,
            from_raw: false,
        },
        Case {
            name: "generalized 1 mm, 5 mm",
            voxel: 1.0,
            metric: Metric::Generalized,
            max_distance: 5.0,
            from_raw: false,
        },
        Case {
            name: "generalized 2 mm, 5 mm",
            voxel: 2.0,
            metric: Metric::Generalized,
            max_distance: 5.0,
            from_raw: false,
        },
        Case {
            name: "point-to-plane 2 mm, 5 mm",
            voxel: 2.0,
            metric: Metric::PointToPlane,
            max_distance: 5.0,
            from_raw: false,
        },
        Case {
            name: "point-to-point 1 mm, 5 mm",
            voxel: 1.0,
            metric: Metric::PointToPoint,
            max_distance: 5.0,
            from_raw: false,
        },
        Case {
            name: "raw: point-to-point 1 mm, 5 mm",
            voxel: 1.0,
            metric: Metric::PointToPoint,
            max_distance: 5.0,
            from_raw: true,
        },
        Case {
            name: "raw: point-to-point 1 mm, 20 mm",
            voxel: 1.0,
            metric: Metric::PointToPoint,
            max_distance: 20.0,
            from_raw: true,
        },
        Case {
            name: "raw: point-to-plane 1 mm, 5 mm",
            voxel: 1.0,
            metric: Metric::PointToPlane,
            max_distance: 5.0,
            from_raw: true,
        },
        Case {
            name: "raw: generalized 2 mm, 5 mm",
            voxel: 2.0,
            metric: Metric::Generalized,
            max_distance: 5.0,
            from_raw: true,
        },
    ];
    println!(
        "{:<34} {:>8} {:>8} {:>8} {:>9} {:>6} {:>8} {:>8} {:>8} {:>7} {:>5}",
        "case",
        "prep med",
        "icp med",
        "icp min",
        "total med",
        "iters",
        "rot deg",
        "trans mm",
        "rms mm",
        "fitness",
        "conv"
    );
    for case in &cases {
        // Normals only where the metric needs them: the target's for point-to-plane, both
        // for generalized ICP.
        let estimate = NormalSource::Estimate(NormalConfig {
            k: neighbours(case.metric),
            ..NormalConfig::default()
        });
        let target_prep = PrepareConfig {
            voxel_size: Some(case.voxel),
            normals: if case.metric == Metric::PointToPoint {
                NormalSource::None
            } else {
                estimate
            },
        };
        let source_prep = PrepareConfig {
            voxel_size: Some(case.voxel),
            normals: if case.metric == Metric::Generalized {
                estimate
            } else {
                NormalSource::None
            },
        };
        let config = IcpConfig {
            metric: case.metric,
            max_correspondence_distance: case.max_distance,
            ..IcpConfig::default()
        };
        let init = if case.from_raw {
            Isometry3::identity()
        } else {
            start
        };
        let (mut t_prep, mut t_icp, mut t_total) = (Vec::new(), Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..RUNS {
            let t0 = Instant::now();
            let s = PreparedCloud::new(&source.cloud, &source_prep)?;
            let t = PreparedCloud::new(&target.cloud, &target_prep)?;
            t.build_index();
            let t1 = Instant::now();
            let r = register(&s, &t, &init, &config);
            let t2 = Instant::now();
            t_prep.push((t1 - t0).as_secs_f64() * 1e3);
            t_icp.push((t2 - t1).as_secs_f64() * 1e3);
            t_total.push((t2 - t0).as_secs_f64() * 1e3);
            last = Some(r);
        }
        match last {
            Some(Ok(r)) => {
                let e = PoseError::between(&r.pose, &reference, source.cloud.positions());
                let icp_min = t_icp.iter().copied().fold(f64::INFINITY, f64::min);
                println!(
                    "{:<34} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>6} {:>8.3} {:>8.3} {:>8.3} {:>7.3} {:>5}",
                    case.name,
                    median(t_prep),
                    median(t_icp),
                    icp_min,
                    median(t_total),
                    r.iterations,
                    e.rotation_deg,
                    e.translation_mm,
                    e.rms_displacement_mm,
                    r.fitness,
                    r.converged
                );
            }
            Some(Err(err)) => println!("{:<34} failed: {err}", case.name),
            None => {}
        }
    }
    Ok(())
}
