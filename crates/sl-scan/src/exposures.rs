//! Scanning at several exposures: what a scan asks for ([`Exposures`]), how a session's
//! exposures are settled (measured once, kept when the session resumes), and fusing a capture
//! folder that holds several exposures ([`fuse_exposure_folder`]).

use std::path::Path;

use sl_codec::{
    AutoExposureConfig, CaptureSet, EXPOSURES_FILE, ExposureFrames, ExposurePlan, ExposureRecord,
    FusionSettings, FusionSummary, MANIFEST_FILE, fuse_exposures, write_png_grey,
};
use sl_rig::{
    Camera, CaptureTiming, Projector, SessionExposures, Turntable, measure_exposures,
    read_session_plan,
};

use crate::ScanError;

/// The exposures a scan captures each view at.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Exposures {
    /// One, the camera's own (the default).
    #[default]
    Camera,
    /// These exposure times (milliseconds).
    Fixed(Vec<f64>),
    /// Chosen from a white and a black frame of the object at the session's first view
    /// ([`sl_rig::measure_exposures`]), once per session: a resumed session keeps the
    /// exposures it was started with.
    Auto(AutoExposureConfig),
}

impl Exposures {
    /// Whether several exposures may be captured (a camera with an exposure control needed).
    pub fn is_single(&self) -> bool {
        matches!(self, Self::Camera)
    }
}

impl std::str::FromStr for Exposures {
    type Err = ScanError;

    /// `auto`, `camera`, or exposure times in milliseconds separated by commas (`2,8,32`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "auto" => Ok(Self::Auto(AutoExposureConfig::default())),
            "camera" => Ok(Self::Camera),
            list => {
                let times = list
                    .split(',')
                    .map(|t| {
                        t.trim()
                            .parse::<f64>()
                            .ok()
                            .filter(|v| v.is_finite() && *v > 0.0)
                            .ok_or_else(|| ScanError::InvalidParameter {
                                name: "exposures".to_owned(),
                                reason: format!(
                                    "'{t}' in '{s}' is not an exposure time in milliseconds: give `auto`, `camera` or times such as `2,8,32`"
                                ),
                            })
                    })
                    .collect::<Result<Vec<f64>, ScanError>>()?;
                // Checked (distinct, how many) as the session's.
                SessionExposures::new(times.clone(), FusionSettings::default())?;
                Ok(Self::Fixed(times))
            }
        }
    }
}

/// The exposures of the session in `dir`: `Fixed` as given, `Camera` none, and `Auto` those of
/// the session already in `dir` (a resumed session) or else `measure`'s, whose plan is returned
/// as well.
pub(crate) fn session_exposures(
    dir: &Path,
    exposures: &Exposures,
    fusion: FusionSettings,
    overwrite: bool,
    measure: impl FnOnce(&AutoExposureConfig) -> Result<ExposurePlan, ScanError>,
) -> Result<(SessionExposures, Option<ExposurePlan>), ScanError> {
    if let Exposures::Auto(auto) = exposures
        && recorded_exposures(dir, overwrite).is_none()
    {
        let plan = measure(auto)?;
        return Ok((
            SessionExposures::new(plan.exposures_ms.clone(), fusion)?,
            Some(plan),
        ));
    }
    Ok((planned_exposures(dir, exposures, fusion, overwrite)?, None))
}

/// The exposures the session in `dir` is planned with before anything is measured: `Fixed` as
/// given, `Camera` none, `Auto` those already recorded in `dir` and else one (the automatic
/// ones are measured once the devices run, [`session_exposures`]).
pub(crate) fn planned_exposures(
    dir: &Path,
    exposures: &Exposures,
    fusion: FusionSettings,
    overwrite: bool,
) -> Result<SessionExposures, ScanError> {
    match exposures {
        Exposures::Camera => Ok(SessionExposures::default()),
        Exposures::Fixed(times) => Ok(SessionExposures::new(times.clone(), fusion)?),
        Exposures::Auto(_) => Ok(recorded_exposures(dir, overwrite).unwrap_or_default()),
    }
}

/// The several exposures a session already in `dir` was started with (kept when it resumes;
/// none with `overwrite`).
fn recorded_exposures(dir: &Path, overwrite: bool) -> Option<SessionExposures> {
    if overwrite {
        return None;
    }
    read_session_plan(dir)
        .ok()
        .map(|plan| plan.exposures)
        .filter(|e| !e.is_single())
}

/// Measures the automatic exposures `auto` through the devices with the turntable at
/// `first_deg` (the session's first view), showing and capturing with `timing`; a camera that
/// does not report its exposure starts at `start_ms`.
///
/// # Errors
/// The devices' failures.
pub(crate) fn measure_at_first_view<C, P, T>(
    (camera, projector, turntable): (&mut C, &mut P, &mut T),
    first_deg: f64,
    auto: &AutoExposureConfig,
    timing: CaptureTiming,
    start_ms: f64,
) -> Result<ExposurePlan, ScanError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
    T: Turntable + ?Sized,
{
    turntable.rotate_to(first_deg)?;
    Ok(measure_exposures(
        camera,
        projector,
        auto,
        timing,
        start_ms,
        |_, _| {},
    )?)
}

/// Fuses the capture folder `dir` from the exposures its `exposures.json` lists (see
/// docs/capture-format.md): each exposure's folder holds the same frames (by the manifest of
/// `dir`, or else of the first exposure's folder); the fused frames are written into `dir`
/// under those names (as PNG), with the manifest when `dir` has none, and the record gains the fusion's
/// summary. This is how another system's captures at several exposures are decoded: write the
/// small `exposures.json` by hand, fuse, decode `dir`.
///
/// # Errors
/// [`ScanError::Codec`] naming `exposures.json`, the manifest, or the exposure folder and
/// frame at fault (a missing frame, another size); nothing in `dir` is written before every
/// exposure has been read.
pub fn fuse_exposure_folder(dir: &Path) -> Result<FusionSummary, ScanError> {
    let record_path = dir.join(EXPOSURES_FILE);
    let mut record = ExposureRecord::load(&record_path)?;
    let own_manifest = dir.join(MANIFEST_FILE);
    let manifest_path = if own_manifest.is_file() {
        own_manifest.clone()
    } else {
        dir.join(&record.exposures[0].dir).join(MANIFEST_FILE)
    };
    let mut stacks = Vec::with_capacity(record.exposures.len());
    let mut manifest = None;
    for e in &record.exposures {
        let set = CaptureSet::load_with_frames_dir(&manifest_path, Some(&dir.join(&e.dir)))?;
        manifest.get_or_insert_with(|| set.manifest.clone());
        stacks.push(ExposureFrames {
            exposure_ms: e.exposure_ms,
            frames: set.frames.into_images(),
        });
    }
    let Some(mut manifest) = manifest else {
        return Err(ScanError::InvalidParameter {
            name: record_path.display().to_string(),
            reason: "lists no exposure".to_owned(),
        });
    };
    let fused = fuse_exposures(&stacks, &record.fusion.config())?;
    let names: Vec<&String> = manifest.blocks.iter().flat_map(|b| &b.frames).collect();
    for (frame, name) in fused.frames.iter().zip(names) {
        // PNG whatever the exposures' files were: the manifest's name is still found
        // (`CaptureSet::load` accepts a frame saved under another image extension).
        write_png_grey(&dir.join(name).with_extension("png"), frame)?;
    }
    if !own_manifest.is_file() {
        manifest.frames_dir = None;
        manifest.save(&own_manifest)?;
    }
    record.summary = Some(fused.summary.clone());
    record.save(&record_path)?;
    Ok(fused.summary)
}
