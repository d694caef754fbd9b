//! The merge stage: the views of a turntable scan placed with the poses of the calibrated
//! axis (or with given poses), refined by registration when asked, and merged into one cloud
//! (`sl-icp`).

use nalgebra::Isometry3;
use serde::Serialize;
use serde_json::{Value, json};
use sl_camera::TurntableAxis;
use sl_cloud::PointCloud;
use sl_icp::{
    MergeConfig, PairRegistration, ViewAlignment, ViewPoseSource, merge_aligned, merge_views,
    turntable_poses,
};

use crate::{ReconstructedViews, ScanError, ScanProgress};

/// Options of [`merge_scan`].
#[derive(Debug, Clone)]
pub struct MergeStageConfig {
    /// How the views are registered and merged. Default: `sl_icp::MergeConfig::default()`
    /// with `average_overlaps` on.
    pub merge: MergeConfig,
    /// Refine the initial poses by registering the views (`sl_icp::merge_views`): absorbs
    /// the errors of an approximate axis calibration or of a motor that stops off target.
    /// `false` places every view with the initial poses alone (`sl_icp::merge_aligned`):
    /// right when the calibration is good and the views are too far apart or too symmetric
    /// for ICP (a dumbbell seen every 45° leaves ICP a free rotation about the bar). Default
    /// `true`.
    pub icp_refinement: bool,
}

impl MergeStageConfig {
    /// The merge of `slscan scan`, on the virtual and the real rig alike: sl-icp's default
    /// pose model (the calibrated turntable, kept where the registrations agree with it and
    /// corrected where they do not), overlapping views averaged when `average_overlaps`,
    /// `smoothing_neighbours` neighbours for the normals and the averaging surface,
    /// registration refinement when `icp_refinement`.
    pub fn scan(average_overlaps: bool, smoothing_neighbours: usize, icp_refinement: bool) -> Self {
        Self {
            merge: MergeConfig {
                average_overlaps,
                output_normal_neighbours: smoothing_neighbours,
                ..MergeConfig::default()
            },
            icp_refinement,
        }
    }
}

impl Default for MergeStageConfig {
    fn default() -> Self {
        Self {
            merge: MergeConfig {
                average_overlaps: true,
                ..MergeConfig::default()
            },
            icp_refinement: true,
        }
    }
}

/// Where one view's pose came from, for `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewPoseReport {
    /// The view's index.
    pub view: usize,
    /// `reference` (view 0), `turntable` (the calibrated turntable, confirmed by the
    /// registrations), `turntable prior only` (the registrations do not measure its angle),
    /// `registrations` (its angle from the registrations, the motor reading overruled),
    /// `pose graph` (the free pose graph), `given` (poses given, no registration).
    pub source: String,
    /// Why, for `turntable prior only`; the motor reading's offset for `registrations`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
}

/// What the merge stage did with the poses, for `report.json` and the one line `slscan` prints.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergeReport {
    /// One line: where the axis, the angle scale and the angles came from
    /// (`sl_icp::ViewAlignment::pose_summary`).
    pub summary: String,
    /// The turntable model's verdict on the calibrated axis (`None` without the model).
    pub axis_confirmed: Option<bool>,
    /// The Mahalanobis distance between the registered and the calibrated axis, standard
    /// deviations (`None` without the model or without axis priors).
    pub axis_distance_sigma: Option<f64>,
    /// The registrations' a-posteriori variance factor (`None` without the model).
    pub variance_factor: Option<f64>,
    /// The angle scale the poses used (1 unless the registrations corrected it).
    pub angle_scale: Option<f64>,
    /// Pairwise registrations tried and used.
    pub pairs_tried: usize,
    /// Of which used.
    pub pairs_used: usize,
    /// Each view's source.
    pub views: Vec<ViewPoseReport>,
}

impl MergeReport {
    /// The report of an alignment.
    pub fn from_alignment(a: &ViewAlignment) -> Self {
        let views = a
            .sources
            .iter()
            .enumerate()
            .map(|(view, s)| {
                let (source, detail) = match s {
                    ViewPoseSource::Reference => ("reference", None),
                    ViewPoseSource::Turntable => ("turntable", None),
                    ViewPoseSource::TurntablePriorOnly { why } => {
                        ("turntable prior only", Some(why.clone()))
                    }
                    ViewPoseSource::Registrations {
                        motor_off_deg,
                        sigmas,
                    } => (
                        "registrations",
                        Some(format!(
                            "motor reading {motor_off_deg:+.4} deg off, {sigmas:.1} sigma"
                        )),
                    ),
                    ViewPoseSource::PoseGraph => ("pose graph", None),
                };
                ViewPoseReport {
                    view,
                    source: source.to_owned(),
                    detail,
                }
            })
            .collect();
        let t = a.turntable.as_ref();
        Self {
            summary: a.pose_summary(),
            axis_confirmed: t.map(|t| t.axis_confirmed),
            axis_distance_sigma: t.map(|t| t.axis_distance).filter(|d| d.is_finite()),
            variance_factor: t.map(|t| t.variance_factor),
            angle_scale: t.map(|t| t.angle_scale),
            pairs_tried: a.pairs.len(),
            pairs_used: a.pairs.iter().filter(|p| p.used).count(),
            views,
        }
    }

    /// The report of a merge with given poses (no registration).
    pub fn given(views: usize, what: &str) -> Self {
        Self {
            summary: format!("{views} views: {what} (no registration)"),
            axis_confirmed: None,
            axis_distance_sigma: None,
            variance_factor: None,
            angle_scale: None,
            pairs_tried: 0,
            pairs_used: 0,
            views: (0..views)
                .map(|view| ViewPoseReport {
                    view,
                    source: "given".to_owned(),
                    detail: Some(what.to_owned()),
                })
                .collect(),
        }
    }
}

/// The merged cloud and how its poses were found.
#[derive(Debug, Clone)]
pub struct MergedViews {
    /// The merged cloud (mm, camera frame of view 0).
    pub cloud: PointCloud,
    /// The registrations and the pose model's verdicts, when the views were registered.
    pub alignment: Option<ViewAlignment>,
    /// Where each view's pose came from.
    pub report: MergeReport,
    /// `T_world_view` of each view (world: the camera frame of view 0), the poses the views
    /// were merged with.
    pub poses: Vec<Isometry3<f64>>,
}

/// Merges the reconstructed views into one cloud in the camera frame of view 0, reporting the
/// stage `merge`. The initial pose of each view is `poses[k]` when given (the virtual rig's
/// true poses, a diagnostic), else the turntable pose of its motor angle through the
/// calibrated axis (`sl_icp::turntable_poses`).
///
/// # Errors
/// [`ScanError::Icp`]: poses and views of different counts, a registration or merge failure.
pub fn merge_scan(
    views: &ReconstructedViews,
    poses: Option<&[Isometry3<f64>]>,
    config: &MergeStageConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<MergedViews, ScanError> {
    progress(ScanProgress {
        stage: "merge",
        done: 0,
        total: 1,
    });
    let (initial, given) = match poses {
        Some(p) => (p.to_vec(), "the given poses"),
        None => (
            turntable_poses(&views.axis, &views.motor_angles_deg)?,
            "the calibrated turntable's poses",
        ),
    };
    let merged = if config.icp_refinement {
        let m = merge_views(&views.clouds, &initial, &config.merge)?;
        MergedViews {
            cloud: m.cloud,
            report: MergeReport::from_alignment(&m.alignment),
            poses: m.alignment.poses.clone(),
            alignment: Some(m.alignment),
        }
    } else {
        MergedViews {
            cloud: merge_aligned(&views.clouds, &initial, &config.merge)?,
            alignment: None,
            report: MergeReport::given(initial.len(), given),
            poses: initial,
        }
    };
    progress(ScanProgress {
        stage: "merge",
        done: 1,
        total: 1,
    });
    Ok(merged)
}

/// Every pair's figures for `report.json`: views by index and by `name`, fitness, RMSE,
/// whether used, whether the global-registration fallback gave the pose, and why it failed.
pub fn pair_figures(pairs: &[PairRegistration], name: &dyn Fn(usize) -> String) -> Value {
    pairs
        .iter()
        .map(|p| {
            json!({
                "target": p.target,
                "source": p.source,
                "target_view": name(p.target),
                "source_view": name(p.source),
                "used": p.used,
                "global_registration": p.global,
                "rmse_mm": p.registration.as_ref().map(|r| r.rmse),
                "fitness": p.registration.as_ref().map(|r| r.fitness),
                "iterations": p.registration.as_ref().map(|r| r.iterations),
                "failure": p.failure,
            })
        })
        .collect()
}

/// The largest turn (degrees) between a view's initial pose and its aligned one.
#[must_use]
pub fn largest_pose_correction_deg(initial: &[Isometry3<f64>], aligned: &[Isometry3<f64>]) -> f64 {
    initial
        .iter()
        .zip(aligned)
        .map(|(a, b)| a.rotation.angle_to(&b.rotation).to_degrees())
        .fold(0.0, f64::max)
}

/// The figures of an alignment of views (`sl_icp::align_views`) for `report.json`, by name:
/// the pairs ([`pair_figures`]), the pose graph's costs, the largest pose correction from
/// `initial`, the turntable model's axes and verdict, each view's pose source and the pairs'
/// free motions. `name` names view `i`.
pub fn alignment_figures(
    alignment: &ViewAlignment,
    initial: &[Isometry3<f64>],
    name: &dyn Fn(usize) -> String,
) -> Vec<(&'static str, Value)> {
    let pairs = &alignment.pairs;
    let mut f = vec![
        ("pairs", pair_figures(pairs, name)),
        ("pairs_used", pairs.iter().filter(|p| p.used).count().into()),
        (
            "pairs_from_global_registration",
            pairs.iter().filter(|p| p.used && p.global).count().into(),
        ),
        (
            "pose_graph_initial_cost",
            alignment.pose_graph.initial_cost.into(),
        ),
        (
            "pose_graph_final_cost",
            alignment.pose_graph.final_cost.into(),
        ),
        (
            "pose_graph_iterations",
            alignment.pose_graph.iterations.into(),
        ),
        (
            "largest_pose_correction_deg",
            largest_pose_correction_deg(initial, &alignment.poses).into(),
        ),
    ];
    if let Some(t) = &alignment.turntable {
        let axis = |a: &TurntableAxis| {
            json!({
                "direction": [a.direction.x, a.direction.y, a.direction.z],
                "point_mm": [a.point_mm.x, a.point_mm.y, a.point_mm.z],
            })
        };
        f.push((
            "turntable",
            json!({
                "axis_confirmed": t.axis_confirmed,
                "axis_distance_sigma": t.axis_distance.is_finite().then_some(t.axis_distance),
                "variance_factor": t.variance_factor,
                "angle_scale_corrected": t.angle_scale_corrected,
                "initial_axis": axis(&t.initial_axis),
                "registered_axis": axis(&t.registered_axis),
                "axis": axis(&t.axis),
                "angle_scale": t.angle_scale,
                "angles_deg": t.angles_deg,
            }),
        ));
    }
    f.push(("pose_summary", alignment.pose_summary().into()));
    f.push((
        "pose_sources",
        alignment
            .sources
            .iter()
            .enumerate()
            .map(|(view, s)| pose_source_figure(view, s))
            .collect(),
    ));
    f.push((
        "pair_free_motions",
        pairs
            .iter()
            .filter(|p| !p.free_motions.is_empty())
            .map(|p| {
                json!({
                    "target": p.target,
                    "source": p.source,
                    "free": p.free_motions.iter().map(ToString::to_string).collect::<Vec<_>>(),
                })
            })
            .collect(),
    ));
    f
}

/// One view's pose source for `report.json`.
fn pose_source_figure(view: usize, s: &ViewPoseSource) -> Value {
    match s {
        ViewPoseSource::Reference => json!({"view": view, "source": "reference"}),
        ViewPoseSource::Turntable => json!({"view": view, "source": "turntable"}),
        ViewPoseSource::TurntablePriorOnly { why } => {
            json!({"view": view, "source": "turntable prior only", "why": why})
        }
        ViewPoseSource::Registrations {
            motor_off_deg,
            sigmas,
        } => json!({
            "view": view,
            "source": "registrations",
            "motor_off_deg": motor_off_deg,
            "sigmas": sigmas.is_finite().then_some(*sigmas),
        }),
        ViewPoseSource::PoseGraph => json!({"view": view, "source": "pose graph"}),
    }
}
