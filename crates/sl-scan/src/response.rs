//! The projector's response: a grey ramp shown and captured on the devices (virtual or real)
//! or read from a folder, measured ([`sl_calib::measure_response`]) and kept in the
//! calibration, whose response every later decode corrects the phase with
//! ([`sl_codec::DecodeConfig::projector_response`]).
//!
//! A ramp folder holds one capture per grey level (`level_NN.png`) and `ramp.json`, which
//! lists the values shown and the files; [`measure_ramp_folder`] reads any such folder, so a
//! ramp captured by another program is measured by writing its `ramp.json`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use sl_calib::{RESPONSE_LEVELS, ResponseMeasurement, measure_response, ramp_levels};
use sl_codec::{GreyImage, PhaseCorrection, ShiftSign, read_image, write_png_grey};
use sl_rig::{Camera, DEFAULT_DISPLAY_LATENCY, Projector};

use crate::error::io;
use crate::{ScanError, write_atomically};

/// The ramp's folder inside a calibration output (`slscan calibrate response --out DIR`).
pub const RESPONSE_DIR: &str = "response";

/// The ramp's description in its folder.
pub const RAMP_FILE: &str = "ramp.json";

/// `format` of [`RAMP_FILE`].
pub const RAMP_FORMAT: &str = "sl-response-ramp";

/// How a ramp is captured ([`capture_ramp`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RampConfig {
    /// Grey levels, from black to white (at least 3). Default [`RESPONSE_LEVELS`].
    pub levels: usize,
    /// Wait after showing a level before capturing. Default
    /// [`sl_rig::DEFAULT_DISPLAY_LATENCY`].
    pub display_latency: Duration,
    /// Frames captured and dropped after each level change (the camera's buffer). Default 0.
    pub flush_frames: usize,
}

impl Default for RampConfig {
    fn default() -> Self {
        Self {
            levels: RESPONSE_LEVELS,
            display_latency: DEFAULT_DISPLAY_LATENCY,
            flush_frames: 0,
        }
    }
}

/// `ramp.json`: the values shown (fractions of the projector's full scale) and the capture of
/// each, relative to the folder.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RampFile {
    /// [`RAMP_FORMAT`].
    pub format: String,
    /// The values shown, increasing from 0 to 1.
    pub levels: Vec<f64>,
    /// The capture of each value, relative to the folder.
    pub files: Vec<String>,
}

/// Shows the ramp of `config.levels` grey levels on `projector`, captures each with `camera`
/// into `dir` (`level_NN.png` and [`RAMP_FILE`]) and measures the response. Point the
/// projector at a matte, light surface the camera sees (a wall, the back of the board).
///
/// The values shown are what an 8-bit projector image can show: `round(255 i / (n - 1))`,
/// recorded as such in `ramp.json`.
///
/// # Errors
/// [`ScanError::Calib`] for a level count out of range or a measurement that fails (no pixel
/// lit well and unsaturated, named by [`sl_calib::measure_response`]); a device's error
/// naming the level; [`ScanError::Io`] or [`ScanError::Codec`] naming the file not written.
pub fn capture_ramp(
    dir: &Path,
    camera: &mut (impl Camera + ?Sized),
    projector: &mut (impl Projector + ?Sized),
    config: &RampConfig,
) -> Result<ResponseMeasurement, ScanError> {
    let wanted = ramp_levels(config.levels)?;
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let (w, h) = projector.image_size();
    let mut levels = Vec::with_capacity(wanted.len());
    let mut files = Vec::with_capacity(wanted.len());
    let mut frames = Vec::with_capacity(wanted.len());
    for (i, v) in wanted.iter().enumerate() {
        let value = (v * 255.0).round().clamp(0.0, 255.0) as u8;
        let level_err = |e: sl_rig::RigError| ScanError::Step {
            what: format!("ramp level {i} (grey {value})"),
            source: Box::new(e.into()),
        };
        let image = GreyImage::filled_u8(w as usize, h as usize, value)
            .map_err(sl_codec::CodecError::from)?;
        let timing = sl_rig::CaptureTiming {
            settle: config.display_latency,
            flush_frames: config.flush_frames,
        };
        let frame =
            sl_rig::show_and_capture(camera, projector, &image, timing).map_err(level_err)?;
        let name = format!("level_{i:02}.png");
        write_png_grey(&dir.join(&name), &frame)?;
        levels.push(f64::from(value) / 255.0);
        files.push(name);
        frames.push(frame);
    }
    let ramp = RampFile {
        format: RAMP_FORMAT.to_owned(),
        levels,
        files,
    };
    let text = serde_json::to_string_pretty(&ramp).map_err(|e| ScanError::Session {
        path: dir.join(RAMP_FILE),
        reason: e.to_string(),
    })?;
    write_atomically(&dir.join(RAMP_FILE), text.as_bytes())?;
    Ok(measure_response(&ramp.levels, &frames)?)
}

/// Measures the response from a ramp folder: its [`RAMP_FILE`] and the captures it lists.
///
/// # Errors
/// [`ScanError::Session`] naming `ramp.json` when it is missing or malformed, or naming a
/// capture it lists that does not exist; [`ScanError::Codec`] for a capture that cannot be
/// read; [`ScanError::Step`] naming the folder around the measurement's error (levels that
/// do not increase from 0 to 1, captures of different sizes named by their level, nothing
/// lit).
pub fn measure_ramp_folder(dir: &Path) -> Result<ResponseMeasurement, ScanError> {
    let path = dir.join(RAMP_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| ScanError::Session {
        path: path.clone(),
        reason: format!("cannot be read ({e}); a ramp folder holds {RAMP_FILE} and its captures"),
    })?;
    let ramp: RampFile = serde_json::from_str(&text).map_err(|e| ScanError::Session {
        path: path.clone(),
        reason: e.to_string(),
    })?;
    if ramp.format != RAMP_FORMAT {
        return Err(ScanError::Session {
            path,
            reason: format!("format {:?}, expected {RAMP_FORMAT:?}", ramp.format),
        });
    }
    if ramp.files.len() != ramp.levels.len() {
        return Err(ScanError::Session {
            path,
            reason: format!(
                "{} levels and {} files: one capture per level",
                ramp.levels.len(),
                ramp.files.len()
            ),
        });
    }
    let mut frames = Vec::with_capacity(ramp.files.len());
    for name in &ramp.files {
        let file = dir.join(name);
        if !file.is_file() {
            return Err(ScanError::Session {
                path: file,
                reason: format!("listed in {RAMP_FILE} but missing"),
            });
        }
        frames.push(read_image(&file)?);
    }
    measure_response(&ramp.levels, &frames).map_err(|e| ScanError::Step {
        what: format!("the ramp in {}", dir.display()),
        source: Box::new(e.into()),
    })
}

/// What a measured response does to phase-shift fringes, for reports: the largest phase error
/// it causes with `steps` steps when not corrected (radians), or `None` when the response
/// folds the phase (no correction possible with that many steps).
pub fn response_phase_error(measurement: &ResponseMeasurement, steps: u32) -> Option<f64> {
    PhaseCorrection::new(&measurement.curve, steps, ShiftSign::Positive, 1.0)
        .ok()
        .map(|c| c.max_error_rad())
}

/// Captures the ramp on the virtual rig of `config` looking at the flatness plate (matte,
/// flat: [`crate::plate_scene`]) into `dir`, without display latency, and measures it.
///
/// # Errors
/// As [`capture_ramp`]; the simulator's for a configuration it refuses.
#[cfg(feature = "sim")]
pub fn capture_virtual_ramp(
    config: &sl_sim::RigConfig,
    dir: &Path,
    levels: usize,
) -> Result<ResponseMeasurement, ScanError> {
    let rig = sl_sim::VirtualRig::new(config.clone(), crate::plate_scene())?;
    let (mut camera, mut projector, _table) = rig.devices();
    capture_ramp(
        dir,
        &mut camera,
        &mut projector,
        &RampConfig {
            levels,
            display_latency: Duration::ZERO,
            flush_frames: 0,
        },
    )
}

/// The figures of a measured response written beside the ramp (`response.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResponseSummary {
    /// The ramp folder.
    pub ramp: PathBuf,
    /// Pixels the measurement used.
    pub pixels: usize,
    /// Mean white minus mean black over those pixels (fraction of full scale).
    pub contrast: f64,
    /// The nearest power law's exponent.
    pub equivalent_gamma: f64,
    /// The values shown and the light read (fraction of full scale) for each.
    pub levels: Vec<f64>,
    /// See `levels`.
    pub light: Vec<f64>,
    /// The largest phase error the response causes uncorrected with 3, 4 and 5 steps
    /// (radians; `None` where it folds the phase).
    pub phase_error_rad: Vec<(u32, Option<f64>)>,
    /// The largest difference in light (fraction of white) between the curve and the true
    /// one, where a truth is known (the virtual rig).
    pub truth_difference: Option<f64>,
    /// The curve.
    pub curve: sl_codec::ToneCurve,
}

impl ResponseSummary {
    /// The summary of `measurement`, captured in `ramp`.
    pub fn new(measurement: &ResponseMeasurement, ramp: &Path) -> Self {
        Self {
            ramp: ramp.to_path_buf(),
            pixels: measurement.pixels,
            contrast: measurement.contrast,
            equivalent_gamma: measurement.curve.equivalent_gamma(),
            levels: measurement.levels.clone(),
            light: measurement.light.clone(),
            phase_error_rad: [3, 4, 5]
                .into_iter()
                .map(|n| (n, response_phase_error(measurement, n)))
                .collect(),
            truth_difference: None,
            curve: measurement.curve.clone(),
        }
    }
}

/// The summary file [`write_response_files`] writes.
pub const RESPONSE_FILE: &str = "response.json";

/// What [`write_response_files`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseFiles {
    /// The figures (also in `response.json`).
    pub summary: ResponseSummary,
    /// `calibration.json`: the calibration given, with the response, when one was given.
    pub calibration: Option<PathBuf>,
}

/// Writes a measured response into `out`: `response.json` (a [`ResponseSummary`], `ramp`
/// naming the ramp's folder) and, when `calibration` is given, `calibration.json` — that
/// calibration with [`Calibration::projector_response`](sl_camera::Calibration) set, which a
/// scan then decodes with.
///
/// # Errors
/// [`ScanError::Io`] naming a file not written; the calibration's own checks.
pub fn write_response_files(
    measurement: &ResponseMeasurement,
    ramp: &Path,
    calibration: Option<sl_camera::Calibration>,
    out: &Path,
) -> Result<ResponseFiles, ScanError> {
    std::fs::create_dir_all(out).map_err(io(out))?;
    let summary = ResponseSummary::new(measurement, ramp);
    let text = serde_json::to_string_pretty(&summary).map_err(|e| ScanError::Session {
        path: out.join(RESPONSE_FILE),
        reason: e.to_string(),
    })?;
    write_atomically(&out.join(RESPONSE_FILE), text.as_bytes())?;
    let calibration = match calibration {
        Some(mut c) => {
            c.projector_response = Some(measurement.curve.clone());
            let path = out.join("calibration.json");
            c.save(&path)?;
            Some(path)
        }
        None => None,
    };
    Ok(ResponseFiles {
        summary,
        calibration,
    })
}
