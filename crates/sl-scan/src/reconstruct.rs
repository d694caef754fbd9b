//! The reconstruction stage: each view of a capture session decoded (`sl-codec`) and
//! triangulated (`sl-tri`) into a cloud in the camera frame, with the points at the edges of
//! the valid region and, on request, those seen or lit at a grazing angle dropped.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Vector3};
use sl_camera::{BinocularCalibration, Calibration, TurntableAxis};
use sl_cloud::PointCloud;
use sl_codec::{
    CaptureSet, ColourImage, ColourSource, CorrespondenceMap, DecodeConfig, MANIFEST_FILE,
    SmoothConfig, capture_in_colour, decode, ramp_stair_codes, read_capture_colour,
    smooth_correspondences,
};
use sl_rig::{RIGHT_DIR, read_session_plan, view_dir_name};
use sl_tri::{Binocular, BinocularConfig, Texture, TriConfig, Triangulator};

use crate::calibrate::require_turntable_axis;
use crate::colour::{ColourMode, ColourView};
use crate::error::stage_err;
use crate::{ScanError, ScanProgress};

/// Options of [`reconstruct_session`].
#[derive(Debug, Clone, PartialEq)]
pub struct ReconstructConfig {
    /// Points within this many pixels (4-connected steps) of a pixel without a valid point —
    /// the silhouette of the object, the edge of a plate, the rim of a hole — are dropped from
    /// each view: their camera pixel or the projector's blurred stripe straddles the edge, so
    /// their depth mixes two surfaces, and the mixed-pixel filter cannot see it where the
    /// other side is empty. Default 3: on the default virtual scan it takes the probing form
    /// from 0.22 to 0.15 mm (0.15 to 0.12 mm with 0.3 % left out) and the plate's flatness
    /// from 0.41 to 0.22 mm, for 5 % of the points (`docs/user-guide.md`).
    pub edge_erosion_px: usize,
    /// Points whose surface normal is more than this far (degrees) from the direction to the
    /// camera or to the projector are dropped from each view ([`drop_grazing`]). Default 90:
    /// every point is kept.
    pub max_view_angle_deg: f64,
    /// Smoothing of the decoded projector coordinates before triangulation
    /// ([`sl_codec::smooth_correspondences`]); `None` triangulates each pixel's own decode.
    /// Default: a 3 × 3 binomial window, which divides the per-point noise by 2.7 for half a
    /// pixel of lateral resolution (`docs/triangulation.md`).
    pub smoothing: Option<SmoothConfig>,
    /// The decoders' thresholds and options. Default [`DecodeConfig::default`]; a session
    /// reconstructed with a calibration that holds the projector's response decodes with it
    /// ([`Self::for_calibration`]).
    pub decode: DecodeConfig,
    /// Whether the views' clouds carry colour ([`ColourMode`]). Default
    /// [`ColourMode::Auto`]: when the capture holds colour.
    pub colour: ColourMode,
}

impl Default for ReconstructConfig {
    fn default() -> Self {
        Self {
            edge_erosion_px: 3,
            max_view_angle_deg: 90.0,
            smoothing: Some(SmoothConfig::default()),
            decode: DecodeConfig::default(),
            colour: ColourMode::Auto,
        }
    }
}

impl ReconstructConfig {
    /// Each pixel's own decode, every point kept: what [`reconstruct_view`] does.
    pub fn raw() -> Self {
        Self {
            edge_erosion_px: 0,
            max_view_angle_deg: 90.0,
            smoothing: None,
            decode: DecodeConfig::default(),
            colour: ColourMode::Auto,
        }
    }

    /// These settings for views triangulated with `calibration`: when the decode settings
    /// name no projector response and the calibration holds one (`slscan calibrate
    /// response`), the phase is corrected with the calibration's.
    pub fn for_calibration(&self, calibration: &Calibration) -> Self {
        let mut config = self.clone();
        if config.decode.projector_response.is_none() {
            config
                .decode
                .projector_response
                .clone_from(&calibration.projector_response);
        }
        config
    }
}

/// The views of a session reconstructed by [`reconstruct_session`].
#[derive(Debug, Clone)]
pub struct ReconstructedViews {
    /// The session folder.
    pub session: PathBuf,
    /// Motor angles of the views (degrees), as the session recorded them.
    pub motor_angles_deg: Vec<f64>,
    /// The calibrated turntable axis the views are placed with.
    pub axis: TurntableAxis,
    /// One cloud per view (mm, camera frame), in the session's order.
    pub clouds: Vec<PointCloud>,
    /// Each view's colour image and depth map when it has colour ([`ColourMode`]), its pose
    /// still the identity: [`merge_scan`](crate::merge_scan) places them.
    pub colours: Vec<Option<ColourView>>,
}

/// Decodes and triangulates one capture set (folder with `manifest.json`): each pixel's own
/// decode, every point kept ([`ReconstructConfig::raw`]).
pub fn reconstruct_view(dir: &Path, triangulator: &Triangulator) -> Result<PointCloud, ScanError> {
    reconstruct_view_eroded(dir, triangulator, &ReconstructConfig::raw())
}

/// Decodes one capture set, smooths the decoded coordinates
/// ([`ReconstructConfig::smoothing`]), triangulates, then drops the points within
/// [`ReconstructConfig::edge_erosion_px`] pixels of an invalid pixel.
pub fn reconstruct_view_eroded(
    dir: &Path,
    triangulator: &Triangulator,
    config: &ReconstructConfig,
) -> Result<PointCloud, ScanError> {
    Ok(reconstruct_view_coloured(dir, triangulator, config)?.0)
}

/// [`reconstruct_view_eroded`] with the view's colour ([`ReconstructConfig::colour`]): the
/// cloud's points coloured from the capture's colour image
/// ([`sl_codec::read_capture_colour`]), and the image with the view's depth map (its pose the
/// identity), `None` without colour.
///
/// # Errors
/// As [`reconstruct_view_eroded`]; [`ScanError::Stage`] naming the colour file when its size
/// is not the frames'.
pub fn reconstruct_view_coloured(
    dir: &Path,
    triangulator: &Triangulator,
    config: &ReconstructConfig,
) -> Result<(PointCloud, Option<ColourView>), ScanError> {
    let manifest = dir.join(MANIFEST_FILE);
    let set = CaptureSet::load(&manifest)?;
    let colour = match config.colour {
        ColourMode::Never => None,
        ColourMode::Always => Some(read_capture_colour(&manifest)?),
        // A grey capture is told from its manifest and its first frame's header: its frames
        // are not read twice.
        ColourMode::Auto if capture_in_colour(&manifest)? => {
            let c = read_capture_colour(&manifest)?;
            (c.source == ColourSource::ColourFrame || c.has_chroma()).then_some(c)
        }
        ColourMode::Auto => None,
    };
    let map = decode(&set, &config.decode)?;
    drop(set);
    if let Some(c) = &colour
        && (c.image.width(), c.image.height()) != (map.width, map.height)
    {
        return Err(stage_err(
            "reconstruct",
            format!(
                "the colour image {} is {}x{}, the frames {}x{}",
                c.files
                    .first()
                    .map(|f| f.display().to_string())
                    .unwrap_or_default(),
                c.image.width(),
                c.image.height(),
                map.width,
                map.height
            ),
        ));
    }
    let (cloud, depth_mm) = reconstruct_decoded_coloured(
        &map,
        triangulator,
        &TriConfig::default(),
        config,
        colour.as_ref().map(|c| &c.image),
    )?;
    Ok((
        cloud,
        colour.map(|c| ColourView {
            t_world_view: Isometry3::identity(),
            image: c.image,
            depth_mm,
            source: c.source,
        }),
    ))
}

/// Triangulates a decoded map as a scan does: the coordinates smoothed
/// ([`ReconstructConfig::smoothing`]), triangulated with `options`, then the points within
/// [`ReconstructConfig::edge_erosion_px`] pixels of an invalid pixel dropped. (The grazing
/// filter, [`ReconstructConfig::max_view_angle_deg`], is [`drop_grazing`]'s.)
pub fn reconstruct_decoded(
    map: &CorrespondenceMap,
    triangulator: &Triangulator,
    options: &TriConfig,
    config: &ReconstructConfig,
) -> Result<PointCloud, ScanError> {
    Ok(reconstruct_decoded_coloured(map, triangulator, options, config, None)?.0)
}

/// [`reconstruct_decoded`] with the points coloured from `colour` (camera-sized), and (with
/// a colour) the depth map of the points kept (mm, camera z; NaN at the other pixels, the
/// eroded rim included); without a colour the depth map is empty.
///
/// # Errors
/// As [`reconstruct_decoded`]; [`ScanError::Tri`] when `colour` is not the map's size.
pub fn reconstruct_decoded_coloured(
    map: &CorrespondenceMap,
    triangulator: &Triangulator,
    options: &TriConfig,
    config: &ReconstructConfig,
    colour: Option<&ColourImage>,
) -> Result<(PointCloud, Vec<f32>), ScanError> {
    let edge_erosion_px = config.edge_erosion_px;
    let smoothed;
    let map = match &config.smoothing {
        Some(smooth) => {
            smoothed = smooth_correspondences(map, smooth)?;
            &smoothed
        }
        None => map,
    };
    let texture = colour.map(|c| Texture::Rgb8(c.data()));
    let tri = triangulator.triangulate_textured(map, texture, options)?;
    // The depth of the pixels that give a point (the others NaN): what the view saw, for the
    // colour's visibility test; the eroded rim is cleared below with the points.
    let mut depth_mm = Vec::new();
    if colour.is_some() {
        depth_mm = tri.depth_map();
        for (d, s) in depth_mm.iter_mut().zip(&tri.status) {
            if *s != sl_tri::PointStatus::Valid {
                *d = f32::NAN;
            }
        }
    }
    if edge_erosion_px == 0 {
        return Ok((tri.cloud, depth_mm));
    }
    let mut valid: Vec<bool> = tri
        .status
        .iter()
        .map(|s| *s == sl_tri::PointStatus::Valid)
        .collect();
    erode(&mut valid, tri.width, tri.height, edge_erosion_px);
    // A pixel of the rim mixes the surface with what lies beside it, in colour as in depth.
    for (d, v) in depth_mm.iter_mut().zip(&valid) {
        if !v {
            *d = f32::NAN;
        }
    }
    let keep: Vec<usize> = tri
        .cloud_pixels
        .iter()
        .enumerate()
        .filter(|(_, px)| valid.get(**px as usize).copied().unwrap_or(false))
        .map(|(i, _)| i)
        .collect();
    Ok((tri.cloud.select(&keep)?, depth_mm))
}

/// Erodes the `w × h` mask `valid` by `steps` 4-connected steps: a pixel stays valid only when
/// it and its four neighbours were (pixels on the image border never stay).
fn erode(valid: &mut [bool], w: usize, h: usize, steps: usize) {
    for _ in 0..steps {
        let prev = valid.to_vec();
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
}

/// Decodes the two capture sets of one view of a binocular rig (`dir` the left camera's,
/// `dir/right` the right camera's) and matches and triangulates them as a scan does: a Gray
/// code's stripes made ramps ([`sl_codec::ramp_stair_codes`]), both maps smoothed ([`ReconstructConfig::smoothing`]), the pixels within
/// [`ReconstructConfig::edge_erosion_px`] of an undecoded pixel cleared in both (the silhouette
/// and the rims, whose codes mix two surfaces), then [`Binocular::reconstruct`]. The cloud is
/// in the left camera's frame.
///
/// # Errors
/// The capture sets' and the decoder's; [`ScanError::Tri`] when a capture's frames are not
/// its camera's size.
pub fn reconstruct_binocular_view(
    dir: &Path,
    pair: &Binocular,
    config: &ReconstructConfig,
    options: &BinocularConfig,
) -> Result<PointCloud, ScanError> {
    let mut maps = Vec::with_capacity(2);
    for d in [dir.to_path_buf(), dir.join(RIGHT_DIR)] {
        let set = CaptureSet::load(&d.join(MANIFEST_FILE))?;
        let mut map = decode(&set, &config.decode)?;
        drop(set);
        // A Gray code's whole-number stripes as ramps: the matching needs codes that vary
        // within a stripe (phase codes are left as they are).
        ramp_stair_codes(&mut map);
        let mut map = match &config.smoothing {
            Some(smooth) => smooth_correspondences(&map, smooth)?,
            None => map,
        };
        if config.edge_erosion_px > 0 {
            let mut valid: Vec<bool> = map.col.iter().map(|c| c.is_finite()).collect();
            erode(&mut valid, map.width, map.height, config.edge_erosion_px);
            for (i, keep) in valid.into_iter().enumerate() {
                if !keep {
                    map.col[i] = f32::NAN;
                    map.row[i] = f32::NAN;
                }
            }
        }
        maps.push(map);
    }
    Ok(pair.reconstruct(&maps[0], &maps[1], options)?.cloud)
}

/// Drops the points of one view (camera frame) whose normal is more than `max_angle_deg` from
/// the direction to the camera (the origin) or to the projector centre. Points without a
/// normal (zero vector) are kept; `max_angle_deg >= 90` keeps everything.
pub fn drop_grazing(
    cloud: PointCloud,
    projector_centre: &Point3<f64>,
    max_angle_deg: f64,
) -> Result<PointCloud, ScanError> {
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
    let seen = |p: &Point3<f64>, n: &Vector3<f64>, from: &Point3<f64>| {
        let to = from - p;
        let len = to.norm();
        len > 0.0 && n.dot(&to).abs() >= min_cos * len
    };
    let origin = Point3::origin();
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

/// Decodes and triangulates every view of the capture session in `session_dir` with
/// `calibration` ([`reconstruct_view_eroded`], then [`drop_grazing`]), reporting each view as
/// progress of the stage `reconstruct`.
///
/// # Errors
/// [`ScanError::Rig`] when `session.json` cannot be read; [`ScanError::Stage`] naming the
/// view and its folder when a view is missing, incomplete or cannot be decoded, or when no
/// point is triangulated in it, and when the session has fewer than 2 views or the
/// calibration no turntable axis or no projector.
pub fn reconstruct_session(
    session_dir: &Path,
    calibration: &Calibration,
    config: &ReconstructConfig,
    progress: impl FnMut(ScanProgress<'_>),
) -> Result<ReconstructedViews, ScanError> {
    let plan = read_session_plan(session_dir)?;
    let axis = require_turntable_axis(
        calibration,
        plan.calibration
            .as_deref()
            .unwrap_or(Path::new("the calibration")),
    )?;
    let triangulator = Triangulator::new(calibration)?;
    let projector_centre = calibration
        .t_cam_proj
        .map(|t| Point3::from(t.translation.vector))
        .ok_or_else(|| stage_err("reconstruct", "the calibration has no projector pose"))?;
    let grazing = (projector_centre, config.max_view_angle_deg);
    let config = &config.for_calibration(calibration);
    reconstruct_views(
        session_dir,
        plan.angles_deg,
        axis,
        grazing,
        progress,
        |dir| reconstruct_view_coloured(dir, &triangulator, config),
    )
}

/// [`reconstruct_session`] for a session captured with two cameras (each view's `right/`
/// folder holds the right camera's capture, `docs/capture-format.md`): each view matched and
/// triangulated by [`reconstruct_binocular_view`] with the two-camera calibration `pair`, then
/// [`drop_grazing`] against the left and the right camera (a point both cameras must see).
/// The clouds are in the left camera's frame; the views are placed with `pair.turntable`.
///
/// # Errors
/// As [`reconstruct_session`]; [`ScanError::Stage`] when `pair` has no turntable axis.
pub fn reconstruct_binocular_session(
    session_dir: &Path,
    pair: &BinocularCalibration,
    config: &ReconstructConfig,
    options: &BinocularConfig,
    progress: impl FnMut(ScanProgress<'_>),
) -> Result<ReconstructedViews, ScanError> {
    let plan = read_session_plan(session_dir)?;
    let axis = pair.turntable.ok_or_else(|| {
        stage_err(
            "calibration",
            format!(
                "{}: the two-camera calibration has no turntable axis: a turntable scan needs it to place the views",
                plan.calibration
                    .as_deref()
                    .unwrap_or(Path::new("the calibration"))
                    .display()
            ),
        )
    })?;
    options.validate()?;
    let rectified = Binocular::new(&pair.left, &pair.right, &pair.t_left_right)?;
    let right_centre = Point3::from(pair.t_left_right.translation.vector);
    let grazing = (right_centre, config.max_view_angle_deg);
    reconstruct_views(
        session_dir,
        plan.angles_deg,
        axis,
        grazing,
        progress,
        |dir| {
            Ok((
                reconstruct_binocular_view(dir, &rectified, config, options)?,
                None,
            ))
        },
    )
}

/// The loop of [`reconstruct_session`] and [`reconstruct_binocular_session`]: each view's
/// folder checked, reconstructed by `view` (named in its errors), the points seen at a grazing
/// angle from the camera or from `grazing.0` dropped ([`drop_grazing`] with the angle
/// `grazing.1`), and reported as progress.
fn reconstruct_views(
    session_dir: &Path,
    angles: Vec<f64>,
    axis: TurntableAxis,
    grazing: (Point3<f64>, f64),
    mut progress: impl FnMut(ScanProgress<'_>),
    mut view: impl FnMut(&Path) -> Result<(PointCloud, Option<ColourView>), ScanError>,
) -> Result<ReconstructedViews, ScanError> {
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
    let total = angles.len();
    let mut clouds = Vec::with_capacity(total);
    let mut colours = Vec::with_capacity(total);
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
        let (cloud, colour) = view(&dir).map_err(|e| {
            stage_err(
                "reconstruct",
                format!(
                    "view {k} ({}): {e}; recapture it with `--overwrite` or delete the folder and {resume}",
                    dir.display()
                ),
            )
        })?;
        let cloud = drop_grazing(cloud, &grazing.0, grazing.1)?;
        if cloud.is_empty() {
            return Err(stage_err(
                "reconstruct",
                format!(
                    "view {k} ({}): no point triangulated (is the projector on, the object lit and in focus? A dark object needs a longer exposure, or several: `--exposures auto`)",
                    dir.display()
                ),
            ));
        }
        clouds.push(cloud);
        colours.push(colour);
        progress(ScanProgress {
            stage: "reconstruct",
            done: k + 1,
            total,
        });
    }
    Ok(ReconstructedViews {
        session: session_dir.to_path_buf(),
        motor_angles_deg: angles,
        axis,
        clouds,
        colours,
    })
}
