//! Correspondences in descriptor space: mutual nearest neighbours with Lowe's ratio test.
//!
//! The search is exact. A k-d tree over the raw descriptors does not help: a cloud of a few
//! thousand descriptors gives a tree of eight or so levels, which splits eight of the 33
//! dimensions, and FPFH has too high an intrinsic dimension for those to prune (kiddo's tree,
//! used here before, visited most leaves). Instead every cloud's descriptors are rotated onto
//! the principal axes of the target's ([`FeatureIndex`]): a rotation keeps distances, and the
//! first two axes hold three quarters of the variance on scans. The targets are cut into strips
//! of the first coordinate, each sorted by the second; a query visits the strips outward from
//! its own and scans each outward from its second coordinate, stopping when the gap in those
//! two coordinates alone exceeds the second-best distance so far, and gives up on a target as
//! soon as a partial sum of its distance does (on the bunny scans ~290 of 7,000 targets are
//! looked at, ~80 beyond three coordinates). The mutual check then searches back from each
//! matched target, the same way.

use nalgebra::{DMatrix, SMatrix, SVector};
use rayon::prelude::*;

use crate::IcpError;
use crate::global::fpfh::{FPFH_BINS, Fpfh};

/// Descriptors per strip of the search order: the strips cut the order of the first principal
/// coordinate into runs this long, each run sorted by the second coordinate. A bunny scan's
/// 7,000 descriptors give ~28 strips, and a query's search window (± the second-nearest
/// distance, ~17 against a spread of ~60) a few of them and a fifth of each. 64 and 128 were
/// slower (more strips to step through).
const STRIP: usize = 256;

/// Leading coordinates kept beside the rows ([`Layout::lead`]).
const LEAD: usize = 6;

/// Targets whose leading distances are summed side by side (two SIMD registers of f32).
const BLOCK: usize = 8;

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
/// descriptors rotated onto them and ordered for the strip search (see the module docs).
/// Built once per cloud and matched with every other cloud.
#[derive(Debug, Clone)]
pub struct FeatureIndex {
    /// Mean of the descriptors.
    mean: SVector<f64, FPFH_BINS>,
    /// Rotation onto their principal axes (applied after subtracting the mean).
    basis: Box<Basis>,
    /// The descriptors in that frame.
    layout: Layout,
}

/// Descriptors in some principal frame, ordered for an exact branch-and-bound search on the
/// first two coordinates (which hold most of the variance: three quarters on bunny scans).
#[derive(Debug, Clone)]
struct Layout {
    /// The descriptors in search order: strip by strip ([`STRIP`]), each strip by its second
    /// coordinate.
    rows: Vec<Fpfh>,
    /// The first [`LEAD`] coordinates of `rows`, coordinate by coordinate: most targets a
    /// query looks at are ruled out by these, [`BLOCK`] at a time.
    lead: [Vec<f32>; LEAD],
    /// Original index of each row.
    ids: Vec<u32>,
    /// Position in `rows` of each original index.
    position: Vec<u32>,
    strips: Vec<Strip>,
}

/// A run of [`Layout::rows`] with the range of its first coordinate.
#[derive(Debug, Clone, Copy)]
struct Strip {
    start: usize,
    end: usize,
    /// Least and greatest first coordinate in the run.
    lo: f32,
    hi: f32,
}

impl Layout {
    fn new(rows: &[Fpfh]) -> Self {
        // Sorted as integers: (the coordinate's bits in an order-preserving form, index).
        let key = |i: usize, k: usize| {
            let b = rows.get(i).map_or(0.0f32, |r| r[k]).to_bits();
            let ordered = if b >> 31 == 1 { !b } else { b | (1 << 31) };
            (u64::from(ordered) << 32) | i as u64
        };
        let mut keyed: Vec<u64> = (0..rows.len()).map(|i| key(i, 0)).collect();
        keyed.sort_unstable();
        let mut ids: Vec<u32> = keyed.iter().map(|&k| k as u32).collect();
        let first = |i: u32| rows.get(i as usize).map_or(0.0, |r| r[0]);
        let mut strips = Vec::with_capacity(rows.len().div_ceil(STRIP));
        for (k, run) in ids.chunks_mut(STRIP).enumerate() {
            let (lo, hi) = (
                run.first().map_or(0.0, |&i| first(i)),
                run.last().map_or(0.0, |&i| first(i)),
            );
            let mut by_second: Vec<u64> = run.iter().map(|&i| key(i as usize, 1)).collect();
            by_second.sort_unstable();
            for (slot, k) in run.iter_mut().zip(by_second) {
                *slot = k as u32;
            }
            strips.push(Strip {
                start: k * STRIP,
                end: k * STRIP + run.len(),
                lo,
                hi,
            });
        }
        let ordered: Vec<Fpfh> = ids
            .iter()
            .map(|&i| rows.get(i as usize).copied().unwrap_or([0.0; FPFH_BINS]))
            .collect();
        let mut position = vec![0u32; rows.len()];
        for (at, &i) in ids.iter().enumerate() {
            if let Some(p) = position.get_mut(i as usize) {
                *p = at as u32;
            }
        }
        Self {
            lead: std::array::from_fn(|k| ordered.iter().map(|r| r[k]).collect()),
            rows: ordered,
            ids,
            position,
            strips,
        }
    }

    fn len(&self) -> usize {
        self.rows.len()
    }

    /// The descriptor of original index `i`.
    fn row(&self, i: u32) -> Option<&Fpfh> {
        self.position
            .get(i as usize)
            .and_then(|&p| self.rows.get(p as usize))
    }

    /// The nearest `N` descriptors to `q` (`(original index, squared distance)`, nearest
    /// first; ties go to the smaller index; `u32::MAX` when there are fewer).
    ///
    /// Exact: the squared distance is summed dimension by dimension in a fixed order, so each
    /// partial sum is a lower bound of it (adding a non-negative term never rounds down), and
    /// a descriptor is left out only when such a bound already exceeds the `N`-th distance so
    /// far. Strips are visited outward from the one holding `q`'s first coordinate until the
    /// gap in that coordinate exceeds the `N`-th distance; inside a strip the scan runs
    /// outward from `q`'s second coordinate until the gap plus the second coordinate's term
    /// does.
    ///
    /// `seeds` (original indices) are measured first: a good guess (the match of the point
    /// before, which lies beside it on the surface and has a similar descriptor) makes the
    /// bound tight from the start. The answer does not depend on them.
    fn nearest<const N: usize>(&self, q: &Fpfh, seeds: &[u32]) -> [(u32, f32); N] {
        let mut best = [(u32::MAX, f32::INFINITY); N];
        for &seed in seeds {
            let Some(&at) = self.position.get(seed as usize) else {
                continue;
            };
            self.visit(at as usize, q, &mut best);
        }
        let q0 = q[0];
        let count = self.strips.len();
        if count == 0 {
            return best;
        }
        let home = self.strips.partition_point(|s| s.hi < q0).min(count - 1);
        let gap2 = |k: usize| {
            self.strips.get(k).map_or(f32::INFINITY, |s| {
                let g = if q0 < s.lo {
                    s.lo - q0
                } else if q0 > s.hi {
                    q0 - s.hi
                } else {
                    0.0
                };
                g * g
            })
        };
        self.scan_strip(home, gap2(home), q, &mut best);
        let (mut left, mut right) = (home, home + 1);
        loop {
            // Every strip visited: with fewer than `N` rows (or no finite distance) the
            // `N`-th best stays infinite and no gap would ever exceed it.
            if left == 0 && right >= count {
                break;
            }
            let gl = if left > 0 {
                gap2(left - 1)
            } else {
                f32::INFINITY
            };
            let gr = if right < count {
                gap2(right)
            } else {
                f32::INFINITY
            };
            let worst = best[N - 1].1;
            if gl <= gr {
                if gl > worst {
                    break;
                }
                left -= 1;
                self.scan_strip(left, gl, q, &mut best);
            } else {
                if gr > worst {
                    break;
                }
                self.scan_strip(right, gr, q, &mut best);
                right += 1;
            }
        }
        best
    }

    /// Visits strip `k` (gap² `g2` to `q` in the first coordinate) outward from `q`'s second
    /// coordinate.
    #[inline]
    fn scan_strip<const N: usize>(&self, k: usize, g2: f32, q: &Fpfh, best: &mut [(u32, f32); N]) {
        let Some(s) = self.strips.get(k) else {
            return;
        };
        let [_, second, ..] = &self.lead;
        let Some(run) = second.get(s.start..s.end) else {
            return;
        };
        let q1 = q[1];
        let mid = s.start + run.partition_point(|&v| v < q1);
        let outside = |j: usize, best: &[(u32, f32); N]| {
            let x = q1 - second.get(j).copied().unwrap_or(f32::INFINITY);
            g2 + x * x > best[N - 1].1
        };
        let mut j = mid;
        while j < s.end && !outside(j, best) {
            let len = (s.end - j).min(BLOCK);
            self.block(j, len, q, best);
            j += len;
        }
        let mut j = mid;
        while j > s.start && !outside(j - 1, best) {
            let len = (j - s.start).min(BLOCK);
            self.block(j - len, len, q, best);
            j -= len;
        }
    }

    /// Visits rows `at..at + len` (`len ≤ BLOCK`): the leading part of their distances to
    /// `q` side by side (vectorised), then the rest for those still under the `N`-th best.
    #[inline]
    fn block<const N: usize>(&self, at: usize, len: usize, q: &Fpfh, best: &mut [(u32, f32); N]) {
        let mut d = [0.0f32; BLOCK];
        for (k, column) in self.lead.iter().enumerate() {
            let qk = q[k];
            if let Some(c) = column.get(at..at + BLOCK) {
                for (dl, &cl) in d.iter_mut().zip(c) {
                    let x = qk - cl;
                    *dl += x * x;
                }
            } else {
                for (dl, &cl) in d.iter_mut().zip(column.get(at..at + len).unwrap_or(&[])) {
                    let x = qk - cl;
                    *dl += x * x;
                }
            }
        }
        let worst = best[N - 1].1;
        let mut under = 0u32;
        for (l, &dl) in d.iter().enumerate().take(len) {
            under |= u32::from(dl <= worst) << l;
        }
        while under != 0 {
            let l = under.trailing_zeros() as usize;
            under &= under - 1;
            self.finish(at + l, d[l], q, best);
        }
    }

    /// The squared distance of `q` to row `at`, summed in order (a seed's).
    #[inline]
    fn visit<const N: usize>(&self, at: usize, q: &Fpfh, best: &mut [(u32, f32); N]) {
        let mut d = 0.0f32;
        for (k, column) in self.lead.iter().enumerate() {
            let x = q[k] - column.get(at).copied().unwrap_or(f32::INFINITY);
            d += x * x;
        }
        self.finish(at, d, q, best);
    }

    /// Row `at` given the sum `d` over its leading coordinates: the rest summed in order and
    /// given up as soon as it exceeds the `N`-th best; kept if it beats that (and is not there
    /// already, as a seed).
    #[inline]
    fn finish<const N: usize>(&self, at: usize, mut d: f32, q: &Fpfh, best: &mut [(u32, f32); N]) {
        let worst = best[N - 1];
        if d > worst.1 {
            return;
        }
        let (Some(r), Some(&id)) = (self.rows.get(at), self.ids.get(at)) else {
            return;
        };
        for (lo, hi) in [(LEAD, 16), (16, FPFH_BINS)] {
            for k in lo..hi {
                let x = q[k] - r[k];
                d += x * x;
            }
            if d > worst.1 {
                return;
            }
        }
        if (d < worst.1 || id < worst.0) && best.iter().all(|b| b.0 != id) {
            insert(best, (id, d));
        }
    }
}

/// Inserts `x` into `best` (sorted by distance, then index), dropping the last.
#[inline]
fn insert<const N: usize>(best: &mut [(u32, f32); N], x: (u32, f32)) {
    let before = |b: &(u32, f32)| x.1 < b.1 || (x.1 == b.1 && x.0 < b.0);
    let mut at = N;
    while at > 0 && best.get(at - 1).is_some_and(before) {
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
        let layout = Layout::new(&rotate_all(&mean, &basis, features));
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

/// `features`, minus `mean`, rotated by `basis`: one matrix product in f32 (matrixmultiply's
/// kernels; the rotated coordinates are compared with each other only).
fn rotate_all(mean: &SVector<f64, FPFH_BINS>, basis: &Basis, features: &[Fpfh]) -> Vec<Fpfh> {
    let n = features.len();
    let centred = DMatrix::<f32>::from_fn(n, FPFH_BINS, |i, k| {
        features.get(i).map_or(0.0, |f| f[k]) - mean[k] as f32
    });
    let basis_t = DMatrix::<f32>::from_fn(FPFH_BINS, FPFH_BINS, |k, r| basis[(r, k)] as f32);
    let rotated = centred * basis_t;
    (0..n)
        .map(|i| std::array::from_fn(|k| rotated[(i, k)]))
        .collect()
}

/// The mean of `features` and the rotation onto their principal axes (eigenvectors of the
/// covariance as rows, by decreasing eigenvalue). Sums run in f64 in a fixed order (the
/// scatter matrix as one matrix product); an empty set gets the identity.
fn principal_axes(features: &[Fpfh]) -> (SVector<f64, FPFH_BINS>, Basis) {
    let n = features.len();
    if n == 0 {
        return (SVector::zeros(), Basis::identity());
    }
    let mut sum = SVector::<f64, FPFH_BINS>::zeros();
    for f in features {
        for (s, &x) in sum.iter_mut().zip(f) {
            *s += f64::from(x);
        }
    }
    let mean = sum / n as f64;
    let centred = DMatrix::<f64>::from_fn(n, FPFH_BINS, |i, k| {
        features.get(i).map_or(0.0, |f| f64::from(f[k])) - mean[k]
    });
    let scatter = centred.transpose() * &centred;
    let cov = Basis::from_iterator(scatter.iter().copied());
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
    // Fixed runs of queries, each seeded with the matches of the query before it.
    let search = || -> Vec<Option<Correspondence>> {
        queries
            .par_chunks(ROWS_PER_TASK)
            .enumerate()
            .flat_map_iter(|(c, run)| {
                let mut seeds = [u32::MAX; 2];
                run.iter().enumerate().map(move |(k, q)| {
                    let best = targets.nearest::<2>(q, &seeds);
                    seeds = [best[0].0, best[1].0];
                    (c * ROWS_PER_TASK + k, best)
                })
            })
            .map(|(i, [(j, d1), (second, d2)])| {
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
            .collect()
    };
    // The sources' layout for the mutual check is built while the forward search runs.
    let (forward, sources) = rayon::join(search, || config.mutual.then(|| Layout::new(&queries)));
    let mut found: Vec<Correspondence> = forward.into_iter().flatten().collect();
    if config.mutual {
        // The nearest source of every matched target, searched back in the same frame (the
        // same squared distances, bit for bit).
        // Each seeded with a source that chose it (most often the answer).
        let mut chosen: Vec<(u32, u32)> = found.iter().map(|c| (c.target, c.source)).collect();
        chosen.sort_unstable();
        chosen.dedup_by_key(|x| x.0);
        let wanted: Vec<u32> = chosen.iter().map(|x| x.0).collect();
        let sources = sources.unwrap_or_else(|| Layout::new(&queries));
        let back: Vec<u32> = chosen
            .par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|&(j, seed)| {
                targets
                    .row(j)
                    .map_or(u32::MAX, |t| sources.nearest::<1>(t, &[seed])[0].0)
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

    /// A target with a single descriptor: the second nearest never exists, so the search must
    /// stop once every strip is visited (it looped forever before: a placement alignment of
    /// `slscan scan --placements 2 --seed 3` hung for 40 minutes in it). The one descriptor is
    /// matched (no second one to fail Lowe's test against).
    #[test]
    fn a_target_of_one_descriptor_ends_the_search() {
        let target = vec![descriptor(7)];
        let source: Vec<Fpfh> = (0..20).map(descriptor).collect();
        let (si, ti) = (FeatureIndex::new(&source), FeatureIndex::new(&target));
        let loose = MatchConfig {
            ratio: 1.0,
            mutual: false,
        };
        let m = match_features(&source, &si, &target, &ti, &loose).unwrap();
        assert_eq!(m.len(), 20);
        assert!(m.iter().all(|c| c.target == 0));
    }
}
