//! Taking the poses of a calibration capture without a key press, and who moves the board.
//!
//! [`capture_poses_auto`] takes each pose right after the board moved when it moves itself
//! (the virtual rig), else once a hand-held board has been still for
//! [`AutoConfig::still_for`]; a refused hand-held pose is not tried again until the board
//! moved. [`wait_for_still_board`] waits for the board laid on the turntable.

use std::path::Path;
use std::time::{Duration, Instant};

use nalgebra::Point2;
use sl_rig::{Camera, Projector};

use crate::calibration_capture::{CalibrationCapture, CaptureError, TakeOutcome};
use crate::pose_gates::{PoseCheck, Refusal};

/// Who moves the board between poses.
pub trait BoardMover {
    /// Whether the board moves by itself (the virtual rig): then [`capture_poses_auto`] takes
    /// each pose right after the move instead of waiting for the board to be still.
    fn moves_itself(&self) -> bool;

    /// Called after each pose taken or refused: moves the board to its next pose (a person
    /// does that on their own: nothing to do).
    fn next_pose(&mut self) -> Result<(), CaptureError>;

    /// Lays the board on the turntable (a person is asked by the user interface instead).
    fn onto_turntable(&mut self) -> Result<(), CaptureError>;
}

/// A person holds the board: nothing to do here, the user interface asks them.
#[derive(Debug, Clone, Copy, Default)]
pub struct HandHeld;

impl BoardMover for HandHeld {
    fn moves_itself(&self) -> bool {
        false
    }

    fn next_pose(&mut self) -> Result<(), CaptureError> {
        Ok(())
    }

    fn onto_turntable(&mut self) -> Result<(), CaptureError> {
        Ok(())
    }
}

/// Options of [`capture_poses_auto`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AutoConfig {
    /// Poses wanted in the session (those of earlier runs count).
    pub poses: usize,
    /// A hand-held board is taken once it has been still this long. Default 1 s.
    pub still_for: Duration,
    /// Largest corner motion (px) that counts as still. Default 1 px.
    pub still_tolerance_px: f64,
    /// Give up after this many frames looked at (`None`: never). A guard for scripts.
    pub max_looks: Option<usize>,
}

impl Default for AutoConfig {
    fn default() -> Self {
        Self {
            poses: 15,
            still_for: Duration::from_secs(1),
            still_tolerance_px: 1.0,
            max_looks: None,
        }
    }
}

/// What [`capture_poses_auto`] reports as it goes.
#[derive(Debug)]
pub enum AutoEvent<'a> {
    /// A frame was looked at.
    Looked(&'a PoseCheck),
    /// A pose was taken.
    Taken {
        /// Its number.
        index: usize,
        /// Its folder.
        dir: &'a Path,
    },
    /// A pose was refused.
    Refused(&'a Refusal),
}

/// Takes poses without a key press until the session holds `cfg.poses`: each pose as soon as
/// the board moved itself, or once a hand-held board has been still for `cfg.still_for` (a
/// refused pose is not tried again until the board moved). Returns the poses taken now.
pub fn capture_poses_auto<C, P, M>(
    session: &mut CalibrationCapture,
    camera: &mut C,
    projector: &mut P,
    mover: &mut M,
    cfg: &AutoConfig,
    on_event: impl FnMut(AutoEvent<'_>),
) -> Result<usize, CaptureError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
    M: BoardMover + ?Sized,
{
    capture_poses_auto_with(session, camera, None, projector, mover, cfg, on_event)
}

/// [`capture_poses_auto`] with the second camera of a binocular rig, which takes its own
/// picture of every pose ([`CalibrationCapture::take_with`]; a pose it does not see whole is
/// refused and the board moved on).
///
/// # Errors
/// As [`capture_poses_auto`].
pub fn capture_poses_auto_with<C, P, M>(
    session: &mut CalibrationCapture,
    camera: &mut C,
    mut right: Option<&mut dyn Camera>,
    projector: &mut P,
    mover: &mut M,
    cfg: &AutoConfig,
    mut on_event: impl FnMut(AutoEvent<'_>),
) -> Result<usize, CaptureError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
    M: BoardMover + ?Sized,
{
    let mut taken = 0;
    let mut looks = 0usize;
    // Corners the board must leave before a refused hand-held pose is tried again.
    let mut refused_at: Option<Vec<Point2<f64>>> = None;
    let mut still = Stillness::default();
    while session.poses().len() < cfg.poses {
        if cfg.max_looks.is_some_and(|m| looks >= m) {
            return Err(CaptureError::param(
                "auto",
                format!(
                    "{} of {} poses after {looks} frames: the board was not still, or every \
                     pose was refused",
                    session.poses().len(),
                    cfg.poses
                ),
            ));
        }
        looks += 1;
        let check = session.look(camera, projector)?;
        on_event(AutoEvent::Looked(&check));
        if !mover.moves_itself() {
            let corners = check.corners.as_ref().map(|c| c.corners.as_slice());
            if let (Some(old), Some(now)) = (&refused_at, corners)
                && max_motion(old, now) <= cfg.still_tolerance_px
            {
                continue;
            }
            refused_at = None;
            if !still.update(corners, cfg, Instant::now()) {
                continue;
            }
        }
        // A shorter reborrow of the second camera for this pose.
        let second = right.as_mut().map(|r| &mut **r as &mut dyn Camera);
        match session.take_with(&check, camera, second, projector)? {
            TakeOutcome::Taken { index, dir } => {
                taken += 1;
                on_event(AutoEvent::Taken { index, dir: &dir });
            }
            TakeOutcome::Refused(r) => {
                on_event(AutoEvent::Refused(&r));
                refused_at = check.corners.as_ref().map(|c| c.corners.clone());
            }
        }
        still = Stillness::default();
        if session.poses().len() < cfg.poses {
            mover.next_pose()?;
        }
    }
    Ok(taken)
}

/// Looks until the whole board is found and has been still for `cfg.still_for` (the board
/// laid on the turntable by a person, in `--auto` mode); `cfg.max_looks` bounds the wait.
pub fn wait_for_still_board<C, P>(
    session: &CalibrationCapture,
    camera: &mut C,
    projector: &mut P,
    cfg: &AutoConfig,
    mut on_look: impl FnMut(&PoseCheck),
) -> Result<PoseCheck, CaptureError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
{
    let mut still = Stillness::default();
    let mut looks = 0usize;
    loop {
        if cfg.max_looks.is_some_and(|m| looks >= m) {
            return Err(CaptureError::param(
                "auto",
                format!("no still board after {looks} frames"),
            ));
        }
        looks += 1;
        let check = session.look(camera, projector)?;
        on_look(&check);
        let corners = check.corners.as_ref().map(|c| c.corners.as_slice());
        if still.update(corners, cfg, Instant::now()) {
            return Ok(check);
        }
    }
}

/// Largest distance between corresponding corners (px); infinite for different counts.
fn max_motion(a: &[Point2<f64>], b: &[Point2<f64>]) -> f64 {
    if a.len() != b.len() {
        return f64::INFINITY;
    }
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

/// Tracks how long the board has been still.
#[derive(Debug, Default)]
struct Stillness {
    reference: Option<(Vec<Point2<f64>>, Instant)>,
}

impl Stillness {
    /// Updates with the corners of a new frame; `true` once the board has been within the
    /// tolerance of the reference for `still_for`.
    fn update(&mut self, corners: Option<&[Point2<f64>]>, cfg: &AutoConfig, now: Instant) -> bool {
        let Some(corners) = corners else {
            self.reference = None;
            return false;
        };
        match &self.reference {
            Some((r, since)) if max_motion(r, corners) <= cfg.still_tolerance_px => {
                now.duration_since(*since) >= cfg.still_for
            }
            _ => {
                self.reference = Some((corners.to_vec(), now));
                cfg.still_for.is_zero()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stillness_needs_the_whole_interval() {
        let cfg = AutoConfig {
            still_for: Duration::from_millis(1000),
            ..AutoConfig::default()
        };
        let t0 = Instant::now();
        let a = [Point2::new(10.0, 10.0), Point2::new(20.0, 10.0)];
        let b = [Point2::new(13.0, 10.0), Point2::new(23.0, 10.0)];
        let mut s = Stillness::default();
        assert!(!s.update(Some(&a), &cfg, t0));
        assert!(!s.update(Some(&a), &cfg, t0 + Duration::from_millis(600)));
        // Moved 3 px: the interval starts again.
        assert!(!s.update(Some(&b), &cfg, t0 + Duration::from_millis(1100)));
        assert!(!s.update(Some(&b), &cfg, t0 + Duration::from_millis(1900)));
        assert!(s.update(Some(&b), &cfg, t0 + Duration::from_millis(2100)));
        // Lost: starts again.
        assert!(!s.update(None, &cfg, t0 + Duration::from_millis(2200)));
        assert!(!s.update(Some(&b), &cfg, t0 + Duration::from_millis(2300)));
    }
}
