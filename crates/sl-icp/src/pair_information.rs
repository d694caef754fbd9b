//! What a pairwise registration of a merge really measures: the information of its pose
//! along the surface normals (point-to-plane), and the motions it leaves free.
//!
//! [`Registration::information`](crate::Registration) is Open3D's point-to-point
//! information `Σ GᵀG`, `G = [-[q]× | I]`: it is full rank for any three points, so it claims
//! that a sphere sliding on itself, or a bar turning about its own axis, is pinned. It is not:
//! the surfaces do not change under those motions, and the registration's answer along them
//! is whatever the start and the noise left. Along the normals, `J = [(q × n)ᵀ, nᵀ]` per
//! correspondence, the information of such a motion is zero.

use nalgebra::{Isometry3, Matrix6, Point3, SymmetricEigen, Vector3, Vector6};

use crate::PreparedCloud;
use crate::icp::sum_in_blocks;
use crate::se3::skew;

/// A direction of a registration's pose whose information is below this fraction of its
/// largest one (rotations measured in mm at the correspondences' RMS radius) counts as
/// degenerate and is given no weight. Measured on the rendered `slscan scan` scenes (1 mm
/// voxels, seed 0): the dumbbell's turn about its bar sits at 2–4e-5 of the largest
/// eigenvalue (what is left is the noise of the normals), every other direction above 0.2;
/// the pebble's low bumps measure its rotations at 3e-3 to 4e-2. 3e-4 sits a factor of ten
/// from both.
pub(crate) const DEGENERATE_RATIO: f64 = 3e-4;

/// A motion a pairwise registration does not measure: its surfaces barely change under it, so
/// its information along it is dropped and the turntable prior decides it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FreeMotion {
    /// A rotation about the line along `direction` through `point_mm` (a sphere about its
    /// centre, a bar or a cylinder about its axis), in the target view's frame.
    Rotation {
        /// Unit direction of the line.
        direction: Vector3<f64>,
        /// A point of the line, mm.
        point_mm: Point3<f64>,
    },
    /// A translation along `direction` (a plane or a prism sliding along itself), in the
    /// target view's frame.
    Translation {
        /// Unit direction.
        direction: Vector3<f64>,
    },
}

impl std::fmt::Display for FreeMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Rotation {
                direction: d,
                point_mm: p,
            } => write!(
                f,
                "rotation about ({:.2}, {:.2}, {:.2}) through ({:.1}, {:.1}, {:.1}) mm",
                d.x, d.y, d.z, p.x, p.y, p.z
            ),
            Self::Translation { direction: d } => {
                write!(f, "translation along ({:.2}, {:.2}, {:.2})", d.x, d.y, d.z)
            }
        }
    }
}

/// The point-to-plane information of a registration and what it leaves free.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PairInformation {
    /// `Σ JᵀJ` with `J = [(q × n)ᵀ, nᵀ]` over the correspondences (target point `q`, target
    /// normal `n`), its degenerate directions removed; ordered (rotation, translation) for a
    /// small motion on the left of the pose, as [`Registration::information`](crate::Registration).
    pub(crate) information: Matrix6<f64>,
    /// The removed directions.
    pub(crate) free: Vec<FreeMotion>,
}

/// The point-to-plane information of `pose` (`T_target_source`) over the correspondences of
/// `source`'s points within `max_distance` of `target`'s, degenerate directions removed.
/// `None` when the target has no normals or nothing corresponds.
pub(crate) fn pair_information(
    source: &PreparedCloud,
    target: &PreparedCloud,
    pose: &Isometry3<f64>,
    max_distance: f64,
) -> Option<PairInformation> {
    let normals = target.normals()?;
    let points = target.points();
    let index = target.index();
    let gate = max_distance * max_distance;
    let source_points = source.points();
    let (h, sum, count) = sum_in_blocks(
        source_points.len(),
        (Matrix6::<f64>::zeros(), Vector3::<f64>::zeros(), 0usize),
        |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2),
        |(h, sum, count), i| {
            let Some(p) = source_points.get(i) else {
                return;
            };
            let moved = pose * p;
            if let Some(nb) = index.nearest_within(&moved, gate)
                && let (Some(q), Some(n)) = (points.get(nb.index), normals.get(nb.index))
            {
                let c = q.coords.cross(n);
                let j = Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z);
                *h += j * j.transpose();
                *sum += q.coords;
                *count += 1;
            }
        },
    );
    if count < 6 {
        return None;
    }
    let centre = Point3::from(sum / count as f64);
    // The RMS radius of the correspondences about their centre: the lever arm of rotations.
    let radius = {
        let s: f64 = source
            .points()
            .iter()
            .map(|p| (pose * p - centre).norm_squared())
            .sum();
        (s / source.len().max(1) as f64).sqrt().max(1e-6)
    };
    Some(project_degenerate(&h, &centre, radius))
}

/// `measurement` (`T_target_source`) with its free motions taken from `model` instead: the
/// registration does not measure them, so their value is whatever the start and the noise
/// left, and a large one (a dumbbell turned 5° about its bar, 25 mm at the camera's distance)
/// leaks into the measured directions at second order even though its information is zero.
/// Each free motion of the measurement is replaced by the model's (a rotation by the twist of
/// `model · measurement⁻¹` about its line, a translation by its component along the
/// direction), a few passes since the motions do not commute exactly.
pub(crate) fn settle_free_motions(
    measurement: &Isometry3<f64>,
    model: &Isometry3<f64>,
    free: &[FreeMotion],
) -> Isometry3<f64> {
    /// Passes over the free motions; each shrinks what is left by the (small) swing.
    const PASSES: usize = 4;
    let mut settled = *measurement;
    if free.is_empty() {
        return settled;
    }
    for _ in 0..PASSES {
        for motion in free {
            // The left correction that would turn the measurement into the model.
            let delta = model * settled.inverse();
            let step = match motion {
                FreeMotion::Rotation {
                    direction,
                    point_mm,
                } => {
                    let q = delta.rotation.quaternion();
                    // The twist of the rotation about `direction` (swing-twist decomposition),
                    // from the quaternion with w ≥ 0 (q and -q are one rotation), so that it
                    // lies in [-π, π].
                    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
                    let twist = 2.0 * (sign * q.imag().dot(direction)).atan2(sign * q.w);
                    let axis = nalgebra::Unit::new_normalize(*direction);
                    let r = nalgebra::UnitQuaternion::from_axis_angle(&axis, twist);
                    Isometry3::from_parts(
                        nalgebra::Translation3::from(point_mm.coords - r * point_mm.coords),
                        r,
                    )
                }
                FreeMotion::Translation { direction } => {
                    let along = delta.translation.vector.dot(direction);
                    Isometry3::translation(
                        along * direction.x,
                        along * direction.y,
                        along * direction.z,
                    )
                }
            };
            settled = step * settled;
        }
    }
    settled
}

/// Removes the degenerate directions of `h` (see [`DEGENERATE_RATIO`]), judged with rotations
/// about `centre` scaled by `radius` (mm), and describes them.
pub(crate) fn project_degenerate(
    h: &Matrix6<f64>,
    centre: &Point3<f64>,
    radius: f64,
) -> PairInformation {
    // A motion (ω, v) about the centre is (ω, v + c × ω) about the origin: x = A y.
    let mut a = Matrix6::<f64>::identity();
    a.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&skew(&centre.coords));
    // Rotations in mm at the radius: y = D z with D = diag(I / r, I).
    let mut d = Matrix6::<f64>::identity();
    for i in 0..3 {
        d[(i, i)] = 1.0 / radius;
    }
    let ad = a * d;
    let scaled = ad.transpose() * h * ad;
    let scaled = (scaled + scaled.transpose()) * 0.5;
    let eig = SymmetricEigen::new(scaled);
    let largest = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let mut kept = Matrix6::zeros();
    let mut free = Vec::new();
    for (k, &lambda) in eig.eigenvalues.iter().enumerate() {
        let u: Vector6<f64> = eig.eigenvectors.column(k).into_owned();
        if largest > 0.0 && lambda >= DEGENERATE_RATIO * largest {
            kept += u * u.transpose() * lambda;
        } else {
            free.push(describe(&u, centre, radius));
        }
    }
    // Back to the origin's coordinates: z = (A D)⁻¹ x.
    let inv = ad.try_inverse().unwrap_or_else(Matrix6::identity);
    let information = inv.transpose() * kept * inv;
    PairInformation {
        information: (information + information.transpose()) * 0.5,
        free,
    }
}

/// The motion of the scaled direction `u` = (r ω, v) about `centre`: a rotation about its
/// screw axis, or a translation when it hardly turns.
fn describe(u: &Vector6<f64>, centre: &Point3<f64>, radius: f64) -> FreeMotion {
    let w = Vector3::new(u[0], u[1], u[2]); // rotation in mm at the radius
    let v = Vector3::new(u[3], u[4], u[5]);
    if w.norm() > v.norm() {
        let omega = w / radius;
        let direction = omega.normalize();
        // The screw axis: the points that move only along ω; p - c = ω × v / |ω|².
        let point_mm = centre + omega.cross(&v) / omega.norm_squared();
        FreeMotion::Rotation {
            direction,
            point_mm,
        }
    } else {
        FreeMotion::Translation {
            direction: v.normalize(),
        }
    }
}

/// `Σ (q × n, n)(q × n, n)ᵀ` of explicit correspondences: for tests.
#[cfg(test)]
fn information_of(points: &[(Point3<f64>, Vector3<f64>)]) -> Matrix6<f64> {
    points.iter().fold(Matrix6::zeros(), |h, (q, n)| {
        let c = q.coords.cross(n);
        let j = Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z);
        h + j * j.transpose()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points and outward normals of a sphere (Fibonacci lattice), a part of it.
    fn sphere(
        centre: Point3<f64>,
        radius: f64,
        n: usize,
        cap: f64,
    ) -> Vec<(Point3<f64>, Vector3<f64>)> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .filter_map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                let normal = Vector3::new(r * t.cos(), r * t.sin(), z);
                // Only the part facing -z (a camera at the origin sees that side).
                (normal.z < cap).then(|| (centre + normal * radius, normal))
            })
            .collect()
    }

    #[test]
    fn a_sphere_leaves_its_three_rotations_free() {
        let c = Point3::new(20.0, -10.0, 450.0);
        let pts = sphere(c, 25.0, 4000, 0.3);
        let info = project_degenerate(&information_of(&pts), &c, 25.0);
        assert_eq!(info.free.len(), 3, "{:?}", info.free);
        for f in &info.free {
            match f {
                FreeMotion::Rotation {
                    point_mm,
                    direction,
                } => {
                    // The line passes through the centre.
                    let off = (point_mm - c) - direction * (point_mm - c).dot(direction);
                    assert!(off.norm() < 1e-6, "{f}");
                }
                FreeMotion::Translation { .. } => panic!("{f}"),
            }
        }
        // Any rotation about the centre now costs nothing; a translation still does.
        let about_centre = |w: Vector3<f64>| {
            let t = c.coords.cross(&w); // (ω, c × ω): the motion ω × (x - c)
            Vector6::new(w.x, w.y, w.z, t.x, t.y, t.z)
        };
        let x = about_centre(Vector3::new(0.3, -0.2, 0.5));
        let q = x.dot(&(info.information * x));
        let t = Vector6::new(0.0, 0.0, 0.0, 0.5, 0.0, 0.0);
        let p = t.dot(&(info.information * t));
        assert!(q < 1e-9 * p, "{q} vs {p}");
    }

    #[test]
    fn two_spheres_leave_only_the_turn_about_their_line_free() {
        let (a, b) = (
            Point3::new(-60.0, 0.0, 450.0),
            Point3::new(60.0, 5.0, 450.0),
        );
        let mut pts = sphere(a, 25.0, 3000, 0.3);
        pts.extend(sphere(b, 25.0, 3000, 0.3));
        let centre = Point3::from((a.coords + b.coords) / 2.0);
        let info = project_degenerate(&information_of(&pts), &centre, 60.0);
        assert_eq!(info.free.len(), 1, "{:?}", info.free);
        let FreeMotion::Rotation {
            direction,
            point_mm,
        } = info.free[0]
        else {
            panic!("{:?}", info.free);
        };
        let line = (b - a).normalize();
        assert!(direction.dot(&line).abs() > 1.0 - 1e-9, "{direction}");
        let off = (point_mm - a) - line * (point_mm - a).dot(&line);
        assert!(off.norm() < 1e-6);
    }

    /// A dumbbell's registration turned 6° about its bar (which it does not measure) and
    /// slightly off elsewhere: settling takes the turn from the model and keeps the rest.
    #[test]
    fn settling_takes_the_free_turn_from_the_model_and_keeps_the_measured_rest() {
        use nalgebra::{Translation3, Unit, UnitQuaternion};
        let about = |d: Vector3<f64>, p: Point3<f64>, angle: f64| {
            let r = UnitQuaternion::from_axis_angle(&Unit::new_normalize(d), angle);
            Isometry3::from_parts(Translation3::from(p.coords - r * p.coords), r)
        };
        let bar = Vector3::new(1.0, 0.05, 0.1).normalize();
        let through = Point3::new(10.0, -20.0, 450.0);
        // The model: a 20° turn about a vertical axis 30 mm behind the object.
        let model = about(
            Vector3::y(),
            Point3::new(0.0, 0.0, 480.0),
            20f64.to_radians(),
        );
        // What the registration measured: the model, 0.05° off about the vertical at the
        // object and 0.02 mm off along z (measured), and 6° about the bar (not measured).
        let measured_error = Isometry3::translation(0.0, 0.0, 0.02)
            * about(Vector3::y(), through, 0.05f64.to_radians());
        let measurement = about(bar, through, 6f64.to_radians()) * measured_error * model;
        let free = [FreeMotion::Rotation {
            direction: bar,
            point_mm: through,
        }];
        let settled = settle_free_motions(&measurement, &model, &free);
        // What is left of the measurement against the model: no turn about the bar, and the
        // measured error (its component across the bar) unchanged.
        let left = settled * model.inverse();
        let twist = left.rotation.scaled_axis().dot(&bar);
        assert!(twist.abs() < 1e-9, "{twist}");
        let wanted = measured_error.rotation.scaled_axis();
        let across = |w: Vector3<f64>| w - bar * w.dot(&bar);
        assert!(
            (across(left.rotation.scaled_axis()) - across(wanted)).norm() < 1e-7,
            "{} vs {}",
            left.rotation.scaled_axis(),
            wanted
        );
        // Before settling, the free turn moves the object's points by ~25 mm at this range;
        // after, the object sits within the measured error of the model.
        let object = Point3::new(0.0, 0.0, 450.0);
        let before = (measurement * object - model * object).norm();
        let after = (settled * object - model * object).norm();
        assert!(before > 1.0, "{before}");
        assert!(after < 0.05, "{after}");
        // A free translation is settled along its direction only.
        let slid = Isometry3::translation(3.0 * bar.x, 3.0 * bar.y, 3.0 * bar.z) * model;
        let settled =
            settle_free_motions(&slid, &model, &[FreeMotion::Translation { direction: bar }]);
        assert!((settled.translation.vector - model.translation.vector).norm() < 1e-9);
        // Nothing free: unchanged.
        assert_eq!(settle_free_motions(&slid, &model, &[]), slid);
    }

    #[test]
    fn a_lumpy_surface_keeps_every_direction() {
        // Three faces of a box corner: nothing slides.
        let mut pts = Vec::new();
        for i in 0..30 {
            for j in 0..30 {
                let (u, v) = (i as f64, j as f64);
                pts.push((Point3::new(u, v, 400.0), -Vector3::z()));
                pts.push((Point3::new(0.0, u, 400.0 + v), -Vector3::x()));
                pts.push((Point3::new(u, 0.0, 400.0 + v), -Vector3::y()));
            }
        }
        let h = information_of(&pts);
        let info = project_degenerate(&h, &Point3::new(10.0, 10.0, 410.0), 20.0);
        assert!(info.free.is_empty(), "{:?}", info.free);
        assert!((info.information - h).norm() < 1e-6 * h.norm());
    }
}
