//! OpenCV's calibration sample (`samples/cpp/calibration.cpp`, `saveCameraParams`):
//! `image_width`, `image_height`, `camera_matrix`, `distortion_coefficients`,
//! `avg_reprojection_error` (+ extras we ignore: `nr_of_frames`, `extrinsic_parameters`, ...).
//! A camera alone.

use super::{
    CalibrationLayout, camera_from, d_item, extras_from, k_item, push_rms, resolve_size,
    size_from_keys, size_item,
};
use crate::filestorage::{Document, Item};
use crate::{Calibration, CameraError, LoadConfig};

pub(super) fn read(doc: &Document, options: &LoadConfig) -> Result<Calibration, CameraError> {
    let stored = size_from_keys(doc, "image_width", "image_height")?;
    let size = resolve_size(
        doc,
        stored,
        "image_width",
        options.camera_size,
        "the image size is required",
    )?;
    let camera = camera_from(
        doc,
        "camera",
        "camera_matrix",
        "distortion_coefficients",
        size,
    )?;
    let mut c = Calibration::new(camera);
    c.rms = super::rms_from(doc, "avg_reprojection_error")?;
    (c.turntable, c.metadata) = extras_from(doc, CalibrationLayout::OpenCvCamera)?;
    Ok(c)
}

pub(super) fn items(c: &Calibration) -> Result<Vec<(&'static str, Item)>, CameraError> {
    if c.projector.is_some() {
        return Err(CameraError::invalid(
            "projector",
            "the opencv-camera layout holds a camera alone; this calibration has a projector \
             (write it as slstudio, scan3d-capture, slmaster, opencv-stereo or json)",
        ));
    }
    let mut items = vec![
        ("image_width", size_item(c.camera.size.width)),
        ("image_height", size_item(c.camera.size.height)),
        ("camera_matrix", k_item(&c.camera)),
        ("distortion_coefficients", d_item(&c.camera)),
    ];
    push_rms(c, "avg_reprojection_error", &mut items);
    Ok(items)
}
