//! A calibration session's board captures rendered one at a time, with the session's noise
//! keys: the captures of `slscan scan`'s calibration stage (`sl_scan::calibrate_virtual`), of
//! `slscan simulate --calibration` ([`crate::simulate_calibration`]) and of the studies of
//! them (sl-calib's `rig_corner_truth`) are the same frames because they come from here.

use nalgebra::Isometry3;
use sl_codec::{Axis, HybridSpec, ImageSize, Pattern, PatternSequence};

use crate::{
    BoardCapture, CalibrationSession, SimError, VirtualRig, capture_board, capture_board_on_table,
    random_board_poses,
};

/// Projector pixels per fringe period of [`calibration_sequence`]: about 30 on both axes, a
/// period the camera resolves at every board pose of the default rig.
pub const CALIBRATION_PERIOD_PX: f64 = 30.0;

/// Phase steps of [`calibration_sequence`]: 4 (8 halve the phase noise but double the
/// rendering time of a calibration).
pub const CALIBRATION_PHASE_STEPS: u32 = 4;

/// The patterns of a projector–camera calibration: the hybrid code (phase shift plus
/// complementary Gray code) on the columns and on the rows — the projector needs both
/// coordinates of every corner — with [`CALIBRATION_PHASE_STEPS`] steps and periods of
/// about [`CALIBRATION_PERIOD_PX`] projector pixels.
pub fn calibration_sequence(projector: ImageSize) -> PatternSequence {
    let p = projector;
    PatternSequence::new(p)
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Column,
            p,
            CALIBRATION_PHASE_STEPS,
            f64::from(p.width) / CALIBRATION_PERIOD_PX,
        )))
        .with(Pattern::Hybrid(HybridSpec::complementary(
            Axis::Row,
            p,
            CALIBRATION_PHASE_STEPS,
            f64::from(p.height) / CALIBRATION_PERIOD_PX,
        )))
}

/// A [`CalibrationSession`] drawn for a rig: its hand-held board poses, ready to be rendered
/// capture by capture (a session at full resolution holds gigabytes of frames; a caller keeps
/// what it needs of each). Capture `k` of the hand-held board has noise key `k`; the board on
/// the turntable at the session's `k`-th angle has key `poses + k`.
///
/// ```
/// use sl_sim::{BoardPoseConfig, CalibrationCaptures, CalibrationSession, RigConfig, Scene, VirtualRig};
/// # fn main() -> Result<(), sl_sim::SimError> {
/// let mut config = RigConfig::default();
/// config.render.supersampling = 1; // one ray per pixel: a quick example
/// let rig = VirtualRig::new(config, Scene::sphere())?;
/// let session = CalibrationSession {
///     poses: BoardPoseConfig { count: 2, ..BoardPoseConfig::default() },
///     turntable_angles_deg: vec![0.0],
///     ..CalibrationSession::default()
/// };
/// let captures = CalibrationCaptures::new(&rig, &session)?;
/// assert_eq!(captures.poses().len(), 2);
/// let first = captures.hand_held(0, None)?;
/// assert_eq!(first.board.t_cam_board, captures.poses()[0]);
/// let on_table = captures.on_table(0, None)?;
/// assert_eq!((on_table.white.width(), on_table.white.height()), (1280, 720));
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Clone)]
pub struct CalibrationCaptures<'a> {
    rig: &'a VirtualRig,
    session: &'a CalibrationSession,
    poses: Vec<Isometry3<f64>>,
}

impl<'a> CalibrationCaptures<'a> {
    /// Draws the session's hand-held poses for `rig` ([`random_board_poses`]).
    ///
    /// # Errors
    /// Those of [`random_board_poses`]: bad settings, or no pose the camera and the projector
    /// both see.
    pub fn new(rig: &'a VirtualRig, session: &'a CalibrationSession) -> Result<Self, SimError> {
        let poses = random_board_poses(rig.config(), &session.board, &session.poses)?;
        Ok(Self {
            rig,
            session,
            poses,
        })
    }

    /// The session.
    pub fn session(&self) -> &CalibrationSession {
        self.session
    }

    /// The hand-held poses `T_cam_board`, in capture order.
    pub fn poses(&self) -> &[Isometry3<f64>] {
        &self.poses
    }

    /// The board held at pose `k`, under full white and, with `sequence`, every pattern.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for `k` beyond the poses; those of [`capture_board`].
    pub fn hand_held(
        &self,
        k: usize,
        sequence: Option<&PatternSequence>,
    ) -> Result<BoardCapture, SimError> {
        let pose = self.poses.get(k).ok_or_else(|| {
            SimError::param(
                "board pose",
                format!("{k}: the session has {} poses", self.poses.len()),
            )
        })?;
        capture_board(self.rig, &self.session.board, pose, sequence, k as u64)
    }

    /// The board standing on the turntable at the session's `k`-th angle.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for `k` beyond the angles; those of
    /// [`capture_board_on_table`].
    pub fn on_table(
        &self,
        k: usize,
        sequence: Option<&PatternSequence>,
    ) -> Result<BoardCapture, SimError> {
        let angles = &self.session.turntable_angles_deg;
        let angle = *angles.get(k).ok_or_else(|| {
            SimError::param(
                "turntable angle",
                format!("{k}: the session has {} angles", angles.len()),
            )
        })?;
        let index = (self.poses.len() + k) as u64;
        capture_board_on_table(self.rig, &self.session.board, angle, sequence, index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BoardPoseConfig, RigConfig, Scene};

    /// Each capture is the one `capture_board` / `capture_board_on_table` render with the
    /// session's noise key (`k`, then `poses + k`); another key gives other noise.
    #[test]
    fn captures_carry_the_sessions_noise_keys() {
        let mut config = RigConfig::default();
        config.render.supersampling = 1;
        let rig = VirtualRig::new(config, Scene::sphere()).unwrap();
        let session = CalibrationSession {
            poses: BoardPoseConfig {
                count: 2,
                ..BoardPoseConfig::default()
            },
            turntable_angles_deg: vec![15.0],
            ..CalibrationSession::default()
        };
        let c = CalibrationCaptures::new(&rig, &session).unwrap();
        let held = c.hand_held(1, None).unwrap();
        let direct = capture_board(&rig, &session.board, &c.poses()[1], None, 1).unwrap();
        assert_eq!(held.white, direct.white);
        let table = c.on_table(0, None).unwrap();
        let direct = capture_board_on_table(&rig, &session.board, 15.0, None, 2).unwrap();
        assert_eq!(table.white, direct.white);
        let other_key = capture_board_on_table(&rig, &session.board, 15.0, None, 0).unwrap();
        assert_ne!(table.white, other_key.white);

        let e = c.hand_held(2, None).unwrap_err().to_string();
        assert!(e.contains("board pose") && e.contains("2 poses"), "{e}");
        let e = c.on_table(1, None).unwrap_err().to_string();
        assert!(
            e.contains("turntable angle") && e.contains("1 angles"),
            "{e}"
        );
    }

    /// Both projector axes are coded, with the documented steps and periods.
    #[test]
    fn the_sequence_codes_both_axes() {
        let p = ImageSize::new(1920, 1080);
        let s = calibration_sequence(p);
        let hybrid: Vec<&HybridSpec> = s
            .blocks
            .iter()
            .filter_map(|x| match x {
                Pattern::Hybrid(h) => Some(h),
                _ => None,
            })
            .collect();
        assert_eq!(hybrid.len(), 2);
        for (h, axis, extent) in [
            (hybrid[0], Axis::Column, 1920),
            (hybrid[1], Axis::Row, 1080),
        ] {
            assert_eq!(
                (h.axis, h.extent, h.steps),
                (axis, extent, CALIBRATION_PHASE_STEPS)
            );
            // Periods of 30 projector pixels.
            assert!((f64::from(extent) / h.periods - CALIBRATION_PERIOD_PX).abs() < 1e-9);
        }
    }
}
