//! The two-camera layouts: SLMaster's binocular `caliInfo.yml` (`M1 D1 M2 D2 R1 P1 R2 P2 Q Rlr
//! Tlr E F S`: `Rlr`, `Tlr` map left-camera coordinates into the right camera's, `p_right = Rlr
//! · p_left + Tlr`, as `cv::stereoCalibrate`'s `R`, `T`; `S` the image size `[width; height]`)
//! and OpenCV's stereo calibration in two files (`intrinsic(s).yml`: `M1 D1 M2 D2`;
//! `extrinsic(s).yml`: `R T` the same way, and the rectification `R1 P1 R2 P2 Q`, not read —
//! we rectify ourselves). Camera 1 is the left camera, camera 2 the right one. Neither stores
//! RMS values; only SLMaster stores the image size (both cameras the same), otherwise it comes
//! from the options ([`LoadConfig::camera_size`]).

use nalgebra::Isometry3;

use super::slmaster::size_of_s;
use super::{CAMERA_SIZE_KEYS, camera_from, resolve_size, size_from_keys, t_cam_proj_from};
use crate::filestorage::Document;
use crate::{CameraError, CameraModel, LoadConfig};

/// Both cameras and `T_left_right` (`p_left = T_left_right · p_right`) from the intrinsics
/// document and, for OpenCV's two-file layout, the extrinsics one.
pub(crate) fn read_pair(
    intrinsics: &Document,
    extrinsics: Option<&Document>,
    options: &LoadConfig,
) -> Result<(CameraModel, CameraModel, Isometry3<f64>), CameraError> {
    super::refuse_fisheye(intrinsics)?;
    for key in ["M1", "M2"] {
        if !intrinsics.has(key) {
            return Err(intrinsics.missing(
                key,
                Some("a two-camera calibration holds M1 D1 (left) and M2 D2 (right)"),
            ));
        }
    }
    let stored = match size_of_s(intrinsics)? {
        Some(s) => Some(s),
        None => size_from_keys(intrinsics, CAMERA_SIZE_KEYS.0, CAMERA_SIZE_KEYS.1)?,
    };
    let key = if intrinsics.has("S") {
        "S"
    } else {
        CAMERA_SIZE_KEYS.0
    };
    let size = resolve_size(
        intrinsics,
        stored,
        key,
        options.camera_size,
        "this two-camera layout does not store the cameras' image size: give it \
         (LoadConfig::camera_size, or slscan --camera-size WxH)",
    )?;
    let left = camera_from(intrinsics, "left camera", "M1", "D1", size)?;
    let right = camera_from(intrinsics, "right camera", "M2", "D2", size)?;
    // `t_cam_proj_from` inverts a pose stored as `p_second = R · p_first + T`: here the right
    // camera's pose in the left camera's frame.
    let pose = if intrinsics.has("Rlr") {
        t_cam_proj_from(intrinsics, "Rlr", "Tlr")?
    } else if let Some(e) = extrinsics {
        t_cam_proj_from(e, "R", "T")?
    } else {
        t_cam_proj_from(intrinsics, "R", "T")?
    };
    let pose = pose.ok_or_else(|| {
        intrinsics.missing(
            "Rlr",
            Some(
                "the pose of the right camera: SLMaster's Rlr Tlr, or R T in the extrinsic(s) \
                 file beside the intrinsic(s) file",
            ),
        )
    })?;
    Ok((left, right, pose))
}
