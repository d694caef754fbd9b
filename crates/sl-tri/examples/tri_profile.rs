//! A driver for profiling the triangulation outside criterion: the bench's 1280×720 wall map
//! (the virtual rig's default geometry, a wall at 450 mm) triangulated `N` times with one
//! method, so that `valgrind --tool=callgrind` can count its instructions and
//! `/usr/bin/time` its CPU time, both independent of the machine's load.
//!
//! ```sh
//! cargo build --release -p sl-tri --example tri_profile
//! # METHOD: ray-plane | linear | midpoint | optimal | none (setup only); MODE: points |
//! # reused | full; SCENE (optional): wall (the bench's, default) | tilted | sphere
//! target/release/examples/tri_profile ray-plane reused 20 sphere
//! RAYON_NUM_THREADS=1 valgrind --tool=callgrind target/release/examples/tri_profile ray-plane reused 3
//! ```
//!
//! Instructions per triangulation = (callgrind total of `N` runs − total of 0 runs) / `N`.
//! Prints the wall time per triangulation (load dependent: a hint, not a measurement).

use std::time::Instant;

use nalgebra::Point3;
use sl_codec::{Axis, CorrespondenceMap, InvalidReason};
use sl_sim::RigConfig;
use sl_tri::{Method, TriConfig, TriError, Triangulator};

/// The depth (camera `z`, mm) at which the camera ray `(x, y, 1)` meets the scene: `wall`, the
/// bench's wall at 450 mm facing the camera (depth constant along every row, the easiest
/// case for warm starts); `tilted`, a wall turned by 35° about the vertical axis through
/// (0, 0, 450) (depth varies along the rows); `sphere`, a sphere of radius 120 mm centred at
/// (0, 0, 480) in front of a wall at 600 mm (curvature and silhouettes).
fn scene_depth(scene: &str, ray: &nalgebra::Vector3<f64>) -> Option<f64> {
    match scene {
        "wall" => Some(450.0),
        "tilted" => {
            let (s, c) = 35f64.to_radians().sin_cos();
            let t = 450.0 * c / (s * ray.x + c);
            (t > 0.0).then_some(t)
        }
        "sphere" => {
            let (centre, radius) = (nalgebra::Vector3::new(0.0, 0.0, 480.0), 120.0);
            // |t·ray − centre|² = r²: the nearer root.
            let a = ray.norm_squared();
            let b = ray.dot(&centre);
            let disc = b * b - a * (centre.norm_squared() - radius * radius);
            Some(if disc > 0.0 {
                (b - disc.sqrt()) / a
            } else {
                600.0
            })
        }
        _ => None,
    }
}

/// The exact map of `scene` seen by the default rig's camera (decoded where the projector
/// lights it; as the bench's wall map).
fn scene_map(
    tri: &Triangulator,
    calibration: &sl_camera::Calibration,
    scene: &str,
) -> CorrespondenceMap {
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
                .and_then(|ray| {
                    let t = scene_depth(scene, &ray)?;
                    proj.project(&(t_proj_cam * Point3::from(ray * t)))
                })
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

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: tri_profile METHOD(ray-plane|linear|midpoint|optimal|none) \
                 MODE(points|reused|full) N [SCENE(wall|tilted|sphere)]";
    let (Some(method), Some(mode), Some(n)) = (args.get(1), args.get(2), args.get(3)) else {
        return Err(usage.into());
    };
    let n: usize = n.parse()?;
    let scene = args.get(4).map_or("wall", String::as_str);
    if scene_depth(scene, &nalgebra::Vector3::z()).is_none() {
        return Err(usage.into());
    }
    let method = match method.as_str() {
        "ray-plane" => Some(Method::RayPlane { axis: Axis::Column }),
        "linear" => Some(Method::Linear),
        "midpoint" => Some(Method::Midpoint),
        "optimal" => Some(Method::Optimal),
        "none" => None,
        _ => return Err(usage.into()),
    };
    let calibration = RigConfig::default().calibration();
    let start = Instant::now();
    let tri = Triangulator::new(&calibration)?;
    eprintln!(
        "Triangulator::new: {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    let map = scene_map(&tri, &calibration, scene);
    let Some(method) = method else {
        return Ok(());
    };
    let options = match mode.as_str() {
        "full" => TriConfig::with_method(method),
        "points" | "reused" => TriConfig {
            normals: false,
            max_depth_jump: f64::INFINITY,
            ..TriConfig::with_method(method)
        },
        _ => return Err(usage.into()),
    };
    // The first call builds the projector's table for the methods that need it: timed
    // apart, and outside the loop (so the loop's figures are those of the pass).
    let start = Instant::now();
    let mut reused = tri.triangulate(&map, &options)?;
    eprintln!(
        "{scene}: first call {:.1} ms, {} points of {} decoded pixels",
        start.elapsed().as_secs_f64() * 1e3,
        reused.counts.valid,
        reused.counts.decoded()
    );
    let start = Instant::now();
    for _ in 0..n {
        if mode == "reused" {
            tri.triangulate_into(&map, None, &options, &mut reused)?;
        } else {
            let r: Result<_, TriError> = tri.triangulate(&map, &options);
            std::hint::black_box(r?);
        }
    }
    if n > 0 {
        eprintln!(
            "{} {mode}: {:.2} ms per triangulation (wall, load dependent)",
            method.name(),
            start.elapsed().as_secs_f64() * 1e3 / n as f64
        );
    }
    Ok(())
}
