//! Scans of several placements: a turntable never sees the underside of the object on its
//! platter, so the object is scanned once standing, then again laid on its side, and the two
//! turntable scans are aligned and merged into one complete model.
//!
//! The loop ([`capture_placements`]) captures one turntable session per placement into
//! `placement_1/session/`, `placement_2/session/`, …, asking a [`PlacementRig`] to re-place the
//! object in between: the virtual rig lays its object on its side; on real devices the CLI
//! waits for the user. Each session is reconstructed and merged as a single-placement scan
//! ([`scan_session`](crate::scan_session)); each later placement's merged cloud is aligned onto the first one's
//! with no pose hint (`sl_icp::register_global`: FPFH descriptors, RANSAC, ICP), refined by
//! ICP on the full clouds ([`align_placement`]), and all are merged into one cloud
//! (`sl_icp::merge_aligned`) in the camera frame of the first placement's first view
//! ([`merge_placements`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::Isometry3;
use serde::Serialize;
use sl_cloud::PointCloud;
use sl_icp::{
    GlobalConfig, IcpConfig, MergeConfig, Metric, PrepareConfig, PreparedCloud, merge_aligned,
    register, register_global,
};

use crate::error::stage_err;
use crate::{ScanCalibration, ScanError, ScanProgress, SessionScan, SessionScanConfig, StageTime};

/// The most placements a scan supports: a standing one and one on the side cover every
/// surface of an object that is not hollow; more would need a multiway alignment of the
/// placements.
pub const MAX_PLACEMENTS: usize = 2;

/// Folder of placement `k` (1-based) inside the scan's output folder: `placement_1`, ….
pub fn placement_dir_name(k: usize) -> String {
    format!("placement_{k}")
}

/// The capture session folder inside a placement's folder.
pub const PLACEMENT_SESSION_DIR: &str = "session";

/// Checks a number of placements: 1 to [`MAX_PLACEMENTS`].
///
/// # Errors
/// [`ScanError::Stage`] (stage `placements`) saying what is supported.
pub fn check_placements(placements: usize) -> Result<(), ScanError> {
    if (1..=MAX_PLACEMENTS).contains(&placements) {
        Ok(())
    } else {
        Err(stage_err(
            "placements",
            format!(
                "{placements} placements: 1 (standing) or 2 (standing, then laid on its side) are supported"
            ),
        ))
    }
}

/// The devices of a scan of several placements: they capture a turntable session, and
/// re-place the object between two sessions.
pub trait PlacementRig {
    /// Captures the turntable session of placement `placement` (1-based) into `session_dir`
    /// (resuming an interrupted one). Returns the views captured in this run.
    ///
    /// # Errors
    /// The capture's, naming the device or the view.
    fn capture(&mut self, placement: usize, session_dir: &Path) -> Result<usize, ScanError>;

    /// Re-places the object before placement `next` (2-based up to `total`): the virtual rig
    /// turns its scene; on real devices the user lays the object on its side and confirms.
    ///
    /// # Errors
    /// When the object cannot be re-placed (the user gave up, the scene cannot be turned).
    fn replace(&mut self, next: usize, total: usize) -> Result<(), ScanError>;
}

/// Runs the placement loop into `out`: for each placement `k` in `1..=placements`, re-place
/// the object (from the second on), then capture `out/placement_k/session/`. Returns the
/// session folders and the views captured in this run, per placement.
///
/// # Errors
/// [`check_placements`]'s, and those of the rig.
pub fn capture_placements<R: PlacementRig + ?Sized>(
    out: &Path,
    placements: usize,
    rig: &mut R,
) -> Result<Vec<(PathBuf, usize)>, ScanError> {
    check_placements(placements)?;
    let mut sessions = Vec::with_capacity(placements);
    for k in 1..=placements {
        if k > 1 {
            rig.replace(k, placements)?;
        }
        let dir = out.join(placement_dir_name(k)).join(PLACEMENT_SESSION_DIR);
        let captured = rig.capture(k, &dir)?;
        sessions.push((dir, captured));
    }
    Ok(sessions)
}

/// Options of [`align_placement`] and [`merge_placements`].
#[derive(Debug, Clone)]
pub struct PlacementConfig {
    /// The global registration of a placement's merged cloud onto the first one's, with no
    /// pose hint. Default `sl_icp::GlobalConfig::default()` (2 mm voxels).
    pub global: GlobalConfig,
    /// Voxel size of both clouds for the refining ICP (mm). Default 0.5 mm: the merged
    /// clouds' own voxel, every point kept.
    pub refine_voxel_mm: f64,
    /// The refining ICP from the global pose. Default point-to-plane with a 1.5 mm gate (the
    /// global registration's final ICP leaves well under 1 mm; tighter than that, the parts
    /// one placement saw and the other did not cannot pull the pose).
    pub refine: IcpConfig,
    /// Below this fitness of the refined registration (fraction of the moving cloud within
    /// the gate), the placement is refused as not aligned. Default 0.3: two placements of a
    /// convex object share half their surface or more.
    pub min_fitness: f64,
    /// The merge of the aligned clouds. Default: `sl_icp::MergeConfig::default()` with
    /// overlapping points averaged (as the turntable merge of `slscan scan`).
    pub merge: MergeConfig,
}

impl Default for PlacementConfig {
    fn default() -> Self {
        Self {
            global: GlobalConfig::default(),
            refine_voxel_mm: 0.5,
            refine: IcpConfig {
                metric: Metric::PointToPlane,
                max_correspondence_distance: 1.5,
                ..IcpConfig::default()
            },
            min_fitness: 0.3,
            merge: MergeConfig {
                average_overlaps: true,
                ..MergeConfig::default()
            },
        }
    }
}

/// How one placement was aligned onto the first.
#[derive(Debug, Clone, Serialize)]
pub struct PlacementAlignment {
    /// The placement (1-based).
    pub placement: usize,
    /// `T_first_this`: maps this placement's cloud into the first placement's frame.
    pub pose: [[f64; 4]; 4],
    /// Descriptor matches of the global registration.
    pub correspondences: usize,
    /// RANSAC inliers of the global registration.
    pub ransac_inliers: usize,
    /// Fitness and RMSE (mm) of the global registration's ICP (2 mm voxels).
    pub global_fitness: f64,
    /// See `global_fitness`.
    pub global_rmse_mm: f64,
    /// Fitness and RMSE (mm) of the refining ICP.
    pub fitness: f64,
    /// See `fitness`.
    pub rmse_mm: f64,
    /// Wall time (ms).
    pub ms: f64,
}

/// Aligns `moving` (the merged cloud of placement `placement`) onto `reference` (the first
/// placement's) with no pose hint: global registration, then ICP on both clouds at
/// `refine_voxel_mm`. Returns `T_reference_moving` and the figures.
///
/// # Errors
/// [`ScanError::Icp`] when the global registration fails (naming the placement); a
/// [`ScanError::Stage`] when the refined fitness stays below `min_fitness`.
pub fn align_placement(
    reference: &PointCloud,
    moving: &PointCloud,
    placement: usize,
    cfg: &PlacementConfig,
) -> Result<(Isometry3<f64>, PlacementAlignment), ScanError> {
    let t = Instant::now();
    let global = register_global(moving, reference, &cfg.global).map_err(|e| {
        stage_err(
            "placements",
            format!(
                "placement {placement} could not be aligned onto placement 1 without pose hints: {e}"
            ),
        )
    })?;
    let prep = PrepareConfig {
        voxel_size: Some(cfg.refine_voxel_mm),
        ..PrepareConfig::default()
    };
    let source = PreparedCloud::new(moving, &prep)?;
    let target = PreparedCloud::new(reference, &prep)?;
    let refined = register(&source, &target, &global.pose, &cfg.refine)?;
    if refined.fitness < cfg.min_fitness {
        return Err(stage_err(
            "placements",
            format!(
                "placement {placement} aligned onto placement 1 with fitness {:.3} (RMSE {:.3} mm), below {}: the placements share too little surface, or the alignment is wrong",
                refined.fitness, refined.rmse, cfg.min_fitness
            ),
        ));
    }
    Ok((
        refined.pose,
        PlacementAlignment {
            placement,
            pose: sl_camera::pose_to_matrix(&refined.pose),
            correspondences: global.correspondences,
            ransac_inliers: global.ransac.inliers,
            global_fitness: global.registration.fitness,
            global_rmse_mm: global.registration.rmse,
            fitness: refined.fitness,
            rmse_mm: refined.rmse,
            ms: t.elapsed().as_secs_f64() * 1e3,
        },
    ))
}

/// The placements merged into one cloud.
#[derive(Debug, Clone)]
pub struct PlacementsMerge {
    /// The merged cloud, in the first placement's frame (mm).
    pub merged: PointCloud,
    /// `T_first_k` of every placement (identity for the first).
    pub poses: Vec<Isometry3<f64>>,
    /// How each placement after the first was aligned.
    pub alignments: Vec<PlacementAlignment>,
}

/// Aligns every placement's merged cloud onto the first one's ([`align_placement`]) and
/// merges them (`sl_icp::merge_aligned` with `cfg.merge`: overlapping points averaged,
/// normals oriented as each placement's).
///
/// # Errors
/// [`ScanError::Stage`] for no cloud; those of [`align_placement`] and the merge.
pub fn merge_placements(
    clouds: &[PointCloud],
    cfg: &PlacementConfig,
) -> Result<PlacementsMerge, ScanError> {
    let Some(first) = clouds.first() else {
        return Err(stage_err("placements", "no placement to merge"));
    };
    let mut poses = vec![Isometry3::identity()];
    let mut alignments = Vec::new();
    for (k, cloud) in clouds.iter().enumerate().skip(1) {
        let (pose, a) = align_placement(first, cloud, k + 1, cfg)?;
        poses.push(pose);
        alignments.push(a);
    }
    let merged = if clouds.len() == 1 {
        first.clone()
    } else {
        merge_aligned(clouds, &poses, &cfg.merge)?
    };
    Ok(PlacementsMerge {
        merged,
        poses,
        alignments,
    })
}

/// A scan of several placements, reconstructed and merged by [`scan_placements`].
#[derive(Debug, Clone)]
pub struct PlacementsScan {
    /// Each placement's session, reconstructed and merged as a single-placement scan (each in
    /// the camera frame of its own first view).
    pub sessions: Vec<SessionScan>,
    /// All placements in one cloud, and how they were aligned.
    pub merge: PlacementsMerge,
    /// Wall time per stage.
    pub stages: Vec<StageTime>,
}

/// Reconstructs and merges each placement's session with `calibration`
/// ([`ScanCalibration::scan_session`]: one camera and the projector, or two cameras), then
/// aligns and merges the placements ([`merge_placements`]), reporting the stage `placements`.
///
/// # Errors
/// Those of [`ScanCalibration::scan_session`] and [`merge_placements`].
pub fn scan_placements(
    sessions: &[PathBuf],
    calibration: &ScanCalibration,
    session_cfg: &SessionScanConfig,
    cfg: &PlacementConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<PlacementsScan, ScanError> {
    let mut scans = Vec::with_capacity(sessions.len());
    let mut stages = Vec::new();
    for dir in sessions {
        let scan = calibration.scan_session(dir, session_cfg, &mut progress)?;
        stages.extend(scan.stages.iter().cloned());
        scans.push(scan);
    }
    let t = Instant::now();
    progress(ScanProgress {
        stage: "placements",
        done: 0,
        total: 1,
    });
    let clouds: Vec<PointCloud> = scans.iter().map(|s| s.merged.clone()).collect();
    let merge = merge_placements(&clouds, cfg)?;
    progress(ScanProgress {
        stage: "placements",
        done: 1,
        total: 1,
    });
    stages.push(StageTime::since("placements", t));
    Ok(PlacementsScan {
        sessions: scans,
        merge,
        stages,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Recorder(Vec<String>);

    impl PlacementRig for Recorder {
        fn capture(&mut self, placement: usize, dir: &Path) -> Result<usize, ScanError> {
            self.0
                .push(format!("capture {placement} {}", dir.display()));
            Ok(3)
        }
        fn replace(&mut self, next: usize, total: usize) -> Result<(), ScanError> {
            self.0.push(format!("replace {next}/{total}"));
            Ok(())
        }
    }

    /// The loop captures each placement into its folder and re-places the object in
    /// between, never before the first; unsupported counts are refused before anything runs.
    #[test]
    fn the_loop_replaces_between_sessions() {
        let mut r = Recorder(Vec::new());
        let s = capture_placements(Path::new("out"), 2, &mut r).unwrap();
        assert_eq!(
            r.0,
            [
                "capture 1 out/placement_1/session",
                "replace 2/2",
                "capture 2 out/placement_2/session"
            ]
        );
        assert_eq!(s.len(), 2);
        for n in [0, 3] {
            let mut r = Recorder(Vec::new());
            let e = capture_placements(Path::new("out"), n, &mut r)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!("{n} placements")) && e.contains("2"),
                "{e}"
            );
            assert!(r.0.is_empty());
        }
    }
}
