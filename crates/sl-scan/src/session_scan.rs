//! A turntable scan from a finished capture session and a calibration: the reconstruction and
//! merge stages run in turn ([`reconstruct_session`], [`merge_scan`]). `slscan scan` runs it
//! on the real rig once the devices have captured every view, and on the virtual rig
//! ([`scan_virtual`](crate::scan_virtual)) after the same capture stage; any session can be
//! reconstructed with it again.
//!
//! ```no_run
//! use std::path::Path;
//! use sl_scan::{SessionScanConfig, load_scan_calibration, scan_session, write_scan_cloud};
//! let calib = load_scan_calibration(Path::new("calibration.json"))?;
//! let scan = scan_session(
//!     Path::new("scan/session"),
//!     &calib,
//!     &SessionScanConfig::default(),
//!     |_| {},
//! )?;
//! let files = write_scan_cloud(Path::new("scan"), &scan.merged, |_| {})?;
//! println!("{} points in {}", scan.merged.len(), files.merged);
//! # Ok::<(), sl_scan::ScanError>(())
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::Isometry3;
use sl_camera::{BinocularCalibration, Calibration, CameraModel, TurntableAxis};
use sl_cloud::PointCloud;
use sl_tri::BinocularConfig;

use crate::{
    ColourConfig, ColourView, MergeReport, MergeStageConfig, ReconstructConfig, ReconstructedViews,
    ScanColours, ScanError, ScanProgress, StageTime, merge_scan, reconstruct_binocular_session,
    reconstruct_session,
};

/// Options of [`scan_session`].
#[derive(Debug, Clone, Default)]
pub struct SessionScanConfig {
    /// The reconstruction of each view.
    pub reconstruct: ReconstructConfig,
    /// The registration and merge of the views.
    pub merge: MergeStageConfig,
    /// Initial poses of the views instead of the calibrated turntable's (diagnostic: the
    /// virtual rig's true poses). Default `None`.
    pub poses: Option<Vec<Isometry3<f64>>>,
    /// The matching between the two cameras of a session captured with two
    /// ([`ScanCalibration::Binocular`]); unused with one camera.
    pub binocular: BinocularConfig,
    /// How the views' colours are blended on the surface.
    pub colour: ColourConfig,
}

/// The calibration a turntable scan reconstructs with: one camera and the projector
/// ([`scan_session`]), or two cameras, the projector only labelling the surface
/// ([`scan_binocular_session`]). Either holds the turntable axis the views are placed by.
#[derive(Debug, Clone, PartialEq)]
pub enum ScanCalibration {
    /// The camera, the projector and its pose (`calibration.json`).
    Monocular(Calibration),
    /// Two cameras and their relative pose (`stereo.json`, as `slscan calibrate stereo` writes
    /// it); the session's views hold the second camera's frames in `view_NNN/right/`.
    Binocular(BinocularCalibration),
}

impl ScanCalibration {
    /// The turntable axis, when calibrated.
    pub fn turntable(&self) -> Option<&TurntableAxis> {
        match self {
            Self::Monocular(c) => c.turntable.as_ref(),
            Self::Binocular(p) => p.turntable.as_ref(),
        }
    }

    /// Whether the scan needs the second camera's frames.
    pub fn is_binocular(&self) -> bool {
        matches!(self, Self::Binocular(_))
    }

    /// Reconstructs and merges the session in `session_dir` with this calibration:
    /// [`scan_session`] or [`scan_binocular_session`] (with `config.binocular`).
    ///
    /// # Errors
    /// Those of the two.
    pub fn scan_session(
        &self,
        session_dir: &Path,
        config: &SessionScanConfig,
        progress: impl FnMut(ScanProgress<'_>),
    ) -> Result<SessionScan, ScanError> {
        match self {
            Self::Monocular(c) => scan_session(session_dir, c, config, progress),
            Self::Binocular(p) => scan_binocular_session(session_dir, p, config, progress),
        }
    }
}

impl From<Calibration> for ScanCalibration {
    fn from(c: Calibration) -> Self {
        Self::Monocular(c)
    }
}

impl From<BinocularCalibration> for ScanCalibration {
    fn from(p: BinocularCalibration) -> Self {
        Self::Binocular(p)
    }
}

/// A session reconstructed and merged by [`scan_session`].
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
    /// The first view alone, before the merge (camera frame of view 0).
    pub first_view: PointCloud,
    /// The merged cloud (mm, camera frame of view 0).
    pub merged: PointCloud,
    /// Where each view's pose came from (the merge's report).
    pub merge: MergeReport,
    /// Wall time per stage (`reconstruct`, `merge`).
    pub stages: Vec<StageTime>,
    /// The views' colours placed by the merge's poses, when the views have colour
    /// ([`crate::ColourMode`]): what colours the mesh.
    pub colours: Option<ScanColours>,
}

/// Reconstructs every view of the capture session in `session_dir` with `calibration`, then
/// merges the views ([`reconstruct_session`], then [`merge_scan`]).
///
/// # Errors
/// Those of [`reconstruct_session`] and [`merge_scan`].
pub fn scan_session(
    session_dir: &Path,
    calibration: &Calibration,
    config: &SessionScanConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionScan, ScanError> {
    let t = Instant::now();
    let views = reconstruct_session(session_dir, calibration, &config.reconstruct, &mut progress)?;
    merge_views(views, Some(&calibration.camera), t, config, progress)
}

/// [`scan_session`] for a session captured with two cameras: each view matched and
/// triangulated between the cameras ([`reconstruct_binocular_session`] with the two-camera
/// calibration `pair`, which holds the turntable axis, and `config.binocular`), then merged as
/// [`scan_session`] does.
/// The merged cloud is in the left camera's frame of view 0.
///
/// # Errors
/// Those of [`reconstruct_binocular_session`] and [`merge_scan`].
pub fn scan_binocular_session(
    session_dir: &Path,
    pair: &BinocularCalibration,
    config: &SessionScanConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionScan, ScanError> {
    let t = Instant::now();
    let views = reconstruct_binocular_session(
        session_dir,
        pair,
        &config.reconstruct,
        &config.binocular,
        &mut progress,
    )?;
    merge_views(views, None, t, config, progress)
}

/// The merge stage of both scans, `t` the start of their reconstruction; `camera` took the
/// views' colours.
fn merge_views(
    views: ReconstructedViews,
    camera: Option<&CameraModel>,
    t: Instant,
    config: &SessionScanConfig,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionScan, ScanError> {
    let mut stages = vec![StageTime::since("reconstruct", t)];
    let t = Instant::now();
    let merged = merge_scan(
        &views,
        config.poses.as_deref(),
        &config.merge,
        &mut progress,
    )?;
    stages.push(StageTime::since("merge", t));
    let colours = camera.and_then(|camera| {
        let placed: Vec<ColourView> = views
            .colours
            .into_iter()
            .zip(&merged.poses)
            .filter_map(|(c, pose)| {
                c.map(|c| ColourView {
                    t_world_view: *pose,
                    ..c
                })
            })
            .collect();
        (!placed.is_empty()).then_some(ScanColours {
            camera: *camera,
            views: placed,
            config: config.colour,
        })
    });
    Ok(SessionScan {
        session: views.session,
        platter_angles_deg: views
            .motor_angles_deg
            .iter()
            .map(|&m| views.axis.table_angle_deg(m))
            .collect(),
        motor_angles_deg: views.motor_angles_deg,
        view_points: views.clouds.iter().map(PointCloud::len).collect(),
        first_view: views.clouds.into_iter().next().unwrap_or_default(),
        merged: merged.cloud,
        merge: merged.report,
        stages,
        colours,
    })
}
