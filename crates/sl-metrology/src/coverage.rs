//! How much of a known surface a scan covers, and how far the scan lies from it: the true
//! surface as a triangle mesh (the virtual rig's object, a CAD model), sampled evenly over its
//! area.
//!
//! - [`surface_coverage`]: the fraction of the true surface within a distance `d` of the
//!   scanned points (or of a mesh's area-weighted samples). A surface point farther than `d`
//!   from every scanned point is a part of the object the scan missed.
//! - [`distance_to_surface`]: the distance of every scanned point to the true surface (exact
//!   point-to-triangle distances), with its RMS.
//!
//! # Choosing `d`
//! `d` must exceed the largest distance from a covered surface point to its nearest scanned
//! point, which the scan's sampling sets: with samples `s` apart on a grid, no surface point is
//! farther than `s/√2 ≈ 0.71 s` from one; a surface seen at 60° from its normal is sampled
//! twice as sparsely across the slope (`√(1 + 4)/2 · s ≈ 1.1 s`), and noise and registration
//! error add a fraction of `s`. [`COVERAGE_SPACINGS`] `= 2` spacings clears all of that, while a
//! hole in the scan wider than `2d` still shows (its part farther than `d` from its rim).

use nalgebra::{Point3, Vector3};
use serde::Serialize;
use sl_cloud::{KdIndex, PointCloud, TriangleMesh};

use crate::MetrologyError;

/// Coverage distance in units of the scan's sample spacing (see the module docs): 2.
pub const COVERAGE_SPACINGS: f64 = 2.0;

/// Default area of the true surface each sample stands for (mm²): 0.04 mm², samples about
/// 0.2 mm apart — finer than any scan's sampling here (0.31 mm pixels at full resolution, a
/// 0.5 mm merge voxel), so the coverage is resolved to a small fraction of `d`.
pub const DEFAULT_TRUTH_SAMPLE_AREA_MM2: f64 = 0.04;

/// Nearest truth samples whose triangles [`distance_to_surface`] tries for each point: with
/// samples 0.2 mm apart, the closest triangle is among the 8 nearest samples' triangles but
/// where triangles are much smaller than the sample spacing.
const CANDIDATE_SAMPLES: usize = 8;

/// Options of [`surface_coverage`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoverageConfig {
    /// A surface point within this distance of a scanned point is covered (mm). Choose it
    /// from the scan's sampling: [`COVERAGE_SPACINGS`] times the sample spacing.
    pub distance_mm: f64,
    /// Area of the true surface each sample stands for (mm²). Default
    /// [`DEFAULT_TRUTH_SAMPLE_AREA_MM2`].
    pub sample_area_mm2: f64,
}

impl CoverageConfig {
    /// The coverage distance for a scan sampled `spacing_mm` apart:
    /// [`COVERAGE_SPACINGS`] `× spacing_mm`, default sample area.
    pub fn for_spacing(spacing_mm: f64) -> Self {
        Self {
            distance_mm: COVERAGE_SPACINGS * spacing_mm,
            sample_area_mm2: DEFAULT_TRUTH_SAMPLE_AREA_MM2,
        }
    }

    fn validate(&self) -> Result<(), MetrologyError> {
        for (parameter, v) in [
            ("distance_mm", self.distance_mm),
            ("sample_area_mm2", self.sample_area_mm2),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(MetrologyError::InvalidParameter {
                    parameter,
                    reason: format!("{v} is not a positive number"),
                });
            }
        }
        Ok(())
    }
}

/// What [`surface_coverage`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceCoverage {
    /// The coverage distance used (mm).
    pub distance_mm: f64,
    /// Area of the true surface (mm²).
    pub area_mm2: f64,
    /// Samples of the true surface.
    pub samples: usize,
    /// Samples within `distance_mm` of a scanned point.
    pub covered_samples: usize,
    /// `covered_samples / samples`: the fraction of the true surface's area covered.
    pub covered_fraction: f64,
    /// The area not covered (mm²): `(1 − covered_fraction) · area_mm2`.
    pub uncovered_area_mm2: f64,
}

/// Distances of scanned points to the true surface ([`distance_to_surface`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceDistance {
    /// Points measured (the finite points of the cloud).
    pub points: usize,
    /// Root mean square distance over all points (mm).
    pub rms_mm: f64,
    /// Mean signed distance (mm): positive on the side the triangles' winding normal points
    /// to (outside, for a mesh wound counter-clockwise seen from outside).
    pub mean_signed_mm: f64,
    /// Largest distance (mm).
    pub max_mm: f64,
    /// Points farther than `select_mm` from the surface: stray points.
    pub outliers: usize,
    /// RMS over the points within `select_mm` (mm): the surface error without stray points.
    pub rms_selected_mm: f64,
    /// The selection distance (mm).
    pub select_mm: f64,
}

/// Points spread evenly over the triangles of `mesh`, one per `area` mm² (a low-discrepancy
/// pattern in each triangle, the fractional carry passed on so the total is the area's), each
/// with the index of its triangle.
fn samples_with_triangles(mesh: &TriangleMesh, area: f64) -> (Vec<Point3<f64>>, Vec<u32>, f64) {
    // Fractional part of the golden ratio: the second coordinate of the pattern.
    const GOLDEN: f64 = 0.618_033_988_749_894_8;
    let mut pts = Vec::new();
    let mut ids = Vec::new();
    let mut carry = 0.0;
    let mut total = 0.0;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|i| mesh.vertices[i as usize]);
        let a_t = (b - a).cross(&(c - a)).norm() * 0.5;
        total += a_t;
        carry += a_t / area;
        let k = carry.floor().max(0.0) as usize;
        carry -= k as f64;
        for j in 0..k {
            let r1 = ((j as f64 + 0.5) / k as f64).sqrt();
            let r2 = (j as f64 * GOLDEN + 0.5).fract();
            pts.push(a + (b - a) * (r1 * (1.0 - r2)) + (c - a) * (r1 * r2));
            ids.push(t as u32);
        }
    }
    (pts, ids, total)
}

fn check_mesh(mesh: &TriangleMesh) -> Result<(), MetrologyError> {
    let n = mesh.vertices.len();
    if mesh.triangles.is_empty() {
        return Err(MetrologyError::InvalidParameter {
            parameter: "truth mesh",
            reason: "it has no triangle".to_owned(),
        });
    }
    if let Some(k) = mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(MetrologyError::InvalidParameter {
            parameter: "truth mesh",
            reason: format!("triangle {k} has a vertex index out of range ({n} vertices)"),
        });
    }
    Ok(())
}

/// The fraction of the surface of `truth` (mm) within `cfg.distance_mm` of a point of `cloud`
/// (mm, same frame), over samples spread evenly over its area.
///
/// # Errors
/// [`MetrologyError::InvalidParameter`] for a distance or sample area that is not positive, a
/// mesh without triangles or with an index out of range, or a mesh so small that no sample
/// falls on it; [`MetrologyError::Cloud`] when the cloud cannot be indexed.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{PointCloud, TriangleMesh};
/// use sl_metrology::{CoverageConfig, surface_coverage};
/// // A 10 mm square, scanned on its left half only (points 0.25 mm apart).
/// let p = |x: f64, y: f64| Point3::new(x, y, 0.0);
/// let square = TriangleMesh {
///     vertices: vec![p(0.0, 0.0), p(10.0, 0.0), p(10.0, 10.0), p(0.0, 10.0)],
///     triangles: vec![[0, 1, 2], [0, 2, 3]],
/// };
/// let pts = (0..=20).flat_map(|i| (0..=40).map(move |j| p(i as f64 * 0.25, j as f64 * 0.25)));
/// let c = surface_coverage(&square, &PointCloud::from_positions(pts.collect()), &CoverageConfig::for_spacing(0.25))?;
/// // Covered: x ≤ 5 + 0.5 mm, 55 % of the square.
/// assert!((c.covered_fraction - 0.55).abs() < 0.01, "{c:?}");
/// # Ok::<(), sl_metrology::MetrologyError>(())
/// ```
pub fn surface_coverage(
    truth: &TriangleMesh,
    cloud: &PointCloud,
    cfg: &CoverageConfig,
) -> Result<SurfaceCoverage, MetrologyError> {
    cfg.validate()?;
    check_mesh(truth)?;
    let (samples, _, area) = samples_with_triangles(truth, cfg.sample_area_mm2);
    if samples.is_empty() {
        return Err(MetrologyError::InvalidParameter {
            parameter: "sample_area_mm2",
            reason: format!(
                "{} mm² per sample leaves no sample on a surface of {area} mm²",
                cfg.sample_area_mm2
            ),
        });
    }
    let index = KdIndex::new(cloud.positions())?;
    let d2 = cfg.distance_mm * cfg.distance_mm;
    let covered = samples
        .iter()
        .filter(|s| index.nearest_within(s, d2).is_some())
        .count();
    let fraction = covered as f64 / samples.len() as f64;
    Ok(SurfaceCoverage {
        distance_mm: cfg.distance_mm,
        area_mm2: area,
        samples: samples.len(),
        covered_samples: covered,
        covered_fraction: fraction,
        uncovered_area_mm2: (1.0 - fraction) * area,
    })
}

/// The point of triangle `abc` closest to `p` (Ericson, *Real-Time Collision Detection*,
/// 5.1.5: the Voronoi regions of the vertices, edges and face).
fn closest_on_triangle(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> Point3<f64> {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // A degenerate triangle: its vertices are the candidates.
        return [a, b, c]
            .into_iter()
            .min_by(|u, v| (p - *u).norm_squared().total_cmp(&(p - *v).norm_squared()))
            .copied()
            .unwrap_or(*a);
    }
    let v = vb / denom;
    let w = vc / denom;
    a + ab * v + ac * w
}

/// The distance of every finite point of `cloud` to the surface of `truth` (both mm, same
/// frame): the exact distance to the closest of the triangles under the point's nearest
/// surface samples (one per `sample_area_mm2`), signed by the triangle's winding normal. Points
/// farther than `select_mm` count as outliers and are left out of
/// [`SurfaceDistance::rms_selected_mm`].
///
/// # Errors
/// As [`surface_coverage`]; [`MetrologyError::InvalidParameter`] for a non-positive
/// `select_mm` or a cloud without a finite point.
pub fn distance_to_surface(
    cloud: &PointCloud,
    truth: &TriangleMesh,
    sample_area_mm2: f64,
    select_mm: f64,
) -> Result<SurfaceDistance, MetrologyError> {
    CoverageConfig {
        distance_mm: select_mm,
        sample_area_mm2,
    }
    .validate()
    .map_err(|e| match e {
        MetrologyError::InvalidParameter {
            parameter: "distance_mm",
            reason,
        } => MetrologyError::InvalidParameter {
            parameter: "select_mm",
            reason,
        },
        other => other,
    })?;
    check_mesh(truth)?;
    let (samples, tri_of, _) = samples_with_triangles(truth, sample_area_mm2);
    if samples.is_empty() {
        return Err(MetrologyError::InvalidParameter {
            parameter: "sample_area_mm2",
            reason: "no sample falls on the truth mesh".to_owned(),
        });
    }
    let index = KdIndex::new(&samples)?;
    let mut found = Vec::with_capacity(CANDIDATE_SAMPLES);
    let (mut n, mut sum2, mut sum, mut max) = (0usize, 0.0, 0.0, 0.0f64);
    let (mut outliers, mut sel_n, mut sel2) = (0usize, 0usize, 0.0);
    for p in cloud.positions() {
        if !p.coords.iter().all(|v| v.is_finite()) {
            continue;
        }
        index.knn_into(p, CANDIDATE_SAMPLES, &mut found);
        let mut best: Option<(f64, f64)> = None; // (distance², signed distance)
        let mut seen = [u32::MAX; CANDIDATE_SAMPLES];
        for (k, nb) in found.iter().enumerate() {
            let t = tri_of[nb.index];
            if seen[..k].contains(&t) {
                continue;
            }
            seen[k] = t;
            let [a, b, c] = truth.triangles[t as usize].map(|i| truth.vertices[i as usize]);
            let q = closest_on_triangle(p, &a, &b, &c);
            let d2 = (p - q).norm_squared();
            if best.is_none_or(|(b2, _)| d2 < b2) {
                let normal: Vector3<f64> = (b - a).cross(&(c - a));
                let sign = if normal.dot(&(p - q)) < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                best = Some((d2, sign * d2.sqrt()));
            }
        }
        let Some((d2, signed)) = best else { continue };
        n += 1;
        sum2 += d2;
        sum += signed;
        max = max.max(d2.sqrt());
        if d2 > select_mm * select_mm {
            outliers += 1;
        } else {
            sel_n += 1;
            sel2 += d2;
        }
    }
    if n == 0 {
        return Err(MetrologyError::InvalidParameter {
            parameter: "cloud",
            reason: "it has no finite point to measure".to_owned(),
        });
    }
    let rms_selected = if sel_n > 0 {
        (sel2 / sel_n as f64).sqrt()
    } else {
        f64::NAN
    };
    Ok(SurfaceDistance {
        points: n,
        rms_mm: (sum2 / n as f64).sqrt(),
        mean_signed_mm: sum / n as f64,
        max_mm: max,
        outliers,
        rms_selected_mm: rms_selected,
        select_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed cube of side `s` from the origin, wound counter-clockwise from outside.
    fn cube(s: f64) -> TriangleMesh {
        let v = (0..8)
            .map(|i| {
                Point3::new(
                    f64::from(i & 1) * s,
                    f64::from((i >> 1) & 1) * s,
                    f64::from((i >> 2) & 1) * s,
                )
            })
            .collect();
        let quads = [
            [0, 2, 3, 1], // z = 0, normal -z
            [4, 5, 7, 6], // z = s, normal +z
            [0, 1, 5, 4], // y = 0, normal -y
            [2, 6, 7, 3], // y = s, normal +y
            [0, 4, 6, 2], // x = 0, normal -x
            [1, 3, 7, 5], // x = s, normal +x
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriangleMesh {
            vertices: v,
            triangles,
        }
    }

    /// A grid of points `h` mm apart over the faces of the cube of side `s` whose normal is
    /// not `-z` (the cube scanned on a turntable: five faces of six), each pushed `offset` mm
    /// outward.
    fn five_faces(s: f64, h: f64, offset: f64) -> PointCloud {
        let n = (s / h).round() as usize;
        let mut pts = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let (u, v) = (i as f64 * h, j as f64 * h);
                pts.push(Point3::new(u, v, s + offset));
                pts.push(Point3::new(u, -offset, v));
                pts.push(Point3::new(u, s + offset, v));
                pts.push(Point3::new(-offset, u, v));
                pts.push(Point3::new(s + offset, u, v));
            }
        }
        PointCloud::from_positions(pts)
    }

    /// Five faces of six scanned: 5/6 covered, up to the band of width `d` along the bottom
    /// edges that the side faces' points reach on the bottom face (4 edges × s × d of the
    /// 6 s² area, plus the sample spacing).
    #[test]
    fn five_faces_of_a_cube_cover_five_sixths() {
        let s = 20.0;
        let cfg = CoverageConfig::for_spacing(0.25);
        let c = surface_coverage(&cube(s), &five_faces(s, 0.25, 0.0), &cfg).unwrap();
        assert!((c.area_mm2 - 6.0 * s * s).abs() < 1e-9, "{c:?}");
        let band = 4.0 * s * cfg.distance_mm / (6.0 * s * s);
        assert!(c.covered_fraction >= 5.0 / 6.0 - 1e-3, "{c:?}");
        assert!(c.covered_fraction <= 5.0 / 6.0 + band + 1e-3, "{c:?}");
        assert!((c.uncovered_area_mm2 - (1.0 - c.covered_fraction) * c.area_mm2).abs() < 1e-9);
        // All six faces: everything covered.
        let mut all = five_faces(s, 0.25, 0.0).positions().to_vec();
        all.extend((0..=80).flat_map(|i| {
            (0..=80).map(move |j| Point3::new(i as f64 * 0.25, j as f64 * 0.25, 0.0))
        }));
        let c = surface_coverage(&cube(s), &PointCloud::from_positions(all), &cfg).unwrap();
        assert_eq!(c.covered_samples, c.samples);
    }

    /// Points a known distance outside the faces measure that distance, with a positive
    /// sign (the cube is wound outward); a far point is an outlier, left out of the selected
    /// RMS.
    #[test]
    fn distances_to_a_cube() {
        let s = 20.0;
        let off = 0.3;
        let cloud = five_faces(s, 1.0, off);
        let d = distance_to_surface(&cloud, &cube(s), 0.04, 2.0).unwrap();
        assert_eq!(d.points, cloud.len());
        // Every point lies over its face, 0.3 mm out: its distance is 0.3 mm exactly.
        assert!((d.rms_mm - off).abs() < 1e-9, "{d:?}");
        assert!(
            (d.mean_signed_mm - off).abs() < 1e-9 && (d.max_mm - off).abs() < 1e-9,
            "{d:?}"
        );
        assert_eq!(d.outliers, 0);
        let mut pts = cloud.positions().to_vec();
        pts.push(Point3::new(s / 2.0, s / 2.0, s / 2.0)); // the centre: 10 mm inside
        let d = distance_to_surface(&PointCloud::from_positions(pts), &cube(s), 0.04, 2.0).unwrap();
        assert_eq!(d.outliers, 1);
        assert!(
            (d.max_mm - 10.0).abs() < 1e-9 && d.mean_signed_mm < 0.3,
            "{d:?}"
        );
        assert!((d.rms_selected_mm - off).abs() < 1e-9, "{d:?}");
    }

    #[test]
    fn closest_point_regions() {
        let (a, b, c) = (
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        );
        let q = |x: f64, y: f64, z: f64| closest_on_triangle(&Point3::new(x, y, z), &a, &b, &c);
        let near = |u: Point3<f64>, v: Point3<f64>| (u - v).norm() < 1e-12;
        assert!(near(q(0.2, 0.2, 5.0), Point3::new(0.2, 0.2, 0.0)));
        assert_eq!(q(-1.0, -1.0, 0.0), a);
        assert_eq!(q(2.0, -0.5, 0.0), b);
        assert_eq!(q(-0.5, 2.0, 0.0), c);
        assert!(near(q(0.5, -1.0, 1.0), Point3::new(0.5, 0.0, 0.0)));
        assert!(near(q(-1.0, 0.3, 0.0), Point3::new(0.0, 0.3, 0.0)));
        assert!(near(q(1.0, 1.0, 0.0), Point3::new(0.5, 0.5, 0.0)));
    }

    #[test]
    fn bad_input_is_named() {
        let cloud = five_faces(10.0, 1.0, 0.0);
        let e = surface_coverage(&cube(10.0), &cloud, &CoverageConfig::for_spacing(0.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("distance_mm"), "{e}");
        let e = surface_coverage(
            &TriangleMesh::default(),
            &cloud,
            &CoverageConfig::for_spacing(1.0),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("truth mesh"), "{e}");
        let e = distance_to_surface(&cloud, &cube(10.0), 0.04, -1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("select_mm"), "{e}");
        let e = distance_to_surface(&PointCloud::default(), &cube(10.0), 0.04, 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cloud"), "{e}");
    }
}
