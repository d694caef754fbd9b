//! The end-to-end scan on the virtual rig, as one library call: calibrate from simulated
//! board captures, capture a turntable session of a known object through the device traits,
//! reconstruct and merge it with the same stage functions as a scan on real devices
//! ([`scan_session`]), and — what only the virtual rig can add — measure the result against
//! its truth with `sl-metrology` (the dumbbell for the probing and sphere-spacing errors, then
//! one capture of a tilted flat plate for the flatness). `slscan scan` is a thin wrapper
//! around [`scan_virtual`]; `crates/sl-scan/tests/it/scan_pipeline.rs` runs it small.

use std::path::Path;
use std::time::{Duration, Instant};

use nalgebra::Isometry3;
use serde::Serialize;
use sl_camera::{BinocularCalibration, Calibration, ImageSize};
use sl_cloud::{PlyFormat, PointCloud, write_ply};
use sl_codec::BitDepth;
use sl_metrology::{Report, Truth};
use sl_rig::{
    CaptureTiming, SessionConfig, SessionExposures, SessionPlan, SessionSummary, turntable_angles,
    view_dir_name,
};
use sl_sim::{RigConfig, Scene, SecondCamera, VirtualRig};
use sl_tri::{Binocular, BinocularConfig, Triangulator};

use crate::error::{io, stage_err};
use crate::exposures::{Exposures, measure_at_first_view, planned_exposures, session_exposures};
use crate::mesh::{MeshConfig, MeshFiles, MeshSummary, mesh_stage_coloured, scan_poisson_config};
use crate::virtual_calibrate::{calibrate_virtual_binocular_stage, calibrate_virtual_stage};
use crate::{
    CalibrationSummary, MergeReport, MergeStageConfig, ReconstructConfig, SCAN_PERIOD_PX,
    ScanCalibration, ScanError, ScanProgress, SessionScanConfig, StageTime,
    capture_binocular_session, capture_session, measure_scan, plate_scene, plate_truth,
    reconstruct_binocular_view, reconstruct_view_eroded, scan_patterns_with, scene_truth,
    write_heat_map, write_scan_cloud,
};

/// What a scan on the virtual rig does about its projector's response
/// ([`VirtualScanConfig::response_correction`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ResponseCorrection {
    /// Nothing: the fringes are taken for sinusoids.
    #[default]
    None,
    /// Measure the response first (a grey ramp on the plate,
    /// [`capture_virtual_ramp`](crate::capture_virtual_ramp), into `response/`), keep it in
    /// `calibration.json` and correct every decoded phase with it
    /// ([`sl_codec::PhaseCorrection`]): the fringes keep the contrast the response leaves
    /// them.
    Decode,
    /// Measure the response first, keep it in `calibration.json` and pre-compensate it in the
    /// scan's fringes (`sl_codec::HybridSpec::precompensation`): the light is a sinusoid of
    /// full contrast; the decode's correction then has only the 8-bit quantisation left.
    Precompensate,
}

/// Options of [`scan_virtual`].
#[derive(Debug, Clone, PartialEq)]
pub struct VirtualScanConfig {
    /// Turntable views over a full turn. Default 36 (10° apart, as the original rig).
    pub views: usize,
    /// Hand-held board poses of the camera–projector calibration. Default 12: Zhang's method
    /// needs 3, 10–20 is the usual advice.
    pub calibration_poses: usize,
    /// Motor angles of the board standing on the turntable (axis calibration). Default −45°
    /// to 45° in 15° steps: a 90° span pins the axis direction to hundredths of a degree.
    pub table_angles_deg: Vec<f64>,
    /// Divides the camera's and the projector's resolution (1: the default rig, 1280x720
    /// camera and 1920x1080 projector). Tests use 2 to run quickly.
    pub resolution_divisor: u32,
    /// Seed of the board poses and of the sensor noise.
    pub seed: u64,
    /// Width of one fringe period on the projector (projector pixels). Default
    /// [`SCAN_PERIOD_PX`] (15), as a scan on real devices: the finest period the rendered
    /// projector blur still resolves with good modulation (`docs/triangulation.md`).
    pub period_px: f64,
    /// Recapture views already captured in the session folder.
    pub overwrite: bool,
    /// Average overlapping views in the merge (`sl_icp::MergeConfig::average_overlaps`).
    /// Default `true`: on the default scan it halves the probing form error (0.47 → 0.22 mm
    /// over all points) for ~1 s more.
    pub average_overlaps: bool,
    /// After the turntable session, capture a tilted flat plate ([`plate_scene`]) through the
    /// same calibration, decoding and triangulation, and measure its flatness. Default `true`.
    pub flatness_plate: bool,
    /// Points whose surface normal is more than this far (degrees) from the direction to the
    /// camera or to the projector are dropped from each view before the merge: seen or lit at
    /// a grazing angle, their decoded coordinate is smeared over a long stretch of surface
    /// (and the grid normal itself is unreliable there). `90` keeps every point.
    pub max_view_angle_deg: f64,
    /// Diagnostic: triangulate with the rig's true calibration instead of the estimated one
    /// (the calibration stage then renders nothing). Default `false`.
    pub true_calibration: bool,
    /// Diagnostic: merge with the rig's true turntable poses instead of registering the views
    /// (`sl_icp::merge_aligned`). Default `false`.
    pub true_poses: bool,
    /// Neighbours of each merged point for its normal and, with `average_overlaps`, for the
    /// moving-least-squares surface it is moved onto (`sl_icp::MergeConfig::
    /// output_normal_neighbours`). Default 16.
    pub smoothing_neighbours: usize,
    /// Points within this many pixels (4-connected steps) of a pixel without a valid point —
    /// the silhouette of the object, the edge of a plate, the rim of a hole — are dropped from
    /// each view: their camera pixel or the projector's blurred stripe straddles the edge, so
    /// their depth mixes two surfaces, and the mixed-pixel filter cannot see it where the
    /// other side is empty. Default 3: on the default scan it takes the probing form from
    /// 0.22 to 0.15 mm (0.15 to 0.12 mm with 0.3 % left out) and the plate's flatness from
    /// 0.41 to 0.22 mm, for 5 % of the points (`docs/user-guide.md`).
    pub edge_erosion_px: usize,
    /// Largest octree depth of the mesh of the merged cloud (`sl_mesh::PoissonConfig::depth`;
    /// [`scan_poisson_config`](crate::scan_poisson_config) takes a shallower one where its cells
    /// would be much finer than the merged cloud's samples); `None` makes no mesh. Default 9
    /// (cells of 0.37 mm on the dumbbell).
    pub mesh_depth: Option<u32>,
    /// What the mesh stage does after the reconstruction: the simplification and the
    /// fairing of the unseen surface, both on by default ([`MeshConfig`]).
    pub mesh_options: MeshConfig,
    /// How the calibration's board corners are refined (`sl_calib::CornerRefiner`; the
    /// junction fit by default).
    pub corners: sl_calib::CornerRefiner,
    /// Smoothing of each view's decoded coordinates before triangulation
    /// ([`ReconstructConfig::smoothing`]; a 3 × 3 window by default, `None` for none).
    pub smoothing: Option<sl_codec::SmoothConfig>,
    /// Scan with two cameras (binocular structured light): the rig gains its default second
    /// camera ([`RigConfig::default_second_camera`]: the camera's twin on the other side of
    /// the projector), the calibration is of the two cameras and the turntable
    /// ([`calibrate_virtual_binocular`](crate::calibrate_virtual_binocular)), each view is
    /// captured by both and matched between them
    /// ([`scan_binocular_session`](crate::scan_binocular_session)); the projector only labels
    /// the surface. The same scene, patterns, merge and measures as the one-camera scan.
    /// Default `false`.
    pub binocular: bool,
    /// Exponent of the virtual projector's response (`sl_sim::Illumination::gamma`), which
    /// the patterns do not pre-compensate: 1 (the default) is a linear projector; 2.2 a
    /// display-calibrated one run as it comes, whose fringes are no longer sinusoids.
    pub projector_gamma: f64,
    /// The shape of the virtual projector's response: a power law of `projector_gamma`
    /// (the default) or a measured projector's curve ([`sl_sim::ResponseShape::Measured`]).
    pub projector_response: sl_sim::ResponseShape,
    /// What the scan does about the projector's response. Default
    /// [`ResponseCorrection::None`].
    pub response_correction: ResponseCorrection,
    /// Phase steps of the scan's hybrid code (3 to 64). Default
    /// [`SCAN_PHASE_STEPS`](crate::SCAN_PHASE_STEPS) (8).
    pub phase_steps: u32,
    /// Options of the matching between the two cameras (with `binocular`).
    pub binocular_options: BinocularConfig,
    /// The virtual projector's lens distortion instead of the rig's (OpenCV's coefficients:
    /// 5, or 8 for the rational model). The calibration still estimates the 5-coefficient
    /// model (OpenCV's default): a rational projector lens is one it cannot represent, which
    /// a one-camera scan triangulates with and a two-camera scan never uses. Default `None`.
    pub projector_distortion: Option<sl_camera::Distortion>,
    /// The projector turns by this angle (degrees, about its own vertical axis) between the
    /// calibration and the scan: the drift of a projector warming up, or knocked. A one-camera
    /// scan triangulates with the calibrated pose; a two-camera scan does not use it.
    /// Default 0.
    pub projector_drift_deg: f64,
    /// The dumbbell's surface: matte plaster (the default), a black part, or a glossy
    /// plastic whose highlights saturate the camera ([`sl_sim::Finish`]).
    pub finish: sl_sim::Finish,
    /// The exposures each view is captured at. Default [`Exposures::Camera`]: one, the
    /// virtual camera's ([`sl_sim::VIRTUAL_EXPOSURE_MS`]).
    pub exposures: Exposures,
    /// How several exposures are fused. Default: the longest unsaturated one per pixel.
    pub fusion: sl_codec::FusionSettings,
    /// Capture each view's colour under full white (the virtual camera renders it in colour):
    /// the clouds, the mesh (vertex colours, a textured OBJ) and the 3-D page in colour,
    /// measured against the scene's true albedo ([`ScanResult::colour`]). Default `false`.
    pub colour: bool,
}

impl VirtualScanConfig {
    /// The reconstruction settings of the turntable views and the plate.
    pub fn reconstruct(&self) -> ReconstructConfig {
        ReconstructConfig {
            edge_erosion_px: self.edge_erosion_px,
            max_view_angle_deg: self.max_view_angle_deg,
            smoothing: self.smoothing,
            decode: sl_codec::DecodeConfig::default(),
            colour: crate::ColourMode::Auto,
        }
    }
}

impl Default for VirtualScanConfig {
    fn default() -> Self {
        Self {
            views: 36,
            calibration_poses: 12,
            table_angles_deg: (-3..=3).map(|k| f64::from(k) * 15.0).collect(),
            resolution_divisor: 1,
            seed: 0,
            period_px: SCAN_PERIOD_PX,
            overwrite: false,
            average_overlaps: true,
            flatness_plate: true,
            max_view_angle_deg: 90.0,
            true_calibration: false,
            true_poses: false,
            smoothing_neighbours: 16,
            edge_erosion_px: 3,
            mesh_depth: Some(sl_mesh::PoissonConfig::default().depth),
            mesh_options: MeshConfig::default(),
            corners: sl_calib::CornerRefiner::default(),
            smoothing: ReconstructConfig::default().smoothing,
            binocular: false,
            projector_gamma: 1.0,
            projector_response: sl_sim::ResponseShape::Power,
            response_correction: ResponseCorrection::None,
            phase_steps: crate::SCAN_PHASE_STEPS,
            binocular_options: BinocularConfig::default(),
            projector_distortion: None,
            projector_drift_deg: 0.0,
            finish: sl_sim::Finish::Matte,
            exposures: Exposures::Camera,
            fusion: sl_codec::FusionSettings::default(),
            colour: false,
        }
    }
}

/// Files written by [`scan_virtual`], relative to the output folder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScanFiles {
    /// The estimated calibration.
    pub calibration: String,
    /// The capture session folder.
    pub session: String,
    /// The merged cloud.
    pub merged: String,
    /// Shaded previews from several viewpoints.
    pub previews: Vec<String>,
    /// The cloud coloured by its distance to the true surface.
    pub heat_map: String,
    /// The truth of the turntable scene, in the frame of the merged cloud: `slscan report
    /// merged.ply --truth truth.json` reproduces [`ScanResult::accuracy`].
    pub truth: String,
    /// The plate's cloud, its truth and heat map (when [`VirtualScanConfig::flatness_plate`]).
    pub plate: Option<String>,
    /// See `plate`.
    pub plate_truth: Option<String>,
    /// See `plate`.
    pub plate_heat_map: Option<String>,
    /// The mesh of the merged cloud and its 3-D page (when [`VirtualScanConfig::mesh_depth`]
    /// is set).
    pub mesh: Option<MeshFiles>,
}

/// Everything [`scan_virtual`] produced.
#[derive(Debug, Clone)]
pub struct ScanResult {
    /// The estimated calibration used for the scan (in a binocular scan: the left camera and
    /// the turntable axis; the pair is `pair`).
    pub calibration: Calibration,
    /// The two-camera calibration of a binocular scan ([`VirtualScanConfig::binocular`]).
    pub pair: Option<BinocularCalibration>,
    /// How good it is.
    pub calibration_summary: CalibrationSummary,
    /// The dumbbell's surface ([`VirtualScanConfig::finish`]).
    pub finish: sl_sim::Finish,
    /// The exposures the session captured each view at (as `session.json` records them:
    /// chosen, with [`Exposures::Auto`]), and how they were fused.
    pub exposures: SessionExposures,
    /// Points triangulated in each view.
    pub view_points: Vec<usize>,
    /// Views captured in this run (the others came from an earlier, interrupted run).
    pub views_captured: usize,
    /// The merged cloud (mm, camera frame of view 0).
    pub merged: PointCloud,
    /// The truth of the turntable scene (camera frame of view 0, as the rig places it).
    pub truth: Truth,
    /// The merged cloud measured against `truth` (probing and sphere-spacing errors).
    pub accuracy: Report,
    /// The first view alone (before merging) measured against `truth`: the noise and the
    /// grazing points of one view, without registration or averaging.
    pub first_view: Report,
    /// The plate's cloud measured against its truth (flatness), when captured.
    pub flatness: Option<Report>,
    /// The plate's decoded projector columns against the true ones, when captured.
    pub plate_phase: Option<PhaseError>,
    /// The mesh of the merged cloud: size, topology, accuracy.
    pub mesh: Option<MeshSummary>,
    /// The scan's colours against the scene's true albedo, when scanned in colour
    /// ([`VirtualScanConfig::colour`]).
    pub colour: Option<ScanColourReport>,
    /// Where each view's pose came from in the merge.
    pub merge: MergeReport,
    /// Wall time per stage, in order.
    pub stages: Vec<StageTime>,
    /// The files written.
    pub files: ScanFiles,
}

/// A colour scan's colours against the virtual scene's true albedo ([`crate::colour_accuracy`]:
/// one gain per channel fitted, then the RMS of the levels and the angle between measured
/// and true colours).
#[derive(Debug, Clone, serde::Serialize)]
pub struct ScanColourReport {
    /// Views with a colour image.
    pub views: usize,
    /// Where the views' colour came from (`colour_frame`, …).
    pub source: &'static str,
    /// The merged cloud's points within [`COLOUR_TRUTH_DISTANCE_MM`] of the true surface.
    pub cloud: Option<crate::ColourAccuracy>,
    /// The mesh's vertices (as `mesh.ply` holds them) that a view sees (the others are
    /// [`crate::UNSEEN_COLOUR`]) within that distance.
    pub mesh: Option<crate::ColourAccuracy>,
}

/// Points further than this (mm) from the true surface are left out of the colour figures:
/// the colour of a stray point belongs to no surface.
pub const COLOUR_TRUTH_DISTANCE_MM: f64 = 1.0;

/// The vertices of `mesh` (as read from its PLY, with normals and colours) that a view of
/// `colours` sees: the others hold [`crate::UNSEEN_COLOUR`], no measurement.
fn seen_vertices(mesh: &PointCloud, colours: &crate::ScanColours) -> PointCloud {
    let Some(normals) = mesh.normals() else {
        return mesh.clone();
    };
    let keep: Vec<usize> = (0..mesh.len())
        .filter(|&i| {
            colours
                .colour_at(&mesh.positions()[i], &normals[i].normalize())
                .is_some()
        })
        .collect();
    mesh.select(&keep).unwrap_or_else(|_| mesh.clone())
}

/// The colours of `cloud` against `rig`'s true albedo (views at motor angle `motor_deg` frame
/// the cloud).
fn cloud_colour_accuracy(
    rig: &sl_sim::VirtualRig,
    motor_deg: f64,
    cloud: &PointCloud,
) -> Option<crate::ColourAccuracy> {
    let colours = cloud.colors()?;
    crate::colour_accuracy(cloud.positions(), colours, |p| {
        rig.true_colour(motor_deg, p)
            .filter(|t| t.distance_mm <= COLOUR_TRUTH_DISTANCE_MM)
            .map(|t| t.rgb)
    })
}

/// The default rig with its resolution divided by `d` (same field of view and geometry).
pub fn scaled_rig_config(d: u32) -> RigConfig {
    RigConfig::default().downscaled(d)
}

/// The plan and settings of [`capture_virtual`]'s session.
fn virtual_session(
    rig: &VirtualRigs,
    angles_deg: Vec<f64>,
    turntable: &str,
    cfg: &VirtualScanConfig,
    calibration: &Path,
    exposures: SessionExposures,
) -> (SessionPlan, SessionConfig) {
    let psize = rig.left.config().projector.size;
    let mut devices = rig.left.session_devices(turntable);
    if let Some(right) = &rig.right {
        let c = right.config().camera.size;
        devices.right_camera = Some(format!("virtual camera {}x{}", c.width, c.height));
    }
    let mut patterns = scan_patterns_with(
        ImageSize::new(psize.width, psize.height),
        cfg.period_px,
        cfg.phase_steps,
    );
    if let Some(curve) = &rig.precompensation {
        patterns = patterns.precompensated(curve);
    }
    let plan = SessionPlan {
        angles_deg,
        manifest: patterns.manifest(BitDepth::Eight),
        devices,
        calibration: Some(calibration.to_path_buf()),
        exposures,
        colour: cfg.colour,
    };
    let config = SessionConfig {
        display_latency: Duration::ZERO,
        flush_frames: 0,
        overwrite: cfg.overwrite,
        check_frames: true,
    };
    (plan, config)
}

/// Refuses, before anything is written, a scan into `out` whose session folders `dirs`
/// hold sessions of another plan (another `--downscale`, another number of views) — the
/// calibration the scan writes first would otherwise replace the one those sessions were
/// captured with, and then the capture be refused.
pub(crate) fn check_virtual_sessions(
    rig: &VirtualRigs,
    dirs: &[(std::path::PathBuf, Vec<f64>)],
    cfg: &VirtualScanConfig,
    out: &Path,
) -> Result<(), ScanError> {
    for (dir, angles) in dirs {
        // Automatic exposures are those of the session already there (none is measured yet).
        let exposures = planned_exposures(dir, &cfg.exposures, cfg.fusion, cfg.overwrite)?;
        let (plan, config) = virtual_session(
            rig,
            angles.clone(),
            "",
            cfg,
            &out.join("calibration.json"),
            exposures,
        );
        sl_rig::CaptureSession::check(dir, &plan, &config)?;
    }
    Ok(())
}

/// Captures a session of `rig` at the motor angles `angles_deg` into `dir` with the scan's
/// patterns, through the device traits ([`capture_session`], as on real devices), with the
/// virtual rig's session settings: no display latency, nothing to flush. `turntable` names
/// the turntable in the session's devices.
pub(crate) fn capture_virtual(
    rig: &VirtualRigs,
    dir: &Path,
    angles_deg: Vec<f64>,
    turntable: &str,
    cfg: &VirtualScanConfig,
    calibration: &Path,
    progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionSummary, ScanError> {
    // Automatic exposures: measured at the first view through the devices, as on a real rig.
    let (exposures, _) =
        session_exposures(dir, &cfg.exposures, cfg.fusion, cfg.overwrite, |auto| {
            let (mut camera, mut projector, mut table) = rig.left.devices();
            let timing = CaptureTiming {
                settle: Duration::ZERO,
                flush_frames: 0,
            };
            measure_at_first_view(
                (&mut camera, &mut projector, &mut table),
                angles_deg.first().copied().unwrap_or_default(),
                auto,
                timing,
                sl_sim::VIRTUAL_EXPOSURE_MS,
            )
        })?;
    let (plan, config) = virtual_session(rig, angles_deg, turntable, cfg, calibration, exposures);
    match &rig.right {
        None => {
            let (mut camera, mut projector, mut table) = rig.left.devices();
            capture_session(
                dir,
                plan,
                config,
                &mut camera,
                &mut projector,
                &mut table,
                progress,
            )
        }
        Some(right) => {
            let (mut left, mut right, mut projector, mut table) =
                rig.left.binocular_devices(right)?;
            capture_binocular_session(
                dir,
                plan,
                config,
                (&mut left, &mut right),
                &mut projector,
                &mut table,
                progress,
            )
        }
    }
}

/// The virtual rig of a scan: its camera, and the second camera of a binocular scan (the same
/// scene seen from [`RigConfig::default_second_camera`]).
#[derive(Debug, Clone)]
pub(crate) struct VirtualRigs {
    pub(crate) left: VirtualRig,
    pub(crate) right: Option<VirtualRig>,
    /// Where the second camera is in the first's frame.
    pub(crate) second: Option<SecondCamera>,
    /// The response the scan's fringes pre-compensate
    /// ([`ResponseCorrection::Precompensate`]).
    pub(crate) precompensation: Option<sl_codec::ToneCurve>,
}

impl VirtualRigs {
    /// The rig of `config` looking at `scene`, with the camera `second` when there is one.
    pub(crate) fn new(
        config: RigConfig,
        scene: Scene,
        second: Option<&SecondCamera>,
    ) -> Result<Self, ScanError> {
        let right = match second {
            Some(second) => Some(VirtualRig::new(
                config.seen_from(second),
                scene.seen_from(second),
            )?),
            None => None,
        };
        Ok(Self {
            left: VirtualRig::new(config, scene)?,
            right,
            second: second.copied(),
            precompensation: None,
        })
    }

    /// The same cameras looking at `scene`.
    fn with_scene(&self, scene: Scene) -> Result<Self, ScanError> {
        let right = match (&self.right, &self.second) {
            (Some(r), Some(second)) => Some(r.with_scene(scene.seen_from(second))?),
            _ => None,
        };
        Ok(Self {
            left: self.left.with_scene(scene)?,
            right,
            second: self.second,
            precompensation: self.precompensation.clone(),
        })
    }
}

/// Runs the whole scan on the virtual rig into `out`: the estimated calibration
/// (`calibration.json`), the capture session (`session/`, resumed if interrupted), the
/// merged cloud (`merged.ply`), previews (`preview_*.png`) and the error heat map
/// (`error_map.png`). The caller writes the report from the returned [`ScanResult`].
///
/// The scene is the dumbbell (two spheres of 25 mm radius, 120 mm apart) on the turntable.
pub fn scan_virtual(
    cfg: &VirtualScanConfig,
    out: &Path,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<ScanResult, ScanError> {
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
    if cfg.response_correction != ResponseCorrection::None && cfg.binocular {
        return Err(ScanError::InvalidParameter {
            name: "response_correction".to_owned(),
            reason: "applies to one camera: two cameras match codes that the projector's \
                     response bends alike in both"
                .to_owned(),
        });
    }
    if let Some(d) = cfg.projector_distortion {
        config.projector.distortion = d;
    }
    if !(cfg.projector_drift_deg.is_finite() && cfg.projector_drift_deg.abs() <= 90.0) {
        return Err(stage_err(
            "capture",
            format!(
                "projector_drift_deg {} must be a finite angle of at most 90 degrees",
                cfg.projector_drift_deg
            ),
        ));
    }
    // The projector's response, first: pre-compensated patterns need it before any capture.
    let response = measure_virtual_response(&config, cfg, out, &mut stages)?;
    // The second camera stands where the rig puts it, whatever the projector does later.
    let second = cfg.binocular.then(|| config.default_second_camera());
    let calibration_rig = VirtualRigs::new(
        config.clone(),
        Scene::dumbbell().finished(cfg.finish),
        second.as_ref(),
    )?;
    // The rig the scan captures with: the projector drifted after the calibration.
    let rig = if cfg.projector_drift_deg == 0.0 {
        calibration_rig.clone()
    } else {
        let turn = nalgebra::UnitQuaternion::from_axis_angle(
            &nalgebra::Vector3::y_axis(),
            cfg.projector_drift_deg.to_radians(),
        );
        let mut drifted = config;
        drifted.t_cam_proj.rotation *= turn;
        VirtualRigs::new(
            drifted,
            Scene::dumbbell().finished(cfg.finish),
            second.as_ref(),
        )?
    };
    let rig = VirtualRigs {
        precompensation: precompensation(cfg, response.as_ref()),
        ..rig
    };
    let angles = turntable_angles(cfg.views);
    let session_dir = out.join("session");
    let plate_dir = out.join("plate_session");
    let mut sessions = vec![(session_dir.clone(), angles.clone())];
    if cfg.flatness_plate {
        sessions.push((plate_dir.clone(), vec![0.0]));
    }
    check_virtual_sessions(&rig, &sessions, cfg, out)?;

    // 1. Calibrate (and, when asked, measure the projector's response).
    let (calibration, calibration_summary, calib_path) = match &calibration_rig.right {
        None => {
            let (c, summary, path) = calibrate_virtual_stage(
                &calibration_rig.left,
                cfg,
                out,
                &mut stages,
                &mut progress,
                response,
            )?;
            (ScanCalibration::Monocular(c), summary, path)
        }
        Some(right) => {
            let second = calibration_rig
                .second
                .as_ref()
                .ok_or_else(|| stage_err("calibrate", "a second camera's rig without its pose"))?;
            let (c, summary, path) = calibrate_virtual_binocular_stage(
                &calibration_rig.left,
                right,
                second,
                cfg,
                out,
                &mut stages,
                &mut progress,
            )?;
            (ScanCalibration::Binocular(c), summary, path)
        }
    };

    // 2. Capture the turntable session through the device traits.
    let t = Instant::now();
    let summary = capture_virtual(
        &rig,
        &session_dir,
        angles.clone(),
        "virtual turntable",
        cfg,
        &calib_path,
        &mut progress,
    )?;
    stages.push(StageTime::since("capture", t));

    // 3. Reconstruct and merge: the same stages as a scan on real devices. Initial poses
    // from the calibrated turntable axis, or the rig's true poses (diagnostic).
    let poses = cfg.true_poses.then(|| {
        let t_cam_table0 = rig
            .left
            .config()
            .t_cam_table_at(angles.first().copied().unwrap_or(0.0));
        angles
            .iter()
            .map(|&a| t_cam_table0 * rig.left.config().t_cam_table_at(a).inverse())
            .collect::<Vec<Isometry3<f64>>>()
    });
    let scan_config = SessionScanConfig {
        reconstruct: cfg.reconstruct(),
        merge: MergeStageConfig::scan(
            cfg.average_overlaps,
            cfg.smoothing_neighbours,
            !cfg.true_poses,
        ),
        poses,
        binocular: cfg.binocular_options,
        colour: crate::ColourConfig::default(),
    };
    let scan = calibration.scan_session(&session_dir, &scan_config, &mut progress)?;
    stages.extend(scan.stages.iter().cloned());

    // 4. The flatness plate: one more capture, through the same calibration, decoding and
    // triangulation as the turntable views.
    let (plate, plate_phase) = if cfg.flatness_plate {
        let t = Instant::now();
        progress(ScanProgress {
            stage: "plate",
            done: 0,
            total: 1,
        });
        let plate_rig = rig.with_scene(plate_scene())?;
        capture_virtual(
            &plate_rig,
            &plate_dir,
            vec![0.0],
            "none: a flat plate fixed in front of the camera",
            cfg,
            &calib_path,
            |_| {},
        )?;
        let view = plate_dir.join(view_dir_name(0));
        let cloud = match &calibration {
            ScanCalibration::Monocular(c) => reconstruct_view_eroded(
                &view,
                &Triangulator::new(c)?,
                &cfg.reconstruct().for_calibration(c),
            )?,
            ScanCalibration::Binocular(pair) => reconstruct_binocular_view(
                &view,
                &Binocular::new(&pair.left, &pair.right, &pair.t_left_right)?,
                &cfg.reconstruct(),
                &cfg.binocular_options,
            )?,
        };
        write_ply(&out.join("plate.ply"), &cloud, PlyFormat::default())?;
        plate_truth().save(&out.join("plate_truth.json"))?;
        progress(ScanProgress {
            stage: "plate",
            done: 1,
            total: 1,
        });
        // The decoded columns against the rig's truth (one camera: the view's own decode).
        let phase = match &calibration {
            ScanCalibration::Monocular(c) => Some(plate_phase_error(
                &plate_rig.left,
                &view,
                &cfg.reconstruct().for_calibration(c).decode,
                cfg.period_px,
            )?),
            ScanCalibration::Binocular(_) => None,
        };
        stages.push(StageTime::since("plate", t));
        (Some(cloud), phase)
    } else {
        (None, None)
    };

    // 5. Measure against the truth (sl-metrology, from the truth files a user can re-run
    // `slscan report` on).
    let t = Instant::now();
    let truth = scene_truth(&rig.left, angles.first().copied().unwrap_or(0.0));
    truth.save(&out.join("truth.json"))?;
    let measured = measure_scan(&scan.merged, &scan.first_view, &truth, plate.as_ref())?;
    stages.push(StageTime::since("measure", t));

    // 6. Report: the cloud, its previews and the heat maps.
    let t = Instant::now();
    let cloud_files = write_scan_cloud(out, &scan.merged, &mut progress)?;
    let heat_map = "error_map.png".to_owned();
    write_heat_map(&out.join(&heat_map), &scan.merged, &measured.accuracy)?;
    let plate_heat_map = match (&plate, &measured.flatness) {
        (Some(cloud), Some(report)) => {
            let name = "plate_error_map.png".to_owned();
            write_heat_map(&out.join(&name), cloud, report)?;
            Some(name)
        }
        _ => None,
    };
    stages.push(StageTime::since("report", t));

    // 7. The mesh: a watertight surface of the merged cloud, measured like the cloud.
    let (mesh, mesh_files) = match cfg.mesh_depth {
        Some(depth) => {
            let t = Instant::now();
            let poisson = scan_poisson_config(
                &scan.merged,
                scan_config.merge.merge.output_voxel_size,
                depth,
            );
            let (summary, files) = mesh_stage_coloured(
                &scan.merged,
                Some(&measured.accuracy.signed_distances_mm),
                Some(&truth),
                &poisson,
                &cfg.mesh_options,
                scan.colours.as_ref(),
                out,
            )?;
            stages.push(StageTime::since("mesh", t));
            (Some(summary), Some(files))
        }
        None => (None, None),
    };

    // 8. The colours against the true albedo.
    let angle0 = angles.first().copied().unwrap_or(0.0);
    let colour = match &scan.colours {
        Some(c) => {
            let mesh_cloud = match &mesh_files {
                Some(f) => Some(sl_cloud::read_ply(&out.join(&f.ply))?),
                None => None,
            };
            Some(ScanColourReport {
                views: c.views.len(),
                source: c.views.first().map_or("none", |v| v.source.name()),
                cloud: cloud_colour_accuracy(&rig.left, angle0, &scan.merged),
                mesh: mesh_cloud
                    .map(|m| seen_vertices(&m, c))
                    .and_then(|m| cloud_colour_accuracy(&rig.left, angle0, &m)),
            })
        }
        None => None,
    };

    let (calibration, pair) = match calibration {
        ScanCalibration::Monocular(c) => (c, None),
        ScanCalibration::Binocular(pair) => {
            let mut c = Calibration::new(pair.left);
            c.turntable = pair.turntable;
            (c, Some(pair))
        }
    };
    let exposures = sl_rig::read_session_plan(&session_dir)?.exposures;
    Ok(ScanResult {
        calibration,
        pair,
        calibration_summary,
        finish: cfg.finish,
        exposures,
        view_points: scan.view_points,
        views_captured: summary.captured,
        merged: scan.merged,
        merge: scan.merge,
        truth,
        accuracy: measured.accuracy,
        first_view: measured.first_view,
        flatness: measured.flatness,
        plate_phase,
        mesh,
        colour,
        stages,
        files: ScanFiles {
            calibration: "calibration.json".to_owned(),
            session: "session".to_owned(),
            merged: cloud_files.merged,
            previews: cloud_files.previews,
            heat_map,
            truth: "truth.json".to_owned(),
            plate: plate.as_ref().map(|_| "plate.ply".to_owned()),
            plate_truth: plate.as_ref().map(|_| "plate_truth.json".to_owned()),
            plate_heat_map,
            mesh: mesh_files,
        },
    })
}

/// Decoded projector columns against the true ones over a view (projector pixels).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PhaseError {
    /// Pixels compared: decoded, and lit by the projector in the truth.
    pub pixels: usize,
    /// Mean of decoded minus true column.
    pub mean_px: f64,
    /// RMS of decoded minus true column, the mean removed.
    pub rms_px: f64,
    /// The same RMS as a phase (radians of the fringe period).
    pub rms_rad: f64,
    /// 99th percentile of the absolute error, the mean removed.
    pub p99_px: f64,
}

/// Decodes the capture in `view` with `decode` and compares its projector columns with the
/// true ones of `rig` (motor angle 0): how far the decoded phase is from the truth, the
/// figure a projector's response bends (`period_px` turns pixels into radians).
pub(crate) fn plate_phase_error(
    rig: &VirtualRig,
    view: &Path,
    decode: &sl_codec::DecodeConfig,
    period_px: f64,
) -> Result<PhaseError, ScanError> {
    let set = sl_codec::CaptureSet::load(&view.join(sl_codec::MANIFEST_FILE))?;
    let map = sl_codec::decode(&set, decode)?;
    drop(set);
    let truth = rig.view(0.0, 0)?.truth;
    let errors: Vec<f64> = map
        .col
        .iter()
        .zip(&truth.projector)
        .filter(|(c, t)| c.is_finite() && t.x.is_finite())
        .map(|(&c, t)| f64::from(c) - t.x)
        .collect();
    if errors.is_empty() {
        return Err(stage_err("plate", "no pixel of the plate decoded"));
    }
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let mut centred: Vec<f64> = errors.iter().map(|e| (e - mean).abs()).collect();
    let rms = (centred.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    let k = ((centred.len() - 1) as f64 * 0.99) as usize;
    let p99 = *centred.select_nth_unstable_by(k, f64::total_cmp).1;
    Ok(PhaseError {
        pixels: errors.len(),
        mean_px: mean,
        rms_px: rms,
        rms_rad: rms * std::f64::consts::TAU / period_px,
        p99_px: p99,
    })
}

/// The response stage of a scan on the virtual rig of `config`: when `cfg` asks for a
/// correction, the ramp captured on the plate into `out/response/` and measured (timed as
/// `response`), with its figures against the rig's true response.
pub(crate) fn measure_virtual_response(
    config: &RigConfig,
    cfg: &VirtualScanConfig,
    out: &Path,
    stages: &mut Vec<StageTime>,
) -> Result<Option<(sl_codec::ToneCurve, crate::ResponseSummary)>, ScanError> {
    if cfg.response_correction == ResponseCorrection::None {
        return Ok(None);
    }
    let t = Instant::now();
    let m = crate::capture_virtual_ramp(
        config,
        &out.join(crate::RESPONSE_DIR),
        sl_calib::RESPONSE_LEVELS,
    )?;
    let mut summary = crate::ResponseSummary::new(&m, Path::new(crate::RESPONSE_DIR));
    let truth = config
        .render
        .illumination
        .response_curve()
        .unwrap_or_else(sl_codec::ToneCurve::linear);
    summary.truth_difference = Some(m.curve.max_difference(&truth));
    stages.push(StageTime::since("response", t));
    Ok(Some((m.curve, summary)))
}

/// The curve the scan's fringes pre-compensate: the measured response with
/// [`ResponseCorrection::Precompensate`].
pub(crate) fn precompensation(
    cfg: &VirtualScanConfig,
    response: Option<&(sl_codec::ToneCurve, crate::ResponseSummary)>,
) -> Option<sl_codec::ToneCurve> {
    match (cfg.response_correction, response) {
        (ResponseCorrection::Precompensate, Some((curve, _))) => Some(curve.clone()),
        _ => None,
    }
}
