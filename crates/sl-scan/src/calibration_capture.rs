//! The capture of a calibration session through the device traits: the board held at varied
//! poses under the patterns, then standing on the turntable at several angles — what
//! `slscan calibrate capture` runs on the virtual rig and on real devices alike.
//!
//! The session folder has the layout `slscan simulate --scene board` writes, so that
//! `slscan calibrate all SESSION` reads either:
//!
//! ```text
//! SESSION/board/pose_NNN/      white.png, the pattern frames, manifest.json, board.json
//! SESSION/turntable/angle_NNN/ the same, board.json holding motor_angle_deg
//! ```
//!
//! Every pose is checked before it is written ([`CalibrationCapture::check`]): the board must
//! be found with all its corners, not over-exposed, sharp, and far enough from every earlier
//! pose in position, size or tilt; a refused pose writes nothing and says why ([`Refusal`]).
//! A pose is written into a hidden folder and renamed when complete, so an interrupted
//! capture leaves no half pose; a session opened again continues its numbering.
//!
//! Who moves the board is a [`crate::BoardMover`]: a person ([`crate::HandHeld`]) or the
//! virtual rig ([`crate::VirtualBoardRig`]). [`crate::capture_poses_auto`] takes the poses
//! without a key press: right after each move when the board moves itself, else once the
//! board has been still for [`crate::AutoConfig::still_for`].

use std::path::{Path, PathBuf};
use std::time::Duration;

use nalgebra::Point2;
use serde::Serialize;
use sl_calib::sl_camera::{CameraModel, ImageSize};
use sl_calib::sl_codec::{BitDepth, Manifest, write_png_grey};
use sl_calib::{
    BoardCorners, BoardSize, CalibrationView, DetectorConfig, ZhangConfig, calibrate_camera,
    detect_checkerboard,
};
use sl_rig::{Camera, GreyImage, Projector, RIGHT_DIR, RigError, Turntable, write_capture_set};

use crate::calibration_coverage::Coverage;
use crate::calibration_files::{
    BoardFile, BoardJson, PARTIAL_PREFIX, complete_folder, pose_dir_name, remove_partials,
};
use crate::pose_gates::{PoseCheck, PoseGates, Refusal};
use crate::pose_quality::{BoardGeometry, edge_width_px, nominal_camera, saturated_fraction};
use crate::{
    BOARD_DIR, BOARD_FILE, TURNTABLE_DIR, WHITE_IMAGE, angle_dir_name, calibration_patterns,
};

/// Poses needed before the camera guess is replaced by a calibration of the poses so far:
/// Zhang's method needs three views for the focal length and the principal point.
const MIN_POSES_FOR_CAMERA: usize = 3;

/// Everything that can go wrong in a calibration capture (a refused pose is not an error: see
/// [`Refusal`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CaptureError {
    /// A device failed, or a file could not be written by `sl-rig`.
    #[error(transparent)]
    Rig(#[from] RigError),
    /// A file or folder of the session could not be read, written or removed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A session file is not what it should be.
    #[error("{}: {reason}", path.display())]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// An option is out of its range.
    #[error("parameter `{name}`: {reason}")]
    InvalidParameter {
        /// The option, as the command line names it.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// The virtual rig could not do what it was asked.
    #[error("virtual rig: {0}")]
    Simulator(String),
}

impl CaptureError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn param(name: &str, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.to_owned(),
            reason: reason.into(),
        }
    }

    /// Wraps an error of the simulator (whatever its type: it moves between crates).
    #[cfg(feature = "sim")]
    pub(crate) fn sim(e: impl std::fmt::Display) -> Self {
        Self::Simulator(e.to_string())
    }
}

/// A pose of the session.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRecord {
    /// Its number (folder `pose_NNN`).
    pub index: usize,
    /// Its folder.
    pub dir: PathBuf,
    /// The detected corners (px).
    pub corners: Vec<Point2<f64>>,
    /// Its geometry, measured with the camera known so far.
    pub geometry: BoardGeometry,
}

/// What [`CalibrationCapture::take`] did.
#[derive(Debug, Clone, PartialEq)]
pub enum TakeOutcome {
    /// The pose was captured and written.
    Taken {
        /// Its number.
        index: usize,
        /// Its folder.
        dir: PathBuf,
    },
    /// The pose was refused; nothing was written.
    Refused(Refusal),
}

/// One turntable view of the session.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TableView {
    /// Its folder.
    pub dir: PathBuf,
    /// The motor angle the turntable reported (degrees).
    pub motor_angle_deg: f64,
    /// Whether the whole board was found on its white frame.
    pub board_found: bool,
    /// `true` when the view was complete from an earlier run and kept.
    pub kept: bool,
}

/// Options of a calibration capture.
#[derive(Debug, Clone)]
pub struct CalibrationCaptureConfig {
    /// The printed board's inner corners.
    pub board: BoardSize,
    /// Side of its squares (mm).
    pub square_mm: f64,
    /// The pattern sequence captured at every pose (its projector size must be the
    /// projector's).
    pub manifest: Manifest,
    /// Wait after showing an image before capturing (the projector's display latency).
    pub display_latency: Duration,
    /// Camera frames to drop after the wait (frames the camera buffered earlier).
    pub flush_frames: usize,
    /// Corner detection.
    pub detector: DetectorConfig,
    /// The checks of a pose.
    pub gates: PoseGates,
}

impl CalibrationCaptureConfig {
    /// A board of `board` inner corners and `square_mm` squares, the default calibration
    /// patterns for a projector of `projector` pixels, no latency, the default detector and
    /// gates.
    pub fn new(board: BoardSize, square_mm: f64, projector: (u32, u32)) -> Self {
        Self {
            board,
            square_mm,
            manifest: calibration_patterns(ImageSize::new(projector.0, projector.1))
                .manifest(BitDepth::Eight),
            display_latency: Duration::ZERO,
            flush_frames: 0,
            detector: DetectorConfig::default(),
            gates: PoseGates::default(),
        }
    }
}

/// A calibration capture session: its folder, the poses taken so far and the checks.
///
/// On the virtual rig, whose board moves itself (what `slscan calibrate capture --virtual
/// --auto` runs; `examples/slscan/calibrate_capture.rs` is the interactive front end):
///
/// ```no_run
/// use sl_rig::{Camera, Projector};
/// use sl_scan::{
///     AutoConfig, BoardMover, CalibrationCapture, CalibrationCaptureConfig, VirtualBoardRig,
///     calibration_turntable_angles, capture_poses_auto,
/// };
/// use sl_calib::BoardSize;
/// use sl_sim::{BoardPoseConfig, Checkerboard, RigConfig};
///
/// let board = Checkerboard::default();
/// let rig = VirtualBoardRig::new(RigConfig::default(), board, &BoardPoseConfig::default())?;
/// let (mut camera, mut projector, mut table, mut mover) = rig.devices();
/// let size = BoardSize::new(board.inner_cols, board.inner_rows);
/// let config = CalibrationCaptureConfig::new(size, board.square_mm, projector.image_size());
/// let mut session = CalibrationCapture::open(
///     "calib/session".as_ref(),
///     config,
///     camera.frame_size(),
///     projector.image_size(),
/// )?;
/// let auto = AutoConfig { poses: 12, ..AutoConfig::default() };
/// capture_poses_auto(&mut session, &mut camera, &mut projector, &mut mover, &auto, |_| {})?;
/// mover.onto_turntable()?;
/// let angles = calibration_turntable_angles(7);
/// session.capture_turntable(&mut camera, &mut projector, &mut table, &angles, |_| {})?;
/// // `slscan calibrate all calib/session --out calib/all` calibrates from it.
/// # Ok::<(), sl_scan::CaptureError>(())
/// ```
#[derive(Debug)]
pub struct CalibrationCapture {
    dir: PathBuf,
    config: CalibrationCaptureConfig,
    frame_size: (u32, u32),
    patterns: Vec<GreyImage>,
    poses: Vec<PoseRecord>,
    camera: CameraModel,
}

impl CalibrationCapture {
    /// Opens (creating it) the session folder `dir` for a camera of `frame_size` pixels and a
    /// projector of `projector_size`: the poses already in `dir/board/` are kept and the
    /// numbering continues after them; half-written poses of an interrupted run are removed.
    pub fn open(
        dir: &Path,
        config: CalibrationCaptureConfig,
        frame_size: (u32, u32),
        projector_size: (u32, u32),
    ) -> Result<Self, CaptureError> {
        if config.board.cols < 2 || config.board.rows < 2 {
            return Err(CaptureError::param(
                "board",
                format!(
                    "{}x{} inner corners: at least 2x2 are needed",
                    config.board.cols, config.board.rows
                ),
            ));
        }
        if !(config.square_mm.is_finite() && config.square_mm > 0.0) {
            return Err(CaptureError::param(
                "square",
                format!("{} mm: a square's side must be positive", config.square_mm),
            ));
        }
        let m = &config.manifest;
        if (m.projector.width, m.projector.height) != projector_size {
            return Err(CaptureError::param(
                "patterns",
                format!(
                    "the patterns are for a {}x{} projector, the projector is {}x{}",
                    m.projector.width, m.projector.height, projector_size.0, projector_size.1
                ),
            ));
        }
        let camera = nominal_camera(frame_size.0, frame_size.1).ok_or_else(|| {
            CaptureError::param(
                "camera",
                format!("frame size {}x{}", frame_size.0, frame_size.1),
            )
        })?;
        let sequence = m.sequence();
        let patterns = (0..sequence.frame_count())
            .map(|k| sequence.render_image(k, m.bit_depth))
            .collect::<Result<Vec<_>, _>>()
            .map_err(RigError::from)?;
        let board_dir = dir.join(BOARD_DIR);
        for d in [&board_dir, &dir.join(TURNTABLE_DIR)] {
            std::fs::create_dir_all(d).map_err(|e| CaptureError::io(d, e))?;
            remove_partials(d)?;
        }
        let mut session = Self {
            dir: dir.to_path_buf(),
            config,
            frame_size,
            patterns,
            poses: Vec::new(),
            camera,
        };
        session.poses = session.read_poses(&board_dir)?;
        session.update_camera();
        Ok(session)
    }

    /// The session folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The options.
    pub fn config(&self) -> &CalibrationCaptureConfig {
        &self.config
    }

    /// The poses taken so far (from earlier runs too), in order.
    pub fn poses(&self) -> &[PoseRecord] {
        &self.poses
    }

    /// The camera the tilts are measured with: a nominal one until three poses are taken,
    /// then Zhang's calibration of the poses so far.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// Coverage of the image and the tilts by the poses so far.
    pub fn coverage(&self) -> Coverage {
        Coverage::of(
            self.frame_size.0,
            self.frame_size.1,
            self.poses
                .iter()
                .map(|p| (p.corners.as_slice(), &p.geometry)),
        )
    }

    /// The text of an interactive capture's view, for a terminal (cleared first): the check
    /// of the current frame, the coverage of the image and the tilts with a hint for the next
    /// of the `target` poses, the `last` thing that happened, and the keys (with `n` when the
    /// board is virtual and moves itself).
    #[must_use]
    pub fn screen(
        &self,
        check: &PoseCheck,
        target: usize,
        last: &str,
        virtual_board: bool,
    ) -> String {
        let coverage = self.coverage();
        format!(
            "\x1b[2J\x1b[Hcalibration capture: {} - pose {} of {target}\n\n{}\n\n{}hint: {}\n\nlast: {last}\nkeys: space/enter take pose, d drop last pose, q finish{}\n",
            self.dir().display(),
            self.poses().len(),
            check.summary(),
            coverage.draw(),
            coverage.hint(target),
            if virtual_board {
                ", n move the virtual board"
            } else {
                ""
            }
        )
    }

    fn board_size(&self) -> BoardSize {
        self.config.board
    }

    /// Checks a frame of the board under white: found, exposure, sharpness, novelty.
    pub fn check(&self, white: GreyImage) -> PoseCheck {
        let size = self.board_size();
        let mut check = PoseCheck {
            expected_corners: size.corner_count(),
            corners: None,
            geometry: None,
            saturated_fraction: 0.0,
            edge_width_px: None,
            verdict: Ok(()),
            white,
        };
        let max_value = f64::from(check.white.max_value());
        // 16-bit frames by `round(v / 257)` (`GreyImage::into_u8`), as 16-bit image files are read.
        let grey = check.white.clone().into_u8();
        let corners = match detect_checkerboard(&grey, size, &self.config.detector, "frame") {
            Ok(c) => c,
            Err(e) => {
                let reason = match e {
                    sl_calib::CalibError::BoardNotFound { reason, .. } => reason,
                    other => other.to_string(),
                };
                check.verdict = Err(Refusal::BoardNotFound { reason });
                return check;
            }
        };
        let full = if max_value > 255.0 { 255.0 } else { max_value };
        check.saturated_fraction = saturated_fraction(&grey, full, &corners);
        check.edge_width_px = edge_width_px(&grey, &corners);
        check.geometry = BoardGeometry::measure(&corners, self.config.square_mm, &self.camera);
        let gates = &self.config.gates;
        check.verdict = if check.saturated_fraction > gates.max_saturated_fraction {
            Err(Refusal::OverExposed {
                saturated_fraction: check.saturated_fraction,
            })
        } else if let Some(w) = check.edge_width_px.filter(|&w| w > gates.max_edge_width_px) {
            Err(Refusal::Blurred { edge_width_px: w })
        } else if let Some(r) = check.geometry.as_ref().and_then(|g| self.too_close(g)) {
            Err(r)
        } else {
            Ok(())
        };
        check.corners = Some(corners);
        check
    }

    /// The earlier pose this one is too close to, if any.
    fn too_close(&self, g: &BoardGeometry) -> Option<Refusal> {
        let (w, h) = self.frame_size;
        let diagonal = f64::from(w).hypot(f64::from(h));
        let gates = &self.config.gates;
        self.poses
            .iter()
            .map(|p| {
                let q = &p.geometry;
                let tilt = g.facing.angle(&q.facing).to_degrees();
                let shift = (g.centre_px - q.centre_px).norm() / diagonal;
                let size = (g.size_px / q.size_px.max(f64::MIN_POSITIVE)).ln().abs();
                (p.index, tilt, shift, size)
            })
            .filter(|&(_, tilt, shift, size)| {
                tilt < gates.min_tilt_change_deg
                    && shift < gates.min_shift
                    && size < (1.0 + gates.min_size_change).ln()
            })
            .min_by(|a, b| a.2.total_cmp(&b.2))
            .map(|(pose, tilt_change_deg, shift, _)| Refusal::TooClose {
                pose,
                tilt_change_deg,
                shift,
            })
    }

    /// Shows full white, waits for the display, and checks the frame the camera captures.
    pub fn look<C, P>(&self, camera: &mut C, projector: &mut P) -> Result<PoseCheck, CaptureError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        let white = self.white_image(projector.image_size())?;
        let frame = self.show_and_capture(camera, projector, &white)?;
        Ok(self.check(frame))
    }

    fn white_image(&self, (w, h): (u32, u32)) -> Result<GreyImage, CaptureError> {
        Ok(GreyImage::filled_u8(w as usize, h as usize, u8::MAX).map_err(RigError::from)?)
    }

    /// Show → wait for the display latency → flush → capture.
    fn show_and_capture<C, P>(
        &self,
        camera: &mut C,
        projector: &mut P,
        image: &GreyImage,
    ) -> Result<GreyImage, CaptureError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        let timing = sl_rig::CaptureTiming {
            settle: self.config.display_latency,
            flush_frames: self.config.flush_frames,
        };
        Ok(sl_rig::show_and_capture(camera, projector, image, timing)?)
    }

    /// Takes the pose `check` was made of: refused (nothing written) unless its verdict is
    /// `Ok`; else every pattern is shown and captured and the pose folder written (into a
    /// hidden folder renamed when complete).
    pub fn take<C, P>(
        &mut self,
        check: &PoseCheck,
        camera: &mut C,
        projector: &mut P,
    ) -> Result<TakeOutcome, CaptureError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        self.take_with(check, camera, None, projector)
    }

    /// [`CalibrationCapture::take`] with the second camera of a binocular rig: under the same
    /// white light it takes its picture of the board too (`right/white.png` in the pose
    /// folder, for `slscan calibrate stereo`), and the pose is refused, nothing written, when
    /// that camera does not find the whole board. When the session captures patterns, each
    /// pattern stays on until both cameras have their frame; the second camera's are written
    /// with their `manifest.json` in `right/` beside its `white.png`.
    pub fn take_with<C, P>(
        &mut self,
        check: &PoseCheck,
        camera: &mut C,
        right: Option<&mut dyn Camera>,
        projector: &mut P,
    ) -> Result<TakeOutcome, CaptureError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        if let Err(r) = &check.verdict {
            return Ok(TakeOutcome::Refused(r.clone()));
        }
        let (Some(corners), Some(geometry)) = (&check.corners, &check.geometry) else {
            return Ok(TakeOutcome::Refused(Refusal::BoardNotFound {
                reason: "no pose fits the corners".to_owned(),
            }));
        };
        let mut right = right;
        let right_white = match right.as_deref_mut() {
            Some(right) => {
                let white = self.white_image(projector.image_size())?;
                let frame = self.show_and_capture(right, projector, &white)?;
                let grey = frame.clone().into_u8();
                if let Err(e) =
                    detect_checkerboard(&grey, self.board_size(), &self.config.detector, "right")
                {
                    let reason = match e {
                        sl_calib::CalibError::BoardNotFound { reason, .. } => reason,
                        other => other.to_string(),
                    };
                    return Ok(TakeOutcome::Refused(Refusal::BoardNotFound {
                        reason: format!("the right camera does not see the whole board: {reason}"),
                    }));
                }
                Some(frame)
            }
            None => None,
        };
        let index = self.poses.last().map_or(0, |p| p.index + 1);
        let dir = self.dir.join(BOARD_DIR).join(pose_dir_name(index));
        let (frames, right_frames) = self.capture_patterns_with(camera, right, projector)?;
        let right_set = right_white.as_ref().map(|w| (w, right_frames.as_slice()));
        self.write_folder(
            &dir,
            &check.white,
            right_set,
            &frames,
            &BoardFile {
                board: BoardJson::of(&self.config),
                motor_angle_deg: 0.0,
                detected_corners_px: corners.corners.iter().map(|p| [p.x, p.y]).collect(),
                saturated_fraction: check.saturated_fraction,
                edge_width_px: check.edge_width_px,
            },
            &format!("slscan calibrate capture, board pose {index}"),
        )?;
        self.poses.push(PoseRecord {
            index,
            dir: dir.clone(),
            corners: corners.corners.clone(),
            geometry: geometry.clone(),
        });
        self.update_camera();
        Ok(TakeOutcome::Taken { index, dir })
    }

    fn capture_patterns<C, P>(
        &self,
        camera: &mut C,
        projector: &mut P,
    ) -> Result<Vec<GreyImage>, CaptureError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        Ok(self.capture_patterns_with(camera, None, projector)?.0)
    }

    /// [`CalibrationCapture::capture_patterns`] with an optional second camera: the pattern
    /// stays on until it too has captured (after flushing as the first does). Its frames are
    /// empty without one.
    fn capture_patterns_with<C, P>(
        &self,
        camera: &mut C,
        mut right: Option<&mut dyn Camera>,
        projector: &mut P,
    ) -> Result<(Vec<GreyImage>, Vec<GreyImage>), CaptureError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
    {
        let mut left_frames = Vec::with_capacity(self.patterns.len());
        let mut right_frames = Vec::new();
        for pattern in &self.patterns {
            left_frames.push(self.show_and_capture(camera, projector, pattern)?);
            if let Some(r) = right.as_deref_mut() {
                right_frames.push(sl_rig::flush_and_capture(r, self.config.flush_frames)?);
            }
        }
        Ok((left_frames, right_frames))
    }

    /// Writes a capture folder atomically: everything into a hidden sibling, `white.png`
    /// last, then one rename.
    fn write_folder(
        &self,
        dir: &Path,
        white: &GreyImage,
        right: Option<(&GreyImage, &[GreyImage])>,
        frames: &[GreyImage],
        board: &BoardFile,
        description: &str,
    ) -> Result<(), CaptureError> {
        let (Some(parent), Some(name)) = (dir.parent(), dir.file_name()) else {
            return Err(CaptureError::param(
                "session folder",
                dir.display().to_string(),
            ));
        };
        let partial = parent.join(format!("{PARTIAL_PREFIX}{}", name.to_string_lossy()));
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(|e| CaptureError::io(&partial, e))?;
        }
        write_capture_set(&partial, &self.config.manifest, frames, description)?;
        let json = serde_json::to_string_pretty(board).map_err(|e| CaptureError::BadFile {
            path: partial.join(BOARD_FILE),
            reason: e.to_string(),
        })?;
        let file = partial.join(BOARD_FILE);
        std::fs::write(&file, json).map_err(|e| CaptureError::io(&file, e))?;
        if let Some((white, right_frames)) = right {
            let folder = partial.join(RIGHT_DIR);
            std::fs::create_dir_all(&folder).map_err(|e| CaptureError::io(&folder, e))?;
            if !right_frames.is_empty() {
                write_capture_set(
                    &folder,
                    &self.config.manifest,
                    right_frames,
                    &format!("{description}, right camera"),
                )?;
            }
            write_png_grey(&folder.join(WHITE_IMAGE), white).map_err(RigError::from)?;
        }
        write_png_grey(&partial.join(WHITE_IMAGE), white).map_err(RigError::from)?;
        if dir.exists() {
            std::fs::remove_dir_all(dir).map_err(|e| CaptureError::io(dir, e))?;
        }
        std::fs::rename(&partial, dir).map_err(|e| CaptureError::io(dir, e))
    }

    /// Removes the last pose (its folder too); returns its folder, `None` without poses.
    pub fn drop_last(&mut self) -> Result<Option<PathBuf>, CaptureError> {
        let Some(last) = self.poses.pop() else {
            return Ok(None);
        };
        if last.dir.exists() {
            std::fs::remove_dir_all(&last.dir).map_err(|e| CaptureError::io(&last.dir, e))?;
        }
        self.update_camera();
        Ok(Some(last.dir))
    }

    /// Captures the board standing on the turntable at each of `angles_deg` (motor degrees):
    /// rotate, white frame, every pattern, one folder `turntable/angle_NNN` each. Views
    /// complete from an earlier run are kept. `on_view` is called after each view.
    pub fn capture_turntable<C, P, T>(
        &self,
        camera: &mut C,
        projector: &mut P,
        turntable: &mut T,
        angles_deg: &[f64],
        mut on_view: impl FnMut(&TableView),
    ) -> Result<Vec<TableView>, CaptureError>
    where
        C: Camera + ?Sized,
        P: Projector + ?Sized,
        T: Turntable + ?Sized,
    {
        let mut views = Vec::with_capacity(angles_deg.len());
        for (k, &angle) in angles_deg.iter().enumerate() {
            let dir = self.dir.join(TURNTABLE_DIR).join(angle_dir_name(k));
            if let Some(file) = complete_folder(&dir)? {
                let v = TableView {
                    dir,
                    motor_angle_deg: file.motor_angle_deg,
                    board_found: !file.detected_corners_px.is_empty(),
                    kept: true,
                };
                on_view(&v);
                views.push(v);
                continue;
            }
            let reached = turntable.rotate_to(angle)?;
            let white = self.white_image(projector.image_size())?;
            let white = self.show_and_capture(camera, projector, &white)?;
            let check = self.check(white);
            let frames = self.capture_patterns(camera, projector)?;
            let corners = check
                .corners
                .as_ref()
                .map(|c| c.corners.iter().map(|p| [p.x, p.y]).collect())
                .unwrap_or_default();
            self.write_folder(
                &dir,
                &check.white,
                None,
                &frames,
                &BoardFile {
                    board: BoardJson::of(&self.config),
                    motor_angle_deg: reached,
                    detected_corners_px: corners,
                    saturated_fraction: check.saturated_fraction,
                    edge_width_px: check.edge_width_px,
                },
                &format!("slscan calibrate capture, board on the turntable at {reached} degrees"),
            )?;
            let v = TableView {
                dir,
                motor_angle_deg: reached,
                board_found: check.corners.is_some(),
                kept: false,
            };
            on_view(&v);
            views.push(v);
        }
        Ok(views)
    }

    /// Reads the complete pose folders of `board_dir` in order.
    fn read_poses(&self, board_dir: &Path) -> Result<Vec<PoseRecord>, CaptureError> {
        let mut entries: Vec<(usize, PathBuf)> = std::fs::read_dir(board_dir)
            .map_err(|e| CaptureError::io(board_dir, e))?
            .filter_map(Result::ok)
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                let k = name.strip_prefix("pose_")?.parse::<usize>().ok()?;
                Some((k, e.path()))
            })
            .collect();
        entries.sort();
        let size = self.board_size();
        let mut poses = Vec::new();
        for (index, dir) in entries {
            let Some(file) = complete_folder(&dir)? else {
                continue;
            };
            let corners: Vec<Point2<f64>> = file
                .detected_corners_px
                .iter()
                .map(|&[x, y]| Point2::new(x, y))
                .collect();
            if corners.len() != size.corner_count() {
                // A folder of another board or written by another program: kept on disk,
                // counted neither for coverage nor for closeness.
                continue;
            }
            let bc = BoardCorners {
                size,
                corners: corners.clone(),
            };
            let Some(geometry) = BoardGeometry::measure(&bc, self.config.square_mm, &self.camera)
            else {
                continue;
            };
            poses.push(PoseRecord {
                index,
                dir,
                corners,
                geometry,
            });
        }
        Ok(poses)
    }

    /// Replaces the camera guess by a calibration of the poses so far (from three on), and
    /// measures every pose again with it.
    fn update_camera(&mut self) {
        let (w, h) = self.frame_size;
        let nominal = nominal_camera(w, h);
        let size = self.board_size();
        let square = self.config.square_mm;
        let calibrated = if self.poses.len() >= MIN_POSES_FOR_CAMERA {
            let views: Vec<CalibrationView> = self
                .poses
                .iter()
                .map(|p| {
                    CalibrationView::from_corners(
                        &BoardCorners {
                            size,
                            corners: p.corners.clone(),
                        },
                        square,
                    )
                })
                .collect();
            let cfg = ZhangConfig {
                fix_k3: true,
                ..ZhangConfig::default()
            };
            calibrate_camera(&views, ImageSize::new(w, h), &cfg)
                .ok()
                .map(|c| c.camera)
        } else {
            None
        };
        if let Some(camera) = calibrated.or(nominal) {
            self.camera = camera;
        }
        for p in &mut self.poses {
            let bc = BoardCorners {
                size,
                corners: p.corners.clone(),
            };
            if let Some(g) = BoardGeometry::measure(&bc, square, &self.camera) {
                p.geometry = g;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_board_too_small_or_without_size_is_refused_naming_the_parameter() {
        let dir = tempfile::tempdir().unwrap();
        let open = |board: BoardSize, square_mm: f64| {
            let config = CalibrationCaptureConfig::new(board, square_mm, (64, 32));
            CalibrationCapture::open(dir.path(), config, (64, 48), (64, 32))
        };
        let err = open(BoardSize::new(1, 6), 20.0).unwrap_err();
        assert!(err.to_string().contains("board"), "{err}");
        assert!(err.to_string().contains("1x6"), "{err}");
        for bad in [0.0, -1.0, f64::NAN] {
            let err = open(BoardSize::new(9, 6), bad).unwrap_err();
            assert!(err.to_string().contains("square"), "{bad}: {err}");
        }
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "nothing written"
        );
    }
}
