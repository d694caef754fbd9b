//! The 360° merge of a turntable scan: pairwise registration of neighbouring views, a loop
//! closure, the poses from the turntable model (or a free pose graph), then one merged,
//! downsampled cloud with normals.

use nalgebra::{Isometry3, Matrix6, Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::{KdIndex, MergePolicy, NormalConfig, PointCloud, VoxelGridConfig, voxel_downsample};

use crate::global::{GlobalCloud, GlobalConfig, register_global_prepared};
use crate::normals::{local_planes, quadric_projection};
use crate::pair_information::{FreeMotion, pair_information, settle_free_motions};
use crate::pose_graph::unreachable;
use crate::turntable_model::{AngleFrom, Turntable, fit_turntable_gated};
use crate::{
    IcpConfig, IcpError, Metric, NormalSource, PoseGraph, PoseGraphConfig, PoseGraphEdge,
    PoseGraphSolution, PoseModel, PrepareConfig, PreparedCloud, Registration, TurntableFit,
    optimize_pose_graph, register,
};

/// Settings of [`align_views`], [`merge_aligned`] and [`merge_views`]. Lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergeConfig {
    /// Voxel size the views are downsampled to for registration. Default 1 mm: ~10k points
    /// for a 100 mm object, plenty to pin 6 degrees of freedom, and fast.
    pub registration_voxel_size: f64,
    /// Normals of the downsampled views (when the views carry none). Default: 10 neighbours
    /// (as `small_gicp`'s covariances), facing the camera at each view's origin.
    pub registration_normals: NormalConfig,
    /// A first, coarse ICP pass for each pair, whose result starts `icp`; `None` to skip it.
    /// Default: generalized ICP with a 5 mm maximum distance, which absorbs the millimetre
    /// errors of turntable poses from a rough axis calibration.
    pub coarse_icp: Option<IcpConfig>,
    /// The pairwise ICP. Default: generalized ICP with a 1.5 mm maximum distance: tight enough
    /// that points the other view never saw (beyond its silhouette) do not pull the pose; on
    /// the virtual rig it halves the pose error of a 3 mm gate, and generalized ICP is 3 to
    /// 5 times more accurate than point-to-plane on views downsampled on different grids.
    pub icp: IcpConfig,
    /// Each view is registered onto the previous `neighbours` views (1 = a chain). Default 1.
    pub neighbours: usize,
    /// Also register the first view onto the last one, closing the ring (needs 3 views or
    /// more). Default true: a full turn.
    pub loop_closure: bool,
    /// Pairs whose fitness is below this are left out of the pose graph (reported as unused).
    /// Default 0.3: neighbouring views 10° apart overlap by more than 80 %.
    pub min_fitness: f64,
    /// The pose-graph optimisation (of [`PoseModel::Free`]).
    pub pose_graph: PoseGraphConfig,
    /// How the registrations become poses. Default: the turntable model with the default
    /// priors ([`PoseModel::default`]): the calibrated turntable, kept where the
    /// registrations agree with it and corrected where they do not; [`PoseModel::Free`] for
    /// a free 6-degree-of-freedom pose graph.
    pub pose_model: PoseModel,
    /// Voxel size of the merged cloud; `None` keeps every point. Default 0.5 mm: averages the
    /// 10 to 40 overlapping samples of a dense 36-view scan, about the scanner's resolution.
    pub output_voxel_size: Option<f64>,
    /// Neighbours for the normals of the merged cloud (oriented toward the cameras that saw
    /// each point); 0 for no normals. Default 16.
    pub output_normal_neighbours: usize,
    /// Average overlapping points across the surface: move each merged point along its normal
    /// onto the least-squares quadratic surface of its `output_normal_neighbours` neighbours
    /// (moving least squares of degree 2: averages the noise of overlapping views without
    /// flattening curved parts or shrinking the surface sideways). Needs normals. Default
    /// false.
    pub average_overlaps: bool,
    /// Global registration (descriptors and RANSAC, no initial pose) for a pair whose ICP
    /// from the initial poses fails or stays below `min_fitness`, as when a turntable view
    /// sits far from its nominal angle; its pose is then refined by `icp`. `None` turns the
    /// fallback off. Default: [`GlobalConfig::default`] (2 mm voxels).
    pub global_fallback: Option<GlobalConfig>,
}

impl Default for MergeConfig {
    fn default() -> Self {
        Self {
            registration_voxel_size: 1.0,
            registration_normals: NormalConfig {
                k: 10,
                ..NormalConfig::default()
            },
            coarse_icp: Some(IcpConfig {
                metric: Metric::Generalized,
                max_correspondence_distance: 5.0,
                ..IcpConfig::default()
            }),
            icp: IcpConfig {
                metric: Metric::Generalized,
                max_correspondence_distance: 1.5,
                ..IcpConfig::default()
            },
            neighbours: 1,
            loop_closure: true,
            min_fitness: 0.3,
            pose_graph: PoseGraphConfig::default(),
            pose_model: PoseModel::default(),
            output_voxel_size: Some(0.5),
            output_normal_neighbours: 16,
            average_overlaps: false,
            global_fallback: Some(GlobalConfig::default()),
        }
    }
}

impl MergeConfig {
    fn validate(&self) -> Result<(), IcpError> {
        self.icp.validate()?;
        if let Some(g) = &self.global_fallback {
            g.validate()?;
        }
        if let Some(c) = &self.coarse_icp {
            c.validate()?;
        }
        let v = self.registration_voxel_size;
        if !(v > 0.0 && v.is_finite()) {
            return Err(IcpError::invalid(
                "registration_voxel_size",
                v,
                "must be finite and > 0",
            ));
        }
        if let Some(v) = self.output_voxel_size
            && !(v.is_finite() && v > 0.0)
        {
            return Err(IcpError::invalid(
                "output_voxel_size",
                v,
                "must be finite and > 0 (or None)",
            ));
        }
        if let PoseModel::Turntable(prior) = &self.pose_model {
            prior.validate()?;
        }
        if self.neighbours == 0 {
            return Err(IcpError::invalid("neighbours", 0, "must be at least 1"));
        }
        if !(0.0..=1.0).contains(&self.min_fitness) {
            return Err(IcpError::invalid(
                "min_fitness",
                self.min_fitness,
                "must be in [0, 1]",
            ));
        }
        let k = self.output_normal_neighbours;
        if k != 0 && k < 3 {
            return Err(IcpError::invalid(
                "output_normal_neighbours",
                k,
                "must be 0 (no normals) or at least 3",
            ));
        }
        if self.average_overlaps && k == 0 {
            return Err(IcpError::invalid(
                "average_overlaps",
                true,
                "needs output_normal_neighbours > 0 (the averaging fits the neighbourhoods)",
            ));
        }
        Ok(())
    }
}

/// One pairwise registration of a merge.
#[derive(Debug, Clone, PartialEq)]
pub struct PairRegistration {
    /// The target view (its frame holds the measurement).
    pub target: usize,
    /// The source view.
    pub source: usize,
    /// The registration (`pose` is `T_target_source`), or `None` if it failed.
    pub registration: Option<Registration>,
    /// Why it failed, if it did.
    pub failure: Option<String>,
    /// Whether it entered the pose graph (succeeded with enough fitness).
    pub used: bool,
    /// Whether the pose came from the global-registration fallback
    /// ([`MergeConfig::global_fallback`]) because ICP from the initial poses failed; `failure`
    /// then still says why that ICP failed when the fallback failed too.
    pub global: bool,
    /// The motions this registration does not measure (its surfaces barely change under
    /// them: a sphere turning about its centre, a bar about its axis), in the target view's
    /// frame. The turntable model gives its pose no weight along them; empty for a failed
    /// pair.
    pub free_motions: Vec<FreeMotion>,
}

/// Result of [`align_views`].
#[derive(Debug, Clone, PartialEq)]
pub struct ViewAlignment {
    /// Optimised `T_world_view` (world = frame of view 0).
    pub poses: Vec<Isometry3<f64>>,
    /// Every pairwise registration tried, in order.
    pub pairs: Vec<PairRegistration>,
    /// The optimisation: the pose graph's, or the turntable model's (its nodes are then
    /// `poses`, its costs include the priors).
    pub pose_graph: PoseGraphSolution,
    /// The fitted turntable model, when [`PoseModel::Turntable`] was used.
    pub turntable: Option<TurntableFit>,
    /// Which constraint each view's pose came from, one per view.
    pub sources: Vec<ViewPoseSource>,
}

/// Which constraint a view's pose came from in [`align_views`].
#[derive(Debug, Clone, PartialEq)]
pub enum ViewPoseSource {
    /// View 0: it defines the world frame.
    Reference,
    /// The calibrated turntable (the axis of [`TurntableFit::axis`] and the motor reading
    /// times [`TurntableFit::angle_scale`]), which the view's registrations confirm.
    Turntable,
    /// The calibrated turntable alone: the view's registrations do not measure its angle
    /// (they failed, or are degenerate about the turntable's rotation); `why` says which.
    TurntablePriorOnly {
        /// The view's pairs and what each left free or why it failed.
        why: String,
    },
    /// The view's angle from its registrations: they put it `motor_off_deg` away from the
    /// motor reading, `sigmas` standard deviations (beyond the gate), so the reading is
    /// overruled. The axis is still [`TurntableFit::axis`].
    Registrations {
        /// Registered angle minus the motor reading (× the angle scale), degrees.
        motor_off_deg: f64,
        /// That difference in standard deviations (infinite without an angle prior).
        sigmas: f64,
    },
    /// The free pose graph ([`PoseModel::Free`], or initial poses that are not a
    /// turntable's): a 6-degree-of-freedom pose from the registrations.
    PoseGraph,
}

impl ViewAlignment {
    /// One line saying where the poses came from, e.g. "36 views: axis from the calibration
    /// (confirmed, 1.2 σ), angle scale 1 (confirmed); 35 angles from the motor (confirmed by
    /// the registrations); view 17: turntable prior only (with view 16: degenerate: rotation
    /// about …)".
    pub fn pose_summary(&self) -> String {
        let n = self.sources.len();
        let Some(fit) = &self.turntable else {
            return format!("{n} views: free pose graph (6 degrees of freedom per view)");
        };
        let axis = if fit.axis_confirmed {
            format!(
                "axis from the calibration (confirmed by the registrations, {:.1} σ)",
                fit.axis_distance
            )
        } else if fit.axis_distance.is_finite() {
            format!(
                "axis from the registrations (the calibration is {:.1} σ off)",
                fit.axis_distance
            )
        } else {
            "axis from the registrations (no axis prior)".to_owned()
        };
        let scale = if fit.angle_scale_corrected {
            format!("angle scale corrected to {:.6}", fit.angle_scale)
        } else {
            "angle scale 1".to_owned()
        };
        let motor = self
            .sources
            .iter()
            .filter(|s| matches!(s, ViewPoseSource::Turntable))
            .count();
        let mut parts = vec![format!(
            "{n} views: {axis}, {scale}; {motor} angles from the motor (confirmed by the registrations)"
        )];
        for (k, s) in self.sources.iter().enumerate() {
            match s {
                ViewPoseSource::TurntablePriorOnly { why } => {
                    parts.push(format!("view {k}: turntable prior only ({why})"));
                }
                ViewPoseSource::Registrations {
                    motor_off_deg,
                    sigmas,
                } => parts.push(format!(
                    "view {k}: angle from the registrations (motor reading {motor_off_deg:+.3}° off, {sigmas:.1} σ)"
                )),
                _ => {}
            }
        }
        parts.join("; ")
    }
}

/// Result of [`merge_views`].
#[derive(Debug, Clone, PartialEq)]
pub struct MergedScan {
    /// The merged cloud in the world frame (view 0's), mm.
    pub cloud: PointCloud,
    /// How the views were aligned.
    pub alignment: ViewAlignment,
}

/// The pairs `(target, source)` to register: each view onto its `neighbours` predecessors,
/// plus the ring closure.
fn pair_list(n: usize, neighbours: usize, loop_closure: bool) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    for j in 1..n {
        for s in 1..=neighbours.min(j) {
            pairs.push((j - s, j));
        }
    }
    if loop_closure && n >= 3 {
        // Wrap-around pairs, e.g. (n-1, 0) for a chain.
        for i in (n.saturating_sub(neighbours))..n {
            for s in 1..=neighbours {
                let j = i + s;
                if j >= n && j - n < i && !pairs.contains(&(i, j - n)) {
                    pairs.push((i, j - n));
                }
            }
        }
    }
    pairs
}

/// Registers the views of a turntable scan with one another and optimises their poses.
///
/// `initial[i]` is `T_world_view_i`, e.g. from [`turntable_poses`](crate::turntable_poses).
/// The views are downsampled and given normals, each is registered onto its predecessor(s)
/// starting from the relative initial pose, the last onto the first if `loop_closure`, and a
/// pose graph (node 0 fixed) reconciles the pairwise results.
///
/// # Errors
/// [`IcpError::ViewPoseCount`], [`IcpError::EmptyCloud`] naming the view,
/// [`IcpError::InvalidParameter`], [`IcpError::PoseGraphDisconnected`] when failed or weak
/// pairs leave a view unconnected.
pub fn align_views(
    views: &[PointCloud],
    initial: &[Isometry3<f64>],
    config: &MergeConfig,
) -> Result<ViewAlignment, IcpError> {
    config.validate()?;
    if views.len() != initial.len() {
        return Err(IcpError::ViewPoseCount {
            views: views.len(),
            poses: initial.len(),
        });
    }
    let prep = PrepareConfig {
        voxel_size: Some(config.registration_voxel_size),
        normals: NormalSource::FromCloudOrEstimate(config.registration_normals),
    };
    let prepared: Vec<PreparedCloud> = views
        .par_iter()
        .map(|v| PreparedCloud::new(v, &prep))
        .collect::<Result<_, _>>()?;
    if let Some(i) = prepared.iter().position(PreparedCloud::is_empty) {
        return Err(IcpError::EmptyCloud {
            cloud: format!("view {i}"),
        });
    }
    let pairs: Vec<PairRegistration> =
        pair_list(views.len(), config.neighbours, config.loop_closure)
            .into_par_iter()
            .map(|(t, s)| {
                let (Some(target), Some(source), Some(pt), Some(ps)) = (
                    prepared.get(t),
                    prepared.get(s),
                    initial.get(t),
                    initial.get(s),
                ) else {
                    return PairRegistration {
                        target: t,
                        source: s,
                        registration: None,
                        failure: Some("view index out of range".into()),
                        used: false,
                        global: false,
                        free_motions: Vec::new(),
                    };
                };
                let start = pt.inverse() * ps;
                match register(source, target, &start, &config.icp) {
                    Ok(r) => PairRegistration {
                        target: t,
                        source: s,
                        used: r.fitness >= config.min_fitness,
                        failure: (r.fitness < config.min_fitness).then(|| {
                            format!(
                                "fitness {:.3} below min_fitness {:.3}",
                                r.fitness, config.min_fitness
                            )
                        }),
                        registration: Some(r),
                        global: false,
                        free_motions: Vec::new(),
                    },
                    Err(e) => PairRegistration {
                        target: t,
                        source: s,
                        registration: None,
                        failure: Some(e.to_string()),
                        used: false,
                        global: false,
                        free_motions: Vec::new(),
                    },
                }
            })
            .collect();
    let mut pairs = match &config.global_fallback {
        Some(global) => with_global_fallback(views, &prepared, pairs, global, config),
        None => pairs,
    };
    if !pairs.iter().any(|p| p.used) {
        return Err(IcpError::ViewsNotPlaced {
            views: (1..views.len()).collect(),
            why: "no pair of views registered (every pair failed or stayed below min_fitness)"
                .to_owned(),
            pairs,
        });
    }
    // What each used registration measures along the normals, and what it leaves free.
    let gate = config.icp.max_correspondence_distance;
    let plane: Vec<Option<Matrix6<f64>>> = pairs
        .par_iter_mut()
        .map(|p| {
            let (Some(r), Some(s), Some(t)) = (
                p.registration.as_ref().filter(|_| p.used),
                prepared.get(p.source),
                prepared.get(p.target),
            ) else {
                return None;
            };
            let info = pair_information(s, t, &r.pose, gate)?;
            p.free_motions = info.free;
            Some(info.information)
        })
        .collect();
    let edges: Vec<PoseGraphEdge> = pairs
        .iter()
        .filter(|p| p.used)
        .filter_map(|p| {
            p.registration.as_ref().map(|r| PoseGraphEdge {
                from: p.target,
                to: p.source,
                measurement: r.pose,
                information: r.information,
            })
        })
        .collect();
    // A pair placed by the global fallback contradicts the initial poses beyond ICP's reach:
    // they are no turntable prior to hold views to, so the free pose graph places the views.
    let fallback_used = pairs.iter().any(|p| p.used && p.global);
    let free_or_unanchored = match &config.pose_model {
        PoseModel::Free => true,
        PoseModel::Turntable(prior) => prior.angle_sigma_deg.is_none() || fallback_used,
    };
    if free_or_unanchored {
        let lost = unreachable_all(views.len(), &edges);
        if !lost.is_empty() {
            let why = lost
                .iter()
                .map(|&v| format!("view {v}: {}", why_not_placed(v, &pairs)))
                .collect::<Vec<_>>()
                .join("; ");
            return Err(IcpError::ViewsNotPlaced {
                views: lost,
                why,
                pairs,
            });
        }
    }
    // A pose from the fallback contradicts the initial poses: start the graph from the
    // registrations themselves (along a spanning tree), or it may not reach them.
    let nodes = if pairs.iter().any(|p| p.used && p.global) {
        chained_poses(initial, &pairs)
    } else {
        initial.to_vec()
    };
    let graph = PoseGraph { nodes, edges };
    let calibrated = match &config.pose_model {
        PoseModel::Turntable(prior) if !fallback_used => {
            let centre = prepared
                .first()
                .map_or_else(Point3::origin, PreparedCloud::centroid);
            Turntable::from_poses(initial, &centre).map(|t| (t, *prior))
        }
        PoseModel::Turntable(_) | PoseModel::Free => None,
    };
    let Some((calibrated, prior)) = calibrated else {
        let pose_graph = optimize_pose_graph(&graph, &config.pose_graph)?;
        let sources = (0..views.len())
            .map(|k| {
                if k == 0 {
                    ViewPoseSource::Reference
                } else {
                    ViewPoseSource::PoseGraph
                }
            })
            .collect();
        return Ok(ViewAlignment {
            poses: pose_graph.nodes.clone(),
            pairs,
            pose_graph,
            turntable: None,
            sources,
        });
    };
    // Without an angle prior, a view no registration reaches has a free angle.
    if prior.angle_sigma_deg.is_none()
        && let Some(node) = unreachable(graph.nodes.len(), &graph.edges)
    {
        return Err(IcpError::PoseGraphDisconnected { node });
    }
    // The turntable model weighs each registration by what it measures along the normals, and
    // takes what it leaves free from the calibrated turntable.
    let plane_edges: Vec<PoseGraphEdge> = pairs
        .iter()
        .zip(&plane)
        .filter(|(p, _)| p.used)
        .filter_map(|(p, info)| {
            let model = initial.get(p.target)?.inverse() * initial.get(p.source)?;
            Some(PoseGraphEdge {
                from: p.target,
                to: p.source,
                measurement: settle_free_motions(
                    &p.registration.as_ref()?.pose,
                    &model,
                    &p.free_motions,
                ),
                information: (*info)?,
            })
        })
        .collect();
    let fit = fit_turntable_gated(&calibrated, &plane_edges, &prior);
    let poses = fit.solution.turntable.poses();
    let sources = fit
        .angles_from
        .iter()
        .enumerate()
        .map(|(k, a)| match a {
            AngleFrom::Reference => ViewPoseSource::Reference,
            AngleFrom::Motor => ViewPoseSource::Turntable,
            AngleFrom::MotorUnconstrained => ViewPoseSource::TurntablePriorOnly {
                why: why_unconstrained(k, &pairs),
            },
            AngleFrom::Registrations { off_deg, sigmas } => ViewPoseSource::Registrations {
                motor_off_deg: *off_deg,
                sigmas: *sigmas,
            },
        })
        .collect();
    Ok(ViewAlignment {
        poses: poses.clone(),
        pairs,
        pose_graph: PoseGraphSolution {
            nodes: poses,
            initial_cost: fit.solution.initial_cost,
            final_cost: fit.solution.final_cost,
            iterations: fit.solution.iterations,
            converged: fit.solution.converged,
        },
        turntable: Some(TurntableFit {
            initial_axis: calibrated.axis(),
            registered_axis: fit.registered.axis(),
            axis: fit.solution.turntable.axis(),
            axis_confirmed: fit.axis_confirmed,
            axis_distance: fit.axis_distance,
            variance_factor: fit.variance_factor,
            angle_scale_corrected: fit.scale_corrected,
            angle_scale: fit.solution.angle_scale,
            initial_angles_deg: calibrated.angles.iter().map(|a| a.to_degrees()).collect(),
            angles_deg: fit
                .solution
                .turntable
                .angles
                .iter()
                .map(|a| a.to_degrees())
                .collect(),
        }),
        sources,
    })
}

/// Why the registrations of view `v` do not measure its angle: each of its pairs, failed or
/// with the motions it leaves free.
fn why_unconstrained(v: usize, pairs: &[PairRegistration]) -> String {
    let mine: Vec<String> = pairs
        .iter()
        .filter(|p| p.source == v || p.target == v)
        .map(|p| {
            let other = if p.source == v { p.target } else { p.source };
            match (&p.failure, p.used) {
                (Some(f), _) => format!("with view {other}: failed, {f}"),
                (None, true) if p.free_motions.is_empty() => {
                    format!("with view {other}: weak")
                }
                (None, true) => format!(
                    "with view {other}: degenerate about {}",
                    p.free_motions
                        .iter()
                        .map(ToString::to_string)
                        .collect::<Vec<_>>()
                        .join(" and ")
                ),
                (None, false) => format!("with view {other}: not used"),
            }
        })
        .collect();
    if mine.is_empty() {
        "no registration".to_owned()
    } else {
        format!("registrations {}", mine.join(", "))
    }
}

/// Retries the failed pairs by global registration (each view described once, in parallel),
/// refining the global pose with `config.icp` on the merge's prepared clouds.
fn with_global_fallback(
    views: &[PointCloud],
    prepared: &[PreparedCloud],
    mut pairs: Vec<PairRegistration>,
    global: &GlobalConfig,
    config: &MergeConfig,
) -> Vec<PairRegistration> {
    let failed: Vec<usize> = (0..pairs.len()).filter(|&k| !pairs[k].used).collect();
    if failed.is_empty() {
        return pairs;
    }
    let mut needed: Vec<usize> = failed
        .iter()
        .flat_map(|&k| [pairs[k].source, pairs[k].target])
        .collect();
    needed.sort_unstable();
    needed.dedup();
    let described: Vec<(usize, Result<GlobalCloud, IcpError>)> = needed
        .par_iter()
        .filter_map(|&v| {
            let cloud = views.get(v)?;
            Some((v, GlobalCloud::new(cloud, global, &format!("view {v}"))))
        })
        .collect();
    let cloud_of = |v: usize| -> Result<&GlobalCloud, String> {
        match described.iter().find(|(i, _)| *i == v) {
            Some((_, Ok(g))) => Ok(g),
            Some((_, Err(e))) => Err(e.to_string()),
            None => Err(format!("view {v} does not exist")),
        }
    };
    let retried: Vec<(usize, Result<Registration, String>)> = failed
        .par_iter()
        .map(|&k| {
            let (s, t) = (pairs[k].source, pairs[k].target);
            let attempt = || -> Result<Registration, String> {
                let (gs, gt) = (cloud_of(s)?, cloud_of(t)?);
                let (sn, tn) = (format!("view {s}"), format!("view {t}"));
                let g = register_global_prepared(gs, gt, global, (&sn, &tn))
                    .map_err(|e| e.to_string())?;
                let (Some(ps), Some(pt)) = (prepared.get(s), prepared.get(t)) else {
                    return Err("view index out of range".to_owned());
                };
                register(ps, pt, &g.pose, &config.icp).map_err(|e| e.to_string())
            };
            (k, attempt())
        })
        .collect();
    for (k, result) in retried {
        let p = &mut pairs[k];
        let before = p.failure.clone().unwrap_or_default();
        match result {
            Ok(r) if r.fitness >= config.min_fitness => {
                p.used = true;
                p.global = true;
                p.failure = None;
                p.registration = Some(r);
            }
            Ok(r) => {
                p.failure = Some(format!(
                    "{before}; global registration: fitness {:.3} below min_fitness {:.3}",
                    r.fitness, config.min_fitness
                ));
                if p.registration
                    .as_ref()
                    .is_none_or(|old| old.fitness < r.fitness)
                {
                    p.registration = Some(r);
                    p.global = true;
                }
            }
            Err(e) => p.failure = Some(format!("{before}; global registration: {e}")),
        }
    }
    pairs
}

/// Every node that no chain of `edges` ties to node 0, in order.
fn unreachable_all(n: usize, edges: &[PoseGraphEdge]) -> Vec<usize> {
    let mut seen = vec![false; n];
    let mut stack = vec![0usize];
    if let Some(s) = seen.get_mut(0) {
        *s = true;
    }
    while let Some(k) = stack.pop() {
        for e in edges {
            let other = match (e.from == k, e.to == k) {
                (true, _) => e.to,
                (_, true) => e.from,
                _ => continue,
            };
            if let Some(s) = seen.get_mut(other)
                && !*s
            {
                *s = true;
                stack.push(other);
            }
        }
    }
    (0..n).filter(|&i| !seen[i]).collect()
}

/// Why view `v` is not placed: the failures of its pairs.
fn why_not_placed(v: usize, pairs: &[PairRegistration]) -> String {
    let mine: Vec<String> = pairs
        .iter()
        .filter(|p| p.source == v || p.target == v)
        .map(|p| {
            let other = if p.source == v { p.target } else { p.source };
            match (&p.failure, p.used) {
                (Some(f), _) => format!("with view {other}: {f}"),
                (None, true) => format!("with view {other}: registered, but not tied to view 0"),
                (None, false) => format!("with view {other}: not used"),
            }
        })
        .collect();
    if mine.is_empty() {
        "no pair was tried".to_owned()
    } else {
        mine.join(", ")
    }
}

/// Initial poses along the used pairs (a maximum-fitness spanning tree from view 0); views
/// they do not reach keep `initial`.
fn chained_poses(initial: &[Isometry3<f64>], pairs: &[PairRegistration]) -> Vec<Isometry3<f64>> {
    let n = initial.len();
    let mut placed: Vec<Option<Isometry3<f64>>> = vec![None; n];
    if let Some(p) = placed.first_mut() {
        *p = initial.first().copied();
    }
    loop {
        let mut best: Option<(f64, usize, Isometry3<f64>)> = None;
        for p in pairs.iter().filter(|p| p.used) {
            let Some(r) = &p.registration else { continue };
            let (Some(&tt), Some(&ts)) = (placed.get(p.target), placed.get(p.source)) else {
                continue;
            };
            let step = match (tt, ts) {
                (Some(tt), None) => Some((p.source, tt * r.pose)),
                (None, Some(ts)) => Some((p.target, ts * r.pose.inverse())),
                _ => None,
            };
            if let Some((v, pose)) = step
                && best.as_ref().is_none_or(|b| r.fitness > b.0)
            {
                best = Some((r.fitness, v, pose));
            }
        }
        match best {
            Some((_, v, pose)) => placed[v] = Some(pose),
            None => break,
        }
    }
    placed
        .iter()
        .zip(initial)
        .map(|(p, i)| p.unwrap_or(*i))
        .collect()
}

/// Merges views already aligned by `poses` (`T_world_view`): moves them into the world frame,
/// concatenates them, downsamples on `output_voxel_size` (which averages the overlapping
/// points of each voxel) and estimates normals, oriented toward the cameras that saw each
/// point (each view's origin, or its own normals when it carries some). Colours and quality
/// are kept when every view has them.
///
/// # Errors
/// [`IcpError::ViewPoseCount`], [`IcpError::InvalidParameter`].
pub fn merge_aligned(
    views: &[PointCloud],
    poses: &[Isometry3<f64>],
    config: &MergeConfig,
) -> Result<PointCloud, IcpError> {
    config.validate()?;
    if views.len() != poses.len() {
        return Err(IcpError::ViewPoseCount {
            views: views.len(),
            poses: poses.len(),
        });
    }
    // Each view in the world frame, with its "normals" slot holding the direction toward its
    // camera (or its own normals): averaged by the voxel grid, this orients the final normals.
    let moved: Vec<PointCloud> = views
        .par_iter()
        .zip(poses.par_iter())
        .map(|(view, pose)| {
            let (positions, normals, colors, quality) = view.clone().into_parts();
            let reference: Vec<Vector3<f64>> = match normals {
                Some(n) => n,
                None => positions
                    .iter()
                    .map(|p| {
                        (Point3::origin() - p)
                            .try_normalize(0.0)
                            .unwrap_or_default()
                    })
                    .collect(),
            };
            let mut c = PointCloud::from_parts(positions, Some(reference), colors, quality)?;
            c.transform(pose);
            Ok(c.remove_non_finite())
        })
        .collect::<Result<_, IcpError>>()?;
    let mut merged = PointCloud::new();
    for c in &moved {
        merged.extend(c, MergePolicy::DropMismatched)?;
    }
    drop(moved);
    let merged = match config.output_voxel_size {
        Some(size) => voxel_downsample(&merged, &VoxelGridConfig { voxel_size: size })?.cloud,
        None => merged,
    };
    let k = config.output_normal_neighbours;
    let (mut positions, reference, colors, quality) = merged.into_parts();
    if k == 0 {
        return Ok(PointCloud::from_parts(positions, None, colors, quality)?);
    }
    let tree = KdIndex::new(&positions)?;
    let frames = if config.average_overlaps {
        quadric_projection(&positions, &tree, k)
    } else {
        local_planes(&positions, &tree, k)
            .into_iter()
            .zip(&positions)
            .map(|((n, _), p)| (n, *p))
            .collect()
    };
    let reference = reference.unwrap_or_default();
    let normals: Vec<Vector3<f64>> = frames
        .iter()
        .zip(positions.iter_mut())
        .enumerate()
        .map(|(i, ((n, moved), p))| {
            let toward = reference.get(i).copied().unwrap_or_default();
            *p = *moved;
            if n.dot(&toward) < 0.0 { -n } else { *n }
        })
        .collect();
    Ok(PointCloud::from_parts(
        positions,
        Some(normals),
        colors,
        quality,
    )?)
}

/// Registers and merges the views of a turntable scan: [`align_views`] then
/// [`merge_aligned`].
///
/// # Errors
/// As [`align_views`] and [`merge_aligned`].
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use sl_icp::{merge_views, turntable_poses, MergeConfig, PointCloud, TurntableAxis};
/// // A lumpy object on a turntable whose axis is the camera's -y through (0, 0, 300 mm),
/// // seen at 0°, 120° and 240° (each view: the points of the near half).
/// let axis = TurntableAxis::new(-Vector3::y(), Point3::new(0.0, 0.0, 300.0))?;
/// let surface = |u: f64, v: f64| {
///     let r = 40.0 + 6.0 * (3.0 * u).sin() * v.cos() + 4.0 * (2.0 * v).cos();
///     Point3::new(r * v.cos() * u.cos(), r * v.sin(), 300.0 + r * v.cos() * u.sin())
/// };
/// let angles = [0.0, 120.0, 240.0];
/// let views: Vec<PointCloud> = angles.iter().map(|&a| {
///     let m = axis.motion(a);
///     let pts = (0..120).flat_map(|i| (0..60).map(move |j| (i, j))).map(|(i, j)| {
///         m * surface(i as f64 * std::f64::consts::TAU / 120.0, (j as f64 / 60.0 - 0.5) * 2.6)
///     }).filter(|p| p.z < 300.0 + 10.0).collect();
///     PointCloud::from_positions(pts)
/// }).collect();
/// let initial = turntable_poses(&axis, &angles)?;
/// let config = MergeConfig { output_voxel_size: Some(2.0), ..MergeConfig::default() };
/// let merged = merge_views(&views, &initial, &config)?;
/// assert_eq!(merged.alignment.pairs.len(), 3); // 0-1, 1-2 and the loop closure 2-0
/// assert!(merged.cloud.len() > 1000 && merged.cloud.normals().is_some());
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
pub fn merge_views(
    views: &[PointCloud],
    initial: &[Isometry3<f64>],
    config: &MergeConfig,
) -> Result<MergedScan, IcpError> {
    let alignment = align_views(views, initial, config)?;
    let cloud = merge_aligned(views, &alignment.poses, config)?;
    Ok(MergedScan { cloud, alignment })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_form_a_chain_and_close_the_ring() {
        assert_eq!(pair_list(4, 1, true), vec![(0, 1), (1, 2), (2, 3), (3, 0)]);
        assert_eq!(pair_list(4, 1, false), vec![(0, 1), (1, 2), (2, 3)]);
        assert_eq!(
            pair_list(5, 2, true),
            vec![
                (0, 1),
                (1, 2),
                (0, 2),
                (2, 3),
                (1, 3),
                (3, 4),
                (2, 4),
                (3, 0),
                (4, 0),
                (4, 1)
            ]
        );
        assert_eq!(pair_list(2, 1, true), vec![(0, 1)]);
        assert!(pair_list(1, 1, true).is_empty());
    }
}
