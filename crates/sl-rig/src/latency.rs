//! Display-to-camera latency: how many frames (and how long) after a projector change the
//! camera first sees it, measured by flashing black and white; and a camera wrapper that
//! buffers frames the way a driver's queue does, so that the measurement and the session's
//! flushing are testable without hardware.

use std::collections::VecDeque;
use std::time::Instant;

use serde::Serialize;

use crate::{Camera, GreyImage, Projector, RigError};

/// How [`measure_latency`] flashes and watches.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LatencyConfig {
    /// Frames captured after each change: the longest latency that can be measured is this
    /// minus [`LatencyConfig::stable_frames`]. Default 16: V4L2 drivers queue 2–8 buffers, so
    /// 16 leaves room for a projector that lags a few frames more.
    pub window_frames: usize,
    /// The last frames of the window, averaged as the settled level. Default 3.
    pub stable_frames: usize,
    /// Black → white → black flashes; the latency reported is the largest over them (the
    /// safe value to flush). Default 3.
    pub flashes: usize,
    /// Smallest difference between the settled white and black mean levels, as a fraction of
    /// full scale. Default [`MIN_FLASH_CONTRAST`].
    pub min_contrast: f64,
}

/// Default smallest flash contrast: 0.5 % of full scale (1.3 grey levels of the frame mean on
/// 8 bits). The mean is over the whole frame, so an object filling a tenth of the image still
/// changes it by several percent, while the noise of a mean over ~10⁵ pixels with a few grey
/// levels of noise is ~0.01 grey level: the threshold sits ~100 times above it.
pub const MIN_FLASH_CONTRAST: f64 = 0.005;

impl Default for LatencyConfig {
    fn default() -> Self {
        Self {
            window_frames: 16,
            stable_frames: 3,
            flashes: 3,
            min_contrast: MIN_FLASH_CONTRAST,
        }
    }
}

/// The measured latency.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Latency {
    /// Frames to drop after a change before a frame shows it: the largest over every
    /// transition (set [`crate::SessionConfig::flush_frames`] to this).
    pub frames: usize,
    /// Time from `show` to the return of the first capture that showed the change, largest
    /// over every transition (ms).
    pub ms: f64,
    /// The frames of each transition, in order (black → white, white → black, …).
    pub transitions: Vec<usize>,
    /// Settled mean level under black, as a fraction of full scale.
    pub black_level: f64,
    /// Settled mean level under white, as a fraction of full scale.
    pub white_level: f64,
}

/// Mean of a frame as a fraction of its full scale.
fn mean_level(frame: &GreyImage) -> f64 {
    frame.mean_normalised()
}

/// One transition: show `image`, capture the window, return the frame means and the time from
/// `show` to the return of each capture (ms).
fn transition<C, P>(
    camera: &mut C,
    projector: &mut P,
    image: &GreyImage,
    window: usize,
) -> Result<(Vec<f64>, Vec<f64>), RigError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
{
    let t = Instant::now();
    projector.show(image)?;
    let mut levels = Vec::with_capacity(window);
    let mut times = Vec::with_capacity(window);
    for _ in 0..window {
        levels.push(mean_level(&camera.capture()?));
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok((levels, times))
}

/// Measures the latency between the projector and the camera by flashing full black and full
/// white and counting the frames (and the time) until the camera's mean level crosses half way
/// between the settled levels.
///
/// Point the camera at the projected area (a white wall or the turntable) first.
///
/// # Errors
/// [`RigError::InvalidParameter`] for a window no longer than the stable frames or zero
/// flashes; [`RigError::Device`] when the camera sees less contrast than
/// [`LatencyConfig::min_contrast`] or does not settle inside the window; the devices' errors.
///
/// ```
/// use sl_rig::{BufferedCamera, LatencyConfig, measure_latency};
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
/// # fn main() -> Result<(), sl_rig::RigError> {
/// // A camera that sees exactly what the projector shows (any devices behind the traits do).
/// let (camera, mut projector, _) = devices()?;
/// // A camera whose driver queues 2 frames.
/// let mut camera = BufferedCamera::new(camera, 2);
/// let latency = measure_latency(&mut camera, &mut projector, &LatencyConfig::default())?;
/// assert_eq!(latency.frames, 2);
/// # Ok(())
/// # }
/// ```
pub fn measure_latency<C, P>(
    camera: &mut C,
    projector: &mut P,
    config: &LatencyConfig,
) -> Result<Latency, RigError>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
{
    if config.stable_frames == 0 || config.window_frames <= config.stable_frames {
        return Err(RigError::param(
            "window_frames",
            format!(
                "{} frames: must exceed stable_frames ({}), which must be at least 1",
                config.window_frames, config.stable_frames
            ),
        ));
    }
    if config.flashes == 0 {
        return Err(RigError::param("flashes", "at least one flash"));
    }
    let (w, h) = projector.image_size();
    let black = GreyImage::filled_u8(w as usize, h as usize, 0)?;
    let white = GreyImage::filled_u8(w as usize, h as usize, u8::MAX)?;
    let settled = |levels: &[f64]| {
        let tail = &levels[levels.len() - config.stable_frames..];
        tail.iter().sum::<f64>() / tail.len() as f64
    };
    // Start from a settled black.
    let (levels, _) = transition(camera, projector, &black, config.window_frames)?;
    let mut previous = settled(&levels);
    let (mut black_level, mut white_level) = (previous, previous);
    let mut transitions = Vec::new();
    let (mut frames, mut worst_ms) = (0usize, 0.0f64);
    for k in 0..2 * config.flashes {
        let to_white = k % 2 == 0;
        let image = if to_white { &white } else { &black };
        let (levels, times) = transition(camera, projector, image, config.window_frames)?;
        let level = settled(&levels);
        if to_white {
            white_level = level;
        } else {
            black_level = level;
        }
        let contrast = (level - previous).abs();
        if contrast < config.min_contrast {
            return Err(RigError::Device {
                device: "camera".to_owned(),
                reason: format!(
                    "latency flash {}: the mean level changed by {:.4} of full scale (need {}): point the camera at the projected area, open the aperture or lengthen the exposure (or the camera queues more frames than window_frames)",
                    k + 1,
                    contrast,
                    config.min_contrast
                ),
            });
        }
        let half = 0.5 * (level + previous);
        let crossed = levels
            .iter()
            .position(|&l| if to_white { l > half } else { l < half });
        let settle_start = config.window_frames - config.stable_frames;
        let Some(first) = crossed.filter(|&i| i < settle_start) else {
            return Err(RigError::Device {
                device: "camera".to_owned(),
                reason: format!(
                    "latency flash {}: the change did not settle within {} frames; raise window_frames",
                    k + 1,
                    config.window_frames
                ),
            });
        };
        transitions.push(first);
        frames = frames.max(first);
        worst_ms = worst_ms.max(times.get(first).copied().unwrap_or(0.0));
        previous = level;
    }
    Ok(Latency {
        frames,
        ms: worst_ms,
        transitions,
        black_level,
        white_level,
    })
}

/// A camera whose frames come out of a queue `depth` frames deep, like a driver's ring of
/// buffers: each capture takes a frame of the scene now and returns the one taken `depth`
/// captures ago. Wraps any [`Camera`]: with a camera that buffers nothing it is the stand-in that makes
/// the session's flushing and [`measure_latency`] testable.
#[derive(Debug, Clone)]
pub struct BufferedCamera<C> {
    inner: C,
    depth: usize,
    queue: VecDeque<GreyImage>,
}

impl<C: Camera> BufferedCamera<C> {
    /// Wraps `inner` behind a queue of `depth` frames (0: no delay).
    pub fn new(inner: C, depth: usize) -> Self {
        Self {
            inner,
            depth,
            queue: VecDeque::with_capacity(depth + 1),
        }
    }

    /// The queue's depth in frames.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// The wrapped camera.
    pub fn into_inner(self) -> C {
        self.inner
    }
}

impl<C: Camera> Camera for BufferedCamera<C> {
    fn frame_size(&self) -> (u32, u32) {
        self.inner.frame_size()
    }

    fn capture(&mut self) -> Result<GreyImage, RigError> {
        // The first capture fills the queue with what the camera sees now, as a driver's
        // buffers hold frames of the scene before the change.
        while self.queue.len() < self.depth {
            let frame = self.inner.capture()?;
            self.queue.push_back(frame);
        }
        let frame = self.inner.capture()?;
        self.queue.push_back(frame);
        self.queue.pop_front().ok_or_else(|| RigError::Device {
            device: "buffered camera".to_owned(),
            reason: "empty frame queue".to_owned(),
        })
    }

    fn set_exposure_ms(&mut self, exposure_ms: f64) -> Result<(), RigError> {
        self.inner.set_exposure_ms(exposure_ms)
    }

    fn exposure_ms(&self) -> Option<f64> {
        self.inner.exposure_ms()
    }
}
