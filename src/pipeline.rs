//! The end-to-end scan on the virtual rig, as one library call: calibrate from simulated
//! board captures, capture a turntable session of a known object, decode, triangulate, merge,
//! and measure the result against the truth with `sl-metrology` (the dumbbell for the probing
//! and sphere-spacing errors, then one capture of a tilted flat plate for the flatness).
//! `slscan scan` is a thin wrapper around [`scan_virtual`]; `tests/scan_pipeline.rs` runs it
//! small.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;
use sl_calib::{
    BoardSize, ProcamConfig, ProcamView, TurntableConfig, TurntableView, calibrate_procam,
    calibrate_turntable,
};
use sl_camera::{Calibration, ImageSize, Intrinsics};
use sl_cloud::{PlyFormat, PointCloud, PreviewColoring, PreviewConfig, render_preview, write_ply};
use sl_codec::{
    Axis, BitDepth, CaptureSet, DecodeConfig, Frame, Frames, HybridSpec, MANIFEST_FILE, Pattern,
    PatternSequence, ProjectorSize, decode, write_png_rgb8,
};
use sl_icp::{MergeConfig, merge_aligned, merge_views, turntable_poses};
use sl_metrology::{
    DEFAULT_HEAT_MAP_RANGE_MM, Feature, PlaneNominal, PlaneSpec, Report, SpherePairSpec,
    SphereSpec, Truth, evaluate, heat_map,
};
use sl_rig::{
    CaptureSession, GreyImage, Pixels, SessionConfig, SessionDevices, SessionPlan, turntable_angles,
};
use sl_sim::{
    BoardPoseConfig, Checkerboard, DEFAULT_ALBEDO, DEFAULT_WORKING_DISTANCE_MM, Mount, RigConfig,
    Scene, SceneObject, Shape, Texture, VirtualRig, capture_board, capture_board_on_table,
    random_board_poses,
};
use sl_tri::{TriOptions, Triangulator};

/// Everything that can stop the pipeline: the error of the crate that failed, or a file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// The devices or the capture session.
    #[error(transparent)]
    Rig(#[from] sl_rig::RigError),
    /// The virtual rig.
    #[error(transparent)]
    Sim(#[from] sl_sim::SimError),
    /// Calibration.
    #[error("calibration: {0}")]
    Calib(#[from] sl_calib::CalibError),
    /// Patterns, decoding or image files.
    #[error(transparent)]
    Codec(#[from] sl_codec::CodecError),
    /// Triangulation.
    #[error(transparent)]
    Tri(#[from] sl_tri::TriError),
    /// Measuring the result against the truth.
    #[error("report: {0}")]
    Metrology(#[from] sl_metrology::MetrologyError),
    /// Registration and merging.
    #[error("merge: {0}")]
    Icp(#[from] sl_icp::IcpError),
    /// Point-cloud files and previews.
    #[error(transparent)]
    Cloud(#[from] sl_cloud::CloudError),
    /// Calibration files.
    #[error(transparent)]
    Camera(#[from] sl_camera::CameraError),
    /// A stage found nothing to work on (no board found, an empty view, ...).
    #[error("{stage}: {reason}")]
    Stage {
        /// The stage (`calibrate`, `reconstruct`, ...).
        stage: String,
        /// What went wrong.
        reason: String,
    },
    /// A file could not be written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
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
    /// Width of one fringe period on the projector (projector pixels). Default 15: the
    /// finest period the rendered projector blur still resolves with good modulation
    /// (`docs/triangulation.md`).
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
}

impl Default for VirtualScanConfig {
    fn default() -> Self {
        Self {
            views: 36,
            calibration_poses: 12,
            table_angles_deg: (-3..=3).map(|k| f64::from(k) * 15.0).collect(),
            resolution_divisor: 1,
            seed: 0,
            period_px: 15.0,
            overwrite: false,
            average_overlaps: true,
            flatness_plate: true,
            max_view_angle_deg: 90.0,
            true_calibration: false,
            true_poses: false,
            smoothing_neighbours: 16,
            edge_erosion_px: 3,
        }
    }
}

/// Progress of [`scan_virtual`]: `done` of `total` steps of `stage`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScanProgress<'a> {
    /// The stage: `calibrate`, `capture`, `reconstruct`, `merge`, `plate` (when
    /// [`VirtualScanConfig::flatness_plate`]), `report`.
    pub stage: &'a str,
    /// Steps done.
    pub done: usize,
    /// Steps of the stage.
    pub total: usize,
}

/// Wall time of one stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageTime {
    /// Stage name.
    pub name: String,
    /// Milliseconds.
    pub ms: f64,
}

/// How the calibration was obtained and how far it is from the rig's truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationSummary {
    /// Where each part of the calibration comes from.
    pub sources: Vec<String>,
    /// Board poses used / rendered.
    pub poses_used: usize,
    /// RMS reprojection errors (px): camera alone, projector alone, joint.
    pub rms_camera_px: f64,
    /// See `rms_camera_px`.
    pub rms_projector_px: f64,
    /// See `rms_camera_px`.
    pub rms_stereo_px: f64,
    /// RMS of the turntable-axis fit (px).
    pub rms_turntable_px: f64,
    /// Relative error of the camera's `fx` against the truth (%).
    pub camera_fx_error_percent: f64,
    /// Relative error of the projector's `fx` against the truth (%).
    pub projector_fx_error_percent: f64,
    /// Error of the camera–projector translation (mm).
    pub baseline_error_mm: f64,
    /// Angle between the fitted and the true axis direction (degrees).
    pub axis_direction_error_deg: f64,
    /// Distance of the true axis point to the fitted axis line, near the object (mm).
    pub axis_position_error_mm: f64,
}

/// Half-width of the selection region of every feature of the scene's truth (mm): points
/// within 2 mm of a true surface — 40 times the 0.05 mm probing target — are measured, so
/// only mis-decoded or mis-merged points are left out.
pub const SELECT_MM: f64 = 2.0;

/// The flat plate of the flatness measurement: 160 × 100 mm.
pub const PLATE_SIZE_MM: (f64, f64) = (160.0, 100.0);

/// Tilt of the plate about the camera's vertical and horizontal axes (degrees): VDI/VDE 2634
/// part 2 measures flatness in several oblique positions; one such position, at the working
/// distance, is measured here.
pub const PLATE_TILT_DEG: (f64, f64) = (25.0, 15.0);

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
}

/// Everything [`scan_virtual`] produced.
#[derive(Debug, Clone)]
pub struct ScanResult {
    /// The estimated calibration used for the scan.
    pub calibration: Calibration,
    /// How good it is.
    pub calibration_summary: CalibrationSummary,
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
    /// Wall time per stage, in order.
    pub stages: Vec<StageTime>,
    /// The files written.
    pub files: ScanFiles,
}

/// Viewpoints of the previews: azimuth and elevation (degrees).
const PREVIEWS: [(f64, f64); 4] = [(0.0, 20.0), (90.0, 20.0), (180.0, 20.0), (0.0, 80.0)];

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> PipelineError + '_ {
    move |source| PipelineError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn stage_err(stage: &str, reason: impl Into<String>) -> PipelineError {
    PipelineError::Stage {
        stage: stage.to_owned(),
        reason: reason.into(),
    }
}

/// The default rig with its resolution divided by `d` (same field of view and geometry).
pub fn scaled_rig_config(d: u32) -> RigConfig {
    let mut c = RigConfig::default();
    if d > 1 {
        let f = f64::from(d);
        for m in [&mut c.camera, &mut c.projector] {
            let k = m.intrinsics;
            m.intrinsics = Intrinsics::new(
                k.fx / f,
                k.fy / f,
                (k.cx + 0.5) / f - 0.5,
                (k.cy + 0.5) / f - 0.5,
            );
            m.size = ImageSize::new(m.size.width / d, m.size.height / d);
        }
    }
    c
}

fn grey_image(img: GreyImage, what: &str) -> Result<sl_calib::image::GrayImage, PipelineError> {
    let px = match img.pixels {
        Pixels::U8(p) => p,
        Pixels::U16(p) => p.into_iter().map(|v| (v >> 8) as u8).collect(),
    };
    sl_calib::image::GrayImage::from_raw(img.width, img.height, px)
        .ok_or_else(|| stage_err("calibrate", format!("{what}: bad image buffer")))
}

fn frames_u8(images: Vec<GreyImage>) -> Result<Frames, PipelineError> {
    let frames = images
        .into_iter()
        .map(|img| {
            let (w, h) = (img.width as usize, img.height as usize);
            let g = grey_image(img, "frame")?;
            Ok(Frame::new(w, h, g.into_raw())?)
        })
        .collect::<Result<Vec<_>, PipelineError>>()?;
    Ok(Frames::U8(frames))
}

/// Calibrates the rig from simulated board captures: camera, projector and `T_cam_proj` by
/// `sl_calib::calibrate_procam`, the turntable axis by `sl_calib::calibrate_turntable`.
pub fn calibrate_virtual(
    rig: &VirtualRig,
    cfg: &VirtualScanConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<(Calibration, CalibrationSummary), PipelineError> {
    let config = rig.config();
    let board = Checkerboard::default();
    let poses = random_board_poses(
        config,
        &board,
        &BoardPoseConfig {
            count: cfg.calibration_poses,
            seed: cfg.seed,
            ..BoardPoseConfig::default()
        },
    )?;
    let p = ProjectorSize::new(config.projector.size.width, config.projector.size.height);
    // Both axes coded (the projector needs rows and columns), ~30 projector px per period,
    // 4 phase steps (8 halve the phase noise but double the rendering time of this stage).
    let sequence = PatternSequence::new(p)
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Column,
            p,
            4,
            f64::from(p.width) / 30.0,
        )))
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Row,
            p,
            4,
            f64::from(p.height) / 30.0,
        )));
    let manifest = sequence.manifest(BitDepth::Eight);
    let total = poses.len() + cfg.table_angles_deg.len();
    let mut views = Vec::with_capacity(poses.len());
    for (k, pose) in poses.iter().enumerate() {
        let cap = capture_board(rig, &board, pose, Some(&sequence), k as u64)?;
        let set = CaptureSet::from_frames(manifest.clone(), frames_u8(cap.frames)?)?;
        views.push(ProcamView {
            name: format!("board pose {k}"),
            lit: grey_image(cap.white, "white")?,
            map: decode(&set, &DecodeConfig::default())?,
        });
        progress(ScanProgress {
            stage: "calibrate",
            done: k + 1,
            total,
        });
    }
    let size = BoardSize::new(board.inner_cols, board.inner_rows);
    let procam = calibrate_procam(
        &views,
        &ProcamConfig::new(size, board.square_mm, config.projector.size),
    )?;
    drop(views);
    let mut table_views = Vec::new();
    for (k, &angle) in cfg.table_angles_deg.iter().enumerate() {
        let index = (poses.len() + k) as u64;
        let cap = capture_board_on_table(rig, &board, angle, None, index)?;
        let label = format!("board on the turntable at {angle} degrees");
        table_views.push(TurntableView::detect(
            &grey_image(cap.white, &label)?,
            &label,
            angle,
            size,
            board.square_mm,
            &sl_calib::DetectorConfig::default(),
        )?);
        progress(ScanProgress {
            stage: "calibrate",
            done: poses.len() + k + 1,
            total,
        });
    }
    let table = calibrate_turntable(
        &procam.camera.camera,
        &table_views,
        &TurntableConfig::default(),
    )?;
    let mut calibration = procam.to_calibration();
    calibration.turntable = Some(table.axis);
    calibration.metadata.notes = "estimated by slscan scan from simulated board captures of the virtual rig (sl_calib::calibrate_procam, sl_calib::calibrate_turntable)".to_owned();

    let truth_axis = config.turntable_axis();
    let d_est = table.axis.direction.normalize();
    let d_true = truth_axis.direction.normalize();
    let direction_error = d_est
        .dot(&d_true)
        .abs()
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    // Distance from the true axis point (on the table, under the object) to the fitted line.
    let off = truth_axis.point_mm - table.axis.point_mm;
    let position_error = (off - d_est * off.dot(&d_est)).norm();
    let rel = |a: f64, b: f64| 100.0 * (a - b) / b;
    let summary = CalibrationSummary {
        sources: vec![
            "camera, projector, T_cam_proj: sl_calib::calibrate_procam on simulated board captures"
                .to_owned(),
            "turntable axis: sl_calib::calibrate_turntable on the board standing on the simulated turntable".to_owned(),
        ],
        poses_used: procam.views.len(),
        rms_camera_px: procam.rms_camera,
        rms_projector_px: procam.rms_projector,
        rms_stereo_px: procam.rms_stereo,
        rms_turntable_px: table.rms,
        camera_fx_error_percent: rel(
            procam.camera.camera.intrinsics.fx,
            config.camera.intrinsics.fx,
        ),
        projector_fx_error_percent: rel(
            procam.projector.camera.intrinsics.fx,
            config.projector.intrinsics.fx,
        ),
        baseline_error_mm: (procam.t_cam_proj.translation.vector
            - config.t_cam_proj.translation.vector)
            .norm(),
        axis_direction_error_deg: direction_error,
        axis_position_error_mm: position_error,
    };
    Ok((calibration, summary))
}

/// Phase steps of the scan's hybrid code. 8 rather than 4: with 15 px fringes the plane
/// flatness RMS falls from 0.0214 to 0.0154 mm (issue 6's target is 0.02 mm) for 4 more
/// frames per view (24 instead of 20; `docs/triangulation.md`, rendered accuracy).
pub const SCAN_PHASE_STEPS: u32 = 8;

/// The scan's pattern sequence: hybrid code on the projector columns, [`SCAN_PHASE_STEPS`]
/// phase steps, periods of `period_px` projector pixels.
pub fn scan_patterns(projector: ProjectorSize, period_px: f64) -> PatternSequence {
    PatternSequence::new(projector).with(Pattern::Hybrid(HybridSpec::complementary(
        Axis::Column,
        projector,
        SCAN_PHASE_STEPS,
        f64::from(projector.width) / period_px,
    )))
}

/// Decodes and triangulates one capture set (folder with `manifest.json`).
pub fn reconstruct_view(
    dir: &Path,
    triangulator: &Triangulator,
) -> Result<PointCloud, PipelineError> {
    reconstruct_view_eroded(dir, triangulator, 0)
}

/// [`reconstruct_view`], then drops the points within `edge_erosion_px` pixels of an invalid
/// pixel (see [`VirtualScanConfig::edge_erosion_px`]).
pub fn reconstruct_view_eroded(
    dir: &Path,
    triangulator: &Triangulator,
    edge_erosion_px: usize,
) -> Result<PointCloud, PipelineError> {
    let set = CaptureSet::load(&dir.join(MANIFEST_FILE))?;
    let map = decode(&set, &DecodeConfig::default())?;
    drop(set);
    let tri = triangulator.triangulate(&map, &TriOptions::default())?;
    if edge_erosion_px == 0 {
        return Ok(tri.cloud);
    }
    // Erode the valid mask one 4-connected step at a time.
    let (w, h) = (tri.width, tri.height);
    let mut valid: Vec<bool> = tri
        .status
        .iter()
        .map(|s| *s == sl_tri::PointStatus::Valid)
        .collect();
    for _ in 0..edge_erosion_px {
        let prev = valid.clone();
        let at = |x: usize, y: usize| prev.get(y * w + x).copied().unwrap_or(false);
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if prev[i] {
                    let inner = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                    valid[i] =
                        inner && at(x - 1, y) && at(x + 1, y) && at(x, y - 1) && at(x, y + 1);
                }
            }
        }
    }
    let keep: Vec<usize> = tri
        .cloud_pixels
        .iter()
        .enumerate()
        .filter(|(_, px)| valid.get(**px as usize).copied().unwrap_or(false))
        .map(|(i, _)| i)
        .collect();
    Ok(tri.cloud.select(&keep)?)
}

/// The rig's exact calibration, as [`calibrate_virtual`] would return it (diagnostic runs).
fn true_calibration(rig: &VirtualRig) -> (Calibration, CalibrationSummary) {
    let summary = CalibrationSummary {
        sources: vec!["the rig's true calibration (diagnostic run, nothing estimated)".to_owned()],
        poses_used: 0,
        rms_camera_px: 0.0,
        rms_projector_px: 0.0,
        rms_stereo_px: 0.0,
        rms_turntable_px: 0.0,
        camera_fx_error_percent: 0.0,
        projector_fx_error_percent: 0.0,
        baseline_error_mm: 0.0,
        axis_direction_error_deg: 0.0,
        axis_position_error_mm: 0.0,
    };
    (rig.config().calibration(), summary)
}

/// Drops the points of one view (camera frame) whose normal is more than `max_angle_deg` from
/// the direction to the camera (the origin) or to the projector centre. Points without a
/// normal (zero vector) are kept; `max_angle_deg >= 90` keeps everything.
pub fn drop_grazing(
    cloud: PointCloud,
    projector_centre: &nalgebra::Point3<f64>,
    max_angle_deg: f64,
) -> Result<PointCloud, PipelineError> {
    if max_angle_deg.is_nan() || max_angle_deg <= 0.0 {
        return Err(stage_err(
            "reconstruct",
            format!("max_view_angle_deg {max_angle_deg} must be positive"),
        ));
    }
    if max_angle_deg >= 90.0 {
        return Ok(cloud);
    }
    let Some(normals) = cloud.normals() else {
        return Ok(cloud);
    };
    let min_cos = max_angle_deg.to_radians().cos();
    let seen = |p: &nalgebra::Point3<f64>, n: &Vector3<f64>, from: &nalgebra::Point3<f64>| {
        let to = from - p;
        let len = to.norm();
        len > 0.0 && n.dot(&to).abs() >= min_cos * len
    };
    let origin = nalgebra::Point3::origin();
    let keep: Vec<usize> = cloud
        .positions()
        .iter()
        .zip(normals)
        .enumerate()
        .filter(|(_, (p, n))| {
            n.norm_squared() == 0.0 || (seen(p, n, &origin) && seen(p, n, projector_centre))
        })
        .map(|(i, _)| i)
        .collect();
    Ok(cloud.select(&keep)?)
}

/// The truth of the rig's scene seen at motor angle `motor_deg`, in the camera frame: every
/// sphere with its true centre and radius, and — for the first two spheres — their true centre
/// distance (the dumbbell's sphere spacing). Selection regions of [`SELECT_MM`].
pub fn scene_truth(rig: &VirtualRig, motor_deg: f64) -> Truth {
    let t_cam_table = rig.config().t_cam_table_at(motor_deg);
    let mut truth = Truth::new(format!(
        "virtual rig scene at motor angle {motor_deg} degrees, camera frame (mm)"
    ));
    let mut centres = Vec::new();
    for o in &rig.scene().objects {
        if let Shape::Sphere { radius } = o.shape {
            let pose = match o.mount {
                Mount::Turntable => t_cam_table * o.pose,
                Mount::Camera => o.pose,
            };
            let centre = nalgebra::Point3::from(pose.translation.vector);
            centres.push((o.name.clone(), centre));
            truth = truth.with(Feature::Sphere(SphereSpec {
                name: o.name.clone(),
                radius_mm: radius,
                centre_mm: Some(centre),
                select_mm: SELECT_MM,
            }));
        }
    }
    if let [(n0, c0), (n1, c1), ..] = centres.as_slice() {
        truth = truth.with(Feature::SpherePair(SpherePairSpec {
            name: format!("{n0}-{n1}"),
            spheres: [n0.clone(), n1.clone()],
            centre_distance_mm: (c0 - c1).norm(),
        }));
    }
    truth
}

/// `T_cam_plate` of the flatness plate: centred on the optical axis at the working distance,
/// turned [`PLATE_TILT_DEG`] about the camera's y and x axes.
pub fn plate_pose() -> Isometry3<f64> {
    let (yaw, pitch) = PLATE_TILT_DEG;
    Isometry3::from_parts(
        Translation3::new(0.0, 0.0, DEFAULT_WORKING_DISTANCE_MM),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), yaw.to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), pitch.to_radians()),
    )
}

/// The flatness scene: the plate of [`PLATE_SIZE_MM`] at [`plate_pose`], fixed in the camera
/// frame (the turntable does not move it).
pub fn plate_scene() -> Scene {
    let (w, h) = PLATE_SIZE_MM;
    Scene::new().with(SceneObject::in_camera(
        "plate",
        Shape::rectangle(w, h),
        Texture::Uniform(DEFAULT_ALBEDO),
        plate_pose(),
    ))
}

/// The truth of [`plate_scene`]: its plane, in the camera frame.
pub fn plate_truth() -> Truth {
    let pose = plate_pose();
    let normal = pose.rotation * Vector3::z();
    Truth::new("flat plate of the virtual rig, camera frame (mm)").with(Feature::Plane(PlaneSpec {
        name: "plate".to_owned(),
        nominal: Some(PlaneNominal {
            normal,
            offset_mm: normal.dot(&pose.translation.vector),
        }),
        select_mm: SELECT_MM,
    }))
}

/// Writes the heat map of `report` over `cloud` to `path`.
pub fn write_heat_map(
    path: &Path,
    cloud: &PointCloud,
    report: &Report,
) -> Result<(), PipelineError> {
    let view = PreviewConfig {
        azimuth_deg: 0.0,
        elevation_deg: 20.0,
        ..PreviewConfig::default()
    };
    let img = heat_map(
        cloud,
        &report.signed_distances_mm,
        DEFAULT_HEAT_MAP_RANGE_MM,
        &view,
    )?;
    write_png_rgb8(path, img.width as usize, img.height as usize, &img.rgb)?;
    Ok(())
}

fn write_preview(
    path: &Path,
    cloud: &PointCloud,
    coloring: PreviewColoring<'_>,
    azimuth_deg: f64,
    elevation_deg: f64,
) -> Result<(), PipelineError> {
    let cfg = PreviewConfig {
        azimuth_deg,
        elevation_deg,
        ..PreviewConfig::default()
    };
    let img = render_preview(cloud, coloring, &cfg)?;
    write_png_rgb8(path, img.width as usize, img.height as usize, &img.rgb)?;
    Ok(())
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
) -> Result<ScanResult, PipelineError> {
    if cfg.views < 2 {
        return Err(stage_err(
            "capture",
            "a turntable scan needs at least 2 views",
        ));
    }
    std::fs::create_dir_all(out).map_err(io(out))?;
    let mut stages = Vec::new();
    let mut timed = |name: &str, t: Instant| {
        stages.push(StageTime {
            name: name.to_owned(),
            ms: t.elapsed().as_secs_f64() * 1e3,
        });
    };
    let mut config = scaled_rig_config(cfg.resolution_divisor);
    config.render.seed = cfg.seed;
    let rig = VirtualRig::new(config, Scene::dumbbell())?;

    // 1. Calibrate.
    let t = Instant::now();
    let (calibration, calibration_summary) = if cfg.true_calibration {
        true_calibration(&rig)
    } else {
        calibrate_virtual(&rig, cfg, &mut progress)?
    };
    let calib_path = out.join("calibration.json");
    calibration.save(&calib_path)?;
    timed("calibrate", t);

    // 2. Capture the turntable session through the device traits.
    let t = Instant::now();
    let psize = rig.config().projector.size;
    let projector = ProjectorSize::new(psize.width, psize.height);
    let angles = turntable_angles(cfg.views);
    let csize = rig.config().camera.size;
    let plan = SessionPlan {
        angles_deg: angles.clone(),
        manifest: scan_patterns(projector, cfg.period_px).manifest(BitDepth::Eight),
        devices: SessionDevices {
            camera: format!("virtual camera {}x{}", csize.width, csize.height),
            projector: format!("virtual projector {}x{}", psize.width, psize.height),
            turntable: "virtual turntable".to_owned(),
        },
        calibration: Some(calib_path.clone()),
    };
    let session_dir = out.join("session");
    let session = CaptureSession::open(
        &session_dir,
        plan,
        SessionConfig {
            display_latency: Duration::ZERO,
            flush_frames: 0,
            overwrite: cfg.overwrite,
        },
    )?;
    let (mut camera, mut proj, mut table) = rig.devices();
    let total = cfg.views;
    let summary = session.run(&mut camera, &mut proj, &mut table, |v| {
        progress(ScanProgress {
            stage: "capture",
            done: v.index + 1,
            total,
        });
    })?;
    timed("capture", t);

    // 3. Decode and triangulate every view.
    let t = Instant::now();
    let triangulator = Triangulator::new(&calibration)?;
    let projector_centre = calibration
        .t_cam_proj
        .map(|t| nalgebra::Point3::from(t.translation.vector))
        .ok_or_else(|| stage_err("reconstruct", "the calibration has no projector pose"))?;
    let mut clouds = Vec::with_capacity(cfg.views);
    for (k, dir) in session.view_dirs().iter().enumerate() {
        let cloud = drop_grazing(
            reconstruct_view_eroded(dir, &triangulator, cfg.edge_erosion_px)?,
            &projector_centre,
            cfg.max_view_angle_deg,
        )?;
        if cloud.is_empty() {
            return Err(stage_err(
                "reconstruct",
                format!("{}: no point triangulated", dir.display()),
            ));
        }
        clouds.push(cloud);
        progress(ScanProgress {
            stage: "reconstruct",
            done: k + 1,
            total,
        });
    }
    let view_points = clouds.iter().map(PointCloud::len).collect();
    timed("reconstruct", t);

    // 4. Merge with initial poses from the calibrated turntable axis.
    let t = Instant::now();
    progress(ScanProgress {
        stage: "merge",
        done: 0,
        total: 1,
    });
    let axis = calibration
        .turntable
        .ok_or_else(|| stage_err("merge", "the calibration has no turntable axis"))?;
    let initial = turntable_poses(&axis, &angles)?;
    let merge = MergeConfig {
        average_overlaps: cfg.average_overlaps,
        output_normal_neighbours: cfg.smoothing_neighbours,
        // The free pose graph (sl-icp's default), said explicitly: with sl-icp's turntable
        // pose model this scan's spheres came out 0.5 mm too small in diameter (form 0.9 mm)
        // at full resolution and 0.77 mm at half (2026-11-23 19:52 UTC; `PoseModel::default`).
        pose_model: sl_icp::PoseModel::Free,
        ..MergeConfig::default()
    };
    let first_view = clouds.first().cloned().unwrap_or_default();
    let merged = if cfg.true_poses {
        let t_cam_table0 = rig
            .config()
            .t_cam_table_at(angles.first().copied().unwrap_or(0.0));
        let poses: Vec<Isometry3<f64>> = angles
            .iter()
            .map(|&a| t_cam_table0 * rig.config().t_cam_table_at(a).inverse())
            .collect();
        merge_aligned(&clouds, &poses, &merge)?
    } else {
        merge_views(&clouds, &initial, &merge)?.cloud
    };
    drop(clouds);
    let merged_path = out.join("merged.ply");
    write_ply(&merged_path, &merged, PlyFormat::default())?;
    progress(ScanProgress {
        stage: "merge",
        done: 1,
        total: 1,
    });
    timed("merge", t);

    // 5. The flatness plate: one more capture, through the same calibration, decoding and
    // triangulation as the turntable views.
    let plate = if cfg.flatness_plate {
        let t = Instant::now();
        progress(ScanProgress {
            stage: "plate",
            done: 0,
            total: 1,
        });
        let plate_rig = rig.with_scene(plate_scene())?;
        let plan = SessionPlan {
            angles_deg: vec![0.0],
            manifest: scan_patterns(projector, cfg.period_px).manifest(BitDepth::Eight),
            devices: SessionDevices {
                camera: format!("virtual camera {}x{}", csize.width, csize.height),
                projector: format!("virtual projector {}x{}", psize.width, psize.height),
                turntable: "none: a flat plate fixed in front of the camera".to_owned(),
            },
            calibration: Some(calib_path.clone()),
        };
        let plate_session = CaptureSession::open(
            &out.join("plate_session"),
            plan,
            SessionConfig {
                display_latency: Duration::ZERO,
                flush_frames: 0,
                overwrite: cfg.overwrite,
            },
        )?;
        let (mut camera, mut proj, mut table) = plate_rig.devices();
        plate_session.run(&mut camera, &mut proj, &mut table, |_| {})?;
        let dir = plate_session
            .view_dirs()
            .into_iter()
            .next()
            .ok_or_else(|| stage_err("plate", "the plate session has no view"))?;
        let cloud = reconstruct_view_eroded(&dir, &triangulator, cfg.edge_erosion_px)?;
        write_ply(&out.join("plate.ply"), &cloud, PlyFormat::default())?;
        plate_truth().save(&out.join("plate_truth.json"))?;
        progress(ScanProgress {
            stage: "plate",
            done: 1,
            total: 1,
        });
        timed("plate", t);
        Some(cloud)
    } else {
        None
    };

    // 6. Accuracy (sl-metrology, from the truth files a user can re-run `slscan report` on)
    // and pictures.
    let t = Instant::now();
    let truth = scene_truth(&rig, angles.first().copied().unwrap_or(0.0));
    truth.save(&out.join("truth.json"))?;
    let accuracy = evaluate(&merged, &truth)?;
    let first_view = evaluate(&first_view, &truth)?;
    let flatness = match &plate {
        Some(cloud) => Some(evaluate(cloud, &plate_truth())?),
        None => None,
    };
    let mut previews = Vec::new();
    for (k, &(az, el)) in PREVIEWS.iter().enumerate() {
        let name = format!("preview_{k}.png");
        write_preview(&out.join(&name), &merged, PreviewColoring::Grey, az, el)?;
        previews.push(name);
        progress(ScanProgress {
            stage: "report",
            done: k + 1,
            total: PREVIEWS.len() + 1,
        });
    }
    let heat_map = "error_map.png".to_owned();
    write_heat_map(&out.join(&heat_map), &merged, &accuracy)?;
    let plate_heat_map = match (&plate, &flatness) {
        (Some(cloud), Some(report)) => {
            let name = "plate_error_map.png".to_owned();
            write_heat_map(&out.join(&name), cloud, report)?;
            Some(name)
        }
        _ => None,
    };
    timed("report", t);

    Ok(ScanResult {
        calibration,
        calibration_summary,
        view_points,
        views_captured: summary.captured,
        merged,
        truth,
        accuracy,
        first_view,
        flatness,
        stages,
        files: ScanFiles {
            calibration: "calibration.json".to_owned(),
            session: "session".to_owned(),
            merged: "merged.ply".to_owned(),
            previews,
            heat_map,
            truth: "truth.json".to_owned(),
            plate: plate.as_ref().map(|_| "plate.ply".to_owned()),
            plate_truth: plate.as_ref().map(|_| "plate_truth.json".to_owned()),
            plate_heat_map,
        },
    })
}

/// Writes `index.html`: a one-page summary linking the pictures and figures of a scan.
pub fn write_summary_html(out: &Path, result: &ScanResult) -> Result<PathBuf, PipelineError> {
    let a = &result.accuracy;
    let c = &result.calibration_summary;
    let mut rows = String::new();
    for s in &a.spheres {
        rows.push_str(&format!(
            "<tr><td>{}</td><td>{}</td><td>{:.4}</td><td>{:+.4}</td><td>{:.4}</td><td>{:.4}</td></tr>\n",
            s.name,
            s.points,
            s.radius_mm,
            s.probing_size_mm,
            s.probing_form_mm,
            s.probing_form_trimmed_mm
        ));
    }
    let spacing: String = a
        .sphere_pairs
        .iter()
        .map(|p| {
            format!(
                "Sphere-spacing error ({}) {:+.4} mm. ",
                p.name, p.sphere_spacing_mm
            )
        })
        .collect();
    let flatness: String = match (&result.flatness, &result.files.plate_heat_map) {
        (Some(f), Some(heat)) => f
            .planes
            .iter()
            .map(|p| {
                format!(
                    "<h2>Flatness (tilted plate)</h2>\n<p>{} points; flatness {:.4} mm, {:.4} mm with 0.3 % left out; RMS to the fitted plane {:.4} mm. Cloud <a href=\"plate.ply\">plate.ply</a>, truth <a href=\"plate_truth.json\">plate_truth.json</a>.</p>\n<p><a href=\"{heat}\"><img src=\"{heat}\" width=\"480\"></a></p>\n",
                    p.points, p.flatness_mm, p.flatness_trimmed_mm, p.fit_rms_mm
                )
            })
            .collect(),
        _ => String::new(),
    };
    let stages: String = result
        .stages
        .iter()
        .map(|s| format!("<tr><td>{}</td><td>{:.2} s</td></tr>", s.name, s.ms / 1e3))
        .collect();
    let imgs: String = result
        .files
        .previews
        .iter()
        .map(|p| format!("<a href=\"{p}\"><img src=\"{p}\" width=\"320\"></a>\n"))
        .collect();
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>slscan scan</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}td,th{{padding:2px 10px;text-align:right}}</style>
</head><body>
<h1>Virtual-rig scan: dumbbell on the turntable</h1>
<p>{views} views, {points} merged points: <a href="{merged}">{merged}</a>; calibration <a href="{calib}">{calib}</a>; figures <a href="report.json">report.json</a>; frames in <a href="{session}/">{session}/</a>.</p>
{imgs}
<h2>Accuracy against the truth</h2>
<p>Measured by sl-metrology against <a href="{truth}">{truth}</a> (<code>slscan report {merged} --truth {truth}</code> gives the same figures). RMS distance to the true surface {rms:.4} mm in the estimated camera frame (largest {max:.3} mm; {outliers} points farther than 2 mm from every sphere are left out). {spacing}</p>
<table><tr><th>sphere</th><th>points</th><th>radius (mm)</th><th>probing size (mm)</th><th>probing form (mm)</th><th>form, 0.3 % trimmed (mm)</th></tr>
{rows}</table>
<p>Probing form: range of the radial residuals of the least-squares sphere over all its points, and with the 0.3 % farthest left out as VDI/VDE 2634 part 2 allows.</p>
<p><a href="{heat}"><img src="{heat}" width="480"></a><br>Signed distance to the true surface, blue −{range} mm to red +{range} mm.</p>
{flatness}<h2>Calibration (estimated from simulated board captures)</h2>
<p>RMS camera {rc:.3} px, projector {rp:.3} px, stereo {rs:.3} px, turntable {rt:.3} px; camera fx error {fxc:+.4} %, projector fx error {fxp:+.4} %, baseline error {base:.3} mm; axis direction error {ad:.4}°, position error {ap:.3} mm.</p>
<h2>Stages</h2>
<table>{stages}</table>
</body></html>
"#,
        views = result.view_points.len(),
        points = result.merged.len(),
        merged = result.files.merged,
        calib = result.files.calibration,
        session = result.files.session,
        truth = result.files.truth,
        rms = a.rms_to_reference_mm,
        max = a.max_to_reference_mm,
        outliers = a.points - a.assigned_points,
        heat = result.files.heat_map,
        range = DEFAULT_HEAT_MAP_RANGE_MM,
        rc = c.rms_camera_px,
        rp = c.rms_projector_px,
        rs = c.rms_stereo_px,
        rt = c.rms_turntable_px,
        fxc = c.camera_fx_error_percent,
        fxp = c.projector_fx_error_percent,
        base = c.baseline_error_mm,
        ad = c.axis_direction_error_deg,
        ap = c.axis_position_error_mm,
    );
    let path = out.join("index.html");
    std::fs::write(&path, html).map_err(io(&path))?;
    Ok(path)
}
