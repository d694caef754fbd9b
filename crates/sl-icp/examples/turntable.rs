//! The virtual-rig merge: 36 views at 10° of a known object (rounded box + sphere), ~100k
//! points per view with 0.03 mm noise along the view rays, initial poses from a slightly wrong
//! turntable axis; prints the merge time, the pose errors and the RMS distance of the merged
//! cloud to the true surface.
//!
//! ```sh
//! cargo run --release -p sl-icp --example turntable [-- POINTS_PER_VIEW NOISE_MM [--average]]
//! ```

use std::time::Instant;

use nalgebra::{Point3, Rotation3, Vector3};
use sl_icp::{IcpError, MergeConfig, PoseError, TurntableAxis, merge_views, turntable_poses};

#[path = "../tests/it/support/turntable_scene.rs"]
mod scene;

fn main() -> Result<(), IcpError> {
    let args: Vec<String> = std::env::args().collect();
    let points: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let noise: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.03);
    let scene = scene::Scene::new(points, noise);
    let angles: Vec<f64> = (0..36).map(|i| i as f64 * 10.0).collect();
    let t = Instant::now();
    let views: Vec<_> = angles
        .iter()
        .enumerate()
        .map(|(i, &a)| scene.view(a, i as u64))
        .collect();
    let n: usize = views.iter().map(|v| v.len()).sum();
    println!(
        "rendered 36 views, {:.0} points per view on average, in {:.1} s",
        n as f64 / 36.0,
        t.elapsed().as_secs_f64()
    );
    let raw: Vec<Point3<f64>> = views[0].positions().to_vec();
    let (rms0, _) = scene.surface_error(0.0, &raw);
    println!("noise check: view 0 RMS distance to the surface {rms0:.4} mm");
    // An imperfect calibration: axis 0.3° off, 0.5 mm off, angle scale 0.1 % off.
    let mut wrong: TurntableAxis = scene.axis;
    wrong.direction =
        Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3f64.to_radians()) * wrong.direction;
    wrong.point_mm += Vector3::new(0.5, 0.0, -0.3);
    wrong.angle_scale = 1.001;
    let initial = turntable_poses(&wrong, &angles)?;
    let config = MergeConfig {
        average_overlaps: args.iter().any(|a| a == "--average"),
        ..MergeConfig::default()
    };
    let t = Instant::now();
    let merged = merge_views(&views, &initial, &config)?;
    let secs = t.elapsed().as_secs_f64();
    let (mut worst_rot, mut worst_rms) = (0.0f64, 0.0f64);
    let (mut init_rot, mut init_rms) = (0.0f64, 0.0f64);
    for (i, &a) in angles.iter().enumerate() {
        let truth = scene.true_pose(0.0, a);
        let e = PoseError::between(&merged.alignment.poses[i], &truth, views[i].positions());
        let e0 = PoseError::between(&initial[i], &truth, views[i].positions());
        worst_rot = worst_rot.max(e.rotation_deg);
        worst_rms = worst_rms.max(e.rms_displacement_mm);
        init_rot = init_rot.max(e0.rotation_deg);
        init_rms = init_rms.max(e0.rms_displacement_mm);
    }
    if args.iter().any(|a| a == "--verbose") {
        for p in &merged.alignment.pairs {
            if let Some(r) = &p.registration {
                let truth = scene.true_pose(0.0, angles[p.target]).inverse()
                    * scene.true_pose(0.0, angles[p.source]);
                let e = PoseError::between(&r.pose, &truth, views[p.source].positions());
                println!(
                    "pair {}<-{}: it {} conv {} fit {:.3} rmse {:.4} err {:.4} deg {:.4} mm",
                    p.target,
                    p.source,
                    r.iterations,
                    r.converged,
                    r.fitness,
                    r.rmse,
                    e.rotation_deg,
                    e.rms_displacement_mm
                );
            }
        }
    }
    let (rms, max) = scene.surface_error(0.0, merged.cloud.positions());
    println!(
        "merge of 36 views in {secs:.2} s on {} threads",
        rayon::current_num_threads()
    );
    println!("initial poses: worst {init_rot:.3} deg / rms displacement {init_rms:.3} mm");
    println!("merged poses:  worst {worst_rot:.4} deg / rms displacement {worst_rms:.4} mm");
    println!(
        "pose graph: cost {:.3e} -> {:.3e} in {} iterations; pairs used {}/{}",
        merged.alignment.pose_graph.initial_cost,
        merged.alignment.pose_graph.final_cost,
        merged.alignment.pose_graph.iterations,
        merged.alignment.pairs.iter().filter(|p| p.used).count(),
        merged.alignment.pairs.len()
    );
    println!(
        "merged cloud: {} points, RMS distance to the true surface {rms:.4} mm (max {max:.3} mm)",
        merged.cloud.len()
    );
    Ok(())
}
