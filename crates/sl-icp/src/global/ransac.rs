//! RANSAC over descriptor correspondences (Fischler & Bolles 1981), with the pre-checks of
//! Open3D's feature-matching RANSAC: a sample of three correspondences is scored only when
//! its edge lengths agree on both sides and the pose fitted to it maps each of its three
//! source points next to its target point. Scoring counts the correspondences (not the
//! clouds' points) the pose brings within the inlier distance, so a hypothesis costs one pass
//! over the correspondences and no tree search.
//!
//! Deterministic: hypotheses are drawn in batches, each batch from its own generator seeded
//! by `(seed, batch number)`, rounds of batches run in parallel and are merged in batch order,
//! and the early stop (enough iterations for `confidence` at the best inlier ratio so far) is
//! only tested between rounds. The result depends on the seed, not on the number of threads.

use nalgebra::{Isometry3, Point3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use crate::IcpError;
use crate::global::correspondences::Correspondence;
use crate::metric::point_to_point::PointToPoint;

/// Hypotheses drawn by one task: large enough that a task outlasts its scheduling (~1 µs per
/// rejected sample, ~N µs per scored one), small enough that the early stop is not late.
const BATCH: usize = 256;

/// Batches per round (independent of the thread count, for determinism): 2048 hypotheses
/// between two tests of the early stop.
const BATCHES_PER_ROUND: usize = 8;

/// Refinement passes at the end: least squares on the inliers, then recount (the "local
/// optimisation" of LO-RANSAC, Chum, Matas & Kittler 2003, in its simplest form).
const REFINEMENTS: usize = 3;

/// Fewest inliers for a pose to be returned: three define it, so anything below a handful is
/// chance.
const MIN_INLIERS: usize = 6;

/// Settings of [`ransac_pose`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacConfig {
    /// Most hypotheses drawn. Default 100,000, as Open3D's examples.
    pub max_iterations: usize,
    /// Stop early once the probability of having drawn at least one all-inlier sample, at the
    /// best inlier ratio found so far, reaches this. Default 0.999 (Open3D's).
    pub confidence: f64,
    /// A correspondence is an inlier when the pose brings its source point within this
    /// distance of its target point, mm. Default 3 mm: 1.5 times the default 2 mm voxel, as
    /// Open3D's examples.
    pub inlier_distance: f64,
    /// Edge-length check: for every two correspondences of a sample, the shorter of the two
    /// distances (source side, target side) must be at least this fraction of the longer.
    /// Default 0.9, as Open3D's `CorrespondenceCheckerBasedOnEdgeLength`.
    pub edge_length_ratio: f64,
    /// Seed of the sampling.
    pub seed: u64,
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            max_iterations: 100_000,
            confidence: 0.999,
            inlier_distance: 3.0,
            edge_length_ratio: 0.9,
            seed: 0,
        }
    }
}

impl RansacConfig {
    pub(crate) fn validate(&self) -> Result<(), IcpError> {
        if self.max_iterations == 0 {
            return Err(IcpError::invalid(
                "ransac.max_iterations",
                0,
                "must be at least 1",
            ));
        }
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return Err(IcpError::invalid(
                "ransac.confidence",
                self.confidence,
                "must be in (0, 1)",
            ));
        }
        if !(self.inlier_distance.is_finite() && self.inlier_distance > 0.0) {
            return Err(IcpError::invalid(
                "ransac.inlier_distance",
                self.inlier_distance,
                "must be finite and > 0 (mm)",
            ));
        }
        if !(self.edge_length_ratio >= 0.0 && self.edge_length_ratio < 1.0) {
            return Err(IcpError::invalid(
                "ransac.edge_length_ratio",
                self.edge_length_ratio,
                "must be in [0, 1)",
            ));
        }
        Ok(())
    }
}

/// Result of [`ransac_pose`].
#[derive(Debug, Clone, PartialEq)]
pub struct RansacResult {
    /// `T_target_source`, refined by least squares on the inliers.
    pub pose: Isometry3<f64>,
    /// Correspondences within the inlier distance at `pose`.
    pub inliers: usize,
    /// Correspondences given.
    pub correspondences: usize,
    /// Hypotheses drawn (including those the pre-checks rejected).
    pub iterations: usize,
    /// Hypotheses that passed the pre-checks and were scored.
    pub scored: usize,
}

/// The best hypothesis of a batch or round.
#[derive(Debug, Clone, Copy)]
struct Best {
    pose: Isometry3<f64>,
    inliers: usize,
    scored: usize,
}

fn better(a: Option<Best>, b: Option<Best>) -> Option<Best> {
    // Ties keep `a`, the earlier batch: the merge order is fixed, so is the winner.
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.inliers > x.inliers { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

/// Counts the correspondences `pose` maps within `d2` (squared), giving up once even all the
/// rest could not beat `to_beat`.
#[inline]
fn count(
    pose: &Isometry3<f64>,
    a: &[Point3<f64>],
    b: &[Point3<f64>],
    d2: f64,
    to_beat: usize,
) -> usize {
    let r = pose.rotation.to_rotation_matrix();
    let t = pose.translation.vector;
    let n = a.len();
    let mut inliers = 0;
    for (k, (p, q)) in a.iter().zip(b).enumerate() {
        if (r * p + t - q).norm_squared() < d2 {
            inliers += 1;
        }
        // Every 64 points: can the rest still beat the best?
        if k % 64 == 63 && inliers + (n - k - 1) <= to_beat {
            return 0;
        }
    }
    inliers
}

/// Least-squares pose of the given pairs; `None` if degenerate.
fn fit(
    a: &[Point3<f64>],
    b: &[Point3<f64>],
    keep: impl Fn(usize) -> bool,
) -> Option<Isometry3<f64>> {
    let mut acc = PointToPoint::zero();
    let mut centre = nalgebra::Vector3::zeros();
    let mut n = 0.0;
    for (k, p) in a.iter().enumerate() {
        if keep(k) {
            centre += p.coords;
            n += 1.0;
        }
    }
    if n < 3.0 {
        return None;
    }
    let c = Point3::from(centre / n);
    for (k, (p, q)) in a.iter().zip(b).enumerate() {
        if keep(k) {
            acc.add(&(p - c), &(q - c), 1.0);
        }
    }
    acc.solve(&c)
}

/// One batch of hypotheses.
fn batch(
    a: &[Point3<f64>],
    b: &[Point3<f64>],
    config: &RansacConfig,
    number: u64,
    draws: usize,
) -> Option<Best> {
    let n = a.len();
    // SplitMix-style spreading of the batch number, so that neighbouring batches get
    // unrelated streams.
    let mut rng = Pcg64Mcg::seed_from_u64(
        config
            .seed
            .wrapping_add(number.wrapping_mul(0x9E37_79B9_7F4A_7C15)),
    );
    let d2 = config.inlier_distance * config.inlier_distance;
    let ratio = config.edge_length_ratio;
    let min_edge = config.inlier_distance;
    let mut best: Option<Best> = None;
    let mut scored = 0;
    for _ in 0..draws {
        let i = rng.random_range(0..n);
        let j = rng.random_range(0..n);
        let k = rng.random_range(0..n);
        if i == j || j == k || i == k {
            continue;
        }
        let (Some(ai), Some(aj), Some(ak), Some(bi), Some(bj), Some(bk)) =
            (a.get(i), a.get(j), a.get(k), b.get(i), b.get(j), b.get(k))
        else {
            continue;
        };
        let edges_agree = [(ai, aj, bi, bj), (aj, ak, bj, bk), (ak, ai, bk, bi)]
            .iter()
            .all(|(p, q, u, v)| {
                let (ls, lt) = ((*p - *q).norm(), (*u - *v).norm());
                ls.min(lt) >= ratio * ls.max(lt) && ls.min(lt) >= min_edge
            });
        if !edges_agree {
            continue;
        }
        let (sa, sb) = ([*ai, *aj, *ak], [*bi, *bj, *bk]);
        let Some(pose) = fit(&sa, &sb, |_| true) else {
            continue;
        };
        if sa
            .iter()
            .zip(&sb)
            .any(|(p, q)| (pose * p - q).norm_squared() >= d2)
        {
            continue;
        }
        scored += 1;
        let to_beat = best.map_or(MIN_INLIERS.saturating_sub(1), |x| x.inliers);
        let inliers = count(&pose, a, b, d2, to_beat);
        if inliers > to_beat {
            best = Some(Best {
                pose,
                inliers,
                scored: 0,
            });
        }
    }
    best.map(|x| Best { scored, ..x }).or(Some(Best {
        pose: Isometry3::identity(),
        inliers: 0,
        scored,
    }))
}

/// Estimates `T_target_source` from descriptor correspondences by RANSAC; `source_points`
/// and `target_points` are the points the correspondences index. `Ok(None)` when no
/// hypothesis gathers enough inliers (or there are fewer than 3 correspondences).
///
/// # Errors
/// [`IcpError::InvalidParameter`] for a bad configuration.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use sl_icp::{ransac_pose, Correspondence, RansacConfig};
/// let src: Vec<Point3<f64>> = (0..200).map(|i| Point3::new((i * 37 % 101) as f64, (i * 53 % 89) as f64, (i * 19 % 43) as f64)).collect();
/// let truth = Isometry3::new(Vector3::new(10.0, -4.0, 7.0), Vector3::new(0.3, 2.0, -1.0));
/// let tgt: Vec<Point3<f64>> = src.iter().map(|p| truth * p).collect();
/// // Half the matches right, half wrong.
/// let corr: Vec<Correspondence> = (0..200u32)
///     .map(|i| Correspondence { source: i, target: if i % 2 == 0 { i } else { (i * 7 + 3) % 200 }, ratio: 0.5 })
///     .collect();
/// let r = ransac_pose(&src, &tgt, &corr, &RansacConfig::default())?.expect("a pose");
/// assert!(r.inliers >= 100);
/// assert!((r.pose.translation.vector - truth.translation.vector).norm() < 1e-6);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
pub fn ransac_pose(
    source_points: &[Point3<f64>],
    target_points: &[Point3<f64>],
    correspondences: &[Correspondence],
    config: &RansacConfig,
) -> Result<Option<RansacResult>, IcpError> {
    config.validate()?;
    let (a, b): (Vec<Point3<f64>>, Vec<Point3<f64>>) = correspondences
        .iter()
        .filter_map(|c| {
            Some((
                *source_points.get(c.source as usize)?,
                *target_points.get(c.target as usize)?,
            ))
        })
        .unzip();
    let n = a.len();
    if n < 3 {
        return Ok(None);
    }
    let mut best: Option<Best> = None;
    let mut drawn = 0usize;
    let mut scored = 0usize;
    let mut next_batch = 0u64;
    while drawn < config.max_iterations {
        let round: Vec<(u64, usize)> = (0..BATCHES_PER_ROUND)
            .map_while(|_| {
                let left = config.max_iterations.saturating_sub(drawn);
                if left == 0 {
                    return None;
                }
                let draws = left.min(BATCH);
                drawn += draws;
                next_batch += 1;
                Some((next_batch - 1, draws))
            })
            .collect();
        let results: Vec<Option<Best>> = round
            .par_iter()
            .map(|&(number, draws)| batch(&a, &b, config, number, draws))
            .collect();
        for r in results {
            scored += r.map_or(0, |x| x.scored);
            best = better(best, r.filter(|x| x.inliers > 0));
        }
        // Iterations needed for `confidence` at the best inlier ratio so far.
        if let Some(x) = best {
            let w = x.inliers as f64 / n as f64;
            let all_in = w * w * w;
            let needed = if all_in >= 1.0 {
                0.0
            } else {
                (1.0 - config.confidence).ln() / (1.0 - all_in).ln()
            };
            if (drawn as f64) >= needed {
                break;
            }
        }
    }
    let Some(found) = best.filter(|x| x.inliers >= MIN_INLIERS) else {
        return Ok(None);
    };
    let d2 = config.inlier_distance * config.inlier_distance;
    let mut pose = found.pose;
    let mut inliers = found.inliers;
    for _ in 0..REFINEMENTS {
        let keep: Vec<bool> = a
            .iter()
            .zip(&b)
            .map(|(p, q)| (pose * p - q).norm_squared() < d2)
            .collect();
        let Some(refined) = fit(&a, &b, |k| keep.get(k).copied().unwrap_or(false)) else {
            break;
        };
        let c = count(&refined, &a, &b, d2, 0);
        if c < inliers {
            break;
        }
        pose = refined;
        inliers = c;
    }
    Ok(Some(RansacResult {
        pose,
        inliers,
        correspondences: n,
        iterations: drawn,
        scored,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn scene() -> (Vec<Point3<f64>>, Vec<Point3<f64>>, Isometry3<f64>) {
        let src: Vec<Point3<f64>> = (0..500)
            .map(|i| {
                Point3::new(
                    (i * 37 % 101) as f64,
                    (i * 53 % 89) as f64,
                    (i * 19 % 43) as f64,
                )
            })
            .collect();
        let truth = Isometry3::new(Vector3::new(10.0, -4.0, 7.0), Vector3::new(0.3, 2.0, -1.0));
        let tgt = src.iter().map(|p| truth * p).collect();
        (src, tgt, truth)
    }

    #[test]
    fn finds_the_pose_among_80_percent_outliers_the_same_for_any_thread_count() {
        let (src, tgt, truth) = scene();
        let corr: Vec<Correspondence> = (0..500u32)
            .map(|i| Correspondence {
                source: i,
                target: if i % 5 == 0 { i } else { (i * 7 + 3) % 500 },
                ratio: 0.5,
            })
            .collect();
        let config = RansacConfig::default();
        let r = ransac_pose(&src, &tgt, &corr, &config).unwrap().unwrap();
        assert!(r.inliers >= 100, "{r:?}");
        assert!(r.iterations < config.max_iterations, "early stop: {r:?}");
        assert!((r.pose.translation.vector - truth.translation.vector).norm() < 1e-6);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| ransac_pose(&src, &tgt, &corr, &config))
            .unwrap()
            .unwrap();
        assert_eq!(one, r);
        // Nothing consistent: no pose.
        let wrong: Vec<Correspondence> = (0..500u32)
            .map(|i| Correspondence {
                source: i,
                target: (i * 7 + 3) % 500,
                ratio: 0.5,
            })
            .collect();
        let few = RansacConfig {
            max_iterations: 5000,
            ..config
        };
        let none = ransac_pose(&src, &tgt, &wrong, &few).unwrap();
        assert!(none.as_ref().is_none_or(|x| x.inliers < 10), "{none:?}");
    }
}
