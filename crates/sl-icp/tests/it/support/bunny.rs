//! Loading the Stanford bunny scans of `$SL_DATA/bunny` (shared by tests, benches, examples).
//!
//! The scans are in metres; they are converted to millimetres here. `bun.conf` gives per scan
//! `tx ty tz qx qy qz qw` with `p_world = R(q)^T p + t` (see `$SL_DATA/README.md`), so
//! `T_world_scan = (R(q)^T, 1000 t)` in mm.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)] // test support: fail loudly

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use sl_icp::PointCloud;

/// Metres to millimetres.
pub(crate) const MM_PER_M: f64 = 1000.0;

/// `$SL_DATA/bunny`, or `None` (after printing why) when `SL_DATA` is unset.
pub(crate) fn bunny_dir(what: &str) -> Option<PathBuf> {
    match std::env::var_os("SL_DATA") {
        Some(d) => Some(Path::new(&d).join("bunny")),
        None => {
            eprintln!("SL_DATA not set: skipping {what}");
            None
        }
    }
}

/// A scan in mm and its reference pose `T_world_scan` (mm).
pub(crate) struct Scan {
    pub(crate) cloud: PointCloud,
    pub(crate) t_world_scan: Isometry3<f64>,
}

/// Loads `name` (e.g. `"bun045"`) and its pose from `bun.conf`.
pub(crate) fn load(dir: &Path, name: &str) -> Scan {
    let mut cloud = sl_cloud::read_ply(&dir.join(format!("{name}.ply"))).unwrap();
    for p in cloud.positions_mut() {
        *p = Point3::from(p.coords * MM_PER_M);
    }
    let conf = std::fs::read_to_string(dir.join("bun.conf")).unwrap();
    let line = conf
        .lines()
        .find(|l| l.starts_with("bmesh") && l.contains(&format!("{name}.ply")))
        .unwrap();
    let v: Vec<f64> = line
        .split_whitespace()
        .skip(2)
        .map(|s| s.parse().unwrap())
        .collect();
    let q = UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5]));
    let t_world_scan = Isometry3::from_parts(
        Translation3::from(Vector3::new(v[0], v[1], v[2]) * MM_PER_M),
        q.inverse(),
    );
    Scan {
        cloud,
        t_world_scan,
    }
}

/// The reference `T_target_source` of two scans.
pub(crate) fn reference(target: &Scan, source: &Scan) -> Isometry3<f64> {
    target.t_world_scan.inverse() * source.t_world_scan
}

/// The start used by every "5° off" figure: the reference pose followed by a 5° rotation about
/// the source's vertical axis (+y of the scan, the turntable axis of the Stanford scanner)
/// through the source centroid, `T_init = T_ref * R_y(5°) about c`.
pub(crate) fn perturbed(
    reference: &Isometry3<f64>,
    source_centroid: &Point3<f64>,
) -> Isometry3<f64> {
    let r = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 5f64.to_radians());
    let c = source_centroid.coords;
    let p = Isometry3::from_parts(Translation3::from(c - r * c), r);
    reference * p
}
