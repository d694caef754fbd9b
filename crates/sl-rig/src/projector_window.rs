//! The projector as a full-screen window on a chosen monitor (feature `window`): winit for the
//! window, softbuffer to put the pattern's pixels on screen one for one.
//!
//! Display event loops belong to one thread (on macOS the main thread); the capture logic runs
//! in a worker. [`run_projector`] runs the event loop on the calling thread and the caller's
//! closure on a worker thread, handing it a [`ProjectorWindow`] (a [`Projector`]) that sends
//! each image to the event loop and waits until it is presented.

use std::cell::RefCell;
use std::num::NonZeroU32;
use std::rc::Rc;
use std::sync::mpsc;
use std::time::Duration;

use softbuffer::{Context, Surface};
use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::{ElementState, KeyEvent, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop, EventLoopProxy};
use winit::keyboard::{Key, NamedKey};
use winit::monitor::MonitorHandle;
use winit::platform::run_on_demand::EventLoopExtRunOnDemand as _;
use winit::window::{Fullscreen, Window, WindowId};

use crate::{GreyImage, Projector, RigError};

/// Default longest wait for the event loop to present one image: far above a frame time, short
/// enough that a dead display is reported rather than waited on.
pub const DEFAULT_PRESENT_TIMEOUT: Duration = Duration::from_secs(5);

/// Title of the projector window (window managers show it in their lists).
pub const PROJECTOR_WINDOW_TITLE: &str = "sl-rig projector";

/// A monitor the display server knows, as [`list_monitors`] reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct MonitorInfo {
    /// Index in the display server's order: the number `monitor` options take.
    pub index: usize,
    /// Name (`HDMI-1`, `DP-2`; `monitor N` when the server gives none).
    pub name: String,
    /// Size in physical pixels, `(width, height)`: the projector's native resolution when the
    /// display mode is set to it.
    pub size: (u32, u32),
    /// Top-left corner on the virtual desktop in physical pixels, `(x, y)`.
    pub position: (i32, i32),
    /// The desktop's scale factor for this monitor (1.0 is what a projector should have).
    pub scale_factor: f64,
    /// Refresh rate in millihertz, when known.
    pub refresh_millihertz: Option<u32>,
    /// Whether the server calls it the primary monitor.
    pub primary: bool,
}

/// `INDEX: NAME WxH at (X, Y), scale S[, R Hz][, primary]`.
impl std::fmt::Display for MonitorInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let refresh = self
            .refresh_millihertz
            .map(|r| format!(", {:.2} Hz", f64::from(r) / 1000.0))
            .unwrap_or_default();
        write!(
            f,
            "{}: {} {}x{} at ({}, {}), scale {}{refresh}{}",
            self.index,
            self.name,
            self.size.0,
            self.size.1,
            self.position.0,
            self.position.1,
            self.scale_factor,
            if self.primary { ", primary" } else { "" }
        )
    }
}

impl MonitorInfo {
    /// The monitor as JSON: index, name, size, position, scale factor, primary.
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "index": self.index, "name": self.name, "size": self.size, "position": self.position,
            "scale_factor": self.scale_factor, "primary": self.primary,
        })
    }
}

/// How [`run_projector`] opens the projector window.
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectorWindowConfig {
    /// Index of the monitor (as [`list_monitors`] numbers them). Default 0.
    pub monitor: usize,
    /// The size the projector must have, `(width, height)`; `None` takes the monitor's. When
    /// set and different, opening fails instead of showing scaled patterns.
    pub expected_size: Option<(u32, u32)>,
    /// Longest wait for one image to be presented. Default [`DEFAULT_PRESENT_TIMEOUT`].
    pub present_timeout: Duration,
}

impl Default for ProjectorWindowConfig {
    fn default() -> Self {
        Self {
            monitor: 0,
            expected_size: None,
            present_timeout: DEFAULT_PRESENT_TIMEOUT,
        }
    }
}

/// What the worker asks of the event loop.
enum Request {
    /// Present this image, then answer.
    Show(GreyImage, mpsc::Sender<Result<(), RigError>>),
    /// The worker has finished (sent from a drop guard, so also when it panics).
    Done,
}

thread_local! {
    /// The display's event loop. winit makes one per process and it stays on the thread that
    /// made it; kept here, it serves every [`run_projector`] and [`list_monitors`] call made
    /// from that thread.
    static EVENT_LOOP: RefCell<Option<EventLoop<Request>>> = const { RefCell::new(None) };
}

fn display_err(reason: impl Into<String>) -> RigError {
    RigError::Device {
        device: "projector window".to_owned(),
        reason: reason.into(),
    }
}

/// Runs `f` with this thread's event loop, creating it at the first call.
fn with_event_loop<R>(f: impl FnOnce(&mut EventLoop<Request>) -> R) -> Result<R, RigError> {
    EVENT_LOOP.with(|cell| {
        let mut slot = cell.borrow_mut();
        if slot.is_none() {
            let mut builder = EventLoop::<Request>::with_user_event();
            // X11 and Wayland can run the loop on any thread (tests, workers); other systems
            // need the main thread.
            #[cfg(target_os = "linux")]
            winit::platform::x11::EventLoopBuilderExtX11::with_any_thread(&mut builder, true);
            let event_loop = builder.build().map_err(|e| match e {
                winit::error::EventLoopError::RecreationAttempt => display_err(
                    "another thread of this process already holds the display's event loop \
                     (winit allows one per process): call from that thread",
                ),
                e => display_err(format!(
                    "cannot open the display ({e}); is DISPLAY or WAYLAND_DISPLAY set?"
                )),
            })?;
            *slot = Some(event_loop);
        }
        match slot.as_mut() {
            Some(event_loop) => Ok(f(event_loop)),
            None => Err(display_err("no event loop")),
        }
    })
}

fn monitor_info(
    index: usize,
    handle: &MonitorHandle,
    primary: Option<&MonitorHandle>,
) -> MonitorInfo {
    let size = handle.size();
    let position = handle.position();
    MonitorInfo {
        index,
        name: handle.name().unwrap_or_else(|| format!("monitor {index}")),
        size: (size.width, size.height),
        position: (position.x, position.y),
        scale_factor: handle.scale_factor(),
        refresh_millihertz: handle.refresh_rate_millihertz(),
        primary: primary == Some(handle),
    }
}

fn monitors_of(event_loop: &ActiveEventLoop) -> (Vec<MonitorInfo>, Vec<MonitorHandle>) {
    let primary = event_loop.primary_monitor();
    let handles: Vec<MonitorHandle> = event_loop.available_monitors().collect();
    let infos = handles
        .iter()
        .enumerate()
        .map(|(i, h)| monitor_info(i, h, primary.as_ref()))
        .collect();
    (infos, handles)
}

/// The monitors of the display (`$DISPLAY` or `$WAYLAND_DISPLAY`), in the server's order.
///
/// Uses the calling thread's display event loop (see [`run_projector`]): call it from the
/// thread that will run the projector.
///
/// # Errors
/// [`RigError::Device`] when there is no display to connect to, or when another thread of
/// the process already holds the display.
pub fn list_monitors() -> Result<Vec<MonitorInfo>, RigError> {
    let (result, monitors) = with_event_loop(|event_loop| {
        let mut probe = MonitorProbe(None);
        let result = event_loop.run_app_on_demand(&mut probe);
        (result, probe.0)
    })?;
    result.map_err(|e| display_err(format!("event loop: {e}")))?;
    monitors.ok_or_else(|| display_err("the display never became active"))
}

/// Reads the monitors at the first chance and stops: winit lists monitors only from inside
/// its running event loop.
struct MonitorProbe(Option<Vec<MonitorInfo>>);

impl ApplicationHandler<Request> for MonitorProbe {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        self.0 = Some(monitors_of(event_loop).0);
        event_loop.exit();
    }

    fn window_event(&mut self, _: &ActiveEventLoop, _: WindowId, _: WindowEvent) {}
}

/// The worker's handle on the projector window: a [`Projector`] that shows grey images full
/// screen, pixel for pixel.
#[derive(Debug)]
pub struct ProjectorWindow {
    proxy: EventLoopProxy<Request>,
    size: (u32, u32),
    monitor: MonitorInfo,
    monitors: Vec<MonitorInfo>,
    timeout: Duration,
}

impl ProjectorWindow {
    /// The monitor the window covers.
    pub fn monitor(&self) -> &MonitorInfo {
        &self.monitor
    }

    /// Every monitor of the display.
    pub fn monitors(&self) -> &[MonitorInfo] {
        &self.monitors
    }
}

impl Projector for ProjectorWindow {
    fn image_size(&self) -> (u32, u32) {
        self.size
    }

    /// Sends `image` to the event loop and returns once it has been handed to the display
    /// server (softbuffer's present). The projector shows it after the display's latency,
    /// which this call does not wait for.
    fn show(&mut self, image: &GreyImage) -> Result<(), RigError> {
        check_size(image, self.size)?;
        let (tx, rx) = mpsc::channel();
        self.proxy
            .send_event(Request::Show(image.clone(), tx))
            .map_err(|_| display_err("the event loop has stopped"))?;
        match rx.recv_timeout(self.timeout) {
            Ok(result) => result,
            Err(mpsc::RecvTimeoutError::Timeout) => Err(display_err(format!(
                "the image was not presented within {:?}",
                self.timeout
            ))),
            Err(mpsc::RecvTimeoutError::Disconnected) => Err(display_err("the window was closed")),
        }
    }
}

/// Sends [`Request::Done`] when dropped: the worker's end, normal or by panic.
struct DoneGuard(EventLoopProxy<Request>);

impl Drop for DoneGuard {
    fn drop(&mut self) {
        // The loop may be gone already (it then has nothing left to stop).
        let _ = self.0.send_event(Request::Done);
    }
}

type Work<T> = Box<dyn FnOnce(ProjectorWindow) -> Result<T, RigError> + Send>;

/// The event-loop side: the window, its softbuffer surface and the image shown.
struct App<T: Send + 'static> {
    config: ProjectorWindowConfig,
    proxy: EventLoopProxy<Request>,
    monitors: Vec<MonitorInfo>,
    handles: Vec<MonitorHandle>,
    window: Option<Rc<Window>>,
    surface: Option<Surface<Rc<Window>, Rc<Window>>>,
    /// The image shown, as softbuffer's `0RGB` words.
    shown: Vec<u32>,
    shown_size: (u32, u32),
    work: Option<Work<T>>,
    worker: Option<std::thread::JoinHandle<Result<T, RigError>>>,
    /// Set when opening fails or the window is closed; later requests get it.
    failure: Option<RigError>,
}

impl<T: Send + 'static> App<T> {
    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<(), RigError> {
        let Some(handle) = self.handles.get(self.config.monitor).cloned() else {
            return Err(RigError::param(
                "monitor",
                format!(
                    "monitor {} does not exist; the display has {}",
                    self.config.monitor,
                    self.monitors.len()
                ),
            ));
        };
        let size = handle.size();
        if let Some((w, h)) = self.config.expected_size
            && (w, h) != (size.width, size.height)
        {
            return Err(RigError::param(
                "monitor",
                format!(
                    "monitor {} is {}x{}, the projector must be {w}x{h}: set the display \
                     mode to the projector's native resolution",
                    self.config.monitor, size.width, size.height
                ),
            ));
        }
        let position = handle.position();
        // Position and size are set as well as the full-screen hint: without a window manager
        // (Xvfb, a bare X server on the scanner) the hint does nothing.
        let attributes = Window::default_attributes()
            .with_title(PROJECTOR_WINDOW_TITLE)
            .with_decorations(false)
            .with_resizable(false)
            .with_position(PhysicalPosition::new(position.x, position.y))
            .with_inner_size(PhysicalSize::new(size.width, size.height))
            .with_fullscreen(Some(Fullscreen::Borderless(Some(handle))));
        let window = Rc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| display_err(format!("cannot create the window: {e}")))?,
        );
        window.set_cursor_visible(false);
        let context = Context::new(Rc::clone(&window))
            .map_err(|e| display_err(format!("softbuffer: {e}")))?;
        let surface = Surface::new(&context, Rc::clone(&window))
            .map_err(|e| display_err(format!("softbuffer: {e}")))?;
        self.shown = vec![0; size.width as usize * size.height as usize];
        self.shown_size = (size.width, size.height);
        self.window = Some(window);
        self.surface = Some(surface);
        Ok(())
    }

    /// Puts `self.shown` on screen, one buffer pixel per window pixel.
    fn present(&mut self) -> Result<(), RigError> {
        let (Some(window), Some(surface)) = (&self.window, &mut self.surface) else {
            return Err(display_err("the window is not open"));
        };
        let inner = window.inner_size();
        if (inner.width, inner.height) != self.shown_size {
            return Err(display_err(format!(
                "the window is {}x{}, not the monitor's {}x{}: the window manager resized it \
                 (patterns are never scaled)",
                inner.width, inner.height, self.shown_size.0, self.shown_size.1
            )));
        }
        let (Some(w), Some(h)) = (NonZeroU32::new(inner.width), NonZeroU32::new(inner.height))
        else {
            return Err(display_err("the window has no pixel"));
        };
        let soft = |e: softbuffer::SoftBufferError| display_err(format!("softbuffer: {e}"));
        surface.resize(w, h).map_err(soft)?;
        let mut buffer = surface.buffer_mut().map_err(soft)?;
        buffer.copy_from_slice(&self.shown);
        buffer.present().map_err(soft)
    }

    fn start_worker(&mut self) {
        let Some(work) = self.work.take() else {
            return;
        };
        let monitor = self.monitors.get(self.config.monitor).cloned();
        let Some(monitor) = monitor else {
            return;
        };
        let handle = ProjectorWindow {
            proxy: self.proxy.clone(),
            size: self.shown_size,
            monitor,
            monitors: self.monitors.clone(),
            timeout: self.config.present_timeout,
        };
        let guard = DoneGuard(self.proxy.clone());
        self.worker = Some(std::thread::spawn(move || {
            let _guard = guard;
            work(handle)
        }));
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, reason: RigError) {
        self.failure = Some(reason);
        self.surface = None;
        self.window = None;
        if self.worker.is_none() {
            // The worker never started: nothing else will end the loop.
            self.work = None;
            event_loop.exit();
        }
    }
}

/// Refuses an image of another size than the window's: patterns are never scaled.
fn check_size(image: &GreyImage, (width, height): (u32, u32)) -> Result<(), RigError> {
    let size = image.size();
    if (size.width, size.height) == (width, height) {
        return Ok(());
    }
    Err(RigError::ImageSize {
        what: "projector image".to_owned(),
        expected_width: width,
        expected_height: height,
        width: size.width,
        height: size.height,
    })
}

/// softbuffer's `0RGB` word for a grey value (16-bit images keep their high byte: the
/// display takes 8 bits).
fn grey_words(image: &GreyImage) -> Vec<u32> {
    let word = |v: u8| u32::from(v) * 0x0001_0101;
    match image {
        GreyImage::U8(f) => f.data().iter().map(|&p| word(p)).collect(),
        GreyImage::U16(f) => f.data().iter().map(|&p| word(p.to_be_bytes()[0])).collect(),
    }
}

impl<T: Send + 'static> ApplicationHandler<Request> for App<T> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() || self.work.is_none() {
            return;
        }
        (self.monitors, self.handles) = monitors_of(event_loop);
        if let Err(e) = self.open(event_loop) {
            self.fail(event_loop, e);
            return;
        }
        if let Some(window) = &self.window {
            window.request_redraw();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.present() {
                    self.fail(event_loop, e);
                    return;
                }
                // The first redraw means the window is mapped: the worker may start.
                self.start_worker();
            }
            WindowEvent::CloseRequested
            | WindowEvent::KeyboardInput {
                event:
                    KeyEvent {
                        logical_key: Key::Named(NamedKey::Escape),
                        state: ElementState::Pressed,
                        ..
                    },
                ..
            } => self.fail(event_loop, display_err("the window was closed")),
            _ => {}
        }
    }

    fn user_event(&mut self, event_loop: &ActiveEventLoop, request: Request) {
        match request {
            Request::Show(image, answer) => {
                let result = match &self.failure {
                    Some(reason) => Err(display_err(reason.to_string())),
                    None => check_size(&image, self.shown_size).and_then(|()| {
                        self.shown = grey_words(&image);
                        self.present()
                    }),
                };
                // The worker may have given up waiting; nothing to do then.
                let _ = answer.send(result);
            }
            Request::Done => {
                self.surface = None;
                self.window = None;
                event_loop.exit();
            }
        }
    }
}

/// Opens the projector window on the monitor of `config`, runs the display's event loop on
/// the calling thread, and runs `work` on a worker thread with a [`ProjectorWindow`]; returns
/// what `work` returns once it has finished and the window has closed.
///
/// The window covers the monitor without decorations, cursor or scaling: pixel `(x, y)` of a
/// shown image is pixel `(x, y)` of the monitor. It shows black until the first image.
/// Escape or the window manager's close ends the window; `work`'s next `show` then fails.
///
/// Threads: on Linux (X11, Wayland) any thread may call this, but one thread per process
/// (the display's event loop stays on the thread that first used it; [`list_monitors`] uses
/// the same). On macOS it must be the main thread.
///
/// # Errors
/// [`RigError::Device`] when there is no display, the window cannot be created or closes, or
/// the worker panics; [`RigError::InvalidParameter`] for a monitor that does not exist or has
/// another size than [`ProjectorWindowConfig::expected_size`]; and whatever `work` returns.
///
/// ```no_run
/// use sl_rig::{GreyImage, Projector, ProjectorWindowConfig, run_projector};
/// # fn main() -> Result<(), sl_rig::RigError> {
/// let (w, h) = run_projector(ProjectorWindowConfig::default(), |mut projector| {
///     let (w, h) = projector.image_size();
///     projector.show(&GreyImage::filled_u8(w as usize, h as usize, 255)?)?; // full white
///     Ok((w, h))
/// })?;
/// println!("the projector is {w}x{h}");
/// # Ok(())
/// # }
/// ```
pub fn run_projector<T, F>(config: ProjectorWindowConfig, work: F) -> Result<T, RigError>
where
    T: Send + 'static,
    F: FnOnce(ProjectorWindow) -> Result<T, RigError> + Send + 'static,
{
    let run = with_event_loop(|event_loop| {
        let mut app = App {
            config,
            proxy: event_loop.create_proxy(),
            monitors: Vec::new(),
            handles: Vec::new(),
            window: None,
            surface: None,
            shown: Vec::new(),
            shown_size: (0, 0),
            work: Some(Box::new(work)),
            worker: None,
            failure: None,
        };
        let result = event_loop.run_app_on_demand(&mut app);
        (result, app.worker.take(), app.failure.take())
    })?;
    let (result, worker, failure) = run;
    result.map_err(|e| display_err(format!("event loop: {e}")))?;
    match worker {
        Some(handle) => handle
            .join()
            .unwrap_or_else(|_| Err(display_err("the projector worker panicked"))),
        None => Err(failure.unwrap_or_else(|| display_err("the window never opened"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_words_replicate_the_grey_value() {
        let img = GreyImage::U8(sl_image::Frame::new(3, 1, vec![0, 0x80, 0xFF]).unwrap());
        assert_eq!(grey_words(&img), vec![0, 0x0080_8080, 0x00FF_FFFF]);
        let img = GreyImage::U16(sl_image::Frame::new(2, 1, vec![0x12FF, 0xFFFF]).unwrap());
        assert_eq!(grey_words(&img), vec![0x0012_1212, 0x00FF_FFFF]);
    }
}
