//! OpenCV's stereo sample (`samples/cpp/stereo_calib.cpp`): `intrinsics.yml` holds `M1 D1 M2
//! D2` and `extrinsics.yml` holds `R T R1 R2 P1 P2 Q`. `R`, `T` are `cv::stereoCalibrate`'s:
//! `p_2 = R · p_1 + T`; camera 1 is our camera, camera 2 our projector. The sample's board
//! unit is its `squareSize` (1 unless edited: translations are then in squares; we take them
//! to be millimetres). No image sizes and no RMS values: they come from the options or our
//! extra keys, which are written into the intrinsics file. The rectification (`R1 R2 P1 P2
//! Q`) is not read and not written.

use std::path::{Path, PathBuf};

use super::Items;
use super::{
    CAMERA_SIZE_KEYS, CalibrationLayout, PROJECTOR_SIZE_KEYS, camera_from, d_item, extras_from,
    k_item, push_rms, push_size_extra, require_projector, resolve_size, rms_from, rt_items,
    size_from_keys, size_hint, t_cam_proj_from,
};
use crate::filestorage::Document;
use crate::{Calibration, CameraError, LoadConfig};

const LAYOUT: CalibrationLayout = CalibrationLayout::OpenCvStereo;

/// The intrinsics file's name part and the extrinsics file's.
const INTRINSICS: &str = "intrinsics";
/// See [`INTRINSICS`].
const EXTRINSICS: &str = "extrinsics";

/// The file named as `path` with `from` replaced by `to` in its name (the last occurrence),
/// or `to.<ext>` in the same folder when the name has no `from`.
fn sibling(path: &Path, from: &str, to: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let new_name = match name.rfind(from) {
        Some(i) => format!("{}{to}{}", &name[..i], &name[i + from.len()..]),
        None => {
            let ext = path
                .extension()
                .map_or_else(|| "yml".to_owned(), |e| e.to_string_lossy().into_owned());
            format!("{to}.{ext}")
        }
    };
    path.with_file_name(new_name)
}

/// The extrinsics file that goes with an intrinsics file (`intrinsics.yml` →
/// `extrinsics.yml`, `left_intrinsics.xml` → `left_extrinsics.xml`).
pub(crate) fn extrinsics_sibling(path: &Path) -> PathBuf {
    sibling(path, INTRINSICS, EXTRINSICS)
}

/// The intrinsics file that goes with an extrinsics file.
pub(crate) fn intrinsics_sibling(path: &Path) -> PathBuf {
    sibling(path, EXTRINSICS, INTRINSICS)
}

pub(super) fn read(
    intrinsics: &Document,
    extrinsics: Option<&Document>,
    options: &LoadConfig,
) -> Result<Calibration, CameraError> {
    if !intrinsics.has("M1") {
        return Err(intrinsics.missing(
            "M1",
            Some("OpenCV's stereo sample keeps M1 D1 M2 D2 in intrinsics.yml: load that file"),
        ));
    }
    let stored = size_from_keys(intrinsics, CAMERA_SIZE_KEYS.0, CAMERA_SIZE_KEYS.1)?;
    let size = resolve_size(
        intrinsics,
        stored,
        CAMERA_SIZE_KEYS.0,
        options.camera_size,
        &size_hint(LAYOUT, "camera", "camera_size", "--camera-size"),
    )?;
    let camera = camera_from(intrinsics, "camera", "M1", "D1", size)?;
    let stored = size_from_keys(intrinsics, PROJECTOR_SIZE_KEYS.0, PROJECTOR_SIZE_KEYS.1)?;
    let size = resolve_size(
        intrinsics,
        stored,
        PROJECTOR_SIZE_KEYS.0,
        options.projector_size,
        &size_hint(LAYOUT, "projector", "projector_size", "--projector-size"),
    )?;
    let projector = camera_from(intrinsics, "projector", "M2", "D2", size)?;
    let mut c = Calibration::new(camera);
    c.projector = Some(projector);
    c.t_cam_proj = match extrinsics {
        Some(doc) => {
            let t = t_cam_proj_from(doc, "R", "T")?;
            if t.is_none() {
                return Err(doc.missing("R", Some("the stereo sample's extrinsics hold R and T")));
            }
            t
        }
        // Only in a one-file document that holds R and T with the intrinsics.
        None => t_cam_proj_from(intrinsics, "R", "T")?,
    };
    c.rms = rms_from(intrinsics, "cam_error")?;
    (c.turntable, c.metadata) = extras_from(intrinsics, LAYOUT)?;
    Ok(c)
}

/// The intrinsics file's items and the extrinsics file's.
pub(super) fn items(c: &Calibration) -> Result<(Items, Items), CameraError> {
    let projector = require_projector(c, LAYOUT)?;
    let mut intrinsics = vec![
        ("M1", k_item(&c.camera)),
        ("D1", d_item(&c.camera)),
        ("M2", k_item(projector)),
        ("D2", d_item(projector)),
    ];
    push_size_extra(c.camera.size, CAMERA_SIZE_KEYS, &mut intrinsics);
    push_size_extra(projector.size, PROJECTOR_SIZE_KEYS, &mut intrinsics);
    push_rms(c, "cam_error", &mut intrinsics);
    let t = c.t_cam_proj.as_ref().ok_or_else(|| {
        CameraError::invalid(
            "T_cam_proj",
            "the opencv-stereo layout's extrinsics.yml holds R and T; this calibration has \
             no camera-projector extrinsics",
        )
    })?;
    Ok((intrinsics, rt_items(t, "R", "T").into()))
}
