//! A scan from a finished capture session and a calibration file: what `slscan scan` does on
//! the real rig once the devices have captured every view, and what any session (virtual or
//! real) can be reconstructed with again.
//!
//! [`reconstruct_session`] decodes and triangulates every view of a session folder
//! (`sl_rig::CaptureSession`'s format), places each view with the turntable pose of its motor
//! angle through the calibrated axis (`sl_camera::TurntableAxis`, with its angle offset and
//! scale), refines and merges them (`sl_icp::merge_views`). [`write_session_scan`] writes the
//! merged PLY and the previews. [`full_turn_motor_angles`] plans the motor angles of a session
//! so that the *platter* turns a full turn whatever the calibrated gear scale.
//!
//! ```no_run
//! use std::path::Path;
//! use structured_light::session_scan::{
//!     SessionScanConfig, load_scan_calibration, reconstruct_session, write_session_scan,
//! };
//! let calib = load_scan_calibration(Path::new("calibration.json"))?;
//! let scan = reconstruct_session(
//!     Path::new("scan/session"),
//!     &calib,
//!     &SessionScanConfig::default(),
//!     |_| {},
//! )?;
//! let files = write_session_scan(Path::new("scan"), &scan)?;
//! println!("{} points in {}", scan.merged.len(), files.merged);
//! # Ok::<(), structured_light::pipeline::PipelineError>(())
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use sl_camera::{Calibration, TurntableAxis};
use sl_cloud::{PlyFormat, PointCloud, PreviewColoring, PreviewConfig, render_preview, write_ply};
use sl_codec::{MANIFEST_FILE, write_png_rgb8};
use sl_icp::{MergeConfig, merge_aligned, merge_views, turntable_poses};
use sl_rig::{read_session_plan, turntable_angles, view_dir_name};
use sl_tri::Triangulator;

use crate::pipeline::{PipelineError, ScanProgress, StageTime, reconstruct_view_eroded};

/// Viewpoints of the previews: azimuth and elevation (degrees), as the virtual scan's.
const PREVIEWS: [(f64, f64); 4] = [(0.0, 20.0), (90.0, 20.0), (180.0, 20.0), (0.0, 80.0)];

/// Options of [`reconstruct_session`].
#[derive(Debug, Clone)]
pub struct SessionScanConfig {
    /// How the views are registered and merged. Default: `sl_icp::MergeConfig::default()`
    /// with `average_overlaps` on, as `slscan scan` on the virtual rig.
    pub merge: MergeConfig,
    /// Refine the turntable poses by registering the views (`sl_icp::merge_views`): absorbs
    /// the errors of an approximate axis calibration or of a motor that stops off target.
    /// `false` places every view with the calibrated poses alone (`sl_icp::merge_aligned`):
    /// right when the calibration is good and the views are too far apart or too symmetric
    /// for ICP (a dumbbell seen every 45° leaves ICP a free rotation about the bar). Default
    /// `true`, as the virtual scan.
    pub icp_refinement: bool,
    /// Points within this many pixels of a pixel without a valid point are dropped from each
    /// view (silhouettes, rims: see [`crate::pipeline::VirtualScanConfig::edge_erosion_px`]).
    /// Default 3, as the virtual scan.
    pub edge_erosion_px: usize,
}

impl Default for SessionScanConfig {
    fn default() -> Self {
        Self {
            merge: MergeConfig {
                average_overlaps: true,
                ..MergeConfig::default()
            },
            icp_refinement: true,
            edge_erosion_px: 3,
        }
    }
}

/// A session reconstructed and merged by [`reconstruct_session`].
#[derive(Debug, Clone)]
pub struct SessionScan {
    /// The session folder.
    pub session: PathBuf,
    /// Motor angles of the views (degrees), as the session recorded them.
    pub motor_angles_deg: Vec<f64>,
    /// Platter angles of the views (degrees) through the calibrated offset and scale.
    pub platter_angles_deg: Vec<f64>,
    /// Points triangulated in each view.
    pub view_points: Vec<usize>,
    /// The merged cloud (mm, camera frame of view 0).
    pub merged: PointCloud,
    /// Wall time per stage (`reconstruct`, `merge`).
    pub stages: Vec<StageTime>,
}

/// Files written by [`write_session_scan`], relative to the output folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SessionScanFiles {
    /// The merged cloud.
    pub merged: String,
    /// Shaded previews from several viewpoints.
    pub previews: Vec<String>,
}

fn stage_err(stage: &str, reason: impl Into<String>) -> PipelineError {
    PipelineError::Stage {
        stage: stage.to_owned(),
        reason: reason.into(),
    }
}

/// The turntable axis of `calibration`, read from `path`; an error naming the file and the
/// command that adds the axis when it has none.
///
/// # Errors
/// [`PipelineError::Stage`] (stage `calibration`) when the calibration has no turntable axis.
pub fn require_turntable_axis(
    calibration: &Calibration,
    path: &Path,
) -> Result<TurntableAxis, PipelineError> {
    calibration.turntable.ok_or_else(|| {
        stage_err(
            "calibration",
            format!(
                "{}: no turntable axis: a turntable scan needs it to place the views; add it with `slscan calibrate turntable SESSION --calib {} --out DIR` (or calibrate everything with `slscan calibrate all`)",
                path.display(),
                path.display()
            ),
        )
    })
}

/// Loads a calibration file for a turntable scan and checks that it holds what a scan needs:
/// the camera, the projector with its pose, and the turntable axis.
///
/// # Errors
/// [`PipelineError::Camera`] when the file cannot be read; [`PipelineError::Stage`] naming the
/// file and what is missing otherwise.
pub fn load_scan_calibration(path: &Path) -> Result<Calibration, PipelineError> {
    let calibration = Calibration::load(path)?;
    if calibration.projector.is_none() || calibration.t_cam_proj.is_none() {
        return Err(stage_err(
            "calibration",
            format!(
                "{}: no projector calibration: a scan needs the projector and its pose; calibrate them with `slscan calibrate projector` (or `slscan calibrate all`)",
                path.display()
            ),
        ));
    }
    require_turntable_axis(&calibration, path)?;
    Ok(calibration)
}

/// Motor angles (degrees) of `views` views that turn the *platter* a full turn in equal steps
/// from motor angle 0, through the calibrated scale (`θ = angle_scale · m + offset`):
/// `m_k = 360° k / (views · angle_scale)`. Without an axis (or with scale 1) these are the
/// angles of `sl_rig::turntable_angles`.
///
/// # Errors
/// [`PipelineError::Stage`] when the scale is zero or not finite.
pub fn full_turn_motor_angles(
    axis: Option<&TurntableAxis>,
    views: usize,
) -> Result<Vec<f64>, PipelineError> {
    let scale = axis.map_or(1.0, |a| a.angle_scale);
    if !scale.is_finite() || scale == 0.0 {
        return Err(stage_err(
            "capture",
            format!("turntable.angle_scale {scale}: must be finite and non-zero"),
        ));
    }
    Ok(turntable_angles(views)
        .into_iter()
        .map(|a| a / scale)
        .collect())
}

/// Decodes and triangulates every view of the capture session in `session_dir` with
/// `calibration`, then merges the views: the pose of each view comes from the calibrated
/// turntable axis and the motor angle the session recorded, refined by `sl_icp::merge_views`
/// when [`SessionScanConfig::icp_refinement`] is on.
///
/// # Errors
/// [`PipelineError::Rig`] when `session.json` cannot be read; [`PipelineError::Stage`] naming
/// the view and its folder when a view is missing, incomplete or cannot be decoded, or when no
/// point is triangulated in it; the calibration's errors (no turntable axis, no projector);
/// the merge's errors.
pub fn reconstruct_session(
    session_dir: &Path,
    calibration: &Calibration,
    config: &SessionScanConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionScan, PipelineError> {
    let plan = read_session_plan(session_dir)?;
    let angles = plan.angles_deg;
    if angles.len() < 2 {
        return Err(stage_err(
            "reconstruct",
            format!(
                "{}: a turntable scan needs at least 2 views, the session has {}",
                session_dir.display(),
                angles.len()
            ),
        ));
    }
    let axis = require_turntable_axis(
        calibration,
        plan.calibration
            .as_deref()
            .unwrap_or(Path::new("the calibration")),
    )?;
    let mut stages = Vec::new();
    let total = angles.len();

    let t = Instant::now();
    let triangulator = Triangulator::new(calibration)?;
    let mut clouds = Vec::with_capacity(total);
    for k in 0..total {
        let dir = session_dir.join(view_dir_name(k));
        let resume = "resume the capture with the same command (finished views are kept)";
        if !dir.join(MANIFEST_FILE).is_file() {
            return Err(stage_err(
                "reconstruct",
                format!(
                    "view {k} ({}): not captured or interrupted (no {MANIFEST_FILE}); {resume}",
                    dir.display()
                ),
            ));
        }
        let cloud = reconstruct_view_eroded(&dir, &triangulator, config.edge_erosion_px).map_err(|e| {
            stage_err(
                "reconstruct",
                format!(
                    "view {k} ({}): {e}; recapture it with `--overwrite` or delete the folder and {resume}",
                    dir.display()
                ),
            )
        })?;
        if cloud.is_empty() {
            return Err(stage_err(
                "reconstruct",
                format!(
                    "view {k} ({}): no point triangulated (is the projector on, the object lit and in focus?)",
                    dir.display()
                ),
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
    stages.push(StageTime {
        name: "reconstruct".to_owned(),
        ms: t.elapsed().as_secs_f64() * 1e3,
    });

    let t = Instant::now();
    progress(ScanProgress {
        stage: "merge",
        done: 0,
        total: 1,
    });
    let initial = turntable_poses(&axis, &angles)?;
    let merged = if config.icp_refinement {
        merge_views(&clouds, &initial, &config.merge)?.cloud
    } else {
        merge_aligned(&clouds, &initial, &config.merge)?
    };
    progress(ScanProgress {
        stage: "merge",
        done: 1,
        total: 1,
    });
    stages.push(StageTime {
        name: "merge".to_owned(),
        ms: t.elapsed().as_secs_f64() * 1e3,
    });
    Ok(SessionScan {
        session: session_dir.to_path_buf(),
        platter_angles_deg: angles.iter().map(|&m| axis.table_angle_deg(m)).collect(),
        motor_angles_deg: angles,
        view_points,
        merged,
        stages,
    })
}

/// Writes the merged cloud (`merged.ply`) and shaded previews (`preview_*.png`) of `scan`
/// into `out` (created when missing).
///
/// # Errors
/// [`PipelineError::Io`] naming the folder; the PLY's and the pictures' errors.
pub fn write_session_scan(
    out: &Path,
    scan: &SessionScan,
) -> Result<SessionScanFiles, PipelineError> {
    std::fs::create_dir_all(out).map_err(|source| PipelineError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let merged = "merged.ply".to_owned();
    write_ply(&out.join(&merged), &scan.merged, PlyFormat::default())?;
    let mut previews = Vec::with_capacity(PREVIEWS.len());
    for (k, &(azimuth_deg, elevation_deg)) in PREVIEWS.iter().enumerate() {
        let name = format!("preview_{k}.png");
        let cfg = PreviewConfig {
            azimuth_deg,
            elevation_deg,
            ..PreviewConfig::default()
        };
        let img = render_preview(&scan.merged, PreviewColoring::Grey, &cfg)?;
        write_png_rgb8(
            &out.join(&name),
            img.width as usize,
            img.height as usize,
            &img.rgb,
        )?;
        previews.push(name);
    }
    Ok(SessionScanFiles { merged, previews })
}
