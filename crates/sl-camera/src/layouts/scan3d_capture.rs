//! Moreno & Taubin's scan3d-capture `calibration.yml` (`CalibrationData::save_calibration_yml`):
//! `cam_K cam_kc proj_K proj_kc R T cam_error proj_error stereo_error`. `R`, `T` are
//! `cv::stereoCalibrate`'s with the camera first and the projector second, so
//! `p_proj = R · p_cam + T`, in the board's unit (its corner size, millimetres in practice).
//! No image sizes: they come from the options or our extra keys.

use super::{
    CAMERA_SIZE_KEYS, CalibrationLayout, PROJECTOR_SIZE_KEYS, camera_from, d_item, extras_from,
    k_item, push_rms, push_size_extra, require_projector, resolve_size, rms_from, rt_items,
    size_from_keys, size_hint, t_cam_proj_from,
};
use crate::filestorage::{Document, Item};
use crate::{Calibration, CameraError, LoadConfig};

const LAYOUT: CalibrationLayout = CalibrationLayout::Scan3dCapture;

pub(super) fn read(doc: &Document, options: &LoadConfig) -> Result<Calibration, CameraError> {
    let stored = size_from_keys(doc, CAMERA_SIZE_KEYS.0, CAMERA_SIZE_KEYS.1)?;
    let size = resolve_size(
        doc,
        stored,
        CAMERA_SIZE_KEYS.0,
        options.camera_size,
        &size_hint(LAYOUT, "camera", "camera_size", "--camera-size"),
    )?;
    let camera = camera_from(doc, "camera", "cam_K", "cam_kc", size)?;
    let stored = size_from_keys(doc, PROJECTOR_SIZE_KEYS.0, PROJECTOR_SIZE_KEYS.1)?;
    let size = resolve_size(
        doc,
        stored,
        PROJECTOR_SIZE_KEYS.0,
        options.projector_size,
        &size_hint(LAYOUT, "projector", "projector_size", "--projector-size"),
    )?;
    let projector = camera_from(doc, "projector", "proj_K", "proj_kc", size)?;
    let mut c = Calibration::new(camera);
    c.projector = Some(projector);
    c.t_cam_proj = t_cam_proj_from(doc, "R", "T")?;
    c.rms = rms_from(doc, "cam_error")?;
    (c.turntable, c.metadata) = extras_from(doc, LAYOUT)?;
    Ok(c)
}

pub(super) fn items(c: &Calibration) -> Result<Vec<(&'static str, Item)>, CameraError> {
    let projector = require_projector(c, LAYOUT)?;
    let mut items = vec![
        ("cam_K", k_item(&c.camera)),
        ("cam_kc", d_item(&c.camera)),
        ("proj_K", k_item(projector)),
        ("proj_kc", d_item(projector)),
    ];
    if let Some(t) = &c.t_cam_proj {
        items.extend(rt_items(t, "R", "T"));
    }
    push_rms(c, "cam_error", &mut items);
    push_size_extra(c.camera.size, CAMERA_SIZE_KEYS, &mut items);
    push_size_extra(projector.size, PROJECTOR_SIZE_KEYS, &mut items);
    Ok(items)
}
