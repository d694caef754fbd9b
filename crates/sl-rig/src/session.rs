//! Capture sessions: a turntable scan written once against the device traits, saved view by
//! view so that an interrupted scan resumes where it stopped.
//!
//! For each turntable angle of the plan: rotate, then for each pattern show it, wait for the
//! display latency, flush the frames the camera buffered before the change, and capture. Each
//! view goes into `SESSION/view_NNN/` as a capture set in `sl-codec`'s format: every file is
//! written under a temporary name and renamed into place, and the view's `manifest.json` is
//! written last — its presence marks the view complete. `SESSION/session.json` holds the plan.
//!
//! With [`SessionPlan::colour`] each view then shows full white and captures one colour frame
//! ([`Camera::capture_colour`]) into `view_NNN/colour.png` ([`COLOUR_FILE`]), named by the
//! view manifest's `colour` key.
//!
//! With a second camera ([`CaptureSession::run_binocular`]; the plan names it in
//! [`SessionDevices::right_camera`]) each view also holds `view_NNN/right/`, the second
//! camera's capture set of the same patterns, written before the view's own manifest. The two
//! cameras are kept in step by the projector: each pattern stays on until both have captured
//! their frame under it (after the display latency and each camera's flush).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use sl_codec::{
    CaptureSet, DecodeConfig, EXPOSURES_FILE, ExposureFolder, ExposureFrames, ExposureRecord,
    FrameIssue, Frames, FusionSettings, MANIFEST_FILE, Manifest, check_frames, decode,
    fuse_exposures, write_png_colour, write_png_grey,
};

use crate::{Camera, GreyImage, Projector, RigError, Turntable, flush_and_capture};

/// Name of the plan file at the root of a session folder.
pub const SESSION_FILE: &str = "session.json";
/// Value of the `format` key of [`SESSION_FILE`].
pub const SESSION_FORMAT: &str = "sl-session";
/// Version of the [`SESSION_FILE`] schema this crate writes and reads.
pub const SESSION_VERSION: u32 = 1;
/// Prefix of the temporary names files are written under before being renamed into place;
/// [`CaptureSession::run`] deletes leftovers with this prefix when it redoes a view.
const PARTIAL_PREFIX: &str = ".partial-";

/// File, inside a view's folder, of the colour frame of a session with
/// [`SessionPlan::colour`]: the object under full white, 8-bit RGB PNG, named by the view
/// manifest's `colour` key.
pub const COLOUR_FILE: &str = "colour.png";

/// Folder, inside a view's (or a calibration pose's) folder, of the second camera's capture set.
pub const RIGHT_DIR: &str = "right";

/// Folder name of exposure `index` (shortest first) inside a view folder captured at several
/// exposures (`exposure_0`, `exposure_1`, …).
pub fn exposure_dir_name(index: usize) -> String {
    format!("exposure_{index}")
}

/// The exposures a session captures each view at ([`SessionPlan::exposures`]).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SessionExposures {
    /// Exposure times (milliseconds), shortest first. Empty (the default): one pass at the
    /// camera's own exposure, frames straight into the view's folder. Otherwise each view
    /// captures the whole sequence once per exposure into `exposure_<i>/`, and its folder
    /// holds the frames fused from them ([`sl_codec::fuse_exposures`]) and `exposures.json`.
    pub times_ms: Vec<f64>,
    /// How the exposures are fused.
    #[serde(default)]
    pub fusion: FusionSettings,
}

impl SessionExposures {
    /// Exposures `times_ms` (any order: they are sorted) fused with `fusion`.
    ///
    /// # Errors
    /// [`RigError::InvalidParameter`] naming `exposures` when a time is not positive, appears
    /// twice, or there are more than [`sl_codec::MAX_EXPOSURES`].
    pub fn new(mut times_ms: Vec<f64>, fusion: FusionSettings) -> Result<Self, RigError> {
        times_ms.sort_by(f64::total_cmp);
        if times_ms.len() > sl_codec::MAX_EXPOSURES
            || times_ms.iter().any(|t| !(t.is_finite() && *t > 0.0))
            || times_ms.windows(2).any(|w| w[0] == w[1])
        {
            return Err(RigError::param(
                "exposures",
                format!(
                    "{times_ms:?} ms: up to {} different positive exposure times",
                    sl_codec::MAX_EXPOSURES
                ),
            ));
        }
        Ok(Self { times_ms, fusion })
    }

    /// Whether the views are captured once, at the camera's own exposure.
    pub fn is_single(&self) -> bool {
        self.times_ms.is_empty()
    }
}

/// Folder name of view `index` inside a session folder (`view_000`, `view_001`, …).
pub fn view_dir_name(index: usize) -> String {
    format!("view_{index:03}")
}

/// Angles (degrees) of `views` views evenly spread over a full turn, starting at 0.
pub fn turntable_angles(views: usize) -> Vec<f64> {
    (0..views)
        .map(|k| 360.0 * k as f64 / views.max(1) as f64)
        .collect()
}

/// What the devices of a session are, as free text for the record (`session.json`).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SessionDevices {
    /// The camera, e.g. `/dev/video0`.
    pub camera: String,
    /// The projector, e.g. `monitor 1`.
    pub projector: String,
    /// The turntable, e.g. `/dev/ttyUSB0 id 1`.
    pub turntable: String,
    /// The second camera of a binocular rig, e.g. `/dev/video2`; `None` for one camera. A
    /// plan with one captures each view with both cameras ([`CaptureSession::run_binocular`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub right_camera: Option<String>,
}

/// The plan of a capture session: where the turntable goes and what the projector shows.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionPlan {
    /// Turntable motor angles (degrees), one view each, in capture order.
    pub angles_deg: Vec<f64>,
    /// The pattern sequence (and the frame file names) every view captures.
    pub manifest: Manifest,
    /// The devices, for the record.
    pub devices: SessionDevices,
    /// The calibration file the session is meant to be reconstructed with, for the record.
    pub calibration: Option<PathBuf>,
    /// The exposures each view is captured at. Default: one, the camera's own.
    pub exposures: SessionExposures,
    /// Capture each view's colour: after the patterns (and the exposures' passes, at the
    /// camera's own exposure), show full white and capture one colour frame
    /// ([`Camera::capture_colour`]) into the view's [`COLOUR_FILE`], which its manifest names
    /// (`colour` key). The first camera's only. A camera that cannot capture colour fails the
    /// view with [`RigError::Unsupported`] naming this option. `session.json`'s `colour`
    /// (absent: `false`).
    pub colour: bool,
}

/// How a session synchronises the projector and the camera, and whether it may overwrite.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SessionConfig {
    /// Time to wait after showing a pattern before capturing: the projector's display latency
    /// (input lag plus the frame being scanned out). Default [`DEFAULT_DISPLAY_LATENCY`].
    pub display_latency: Duration,
    /// Frames captured and dropped after each pattern change: the frames the camera driver
    /// buffered before the change ([`crate::measure_latency`] measures it). Default 0 (a camera
    /// that buffers nothing).
    pub flush_frames: usize,
    /// Recapture views that are already complete, and accept a `session.json` with another
    /// plan (which is then replaced). Default `false`: a finished view is never overwritten.
    pub overwrite: bool,
    /// Check each view's frames once captured (`sl_codec::check_frames` after a decode) and
    /// capture the frames it names again — late, mixed or dark: the projector or the camera
    /// out of step — after a longer wait, which the rest of the session keeps (doubled, at
    /// least 50 ms, at most 2 s). Default `true`.
    pub check_frames: bool,
}

/// Rounds of capturing named frames again before a view is kept with them (each named in
/// [`ViewOutcome::frame_issues`]).
pub const RECAPTURE_ROUNDS: usize = 3;

/// Default display latency: a 60 Hz projector shows a new image within two or three refreshes
/// (17–50 ms) once the compositor has it; 100 ms leaves a margin for a slow compositor or a
/// projector's image processing. Measure it with [`crate::measure_latency`] to go faster.
pub const DEFAULT_DISPLAY_LATENCY: Duration = Duration::from_millis(100);

impl Default for SessionConfig {
    fn default() -> Self {
        Self {
            display_latency: DEFAULT_DISPLAY_LATENCY,
            flush_frames: 0,
            overwrite: false,
            check_frames: true,
        }
    }
}

/// State of one view's folder on disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum ViewState {
    /// No folder yet.
    Missing,
    /// A folder without a valid manifest, or with frames missing: an interrupted capture,
    /// redone from scratch on the next run.
    Partial,
    /// The manifest of the plan and every frame it names are there.
    Complete,
}

/// What happened to one view during [`CaptureSession::run`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewOutcome {
    /// Index of the view in the plan.
    pub index: usize,
    /// Its folder.
    pub dir: PathBuf,
    /// Motor angle asked for (degrees).
    pub motor_angle_deg: f64,
    /// Angle the turntable reported after moving (`None` when the view was skipped).
    pub reached_deg: Option<f64>,
    /// `true` when captured in this run, `false` when an existing complete view was kept.
    pub captured: bool,
    /// Frames written (0 when skipped).
    pub frames: usize,
    /// Wall time spent on the view (ms): rotation, capture and writing.
    pub ms: f64,
    /// Frames captured again because the frame checks named them (one message each: the
    /// frame, what was wrong, the wait it was captured again after).
    pub recaptured: Vec<String>,
    /// Frames the checks still name after [`RECAPTURE_ROUNDS`] rounds: the view is kept with
    /// them (decoded all the same), and they are named here.
    pub frame_issues: Vec<String>,
}

/// What a whole [`CaptureSession::run`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SessionSummary {
    /// One outcome per view of the plan, in order.
    pub views: Vec<ViewOutcome>,
    /// Views captured in this run.
    pub captured: usize,
    /// Complete views kept from an earlier run.
    pub skipped: usize,
}

/// `session.json` on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SessionFile {
    format: String,
    version: u32,
    angles_deg: Vec<f64>,
    patterns: serde_json::Value,
    devices: SessionDevices,
    calibration: Option<String>,
    views: Vec<String>,
    #[serde(default, skip_serializing_if = "SessionExposures::is_single")]
    exposures: SessionExposures,
    /// Written only when `true`, so that sessions without colour keep their `session.json`.
    #[serde(default, skip_serializing_if = "is_false")]
    colour: bool,
}

/// Whether `b` is `false` (serde's `skip_serializing_if` takes a function).
#[allow(clippy::trivially_copy_pass_by_ref)]
fn is_false(b: &bool) -> bool {
    !*b
}

/// A capture session in a folder: the plan, the synchronisation settings, and the views on
/// disk.
///
/// ```
/// use sl_rig::{CaptureSession, SessionConfig, SessionPlan};
/// # use std::{cell::RefCell, rc::Rc};
/// # use sl_rig::{Camera, GreyImage, Projector, RigError, Turntable};
/// # // A "mirror" rig: the camera sees exactly what the projector shows (black before).
/// # struct Mirror(Rc<RefCell<GreyImage>>);
/// # impl Camera for Mirror {
/// #     fn frame_size(&self) -> (u32, u32) { (64, 36) }
/// #     fn capture(&mut self) -> Result<GreyImage, RigError> { Ok(self.0.borrow().clone()) }
/// # }
/// # impl Projector for Mirror {
/// #     fn image_size(&self) -> (u32, u32) { (64, 36) }
/// #     fn show(&mut self, image: &GreyImage) -> Result<(), RigError> {
/// #         *self.0.borrow_mut() = image.clone();
/// #         Ok(())
/// #     }
/// # }
/// # struct Table(f64);
/// # impl Turntable for Table {
/// #     fn rotate_to(&mut self, a: f64) -> Result<f64, RigError> { self.0 = a; Ok(a) }
/// #     fn angle_deg(&mut self) -> Result<f64, RigError> { Ok(self.0) }
/// # }
/// # fn devices() -> Result<(Mirror, Mirror, Table), RigError> {
/// #     let screen = Rc::new(RefCell::new(GreyImage::filled_u8(64, 36, 0)?));
/// #     Ok((Mirror(screen.clone()), Mirror(screen), Table(0.0)))
/// # }
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// // Any devices behind the traits; here a 64x36 camera that sees exactly what the projector
/// // shows, and a turntable.
/// let (mut camera, mut projector, mut table) = devices()?;
/// // Gray code columns of the 64x36 projector, two views.
/// use sl_codec::{Axis, BitDepth, GrayCodeSpec, Pattern, PatternSequence, ImageSize};
/// let p = ImageSize::new(64, 36);
/// let sequence = PatternSequence::new(p)
///     .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Column, p, true)));
/// let manifest = sequence.manifest(BitDepth::Eight);
/// let plan = SessionPlan {
///     angles_deg: vec![0.0, 180.0],
///     manifest,
///     devices: Default::default(),
///     calibration: None,
///     exposures: Default::default(),
///     colour: false,
/// };
/// let dir = tempfile::tempdir()?;
/// let config = SessionConfig { display_latency: std::time::Duration::ZERO, ..Default::default() };
/// let session = CaptureSession::open(dir.path(), plan, config)?;
/// let summary = session.run(&mut camera, &mut projector, &mut table, |_| {})?;
/// assert_eq!(summary.captured, 2);
/// // Running again captures nothing: both views are complete.
/// let again = session.run(&mut camera, &mut projector, &mut table, |_| {})?;
/// assert_eq!((again.captured, again.skipped), (0, 2));
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Clone)]
pub struct CaptureSession {
    dir: PathBuf,
    plan: SessionPlan,
    config: SessionConfig,
    /// The wait after showing a pattern (ns): the configured display latency, longer once a
    /// frame came out of step ([`SessionConfig::check_frames`]).
    settle_ns: Arc<AtomicU64>,
}

impl CaptureSession {
    /// What [`CaptureSession::open`] checks, without writing anything: a plan that can be
    /// captured, and one that `dir` can take (no session there, the same plan, or
    /// `config.overwrite`). A program that writes other files beside the session (a
    /// calibration, the truth) checks first, so that a refused session leaves them as they
    /// were.
    ///
    /// # Errors
    /// As [`CaptureSession::open`].
    pub fn check(dir: &Path, plan: &SessionPlan, config: &SessionConfig) -> Result<(), RigError> {
        if plan.angles_deg.is_empty() {
            return Err(RigError::param(
                "angles",
                "a session needs at least one view",
            ));
        }
        if let Some((k, a)) = plan
            .angles_deg
            .iter()
            .enumerate()
            .find(|(_, a)| !a.is_finite())
        {
            return Err(RigError::param(
                format!("angles[{k}]"),
                format!("{a} is not finite"),
            ));
        }
        if plan.manifest.frame_count() == 0 {
            return Err(RigError::param("patterns", "the manifest names no frame"));
        }
        let path = dir.join(SESSION_FILE);
        if path.exists() && !config.overwrite {
            let existing = read_session_file(&path)?;
            if let Some(reason) = plan_difference(&existing, &session_file(plan)) {
                return Err(RigError::SessionMismatch { path, reason });
            }
        }
        Ok(())
    }

    /// Opens (or starts) the session in `dir`: creates the folder and writes `session.json`,
    /// or checks that an existing `session.json` holds the same plan (angles and patterns).
    ///
    /// # Errors
    /// [`RigError::SessionMismatch`] when `dir` holds a session with another plan and
    /// `config.overwrite` is off; [`RigError::InvalidParameter`] for an empty plan or a
    /// non-finite angle; [`RigError::Io`] / [`RigError::Json`] naming the file.
    pub fn open(dir: &Path, plan: SessionPlan, config: SessionConfig) -> Result<Self, RigError> {
        Self::check(dir, &plan, &config)?;
        std::fs::create_dir_all(dir).map_err(|e| RigError::io(dir, e))?;
        let session = Self {
            dir: dir.to_path_buf(),
            plan,
            settle_ns: Arc::new(AtomicU64::new(duration_ns(config.display_latency))),
            config,
        };
        let file = session.file();
        let path = dir.join(SESSION_FILE);
        let text = serde_json::to_string_pretty(&file).map_err(|source| RigError::Json {
            path: path.clone(),
            source,
        })?;
        write_atomically(&path, |tmp| {
            std::fs::write(tmp, format!("{text}\n")).map_err(|e| RigError::io(tmp, e))
        })?;
        Ok(session)
    }

    /// The session folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The plan.
    pub fn plan(&self) -> &SessionPlan {
        &self.plan
    }

    /// The synchronisation settings.
    pub fn config(&self) -> &SessionConfig {
        &self.config
    }

    /// Folder of view `index`.
    pub fn view_dir(&self, index: usize) -> PathBuf {
        self.dir.join(view_dir_name(index))
    }

    /// Folders of every view of the plan, in order.
    pub fn view_dirs(&self) -> Vec<PathBuf> {
        (0..self.plan.angles_deg.len())
            .map(|k| self.view_dir(k))
            .collect()
    }

    /// State of view `index` on disk.
    pub fn view_state(&self, index: usize) -> ViewState {
        let dir = self.view_dir(index);
        if !dir.is_dir() {
            return ViewState::Missing;
        }
        let complete = self.capture_set_complete(&dir)
            && (!self.plan.colour || colour_complete(&dir))
            && (self.plan.devices.right_camera.is_none()
                || self.capture_set_complete(&dir.join(RIGHT_DIR)));
        if complete {
            ViewState::Complete
        } else {
            ViewState::Partial
        }
    }

    /// Whether `dir` holds the plan's manifest and every frame it names.
    fn capture_set_complete(&self, dir: &Path) -> bool {
        let Ok(manifest) = Manifest::load(&dir.join(MANIFEST_FILE)) else {
            return false;
        };
        let frames_match = manifest.blocks.len() == self.plan.manifest.blocks.len()
            && manifest
                .blocks
                .iter()
                .zip(&self.plan.manifest.blocks)
                .all(|(a, b)| a.pattern == b.pattern && a.frames == b.frames);
        let all_there = frame_names(&self.plan.manifest)
            .iter()
            .all(|name| dir.join(name).is_file());
        frames_match && all_there
    }

    /// State of every view of the plan.
    pub fn view_states(&self) -> Vec<ViewState> {
        (0..self.plan.angles_deg.len())
            .map(|k| self.view_state(k))
            .collect()
    }

    /// Runs the session: captures every view that is not complete (every view with
    /// `overwrite`), calling `on_view` after each view, captured or kept.
    ///
    /// # Errors
    /// [`RigError::Session`] naming the view (and the frame) at fault, around the device's or
    /// the file system's error; [`RigError::ImageSize`] when the projector's size differs from
    /// the patterns'. Views completed before the failure stay complete.
    pub fn run<C, P, T>(
        &self,
        camera: &mut C,
        projector: &mut P,
        turntable: &mut T,
        on_view: impl FnMut(&ViewOutcome),
    ) -> Result<SessionSummary, RigError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
        T: Turntable + ?Sized,
    {
        if let Some(right) = &self.plan.devices.right_camera {
            return Err(RigError::param(
                "right camera",
                format!("the plan names a second camera ({right}): capture it with run_binocular"),
            ));
        }
        self.run_cameras(camera, None::<&mut C>, projector, turntable, on_view)
    }

    /// [`CaptureSession::run`] with a second camera: under each pattern both cameras capture
    /// a frame (`left` first), the second camera's into `view_NNN/right/`. A view is complete
    /// when both capture sets are.
    ///
    /// # Errors
    /// As [`CaptureSession::run`]; [`RigError::InvalidParameter`] when the plan names no
    /// second camera ([`SessionDevices::right_camera`]).
    pub fn run_binocular<C, R, P, T>(
        &self,
        left: &mut C,
        right: &mut R,
        projector: &mut P,
        turntable: &mut T,
        on_view: impl FnMut(&ViewOutcome),
    ) -> Result<SessionSummary, RigError>
    where
        C: Camera + ?Sized,
        R: Camera + ?Sized,
        P: Projector + ?Sized,
        T: Turntable + ?Sized,
    {
        if self.plan.devices.right_camera.is_none() {
            return Err(RigError::param(
                "right camera",
                "the plan names no second camera (SessionDevices::right_camera): capture it with run",
            ));
        }
        self.run_cameras(left, Some(right), projector, turntable, on_view)
    }

    fn run_cameras<C, R, P, T>(
        &self,
        camera: &mut C,
        mut right: Option<&mut R>,
        projector: &mut P,
        turntable: &mut T,
        mut on_view: impl FnMut(&ViewOutcome),
    ) -> Result<SessionSummary, RigError>
    where
        C: Camera + ?Sized,
        R: Camera + ?Sized,
        P: Projector + ?Sized,
        T: Turntable + ?Sized,
    {
        let patterns = pattern_images(&self.plan.manifest, projector.image_size())?;
        let names = frame_names(&self.plan.manifest);
        let right_name = self
            .plan
            .devices
            .right_camera
            .as_deref()
            .unwrap_or_default();
        let mut views = Vec::with_capacity(self.plan.angles_deg.len());
        for (index, &angle) in self.plan.angles_deg.iter().enumerate() {
            let t = Instant::now();
            let dir = self.view_dir(index);
            let outcome = if !self.config.overwrite && self.view_state(index) == ViewState::Complete
            {
                ViewOutcome {
                    index,
                    dir,
                    motor_angle_deg: angle,
                    reached_deg: None,
                    captured: false,
                    frames: 0,
                    ms: ms(t),
                    recaptured: Vec::new(),
                    frame_issues: Vec::new(),
                }
            } else {
                let at = |frame: Option<usize>| {
                    move |source: RigError| RigError::Session {
                        view: index,
                        frame,
                        source: Box::new(source),
                    }
                };
                let right_dir = dir.join(RIGHT_DIR);
                prepare_view_dir(&dir).map_err(at(None))?;
                if right.is_some() {
                    prepare_view_dir(&right_dir).map_err(at(None))?;
                }
                let reached = turntable.rotate_to(angle).map_err(at(None))?;
                // Show pattern `k`, capture it with each camera and write the frames into
                // `dirs` (the first camera's folder, the second's).
                let take = |k: usize,
                            dirs: (&Path, &Path),
                            camera: &mut C,
                            right: Option<&mut R>,
                            projector: &mut P|
                 -> Result<(GreyImage, Option<GreyImage>), RigError> {
                    let frame = self
                        .capture_one(camera, projector, &patterns[k])
                        .map_err(at(Some(k)))?;
                    // The pattern is still on: the second camera captures under it too.
                    let second = match right {
                        Some(r) => Some(
                            self.grab(r, "second camera")
                                .map_err(|e| e.of_right_camera(right_name))
                                .map_err(at(Some(k)))?,
                        ),
                        None => None,
                    };
                    let path = dirs.0.join(&names[k]);
                    write_atomically(&path, |tmp| Ok(write_png_grey(tmp, &frame)?))
                        .map_err(at(Some(k)))?;
                    if let Some(second) = &second {
                        let path = dirs.1.join(&names[k]);
                        write_atomically(&path, |tmp| Ok(write_png_grey(tmp, second)?))
                            .map_err(at(Some(k)))?;
                    }
                    Ok((frame, second))
                };
                // One pass of the sequence, or one per exposure into its own folders.
                let exposures = &self.plan.exposures.times_ms;
                let passes: Vec<Option<(usize, f64)>> = if exposures.is_empty() {
                    vec![None]
                } else {
                    exposures.iter().copied().enumerate().map(Some).collect()
                };
                let pass_dirs = |pass: Option<(usize, f64)>| match pass {
                    None => (dir.clone(), right_dir.clone()),
                    Some((i, _)) => {
                        let name = exposure_dir_name(i);
                        (dir.join(&name), right_dir.join(&name))
                    }
                };
                // Both cameras at the pass's exposure (the camera's own for the one pass).
                let expose = |pass: Option<(usize, f64)>,
                              camera: &mut C,
                              right: Option<&mut R>|
                 -> Result<(), RigError> {
                    if let Some((_, ms)) = pass {
                        camera.set_exposure_ms(ms).map_err(at(None))?;
                        if let Some(r) = right {
                            r.set_exposure_ms(ms)
                                .map_err(|e| e.of_right_camera(right_name))
                                .map_err(at(None))?;
                        }
                    }
                    Ok(())
                };
                let restore = camera.exposure_ms();
                let (mut lefts_of, mut rights_of) = (Vec::new(), Vec::new());
                for &pass in &passes {
                    let (l, r) = pass_dirs(pass);
                    if pass.is_some() {
                        prepare_view_dir(&l).map_err(at(None))?;
                        if right.is_some() {
                            prepare_view_dir(&r).map_err(at(None))?;
                        }
                    }
                    expose(pass, camera, right.as_deref_mut())?;
                    let (mut lefts, mut rights) = (Vec::new(), Vec::new());
                    for k in 0..patterns.len() {
                        let (frame, second) =
                            take(k, (&l, &r), camera, right.as_deref_mut(), projector)?;
                        lefts.push(frame);
                        rights.extend(second);
                    }
                    lefts_of.push(lefts);
                    rights_of.push(rights);
                }
                // Frames out of step captured again (at every exposure), after a longer wait.
                // With several exposures one pass is judged: the one nearest the camera's own
                // exposure (the one it was set up with; without one, the middle exposure). The
                // passes far from it are mostly saturated or mostly dark, where the checks
                // took true frames for late ones on the virtual rig, and so would the fused
                // frames, whose pixels differ in gain. Late projectors and dropped frames come
                // from the devices' timing, which every pass shares, and the longer wait
                // learned from the judged pass serves them all.
                let judged = judged_pass(exposures, restore);
                let (mut recaptured, mut frame_issues) = (Vec::new(), Vec::new());
                if self.config.check_frames {
                    let dirs: Vec<(PathBuf, PathBuf)> =
                        passes.iter().map(|&p| pass_dirs(p)).collect();
                    let left_dirs: Vec<PathBuf> = dirs.iter().map(|d| d.0.clone()).collect();
                    let right_dirs: Vec<PathBuf> = dirs.iter().map(|d| d.1.clone()).collect();
                    for round in 0..=RECAPTURE_ROUNDS {
                        let mut issues = self.lying_pass(&lefts_of, &left_dirs, judged, &names);
                        issues.extend(self.lying_pass(&rights_of, &right_dirs, judged, &names));
                        if issues.is_empty() {
                            break;
                        }
                        if round == RECAPTURE_ROUNDS {
                            frame_issues = issues.iter().map(ToString::to_string).collect();
                            break;
                        }
                        let settle = self.settle_longer();
                        let mut again: Vec<usize> = issues.iter().map(|i| i.frame).collect();
                        again.sort_unstable();
                        again.dedup();
                        for issue in &issues {
                            recaptured.push(format!(
                                "{issue}; captured again after {} ms",
                                settle.as_millis()
                            ));
                        }
                        for (p, &pass) in passes.iter().enumerate() {
                            let (l, r) = pass_dirs(pass);
                            expose(pass, camera, right.as_deref_mut())?;
                            for &k in &again {
                                let (frame, second) =
                                    take(k, (&l, &r), camera, right.as_deref_mut(), projector)?;
                                lefts_of[p][k] = frame;
                                if let (Some(second), Some(slot)) =
                                    (second, rights_of[p].get_mut(k))
                                {
                                    *slot = second;
                                }
                            }
                        }
                    }
                }
                if !exposures.is_empty() {
                    // Each exposure's folder is a capture of its own.
                    for &pass in &passes {
                        let (l, r) = pass_dirs(pass);
                        if right.is_some() {
                            self.write_view_manifest(&r, index, angle, reached, None)
                                .map_err(at(None))?;
                        }
                        self.write_view_manifest(&l, index, angle, reached, None)
                            .map_err(at(None))?;
                    }
                    if let Some(ms) = restore {
                        camera.set_exposure_ms(ms).map_err(at(None))?;
                    }
                    self.write_fused(&dir, lefts_of, &names).map_err(at(None))?;
                    if right.is_some() {
                        self.write_fused(&right_dir, rights_of, &names)
                            .map_err(at(None))?;
                    }
                }
                // The colour under full white, at the camera's own exposure (restored above).
                let colour = if self.plan.colour {
                    self.capture_colour(camera, projector, &dir)
                        .map_err(at(None))?;
                    Some(COLOUR_FILE)
                } else {
                    None
                };
                // The second camera's manifest first: the view's own marks it complete.
                if right.is_some() {
                    self.write_view_manifest(&right_dir, index, angle, reached, None)
                        .map_err(at(None))?;
                }
                self.write_view_manifest(&dir, index, angle, reached, colour)
                    .map_err(at(None))?;
                ViewOutcome {
                    index,
                    dir,
                    motor_angle_deg: angle,
                    reached_deg: Some(reached),
                    captured: true,
                    frames: names.len(),
                    ms: ms(t),
                    recaptured,
                    frame_issues,
                }
            };
            on_view(&outcome);
            views.push(outcome);
        }
        let captured = views.iter().filter(|v| v.captured).count();
        Ok(SessionSummary {
            skipped: views.len() - captured,
            captured,
            views,
        })
    }

    /// The wait after showing a pattern: the display latency, or longer once frames came out
    /// of step in this session.
    pub fn settle(&self) -> Duration {
        Duration::from_nanos(self.settle_ns.load(Ordering::Relaxed))
    }

    /// Waits longer after each pattern from now on: twice as long, at least 50 ms, at most 2 s
    /// (or as long as it was, when that was longer).
    fn settle_longer(&self) -> Duration {
        let now = self.settle();
        let longer = (now * 2)
            .clamp(Duration::from_millis(50), Duration::from_secs(2))
            .max(now);
        self.settle_ns.store(duration_ns(longer), Ordering::Relaxed);
        longer
    }

    /// Show → wait for the display latency → flush → capture.
    fn capture_one<C, P>(
        &self,
        camera: &mut C,
        projector: &mut P,
        pattern: &GreyImage,
    ) -> Result<GreyImage, RigError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        projector.show(pattern)?;
        let settle = self.settle();
        if !settle.is_zero() {
            std::thread::sleep(settle);
        }
        self.grab(camera, "camera")
    }

    /// The frames of one camera's view that the frame checks name, each by its file in `dir`
    /// (none when the frames do not decode: the checks need the codes).
    fn lying_frames(&self, frames: &[GreyImage], dir: &Path, names: &[String]) -> Vec<FrameIssue> {
        let frames = Frames::from_images(frames.to_vec());
        let Ok(set) = CaptureSet::from_frames(self.plan.manifest.clone(), frames) else {
            return Vec::new();
        };
        let Ok(map) = decode(&set, &DecodeConfig::default()) else {
            return Vec::new();
        };
        let mut issues = check_frames(&set, &map);
        for issue in &mut issues {
            if let Some(name) = names.get(issue.frame) {
                issue.name = dir.join(name).display().to_string();
            }
        }
        issues
    }

    /// Flush → capture, the frame's size checked against the camera's.
    fn grab<C: Camera + ?Sized>(&self, camera: &mut C, what: &str) -> Result<GreyImage, RigError> {
        let frame = flush_and_capture(camera, self.config.flush_frames)?;
        let expected = camera.frame_size();
        let size = frame.size();
        if (size.width, size.height) != expected {
            return Err(RigError::ImageSize {
                what: format!("{what} frame"),
                expected_width: expected.0,
                expected_height: expected.1,
                width: size.width,
                height: size.height,
            });
        }
        Ok(frame)
    }

    /// The frames the checks name among one camera's passes (`dirs`: their folders): those of
    /// pass `judged`, as a one-exposure capture's.
    fn lying_pass(
        &self,
        frames_of: &[Vec<GreyImage>],
        dirs: &[PathBuf],
        judged: usize,
        names: &[String],
    ) -> Vec<FrameIssue> {
        match (frames_of.get(judged), dirs.get(judged)) {
            (Some(frames), Some(dir)) if !frames.is_empty() => {
                self.lying_frames(frames, dir, names)
            }
            _ => Vec::new(),
        }
    }

    /// Fuses one camera's frames of each exposure (in the plan's order) and writes the fused
    /// frames and `exposures.json` into `dir`.
    fn write_fused(
        &self,
        dir: &Path,
        frames_of: Vec<Vec<GreyImage>>,
        names: &[String],
    ) -> Result<(), RigError> {
        let stacks: Vec<ExposureFrames> = self
            .plan
            .exposures
            .times_ms
            .iter()
            .zip(frames_of)
            .map(|(&exposure_ms, frames)| ExposureFrames {
                exposure_ms,
                frames,
            })
            .collect();
        let fused = fuse_exposures(&stacks, &self.plan.exposures.fusion.config())?;
        for (frame, name) in fused.frames.iter().zip(names) {
            write_atomically(&dir.join(name), |tmp| Ok(write_png_grey(tmp, frame)?))?;
        }
        let folders = self
            .plan
            .exposures
            .times_ms
            .iter()
            .enumerate()
            .map(|(i, &exposure_ms)| ExposureFolder {
                dir: exposure_dir_name(i),
                exposure_ms,
            })
            .collect();
        let mut record = ExposureRecord::new(folders, self.plan.exposures.fusion);
        record.summary = Some(fused.summary);
        write_atomically(&dir.join(EXPOSURES_FILE), |tmp| Ok(record.save(tmp)?))
    }

    /// Shows full white (the plan's bit depth, the projector's size), waits for the display,
    /// flushes, captures one colour frame and writes it into `dir`'s [`COLOUR_FILE`]. A camera
    /// that cannot capture colour is [`RigError::Unsupported`] naming the plan's option.
    fn capture_colour<C, P>(
        &self,
        camera: &mut C,
        projector: &mut P,
        dir: &Path,
    ) -> Result<(), RigError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        let (w, h) = projector.image_size();
        let (w, h) = (w as usize, h as usize);
        let white = match self.plan.manifest.bit_depth {
            sl_codec::BitDepth::Eight => GreyImage::filled_u8(w, h, u8::MAX)?,
            sl_codec::BitDepth::Sixteen => sl_image::Frame::filled(w, h, u16::MAX)?.into(),
        };
        projector.show(&white)?;
        let settle = self.settle();
        if !settle.is_zero() {
            std::thread::sleep(settle);
        }
        for _ in 0..self.config.flush_frames {
            camera.capture()?;
        }
        let colour = camera.capture_colour().map_err(|e| match e {
            RigError::Unsupported { device, what } => RigError::Unsupported {
                device,
                what: format!(
                    "{what} (the session plan's `colour` option, `colour: true` in {SESSION_FILE})"
                ),
            },
            other => other,
        })?;
        let expected = camera.frame_size();
        let size = colour.size();
        if (size.width, size.height) != expected {
            return Err(RigError::ImageSize {
                what: "camera colour frame".to_owned(),
                expected_width: expected.0,
                expected_height: expected.1,
                width: size.width,
                height: size.height,
            });
        }
        write_atomically(&dir.join(COLOUR_FILE), |tmp| {
            Ok(write_png_colour(tmp, &colour)?)
        })
    }

    /// Writes the manifest of a capture set into `dir` (last: it marks the set complete),
    /// naming `colour` as its colour frame when there is one.
    fn write_view_manifest(
        &self,
        dir: &Path,
        index: usize,
        angle: f64,
        reached: f64,
        colour: Option<&str>,
    ) -> Result<(), RigError> {
        let mut m = self.plan.manifest.clone();
        m.frames_dir = None;
        m.colour = colour.map(str::to_owned);
        m.description = Some(format!(
            "capture session view {index}: turntable motor at {angle} degrees (reported {reached} degrees)"
        ));
        write_atomically(&dir.join(MANIFEST_FILE), |tmp| Ok(m.save(tmp)?))
    }

    fn file(&self) -> SessionFile {
        session_file(&self.plan)
    }
}

/// The `session.json` of `plan`.
fn session_file(plan: &SessionPlan) -> SessionFile {
    SessionFile {
        format: SESSION_FORMAT.to_owned(),
        version: SESSION_VERSION,
        angles_deg: plan.angles_deg.clone(),
        patterns: plan.manifest.to_json(),
        devices: plan.devices.clone(),
        calibration: plan.calibration.as_ref().map(|p| p.display().to_string()),
        views: (0..plan.angles_deg.len()).map(view_dir_name).collect(),
        exposures: plan.exposures.clone(),
        colour: plan.colour,
    }
}

/// Reads the plan of an existing session folder (its `session.json`).
///
/// # Errors
/// [`RigError::Io`], [`RigError::Json`] or [`RigError::InvalidParameter`] naming the file and
/// the key at fault.
pub fn read_session_plan(dir: &Path) -> Result<SessionPlan, RigError> {
    let path = dir.join(SESSION_FILE);
    let file = read_session_file(&path)?;
    let text = file.patterns.to_string();
    let manifest = Manifest::from_json_str(&text, &path)?;
    let exposures = SessionExposures::new(file.exposures.times_ms, file.exposures.fusion).map_err(
        |e| match e {
            RigError::InvalidParameter { name, reason } => {
                RigError::param(format!("{}: {name}", path.display()), reason)
            }
            other => other,
        },
    )?;
    Ok(SessionPlan {
        angles_deg: file.angles_deg,
        manifest,
        devices: file.devices,
        calibration: file.calibration.map(PathBuf::from),
        exposures,
        colour: file.colour,
    })
}

fn read_session_file(path: &Path) -> Result<SessionFile, RigError> {
    let text = std::fs::read_to_string(path).map_err(|e| RigError::io(path, e))?;
    let file: SessionFile = serde_json::from_str(&text).map_err(|source| RigError::Json {
        path: path.to_path_buf(),
        source,
    })?;
    if file.format != SESSION_FORMAT || file.version != SESSION_VERSION {
        return Err(RigError::param(
            format!("{}: format/version", path.display()),
            format!(
                "expected \"{SESSION_FORMAT}\" version {SESSION_VERSION}, got \"{}\" version {}",
                file.format, file.version
            ),
        ));
    }
    Ok(file)
}

/// What differs between two plans (angles and patterns; devices and calibration are only a
/// record), or `None`.
fn plan_difference(existing: &SessionFile, new: &SessionFile) -> Option<String> {
    if existing.angles_deg != new.angles_deg {
        return Some(format!(
            "holds a session of {} views at {:?} degrees, not the {} views asked for; choose another folder or allow overwriting",
            existing.angles_deg.len(),
            existing.angles_deg,
            new.angles_deg.len()
        ));
    }
    if existing.devices.right_camera.is_some() != new.devices.right_camera.is_some() {
        let cameras = |f: &SessionFile| {
            if f.devices.right_camera.is_some() {
                2
            } else {
                1
            }
        };
        return Some(format!(
            "holds a session captured with {} camera(s), not {}; choose another folder or allow overwriting",
            cameras(existing),
            cameras(new)
        ));
    }
    if existing.exposures != new.exposures {
        return Some(format!(
            "holds a session captured at exposures {:?} ms, not {:?} ms; choose another folder or allow overwriting",
            existing.exposures.times_ms, new.exposures.times_ms
        ));
    }
    if existing.colour != new.colour {
        let with = |c: bool| if c { "with" } else { "without" };
        return Some(format!(
            "holds a session captured {} colour, not {}; choose another folder or allow overwriting",
            with(existing.colour),
            with(new.colour)
        ));
    }
    if existing.patterns != new.patterns {
        return Some(
            "holds a session with other patterns; choose another folder or allow overwriting"
                .to_owned(),
        );
    }
    None
}

/// Whether the view folder `dir` holds its colour frame and its manifest names it.
fn colour_complete(dir: &Path) -> bool {
    dir.join(COLOUR_FILE).is_file()
        && Manifest::load(&dir.join(MANIFEST_FILE))
            .is_ok_and(|m| m.colour.as_deref() == Some(COLOUR_FILE))
}

/// The file names of every frame of `manifest`, in projection order.
fn frame_names(manifest: &Manifest) -> Vec<String> {
    manifest
        .blocks
        .iter()
        .flat_map(|b| b.frames.iter().cloned())
        .collect()
}

/// The projector images of `manifest`'s sequence, checked against the projector's size.
fn pattern_images(manifest: &Manifest, projector: (u32, u32)) -> Result<Vec<GreyImage>, RigError> {
    let sequence = manifest.sequence();
    let size = (sequence.projector.width, sequence.projector.height);
    if size != projector {
        return Err(RigError::ImageSize {
            what: "patterns of the session plan (projector size)".to_owned(),
            expected_width: projector.0,
            expected_height: projector.1,
            width: size.0,
            height: size.1,
        });
    }
    (0..sequence.frame_count())
        .map(|k| Ok(sequence.render_image(k, manifest.bit_depth)?))
        .collect()
}

/// The pass of `exposures` (milliseconds, the plan's order) whose frames are checked: the one
/// nearest (in ratio) `own`, the camera's own exposure, or else the middle one; 0 with none.
fn judged_pass(exposures: &[f64], own: Option<f64>) -> usize {
    let Some(reference) = own.or_else(|| {
        let mut sorted = exposures.to_vec();
        sorted.sort_by(f64::total_cmp);
        sorted.get(sorted.len() / 2).copied()
    }) else {
        return 0;
    };
    let distance = |t: f64| (t / reference).ln().abs();
    (0..exposures.len())
        .min_by(|&a, &b| distance(exposures[a]).total_cmp(&distance(exposures[b])))
        .unwrap_or(0)
}

/// Makes `dir` ready for a fresh capture: removes its manifest first (so that the view reads as
/// incomplete until the new one is written), then leftovers of an interrupted write.
fn prepare_view_dir(dir: &Path) -> Result<(), RigError> {
    std::fs::create_dir_all(dir).map_err(|e| RigError::io(dir, e))?;
    let manifest = dir.join(MANIFEST_FILE);
    if manifest.exists() {
        std::fs::remove_file(&manifest).map_err(|e| RigError::io(&manifest, e))?;
    }
    let entries = std::fs::read_dir(dir).map_err(|e| RigError::io(dir, e))?;
    for entry in entries {
        let entry = entry.map_err(|e| RigError::io(dir, e))?;
        if entry
            .file_name()
            .to_string_lossy()
            .starts_with(PARTIAL_PREFIX)
        {
            let p = entry.path();
            std::fs::remove_file(&p).map_err(|e| RigError::io(&p, e))?;
        }
    }
    Ok(())
}

/// Writes `path` through `write` into a temporary name in the same folder, then renames it
/// into place (a rename within one folder is atomic on POSIX file systems).
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), RigError>,
) -> Result<(), RigError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!("{PARTIAL_PREFIX}{name}"));
    write(&tmp)?;
    std::fs::rename(&tmp, path).map_err(|e| RigError::io(path, e))
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// `d` in nanoseconds, saturated.
fn duration_ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    //! A binocular session on devices behind the traits: a right camera that fails is named.

    use std::{cell::RefCell, rc::Rc};

    use sl_codec::{Axis, BitDepth, GrayCodeSpec, ImageSize, Pattern, PatternSequence};

    use super::*;

    /// A camera that sees exactly what the projector shows (and the projector).
    struct Mirror(Rc<RefCell<GreyImage>>);

    impl Camera for Mirror {
        fn frame_size(&self) -> (u32, u32) {
            (64, 36)
        }
        fn capture(&mut self) -> Result<GreyImage, RigError> {
            Ok(self.0.borrow().clone())
        }
    }

    impl Projector for Mirror {
        fn image_size(&self) -> (u32, u32) {
            (64, 36)
        }
        fn show(&mut self, image: &GreyImage) -> Result<(), RigError> {
            *self.0.borrow_mut() = image.clone();
            Ok(())
        }
    }

    /// A camera whose driver fails after `good` frames, as an unplugged USB camera does.
    struct Failing {
        good: usize,
    }

    impl Camera for Failing {
        fn frame_size(&self) -> (u32, u32) {
            (64, 36)
        }
        fn capture(&mut self) -> Result<GreyImage, RigError> {
            if self.good == 0 {
                return Err(RigError::Device {
                    device: "camera".to_owned(),
                    reason: "VIDIOC_DQBUF: No such device".to_owned(),
                });
            }
            self.good -= 1;
            Ok(GreyImage::filled_u8(64, 36, 0)?)
        }
    }

    struct Table(f64);

    impl Turntable for Table {
        fn rotate_to(&mut self, a: f64) -> Result<f64, RigError> {
            self.0 = a;
            Ok(a)
        }
        fn angle_deg(&mut self) -> Result<f64, RigError> {
            Ok(self.0)
        }
    }

    fn plan(right: Option<&str>) -> SessionPlan {
        let p = ImageSize::new(64, 36);
        let sequence = PatternSequence::new(p).with(Pattern::Gray(GrayCodeSpec::per_pixel(
            Axis::Column,
            p,
            true,
        )));
        SessionPlan {
            angles_deg: vec![0.0, 90.0],
            manifest: sequence.manifest(BitDepth::Eight),
            devices: SessionDevices {
                right_camera: right.map(str::to_owned),
                ..Default::default()
            },
            calibration: None,
            exposures: Default::default(),
            colour: false,
        }
    }

    /// A colour camera seeing what the projector shows, tinted: red at full, green at half,
    /// blue at a quarter of the grey value.
    struct ColourMirror(Mirror);

    impl Camera for ColourMirror {
        fn frame_size(&self) -> (u32, u32) {
            self.0.frame_size()
        }
        fn capture(&mut self) -> Result<GreyImage, RigError> {
            self.0.capture()
        }
        fn capture_colour(&mut self) -> Result<crate::ColourImage, RigError> {
            let grey = self.0.capture()?.into_u8();
            let data = grey.data().iter().map(|&g| [g, g / 2, g / 4]).collect();
            Ok(crate::ColourImage::new(grey.width(), grey.height(), data)?)
        }
    }

    fn colour_plan() -> SessionPlan {
        SessionPlan {
            colour: true,
            ..plan(None)
        }
    }

    #[test]
    fn a_colour_session_writes_each_views_colour_under_white() -> Result<(), RigError> {
        let dir = tempfile::tempdir().map_err(|e| RigError::io("tempdir", e))?;
        let config = SessionConfig {
            display_latency: Duration::ZERO,
            ..Default::default()
        };
        let session = CaptureSession::open(dir.path(), colour_plan(), config)?;
        let screen = Rc::new(RefCell::new(GreyImage::filled_u8(64, 36, 0)?));
        let mut camera = ColourMirror(Mirror(screen.clone()));
        let summary = session.run(&mut camera, &mut Mirror(screen), &mut Table(0.0), |_| {})?;
        assert_eq!(summary.captured, 2);
        for k in 0..2 {
            let view = session.view_dir(k);
            // The camera saw full white (255) when it captured the colour: tinted 255, 127, 63.
            let colour = sl_codec::read_colour_image(&view.join(COLOUR_FILE))?;
            assert_eq!((colour.width(), colour.height()), (64, 36));
            assert!(colour.data().iter().all(|&p| p == [255, 127, 63]));
            let manifest = Manifest::load(&view.join(MANIFEST_FILE))?;
            assert_eq!(manifest.colour.as_deref(), Some(COLOUR_FILE));
            assert_eq!(session.view_state(k), ViewState::Complete);
        }
        // session.json keeps the option; a view without its colour frame is not complete.
        assert!(read_session_plan(dir.path())?.colour);
        std::fs::remove_file(session.view_dir(1).join(COLOUR_FILE))
            .map_err(|e| RigError::io("colour.png", e))?;
        assert_eq!(session.view_state(1), ViewState::Partial);
        // The same folder without colour is another plan.
        let err = CaptureSession::open(dir.path(), plan(None), config).unwrap_err();
        assert!(matches!(err, RigError::SessionMismatch { .. }), "{err}");
        assert!(err.to_string().contains("colour"), "{err}");
        Ok(())
    }

    #[test]
    fn a_grey_camera_fails_a_colour_session_naming_the_option() -> Result<(), RigError> {
        let dir = tempfile::tempdir().map_err(|e| RigError::io("tempdir", e))?;
        let config = SessionConfig {
            display_latency: Duration::ZERO,
            ..Default::default()
        };
        let session = CaptureSession::open(dir.path(), colour_plan(), config)?;
        let screen = Rc::new(RefCell::new(GreyImage::filled_u8(64, 36, 0)?));
        let err = session
            .run(
                &mut Mirror(screen.clone()),
                &mut Mirror(screen),
                &mut Table(0.0),
                |_| {},
            )
            .unwrap_err();
        let RigError::Session {
            view: 0, source, ..
        } = &err
        else {
            panic!("not a session error of view 0: {err}");
        };
        assert!(matches!(**source, RigError::Unsupported { .. }), "{err}");
        let message = err.to_string();
        assert!(message.contains("`colour`"), "{message}");
        assert_ne!(session.view_state(0), ViewState::Complete);
        Ok(())
    }

    #[test]
    fn sessions_without_colour_read_as_before() -> Result<(), RigError> {
        let dir = tempfile::tempdir().map_err(|e| RigError::io("tempdir", e))?;
        CaptureSession::open(dir.path(), plan(None), SessionConfig::default())?;
        // The key is absent when false (older sessions have none) and reads as false.
        let text = std::fs::read_to_string(dir.path().join(SESSION_FILE))
            .map_err(|e| RigError::io(SESSION_FILE, e))?;
        assert!(!text.contains("colour"), "{text}");
        assert!(!read_session_plan(dir.path())?.colour);
        Ok(())
    }

    #[test]
    fn a_failing_right_camera_is_named_and_its_view_left_incomplete() -> Result<(), RigError> {
        let dir = tempfile::tempdir().map_err(|e| RigError::io("tempdir", e))?;
        let config = SessionConfig {
            display_latency: Duration::ZERO,
            ..Default::default()
        };
        let session = CaptureSession::open(dir.path(), plan(Some("/dev/video2")), config)?;
        let screen = Rc::new(RefCell::new(GreyImage::filled_u8(64, 36, 0)?));
        let (mut left, mut projector) = (Mirror(screen.clone()), Mirror(screen));
        let frames = frame_names(&session.plan().manifest).len();
        // The right camera fails on view 1's third frame.
        let mut right = Failing { good: frames + 2 };
        let err = match session.run_binocular(
            &mut left,
            &mut right,
            &mut projector,
            &mut Table(0.0),
            |_| {},
        ) {
            Err(e) => e,
            Ok(s) => panic!("the failing right camera went unnoticed: {s:?}"),
        };
        let message = err.to_string();
        assert!(message.contains("view 1, frame 2"), "{message}");
        assert!(message.contains("right camera /dev/video2"), "{message}");
        assert!(message.contains("No such device"), "{message}");
        assert_eq!(session.view_state(0), ViewState::Complete);
        assert_ne!(session.view_state(1), ViewState::Complete);
        // The left camera's own failure is not blamed on the right one.
        let mut left = Failing { good: 0 };
        let mut right = Failing { good: 1000 };
        let config = SessionConfig {
            overwrite: true,
            ..config
        };
        let session = CaptureSession::open(dir.path(), plan(Some("/dev/video2")), config)?;
        let screen = Rc::new(RefCell::new(GreyImage::filled_u8(64, 36, 0)?));
        let err = session
            .run_binocular(
                &mut left,
                &mut right,
                &mut Mirror(screen),
                &mut Table(0.0),
                |_| {},
            )
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(!err.contains("right camera"), "{err}");
        assert!(err.contains("No such device"), "{err}");
        Ok(())
    }
}
