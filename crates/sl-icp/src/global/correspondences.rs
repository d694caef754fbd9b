//! Correspondences in descriptor space: mutual nearest neighbours with Lowe's ratio test.
//!
//! The search is exact. A k-d tree does not help here: a cloud of a few thousand descriptors
//! gives a tree of eight or so levels, which splits eight of the 33 dimensions, and FPFH has
//! too high an intrinsic dimension for those to prune — kiddo's tree (used here before) visited
//! most leaves and was slower than a plain scan. Instead every cloud's descriptors are rotated
//! onto the principal axes of the target's ([`FeatureIndex`]): a rotation keeps distances, and
//! the squared distance over the first [`BOUND_DIMS`] axes (most of the variance) is a lower
//! bound of the full one. A scan computes that bound for every target, vectorised over
//! targets stored dimension by dimension, and finishes the full distance only for targets whose
//! bound beats the second-best distance so far. The mutual check then searches back from each
//! matched target, the same way.

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::IcpError;
use crate::global::fpfh::{FPFH_BINS, Fpfh};

/// Principal axes summed for the lower bound. FPFH's first eight principal axes hold most of
/// its variance on scans (the bound is then tight); more make the vectorised pass longer for
/// little more pruning.
const BOUND_DIMS: usize = 8;

/// Targets per tile of the bound pass: the bounds of one query to a tile stay in registers
/// and L1 while the dimensions are summed.
const TILE: usize = 64;

/// Queries per parallel task.
const ROWS_PER_TASK: usize = 64;

/// The rotation onto principal axes, rows by decreasing variance.
type Basis = SMatrix<f64, FPFH_BINS, FPFH_BINS>;

/// Settings of [`match_features`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchConfig {
    /// Lowe's ratio test: keep a match when the distance to the nearest target descriptor is
    /// at most this fraction of the distance to the second nearest. Default 0.95: FPFH is far
    /// less distinctive than image descriptors, and a 0.8 test (Lowe's) leaves too few matches
    /// in the small overlap of two views; RANSAC deals with the rest.
    pub ratio: f64,
    /// Keep a match only when the source descriptor is also the nearest of its target (cross
    /// check, as Open3D's `mutual_filter`). Default true: it removes most wrong matches, and
    /// costs little (the same scan gives both directions).
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

/// The descriptors of one cloud made ready for matching: the principal axes of the set, the
/// descriptors rotated onto them, and the first eight rotated coordinates laid out
/// dimension by dimension. Built once per cloud and matched with every other cloud.
#[derive(Debug, Clone)]
pub struct FeatureIndex {
    /// Mean of the descriptors.
    mean: SVector<f64, FPFH_BINS>,
    /// Rotation onto their principal axes (applied after subtracting the mean).
    basis: Box<Basis>,
    /// The descriptors in that frame.
    layout: Layout,
}

/// Descriptors in some principal frame: whole rows, and the leading coordinates column-wise.
#[derive(Debug, Clone)]
struct Layout {
    rows: Vec<Fpfh>,
    /// `columns[k * stride + j]`: coordinate `k < BOUND_DIMS` of descriptor `j`; zero in the
    /// padding.
    columns: Vec<f32>,
    /// The number of descriptors rounded up to whole tiles.
    stride: usize,
}

impl Layout {
    fn new(rows: Vec<Fpfh>) -> Self {
        let stride = rows.len().div_ceil(TILE) * TILE;
        let mut columns = vec![0.0f32; stride * BOUND_DIMS];
        for (k, column) in columns.chunks_exact_mut(stride.max(1)).enumerate() {
            for (c, f) in column.iter_mut().zip(&rows) {
                if let Some(v) = f.get(k) {
                    *c = *v;
                }
            }
        }
        Self {
            rows,
            columns,
            stride,
        }
    }

    fn len(&self) -> usize {
        self.rows.len()
    }

    /// The bounds of `q` to the tile of descriptors starting at `j0`.
    #[inline]
    fn tile_bounds(&self, q: &Fpfh, j0: usize) -> [f32; TILE] {
        let mut acc = [0.0f32; TILE];
        for (k, &qk) in q.iter().take(BOUND_DIMS).enumerate() {
            let at = k * self.stride + j0;
            let Some(column) = self.columns.get(at..at + TILE) else {
                continue;
            };
            for (a, &c) in acc.iter_mut().zip(column) {
                let x = qk - c;
                *a += x * x;
            }
        }
        acc
    }

    /// The nearest `N` descriptors to `q` (`(index, squared distance)`, nearest first; ties go
    /// to the smaller index; `u32::MAX` when there are fewer).
    fn nearest<const N: usize>(&self, q: &Fpfh) -> [(u32, f32); N] {
        let mut best = [(u32::MAX, f32::INFINITY); N];
        let n = self.len();
        for j0 in (0..n).step_by(TILE) {
            let bounds = self.tile_bounds(q, j0);
            // Most tiles hold nothing near: one vectorised minimum rules them out.
            let nearest_bound = bounds.iter().fold(f32::INFINITY, |m, &b| m.min(b));
            if nearest_bound >= best.last().map_or(f32::INFINITY, |b| b.1) {
                continue;
            }
            let valid = (n - j0).min(TILE);
            for (dj, &bound) in bounds.iter().take(valid).enumerate() {
                let worst = best.last().map_or(f32::INFINITY, |b| b.1);
                if bound >= worst {
                    continue;
                }
                let j = j0 + dj;
                let Some(row) = self.rows.get(j) else {
                    continue;
                };
                let d = bound + rest(q, row);
                if d < worst {
                    insert(&mut best, (j as u32, d));
                }
            }
        }
        best
    }
}

/// Squared distance over the coordinates the bound leaves out.
#[inline]
fn rest(q: &Fpfh, r: &Fpfh) -> f32 {
    let mut s = 0.0f32;
    for (a, b) in q.iter().zip(r).skip(BOUND_DIMS) {
        let x = a - b;
        s += x * x;
    }
    s
}

/// Inserts `x` into the sorted `best`, dropping the last; after equal distances (so ties keep
/// the earlier, smaller index).
#[inline]
fn insert<const N: usize>(best: &mut [(u32, f32); N], x: (u32, f32)) {
    let mut at = N;
    while at > 0 && best.get(at - 1).is_some_and(|b| x.1 < b.1) {
        at -= 1;
    }
    for k in (at + 1..N).rev() {
        if let Some(&prev) = best.get(k - 1)
            && let Some(slot) = best.get_mut(k)
        {
            *slot = prev;
        }
    }
    if let Some(slot) = best.get_mut(at) {
        *slot = x;
    }
}

impl FeatureIndex {
    /// Finds the principal axes of `features` and lays them out for matching.
    pub fn new(features: &[Fpfh]) -> Self {
        let (mean, basis) = principal_axes(features);
        let layout = Layout::new(rotate_all(&mean, &basis, features));
        Self {
            mean,
            basis: Box::new(basis),
            layout,
        }
    }

    /// Number of descriptors.
    pub fn len(&self) -> usize {
        self.layout.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// `features`, minus `mean`, rotated by `basis` (in f64, rounded to f32).
fn rotate_all(mean: &SVector<f64, FPFH_BINS>, basis: &Basis, features: &[Fpfh]) -> Vec<Fpfh> {
    features
        .par_iter()
        .with_min_len(256)
        .map(|q| {
            let v = SVector::<f64, FPFH_BINS>::from_iterator(q.iter().map(|&x| f64::from(x)));
            let r = basis * (v - mean);
            let mut out = [0.0f32; FPFH_BINS];
            for (o, x) in out.iter_mut().zip(r.iter()) {
                *o = *x as f32;
            }
            out
        })
        .collect()
}

/// The mean of `features` and the rotation onto their principal axes (eigenvectors of the
/// covariance as rows, by decreasing eigenvalue). Sums run in f64 in a fixed order; an empty
/// set gets the identity.
fn principal_axes(features: &[Fpfh]) -> (SVector<f64, FPFH_BINS>, Basis) {
    let n = features.len();
    if n == 0 {
        return (SVector::zeros(), Basis::identity());
    }
    let as_vector =
        |f: &Fpfh| SVector::<f64, FPFH_BINS>::from_iterator(f.iter().map(|&x| f64::from(x)));
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
/// that pass the ratio test (and the cross check when `config.mutual`). Exact up to float
/// rounding (distances in f32, in the target's principal frame); ties go to the smaller
/// index. The result is ordered by source index and does not depend on the number of
/// threads. `source_index` is checked against `source` (the source descriptors are rotated
/// into the target's frame here).
///
/// # Errors
/// [`IcpError::InvalidParameter`] for a bad configuration or an index not built over the
/// descriptors given with it.
///
/// ```
/// use sl_icp::{match_features, FeatureIndex, MatchConfig, FPFH_BINS};
/// // Three distinct descriptors, and the source holding them in reverse order.
/// let target: Vec<[f32; FPFH_BINS]> = (0..3)
///     .map(|i| std::array::from_fn(|k| ((i * 7 + k * 3) % 11) as f32 * 10.0))
///     .collect();
/// let source: Vec<[f32; FPFH_BINS]> = target.iter().rev().copied().collect();
/// let m = match_features(&source, &FeatureIndex::new(&source), &target, &FeatureIndex::new(&target), &MatchConfig::default())?;
/// let pairs: Vec<(u32, u32)> = m.iter().map(|c| (c.source, c.target)).collect();
/// assert_eq!(pairs, [(0, 2), (1, 1), (2, 0)]);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
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
    if source.is_empty() || target.is_empty() {
        return Ok(Vec::new());
    }
    let targets = &target_index.layout;
    let queries = rotate_all(&target_index.mean, &target_index.basis, source);
    let ratio2 = (config.ratio * config.ratio) as f32;
    let forward: Vec<Option<Correspondence>> = queries
        .par_iter()
        .enumerate()
        .with_min_len(ROWS_PER_TASK)
        .map(|(i, q)| {
            let [(j, d1), (second, d2)] = targets.nearest::<2>(q);
            if j == u32::MAX {
                return None;
            }
            let ratio = if second == u32::MAX {
                0.0
            } else if d2 > 0.0 {
                d1 / d2
            } else {
                1.0
            };
            (ratio <= ratio2).then_some(Correspondence {
                source: i as u32,
                target: j,
                ratio: ratio.sqrt(),
            })
        })
        .collect();
    let mut found: Vec<Correspondence> = forward.into_iter().flatten().collect();
    if config.mutual {
        // The nearest source of every matched target, searched back in the same frame (the
        // same squared distances, bit for bit).
        let mut wanted: Vec<u32> = found.iter().map(|c| c.target).collect();
        wanted.sort_unstable();
        wanted.dedup();
        let sources = Layout::new(queries);
        let back: Vec<u32> = wanted
            .par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|&j| {
                targets
                    .rows
                    .get(j as usize)
                    .map_or(u32::MAX, |t| sources.nearest::<1>(t)[0].0)
            })
            .collect();
        found.retain(|c| {
            wanted
                .binary_search(&c.target)
                .ok()
                .and_then(|k| back.get(k))
                == Some(&c.source)
        });
    }
    Ok(found)
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
