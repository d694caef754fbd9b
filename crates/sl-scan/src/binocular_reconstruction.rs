//! Two capture folders of the same patterns, one from each camera of a binocular rig, decoded,
//! matched and triangulated (what `slscan reconstruct LEFT --right RIGHT` runs).

use std::path::{Path, PathBuf};

use serde::Serialize;
use sl_camera::{BinocularCalibration, ImageSize, LoadConfig};
use sl_cloud::{PlyFormat, PreviewImage, colormap, write_ply};
use sl_codec::{CaptureSet, DecodeConfig, MANIFEST_FILE, decode, ramp_stair_codes, write_png_rgb8};
use sl_tri::{Binocular, BinocularConfig, BinocularCounts};

use crate::error::io;
use crate::progress::timed;
use crate::{ScanError, StageTime};

/// What [`reconstruct_binocular_capture`] made and wrote (`cloud.ply` and `disparity.png` in
/// the output folder).
#[derive(Debug, Clone, Serialize)]
pub struct BinocularReconstruction {
    /// Rectified grid width (the left camera's, px).
    pub width: usize,
    /// Rectified grid height (px).
    pub height: usize,
    /// Points of the cloud.
    pub points: usize,
    /// Fraction of each camera's pixels the decoder gave a code: left, right.
    pub decoded_fraction: (f64, f64),
    /// How the rectified left pixels fared.
    #[serde(skip)]
    pub counts: BinocularCounts,
    /// The disparity range of the picture (px): its colour scale.
    pub disparity_range_px: (f32, f32),
    /// Roughness of the disparity map: the median of `|d(x−1) − 2·d(x) + d(x+1)|` along the
    /// rectified rows where three neighbours matched (px); the matching noise on smooth
    /// surfaces, for comparing methods on the same captures.
    pub roughness_px: f64,
    /// Corners of the cloud's bounding box (mm), when it has a point.
    pub bbox_mm: Option<([f64; 3], [f64; 3])>,
    /// The cloud (mm, the left camera's frame).
    pub cloud: PathBuf,
    /// Wall time per stage.
    pub stages: Vec<StageTime>,
}

/// Decodes the captures `left` and `right` (each a folder with `manifest.json`, the same
/// patterns seen by the left and the right camera), matches and triangulates them with the
/// two-camera calibration `calibration` ([`BinocularCalibration::load_with`]; a layout that
/// does not store the image size takes the left capture's) and writes into `out` `cloud.ply`
/// (mm, the left camera's frame, with normals) and `disparity.png` (false colour on the
/// rectified left grid, with its scale).
///
/// # Errors
/// The captures' and the calibration's files; [`ScanError::Session`] naming the capture whose
/// frames are not its camera's size, or naming both when no point came out (with how the
/// pixels fared).
pub fn reconstruct_binocular_capture(
    left: &Path,
    right: &Path,
    calibration: &Path,
    cfg: &BinocularConfig,
    out: &Path,
) -> Result<BinocularReconstruction, ScanError> {
    cfg.validate()?;
    std::fs::create_dir_all(out).map_err(io(out))?;
    let mut stages = Vec::new();
    let (left_set, right_set) = timed(&mut stages, "read captures", || {
        Ok::<_, ScanError>((
            CaptureSet::load(&left.join(MANIFEST_FILE))?,
            CaptureSet::load(&right.join(MANIFEST_FILE))?,
        ))
    })?;
    let (lw, lh) = (left_set.frames.width(), left_set.frames.height());
    let options = LoadConfig {
        camera_size: Some(ImageSize::new(lw as u32, lh as u32)),
        ..LoadConfig::default()
    };
    let calib = timed(&mut stages, "read calibration", || {
        BinocularCalibration::load_with(calibration, &options)
    })?;
    for (capture, set, model) in [
        (left, &left_set, &calib.left),
        (right, &right_set, &calib.right),
    ] {
        let (w, h) = (set.frames.width(), set.frames.height());
        if (w as u32, h as u32) != (model.size.width, model.size.height) {
            return Err(ScanError::Session {
                path: capture.to_path_buf(),
                reason: format!(
                    "frames of {w}x{h}, but the calibration {} has its camera at {}x{}",
                    calibration.display(),
                    model.size.width,
                    model.size.height
                ),
            });
        }
    }
    let (lmap, rmap) = timed(&mut stages, "decode", || {
        let mut maps = (
            decode(&left_set, &DecodeConfig::default())?,
            decode(&right_set, &DecodeConfig::default())?,
        );
        // A Gray code's whole-number stripes as ramps: the matching needs codes that vary
        // within a stripe (phase codes are left as they are).
        ramp_stair_codes(&mut maps.0);
        ramp_stair_codes(&mut maps.1);
        Ok::<_, ScanError>(maps)
    })?;
    drop((left_set, right_set));
    let pair = timed(&mut stages, "rectify", || {
        Binocular::new(&calib.left, &calib.right, &calib.t_left_right)
    })?;
    let result = timed(&mut stages, "match and triangulate", || {
        pair.reconstruct(&lmap, &rmap, cfg)
    })?;
    if result.counts.valid == 0 {
        return Err(ScanError::Session {
            path: left.to_path_buf(),
            reason: format!(
                "no point matched with {} (decoded {:.1} % and {:.1} %; {:?})",
                right.display(),
                100.0 * lmap.valid_fraction(),
                100.0 * rmap.valid_fraction(),
                result.counts
            ),
        });
    }
    let ply = out.join("cloud.ply");
    timed(&mut stages, "write ply", || {
        write_ply(&ply, &result.cloud, PlyFormat::default())
    })?;
    let range = timed(
        &mut stages,
        "write disparity",
        || -> Result<_, ScanError> {
            let (picture, range) =
                disparity_picture(&result.disparity, result.width, result.height);
            write_png_rgb8(
                &out.join("disparity.png"),
                picture.width as usize,
                picture.height as usize,
                &picture.rgb,
            )?;
            Ok(range)
        },
    )?;
    Ok(BinocularReconstruction {
        width: result.width,
        height: result.height,
        points: result.counts.valid,
        decoded_fraction: (lmap.valid_fraction(), rmap.valid_fraction()),
        counts: result.counts,
        disparity_range_px: range,
        roughness_px: roughness(&result.disparity, result.width),
        bbox_mm: result
            .cloud
            .bounding_box()
            .map(|b| ([b.min.x, b.min.y, b.min.z], [b.max.x, b.max.y, b.max.z])),
        cloud: ply,
        stages,
    })
}

/// See [`BinocularReconstruction::roughness_px`] (NaN without three neighbours in a row).
fn roughness(disparity: &[f32], width: usize) -> f64 {
    let mut second: Vec<f32> = disparity
        .chunks(width.max(1))
        .flat_map(|row| {
            row.windows(3)
                .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
                .filter(|v| v.is_finite())
        })
        .collect();
    if second.is_empty() {
        return f64::NAN;
    }
    let mid = second.len() / 2;
    let (_, m, _) = second.select_nth_unstable_by(mid, f32::total_cmp);
    f64::from(*m)
}

/// The disparity map in false colour over the 1st–99th percentile of its values (black where
/// no point), with its scale; and that range.
fn disparity_picture(disparity: &[f32], width: usize, height: usize) -> (PreviewImage, (f32, f32)) {
    let mut values: Vec<f32> = disparity
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .collect();
    values.sort_by(f32::total_cmp);
    let at = |q: f64| {
        values
            .get(((values.len() as f64 - 1.0) * q) as usize)
            .copied()
    };
    let (lo, hi) = (at(0.01).unwrap_or(0.0), at(0.99).unwrap_or(1.0));
    let span = (hi - lo).max(1e-3);
    let mut rgb = Vec::with_capacity(width * height * 3);
    for &d in disparity {
        if d.is_finite() {
            rgb.extend(colormap(f64::from(((d - lo) / span).clamp(0.0, 1.0))));
        } else {
            rgb.extend([0, 0, 0]);
        }
    }
    let mut img = PreviewImage {
        width: width as u32,
        height: height as u32,
        rgb,
        left_out: 0,
    };
    sl_metrology::draw_scale(&mut img, lo, hi, "px");
    (img, (lo, hi))
}
