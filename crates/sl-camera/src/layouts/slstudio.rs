//! SLStudio's `calibration.xml` (`CalibrationData::saveXML`): `Kc kc` (camera), `Kp kp`
//! (projector), `Rp Tp` (`p_proj = Rp · p_cam + Tp`), `cam_error proj_error stereo_error`,
//! `frameWidth frameHeight` (camera), `screenResX screenResY` (projector).

use super::{
    CalibrationLayout, camera_from, d_item, extras_from, k_item, push_rms, resolve_size, rms_from,
    rt_items, size_from_keys, size_hint, size_item, t_cam_proj_from,
};
use crate::filestorage::{Document, Item};
use crate::{Calibration, CameraError, LoadConfig};

const LAYOUT: CalibrationLayout = CalibrationLayout::SlStudio;

pub(super) fn read(doc: &Document, options: &LoadConfig) -> Result<Calibration, CameraError> {
    let stored = size_from_keys(doc, "frameWidth", "frameHeight")?;
    let size = resolve_size(
        doc,
        stored,
        "frameWidth",
        options.camera_size,
        "the image size is required",
    )?;
    let camera = camera_from(doc, "camera", "Kc", "kc", size)?;
    let projector = if doc.has("Kp") {
        let stored = size_from_keys(doc, "screenResX", "screenResY")?;
        let size = resolve_size(
            doc,
            stored,
            "screenResX",
            options.projector_size,
            &size_hint(LAYOUT, "projector", "projector_size", "--projector-size"),
        )?;
        Some(camera_from(doc, "projector", "Kp", "kp", size)?)
    } else {
        None
    };
    let mut c = Calibration::new(camera);
    c.projector = projector;
    c.t_cam_proj = t_cam_proj_from(doc, "Rp", "Tp")?;
    c.rms = rms_from(doc, "cam_error")?;
    (c.turntable, c.metadata) = extras_from(doc, LAYOUT)?;
    Ok(c)
}

pub(super) fn items(c: &Calibration) -> Vec<(&'static str, Item)> {
    let mut items = vec![("Kc", k_item(&c.camera)), ("kc", d_item(&c.camera))];
    if let Some(projector) = &c.projector {
        items.push(("Kp", k_item(projector)));
        items.push(("kp", d_item(projector)));
    }
    if let Some(t) = &c.t_cam_proj {
        items.extend(rt_items(t, "Rp", "Tp"));
    }
    push_rms(c, "cam_error", &mut items);
    items.push(("frameWidth", size_item(c.camera.size.width)));
    items.push(("frameHeight", size_item(c.camera.size.height)));
    if let Some(projector) = &c.projector {
        items.push(("screenResX", size_item(projector.size.width)));
        items.push(("screenResY", size_item(projector.size.height)));
    }
    items
}
