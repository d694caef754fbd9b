//! Accuracy of `poisson_reconstruct` on a cloud of spheres, split by the distance of each
//! vertex to the cloud (≤ 0.2 mm, 0.2–1 mm, over 1 mm: the surface closing what was not seen).
//!
//! ```sh
//! cargo run --release -p sl-mesh --example poisson_gap -- SOURCE [depth] [r cx cy cz]...
//! ```
//! `SOURCE` is a cloud with normals (`merged.ply` of a scan), `--project=CLOUD.ply` (its
//! points moved onto the nearest true sphere with the sphere's normals: the scan's coverage
//! without its noise) or `--synthetic` (the spheres sampled with 40,000 exact points each,
//! without their lower back, `n.y > 0.4` and `n.z > 0`, as the default scan misses it).
//! Without sphere arguments the default scan's spheres are used (r 25 mm at (±60, 0, 450)).
//! Environment: `FULL_DEPTH` (default `PoissonConfig`'s), `WRITE_MESH=PATH` and
//! `WRITE_CLOUD=PATH` (PLY files of the mesh and of the cloud used).
use std::error::Error;
use std::path::Path;

use nalgebra::{Point3, Vector3};
use sl_cloud::{KdIndex, PlyFormat, PointCloud, read_ply, write_ply};
use sl_mesh::{PoissonConfig, check_topology, poisson_reconstruct, write_ply_mesh};

type Sphere = (f64, Point3<f64>);

fn synthetic(spheres: &[Sphere]) -> Result<PointCloud, Box<dyn Error>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let n = 40_000;
    let (mut pts, mut nrm) = (Vec::new(), Vec::new());
    for (r, c) in spheres {
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            let nv = Vector3::new(s * t.cos(), s * t.sin(), z);
            if nv.y > 0.4 && nv.z > 0.0 {
                continue;
            }
            pts.push(c + nv * *r);
            nrm.push(nv);
        }
    }
    Ok(PointCloud::from_positions(pts).with_normals(nrm)?)
}

/// Signed distance to the nearest sphere's surface, and that sphere.
fn nearest(spheres: &[Sphere], p: &Point3<f64>) -> (f64, Sphere) {
    spheres
        .iter()
        .map(|s| ((p - s.1).norm() - s.0, *s))
        .min_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
        .unwrap_or((f64::NAN, (0.0, Point3::origin())))
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(source) = args.first() else {
        return Err("usage: poisson_gap SOURCE [depth] [r cx cy cz]...".into());
    };
    let nums: Vec<f64> = args[1..].iter().filter_map(|a| a.parse().ok()).collect();
    let depth = nums.first().copied().unwrap_or(9.0) as u32;
    let mut spheres: Vec<Sphere> = nums
        .get(1..)
        .unwrap_or_default()
        .chunks_exact(4)
        .map(|c| (c[0], Point3::new(c[1], c[2], c[3])))
        .collect();
    if spheres.is_empty() {
        spheres = vec![
            (25.0, Point3::new(-60.0, 0.0, 450.0)),
            (25.0, Point3::new(60.0, 0.0, 450.0)),
        ];
    }
    let cloud = if source == "--synthetic" {
        synthetic(&spheres)?
    } else if let Some(path) = source.strip_prefix("--project=") {
        let c = read_ply(Path::new(path))?;
        let (pts, nrm): (Vec<_>, Vec<_>) = c
            .positions()
            .iter()
            .map(|p| {
                let (_, (r, centre)) = nearest(&spheres, p);
                let n = (p - centre).normalize();
                (centre + n * r, n)
            })
            .unzip();
        PointCloud::from_positions(pts).with_normals(nrm)?
    } else {
        read_ply(Path::new(source))?
    };
    if let Ok(out) = std::env::var("WRITE_CLOUD") {
        write_ply(Path::new(&out), &cloud, PlyFormat::default())?;
    }
    let cfg = PoissonConfig {
        depth,
        full_depth: std::env::var("FULL_DEPTH")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(PoissonConfig::default().full_depth),
        scale: std::env::var("SCALE")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(PoissonConfig::default().scale),
        ..PoissonConfig::default()
    };
    let t = std::time::Instant::now();
    let s = poisson_reconstruct(&cloud, &cfg)?;
    let wall = t.elapsed().as_secs_f64();
    if let Ok(out) = std::env::var("WRITE_MESH") {
        write_ply_mesh(Path::new(&out), &s.mesh)?;
    }
    let topo = check_topology(&s.mesh);
    println!(
        "{} points, depth {depth}, full depth {}, cell {:.3} mm: {} vertices, closed manifold {}, \
         {wall:.3} s (solve {:.0} ms, contour {:.0} ms)",
        cloud.len(),
        cfg.full_depth,
        s.cell_size,
        s.mesh.vertices.len(),
        topo.is_watertight_manifold(),
        s.solve_ms,
        s.contour_ms
    );
    let cloud_err: Vec<f64> = cloud
        .positions()
        .iter()
        .map(|p| nearest(&spheres, p).0)
        .filter(|e| e.abs() <= 2.0)
        .collect();
    let n = cloud_err.len().max(1) as f64;
    println!(
        "cloud: RMS {:.4} mm, mean {:+.4} mm (points within 2 mm of a sphere)",
        (cloud_err.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
        cloud_err.iter().sum::<f64>() / n
    );
    let index = KdIndex::new(cloud.positions())?;
    let bins = [
        (0.0, 0.2),
        (0.2, 1.0),
        (1.0, f64::INFINITY),
        (0.0, 1.0),
        (0.0, f64::INFINITY),
    ];
    let mut acc = [(0usize, 0.0f64, 0.0f64); 5];
    for p in &s.mesh.vertices {
        let e = nearest(&spheres, p).0;
        if e.abs() > 2.0 {
            continue;
        }
        let d = index
            .nearest(p)
            .map_or(f64::INFINITY, |n| n.distance_squared.sqrt());
        for (b, a) in bins.iter().zip(acc.iter_mut()) {
            if d >= b.0 && d < b.1 {
                a.0 += 1;
                a.1 += e * e;
                a.2 += e;
            }
        }
    }
    for (b, a) in bins.iter().zip(&acc) {
        let n = a.0.max(1) as f64;
        println!(
            "  vertices [{:.1}, {:.1}) mm from the cloud: {:7}, RMS {:.4} mm, mean {:+.4} mm",
            b.0,
            b.1,
            a.0,
            (a.1 / n).sqrt(),
            a.2 / n
        );
    }
    Ok(())
}
