//! The point cloud container and its geometric bookkeeping.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::CloudError;

/// An axis-aligned box, `min <= max` component-wise (bounds inclusive).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Corner with the smallest coordinates.
    pub min: Point3<f64>,
    /// Corner with the largest coordinates.
    pub max: Point3<f64>,
}

impl Aabb {
    /// The box spanned by two corners given in any order.
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_cloud::Aabb;
    /// let b = Aabb::new(Point3::new(1.0, 0.0, 5.0), Point3::new(0.0, 2.0, 3.0));
    /// assert_eq!(b.min, Point3::new(0.0, 0.0, 3.0));
    /// assert!(b.contains(&Point3::new(0.5, 2.0, 4.0)));
    /// ```
    pub fn new(a: Point3<f64>, b: Point3<f64>) -> Self {
        Self {
            min: a.inf(&b),
            max: a.sup(&b),
        }
    }

    /// Whether `p` lies inside or on the boundary. Always false for a non-finite point.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        (0..3).all(|i| p[i] >= self.min[i] && p[i] <= self.max[i])
    }

    /// Edge lengths `max - min`.
    pub fn extent(&self) -> Vector3<f64> {
        self.max - self.min
    }

    /// Centre of the box.
    pub fn center(&self) -> Point3<f64> {
        nalgebra::center(&self.min, &self.max)
    }
}

/// How [`PointCloud::extend`] treats an optional attribute carried by only one of the two clouds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MergePolicy {
    /// Fail with [`CloudError::AttributeMismatch`] naming the attribute (the default: losing
    /// normals silently is rarely what one wants).
    #[default]
    Strict,
    /// Drop the attribute from the result.
    DropMismatched,
}

/// A set of 3-D points with optional per-point normals, colours and quality.
///
/// Invariant: every attribute present has exactly [`len`](Self::len) entries; the constructors
/// and setters check it, so algorithms can index attributes by point index.
///
/// Units are those of the positions (the scanner works in millimetres, the Stanford bunny is in
/// metres); the cloud does not know or care.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    positions: Vec<Point3<f64>>,
    normals: Option<Vec<Vector3<f64>>>,
    colors: Option<Vec<[u8; 3]>>,
    quality: Option<Vec<f32>>,
}

fn check_len<T>(
    attribute: &'static str,
    expected: usize,
    v: &Option<Vec<T>>,
) -> Result<(), CloudError> {
    match v {
        Some(v) if v.len() != expected => Err(CloudError::AttributeLength {
            attribute,
            expected,
            found: v.len(),
        }),
        _ => Ok(()),
    }
}

impl PointCloud {
    /// An empty cloud without attributes.
    pub fn new() -> Self {
        Self::default()
    }

    /// A cloud of bare positions.
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_cloud::PointCloud;
    /// let c = PointCloud::from_positions(vec![Point3::origin(), Point3::new(1.0, 2.0, 3.0)]);
    /// assert_eq!(c.len(), 2);
    /// assert!(c.normals().is_none());
    /// ```
    pub fn from_positions(positions: Vec<Point3<f64>>) -> Self {
        Self {
            positions,
            normals: None,
            colors: None,
            quality: None,
        }
    }

    /// Builds a cloud from all its parts, checking that every attribute has one entry per point.
    pub fn from_parts(
        positions: Vec<Point3<f64>>,
        normals: Option<Vec<Vector3<f64>>>,
        colors: Option<Vec<[u8; 3]>>,
        quality: Option<Vec<f32>>,
    ) -> Result<Self, CloudError> {
        let n = positions.len();
        check_len("normals", n, &normals)?;
        check_len("colors", n, &colors)?;
        check_len("quality", n, &quality)?;
        Ok(Self {
            positions,
            normals,
            colors,
            quality,
        })
    }

    /// Splits the cloud into `(positions, normals, colors, quality)`.
    #[allow(clippy::type_complexity)]
    pub fn into_parts(
        self,
    ) -> (
        Vec<Point3<f64>>,
        Option<Vec<Vector3<f64>>>,
        Option<Vec<[u8; 3]>>,
        Option<Vec<f32>>,
    ) {
        (self.positions, self.normals, self.colors, self.quality)
    }

    /// Attaches normals (builder style); fails if their number differs from the point count.
    pub fn with_normals(mut self, normals: Vec<Vector3<f64>>) -> Result<Self, CloudError> {
        self.set_normals(Some(normals))?;
        Ok(self)
    }

    /// Attaches colours (builder style); fails if their number differs from the point count.
    pub fn with_colors(mut self, colors: Vec<[u8; 3]>) -> Result<Self, CloudError> {
        self.set_colors(Some(colors))?;
        Ok(self)
    }

    /// Attaches quality values (builder style); fails if their number differs from the point count.
    pub fn with_quality(mut self, quality: Vec<f32>) -> Result<Self, CloudError> {
        self.set_quality(Some(quality))?;
        Ok(self)
    }

    /// Replaces (or removes, with `None`) the normals.
    pub fn set_normals(&mut self, normals: Option<Vec<Vector3<f64>>>) -> Result<(), CloudError> {
        check_len("normals", self.len(), &normals)?;
        self.normals = normals;
        Ok(())
    }

    /// Replaces (or removes, with `None`) the colours.
    pub fn set_colors(&mut self, colors: Option<Vec<[u8; 3]>>) -> Result<(), CloudError> {
        check_len("colors", self.len(), &colors)?;
        self.colors = colors;
        Ok(())
    }

    /// Replaces (or removes, with `None`) the quality values.
    pub fn set_quality(&mut self, quality: Option<Vec<f32>>) -> Result<(), CloudError> {
        check_len("quality", self.len(), &quality)?;
        self.quality = quality;
        Ok(())
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether the cloud has no point.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The positions.
    pub fn positions(&self) -> &[Point3<f64>] {
        &self.positions
    }

    /// The positions, mutable in place (the count cannot change).
    pub fn positions_mut(&mut self) -> &mut [Point3<f64>] {
        &mut self.positions
    }

    /// The normals, if any (unit vectors, or zero where none could be estimated).
    pub fn normals(&self) -> Option<&[Vector3<f64>]> {
        self.normals.as_deref()
    }

    /// The normals, mutable in place, if any.
    pub fn normals_mut(&mut self) -> Option<&mut [Vector3<f64>]> {
        self.normals.as_deref_mut()
    }

    /// The colours (RGB, 8 bits per channel), if any.
    pub fn colors(&self) -> Option<&[[u8; 3]]> {
        self.colors.as_deref()
    }

    /// The colours, mutable in place, if any.
    pub fn colors_mut(&mut self) -> Option<&mut [[u8; 3]]> {
        self.colors.as_deref_mut()
    }

    /// The per-point quality (confidence, modulation, scalar field...), if any.
    pub fn quality(&self) -> Option<&[f32]> {
        self.quality.as_deref()
    }

    /// The quality values, mutable in place, if any.
    pub fn quality_mut(&mut self) -> Option<&mut [f32]> {
        self.quality.as_deref_mut()
    }

    /// Applies a rigid motion in place: positions are mapped by `pose`, normals rotated by it.
    ///
    /// ```
    /// use nalgebra::{Isometry3, Point3, Vector3};
    /// use sl_cloud::PointCloud;
    /// let mut c = PointCloud::from_positions(vec![Point3::new(1.0, 0.0, 0.0)])
    ///     .with_normals(vec![Vector3::x()])
    ///     .unwrap();
    /// // 90 degrees about z, then 10 along z.
    /// let pose = Isometry3::new(Vector3::new(0.0, 0.0, 10.0), Vector3::z() * std::f64::consts::FRAC_PI_2);
    /// c.transform(&pose);
    /// assert!((c.positions()[0] - Point3::new(0.0, 1.0, 10.0)).norm() < 1e-12);
    /// assert!((c.normals().unwrap()[0] - Vector3::y()).norm() < 1e-12);
    /// ```
    pub fn transform(&mut self, pose: &Isometry3<f64>) {
        let rot = pose.rotation.to_rotation_matrix();
        let t = pose.translation.vector;
        for p in &mut self.positions {
            *p = rot * *p + t;
        }
        if let Some(normals) = &mut self.normals {
            for n in normals {
                *n = rot * *n;
            }
        }
    }

    /// A copy moved by `pose` (see [`transform`](Self::transform)).
    pub fn transformed(&self, pose: &Isometry3<f64>) -> Self {
        let mut c = self.clone();
        c.transform(pose);
        c
    }

    /// Appends the points of `other`.
    ///
    /// An attribute present in both clouds is concatenated. An attribute present in only one is
    /// an error under [`MergePolicy::Strict`] and dropped under [`MergePolicy::DropMismatched`].
    /// An empty cloud constrains nothing: extending an empty cloud adopts `other`'s attributes,
    /// and extending by an empty cloud changes nothing. On error `self` is left unchanged.
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_cloud::{MergePolicy, PointCloud};
    /// let a = PointCloud::from_positions(vec![Point3::origin()]).with_quality(vec![1.0]).unwrap();
    /// let b = PointCloud::from_positions(vec![Point3::new(1.0, 1.0, 1.0)]);
    /// let mut m = a.clone();
    /// assert!(m.extend(&b, MergePolicy::Strict).is_err());
    /// m.extend(&b, MergePolicy::DropMismatched).unwrap();
    /// assert_eq!(m.len(), 2);
    /// assert!(m.quality().is_none());
    /// ```
    pub fn extend(&mut self, other: &PointCloud, policy: MergePolicy) -> Result<(), CloudError> {
        if other.is_empty() {
            return Ok(());
        }
        if self.is_empty() {
            *self = other.clone();
            return Ok(());
        }
        if policy == MergePolicy::Strict {
            if self.normals.is_some() != other.normals.is_some() {
                return Err(CloudError::AttributeMismatch {
                    attribute: "normals",
                });
            }
            if self.colors.is_some() != other.colors.is_some() {
                return Err(CloudError::AttributeMismatch {
                    attribute: "colors",
                });
            }
            if self.quality.is_some() != other.quality.is_some() {
                return Err(CloudError::AttributeMismatch {
                    attribute: "quality",
                });
            }
        }
        fn merge<T: Clone>(a: &mut Option<Vec<T>>, b: &Option<Vec<T>>) {
            match (a.as_mut(), b) {
                (Some(a), Some(b)) => a.extend_from_slice(b),
                _ => *a = None,
            }
        }
        merge(&mut self.normals, &other.normals);
        merge(&mut self.colors, &other.colors);
        merge(&mut self.quality, &other.quality);
        self.positions.extend_from_slice(&other.positions);
        Ok(())
    }

    /// The points with the given indices, in that order (repeats allowed), with their attributes.
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_cloud::PointCloud;
    /// let c = PointCloud::from_positions((0..5).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect());
    /// let s = c.select(&[4, 1]).unwrap();
    /// assert_eq!(s.positions()[0].x, 4.0);
    /// assert!(c.select(&[5]).is_err());
    /// ```
    pub fn select(&self, indices: &[usize]) -> Result<PointCloud, CloudError> {
        let len = self.len();
        if let Some((position, &index)) = indices.iter().enumerate().find(|(_, i)| **i >= len) {
            return Err(CloudError::IndexOutOfRange {
                index,
                position,
                len,
            });
        }
        Ok(self.select_unchecked(indices))
    }

    /// `select` for indices known to be in range (crate-internal: callers built them).
    pub(crate) fn select_unchecked(&self, indices: &[usize]) -> PointCloud {
        fn pick<T: Copy>(v: &[T], idx: &[usize]) -> Vec<T> {
            idx.iter().filter_map(|&i| v.get(i).copied()).collect()
        }
        PointCloud {
            positions: pick(&self.positions, indices),
            normals: self.normals.as_deref().map(|v| pick(v, indices)),
            colors: self.colors.as_deref().map(|v| pick(v, indices)),
            quality: self.quality.as_deref().map(|v| pick(v, indices)),
        }
    }

    /// The points inside `bbox` (bounds inclusive), with their attributes.
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_cloud::{Aabb, PointCloud};
    /// let c = PointCloud::from_positions((0..10).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect());
    /// let inside = c.crop(&Aabb::new(Point3::new(2.0, -1.0, -1.0), Point3::new(4.0, 1.0, 1.0)));
    /// assert_eq!(inside.len(), 3);
    /// ```
    pub fn crop(&self, bbox: &Aabb) -> PointCloud {
        let idx: Vec<usize> = self
            .positions
            .iter()
            .enumerate()
            .filter(|(_, p)| bbox.contains(p))
            .map(|(i, _)| i)
            .collect();
        self.select_unchecked(&idx)
    }

    /// The smallest box holding every finite point; `None` if there is none.
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_cloud::PointCloud;
    /// let c = PointCloud::from_positions(vec![Point3::new(1.0, -2.0, 0.0), Point3::new(-1.0, 4.0, 2.0)]);
    /// let b = c.bounding_box().unwrap();
    /// assert_eq!(b.min, Point3::new(-1.0, -2.0, 0.0));
    /// assert_eq!(b.max, Point3::new(1.0, 4.0, 2.0));
    /// ```
    pub fn bounding_box(&self) -> Option<Aabb> {
        let mut it = self.positions.iter().filter(|p| is_finite(p));
        let first = *it.next()?;
        let (min, max) = it.fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        Some(Aabb { min, max })
    }

    /// The mean of the finite points; `None` if there is none.
    pub fn centroid(&self) -> Option<Point3<f64>> {
        let (sum, n) = self
            .positions
            .iter()
            .filter(|p| is_finite(p))
            .fold((Vector3::zeros(), 0usize), |(s, n), p| {
                (s + p.coords, n + 1)
            });
        (n > 0).then(|| Point3::from(sum / n as f64))
    }

    /// The cloud without the points that have a NaN or infinite coordinate.
    pub fn remove_non_finite(&self) -> PointCloud {
        let idx: Vec<usize> = (0..self.len())
            .filter(|&i| self.positions.get(i).is_some_and(is_finite))
            .collect();
        self.select_unchecked(&idx)
    }
}

/// Whether all three coordinates are finite.
pub(crate) fn is_finite(p: &Point3<f64>) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn sample() -> PointCloud {
        PointCloud::from_parts(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 2.0, 3.0),
                Point3::new(-1.0, 5.0, 1.0),
            ],
            Some(vec![Vector3::x(), Vector3::y(), Vector3::z()]),
            Some(vec![[1, 2, 3], [4, 5, 6], [7, 8, 9]]),
            Some(vec![0.5, 0.25, 1.0]),
        )
        .unwrap()
    }

    #[test]
    fn attribute_length_is_checked() {
        let e = PointCloud::from_parts(vec![Point3::origin()], None, Some(vec![]), None);
        assert!(matches!(
            e,
            Err(CloudError::AttributeLength {
                attribute: "colors",
                expected: 1,
                found: 0
            })
        ));
        let mut c = sample();
        assert!(c.set_quality(Some(vec![1.0])).is_err());
        assert_eq!(
            c.quality().unwrap().len(),
            3,
            "failed set leaves the cloud unchanged"
        );
    }

    #[test]
    fn transform_rotates_normals_and_moves_points() {
        let mut c = sample();
        let pose = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.3, -0.2, 0.9));
        let r = pose.rotation.to_rotation_matrix();
        c.transform(&pose);
        let s = sample();
        for i in 0..3 {
            // Ground truth from the definition p' = R p + t, n' = R n.
            let want = r * s.positions()[i] + pose.translation.vector;
            assert_relative_eq!(c.positions()[i], want, epsilon = 1e-12);
            assert_relative_eq!(
                c.normals().unwrap()[i],
                r * s.normals().unwrap()[i],
                epsilon = 1e-12
            );
            // Rigid motions keep unit normals unit.
            assert_relative_eq!(c.normals().unwrap()[i].norm(), 1.0, epsilon = 1e-12);
        }
        // Inverse brings it back.
        c.transform(&pose.inverse());
        for i in 0..3 {
            assert_relative_eq!(c.positions()[i], s.positions()[i], epsilon = 1e-12);
        }
    }

    #[test]
    fn extend_policies() {
        let a = sample();
        let b = PointCloud::from_positions(vec![Point3::new(9.0, 9.0, 9.0)]);
        let mut m = a.clone();
        let err = m.extend(&b, MergePolicy::Strict).unwrap_err();
        assert!(matches!(
            err,
            CloudError::AttributeMismatch {
                attribute: "normals"
            }
        ));
        assert_eq!(m, a, "failed merge leaves the cloud unchanged");
        m.extend(&b, MergePolicy::DropMismatched).unwrap();
        assert_eq!(m.len(), 4);
        assert!(m.normals().is_none() && m.colors().is_none() && m.quality().is_none());

        let mut m = a.clone();
        m.extend(&a, MergePolicy::Strict).unwrap();
        assert_eq!(m.len(), 6);
        assert_eq!(m.colors().unwrap()[5], [7, 8, 9]);

        let mut e = PointCloud::new();
        e.extend(&a, MergePolicy::Strict).unwrap();
        assert_eq!(e, a);
        let mut m = a.clone();
        m.extend(&PointCloud::new(), MergePolicy::Strict).unwrap();
        assert_eq!(m, a);
    }

    #[test]
    fn select_crop_bbox_centroid() {
        let c = sample();
        let s = c.select(&[2, 0, 2]).unwrap();
        assert_eq!(s.len(), 3);
        assert_eq!(s.colors().unwrap(), &[[7, 8, 9], [1, 2, 3], [7, 8, 9]]);
        assert!(matches!(
            c.select(&[0, 3]),
            Err(CloudError::IndexOutOfRange {
                index: 3,
                position: 1,
                len: 3
            })
        ));

        let b = c.bounding_box().unwrap();
        assert_eq!(b.min, Point3::new(-1.0, 0.0, 0.0));
        assert_eq!(b.max, Point3::new(1.0, 5.0, 3.0));
        // Centroid by hand: ((0+1-1)/3, (0+2+5)/3, (0+3+1)/3).
        assert_relative_eq!(
            c.centroid().unwrap(),
            Point3::new(0.0, 7.0 / 3.0, 4.0 / 3.0),
            epsilon = 1e-15
        );

        let cropped = c.crop(&Aabb::new(
            Point3::new(-0.5, -0.5, -0.5),
            Point3::new(1.0, 2.0, 3.0),
        ));
        assert_eq!(
            cropped.positions(),
            &[Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 2.0, 3.0)]
        );
        assert_eq!(cropped.quality().unwrap(), &[0.5, 0.25]);
    }

    #[test]
    fn non_finite_points_are_ignored_by_statistics() {
        let c = PointCloud::from_positions(vec![
            Point3::new(f64::NAN, 0.0, 0.0),
            Point3::new(2.0, 2.0, 2.0),
            Point3::new(0.0, f64::INFINITY, 0.0),
        ]);
        assert_eq!(c.bounding_box().unwrap().min, Point3::new(2.0, 2.0, 2.0));
        assert_eq!(c.centroid().unwrap(), Point3::new(2.0, 2.0, 2.0));
        assert_eq!(c.remove_non_finite().len(), 1);
        assert!(PointCloud::new().bounding_box().is_none());
        assert!(PointCloud::new().centroid().is_none());
        assert!(
            !Aabb::new(Point3::origin(), Point3::new(1.0, 1.0, 1.0)).contains(&Point3::new(
                f64::NAN,
                0.5,
                0.5
            ))
        );
    }
}
