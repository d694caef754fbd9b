//! Nearest-neighbour queries: a thin wrapper over kiddo's immutable k-d tree, so other crates
//! need not depend on kiddo.

use std::num::NonZero;

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::Point3;

use crate::CloudError;
use crate::cloud::is_finite;

/// Points per k-d tree leaf. kiddo's default; 16 to 64 measured within a few percent for
/// k = 16 queries, and 32 keeps the tree small.
const BUCKET: usize = 32;

type Tree = ImmutableKdTree<f64, u32, 3, BUCKET>;

/// One neighbour found by a [`KdIndex`] query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Index of the point in the slice the index was built from.
    pub index: usize,
    /// Squared Euclidean distance to the query (squared: that is what the tree computes, and
    /// taking roots is left to the callers that need them).
    pub distance_squared: f64,
}

/// A k-d tree over 3-D points for k-nearest and radius queries.
///
/// Built once (in about 0.1 s per million points), then queried from many threads (`&self`
/// queries are `Sync`). Points with a NaN or infinite coordinate are left out of the tree: they
/// are never returned and queries from them return nothing. Indices in results always refer to
/// the original slice.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::KdIndex;
/// let pts: Vec<_> = (0..10).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect();
/// let index = KdIndex::new(&pts)?;
/// let nn = index.knn(&Point3::new(3.2, 0.0, 0.0), 2);
/// assert_eq!((nn[0].index, nn[1].index), (3, 4));
/// assert_eq!(index.radius(&Point3::new(0.0, 0.0, 0.0), 2.0).len(), 3);
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub struct KdIndex {
    tree: Tree,
    /// Tree item -> original index, when non-finite points were left out.
    map: Option<Vec<u32>>,
    /// Number of points given (finite or not).
    len: usize,
}

impl std::fmt::Debug for KdIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KdIndex")
            .field("len", &self.len)
            .field("indexed", &self.tree.size())
            .finish()
    }
}

impl KdIndex {
    /// Builds the index. Fails only for more than `u32::MAX` points.
    pub fn new(points: &[Point3<f64>]) -> Result<Self, CloudError> {
        if points.len() > u32::MAX as usize {
            return Err(CloudError::TooManyPoints {
                len: points.len(),
                max: u32::MAX as usize,
            });
        }
        let all_finite = points.iter().all(is_finite);
        let (coords, map): (Vec<[f64; 3]>, Option<Vec<u32>>) = if all_finite {
            (points.iter().map(|p| [p.x, p.y, p.z]).collect(), None)
        } else {
            let (c, m) = points
                .iter()
                .enumerate()
                .filter(|(_, p)| is_finite(p))
                .map(|(i, p)| ([p.x, p.y, p.z], i as u32))
                .unzip();
            (c, Some(m))
        };
        Ok(Self {
            tree: Tree::new_from_slice(&coords),
            map,
            len: points.len(),
        })
    }

    /// Number of points the index was built from (finite or not).
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it was built from no point.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Number of points actually in the tree (the finite ones).
    pub fn indexed(&self) -> usize {
        self.tree.size()
    }

    #[inline]
    fn original(&self, item: u32) -> usize {
        match &self.map {
            None => item as usize,
            Some(m) => m.get(item as usize).map_or(usize::MAX, |&i| i as usize),
        }
    }

    /// The `k` points nearest to `query`, nearest first (fewer if the tree holds fewer). A query
    /// point that is in the tree is its own nearest neighbour, at distance 0.
    pub fn knn(&self, query: &Point3<f64>, k: usize) -> Vec<Neighbour> {
        let mut out = Vec::with_capacity(k);
        self.knn_into(query, k, &mut out);
        out
    }

    /// [`knn`](Self::knn) writing into `out` (cleared first), to reuse its allocation.
    pub fn knn_into(&self, query: &Point3<f64>, k: usize, out: &mut Vec<Neighbour>) {
        out.clear();
        let Some(k) = NonZero::new(k.min(self.tree.size())) else {
            return;
        };
        if !is_finite(query) {
            return;
        }
        let found = self
            .tree
            .nearest_n::<SquaredEuclidean>(&[query.x, query.y, query.z], k);
        out.extend(found.into_iter().map(|n| Neighbour {
            index: self.original(n.item),
            distance_squared: n.distance,
        }));
    }

    /// The nearest point to `query`, if the tree is not empty.
    pub fn nearest(&self, query: &Point3<f64>) -> Option<Neighbour> {
        self.knn(query, 1).into_iter().next()
    }

    /// All points within distance `radius` of `query` (boundary included), nearest first.
    pub fn radius(&self, query: &Point3<f64>, radius: f64) -> Vec<Neighbour> {
        let mut out = self.radius_unsorted(query, radius);
        out.sort_by(|a, b| {
            a.distance_squared
                .total_cmp(&b.distance_squared)
                .then(a.index.cmp(&b.index))
        });
        out
    }

    /// All points within distance `radius` of `query`, in no particular order (faster).
    pub fn radius_unsorted(&self, query: &Point3<f64>, radius: f64) -> Vec<Neighbour> {
        if !is_finite(query) || radius.is_nan() || radius < 0.0 || self.tree.size() == 0 {
            return Vec::new();
        }
        self.tree
            .within_unsorted::<SquaredEuclidean>(&[query.x, query.y, query.z], radius * radius)
            .into_iter()
            .map(|n| Neighbour {
                index: self.original(n.item),
                distance_squared: n.distance,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_points(n: usize, seed: u64) -> Vec<Point3<f64>> {
        let mut rng = Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                Point3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
            })
            .collect()
    }

    fn brute_knn(pts: &[Point3<f64>], q: &Point3<f64>, k: usize) -> Vec<(f64, usize)> {
        let mut all: Vec<(f64, usize)> = pts
            .iter()
            .enumerate()
            .filter(|(_, p)| is_finite(p))
            .map(|(i, p)| ((p - q).norm_squared(), i))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        all.truncate(k);
        all
    }

    #[test]
    fn knn_matches_brute_force() {
        let pts = random_points(3000, 7);
        let index = KdIndex::new(&pts).unwrap();
        for q in random_points(200, 8) {
            let got = index.knn(&q, 16);
            let want = brute_knn(&pts, &q, 16);
            assert_eq!(got.len(), 16);
            for (g, w) in got.iter().zip(&want) {
                // Random continuous points: ties have probability zero, so indices must agree and
                // distances are the same floating-point expression up to rounding.
                assert_eq!(g.index, w.1);
                approx::assert_relative_eq!(g.distance_squared, w.0, max_relative = 1e-12);
            }
        }
    }

    #[test]
    fn radius_matches_brute_force() {
        let pts = random_points(3000, 9);
        let index = KdIndex::new(&pts).unwrap();
        for q in random_points(100, 10) {
            let r = 0.2;
            let got: Vec<usize> = index.radius(&q, r).iter().map(|n| n.index).collect();
            let mut want: Vec<(f64, usize)> = pts
                .iter()
                .enumerate()
                .map(|(i, p)| ((p - q).norm_squared(), i))
                .filter(|(d, _)| *d <= r * r)
                .collect();
            want.sort_by(|a, b| a.0.total_cmp(&b.0));
            assert_eq!(got, want.iter().map(|w| w.1).collect::<Vec<_>>());
        }
    }

    #[test]
    fn non_finite_points_are_skipped_and_indices_kept() {
        let mut pts = random_points(500, 11);
        pts[3] = Point3::new(f64::NAN, 0.0, 0.0);
        pts[100] = Point3::new(0.0, f64::INFINITY, 0.0);
        let index = KdIndex::new(&pts).unwrap();
        assert_eq!(index.len(), 500);
        assert_eq!(index.indexed(), 498);
        for q in random_points(50, 12) {
            let got: Vec<usize> = index.knn(&q, 8).iter().map(|n| n.index).collect();
            let want: Vec<usize> = brute_knn(&pts, &q, 8).iter().map(|w| w.1).collect();
            assert_eq!(got, want);
        }
        assert!(index.knn(&pts[3], 4).is_empty());
        assert!(index.radius(&Point3::origin(), f64::NAN).is_empty());
    }

    #[test]
    fn small_and_empty_and_duplicates() {
        let empty = KdIndex::new(&[]).unwrap();
        assert!(empty.is_empty());
        assert!(empty.knn(&Point3::origin(), 3).is_empty());
        assert!(empty.nearest(&Point3::origin()).is_none());
        assert!(empty.radius(&Point3::origin(), 1.0).is_empty());
        // Many identical points: a classic k-d tree failure mode.
        let same = vec![Point3::new(1.0, 1.0, 1.0); 1000];
        let index = KdIndex::new(&same).unwrap();
        assert_eq!(index.knn(&Point3::origin(), 5).len(), 5);
        assert_eq!(index.radius(&Point3::new(1.0, 1.0, 1.0), 0.0).len(), 1000);
        let two = KdIndex::new(&[Point3::origin(), Point3::new(1.0, 0.0, 0.0)]).unwrap();
        assert_eq!(two.knn(&Point3::origin(), 10).len(), 2);
    }
}
