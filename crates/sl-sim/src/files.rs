//! Writing what the virtual rig knows beyond its frames: the ground truth beside a capture set,
//! and the rig's exact calibration.

use std::path::{Path, PathBuf};

use serde::Serialize;
use sl_camera::{BinocularCalibration, Calibration, Metadata};
use sl_codec::{Frame, write_png_grey8, write_tiff_f32};

use crate::{RigConfig, SimError, ViewTruth};

/// Name of the ground-truth folder inside a view's folder.
pub const TRUTH_DIR: &str = "truth";
/// Name of the JSON file describing a view's poses inside [`TRUTH_DIR`].
pub const VIEW_JSON: &str = "view.json";

impl RigConfig {
    /// The exact calibration of the rig in the project's calibration file format: camera and
    /// projector models, `T_cam_proj` and the turntable axis, with zero RMS errors.
    pub fn calibration(&self) -> Calibration {
        let mut c = Calibration::new(self.camera);
        c.projector = Some(self.projector);
        c.t_cam_proj = Some(self.t_cam_proj);
        c.turntable = Some(self.turntable_axis());
        c.metadata = Metadata {
            notes: "exact calibration of the sl-sim virtual rig (ground truth)".to_owned(),
            ..c.metadata
        };
        c
    }

    /// The exact two-camera calibration of the rig with its default second camera
    /// ([`RigConfig::default_second_camera`]): both camera models, `T_left_right` and the
    /// turntable axis in the first camera's frame (no projector: two cameras do not need it).
    pub fn binocular_calibration(&self) -> BinocularCalibration {
        let second = self.default_second_camera();
        let mut pair = BinocularCalibration::new(self.camera, second.camera, second.t_cam_second);
        pair.turntable = Some(self.turntable_axis());
        pair.metadata.notes = "the virtual rig's true two-camera calibration".to_owned();
        pair
    }
}

/// The poses of one view, as written to `truth/view.json`.
#[derive(Debug, Clone, Serialize)]
struct ViewFile<'a> {
    motor_angle_deg: f64,
    platter_angle_deg: f64,
    /// `T_cam_table` as a 4x4 row-major matrix.
    t_cam_table: [[f64; 4]; 4],
    objects: Vec<ObjectFile<'a>>,
    width: u32,
    height: u32,
    visible_pixels: usize,
    lit_pixels: usize,
}

#[derive(Debug, Clone, Serialize)]
struct ObjectFile<'a> {
    name: &'a str,
    /// `T_cam_object` as a 4x4 row-major matrix.
    t_cam_object: [[f64; 4]; 4],
}

/// A pose as a 4×4 row-major homogeneous matrix: `sl_camera::pose_to_matrix`.
pub use sl_camera::pose_to_matrix as pose_matrix;

/// Writes a view's ground truth into `dir` (created if needed) and returns the files written:
///
/// - `col.tiff`, `row.tiff`: the exact projector coordinate of each camera pixel (32-bit
///   float, NaN where the projector does not light what the pixel sees) — the same names
///   and conventions as `sl-codec`'s decoded maps;
/// - `depth.tiff`: `z` in the camera frame (mm, NaN where nothing is seen);
/// - `x.tiff`, `y.tiff`, `z.tiff`: the 3-D point in the camera frame (mm);
/// - `visible.png`, `lit.png`: 255 where the camera sees an object / a lit object;
/// - `object.png`: index of the object seen (255 for none);
/// - `view.json`: turntable angles, `T_cam_table` and every `T_cam_object`.
pub fn write_view_truth(truth: &ViewTruth, dir: &Path) -> Result<Vec<PathBuf>, SimError> {
    std::fs::create_dir_all(dir).map_err(|e| SimError::io(dir, e))?;
    let (w, h) = (truth.width as usize, truth.height as usize);
    let mut files = Vec::new();
    let mut tiff = |name: &str, data: Vec<f32>| -> Result<(), SimError> {
        let p = dir.join(name);
        write_tiff_f32(&p, w, h, &data)?;
        files.push(p);
        Ok(())
    };
    tiff(
        "col.tiff",
        truth.projector.iter().map(|p| p.x as f32).collect(),
    )?;
    tiff(
        "row.tiff",
        truth.projector.iter().map(|p| p.y as f32).collect(),
    )?;
    tiff(
        "depth.tiff",
        truth.depth_mm.iter().map(|&d| d as f32).collect(),
    )?;
    tiff(
        "x.tiff",
        truth.points_cam.iter().map(|p| p.x as f32).collect(),
    )?;
    tiff(
        "y.tiff",
        truth.points_cam.iter().map(|p| p.y as f32).collect(),
    )?;
    tiff(
        "z.tiff",
        truth.points_cam.iter().map(|p| p.z as f32).collect(),
    )?;
    let n = truth.object.len();
    let masks: [(&str, Vec<u8>); 3] = [
        (
            "visible.png",
            (0..n)
                .map(|i| if truth.visible(i) { 255 } else { 0 })
                .collect(),
        ),
        (
            "lit.png",
            (0..n).map(|i| if truth.lit(i) { 255 } else { 0 }).collect(),
        ),
        (
            "object.png",
            truth
                .object
                .iter()
                .map(|&o| u8::try_from(o).unwrap_or(u8::MAX))
                .collect(),
        ),
    ];
    for (name, data) in masks {
        let p = dir.join(name);
        write_png_grey8(
            &p,
            &Frame::new(w, h, data).map_err(sl_codec::CodecError::from)?,
        )?;
        files.push(p);
    }
    let view = ViewFile {
        motor_angle_deg: truth.motor_angle_deg,
        platter_angle_deg: truth.platter_angle_deg,
        t_cam_table: pose_matrix(&truth.t_cam_table),
        objects: truth
            .objects
            .iter()
            .map(|o| ObjectFile {
                name: &o.name,
                t_cam_object: pose_matrix(&o.t_cam_object),
            })
            .collect(),
        width: truth.width,
        height: truth.height,
        visible_pixels: truth.visible_count(),
        lit_pixels: truth.lit_count(),
    };
    let p = dir.join(VIEW_JSON);
    write_json(&p, &view)?;
    files.push(p);
    Ok(files)
}

/// Writes `value` as pretty JSON to `path`.
pub(crate) fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), SimError> {
    let text = serde_json::to_string_pretty(value).map_err(|source| SimError::Json {
        path: path.to_path_buf(),
        source,
    })?;
    std::fs::write(path, text).map_err(|e| SimError::io(path, e))
}
