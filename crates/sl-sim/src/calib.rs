//! Calibration captures: a checkerboard at varied poses (camera and projector calibration)
//! and on the turntable at several angles (turntable-axis calibration), with their truth.

use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use sl_codec::PatternSequence;

use crate::{
    Checkerboard, GreyImage, Mount, RigConfig, Scene, SceneObject, SimError, View, VirtualRig,
};

/// Ground truth of a checkerboard in one pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardTruth {
    /// `T_cam_board`: the board frame in the camera frame.
    pub t_cam_board: Isometry3<f64>,
    /// The inner corners in the camera frame (mm), in [`Checkerboard::corners`] order.
    pub corners_cam: Vec<Point3<f64>>,
    /// The inner corners' camera pixels (with distortion); `None` outside the image.
    pub corners_px: Vec<Option<Point2<f64>>>,
    /// The inner corners' projector pixels (with distortion); `None` outside the projector's
    /// image.
    pub corners_projector: Vec<Option<Point2<f64>>>,
}

impl RigConfig {
    /// The truth of `board` at `t_cam_board`: its corners in 3-D, in the camera image and in
    /// the projector image (the references that corner detection and projector calibration
    /// are checked against).
    pub fn board_truth(&self, board: &Checkerboard, t_cam_board: &Isometry3<f64>) -> BoardTruth {
        let corners_cam: Vec<Point3<f64>> =
            board.corners().iter().map(|c| t_cam_board * c).collect();
        let corners_px = corners_cam
            .iter()
            .map(|p| {
                self.camera
                    .project(p)
                    .filter(|q| self.camera.size.contains(q.x, q.y))
            })
            .collect();
        let corners_projector = corners_cam
            .iter()
            .map(|p| {
                self.projector
                    .project(&self.t_cam_proj.inverse_transform_point(p))
                    .filter(|q| self.projector.size.contains(q.x, q.y))
            })
            .collect();
        BoardTruth {
            t_cam_board: *t_cam_board,
            corners_cam,
            corners_px,
            corners_projector,
        }
    }
}

/// How [`random_board_poses`] draws board poses.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardPoseConfig {
    /// Number of poses.
    pub count: usize,
    /// Nearest distance of the board centre from the camera (mm).
    pub min_distance_mm: f64,
    /// Farthest distance of the board centre from the camera (mm).
    pub max_distance_mm: f64,
    /// Largest tilt of the board out of the fronto-parallel orientation (degrees): tilts
    /// between 10° and 40° constrain the focal length best (Zhang 2000).
    pub max_tilt_deg: f64,
    /// Largest rotation of the board about its normal (degrees).
    pub max_roll_deg: f64,
    /// Smallest distance of every inner corner from the image border, in the camera and in
    /// the projector (pixels), so that corner detection and decoding see the whole grid.
    pub margin_px: f64,
    /// Seed of the pose draw.
    pub seed: u64,
}

impl Default for BoardPoseConfig {
    /// 12 poses between 380 and 520 mm, tilted up to 35°, rolled up to 20°, corners 30 px
    /// inside both images.
    fn default() -> Self {
        Self {
            count: 12,
            min_distance_mm: 380.0,
            max_distance_mm: 520.0,
            max_tilt_deg: 35.0,
            max_roll_deg: 20.0,
            margin_px: 30.0,
            seed: 1,
        }
    }
}

/// Attempts per requested pose before [`random_board_poses`] gives up: a pose is refused when
/// a corner leaves either image, which with sensible settings happens for well under half of
/// the draws.
const POSE_ATTEMPTS_PER_POSE: usize = 2000;

/// Smallest cosine between the board normal and the directions to the camera and to the
/// projector (75°): beyond, the board is seen too obliquely for corners or patterns.
const MIN_VIEW_COS: f64 = 0.26;

/// Draws board poses `T_cam_board` (seeded) that the camera and the projector both see
/// entirely: every inner corner at least `margin_px` inside both images, the printed side
/// facing both.
pub fn random_board_poses(
    rig: &RigConfig,
    board: &Checkerboard,
    cfg: &BoardPoseConfig,
) -> Result<Vec<Isometry3<f64>>, SimError> {
    board.validate()?;
    if !(cfg.min_distance_mm > 0.0 && cfg.max_distance_mm >= cfg.min_distance_mm) {
        return Err(SimError::param(
            "board pose distance",
            format!(
                "[{}, {}] mm is not a valid range",
                cfg.min_distance_mm, cfg.max_distance_mm
            ),
        ));
    }
    let mut rng = Pcg64Mcg::seed_from_u64(cfg.seed);
    let s = board.square_mm;
    let centre_board = Vector3::new(
        f64::from(board.inner_cols - 1) * s / 2.0,
        f64::from(board.inner_rows - 1) * s / 2.0,
        0.0,
    );
    let proj_centre = Point3::from(rig.t_cam_proj.translation.vector);
    let mut poses = Vec::with_capacity(cfg.count);
    let mut attempts = 0usize;
    while poses.len() < cfg.count {
        attempts += 1;
        if attempts > POSE_ATTEMPTS_PER_POSE * cfg.count.max(1) {
            return Err(SimError::param(
                "board poses",
                format!(
                    "found only {} of {} poses that both camera and projector see entirely; \
                     use a smaller board, a smaller margin or a wider distance range",
                    poses.len(),
                    cfg.count
                ),
            ));
        }
        let d = rng.random_range(cfg.min_distance_mm..=cfg.max_distance_mm);
        // Board centre: on a ray within the central part of the camera's view.
        let ray = Vector3::new(
            rng.random_range(-0.12..0.12),
            rng.random_range(-0.08..0.08),
            1.0,
        )
        .normalize();
        let centre = Point3::from(ray * d);
        let tilt_axis_angle = rng.random_range(0.0..std::f64::consts::TAU);
        let tilt = rng.random_range(0.0..=cfg.max_tilt_deg).to_radians();
        let roll = rng
            .random_range(-cfg.max_roll_deg..=cfg.max_roll_deg)
            .to_radians();
        let axis = nalgebra::Unit::new_normalize(Vector3::new(
            tilt_axis_angle.cos(),
            tilt_axis_angle.sin(),
            0.0,
        ));
        let rotation = UnitQuaternion::from_axis_angle(&axis, tilt)
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll);
        let translation = centre.coords - rotation * centre_board;
        let pose = Isometry3::from_parts(Translation3::from(translation), rotation);
        let normal = rotation * Vector3::z(); // into the board: away from the viewer
        let facing = |eye: &Point3<f64>| (eye - centre).normalize().dot(&-normal) > MIN_VIEW_COS;
        if !facing(&Point3::origin()) || !facing(&proj_centre) {
            continue;
        }
        let truth = rig.board_truth(board, &pose);
        let inside = |q: &Option<Point2<f64>>, w: u32, h: u32| {
            q.is_some_and(|q| {
                q.x >= cfg.margin_px
                    && q.y >= cfg.margin_px
                    && q.x <= f64::from(w) - 1.0 - cfg.margin_px
                    && q.y <= f64::from(h) - 1.0 - cfg.margin_px
            })
        };
        let (cw, ch) = (rig.camera.size.width, rig.camera.size.height);
        let (pw, ph) = (rig.projector.size.width, rig.projector.size.height);
        if truth.corners_px.iter().all(|q| inside(q, cw, ch))
            && truth.corners_projector.iter().all(|q| inside(q, pw, ph))
        {
            poses.push(pose);
        }
    }
    Ok(poses)
}

/// One calibration capture: a board pose, its truth, the board under full white, and the
/// board under every pattern of a sequence.
#[derive(Debug, Clone)]
pub struct BoardCapture {
    /// Corners and pose.
    pub board: BoardTruth,
    /// The view (geometry cache and per-pixel truth).
    pub view: View,
    /// The board with the projector showing full white (for corner detection).
    pub white: GreyImage,
    /// The board under each pattern of the sequence, in order (empty without a sequence).
    pub frames: Vec<GreyImage>,
}

/// Renders `board` held at `t_cam_board` (fixed in the camera frame) with `rig`: the white
/// frame and, when `sequence` is given, one frame per pattern. `index` keys the noise.
pub fn capture_board(
    rig: &VirtualRig,
    board: &Checkerboard,
    t_cam_board: &Isometry3<f64>,
    sequence: Option<&PatternSequence>,
    index: u64,
) -> Result<BoardCapture, SimError> {
    let scene = Scene::new().with(SceneObject::board(
        "board",
        *board,
        Mount::Camera,
        *t_cam_board,
    ));
    let view = rig.with_scene(scene)?.view(0.0, index)?;
    capture_view(rig, board, view, t_cam_board, sequence)
}

/// Renders `board` standing on the turntable (as [`Scene::board_on_table`] places it) with
/// the motor at `motor_angle_deg`: the turntable-axis calibration capture. `index` keys the
/// noise.
pub fn capture_board_on_table(
    rig: &VirtualRig,
    board: &Checkerboard,
    motor_angle_deg: f64,
    sequence: Option<&PatternSequence>,
    index: u64,
) -> Result<BoardCapture, SimError> {
    let scene = Scene::board_on_table(*board);
    let t_table_board = scene
        .objects
        .first()
        .map(|o| o.pose)
        .unwrap_or_else(Isometry3::identity);
    let t_cam_board = rig.config().t_cam_table_at(motor_angle_deg) * t_table_board;
    let view = rig.with_scene(scene)?.view(motor_angle_deg, index)?;
    capture_view(rig, board, view, &t_cam_board, sequence)
}

fn capture_view(
    rig: &VirtualRig,
    board: &Checkerboard,
    view: View,
    t_cam_board: &Isometry3<f64>,
    sequence: Option<&PatternSequence>,
) -> Result<BoardCapture, SimError> {
    let cfg = rig.config();
    let (pw, ph) = (cfg.projector.size.width, cfg.projector.size.height);
    let white = view.capture(&GreyImage::filled_u8(pw as usize, ph as usize, u8::MAX)?, 0)?;
    let frames = match sequence {
        Some(seq) => (0..seq.frame_count())
            .map(|k| {
                let img = seq.render_image(k, sl_codec::BitDepth::Eight)?;
                view.capture(&img, k as u64 + 1)
            })
            .collect::<Result<Vec<_>, SimError>>()?,
        None => Vec::new(),
    };
    Ok(BoardCapture {
        board: cfg.board_truth(board, t_cam_board),
        view,
        white,
        frames,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_keep_every_corner_in_both_images() {
        let rig = RigConfig::default();
        let board = Checkerboard::default();
        let cfg = BoardPoseConfig {
            count: 8,
            ..BoardPoseConfig::default()
        };
        let poses = random_board_poses(&rig, &board, &cfg).unwrap();
        assert_eq!(poses.len(), 8);
        for p in &poses {
            let t = rig.board_truth(&board, p);
            assert!(t.corners_px.iter().all(Option::is_some));
            assert!(t.corners_projector.iter().all(Option::is_some));
            // The board plane passes through every 3-D corner: z of each corner in the board
            // frame is 0.
            for c in &t.corners_cam {
                assert!(p.inverse_transform_point(c).z.abs() < 1e-9);
            }
        }
        // Seeded: the same configuration gives the same poses.
        assert_eq!(poses, random_board_poses(&rig, &board, &cfg).unwrap());
    }

    #[test]
    fn impossible_pose_requests_fail_with_a_message() {
        let rig = RigConfig::default();
        // A 2 m board cannot fit in either image.
        let board = Checkerboard {
            square_mm: 300.0,
            ..Checkerboard::default()
        };
        let cfg = BoardPoseConfig {
            count: 1,
            ..BoardPoseConfig::default()
        };
        let err = random_board_poses(&rig, &board, &cfg).unwrap_err();
        assert!(err.to_string().contains("board poses"), "{err}");
    }
}
