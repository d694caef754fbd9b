//! The merge stage: the views of a turntable scan placed with the poses of the calibrated
//! axis (or with given poses), refined by registration when asked, and merged into one cloud
//! (`sl-icp`).

use nalgebra::Isometry3;
use sl_cloud::PointCloud;
use sl_icp::{MergeConfig, PoseModel, merge_aligned, merge_views, turntable_poses};

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
    /// The merge of `slscan scan`, on the virtual and the real rig alike: the free pose graph
    /// (sl-icp's default, said explicitly: with sl-icp's turntable pose model the virtual
    /// scan's spheres came out 0.5 mm too small in diameter, form 0.9 mm, at full resolution
    /// and 0.77 mm at half; 2026-11-23 19:52 UTC, `sl_icp::PoseModel::default`), overlapping
    /// views averaged when `average_overlaps`, `smoothing_neighbours` neighbours for the
    /// normals and the averaging surface, registration refinement when `icp_refinement`.
    pub fn scan(average_overlaps: bool, smoothing_neighbours: usize, icp_refinement: bool) -> Self {
        Self {
            merge: MergeConfig {
                average_overlaps,
                output_normal_neighbours: smoothing_neighbours,
                pose_model: PoseModel::Free,
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
) -> Result<PointCloud, ScanError> {
    progress(ScanProgress {
        stage: "merge",
        done: 0,
        total: 1,
    });
    let initial = match poses {
        Some(p) => p.to_vec(),
        None => turntable_poses(&views.axis, &views.motor_angles_deg)?,
    };
    let merged = if config.icp_refinement {
        merge_views(&views.clouds, &initial, &config.merge)?.cloud
    } else {
        merge_aligned(&views.clouds, &initial, &config.merge)?
    };
    progress(ScanProgress {
        stage: "merge",
        done: 1,
        total: 1,
    });
    Ok(merged)
}
