//! Clouds no tool can use whatever their units: no finite point, too few points, every point at
//! one place. Told apart from clouds in the wrong units, so that a message names the real cause.

use std::path::Path;

use nalgebra::Point3;

use crate::cloud::is_finite;
use crate::{CloudError, PointCloud};

/// Fewest finite points any use of a cloud needs: one point spans nothing.
const MIN_SPANNING_POINTS: usize = 2;

/// Why a cloud cannot serve, whatever its units (see [`degeneracy`]). Its message reads after
/// the file's name: `cloud.ply: none of its 500 points is finite`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Degeneracy {
    /// No point has three finite coordinates, or there is no point at all.
    #[error("{}", no_finite_point(*points))]
    NoFinitePoint {
        /// Points in the cloud, finite or not.
        points: usize,
    },
    /// Fewer finite points than the use needs.
    #[error("has {}; {purpose} needs at least {needed}", counted(*finite, *points, "point"))]
    TooFewPoints {
        /// Finite points.
        finite: usize,
        /// Points in the cloud, finite or not.
        points: usize,
        /// Fewest finite points the use needs.
        needed: usize,
        /// The use, as the message says it: `"a mesh"`, `"a registration"`.
        purpose: &'static str,
    },
    /// Every finite point is at the same position: the cloud spans nothing (a zero box).
    #[error(
        "all {} are at the same place ({}, {}, {})",
        counted(*finite, *points, "point"),
        at.x,
        at.y,
        at.z
    )]
    OnePlace {
        /// Finite points.
        finite: usize,
        /// Points in the cloud, finite or not.
        points: usize,
        /// Where they all are.
        at: Point3<f64>,
    },
}

fn no_finite_point(points: usize) -> String {
    match points {
        0 => "has no point".to_owned(),
        1 => "its one point is not finite".to_owned(),
        n => format!("none of its {n} points is finite"),
    }
}

/// `"N things"`, or `"N finite things (of M)"` when some of the `total` are not finite.
fn counted(finite: usize, total: usize, thing: &str) -> String {
    let s = if finite == 1 { "" } else { "s" };
    if finite == total {
        format!("{finite} {thing}{s}")
    } else {
        format!("{finite} finite {thing}{s} (of {total})")
    }
}

/// Why `cloud` cannot serve `purpose` whatever its units, or `None` when it can: it has no
/// finite point, fewer finite points than `min_points` (at least 2: one point spans nothing),
/// or all of them at one place. Checked in that order, so the first cause found is the one a
/// user must mend first. Units are another question ([`check_cloud`] asks it after this one).
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{Degeneracy, PointCloud, degeneracy};
/// let same = PointCloud::from_positions(vec![Point3::new(1.0, 2.0, 3.0); 500]);
/// let d = degeneracy(&same, 16, "a mesh").unwrap();
/// assert_eq!(d.to_string(), "all 500 points are at the same place (1, 2, 3)");
/// let one = PointCloud::from_positions(vec![Point3::origin()]);
/// assert_eq!(
///     degeneracy(&one, 16, "a mesh").unwrap().to_string(),
///     "has 1 point; a mesh needs at least 16"
/// );
/// let nan = PointCloud::from_positions(vec![Point3::new(f64::NAN, 0.0, 0.0); 3]);
/// assert!(matches!(degeneracy(&nan, 16, "a mesh"), Some(Degeneracy::NoFinitePoint { points: 3 })));
/// ```
pub fn degeneracy(
    cloud: &PointCloud,
    min_points: usize,
    purpose: &'static str,
) -> Option<Degeneracy> {
    let points = cloud.len();
    let mut finite = cloud.positions().iter().filter(|p| is_finite(p));
    let Some(first) = finite.next().copied() else {
        return Some(Degeneracy::NoFinitePoint { points });
    };
    let (count, one_place) =
        finite.fold((1usize, true), |(n, same), p| (n + 1, same && *p == first));
    let needed = min_points.max(MIN_SPANNING_POINTS);
    if count < needed {
        return Some(Degeneracy::TooFewPoints {
            finite: count,
            points,
            needed,
            purpose,
        });
    }
    one_place.then_some(Degeneracy::OnePlace {
        finite: count,
        points,
        at: first,
    })
}

/// What a tool needs of a cloud it reads (see [`check_cloud`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloudNeeds {
    /// The use, as messages say it: `"a mesh"`, `"a registration"`.
    pub purpose: &'static str,
    /// Fewest finite points (at least 2 are always needed).
    pub min_points: usize,
    /// Smallest diagonal of the box of the finite points, in mm: a cloud spanning less is
    /// taken for one in metres ([`CloudError::NotMillimetres`]). `None`: units not checked.
    pub min_extent_mm: Option<f64>,
}

impl Default for CloudNeeds {
    /// Two points spanning at least 1 mm: nothing this workspace scans is smaller.
    fn default() -> Self {
        Self {
            purpose: "a cloud with an extent",
            min_points: MIN_SPANNING_POINTS,
            min_extent_mm: Some(1.0),
        }
    }
}

/// Refuses a cloud (read from `path`, which the error names) that cannot serve
/// `needs.purpose`: first for what it is whatever its units ([`degeneracy`]:
/// [`CloudError::Degenerate`]), then for a span too small for millimetres
/// ([`CloudError::NotMillimetres`]: any object worth scanning spans tens of millimetres, while
/// the same object in metres spans a fraction of one). So a cloud of 500 copies of one point is
/// said to be that, not said to be in metres.
///
/// ```
/// use std::path::Path;
/// use nalgebra::Point3;
/// use sl_cloud::{CloudNeeds, PointCloud, check_cloud};
/// let needs = CloudNeeds { purpose: "a mesh", min_points: 16, min_extent_mm: Some(1.0) };
/// let metres: Vec<_> = (0..20).map(|i| Point3::new(0.005 * f64::from(i), 0.0, 0.3)).collect();
/// let err = check_cloud(&PointCloud::from_positions(metres), Path::new("m.ply"), &needs);
/// assert!(err.unwrap_err().to_string().contains("probably metres"));
/// let same = PointCloud::from_positions(vec![Point3::origin(); 20]);
/// let err = check_cloud(&same, Path::new("s.ply"), &needs).unwrap_err().to_string();
/// assert_eq!(err, "s.ply: all 20 points are at the same place (0, 0, 0)");
/// ```
///
/// # Errors
/// [`CloudError::Degenerate`] or [`CloudError::NotMillimetres`] naming the file.
pub fn check_cloud(cloud: &PointCloud, path: &Path, needs: &CloudNeeds) -> Result<(), CloudError> {
    if let Some(reason) = degeneracy(cloud, needs.min_points, needs.purpose) {
        return Err(CloudError::Degenerate {
            file: path.display().to_string(),
            reason,
        });
    }
    if let Some(limit) = needs.min_extent_mm {
        let extent = cloud.bounding_box().map_or(0.0, |b| b.extent().norm());
        if extent < limit {
            return Err(CloudError::NotMillimetres {
                file: path.display().to_string(),
                extent,
                limit,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud(points: Vec<Point3<f64>>) -> PointCloud {
        PointCloud::from_positions(points)
    }

    #[test]
    fn each_cause_is_told_with_its_counts() {
        let nan = Point3::new(f64::NAN, 1.0, 1.0);
        let inf = Point3::new(0.0, f64::NEG_INFINITY, 1.0);
        let cases: [(Vec<Point3<f64>>, &str); 7] = [
            (vec![], "has no point"),
            (vec![nan], "its one point is not finite"),
            (vec![nan, inf, nan], "none of its 3 points is finite"),
            (
                vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0)],
                "has 2 points; a mesh needs at least 16",
            ),
            (
                vec![nan, Point3::origin()],
                "has 1 finite point (of 2); a mesh needs at least 16",
            ),
            (
                vec![Point3::new(-1.5, 0.0, 2.0); 20],
                "all 20 points are at the same place (-1.5, 0, 2)",
            ),
            (
                [vec![Point3::new(0.25, 0.0, 0.0); 20], vec![inf; 3]].concat(),
                "all 20 finite points (of 23) are at the same place (0.25, 0, 0)",
            ),
        ];
        for (points, expected) in cases {
            let d = degeneracy(&cloud(points), 16, "a mesh").map(|d| d.to_string());
            assert_eq!(d.as_deref(), Some(expected));
        }
        // One point is never enough, whatever the use asks.
        let one = degeneracy(&cloud(vec![Point3::origin()]), 0, "x").unwrap();
        assert_eq!(one.to_string(), "has 1 point; x needs at least 2");
        // Two places, however close, span something: a question of units, not of degeneracy.
        let two = cloud(vec![Point3::origin(), Point3::new(0.0, 0.0, 1e-12)]);
        assert_eq!(degeneracy(&two, 2, "x"), None);
    }

    #[test]
    fn units_are_checked_only_on_a_cloud_that_spans_something() {
        let path = Path::new("c.ply");
        let needs = CloudNeeds::default();
        let same = cloud(vec![Point3::origin(); 5]);
        let err = check_cloud(&same, path, &needs).unwrap_err();
        assert!(matches!(err, CloudError::Degenerate { .. }), "{err}");
        let small = cloud(vec![Point3::origin(), Point3::new(0.1, 0.05, 0.0)]);
        let err = check_cloud(&small, path, &needs).unwrap_err();
        assert!(matches!(err, CloudError::NotMillimetres { .. }), "{err}");
        let unchecked = CloudNeeds {
            min_extent_mm: None,
            ..needs
        };
        check_cloud(&small, path, &unchecked).unwrap();
        let mm = cloud(vec![Point3::origin(), Point3::new(100.0, 50.0, 0.0)]);
        check_cloud(&mm, path, &needs).unwrap();
    }
}
