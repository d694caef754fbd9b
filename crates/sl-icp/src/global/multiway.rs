//! Multiway alignment of unordered clouds with no pose hints.
//!
//! 1. **Describe** every cloud once ([`GlobalCloud`], in parallel).
//! 2. **Candidate pairs by descriptor similarity**: each cloud is summarised by the mean of
//!    its FPFH histograms (a shape signature that does not move with the cloud); every cloud
//!    is paired with its [`MultiwayConfig::candidates_per_view`] most similar others.
//! 3. **Pairwise global registration** of the candidates ([`register_global_prepared`], in
//!    parallel), each **verified** by its overlap (ICP fitness) and residual (ICP RMSE).
//! 4. **Pose graph** over the verified edges: initial poses along a maximum-fitness spanning
//!    tree from view 0, then [`optimize_pose_graph`]. **Outlier edges are pruned** one at a
//!    time: while some edge disagrees with the optimised poses (RMS displacement of its
//!    source points between its measurement and the graph) by more than
//!    [`MultiwayConfig::max_edge_disagreement`], the edge whose removal leaves the most
//!    consistent graph (solved without each used edge in turn: most views placed, then the
//!    smallest worst disagreement) is removed and the graph solved again (a greedy form of
//!    switchable constraints: a switch is either on or off). A view held by exactly one right
//!    and one wrong edge is a tie no pruning can settle; it needs a third edge.
//! 5. **Joint refinement**: every surviving edge is re-registered by ICP from the graph's
//!    relative pose, and the graph solved once more with the new measurements.
//!
//! Views not tied to view 0 by surviving edges are left unplaced, each with why.

use std::collections::BTreeSet;

use nalgebra::Isometry3;
use rayon::prelude::*;

use crate::global::fpfh::FPFH_BINS;
use crate::global::pairwise::{
    GlobalCloud, GlobalConfig, GlobalRegistration, register_global_prepared,
};
use crate::{
    IcpConfig, IcpError, PointCloud, PoseError, PoseGraph, PoseGraphConfig, PoseGraphEdge,
    PoseGraphSolution, Registration, optimize_pose_graph, register,
};

/// Settings of [`align_unordered`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiwayConfig {
    /// Pairwise global registration (voxel size, descriptors, RANSAC, final ICP).
    pub global: GlobalConfig,
    /// Each view is registered with this many of its most similar others (by the mean of
    /// its descriptors). Default 4: a turntable view overlaps its two neighbours, a second
    /// placement two or three views of the first; with fewer than 6 views every pair is tried.
    pub candidates_per_view: usize,
    /// A pair is verified only if its final ICP pairs at least this fraction of the source's
    /// downsampled points (within the ICP gate). Default 0.25: the bunny's 90° pairs share
    /// about half their points, while a wrong alignment of two smooth scans rarely brings a
    /// fifth of the points within the 3 mm gate.
    pub min_fitness: f64,
    /// A pair is verified only if its final ICP RMSE is at most this, mm. Default 1.5 mm:
    /// three quarters of the 2 mm voxel; good pairs of the bunny reach about 0.9 mm, a slid
    /// alignment scatters its residuals over the whole 3 mm gate (RMS ≈ 1.7 mm).
    pub max_rmse: f64,
    /// An edge whose measurement moves its source points by more than this RMS from where the
    /// optimised graph puts them is an outlier and is pruned, mm. Default 3 mm, the ICP gate:
    /// a measurement off by more than the gate cannot be the ICP answer near the truth.
    pub max_edge_disagreement: f64,
    /// The ICP of the joint refinement, from the graph's relative poses on the downsampled
    /// clouds. `None` skips the refinement. Default: the pairwise final ICP.
    pub refine: Option<IcpConfig>,
    /// The pose-graph solver.
    pub pose_graph: PoseGraphConfig,
}

impl Default for MultiwayConfig {
    fn default() -> Self {
        let global = GlobalConfig::default();
        Self {
            global,
            candidates_per_view: 4,
            min_fitness: 0.25,
            max_rmse: 1.5,
            max_edge_disagreement: 3.0,
            refine: Some(global.icp),
            pose_graph: PoseGraphConfig::default(),
        }
    }
}

impl MultiwayConfig {
    /// Checks every field, naming the first one out of range.
    ///
    /// # Errors
    /// [`IcpError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), IcpError> {
        self.global.validate()?;
        if self.candidates_per_view == 0 {
            return Err(IcpError::invalid(
                "candidates_per_view",
                0,
                "each view needs at least one candidate partner",
            ));
        }
        if !(self.min_fitness >= 0.0 && self.min_fitness <= 1.0) {
            return Err(IcpError::invalid(
                "min_fitness",
                self.min_fitness,
                "must be in [0, 1]",
            ));
        }
        for (name, v) in [
            ("max_rmse", self.max_rmse),
            ("max_edge_disagreement", self.max_edge_disagreement),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(IcpError::invalid(name, v, "must be finite and > 0 (mm)"));
            }
        }
        if let Some(icp) = &self.refine {
            icp.validate()?;
        }
        Ok(())
    }
}

/// What became of one candidate pair.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiwayPair {
    /// The view registered onto `target`: of the two, the one with fewer downsampled
    /// points (the earlier input on a tie), so the direction does not follow the input order.
    pub source: usize,
    /// The view it was registered onto.
    pub target: usize,
    /// Distance of the two views' mean descriptors (smaller is more similar).
    pub descriptor_distance: f64,
    /// The pairwise global registration, when it produced a pose.
    pub registration: Option<GlobalRegistration>,
    /// Passed the overlap and residual checks.
    pub verified: bool,
    /// Verified but removed from the pose graph as an outlier edge.
    pub pruned: bool,
    /// Why the pair is not used (failed, not verified, pruned), or `None` when used.
    pub reason: Option<String>,
}

impl MultiwayPair {
    /// Whether the pair is an edge of the final pose graph.
    pub fn used(&self) -> bool {
        self.verified && !self.pruned
    }

    /// Fitness of the final pairwise ICP, if there was one.
    pub fn fitness(&self) -> Option<f64> {
        self.registration.as_ref().map(|r| r.registration.fitness)
    }

    /// RMSE of the final pairwise ICP (mm), if there was one.
    pub fn rmse(&self) -> Option<f64> {
        self.registration.as_ref().map(|r| r.registration.rmse)
    }
}

/// A view that could not be placed, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct UnplacedView {
    /// The view (0-based input index).
    pub view: usize,
    /// Why: its best pair and what was wrong with it, or why it could not be described.
    pub why: String,
}

/// Result of [`align_unordered`].
#[derive(Debug, Clone, PartialEq)]
pub struct MultiwayAlignment {
    /// `T_world_view` per input view (world = view 0's frame); `None` for unplaced views.
    pub poses: Vec<Option<Isometry3<f64>>>,
    /// Every candidate pair tried, sorted by (smaller index, larger index).
    pub pairs: Vec<MultiwayPair>,
    /// The views that could not be placed, with why.
    pub unplaced: Vec<UnplacedView>,
    /// The last pose-graph solve (over the placed views), if there were edges.
    pub pose_graph: Option<PoseGraphSolution>,
    /// Edges pruned as outliers.
    pub pruned_edges: usize,
}

/// Aligns clouds given in any order with no pose hints (see the module docs of `sl_icp::global` for the
/// steps). The world frame is view 0's. Views that cannot be tied to view 0 are listed in
/// [`MultiwayAlignment::unplaced`] with why; view 0 itself must be describable.
///
/// Deterministic for a given thread count; the relative poses do not depend on the order of
/// the inputs beyond numerical noise.
///
/// # Errors
/// [`IcpError::InvalidParameter`] for a bad configuration or fewer than two clouds; the errors
/// of [`GlobalCloud::new`] for view 0 (named `"view 0"`); the pose-graph errors.
pub fn align_unordered(
    clouds: &[PointCloud],
    config: &MultiwayConfig,
) -> Result<MultiwayAlignment, IcpError> {
    config.validate()?;
    let n = clouds.len();
    if n < 2 {
        return Err(IcpError::invalid(
            "clouds",
            n,
            "multiway alignment needs at least two clouds",
        ));
    }
    let described: Vec<Result<GlobalCloud, IcpError>> = clouds
        .par_iter()
        .enumerate()
        .map(|(i, c)| GlobalCloud::new(c, &config.global, &format!("view {i}")))
        .collect();
    let mut unplaced_why: Vec<Option<String>> = vec![None; n];
    let mut views: Vec<Option<GlobalCloud>> = Vec::with_capacity(n);
    for (i, d) in described.into_iter().enumerate() {
        match d {
            Ok(g) => views.push(Some(g)),
            Err(e) if i == 0 => return Err(e),
            Err(e) => {
                unplaced_why[i] = Some(format!("could not be described: {e}"));
                views.push(None);
            }
        }
    }

    let candidates = candidate_pairs(&views, config.candidates_per_view);
    let pairs: Vec<MultiwayPair> = candidates
        .par_iter()
        .map(|&(t, s, distance)| register_pair(&views, t, s, distance, config))
        .collect();
    let refs: Vec<Option<&GlobalCloud>> = views.iter().map(Option::as_ref).collect();
    place(&refs, pairs, &unplaced_why, config)
}

/// Places described views from pairs already registered: steps 4 and 5 of
/// [`align_unordered`] (the pose graph over the verified pairs with outlier-edge pruning, then
/// the joint refinement). `views` are the described clouds, view 0 the world frame; `pairs`
/// are what [`MultiwayAlignment::pairs`] holds — from an earlier run, or edited, dropped or
/// added (a pair is an edge when `verified`; its `registration` is the measurement; the
/// `pruned` flags are recomputed here).
///
/// # Errors
/// [`IcpError::InvalidParameter`] for a bad configuration, fewer than two views, or a pair
/// naming a view out of range or the same view twice; the pose-graph errors.
pub fn place_views(
    views: &[GlobalCloud],
    mut pairs: Vec<MultiwayPair>,
    config: &MultiwayConfig,
) -> Result<MultiwayAlignment, IcpError> {
    config.validate()?;
    let n = views.len();
    if n < 2 {
        return Err(IcpError::invalid(
            "views",
            n,
            "multiway alignment needs at least two views",
        ));
    }
    if let Some(p) = pairs
        .iter()
        .find(|p| p.source >= n || p.target >= n || p.source == p.target)
    {
        return Err(IcpError::invalid(
            "pairs",
            format!("view {} onto view {}", p.source, p.target),
            "each pair must join two different views among those given",
        ));
    }
    for p in &mut pairs {
        if p.pruned {
            p.pruned = false;
            p.reason = None;
        }
    }
    let refs: Vec<Option<&GlobalCloud>> = views.iter().map(Some).collect();
    place(&refs, pairs, &vec![None; n], config)
}

/// Steps 4 and 5 over validated pairs; `unplaced_why` names the views that could not be
/// described.
fn place(
    views: &[Option<&GlobalCloud>],
    mut pairs: Vec<MultiwayPair>,
    unplaced_why: &[Option<String>],
    config: &MultiwayConfig,
) -> Result<MultiwayAlignment, IcpError> {
    let n = views.len();
    // Pose graph with pruning of outlier edges.
    let mut pruned_edges = 0;
    let (poses, solution) = loop {
        let (poses, solution) = solve_graph(&pairs, n, config)?;
        let Some((k, disagreement)) = worst_edge(views, &pairs, &poses) else {
            break (poses, solution);
        };
        if disagreement <= config.max_edge_disagreement {
            break (poses, solution);
        }
        let k = edge_to_prune(views, &pairs, n, config)?.unwrap_or(k);
        pairs[k].pruned = true;
        pairs[k].reason = Some(format!(
            "pruned: the graph without it agrees best ({disagreement:.2} mm RMS worst \
             disagreement with it, limit {} mm)",
            config.max_edge_disagreement
        ));
        pruned_edges += 1;
    };

    // Joint refinement: re-register every surviving edge from the graph's relative pose.
    let (poses, solution) = match (&config.refine, solution) {
        (Some(icp), Some(_)) => {
            let refined: Vec<Option<Registration>> = pairs
                .par_iter()
                .map(|p| {
                    let (Some(ts), Some(tt)) = (poses[p.source], poses[p.target]) else {
                        return None;
                    };
                    if !p.used() {
                        return None;
                    }
                    let (vs, vt) = (views[p.source]?, views[p.target]?);
                    register(vs.prepared(), vt.prepared(), &(tt.inverse() * ts), icp).ok()
                })
                .collect();
            let edges = graph_edges(&pairs, &poses, Some(&refined));
            finish_graph(&poses, edges, config)?
        }
        (_, solution) => (poses, solution),
    };

    // Name the views left out.
    let mut unplaced = Vec::new();
    for (i, pose) in poses.iter().enumerate() {
        if pose.is_some() {
            continue;
        }
        let why = unplaced_why
            .get(i)
            .cloned()
            .flatten()
            .unwrap_or_else(|| why_unplaced(i, &pairs));
        unplaced.push(UnplacedView { view: i, why });
    }
    Ok(MultiwayAlignment {
        poses,
        pairs,
        unplaced,
        pose_graph: solution,
        pruned_edges,
    })
}

/// Mean FPFH histogram of a view: a shape signature unchanged by rigid motions.
fn signature(view: &GlobalCloud) -> [f64; FPFH_BINS] {
    let mut s = [0.0; FPFH_BINS];
    for f in view.features() {
        for (a, &b) in s.iter_mut().zip(f.iter()) {
            *a += f64::from(b);
        }
    }
    let n = view.features().len().max(1) as f64;
    s.iter_mut().for_each(|a| *a /= n);
    s
}

/// The candidate pairs `(i, j, distance)` with `i < j`, sorted: each
/// view with its `k` nearest others by signature distance (ties broken by index).
fn candidate_pairs(views: &[Option<GlobalCloud>], k: usize) -> Vec<(usize, usize, f64)> {
    let signatures: Vec<Option<[f64; FPFH_BINS]>> =
        views.iter().map(|v| v.as_ref().map(signature)).collect();
    let distance = |i: usize, j: usize| -> Option<f64> {
        let (a, b) = (signatures[i].as_ref()?, signatures[j].as_ref()?);
        Some(
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y) * (x - y))
                .sum::<f64>()
                .sqrt(),
        )
    };
    let mut set = BTreeSet::new();
    for i in 0..views.len() {
        let mut others: Vec<(f64, usize)> = (0..views.len())
            .filter(|&j| j != i)
            .filter_map(|j| distance(i, j).map(|d| (d, j)))
            .collect();
        others.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(_, j) in others.iter().take(k) {
            set.insert((i.min(j), i.max(j)));
        }
    }
    set.into_iter()
        .filter_map(|(t, s)| distance(t, s).map(|d| (t, s, d)))
        .collect()
}

fn register_pair(
    views: &[Option<GlobalCloud>],
    target: usize,
    source: usize,
    descriptor_distance: f64,
    config: &MultiwayConfig,
) -> MultiwayPair {
    let mut pair = MultiwayPair {
        source,
        target,
        descriptor_distance,
        registration: None,
        verified: false,
        pruned: false,
        reason: None,
    };
    let (Some(a), Some(b)) = (views[source].as_ref(), views[target].as_ref()) else {
        pair.reason = Some("a view could not be described".to_owned());
        return pair;
    };
    // The direction follows the clouds, not their input order (the smaller cloud is the
    // source), so that reordering the inputs registers the same way: ICP of a onto b is
    // not exactly the inverse of b onto a.
    let (source, target, s, t) = if (b.prepared().len(), target) < (a.prepared().len(), source) {
        (target, source, b, a)
    } else {
        (source, target, a, b)
    };
    pair.source = source;
    pair.target = target;
    let (sn, tn) = (format!("view {source}"), format!("view {target}"));
    match register_global_prepared(s, t, &config.global, (&sn, &tn)) {
        Err(e) => pair.reason = Some(e.to_string()),
        Ok(r) => {
            let (fitness, rmse) = (r.registration.fitness, r.registration.rmse);
            if fitness < config.min_fitness {
                pair.reason = Some(format!(
                    "overlap too small: fitness {fitness:.3} < {}",
                    config.min_fitness
                ));
            } else if rmse > config.max_rmse {
                pair.reason = Some(format!(
                    "residual too large: RMSE {rmse:.3} mm > {} mm",
                    config.max_rmse
                ));
            } else {
                pair.verified = true;
            }
            pair.registration = Some(r);
        }
    }
    pair
}

/// Initial poses along the maximum-fitness spanning tree of the used edges, from view 0
/// (Prim's algorithm; ties broken by pair order, so the tree is deterministic).
fn spanning_tree_poses(pairs: &[MultiwayPair], n: usize) -> Vec<Option<Isometry3<f64>>> {
    let mut poses: Vec<Option<Isometry3<f64>>> = vec![None; n];
    poses[0] = Some(Isometry3::identity());
    loop {
        let mut best: Option<(f64, usize, Isometry3<f64>)> = None;
        for p in pairs.iter().filter(|p| p.used()) {
            let Some(r) = &p.registration else { continue };
            let t_target_source = r.pose;
            let step = match (poses[p.target], poses[p.source]) {
                (Some(tt), None) => Some((p.source, tt * t_target_source)),
                (None, Some(ts)) => Some((p.target, ts * t_target_source.inverse())),
                _ => None,
            };
            if let Some((v, pose)) = step {
                let f = r.registration.fitness;
                if best.as_ref().is_none_or(|b| f > b.0) {
                    best = Some((f, v, pose));
                }
            }
        }
        match best {
            Some((_, v, pose)) => poses[v] = Some(pose),
            None => return poses,
        }
    }
}

/// The pose-graph edges of the used pairs between placed views, with the refined
/// registrations when given (else the pairwise ones).
fn graph_edges(
    pairs: &[MultiwayPair],
    poses: &[Option<Isometry3<f64>>],
    refined: Option<&[Option<Registration>]>,
) -> Vec<PoseGraphEdge> {
    pairs
        .iter()
        .enumerate()
        .filter(|(_, p)| p.used() && poses[p.source].is_some() && poses[p.target].is_some())
        .filter_map(|(k, p)| {
            let r = refined
                .and_then(|r| r.get(k).cloned().flatten())
                .or_else(|| p.registration.as_ref().map(|g| g.registration.clone()))?;
            Some(PoseGraphEdge {
                from: p.target,
                to: p.source,
                measurement: r.pose,
                information: r.information,
            })
        })
        .collect()
}

type GraphAnswer = (Vec<Option<Isometry3<f64>>>, Option<PoseGraphSolution>);

/// Spanning-tree start and one pose-graph solve over the placed views.
fn solve_graph(
    pairs: &[MultiwayPair],
    n: usize,
    config: &MultiwayConfig,
) -> Result<GraphAnswer, IcpError> {
    let poses = spanning_tree_poses(pairs, n);
    let edges = graph_edges(pairs, &poses, None);
    finish_graph(&poses, edges, config)
}

/// Solves the graph of the placed views (renumbered densely, view 0 first and fixed).
fn finish_graph(
    poses: &[Option<Isometry3<f64>>],
    edges: Vec<PoseGraphEdge>,
    config: &MultiwayConfig,
) -> Result<GraphAnswer, IcpError> {
    if edges.is_empty() {
        return Ok((poses.to_vec(), None));
    }
    let placed: Vec<usize> = (0..poses.len()).filter(|&i| poses[i].is_some()).collect();
    let mut dense = vec![usize::MAX; poses.len()];
    for (d, &i) in placed.iter().enumerate() {
        dense[i] = d;
    }
    let graph = PoseGraph {
        nodes: placed.iter().filter_map(|&i| poses[i]).collect(),
        edges: edges
            .into_iter()
            .map(|e| PoseGraphEdge {
                from: dense[e.from],
                to: dense[e.to],
                ..e
            })
            .collect(),
    };
    let solution = optimize_pose_graph(&graph, &config.pose_graph)?;
    let mut out = vec![None; poses.len()];
    for (d, &i) in placed.iter().enumerate() {
        out[i] = solution.nodes.get(d).copied();
    }
    Ok((out, Some(solution)))
}

/// The used edge whose removal leaves the most consistent graph (leave-one-out): for each
/// used edge, the graph is solved without it and scored by the views it still places (more is
/// better: an edge that alone ties a view is not removed while another will do) and then by
/// the worst disagreement of the remaining edges (smaller is better; ties to the earlier
/// pair). The edge that disagrees most with a solve that includes it is not always the wrong
/// one: a wrong edge pulls the least-squares poses so far that a right edge can disagree more.
/// `None` when no edge is used.
fn edge_to_prune(
    views: &[Option<&GlobalCloud>],
    pairs: &[MultiwayPair],
    n: usize,
    config: &MultiwayConfig,
) -> Result<Option<usize>, IcpError> {
    let used: Vec<usize> = (0..pairs.len()).filter(|&k| pairs[k].used()).collect();
    let scores: Vec<Result<(usize, usize, f64), IcpError>> = used
        .par_iter()
        .map(|&k| {
            let mut without = pairs.to_vec();
            without[k].pruned = true;
            let (poses, _) = solve_graph(&without, n, config)?;
            let placed = poses.iter().filter(|p| p.is_some()).count();
            let worst = worst_edge(views, &without, &poses).map_or(0.0, |w| w.1);
            Ok((k, placed, worst))
        })
        .collect();
    let mut best: Option<(usize, usize, f64)> = None;
    for score in scores {
        let (k, placed, worst) = score?;
        let better = best.is_none_or(|(_, p, w)| placed > p || (placed == p && worst < w));
        if better {
            best = Some((k, placed, worst));
        }
    }
    Ok(best.map(|b| b.0))
}

/// The used edge that disagrees most with `poses`: RMS displacement of its source's
/// downsampled points between its measurement and the graph's relative pose.
fn worst_edge(
    views: &[Option<&GlobalCloud>],
    pairs: &[MultiwayPair],
    poses: &[Option<Isometry3<f64>>],
) -> Option<(usize, f64)> {
    pairs
        .iter()
        .enumerate()
        .filter(|(_, p)| p.used())
        .filter_map(|(k, p)| {
            let (ts, tt) = (poses[p.source]?, poses[p.target]?);
            let r = p.registration.as_ref()?;
            let points = views[p.source]?.prepared().points();
            let e = PoseError::between(&(tt.inverse() * ts), &r.pose, points);
            Some((k, e.rms_displacement_mm))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
}

/// Why view `v` has no pose: its best pair (highest fitness) and what was wrong with it.
fn why_unplaced(v: usize, pairs: &[MultiwayPair]) -> String {
    let mine: Vec<&MultiwayPair> = pairs
        .iter()
        .filter(|p| p.source == v || p.target == v)
        .collect();
    if mine.is_empty() {
        return "no candidate pair (its descriptors resemble no other view's)".to_owned();
    }
    if let Some(p) = mine.iter().find(|p| p.used()) {
        let other = if p.source == v { p.target } else { p.source };
        return format!(
            "registered with view {other}, but that group of views is not tied to view 0"
        );
    }
    let best = mine
        .iter()
        .max_by(|a, b| {
            a.fitness()
                .unwrap_or(-1.0)
                .total_cmp(&b.fitness().unwrap_or(-1.0))
        })
        .copied();
    match best {
        Some(p) => {
            let other = if p.source == v { p.target } else { p.source };
            format!(
                "no pair verified; best with view {other}: {}",
                p.reason.as_deref().unwrap_or("not used")
            )
        }
        None => "no pair verified".to_owned(),
    }
}
