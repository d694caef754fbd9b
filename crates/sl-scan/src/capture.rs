//! The capture stage: the scan's pattern sequence, the motor angles of a full turn, and a
//! capture session run through `sl-rig`'s device traits — the same call for real devices and
//! for the virtual rig's.

use std::path::Path;

use sl_camera::TurntableAxis;
use sl_codec::{Axis, HybridSpec, ImageSize, Pattern, PatternSequence};
use sl_rig::{
    Camera, CaptureSession, Projector, SessionConfig, SessionPlan, SessionSummary, Turntable,
    turntable_angles,
};

use crate::error::stage_err;
use crate::{ScanError, ScanProgress};

/// Phase steps of the scan's hybrid code: the capture the toolkit recommends
/// (`sl_codec::RECOMMENDED_PHASE_STEPS`, one constant for `slscan patterns`, `capture` and
/// `scan`). 8 rather than 4: with 15 px fringes the plane flatness RMS falls from 0.0214 to
/// 0.0154 mm (issue 6's target is 0.02 mm) for 4 more frames per view (24 instead of 20;
/// `docs/triangulation.md`, rendered accuracy).
pub const SCAN_PHASE_STEPS: u32 = sl_codec::RECOMMENDED_PHASE_STEPS;

/// Fringe period of the scan's hybrid code in projector pixels: the recommended capture's
/// (`sl_codec::RECOMMENDED_PERIOD_PX`), the finest period the projector blur still resolves
/// with good modulation.
pub const SCAN_PERIOD_PX: f64 = sl_codec::RECOMMENDED_PERIOD_PX;

/// The scan's pattern sequence: hybrid code on the projector columns, [`SCAN_PHASE_STEPS`]
/// phase steps, periods of `period_px` projector pixels ([`SCAN_PERIOD_PX`] by default, on
/// the virtual and the real rig).
pub fn scan_patterns(projector: ImageSize, period_px: f64) -> PatternSequence {
    scan_patterns_with(projector, period_px, SCAN_PHASE_STEPS)
}

/// [`scan_patterns`] with `steps` phase steps instead of [`SCAN_PHASE_STEPS`] (3 steps: one
/// frame less a view, and the phase most sensitive to the projector's response).
pub fn scan_patterns_with(projector: ImageSize, period_px: f64, steps: u32) -> PatternSequence {
    PatternSequence::new(projector).with(Pattern::Hybrid(HybridSpec::complementary(
        Axis::Column,
        projector,
        steps,
        f64::from(projector.width) / period_px,
    )))
}

/// Motor angles (degrees) of `views` views that turn the *platter* a full turn in equal steps
/// from motor angle 0, through the calibrated scale (`θ = angle_scale · m + offset`):
/// `m_k = 360° k / (views · angle_scale)`. Without an axis (or with scale 1) these are the
/// angles of [`sl_rig::turntable_angles`].
///
/// # Errors
/// [`ScanError::Stage`] when the scale is zero or not finite.
pub fn full_turn_motor_angles(
    axis: Option<&TurntableAxis>,
    views: usize,
) -> Result<Vec<f64>, ScanError> {
    let scale = axis.map_or(1.0, |a| a.angle_scale);
    if !scale.is_finite() || scale == 0.0 {
        return Err(stage_err(
            "capture",
            format!("turntable.angle_scale {scale}: must be finite and non-zero"),
        ));
    }
    Ok(turntable_angles(views)
        .into_iter()
        .map(|a| a / scale)
        .collect())
}

/// Captures the session `plan` into `dir` on the devices (resuming an interrupted session:
/// views already complete are kept unless `config.overwrite`), reporting each view as
/// progress of the stage `capture`.
///
/// # Errors
/// [`ScanError::Rig`]: a folder holding a session with another plan, or a device's failure
/// naming the view and the frame.
pub fn capture_session<C, P, T>(
    dir: &Path,
    plan: SessionPlan,
    config: SessionConfig,
    camera: &mut C,
    projector: &mut P,
    turntable: &mut T,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionSummary, ScanError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
    T: Turntable + ?Sized,
{
    let total = plan.angles_deg.len();
    let session = CaptureSession::open(dir, plan, config)?;
    Ok(session.run(camera, projector, turntable, |v| {
        progress(ScanProgress {
            stage: "capture",
            done: v.index + 1,
            total,
        });
    })?)
}

/// [`capture_session`] with two cameras (binocular structured light): `cameras` is the left
/// and the right camera; each view's `right/` folder gets the right camera's frames
/// ([`CaptureSession::run_binocular`]). The plan names the second camera
/// ([`sl_rig::SessionDevices::right_camera`]).
///
/// # Errors
/// As [`capture_session`].
pub fn capture_binocular_session<C, R, P, T>(
    dir: &Path,
    plan: SessionPlan,
    config: SessionConfig,
    cameras: (&mut C, &mut R),
    projector: &mut P,
    turntable: &mut T,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionSummary, ScanError>
where
    C: Camera + ?Sized,
    R: Camera + ?Sized,
    P: Projector + ?Sized,
    T: Turntable + ?Sized,
{
    let total = plan.angles_deg.len();
    let session = CaptureSession::open(dir, plan, config)?;
    Ok(
        session.run_binocular(cameras.0, cameras.1, projector, turntable, |v| {
            progress(ScanProgress {
                stage: "capture",
                done: v.index + 1,
                total,
            });
        })?,
    )
}
