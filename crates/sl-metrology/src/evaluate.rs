//! `evaluate`: the VDI/VDE 2634 part 2 figures of a cloud against a [`Truth`].

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use sl_cloud::PointCloud;
use sl_cloud::{fit_plane, fit_sphere};

use crate::find::{SplitMix, ransac_plane, ransac_sphere, refine_centre, subsample};
use crate::{Feature, MetrologyError, PlaneSpec, SphereSpec, Truth};

/// Fraction of a feature's points, farthest from its fitted surface, that VDI/VDE 2634 part 2
/// lets a form or flatness measurement leave out (0.3 %).
pub const VDI_TRIM_FRACTION: f64 = 0.003;

/// Fewest points a feature must have to be measured: a sphere fit needs 4 and a plane 3, but
/// a form figure over a handful of points says nothing; 20 points still give a usable fit.
pub const MIN_FEATURE_POINTS: usize = 20;

/// Options of [`evaluate_with`].
#[derive(Debug, Clone, PartialEq)]
pub struct EvaluateConfig {
    /// Fraction of points left out of the `_trimmed` form and flatness figures. Default
    /// [`VDI_TRIM_FRACTION`].
    pub trim_fraction: f64,
    /// RANSAC hypotheses for a feature without a nominal position. Default 1000: with the
    /// feature holding a fifth of the points, a 3-point sample is all inliers with
    /// probability 1/125, so 1000 draws miss it with probability (1 − 1/125)^1000 ≈ 3e-4.
    pub ransac_iterations: usize,
    /// RANSAC scores its hypotheses on at most this many points, spread evenly over the cloud.
    /// Default 4000: the support of a feature of a fifth of the cloud is then known to ~3 %.
    pub ransac_points: usize,
    /// Seed of the RANSAC samples (the report is reproducible).
    pub seed: u64,
}

impl Default for EvaluateConfig {
    fn default() -> Self {
        Self {
            trim_fraction: VDI_TRIM_FRACTION,
            ransac_iterations: 1000,
            ransac_points: 4000,
            seed: 0,
        }
    }
}

/// How a feature was located.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Located {
    /// At its nominal position, given in the truth.
    Nominal,
    /// Found by RANSAC (the truth gives no position).
    Found,
}

/// Probing errors of one sphere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SphereReport {
    /// The feature.
    pub name: String,
    /// How its points were selected.
    pub located: Located,
    /// Points of the sphere (within `select_mm` of its reference surface).
    pub points: usize,
    /// Centre of the least-squares sphere with free radius (mm).
    pub centre_mm: Point3<f64>,
    /// Its radius (mm).
    pub radius_mm: f64,
    /// Calibrated radius (mm).
    pub nominal_radius_mm: f64,
    /// Probing error size `P_S`: fitted minus calibrated diameter (mm).
    pub probing_size_mm: f64,
    /// Probing error form `P_F`: range of the radial residuals of the least-squares sphere
    /// (mm), over all its points.
    pub probing_form_mm: f64,
    /// The same range with the `trim_fraction` of points farthest from the fitted sphere left
    /// out, as VDI/VDE 2634 part 2 allows (mm).
    pub probing_form_trimmed_mm: f64,
    /// Points left out of `probing_form_trimmed_mm`.
    pub trimmed_points: usize,
    /// RMS of the radial residuals of the fitted sphere (mm).
    pub fit_rms_mm: f64,
    /// RMS of the signed distances to the reference surface: the nominal sphere when its
    /// centre is given, else the sphere of calibrated radius at the found centre (mm).
    pub rms_to_reference_mm: f64,
}

/// Sphere-spacing error of a pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpherePairReport {
    /// The feature.
    pub name: String,
    /// The two spheres.
    pub spheres: [String; 2],
    /// Distance of the fitted centres (mm).
    pub centre_distance_mm: f64,
    /// Calibrated distance (mm).
    pub nominal_distance_mm: f64,
    /// Sphere-spacing error SD: measured minus calibrated distance (mm).
    pub sphere_spacing_mm: f64,
}

/// Flatness of one plane.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneReport {
    /// The feature.
    pub name: String,
    /// How its points were selected.
    pub located: Located,
    /// Points of the plane.
    pub points: usize,
    /// Centroid of the points (a point of the least-squares plane, mm).
    pub point_mm: Point3<f64>,
    /// Unit normal of the least-squares plane.
    pub normal: Vector3<f64>,
    /// Flatness measurement error F: range of the residuals of the least-squares plane (mm),
    /// all points.
    pub flatness_mm: f64,
    /// The same range with the `trim_fraction` of points farthest from the plane left out (mm).
    pub flatness_trimmed_mm: f64,
    /// Points left out of `flatness_trimmed_mm`.
    pub trimmed_points: usize,
    /// RMS of the residuals of the least-squares plane (mm).
    pub fit_rms_mm: f64,
    /// RMS of the signed distances to the reference plane: the nominal one when given, else
    /// the fitted one (mm).
    pub rms_to_reference_mm: f64,
}

/// Everything [`evaluate`] measured. Its `Debug` form leaves out the per-point distances
/// (it gives their count), so that a failing assertion stays readable.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// Points of the cloud (finite or not).
    pub points: usize,
    /// Points in at least one feature's selection region.
    pub assigned_points: usize,
    /// One entry per sphere, in the truth's order.
    pub spheres: Vec<SphereReport>,
    /// One entry per sphere pair.
    pub sphere_pairs: Vec<SpherePairReport>,
    /// One entry per plane.
    pub planes: Vec<PlaneReport>,
    /// RMS of the signed distances of the assigned points to their reference surfaces (mm).
    pub rms_to_reference_mm: f64,
    /// Largest absolute such distance (mm).
    pub max_to_reference_mm: f64,
    /// Fraction of points left out of the `_trimmed` figures.
    pub trim_fraction: f64,
    /// Per point of the cloud, in its order: the signed distance to the reference surface of
    /// the nearest feature whose region holds it (mm, positive outside a sphere and on the
    /// normal's side of a plane), NaN for points of no feature. Feeds [`crate::heat_map`];
    /// not written to JSON.
    #[serde(skip)]
    pub signed_distances_mm: Vec<f32>,
}

impl std::fmt::Debug for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Report")
            .field("points", &self.points)
            .field("assigned_points", &self.assigned_points)
            .field("spheres", &self.spheres)
            .field("sphere_pairs", &self.sphere_pairs)
            .field("planes", &self.planes)
            .field("rms_to_reference_mm", &self.rms_to_reference_mm)
            .field("max_to_reference_mm", &self.max_to_reference_mm)
            .field("trim_fraction", &self.trim_fraction)
            .field(
                "signed_distances_mm",
                &format_args!("[{} values]", self.signed_distances_mm.len()),
            )
            .finish()
    }
}

impl Report {
    /// The figures as lines of text, one per feature, for a terminal.
    pub fn summary(&self) -> Vec<String> {
        let mut lines = Vec::new();
        for s in &self.spheres {
            lines.push(format!(
                "sphere {}: probing size {:+.4} mm, form {:.4} mm ({:.4} mm with {} of {} points left out); radius {:.4} mm",
                s.name,
                s.probing_size_mm,
                s.probing_form_mm,
                s.probing_form_trimmed_mm,
                s.trimmed_points,
                s.points,
                s.radius_mm
            ));
        }
        for p in &self.sphere_pairs {
            lines.push(format!(
                "pair {}: sphere spacing {:+.4} mm (centres {:.4} mm apart, nominal {:.4} mm)",
                p.name, p.sphere_spacing_mm, p.centre_distance_mm, p.nominal_distance_mm
            ));
        }
        for p in &self.planes {
            lines.push(format!(
                "plane {}: flatness {:.4} mm ({:.4} mm with {} of {} points left out); fit RMS {:.4} mm",
                p.name,
                p.flatness_mm,
                p.flatness_trimmed_mm,
                p.trimmed_points,
                p.points,
                p.fit_rms_mm
            ));
        }
        lines.push(format!(
            "{} of {} points measured; RMS to the reference surfaces {:.4} mm, largest {:.4} mm",
            self.assigned_points, self.points, self.rms_to_reference_mm, self.max_to_reference_mm
        ));
        lines
    }
}

/// A reference surface: where signed distances are measured from.
#[derive(Debug, Clone, Copy)]
enum Surface {
    Sphere { centre: Point3<f64>, radius: f64 },
    Plane { normal: Vector3<f64>, offset: f64 },
}

impl Surface {
    fn distance(&self, p: &Point3<f64>) -> f64 {
        match *self {
            Self::Sphere { centre, radius } => (p - centre).norm() - radius,
            Self::Plane { normal, offset } => normal.dot(&p.coords) - offset,
        }
    }
}

/// Range of `residuals` over all values and with the `trim` fraction of largest magnitudes
/// left out: `(range, trimmed range, points left out)`.
fn ranges(mut residuals: Vec<f64>, trim: f64) -> (f64, f64, usize) {
    let range = |r: &[f64]| {
        let (lo, hi) = r
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &d| {
                (lo.min(d), hi.max(d))
            });
        hi - lo
    };
    let all = range(&residuals);
    residuals.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    let dropped = (residuals.len() as f64 * trim).floor() as usize;
    let keep = residuals.len().saturating_sub(dropped).max(1);
    (
        all,
        range(residuals.get(..keep).unwrap_or(&residuals)),
        dropped,
    )
}

struct Located3 {
    surface: Surface,
    members: Vec<usize>,
    located: Located,
}

fn select(points: &[Point3<f64>], surface: &Surface, band: f64) -> Vec<usize> {
    points
        .iter()
        .enumerate()
        .filter(|(_, p)| surface.distance(p).abs() <= band)
        .map(|(i, _)| i)
        .collect()
}

fn gather(points: &[Point3<f64>], idx: &[usize]) -> Vec<Point3<f64>> {
    idx.iter().filter_map(|&i| points.get(i).copied()).collect()
}

fn too_few(name: &str, found: usize) -> MetrologyError {
    MetrologyError::TooFewPoints {
        feature: name.to_owned(),
        found,
        needed: MIN_FEATURE_POINTS,
    }
}

fn locate_sphere(
    s: &SphereSpec,
    points: &[Point3<f64>],
    free: &[bool],
    cfg: &EvaluateConfig,
    rng: &mut SplitMix,
) -> Result<Located3, MetrologyError> {
    let (centre, located) = match s.centre_mm {
        Some(c) => (c, Located::Nominal),
        None => {
            let candidates: Vec<Point3<f64>> = points
                .iter()
                .zip(free)
                .filter(|(_, f)| **f)
                .map(|(p, _)| *p)
                .collect();
            let sample = subsample(&candidates, cfg.ransac_points);
            let (mut centre, support) = ransac_sphere(
                &sample,
                s.radius_mm,
                s.select_mm,
                cfg.ransac_iterations,
                rng,
            )
            .ok_or_else(|| MetrologyError::NotFound {
                feature: s.name.clone(),
                reason: format!(
                    "no sphere of radius {} mm through any sample of the {} unassigned points",
                    s.radius_mm,
                    candidates.len()
                ),
            })?;
            // Ask for the support a real sphere leaves in the sample, not one stray triple.
            if support < MIN_FEATURE_POINTS.min(sample.len()) {
                return Err(MetrologyError::NotFound {
                    feature: s.name.clone(),
                    reason: format!(
                        "the best sphere of radius {} mm has {support} of {} sampled points within {} mm",
                        s.radius_mm,
                        sample.len(),
                        s.select_mm
                    ),
                });
            }
            // Refine on all free points in the band, twice (the band moves with the centre).
            for _ in 0..2 {
                let inliers: Vec<Point3<f64>> = candidates
                    .iter()
                    .filter(|p| (((*p - centre).norm()) - s.radius_mm).abs() <= s.select_mm)
                    .copied()
                    .collect();
                centre = refine_centre(&inliers, s.radius_mm, centre);
            }
            (centre, Located::Found)
        }
    };
    let surface = Surface::Sphere {
        centre,
        radius: s.radius_mm,
    };
    let mut members = select(points, &surface, s.select_mm);
    if located == Located::Found {
        members.retain(|&i| free.get(i).copied().unwrap_or(false));
    }
    Ok(Located3 {
        surface,
        members,
        located,
    })
}

fn locate_plane(
    s: &PlaneSpec,
    points: &[Point3<f64>],
    free: &[bool],
    cfg: &EvaluateConfig,
    rng: &mut SplitMix,
) -> Result<Located3, MetrologyError> {
    if let Some(n) = s.nominal {
        let norm = n.normal.norm();
        let surface = Surface::Plane {
            normal: n.normal / norm,
            offset: n.offset_mm / norm,
        };
        return Ok(Located3 {
            members: select(points, &surface, s.select_mm),
            surface,
            located: Located::Nominal,
        });
    }
    let idx: Vec<usize> = (0..points.len()).filter(|&i| free[i]).collect();
    let candidates = gather(points, &idx);
    let sample = subsample(&candidates, cfg.ransac_points);
    let (normal, offset, support) = ransac_plane(&sample, s.select_mm, cfg.ransac_iterations, rng)
        .ok_or_else(|| MetrologyError::NotFound {
            feature: s.name.clone(),
            reason: format!(
                "no plane through any sample of the {} unassigned points",
                candidates.len()
            ),
        })?;
    if support < MIN_FEATURE_POINTS.min(sample.len()) {
        return Err(MetrologyError::NotFound {
            feature: s.name.clone(),
            reason: format!(
                "the best plane has {support} of {} sampled points within {} mm",
                sample.len(),
                s.select_mm
            ),
        });
    }
    let mut surface = Surface::Plane { normal, offset };
    // Refine by least squares on the points in the band, twice.
    for _ in 0..2 {
        let inliers: Vec<Point3<f64>> = candidates
            .iter()
            .filter(|p| surface.distance(p).abs() <= s.select_mm)
            .copied()
            .collect();
        let fit = fit_plane(&inliers).map_err(|e| MetrologyError::fit(&s.name, e))?;
        surface = Surface::Plane {
            normal: fit.normal,
            offset: fit.normal.dot(&fit.point.coords),
        };
    }
    let mut members = select(points, &surface, s.select_mm);
    members.retain(|&i| free.get(i).copied().unwrap_or(false));
    Ok(Located3 {
        surface,
        members,
        located: Located::Found,
    })
}

/// [`evaluate_with`] with the default options.
///
/// # Errors
/// See [`evaluate_with`].
pub fn evaluate(cloud: &PointCloud, truth: &Truth) -> Result<Report, MetrologyError> {
    evaluate_with(cloud, truth, &EvaluateConfig::default())
}

/// Measures `cloud` (mm) against `truth`, as VDI/VDE 2634 part 2 describes:
///
/// - each feature's points are those within its `select_mm` of its nominal surface, or — when
///   the truth gives no position — of the surface found by RANSAC (sphere of the calibrated
///   radius, or the plane with most points) among the points no earlier feature took, refined
///   by least squares;
/// - a sphere gets a least-squares fit with free radius: probing error form (range of the
///   radial residuals) and size (fitted minus calibrated diameter);
/// - a sphere pair: the distance of the fitted centres minus the calibrated one;
/// - a plane gets a least-squares plane: flatness (range of the residuals);
/// - form and flatness are given over all points and with the `trim_fraction` farthest left out.
///
/// Non-finite points belong to no feature.
///
/// # Errors
/// [`MetrologyError::InvalidTruth`], [`MetrologyError::InvalidParameter`],
/// [`MetrologyError::NotFound`], [`MetrologyError::TooFewPoints`] (fewer than
/// [`MIN_FEATURE_POINTS`]) or [`MetrologyError::Fit`], naming the feature.
pub fn evaluate_with(
    cloud: &PointCloud,
    truth: &Truth,
    cfg: &EvaluateConfig,
) -> Result<Report, MetrologyError> {
    truth.validate()?;
    if !(0.0..0.5).contains(&cfg.trim_fraction) {
        return Err(MetrologyError::InvalidParameter {
            parameter: "trim_fraction",
            reason: format!("{} is not in [0, 0.5)", cfg.trim_fraction),
        });
    }
    if cfg.ransac_iterations == 0 || cfg.ransac_points < 3 {
        return Err(MetrologyError::InvalidParameter {
            parameter: "ransac_iterations/ransac_points",
            reason: "RANSAC needs at least one hypothesis scored on at least 3 points".to_owned(),
        });
    }
    let points = cloud.positions();
    let finite: Vec<bool> = points
        .iter()
        .map(|p| p.coords.iter().all(|v| v.is_finite()))
        .collect();
    // Points not yet taken by a feature that was found (not placed): the next search skips
    // them, so the second sphere of a dumbbell is not the first one again.
    let mut free = finite.clone();
    let mut rng = SplitMix::new(cfg.seed);
    let mut best: Vec<f64> = vec![f64::NAN; points.len()];
    let mut spheres = Vec::new();
    let mut planes = Vec::new();

    let record = |loc: &Located3, best: &mut Vec<f64>| -> f64 {
        let mut sq = 0.0;
        for &i in &loc.members {
            if let (Some(p), Some(b)) = (points.get(i), best.get_mut(i)) {
                let d = loc.surface.distance(p);
                sq += d * d;
                if b.is_nan() || d.abs() < b.abs() {
                    *b = d;
                }
            }
        }
        (sq / loc.members.len().max(1) as f64).sqrt()
    };

    for f in &truth.features {
        match f {
            Feature::Sphere(s) => {
                let loc = locate_sphere(s, points, &free, cfg, &mut rng)?;
                let members: Vec<usize> =
                    loc.members.iter().copied().filter(|&i| finite[i]).collect();
                if members.len() < MIN_FEATURE_POINTS {
                    return Err(too_few(&s.name, members.len()));
                }
                let pts = gather(points, &members);
                let fit = fit_sphere(&pts).map_err(|e| MetrologyError::fit(&s.name, e))?;
                let residuals: Vec<f64> = pts
                    .iter()
                    .map(|p| (p - fit.centre).norm() - fit.radius)
                    .collect();
                let (form, trimmed, dropped) = ranges(residuals, cfg.trim_fraction);
                let loc = Located3 { members, ..loc };
                let rms_ref = record(&loc, &mut best);
                if loc.located == Located::Found {
                    for &i in &loc.members {
                        free[i] = false;
                    }
                }
                spheres.push(SphereReport {
                    name: s.name.clone(),
                    located: loc.located,
                    points: pts.len(),
                    centre_mm: fit.centre,
                    radius_mm: fit.radius,
                    nominal_radius_mm: s.radius_mm,
                    probing_size_mm: 2.0 * (fit.radius - s.radius_mm),
                    probing_form_mm: form,
                    probing_form_trimmed_mm: trimmed,
                    trimmed_points: dropped,
                    fit_rms_mm: fit.rms,
                    rms_to_reference_mm: rms_ref,
                });
            }
            Feature::Plane(s) => {
                let loc = locate_plane(s, points, &free, cfg, &mut rng)?;
                let members: Vec<usize> =
                    loc.members.iter().copied().filter(|&i| finite[i]).collect();
                if members.len() < MIN_FEATURE_POINTS {
                    return Err(too_few(&s.name, members.len()));
                }
                let pts = gather(points, &members);
                let fit = fit_plane(&pts).map_err(|e| MetrologyError::fit(&s.name, e))?;
                let residuals: Vec<f64> = pts.iter().map(|p| fit.distance(p)).collect();
                let (flat, trimmed, dropped) = ranges(residuals, cfg.trim_fraction);
                let loc = Located3 { members, ..loc };
                let rms_ref = record(&loc, &mut best);
                if loc.located == Located::Found {
                    for &i in &loc.members {
                        free[i] = false;
                    }
                }
                planes.push(PlaneReport {
                    name: s.name.clone(),
                    located: loc.located,
                    points: pts.len(),
                    point_mm: fit.point,
                    normal: fit.normal,
                    flatness_mm: flat,
                    flatness_trimmed_mm: trimmed,
                    trimmed_points: dropped,
                    fit_rms_mm: fit.rms,
                    rms_to_reference_mm: rms_ref,
                });
            }
            Feature::SpherePair(_) => {}
        }
    }
    let mut sphere_pairs = Vec::new();
    for f in &truth.features {
        if let Feature::SpherePair(p) = f {
            let centre = |name: &str| {
                spheres
                    .iter()
                    .find(|s| s.name == name)
                    .map(|s| s.centre_mm)
                    .ok_or_else(|| MetrologyError::truth(&p.name, format!("no sphere `{name}`")))
            };
            let d = (centre(&p.spheres[0])? - centre(&p.spheres[1])?).norm();
            sphere_pairs.push(SpherePairReport {
                name: p.name.clone(),
                spheres: p.spheres.clone(),
                centre_distance_mm: d,
                nominal_distance_mm: p.centre_distance_mm,
                sphere_spacing_mm: d - p.centre_distance_mm,
            });
        }
    }
    let (mut sq, mut n, mut max) = (0.0, 0usize, 0.0f64);
    for d in best.iter().filter(|d| !d.is_nan()) {
        sq += d * d;
        n += 1;
        max = max.max(d.abs());
    }
    Ok(Report {
        points: points.len(),
        assigned_points: n,
        spheres,
        sphere_pairs,
        planes,
        rms_to_reference_mm: (sq / n.max(1) as f64).sqrt(),
        max_to_reference_mm: max,
        trim_fraction: cfg.trim_fraction,
        signed_distances_mm: best.iter().map(|&d| d as f32).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PlaneNominal, SpherePairSpec};
    use approx::assert_abs_diff_eq;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// `n` unit vectors spread evenly over the sphere (Fibonacci lattice).
    fn fibonacci(n: usize) -> Vec<Vector3<f64>> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|k| {
                let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * k as f64;
                Vector3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect()
    }

    fn sphere(name: &str, radius: f64, centre: Option<Point3<f64>>, select: f64) -> Feature {
        Feature::Sphere(SphereSpec {
            name: name.to_owned(),
            radius_mm: radius,
            centre_mm: centre,
            select_mm: select,
        })
    }

    /// Antipodal pairs of points with residual +a or −a (alternating by pair) on a sphere of
    /// radius R + δ: by symmetry the least-squares sphere is the true one (Σ u·e = 0 and
    /// Σ e = 0), so the form is exactly 2a and the size exactly 2δ. Five more antipodal
    /// pairs at +6a keep the centre and move the radius by their mean, so the form over all
    /// points is exactly 7a; they are 10 of 4010 points, fewer than the 12 (0.3 %) the
    /// trimmed figure leaves out, which is again exactly 2a.
    #[test]
    fn probing_form_and_size_match_the_constructed_range() {
        let (c, r, delta, a) = (Point3::new(10.0, -20.0, 450.0), 25.0, 0.004, 0.01);
        let mut pts = Vec::new();
        for (k, u) in fibonacci(2000).into_iter().enumerate() {
            let e = if k % 2 == 0 { a } else { -a };
            pts.push(c + u * (r + delta + e));
            pts.push(c - u * (r + delta + e));
        }
        let truth = Truth::new("test").with(sphere("ball", r, Some(c), 1.0));
        let rep = evaluate(&PointCloud::from_positions(pts.clone()), &truth).unwrap();
        let s = &rep.spheres[0];
        assert_eq!(s.points, 4000);
        assert_eq!(s.located, Located::Nominal);
        assert_abs_diff_eq!(s.probing_form_mm, 2.0 * a, epsilon = 1e-9);
        assert_abs_diff_eq!(s.probing_size_mm, 2.0 * delta, epsilon = 1e-9);
        assert_abs_diff_eq!(s.centre_mm, c, epsilon = 1e-9);
        assert_abs_diff_eq!(s.fit_rms_mm, a, epsilon = 1e-9);
        // The reference surface is the nominal sphere: residuals δ ± a, RMS sqrt(δ² + a²).
        assert_abs_diff_eq!(
            s.rms_to_reference_mm,
            (delta * delta + a * a).sqrt(),
            epsilon = 1e-9
        );

        for u in fibonacci(5) {
            pts.push(c + u * (r + delta + 6.0 * a));
            pts.push(c - u * (r + delta + 6.0 * a));
        }
        // Clutter beyond the selection band is not the sphere's.
        pts.push(c + Vector3::new(0.0, 0.0, r + 1.5));
        pts.push(Point3::new(f64::NAN, 0.0, 0.0));
        let rep = evaluate(&PointCloud::from_positions(pts), &truth).unwrap();
        let s = &rep.spheres[0];
        assert_eq!(s.points, 4010);
        assert_eq!(s.trimmed_points, 12);
        assert_abs_diff_eq!(s.probing_form_mm, 7.0 * a, epsilon = 1e-9);
        assert_abs_diff_eq!(s.probing_form_trimmed_mm, 2.0 * a, epsilon = 1e-9);
        assert_eq!(rep.points, 4012);
        assert_eq!(rep.assigned_points, 4010);
        assert!(rep.signed_distances_mm[4010].is_nan() && rep.signed_distances_mm[4011].is_nan());
        assert_abs_diff_eq!(
            f64::from(rep.signed_distances_mm[0]),
            delta + a,
            epsilon = 1e-6
        );
    }

    /// A 60 × 60 grid on a tilted plane with a checker pattern of residuals ±a: the pattern is
    /// orthogonal to the plane's in-plane coordinates and has zero mean, so the least-squares
    /// plane is the true one and the flatness is exactly 2a. Three points +10a off at the
    /// grid's centre shift only the offset: flatness 11a over all points, 2a with 0.3 %
    /// (10 of 3603 points) left out.
    #[test]
    fn flatness_matches_the_constructed_range() {
        let normal = Vector3::new(0.3, -0.2, -1.0).normalize();
        let origin = Point3::new(5.0, 8.0, 430.0);
        let u = normal.cross(&Vector3::x()).normalize();
        let v = normal.cross(&u);
        let a = 0.02;
        let mut pts = Vec::new();
        for i in 0..60 {
            for j in 0..60 {
                let e = if (i + j) % 2 == 0 { a } else { -a };
                let (x, y) = (f64::from(i) - 29.5, f64::from(j) - 29.5);
                pts.push(origin + u * (2.0 * x) + v * (1.5 * y) + normal * e);
            }
        }
        let nominal = PlaneNominal {
            normal,
            offset_mm: normal.dot(&origin.coords),
        };
        let plate = |nominal| {
            Truth::new("plate").with(Feature::Plane(PlaneSpec {
                name: "plate".to_owned(),
                nominal,
                select_mm: 1.0,
            }))
        };
        let rep = evaluate(
            &PointCloud::from_positions(pts.clone()),
            &plate(Some(nominal)),
        )
        .unwrap();
        let p = &rep.planes[0];
        assert_eq!(p.points, 3600);
        assert_abs_diff_eq!(p.flatness_mm, 2.0 * a, epsilon = 1e-9);
        assert_abs_diff_eq!(p.normal.dot(&normal).abs(), 1.0, epsilon = 1e-12);
        for _ in 0..3 {
            pts.push(origin + normal * (10.0 * a));
        }
        let rep = evaluate(
            &PointCloud::from_positions(pts.clone()),
            &plate(Some(nominal)),
        )
        .unwrap();
        let p = &rep.planes[0];
        assert_eq!((p.points, p.trimmed_points), (3603, 10));
        assert_abs_diff_eq!(p.flatness_mm, 11.0 * a, epsilon = 1e-9);
        assert_abs_diff_eq!(p.flatness_trimmed_mm, 2.0 * a, epsilon = 1e-9);

        // Without a nominal plane, among clutter: found, same figures.
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for _ in 0..1500 {
            pts.push(Point3::new(
                rng.random_range(-80.0..80.0),
                rng.random_range(-80.0..80.0),
                rng.random_range(380.0..480.0),
            ));
        }
        let rep = evaluate(&PointCloud::from_positions(pts), &plate(None)).unwrap();
        let p = &rep.planes[0];
        assert_eq!(p.located, Located::Found);
        // The clutter points within the 1 mm band (≈ 1500 · 2 mm · 120 mm · 90 mm / the box's
        // 2.56e6 mm³ ≈ 13) join the plane; its normal stays the true one to 1e-3.
        assert!((3603..3603 + 40).contains(&p.points), "{}", p.points);
        assert_abs_diff_eq!(p.normal.dot(&normal).abs(), 1.0, epsilon = 1e-6);
    }

    /// A dumbbell whose centres the user does not know, among clutter: RANSAC with the
    /// calibrated radius finds both spheres, and the spacing error is the one built in.
    #[test]
    fn spheres_without_centres_are_found() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.01).unwrap();
        let (left, right) = (
            Point3::new(-60.0, 5.0, 450.0),
            Point3::new(60.03, 5.0, 450.0),
        );
        let mut pts = Vec::new();
        for c in [left, right] {
            for _ in 0..3000 {
                // The half facing the camera at the origin.
                let t: f64 = rng.random_range(0.0..1.5);
                let p: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let u = Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), -t.cos());
                pts.push(c + u * (25.0 + noise.sample(&mut rng)));
            }
        }
        for _ in 0..1500 {
            pts.push(Point3::new(
                rng.random_range(-150.0..150.0),
                rng.random_range(-100.0..100.0),
                rng.random_range(380.0..520.0),
            ));
        }
        let truth = Truth::new("dumbbell")
            .with(sphere("a", 25.0, None, 1.0))
            .with(sphere("b", 25.0, None, 1.0))
            .with(Feature::SpherePair(SpherePairSpec {
                name: "bar".to_owned(),
                spheres: ["a".to_owned(), "b".to_owned()],
                centre_distance_mm: 120.0,
            }));
        let rep = evaluate(&PointCloud::from_positions(pts), &truth).unwrap();
        let [a, b] = [&rep.spheres[0], &rep.spheres[1]];
        // Which sphere is found first is RANSAC's choice; together they are the two.
        let near = |c: &Point3<f64>| (c - left).norm().min((c - right).norm());
        // Centre error ~ σ·sqrt(3/n) ≈ 3e-4 mm; clutter in the 2 mm band (≈ 3 points) adds
        // less than that.
        assert!(
            near(&a.centre_mm) < 0.005 && near(&b.centre_mm) < 0.005,
            "{rep:?}"
        );
        assert!(((a.centre_mm - b.centre_mm).norm() - 120.03).abs() < 0.005);
        assert_eq!((a.located, b.located), (Located::Found, Located::Found));
        assert!((3000..3020).contains(&a.points) && (3000..3020).contains(&b.points));
        assert_abs_diff_eq!(rep.sphere_pairs[0].sphere_spacing_mm, 0.03, epsilon = 0.005);
    }

    /// Errors name the feature: too few points near a nominal sphere, no sphere in clutter.
    #[test]
    fn errors_name_the_feature() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let clutter: Vec<_> = (0..200)
            .map(|_| {
                Point3::new(
                    rng.random_range(-50.0..50.0),
                    rng.random_range(-50.0..50.0),
                    rng.random_range(400.0..500.0),
                )
            })
            .collect();
        let cloud = PointCloud::from_positions(clutter);
        let far = Truth::new("").with(sphere("far", 25.0, Some(Point3::new(0.0, 0.0, 900.0)), 1.0));
        match evaluate(&cloud, &far) {
            Err(MetrologyError::TooFewPoints { feature, found, .. }) => {
                assert_eq!((feature.as_str(), found), ("far", 0));
            }
            other => panic!("{other:?}"),
        }
        let lost = Truth::new("").with(sphere("lost", 25.0, None, 0.5));
        match evaluate(&cloud, &lost) {
            Err(e @ MetrologyError::NotFound { .. }) => assert!(e.to_string().contains("lost")),
            other => panic!("{other:?}"),
        }
        let bad = EvaluateConfig {
            trim_fraction: 0.7,
            ..EvaluateConfig::default()
        };
        assert!(matches!(
            evaluate_with(&cloud, &far, &bad),
            Err(MetrologyError::InvalidParameter { .. })
        ));
    }
}
