//! Correspondences in descriptor space: mutual nearest neighbours with Lowe's ratio test.
//!
//! The search uses kiddo's immutable k-d tree over the 33-dimensional FPFH descriptors (a
//! well-kept crate; the workspace's own `KdIndex` is three-dimensional only), in the
//! descriptors' principal axes: a tree of a few thousand points splits only its first eight
//! or so dimensions (one per level, in order), and FPFH bins in their own order are a poor
//! choice of eight — the search then visits most leaves. Rotated onto the principal axes
//! (highest variance first) the same exact search prunes most of the tree; a rotation keeps
//! every distance, so the answer is the same nearest neighbour up to float rounding.

use std::num::NonZero;

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::IcpError;
use crate::global::fpfh::{FPFH_BINS, Fpfh};

/// Points per leaf of the descriptor tree: kiddo's default.
const LEAF: usize = 8;

/// The rotation onto the principal axes of a set of descriptors, rows by decreasing variance.
type Basis = SMatrix<f64, FPFH_BINS, FPFH_BINS>;

/// The k-d tree type over descriptors.
type Tree = ImmutableKdTree<f32, u32, FPFH_BINS, LEAF>;

/// Settings of [`match_features`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchConfig {
    /// Lowe's ratio test: keep a match when the distance to the nearest target descriptor is
    /// at most this fraction of the distance to the second nearest. Default 0.95: FPFH is far
    /// less distinctive than image descriptors, and a 0.8 test (Lowe's) leaves too few matches
    /// in the small overlap of two views; RANSAC deals with the rest.
    pub ratio: f64,
    /// Keep a match only when the source descriptor is also the nearest of its target (cross
    /// check, as Open3D's `mutual_filter`). Default true: it removes most wrong matches for
    /// the price of one more search per target point.
    pub mutual: bool,
}

impl Default for MatchConfig {
    fn default() -> Self {
        Self {
            ratio: 0.95,
            mutual: true,
        }
    }
}

impl MatchConfig {
    pub(crate) fn validate(&self) -> Result<(), IcpError> {
        if !(self.ratio > 0.0 && self.ratio <= 1.0) {
            return Err(IcpError::invalid(
                "matching.ratio",
                self.ratio,
                "must be in (0, 1]",
            ));
        }
        Ok(())
    }
}

/// A match between a source point and a target point (indices into the descriptor slices).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correspondence {
    /// Index of the source point.
    pub source: u32,
    /// Index of the target point.
    pub target: u32,
    /// Nearest over second-nearest descriptor distance (smaller is more distinctive).
    pub ratio: f32,
}

/// A k-d tree over the descriptors of one cloud, built once and searched by every cloud it is
/// matched with.
#[derive(Debug, Clone)]
pub struct FeatureIndex {
    tree: Tree,
    /// Mean of the indexed descriptors.
    mean: SVector<f64, FPFH_BINS>,
    /// Rotation onto their principal axes (applied after subtracting the mean).
    basis: Box<Basis>,
    len: usize,
}

/// A neighbour in descriptor space: `(index, squared distance)`.
type Neighbour = (u32, f32);

impl FeatureIndex {
    /// Builds the tree over `features`.
    pub fn new(features: &[Fpfh]) -> Self {
        let (mean, basis) = principal_axes(features);
        let rotated: Vec<Fpfh> = features
            .par_iter()
            .with_min_len(256)
            .map(|f| rotate(&mean, &basis, f))
            .collect();
        Self {
            tree: Tree::new_from_slice(&rotated),
            mean,
            basis: Box::new(basis),
            len: features.len(),
        }
    }

    /// `q` in the principal frame of the indexed descriptors.
    fn rotate(&self, q: &Fpfh) -> Fpfh {
        rotate(&self.mean, &self.basis, q)
    }

    /// Number of descriptors.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest two descriptors: `(index, squared distance)` of each.
    fn nearest_two(&self, q: &Fpfh) -> Option<(Neighbour, Option<Neighbour>)> {
        if self.len == 0 {
            return None;
        }
        let two = NonZero::new(2)?;
        let found = self
            .tree
            .nearest_n::<SquaredEuclidean>(&self.rotate(q), two);
        let first = found.first().map(|n| (n.item, n.distance))?;
        Some((first, found.get(1).map(|n| (n.item, n.distance))))
    }

    fn nearest(&self, q: &Fpfh) -> Option<u32> {
        (self.len > 0).then(|| {
            self.tree
                .nearest_one::<SquaredEuclidean>(&self.rotate(q))
                .item
        })
    }
}

/// `q - mean` rotated by `basis`.
fn rotate(mean: &SVector<f64, FPFH_BINS>, basis: &Basis, q: &Fpfh) -> Fpfh {
    let v = SVector::<f64, FPFH_BINS>::from_iterator(q.iter().map(|&x| f64::from(x)));
    let r = basis * (v - mean);
    let mut out = [0.0f32; FPFH_BINS];
    for (o, x) in out.iter_mut().zip(r.iter()) {
        *o = *x as f32;
    }
    out
}

/// The mean of `features` and the rotation onto their principal axes (eigenvectors of the
/// covariance as rows, by decreasing eigenvalue). Sums run in f64 in a fixed order; an empty
/// set gets the identity.
fn principal_axes(features: &[Fpfh]) -> (SVector<f64, FPFH_BINS>, Basis) {
    let n = features.len();
    if n == 0 {
        return (SVector::zeros(), Basis::identity());
    }
    let as_vector = |f: &Fpfh| SVector::<f64, FPFH_BINS>::from_iterator(f.iter().map(|&x| f64::from(x)));
    let mean = features
        .iter()
        .fold(SVector::<f64, FPFH_BINS>::zeros(), |s, f| s + as_vector(f))
        / n as f64;
    let mut cov = Basis::zeros();
    for f in features {
        let d = as_vector(f) - mean;
        cov.ger(1.0, &d, &d, 1.0);
    }
    let eigen = cov.symmetric_eigen();
    let mut order: Vec<usize> = (0..FPFH_BINS).collect();
    order.sort_by(|&a, &b| {
        eigen.eigenvalues[b]
            .total_cmp(&eigen.eigenvalues[a])
            .then(a.cmp(&b))
    });
    let mut basis = Basis::zeros();
    for (row, &k) in order.iter().enumerate() {
        basis.set_row(row, &eigen.eigenvectors.column(k).transpose());
    }
    (mean, basis)
}

/// Matches every source descriptor with its nearest target descriptor and keeps the matches
/// that pass the ratio test (and the cross check when `config.mutual`). `source_index` is
/// only searched for the cross check. The result is ordered by source index and does not
/// depend on the number of threads.
///
/// # Errors
/// [`IcpError::InvalidParameter`] for a bad configuration or an index not built over the
/// descriptors given with it.
pub fn match_features(
    source: &[Fpfh],
    source_index: &FeatureIndex,
    target: &[Fpfh],
    target_index: &FeatureIndex,
    config: &MatchConfig,
) -> Result<Vec<Correspondence>, IcpError> {
    config.validate()?;
    if source_index.len() != source.len() || target_index.len() != target.len() {
        return Err(IcpError::invalid(
            "feature index",
            format!(
                "{} / {} descriptors indexed for {} / {}",
                source_index.len(),
                target_index.len(),
                source.len(),
                target.len()
            ),
            "each index must be built over its own descriptors",
        ));
    }
    let ratio2 = (config.ratio * config.ratio) as f32;
    let found = source
        .par_iter()
        .enumerate()
        .with_min_len(64)
        .filter_map(|(i, q)| {
            let ((j, d1), second) = target_index.nearest_two(q)?;
            let ratio = match second {
                Some((_, d2)) if d2 > 0.0 => d1 / d2,
                Some(_) => 1.0,
                None => 0.0,
            };
            if ratio > ratio2 {
                return None;
            }
            if config.mutual {
                let back = target_index_back(target, source_index, j)?;
                if back as usize != i {
                    return None;
                }
            }
            Some(Correspondence {
                source: i as u32,
                target: j,
                ratio: ratio.sqrt(),
            })
        })
        .collect();
    Ok(found)
}

/// The source descriptor nearest to target descriptor `j`.
fn target_index_back(target: &[Fpfh], source_index: &FeatureIndex, j: u32) -> Option<u32> {
    source_index.nearest(target.get(j as usize)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn descriptor(seed: u32) -> Fpfh {
        let mut f = [0.0f32; FPFH_BINS];
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(12345);
        for v in &mut f {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            *v = (s % 1000) as f32 / 10.0;
        }
        f
    }

    #[test]
    fn shuffled_copies_match_back_and_ambiguous_ones_are_dropped() {
        let target: Vec<Fpfh> = (0..300).map(descriptor).collect();
        // The source: target descriptors 299..0, slightly perturbed.
        let mut source: Vec<Fpfh> = target.iter().rev().copied().collect();
        for f in &mut source {
            f[0] += 0.01;
        }
        // An ambiguous source descriptor: halfway between targets 0 and 1.
        let mut mid = [0.0f32; FPFH_BINS];
        for (k, m) in mid.iter_mut().enumerate() {
            *m = 0.5 * (target[0][k] + target[1][k]);
        }
        source.push(mid);
        let (si, ti) = (FeatureIndex::new(&source), FeatureIndex::new(&target));
        let m = match_features(&source, &si, &target, &ti, &MatchConfig::default()).unwrap();
        assert_eq!(m.len(), 300);
        for c in &m {
            assert_eq!(c.target, 299 - c.source);
        }
        let loose = MatchConfig {
            ratio: 1.0,
            mutual: false,
        };
        let m = match_features(&source, &si, &target, &ti, &loose).unwrap();
        assert_eq!(m.len(), 301);
        assert!(
            match_features(&source, &ti, &target, &ti, &loose).is_err(),
            "mismatched index"
        );
    }
}
