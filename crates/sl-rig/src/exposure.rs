//! Choosing a scene's exposures on the devices: full white and black shown, captured, and
//! measured ([`sl_codec::choose_exposures`]) until the frames tell.

use sl_codec::{AutoExposureConfig, ExposureChoice, ExposurePlan, choose_exposures};

use crate::{Camera, CaptureTiming, GreyImage, Projector, RigError, show_and_capture};

/// Most white-and-black measurements [`measure_exposures`] makes: from 10 ms, six steps of 4
/// reach 0.0025 ms or 41 s, past any camera's range.
pub const MAX_EXPOSURE_MEASUREMENTS: usize = 8;

/// Shows full white and full black, captures each at the camera's exposure, and lets
/// [`choose_exposures`] decide; measures again at the exposure it asks for, until it chooses.
/// Starts at the camera's current exposure, or `start_ms` when the camera does not say, and
/// leaves the camera at that exposure (a session judges its frames at the pass nearest it). `on_measure` hears each measurement's exposure
/// and why another is needed.
///
/// # Errors
/// [`RigError::Unsupported`] for a camera without an exposure control, the devices' errors,
/// and [`RigError::Codec`] when the frames cannot tell after
/// [`MAX_EXPOSURE_MEASUREMENTS`] measurements or [`choose_exposures`] refuses them (nothing
/// lit at the longest exposure).
pub fn measure_exposures<C, P>(
    camera: &mut C,
    projector: &mut P,
    config: &AutoExposureConfig,
    timing: CaptureTiming,
    start_ms: f64,
    mut on_measure: impl FnMut(f64, Option<&str>),
) -> Result<ExposurePlan, RigError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
{
    let (w, h) = projector.image_size();
    let (w, h) = (w as usize, h as usize);
    let white = GreyImage::filled_u8(w, h, u8::MAX)?;
    let black = GreyImage::filled_u8(w, h, 0)?;
    let own = camera.exposure_ms();
    let mut exposure = own.unwrap_or(start_ms);
    let mut reasons = Vec::new();
    for _ in 0..MAX_EXPOSURE_MEASUREMENTS {
        camera.set_exposure_ms(exposure)?;
        let lit = show_and_capture(camera, projector, &white, timing)?;
        let dark = show_and_capture(camera, projector, &black, timing)?;
        match choose_exposures(&lit, &dark, exposure, config)? {
            ExposureChoice::Chosen(plan) => {
                on_measure(exposure, None);
                if let Some(own) = own {
                    camera.set_exposure_ms(own)?;
                }
                return Ok(plan);
            }
            ExposureChoice::MeasureAgain {
                exposure_ms,
                reason,
            } => {
                on_measure(exposure, Some(&reason));
                reasons.push(reason);
                exposure = exposure_ms;
            }
        }
    }
    Err(RigError::Codec(sl_codec::CodecError::Frames(format!(
        "no exposure chosen after {MAX_EXPOSURE_MEASUREMENTS} measurements: {}",
        reasons.join("; ")
    ))))
}
