//! SLMaster's `caliInfo.yml` (`CaliPacker::writeCaliInfo`): `M1 D1` (camera), `S` (the camera's
//! image size, a 2x1 matrix `[width; height]`), and after a projector calibration `M4 D4`
//! (projector), `Rlp Tlp` (camera to projector: `p_proj = Rlp · p_cam + Tlp`, from
//! `cv::solvePnPRansac` on board corners in camera coordinates) and `K1` (an 8-parameter
//! phase-to-depth model we ignore). The board unit is millimetres. No projector size and no
//! RMS values: they come from the options or our extra keys.

use super::{
    CalibrationLayout, PROJECTOR_SIZE_KEYS, camera_from, d_item, extras_from, k_item, push_rms,
    push_size_extra, resolve_size, rms_from, rt_items, size_from_keys, size_hint, t_cam_proj_from,
};
use crate::filestorage::{Document, Item};
use crate::{Calibration, CameraError, ImageSize, LoadConfig};

const LAYOUT: CalibrationLayout = CalibrationLayout::SlMaster;

/// The camera size of `S`: a 2-vector `[width, height]` of whole pixels.
pub(super) fn size_of_s(doc: &Document) -> Result<Option<(ImageSize, usize)>, CameraError> {
    let Some(s) = doc.matrix("S")? else {
        return Ok(None);
    };
    let whole =
        |v: f64| (v.fract() == 0.0 && (0.0..=f64::from(u32::MAX)).contains(&v)).then_some(v as u32);
    match s.data.as_slice() {
        [w, h] if s.rows == 1 || s.cols == 1 => match (whole(*w), whole(*h)) {
            (Some(w), Some(h)) => Ok(Some((ImageSize::new(w, h), s.line))),
            _ => Err(doc.bad(
                "S",
                s.line,
                format!("expected whole pixel counts, found {w} x {h}"),
            )),
        },
        _ => Err(doc.bad(
            "S",
            s.line,
            format!(
                "expected the image size [width; height] (2x1), found {}x{}",
                s.rows, s.cols
            ),
        )),
    }
}

pub(super) fn read(doc: &Document, options: &LoadConfig) -> Result<Calibration, CameraError> {
    let size = resolve_size(
        doc,
        size_of_s(doc)?,
        "S",
        options.camera_size,
        "SLMaster writes the camera's image size as `S`",
    )?;
    let camera = camera_from(doc, "camera", "M1", "D1", size)?;
    let projector = if doc.has("M4") {
        let stored = size_from_keys(doc, PROJECTOR_SIZE_KEYS.0, PROJECTOR_SIZE_KEYS.1)?;
        let size = resolve_size(
            doc,
            stored,
            PROJECTOR_SIZE_KEYS.0,
            options.projector_size,
            &size_hint(LAYOUT, "projector", "projector_size", "--projector-size"),
        )?;
        Some(camera_from(doc, "projector", "M4", "D4", size)?)
    } else {
        None
    };
    let mut c = Calibration::new(camera);
    c.projector = projector;
    c.t_cam_proj = t_cam_proj_from(doc, "Rlp", "Tlp")?;
    c.rms = rms_from(doc, "cam_error")?;
    (c.turntable, c.metadata) = extras_from(doc, LAYOUT)?;
    Ok(c)
}

pub(super) fn items(c: &Calibration) -> Vec<(&'static str, Item)> {
    let mut items = vec![
        ("M1", k_item(&c.camera)),
        ("D1", d_item(&c.camera)),
        (
            "S",
            Item::Matrix {
                rows: 2,
                cols: 1,
                data: vec![
                    f64::from(c.camera.size.width),
                    f64::from(c.camera.size.height),
                ],
            },
        ),
    ];
    if let Some(projector) = &c.projector {
        items.push(("M4", k_item(projector)));
        items.push(("D4", d_item(projector)));
    }
    if let Some(t) = &c.t_cam_proj {
        items.extend(rt_items(t, "Rlp", "Tlp"));
    }
    push_rms(c, "cam_error", &mut items);
    if let Some(projector) = &c.projector {
        push_size_extra(projector.size, PROJECTOR_SIZE_KEYS, &mut items);
    }
    items
}
