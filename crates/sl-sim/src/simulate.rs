//! Whole simulated captures written to disk: turntable scans of a scene and calibration
//! sessions with a checkerboard, each as `sl-codec` capture sets with their ground truth.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use sl_codec::{Manifest, write_png_grey};
use sl_rig::write_capture_set;

use crate::files::write_json;
use crate::{
    BoardCapture, BoardPoseConfig, CalibrationCaptures, Checkerboard, GreyImage, SimError,
    TRUTH_DIR, VirtualRig, write_view_truth,
};

/// What one simulated capture wrote, and how long it took.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimulatedCapture {
    /// Folder of the capture set (manifest, frames, `truth/`).
    pub dir: PathBuf,
    /// Turntable motor reading (degrees).
    pub motor_angle_deg: f64,
    /// Camera pixels that see an object.
    pub visible_pixels: usize,
    /// Camera pixels that see an object lit by the projector.
    pub lit_pixels: usize,
    /// Time to cast the view (ms).
    pub cast_ms: f64,
    /// Time to render every frame (ms).
    pub render_ms: f64,
    /// Time to write frames and truth (ms).
    pub write_ms: f64,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The projector images of every frame of `manifest`'s sequence, checked against the rig's
/// projector size.
pub fn projector_images(rig: &VirtualRig, manifest: &Manifest) -> Result<Vec<GreyImage>, SimError> {
    let sequence = manifest.sequence();
    let p = rig.config().projector.size;
    if (sequence.projector.width, sequence.projector.height) != (p.width, p.height) {
        return Err(SimError::param(
            "patterns",
            format!(
                "the manifest's projector is {}x{}, the rig's is {}",
                sequence.projector.width, sequence.projector.height, p
            ),
        ));
    }
    (0..sequence.frame_count())
        .map(|k| Ok(sequence.render_image(k, manifest.bit_depth)?))
        .collect()
}

/// Simulates a turntable scan: for each motor angle, casts the view, renders every pattern of
/// `manifest` and writes a capture set into `out/view_NNN/` (frames named as the manifest
/// names them, `manifest.json`) with the view's ground truth in `out/view_NNN/truth/`.
/// `on_capture` is called after each view (for progress).
pub fn simulate_scan(
    rig: &VirtualRig,
    manifest: &Manifest,
    angles: &[f64],
    out: &Path,
    mut on_capture: impl FnMut(&SimulatedCapture),
) -> Result<Vec<SimulatedCapture>, SimError> {
    let images = projector_images(rig, manifest)?;
    let mut done = Vec::with_capacity(angles.len());
    for (k, &angle) in angles.iter().enumerate() {
        let t = Instant::now();
        let view = rig.view(angle, k as u64)?;
        let cast_ms = ms(t);
        let t = Instant::now();
        let frames = view.capture_all(&images)?;
        let render_ms = ms(t);
        let t = Instant::now();
        let dir = out.join(format!("view_{k:03}"));
        write_capture_set(
            &dir,
            manifest,
            &frames,
            &format!("sl-sim virtual rig, view {k}, turntable motor at {angle} degrees"),
        )?;
        write_view_truth(&view.truth, &dir.join(TRUTH_DIR))?;
        let c = SimulatedCapture {
            dir,
            motor_angle_deg: angle,
            visible_pixels: view.truth.visible_count(),
            lit_pixels: view.truth.lit_count(),
            cast_ms,
            render_ms,
            write_ms: ms(t),
        };
        on_capture(&c);
        done.push(c);
    }
    Ok(done)
}

/// A calibration session to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationSession {
    /// The board.
    pub board: Checkerboard,
    /// Poses of the hand-held board (camera and projector calibration).
    pub poses: BoardPoseConfig,
    /// Motor angles of the board standing on the turntable (turntable-axis calibration).
    pub turntable_angles_deg: Vec<f64>,
}

impl Default for CalibrationSession {
    /// The default board at 12 poses, and on the turntable at −45° to 45° in 15° steps.
    fn default() -> Self {
        Self {
            board: Checkerboard::default(),
            poses: BoardPoseConfig::default(),
            turntable_angles_deg: (-3..=3).map(|k| f64::from(k) * 15.0).collect(),
        }
    }
}

impl CalibrationSession {
    /// The default board and turntable angles, with `count` hand-held board poses drawn with
    /// `seed` (the other settings of [`BoardPoseConfig::default`]).
    pub fn with_poses(count: usize, seed: u64) -> Self {
        Self {
            poses: BoardPoseConfig {
                count,
                seed,
                ..BoardPoseConfig::default()
            },
            ..Self::default()
        }
    }
}

/// Simulates a calibration session: the board at random poses in `out/board/pose_NNN/` and on
/// the turntable in `out/turntable/angle_NNN/`. Each folder holds `white.png` (the board under
/// full white), the capture set of the sequence (`manifest.json` and frames), `board.json`
/// (`T_cam_board` and the inner corners in 3-D, in the camera image and in the projector
/// image) and the per-pixel truth in `truth/`.
pub fn simulate_calibration(
    rig: &VirtualRig,
    session: &CalibrationSession,
    manifest: &Manifest,
    out: &Path,
    mut on_capture: impl FnMut(&SimulatedCapture),
) -> Result<Vec<SimulatedCapture>, SimError> {
    let sequence = manifest.sequence();
    projector_images(rig, manifest)?; // checks the projector size
    let captures = CalibrationCaptures::new(rig, session)?;
    let mut done = Vec::new();
    for k in 0..captures.poses().len() {
        let dir = out.join("board").join(format!("pose_{k:03}"));
        let t = Instant::now();
        let cap = captures.hand_held(k, Some(&sequence))?;
        let c = write_board_capture(
            &session.board,
            &cap,
            manifest,
            &dir,
            0.0,
            ms(t),
            &format!("board pose {k}"),
        )?;
        on_capture(&c);
        done.push(c);
    }
    for (k, &angle) in session.turntable_angles_deg.iter().enumerate() {
        let dir = out.join("turntable").join(format!("angle_{k:03}"));
        let t = Instant::now();
        let cap = captures.on_table(k, Some(&sequence))?;
        let c = write_board_capture(
            &session.board,
            &cap,
            manifest,
            &dir,
            angle,
            ms(t),
            &format!("board on the turntable at {angle} degrees"),
        )?;
        on_capture(&c);
        done.push(c);
    }
    Ok(done)
}

#[derive(Serialize)]
struct BoardFile<'a> {
    board: &'a Checkerboard,
    motor_angle_deg: f64,
    /// `T_cam_board` as a 4x4 row-major matrix.
    t_cam_board: [[f64; 4]; 4],
    /// `[x, y, z]` per inner corner (mm, camera frame), row by row.
    corners_cam: Vec<[f64; 3]>,
    /// `[x, y]` camera pixel per inner corner (`null` outside the image).
    corners_px: Vec<Option<[f64; 2]>>,
    /// `[x, y]` projector pixel per inner corner (`null` outside the projector's image).
    corners_projector: Vec<Option<[f64; 2]>>,
}

fn write_board_capture(
    board: &Checkerboard,
    cap: &BoardCapture,
    manifest: &Manifest,
    dir: &Path,
    motor_angle_deg: f64,
    render_ms: f64,
    what: &str,
) -> Result<SimulatedCapture, SimError> {
    let t = Instant::now();
    write_capture_set(
        dir,
        manifest,
        &cap.frames,
        &format!("sl-sim virtual rig, {what}"),
    )?;
    write_png_grey(&dir.join("white.png"), &cap.white)?;
    write_view_truth(&cap.view.truth, &dir.join(TRUTH_DIR))?;
    let b = &cap.board;
    let file = BoardFile {
        board,
        motor_angle_deg,
        t_cam_board: crate::pose_matrix(&b.t_cam_board),
        corners_cam: b.corners_cam.iter().map(|p| [p.x, p.y, p.z]).collect(),
        corners_px: b.corners_px.iter().map(|q| q.map(|q| [q.x, q.y])).collect(),
        corners_projector: b
            .corners_projector
            .iter()
            .map(|q| q.map(|q| [q.x, q.y]))
            .collect(),
    };
    write_json(&dir.join("board.json"), &file)?;
    Ok(SimulatedCapture {
        dir: dir.to_path_buf(),
        motor_angle_deg,
        visible_pixels: cap.view.truth.visible_count(),
        lit_pixels: cap.view.truth.lit_count(),
        cast_ms: 0.0,
        render_ms,
        write_ms: ms(t),
    })
}
