//! A virtual turntable scan of a known object, for the merge tests, bench and example.
//!
//! The object is the union of a rounded box and a sphere (smooth except along their seam, no
//! continuous symmetry), with an exact signed distance outside. A pinhole camera at the origin
//! (x right, y down, z forward, mm) looks at a turntable whose axis is tilted 25° toward the
//! camera from the vertical (-y) and passes through (0, 0, 400). Each view ray-casts the
//! object (sphere tracing on the exact distance, to 1e-7 mm), drops grazing hits (beyond 75°
//! from the surface normal, as a scanner would), and adds seeded Gaussian noise along the
//! view ray.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)] // test support: fail loudly

use nalgebra::{Isometry3, Point3, Rotation3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use sl_icp::{PointCloud, TurntableAxis};

/// Half extents of the rounded box's inner box (mm), and its rounding radius.
const BOX_HALF: [f64; 3] = [28.0, 26.0, 18.0];
const BOX_ROUND: f64 = 7.0;
/// Centre of the box in the object frame (y up along the axis, origin on the platter).
const BOX_CENTRE: [f64; 3] = [0.0, 33.0, 0.0];
/// The sphere: centre and radius (mm), overlapping a top corner of the box.
const SPHERE_CENTRE: [f64; 3] = [16.0, 66.0, 8.0];
const SPHERE_RADIUS: f64 = 20.0;
/// Bounding sphere of the object, for starting the ray marches.
const BOUND_CENTRE: [f64; 3] = [0.0, 45.0, 0.0];
const BOUND_RADIUS: f64 = 75.0;
/// Sphere tracing stops at this distance to the surface (mm).
const HIT_EPS: f64 = 1e-7;
/// Cosine of the largest accepted angle between the view ray and the normal (75°).
const MIN_COS: f64 = 0.2588;

/// Signed distance (mm) to the object in its own frame: exact outside, a lower bound of the
/// distance inside (so `|sdf|` never overstates how far a point is from the surface).
pub(crate) fn sdf(p: &Point3<f64>) -> f64 {
    let q = p - Point3::from(BOX_CENTRE);
    let d = Vector3::new(
        q.x.abs() - BOX_HALF[0],
        q.y.abs() - BOX_HALF[1],
        q.z.abs() - BOX_HALF[2],
    );
    let outside = Vector3::new(d.x.max(0.0), d.y.max(0.0), d.z.max(0.0)).norm();
    let inside = d.x.max(d.y).max(d.z).min(0.0);
    let rounded_box = outside + inside - BOX_ROUND;
    let sphere = (p - Point3::from(SPHERE_CENTRE)).norm() - SPHERE_RADIUS;
    rounded_box.min(sphere)
}

fn gradient(p: &Point3<f64>) -> Vector3<f64> {
    let h = 1e-5;
    let g = Vector3::new(
        sdf(&(p + Vector3::x() * h)) - sdf(&(p - Vector3::x() * h)),
        sdf(&(p + Vector3::y() * h)) - sdf(&(p - Vector3::y() * h)),
        sdf(&(p + Vector3::z() * h)) - sdf(&(p - Vector3::z() * h)),
    );
    g.normalize()
}

/// The virtual rig.
#[derive(Clone, Copy)]
pub(crate) struct Scene {
    /// The true turntable axis (camera frame).
    pub(crate) axis: TurntableAxis,
    /// `T_cam_object` at platter angle 0.
    pub(crate) object_at_zero: Isometry3<f64>,
    /// Image size and focal length (pixels); principal point at the centre.
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) focal: f64,
    /// Noise along the view ray, standard deviation in mm.
    pub(crate) noise_mm: f64,
}

impl Scene {
    /// The rig at a resolution giving about `points_per_view` points per view.
    pub(crate) fn new(points_per_view: usize, noise_mm: f64) -> Self {
        // The axis: -y tilted 25° toward the camera (top of the platter visible).
        let tilt = Rotation3::from_axis_angle(&Vector3::x_axis(), -25f64.to_radians());
        let direction = tilt * -Vector3::y();
        let axis = TurntableAxis::new(direction, Point3::new(0.0, 0.0, 400.0)).unwrap();
        // Object frame: y along the axis, origin on the axis point; x, z across.
        let y = direction;
        let x = Vector3::x();
        let z = x.cross(&y);
        let r = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[x, y, z]));
        let object_at_zero = Isometry3::from_parts(
            nalgebra::Translation3::new(0.0, 0.0, 400.0),
            nalgebra::UnitQuaternion::from_rotation_matrix(&r),
        );
        // About 16 % of a square image around the object is hit: size the image for the count.
        let side = ((points_per_view as f64 / 0.16).sqrt()).ceil() as usize;
        Self {
            axis,
            object_at_zero,
            width: side,
            height: side,
            // The object (~150 mm) fills ~85 % of the image at 400 mm.
            focal: side as f64 * 0.85 * 400.0 / 150.0,
            noise_mm,
        }
    }

    /// `T_cam_object` at platter angle `deg`.
    pub(crate) fn object_pose(&self, deg: f64) -> Isometry3<f64> {
        self.axis.motion(deg) * self.object_at_zero
    }

    /// The true `T_world_view` of the view at `deg` (world = the view at `first_deg`).
    pub(crate) fn true_pose(&self, first_deg: f64, deg: f64) -> Isometry3<f64> {
        self.axis.motion(first_deg) * self.axis.motion(deg).inverse()
    }

    /// One view at platter angle `deg`, noise seeded by `seed`.
    pub(crate) fn view(&self, deg: f64, seed: u64) -> PointCloud {
        let t_obj_cam = self.object_pose(deg).inverse();
        let origin = t_obj_cam * Point3::origin();
        // Principal point so that the object's bounding centre (at angle 0) is mid-image.
        let centre = self.object_at_zero * Point3::from(BOUND_CENTRE);
        let cx = (self.width as f64 - 1.0) / 2.0 - self.focal * centre.x / centre.z;
        let cy = (self.height as f64 - 1.0) / 2.0 - self.focal * centre.y / centre.z;
        let pts: Vec<Option<(Point3<f64>, u64)>> = (0..self.width * self.height)
            .into_par_iter()
            .map(|i| {
                let (u, v) = ((i % self.width) as f64, (i / self.width) as f64);
                let dir =
                    Vector3::new((u - cx) / self.focal, (v - cy) / self.focal, 1.0).normalize();
                let d = t_obj_cam.rotation * dir;
                let t = march(&origin, &d)?;
                let hit = origin + d * t;
                let cos = -gradient(&hit).dot(&d);
                (cos >= MIN_COS).then_some((Point3::from(dir * t), i as u64))
            })
            .collect();
        let normal = Normal::new(0.0, self.noise_mm).unwrap();
        let positions = pts
            .into_iter()
            .flatten()
            .map(|(p, i)| {
                let mut rng = Pcg64::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ i);
                let dir = p.coords.normalize();
                p + dir * normal.sample(&mut rng)
            })
            .collect();
        PointCloud::from_positions(positions)
    }

    /// RMS of the distances of `points` (world = camera frame of the view at `first_deg`) to
    /// the true surface, and the largest.
    pub(crate) fn surface_error(&self, first_deg: f64, points: &[Point3<f64>]) -> (f64, f64) {
        let t_obj_world = self.object_pose(first_deg).inverse();
        let d: Vec<f64> = points
            .par_iter()
            .map(|p| sdf(&(t_obj_world * p)).abs())
            .collect();
        let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len().max(1) as f64).sqrt();
        (rms, d.iter().copied().fold(0.0, f64::max))
    }
}

/// Distance along the unit ray `o + t d` (object frame) to the surface, if it hits.
fn march(o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
    // Enter the bounding sphere.
    let oc = o - Point3::from(BOUND_CENTRE);
    let b = oc.dot(d);
    let c = oc.norm_squared() - BOUND_RADIUS * BOUND_RADIUS;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let (t0, t1) = (-b - disc.sqrt(), -b + disc.sqrt());
    let mut t = t0.max(0.0);
    for _ in 0..512 {
        let s = sdf(&(o + d * t));
        if s < HIT_EPS {
            return Some(t);
        }
        t += s;
        if t > t1 {
            return None;
        }
    }
    None
}
