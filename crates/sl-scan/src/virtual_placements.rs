//! The scan of several placements on the virtual rig: the pebble (`sl_sim::Scene::pebble`, an
//! object with a flat bottom that no single turntable placement sees) scanned standing, then
//! laid on its side, through the same capture, reconstruction, merge, placement alignment and
//! mesh stages as on real devices ([`capture_placements`], [`scan_placements`],
//! [`mesh_stage`]); and — what only the virtual rig can add — the coverage of the true surface
//! and the distance to it, per placement and for the whole (`sl_metrology::surface_coverage`,
//! `sl_metrology::distance_to_surface`).

use std::path::Path;
use std::time::Instant;

use serde::Serialize;
use sl_cloud::PointCloud;
use sl_mesh::write_ply_mesh;
use sl_metrology::{
    CoverageConfig, DEFAULT_SELECT_MM, DEFAULT_TRUTH_SAMPLE_AREA_MM2, SurfaceCoverage,
    SurfaceDistance, TriangleMesh, distance_to_surface, surface_coverage,
};
use sl_rig::turntable_angles;
use sl_sim::{DEFAULT_WORKING_DISTANCE_MM, Scene, VirtualRig};
use sl_tri::BinocularConfig;

use crate::error::{io, stage_err};
use crate::mesh::{MeshFiles, MeshSummary, mesh_stage_coloured, scan_poisson_config};
use crate::placements::{PlacementAlignment, PlacementConfig, PlacementRig};
use crate::virtual_calibrate::calibrate_virtual_stage;
use crate::virtual_scan::{
    VirtualRigs, capture_virtual, check_virtual_sessions, measure_virtual_response, precompensation,
};
use crate::{
    CalibrationSummary, MergeStageConfig, ScanCalibration, ScanError, ScanProgress,
    SessionScanConfig, StageTime, VirtualScanConfig, capture_placements, placement_dir_name,
    scaled_rig_config, scan_placements, write_scan_cloud,
};

/// The virtual rig's placements: captures each session of the current scene, and lays the
/// object on its side between two.
struct VirtualPlacements<'a> {
    rig: VirtualRig,
    scenes: Vec<Scene>,
    angles: Vec<f64>,
    cfg: &'a VirtualScanConfig,
    calibration: &'a Path,
    precompensation: Option<sl_codec::ToneCurve>,
}

impl PlacementRig for VirtualPlacements<'_> {
    fn capture(&mut self, placement: usize, dir: &Path) -> Result<usize, ScanError> {
        let rigs = VirtualRigs {
            left: self.rig.clone(),
            right: None,
            second: None,
            precompensation: self.precompensation.clone(),
        };
        let summary = capture_virtual(
            &rigs,
            dir,
            self.angles.clone(),
            &format!("virtual turntable, placement {placement}"),
            self.cfg,
            self.calibration,
            |_| {},
        )?;
        Ok(summary.captured)
    }

    fn replace(&mut self, next: usize, _total: usize) -> Result<(), ScanError> {
        let laid = self
            .scenes
            .last()
            .ok_or_else(|| stage_err("placements", "no scene to re-place"))?
            .laid_on_side()?;
        self.rig = self.rig.with_scene(laid.clone())?;
        self.scenes.push(laid);
        debug_assert_eq!(self.scenes.len(), next);
        Ok(())
    }
}

/// One placement's figures.
#[derive(Debug, Clone, Serialize)]
pub struct PlacementFigures {
    /// The placement (1-based).
    pub placement: usize,
    /// Views captured in this run (the others came from an earlier, interrupted run).
    pub views_captured: usize,
    /// Points triangulated in each view.
    pub view_points: Vec<usize>,
    /// Points of the placement's merged cloud.
    pub merged_points: usize,
    /// The placement alone: the fraction of the true surface it covers.
    pub coverage: SurfaceCoverage,
    /// The placement alone: the distance of its merged points to the true surface.
    pub distance: SurfaceDistance,
    /// How it was aligned onto the first placement (none for the first).
    pub alignment: Option<PlacementAlignment>,
    /// Where each of its views' poses came from in its turntable merge.
    pub merge: crate::MergeReport,
    /// Its merged cloud, relative to the output folder.
    pub merged: String,
}

/// Everything [`scan_virtual_placements`] produced.
#[derive(Debug, Clone)]
pub struct PlacementsResult {
    /// How good the calibration is.
    pub calibration_summary: CalibrationSummary,
    /// Per placement, alone.
    pub placements: Vec<PlacementFigures>,
    /// All placements in one cloud (mm, camera frame of the first placement's first view).
    pub merged: PointCloud,
    /// The true surface of the first placement in that frame.
    pub truth: TriangleMesh,
    /// The fraction of the true surface the merged cloud covers.
    pub coverage: SurfaceCoverage,
    /// The distance of the merged points to the true surface.
    pub distance: SurfaceDistance,
    /// The sample spacing the coverage distance is chosen from (mm): the larger of the
    /// camera pixel's footprint at the working distance and the merge voxel.
    pub spacing_mm: f64,
    /// The mesh of the merged cloud.
    pub mesh: Option<MeshSummary>,
    /// Its files.
    pub mesh_files: Option<MeshFiles>,
    /// The merged cloud, relative to the output folder.
    pub merged_file: String,
    /// Its previews.
    pub previews: Vec<String>,
    /// Wall time per stage, in order.
    pub stages: Vec<StageTime>,
}

/// Name of the truth mesh written beside the merged cloud (PLY, camera frame of the first
/// placement's first view).
pub const TRUTH_MESH_FILE: &str = "truth_mesh.ply";

/// Runs a scan of `placements` placements (1 or 2) of the pebble on the virtual rig into
/// `out`: `calibration.json`, `placement_k/session/` and `placement_k/merged.ply` per
/// placement, then `merged.ply` (all placements), its previews, `truth_mesh.ply` and the mesh
/// stage's files. `cfg.flatness_plate` and `cfg.true_poses` do not apply (no plate; each
/// placement is merged from the calibrated turntable poses and ICP). The caller writes the
/// report.
///
/// # Errors
/// [`ScanError::Stage`] for an unsupported count or too few views; those of every stage.
pub fn scan_virtual_placements(
    cfg: &VirtualScanConfig,
    placements: usize,
    out: &Path,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<PlacementsResult, ScanError> {
    crate::check_placements(placements)?;
    if cfg.views < 2 {
        return Err(stage_err(
            "capture",
            "a turntable scan needs at least 2 views",
        ));
    }
    std::fs::create_dir_all(out).map_err(io(out))?;
    let mut stages = Vec::new();
    let mut config = scaled_rig_config(cfg.resolution_divisor);
    config.render.seed = cfg.seed;
    config.render.illumination.gamma = cfg.projector_gamma;
    config.render.illumination.response = cfg.projector_response;
    let scene = Scene::pebble()?;
    let response = measure_virtual_response(&config, cfg, out, &mut stages)?;
    let rig = VirtualRig::new(config, scene.clone())?;
    let sessions: Vec<_> = (0..placements)
        .map(|k| {
            let dir = out
                .join(placement_dir_name(k))
                .join(crate::placements::PLACEMENT_SESSION_DIR);
            (dir, turntable_angles(cfg.views))
        })
        .collect();
    if cfg.binocular {
        return Err(stage_err(
            "placements",
            "a scan in several placements runs with one camera: binocular placements are not built yet",
        ));
    }
    let precompensation = precompensation(cfg, response.as_ref());
    let rigs = VirtualRigs {
        left: rig.clone(),
        right: None,
        second: None,
        precompensation: precompensation.clone(),
    };
    check_virtual_sessions(&rigs, &sessions, cfg, out)?;

    // 1. Calibrate.
    let (calibration, calibration_summary, calib_path) =
        calibrate_virtual_stage(&rig, cfg, out, &mut stages, &mut progress, response)?;

    // 2. The placement loop: capture, lay the object on its side, capture.
    let t = Instant::now();
    let angles = turntable_angles(cfg.views);
    let t_cam_table0 = rig
        .config()
        .t_cam_table_at(angles.first().copied().unwrap_or(0.0));
    let mut placer = VirtualPlacements {
        rig,
        scenes: vec![scene],
        angles,
        cfg,
        calibration: &calib_path,
        precompensation,
    };
    progress(ScanProgress {
        stage: "capture",
        done: 0,
        total: placements,
    });
    let sessions = capture_placements(out, placements, &mut placer)?;
    progress(ScanProgress {
        stage: "capture",
        done: placements,
        total: placements,
    });
    stages.push(StageTime::since("capture", t));

    // 3. Reconstruct and merge each placement, align the placements, merge them.
    let session_cfg = SessionScanConfig {
        reconstruct: cfg.reconstruct(),
        merge: MergeStageConfig::scan(cfg.average_overlaps, cfg.smoothing_neighbours, true),
        poses: None,
        binocular: BinocularConfig::default(),
        colour: crate::ColourConfig::default(),
    };
    let mut placement_cfg = PlacementConfig::default();
    placement_cfg.merge.average_overlaps = cfg.average_overlaps;
    placement_cfg.merge.output_normal_neighbours = cfg.smoothing_neighbours;
    let dirs: Vec<_> = sessions.iter().map(|(d, _)| d.clone()).collect();
    let scan = scan_placements(
        &dirs,
        &ScanCalibration::Monocular(calibration.clone()),
        &session_cfg,
        &placement_cfg,
        &mut progress,
    )?;
    stages.extend(scan.stages.iter().cloned());

    // 4. Measure against the true surfaces: each placement against its own scene, the whole
    // against the first placement's.
    let t = Instant::now();
    let footprint = DEFAULT_WORKING_DISTANCE_MM / calibration.camera.intrinsics.fx;
    let voxel = session_cfg.merge.merge.output_voxel_size.unwrap_or(0.0);
    let spacing_mm = footprint.max(voxel);
    let cov_cfg = CoverageConfig::for_spacing(spacing_mm);
    let measure = |cloud: &PointCloud, truth: &TriangleMesh| -> Result<_, ScanError> {
        Ok((
            surface_coverage(truth, cloud, &cov_cfg)?,
            distance_to_surface(
                cloud,
                truth,
                DEFAULT_TRUTH_SAMPLE_AREA_MM2,
                DEFAULT_SELECT_MM,
            )?,
        ))
    };
    let mut figures = Vec::with_capacity(placements);
    for (k, (session, scene)) in scan.sessions.iter().zip(&placer.scenes).enumerate() {
        let truth = scene.surface_mesh(&t_cam_table0)?;
        let (coverage, distance) = measure(&session.merged, &truth)?;
        let dir = out.join(placement_dir_name(k + 1));
        let files = write_scan_cloud(&dir, &session.merged, |_| {})?;
        figures.push(PlacementFigures {
            placement: k + 1,
            views_captured: sessions.get(k).map_or(0, |s| s.1),
            view_points: session.view_points.clone(),
            merged_points: session.merged.len(),
            coverage,
            distance,
            alignment: k
                .checked_sub(1)
                .and_then(|i| scan.merge.alignments.get(i).cloned()),
            merge: session.merge.clone(),
            merged: format!("{}/{}", placement_dir_name(k + 1), files.merged),
        });
    }
    let truth = placer
        .scenes
        .first()
        .ok_or_else(|| stage_err("placements", "no scene"))?
        .surface_mesh(&t_cam_table0)?;
    let merged = scan.merge.merged;
    let (coverage, distance) = measure(&merged, &truth)?;
    write_ply_mesh(&out.join(TRUTH_MESH_FILE), &truth)?;
    stages.push(StageTime::since("measure", t));

    // 5. Report files and the mesh.
    let t = Instant::now();
    let files = write_scan_cloud(out, &merged, &mut progress)?;
    stages.push(StageTime::since("report", t));
    let (mesh, mesh_files) = match cfg.mesh_depth {
        Some(depth) => {
            let t = Instant::now();
            let poisson =
                scan_poisson_config(&merged, session_cfg.merge.merge.output_voxel_size, depth);
            // In colour when the placements were captured in colour (`--colour`).
            let colours = crate::placed_colours(
                scan.sessions.iter().map(|s| s.colours.as_ref()),
                &scan.merge.alignments,
            )?;
            let (summary, files) = mesh_stage_coloured(
                &merged,
                None,
                None,
                &poisson,
                &cfg.mesh_options,
                colours.as_ref(),
                out,
            )?;
            stages.push(StageTime::since("mesh", t));
            (Some(summary), Some(files))
        }
        None => (None, None),
    };

    Ok(PlacementsResult {
        calibration_summary,
        placements: figures,
        merged,
        truth,
        coverage,
        distance,
        spacing_mm,
        mesh,
        mesh_files,
        merged_file: files.merged,
        previews: files.previews,
        stages,
    })
}
