//! Mapping between [`Calibration`] and the keys of OpenCV FileStorage calibration files.
//!
//! Two layouts are read and written:
//!
//! * OpenCV's calibration sample (`samples/cpp/calibration.cpp`): `camera_matrix`,
//!   `distortion_coefficients`, `image_width`, `image_height`, `avg_reprojection_error`
//!   (+ ignored extras: `nr_of_frames`, `extrinsic_parameters`, ...). Used when the
//!   calibration has no projector.
//! * SLStudio's procam calibration (`CalibrationData::saveXML`): `Kc kc` (camera), `Kp kp`
//!   (projector), `Rp Tp` (`p_proj = Rp · p_cam + Tp`, i.e. `T_proj_cam`; we store its inverse
//!   `T_cam_proj`), `cam_error proj_error stereo_error`, `frameWidth frameHeight` (camera),
//!   `screenResX screenResY` (projector). Used when the calibration has a projector.
//!
//! What neither layout has (turntable axis, metadata) is written under extra keys that
//! OpenCV ignores and we read back: `turntable_direction`, `turntable_point_mm`,
//! `turntable_angle_offset_deg`, `turntable_angle_scale`, `tool_version`, `created`, `notes`.
//! Translations are taken to be millimetres, as SLStudio's are.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::filestorage::{Document, Item, MatrixData};
use crate::pose::{isometry_from_rt, isometry_to_rt};
use crate::{
    Calibration, CameraError, CameraModel, Distortion, ImageSize, Intrinsics, Metadata, RmsErrors,
    TurntableAxis,
};

/// Reads a calibration from a parsed FileStorage document.
pub(crate) fn calibration_from_document(doc: &Document) -> Result<Calibration, CameraError> {
    if let Some(fisheye) = doc.number("fisheye_model")?
        && fisheye != 0.0
    {
        let line = doc.get("fisheye_model").map_or(0, |n| n.line);
        return Err(doc.bad(
            "fisheye_model",
            line,
            "OpenCV's fisheye (Kannala–Brandt) model is not supported; recalibrate with the \
             standard or rational model",
        ));
    }
    let slstudio = doc.has("Kc");
    let (camera, projector, t_cam_proj, rms) = if slstudio {
        let camera = camera_from(doc, "Kc", "kc", ("frameWidth", "frameHeight"))?;
        let projector = if doc.has("Kp") {
            Some(camera_from(doc, "Kp", "kp", ("screenResX", "screenResY"))?)
        } else {
            None
        };
        let t_cam_proj = match (doc.matrix("Rp")?, doc.matrix("Tp")?) {
            (Some(r), Some(t)) => {
                let r = matrix3(doc, "Rp", &r)?;
                let t = vector3(doc, "Tp", &t)?;
                let line = doc.get("Rp").map_or(0, |n| n.line);
                let t_proj_cam =
                    isometry_from_rt(&r, &t).map_err(|e| doc.bad("Rp", line, message_of(e)))?;
                Some(t_proj_cam.inverse())
            }
            (None, None) => None,
            (Some(_), None) => return Err(doc.missing("Tp", Some("`Rp` is given"))),
            (None, Some(_)) => return Err(doc.missing("Rp", Some("`Tp` is given"))),
        };
        let rms = RmsErrors {
            camera: doc.number("cam_error")?,
            projector: doc.number("proj_error")?,
            stereo: doc.number("stereo_error")?,
        };
        (camera, projector, t_cam_proj, rms)
    } else if doc.has("camera_matrix") {
        let camera = camera_from(
            doc,
            "camera_matrix",
            "distortion_coefficients",
            ("image_width", "image_height"),
        )?;
        let rms = RmsErrors {
            camera: doc.number("avg_reprojection_error")?,
            projector: doc.number("proj_error")?,
            stereo: doc.number("stereo_error")?,
        };
        (camera, None, None, rms)
    } else {
        return Err(doc.missing(
            "camera_matrix",
            Some("neither OpenCV's `camera_matrix` nor SLStudio's `Kc` is in the file"),
        ));
    };
    let turntable = turntable_from(doc)?;
    let mut notes = doc.string("notes")?.unwrap_or_default();
    if let Some(time) = doc.string("calibration_time")? {
        if !notes.is_empty() {
            notes.push('\n');
        }
        notes.push_str(&format!("calibration_time: {time}"));
    }
    let metadata = Metadata {
        tool_version: doc.string("tool_version")?.unwrap_or_else(|| {
            format!(
                "imported from OpenCV FileStorage ({} layout)",
                if slstudio {
                    "SLStudio"
                } else {
                    "OpenCV calibration sample"
                }
            )
        }),
        created: doc.string("created")?,
        notes,
    };
    let calibration = Calibration {
        camera,
        projector,
        t_cam_proj,
        turntable,
        rms,
        metadata,
    };
    calibration
        .validate()
        .map_err(|e| e.in_file(&doc.file, "", None))?;
    Ok(calibration)
}

fn camera_from(
    doc: &Document,
    k_key: &str,
    d_key: &str,
    (w_key, h_key): (&str, &str),
) -> Result<CameraModel, CameraError> {
    let k = doc.matrix(k_key)?.ok_or_else(|| doc.missing(k_key, None))?;
    let intrinsics = Intrinsics::from_matrix(&matrix3(doc, k_key, &k)?)
        .map_err(|e| doc.bad(k_key, k.line, message_of(e)))?;
    let distortion = match doc.matrix(d_key)? {
        None => return Err(doc.missing(d_key, Some("write an empty matrix for no distortion"))),
        Some(d) => {
            if d.rows != 1 && d.cols != 1 && !d.data.is_empty() {
                return Err(doc.bad(
                    d_key,
                    d.line,
                    format!("expected a vector, found a {}x{} matrix", d.rows, d.cols),
                ));
            }
            Distortion::from_opencv(&d.data).map_err(|e| doc.bad(d_key, d.line, message_of(e)))?
        }
    };
    let width = doc
        .unsigned(w_key)?
        .ok_or_else(|| doc.missing(w_key, Some("the image size is required")))?;
    let height = doc
        .unsigned(h_key)?
        .ok_or_else(|| doc.missing(h_key, Some("the image size is required")))?;
    let camera = CameraModel {
        intrinsics,
        distortion,
        size: ImageSize::new(width, height),
    };
    camera.size.validate().map_err(|e| {
        let key = if width == 0 { w_key } else { h_key };
        let line = doc.get(key).map_or(0, |n| n.line);
        doc.bad(key, line, message_of(e))
    })?;
    Ok(camera)
}

fn turntable_from(doc: &Document) -> Result<Option<TurntableAxis>, CameraError> {
    let (Some(dir), Some(point)) = (
        doc.matrix("turntable_direction")?,
        doc.matrix("turntable_point_mm")?,
    ) else {
        if doc.has("turntable_direction") {
            return Err(doc.missing("turntable_point_mm", Some("`turntable_direction` is given")));
        }
        if doc.has("turntable_point_mm") {
            return Err(doc.missing("turntable_direction", Some("`turntable_point_mm` is given")));
        }
        return Ok(None);
    };
    let mut axis = TurntableAxis {
        direction: vector3(doc, "turntable_direction", &dir)?,
        point_mm: Point3::from(vector3(doc, "turntable_point_mm", &point)?),
        angle_offset_deg: doc.number("turntable_angle_offset_deg")?.unwrap_or(0.0),
        angle_scale: doc.number("turntable_angle_scale")?.unwrap_or(1.0),
    };
    axis.normalize()
        .map_err(|e| doc.bad("turntable_direction", dir.line, message_of(e)))?;
    Ok(Some(axis))
}

fn matrix3(doc: &Document, key: &str, m: &MatrixData) -> Result<Matrix3<f64>, CameraError> {
    if m.rows != 3 || m.cols != 3 {
        return Err(doc.bad(
            key,
            m.line,
            format!("expected a 3x3 matrix, found {}x{}", m.rows, m.cols),
        ));
    }
    Ok(Matrix3::from_row_slice(&m.data))
}

fn vector3(doc: &Document, key: &str, m: &MatrixData) -> Result<Vector3<f64>, CameraError> {
    if m.data.len() != 3 || (m.rows != 1 && m.cols != 1) {
        return Err(doc.bad(
            key,
            m.line,
            format!("expected 3 values (3x1), found {}x{}", m.rows, m.cols),
        ));
    }
    Ok(Vector3::from_column_slice(&m.data))
}

/// The message part of an API error, for re-wrapping it with a file and key.
fn message_of(e: CameraError) -> String {
    match e {
        CameraError::InvalidParameter { parameter, message } => format!("{parameter}: {message}"),
        other => other.to_string(),
    }
}

/// The FileStorage items of a calibration (see the module docs for the layouts).
pub(crate) fn calibration_to_items(c: &Calibration) -> Vec<(&'static str, Item)> {
    let mut items: Vec<(&'static str, Item)> = Vec::new();
    let k_item = |m: &CameraModel| Item::Matrix {
        rows: 3,
        cols: 3,
        data: m.intrinsics.matrix().transpose().iter().copied().collect(),
    };
    let d_item = |m: &CameraModel| {
        let v = m.distortion.to_opencv_vec();
        Item::Matrix {
            rows: v.len(),
            cols: usize::from(!v.is_empty()),
            data: v,
        }
    };
    let size = |v: u32| Item::Int(i64::from(v));
    if let Some(projector) = &c.projector {
        items.push(("Kc", k_item(&c.camera)));
        items.push(("kc", d_item(&c.camera)));
        items.push(("Kp", k_item(projector)));
        items.push(("kp", d_item(projector)));
        if let Some(t_cam_proj) = &c.t_cam_proj {
            let (r, t) = isometry_to_rt(&t_cam_proj.inverse());
            items.push((
                "Rp",
                Item::Matrix {
                    rows: 3,
                    cols: 3,
                    data: r.transpose().iter().copied().collect(),
                },
            ));
            items.push((
                "Tp",
                Item::Matrix {
                    rows: 3,
                    cols: 1,
                    data: t.iter().copied().collect(),
                },
            ));
        }
        for (key, value) in [
            ("cam_error", c.rms.camera),
            ("proj_error", c.rms.projector),
            ("stereo_error", c.rms.stereo),
        ] {
            if let Some(v) = value {
                items.push((key, Item::Real(v)));
            }
        }
        items.push(("frameWidth", size(c.camera.size.width)));
        items.push(("frameHeight", size(c.camera.size.height)));
        items.push(("screenResX", size(projector.size.width)));
        items.push(("screenResY", size(projector.size.height)));
    } else {
        items.push(("image_width", size(c.camera.size.width)));
        items.push(("image_height", size(c.camera.size.height)));
        items.push(("camera_matrix", k_item(&c.camera)));
        items.push(("distortion_coefficients", d_item(&c.camera)));
        for (key, value) in [
            ("avg_reprojection_error", c.rms.camera),
            ("proj_error", c.rms.projector),
            ("stereo_error", c.rms.stereo),
        ] {
            if let Some(v) = value {
                items.push((key, Item::Real(v)));
            }
        }
    }
    if let Some(axis) = &c.turntable {
        let v3 = |v: [f64; 3]| Item::Matrix {
            rows: 3,
            cols: 1,
            data: v.to_vec(),
        };
        items.push((
            "turntable_direction",
            v3([axis.direction.x, axis.direction.y, axis.direction.z]),
        ));
        items.push((
            "turntable_point_mm",
            v3([axis.point_mm.x, axis.point_mm.y, axis.point_mm.z]),
        ));
        items.push((
            "turntable_angle_offset_deg",
            Item::Real(axis.angle_offset_deg),
        ));
        items.push(("turntable_angle_scale", Item::Real(axis.angle_scale)));
    }
    items.push(("tool_version", Item::Str(c.metadata.tool_version.clone())));
    if let Some(created) = &c.metadata.created {
        items.push(("created", Item::Str(created.clone())));
    }
    if !c.metadata.notes.is_empty() {
        items.push(("notes", Item::Str(c.metadata.notes.clone())));
    }
    items
}
