//! A V4L2 camera (feature `v4l`): device enumeration, format and controls, memory-mapped
//! streaming, and the flush that drops the frames buffered before a projector change.

use std::path::{Path, PathBuf};
use std::time::Duration;

use v4l::buffer::Type as BufferType;
use v4l::capability::Flags as CapabilityFlags;
use v4l::control::{Control, Value};
use v4l::framesize::FrameSizeEnum;
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture as _;
use v4l::{Device, Format, FourCC};

use crate::v4l_camera_controls::{
    CID_AUTO_WHITE_BALANCE, CID_AUTOGAIN, CID_EXPOSURE_ABSOLUTE, CID_EXPOSURE_AUTO,
    CID_EXPOSURE_AUTO_PRIORITY, CID_GAIN, CID_WHITE_BALANCE_TEMPERATURE, ControlKey,
    EXPOSURE_MANUAL, exposure_ms_to_v4l,
};
use crate::{
    Camera, ColourImage, FrameLayout, GreyImage, PixelFormat, RigError, convert_frame,
    convert_frame_colour,
};

/// Default number of driver buffers. Two is the fewest that streams without dropping frames,
/// and the fewer buffers, the fewer stale frames a flush has to drain.
pub const DEFAULT_V4L_BUFFERS: u32 = 2;

/// Default number of frames dropped after the drain (see [`V4lCamera::flush`]): the frame
/// being exposed while the projector changed. UVC webcams that pipeline frames inside the
/// camera may need 2; measure it (see `docs/hardware-camera-projector.md`).
pub const DEFAULT_IN_FLIGHT_FRAMES: u32 = 1;

/// Default time to wait for one frame: long enough for a 1 s exposure plus transfer.
pub const DEFAULT_FRAME_TIMEOUT: Duration = Duration::from_secs(3);

/// Bound on the frames the drain of a flush dequeues without waiting: a camera cannot have
/// more frames ready than it has buffers, so this bound is never met unless the driver misbehaves.
const MAX_DRAINED_PER_BUFFER: u32 = 2;

/// One pixel format a V4L2 device offers, with its frame sizes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct V4lFormatInfo {
    /// The four-character code, trailing spaces removed (`YUYV`, `MJPG`, `NV12`, ...).
    pub fourcc: String,
    /// The driver's description (`YUYV 4:2:2`).
    pub description: String,
    /// The format as this crate converts it, `None` when it cannot.
    pub pixel_format: Option<PixelFormat>,
    /// Frame sizes `(width, height)`: every size of a discrete list, or the smallest and the
    /// largest of a stepwise range.
    pub sizes: Vec<(u32, u32)>,
}

/// A V4L2 capture device found by [`list_v4l_cameras`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct V4lDeviceInfo {
    /// Device node, e.g. `/dev/video0`.
    pub path: PathBuf,
    /// Card name (`HD Pro Webcam C920`); empty when the device could not be opened.
    pub name: String,
    /// Driver (`uvcvideo`).
    pub driver: String,
    /// Bus (`usb-0000:00:14.0-1`).
    pub bus: String,
    /// Pixel formats with their sizes.
    pub formats: Vec<V4lFormatInfo>,
    /// Why the device could not be queried (e.g. permission denied), when it could not.
    pub error: Option<String>,
}

/// `PATH: NAME (driver DRIVER, BUS)` and a line per format, `    FOURCC (DESCRIPTION): SIZES`
/// (`[not converted]` for a format this crate cannot convert); `PATH: cannot open: WHY` for a
/// device that could not be queried.
impl std::fmt::Display for V4lDeviceInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(err) = &self.error {
            return write!(f, "{}: cannot open: {err}", self.path.display());
        }
        write!(
            f,
            "{}: {} (driver {}, {})",
            self.path.display(),
            self.name,
            self.driver,
            self.bus
        )?;
        for format in &self.formats {
            let sizes: Vec<String> = format
                .sizes
                .iter()
                .map(|(w, h)| format!("{w}x{h}"))
                .collect();
            let usable = if format.pixel_format.is_some() {
                ""
            } else {
                " [not converted]"
            };
            write!(
                f,
                "\n    {} ({}){usable}: {}",
                format.fourcc,
                format.description,
                sizes.join(" ")
            )?;
        }
        Ok(())
    }
}

impl V4lDeviceInfo {
    /// The device as JSON: path, name, driver, error and each format's code and sizes.
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "path": self.path.display().to_string(),
            "name": self.name,
            "driver": self.driver,
            "error": self.error,
            "formats": self.formats.iter().map(|f| serde_json::json!({
                "fourcc": f.fourcc, "sizes": f.sizes,
            })).collect::<Vec<_>>(),
        })
    }
}

/// The video capture devices among `/dev/video*`, in numeric order.
///
/// Nodes that are not video capture devices (a UVC camera's metadata node, an output or a
/// codec) are left out; a node that cannot be opened is listed with its [`V4lDeviceInfo::error`].
///
/// # Errors
/// [`RigError::Io`] when `/dev` cannot be read.
pub fn list_v4l_cameras() -> Result<Vec<V4lDeviceInfo>, RigError> {
    list_v4l_cameras_in(Path::new("/dev"))
}

fn list_v4l_cameras_in(dev: &Path) -> Result<Vec<V4lDeviceInfo>, RigError> {
    let entries = std::fs::read_dir(dev).map_err(|e| RigError::io(dev, e))?;
    let mut nodes: Vec<(u32, PathBuf)> = entries
        .filter_map(Result::ok)
        .filter_map(|entry| {
            let name = entry.file_name();
            let index = name.to_str()?.strip_prefix("video")?.parse().ok()?;
            Some((index, entry.path()))
        })
        .collect();
    nodes.sort();
    let mut out = Vec::new();
    for (_, path) in nodes {
        match query_device(&path) {
            Ok(Some(info)) => out.push(info),
            Ok(None) => {}
            Err(e) => out.push(V4lDeviceInfo {
                path,
                name: String::new(),
                driver: String::new(),
                bus: String::new(),
                formats: Vec::new(),
                error: Some(e.to_string()),
            }),
        }
    }
    Ok(out)
}

/// Capabilities and formats of one node; `None` when it is not a video capture device.
fn query_device(path: &Path) -> std::io::Result<Option<V4lDeviceInfo>> {
    let device = Device::with_path(path)?;
    let caps = device.query_caps()?;
    if !caps.capabilities.contains(CapabilityFlags::VIDEO_CAPTURE) {
        return Ok(None);
    }
    let mut formats = Vec::new();
    for desc in device.enum_formats()? {
        let sizes = device
            .enum_framesizes(desc.fourcc)
            .unwrap_or_default()
            .into_iter()
            .flat_map(|size| match size.size {
                FrameSizeEnum::Discrete(d) => vec![(d.width, d.height)],
                FrameSizeEnum::Stepwise(s) => {
                    vec![(s.min_width, s.min_height), (s.max_width, s.max_height)]
                }
            })
            .collect();
        formats.push(V4lFormatInfo {
            fourcc: fourcc_text(desc.fourcc),
            description: desc.description,
            pixel_format: PixelFormat::from_fourcc(desc.fourcc.repr),
            sizes,
        });
    }
    Ok(Some(V4lDeviceInfo {
        path: path.to_path_buf(),
        name: caps.card,
        driver: caps.driver,
        bus: caps.bus,
        formats,
        error: None,
    }))
}

fn fourcc_text(code: FourCC) -> String {
    String::from_utf8_lossy(&code.repr).trim_end().to_owned()
}

/// How to open a [`V4lCamera`].
#[derive(Debug, Clone, PartialEq)]
pub struct V4lCameraConfig {
    /// Device node. Default `/dev/video0`.
    pub path: PathBuf,
    /// Frame width in pixels. Default 1280.
    pub width: u32,
    /// Frame height in pixels. Default 720.
    pub height: u32,
    /// Pixel format asked of the driver. Default [`PixelFormat::Yuyv`], the uncompressed
    /// format every UVC webcam offers (MJPG blurs stripe edges).
    pub pixel_format: PixelFormat,
    /// Number of memory-mapped driver buffers. Default [`DEFAULT_V4L_BUFFERS`].
    pub buffers: u32,
    /// Manual exposure time in milliseconds (auto exposure is turned off); `None` leaves the
    /// camera's setting. Structured light needs it fixed: auto exposure follows the patterns.
    pub exposure_ms: Option<f64>,
    /// Manual gain in the driver's units (auto gain is turned off); `None` leaves it.
    pub gain: Option<i64>,
    /// White balance temperature in kelvin (auto white balance is turned off); `None` leaves
    /// it. It matters for colour cameras whose grey is computed from white-balanced colour.
    pub white_balance_kelvin: Option<i64>,
    /// Further controls set after the above, by name or id (see [`ControlKey`]), e.g.
    /// `("power_line_frequency", 0)`.
    pub controls: Vec<(String, i64)>,
    /// Frames dropped after the drain of a flush. Default [`DEFAULT_IN_FLIGHT_FRAMES`].
    pub in_flight_frames: u32,
    /// Whether [`Camera::capture`] flushes first, so that each captured frame was exposed
    /// entirely after the call (the structured-light case: a capture follows a projector
    /// change). Default `true`.
    pub flush_before_capture: bool,
    /// Longest wait for one frame. Default [`DEFAULT_FRAME_TIMEOUT`].
    pub timeout: Duration,
}

impl Default for V4lCameraConfig {
    fn default() -> Self {
        Self {
            path: PathBuf::from("/dev/video0"),
            width: 1280,
            height: 720,
            pixel_format: PixelFormat::Yuyv,
            buffers: DEFAULT_V4L_BUFFERS,
            exposure_ms: None,
            gain: None,
            white_balance_kelvin: None,
            controls: Vec::new(),
            in_flight_frames: DEFAULT_IN_FLIGHT_FRAMES,
            flush_before_capture: true,
            timeout: DEFAULT_FRAME_TIMEOUT,
        }
    }
}

/// One control of a V4L2 device, as [`V4lCamera::controls`] lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct V4lControlInfo {
    /// Control id.
    pub id: u32,
    /// Driver's name (`Exposure Time, Absolute`).
    pub name: String,
    /// Smallest value.
    pub minimum: i64,
    /// Largest value.
    pub maximum: i64,
    /// Step between values.
    pub step: u64,
    /// Default value.
    pub default: i64,
}

/// A V4L2 camera streaming through memory-mapped buffers, converting frames to grey.
///
/// Opening sets the format and the controls of [`V4lCameraConfig`]; streaming starts at the
/// first capture. See [`V4lCamera::flush`] for the frames it drops.
pub struct V4lCamera {
    // Declared before `device`: the stream stops and unmaps before the device closes.
    stream: Stream<'static>,
    device: Device,
    config: V4lCameraConfig,
    layout: FrameLayout,
    streaming: bool,
    frames: u64,
}

impl std::fmt::Debug for V4lCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V4lCamera")
            .field("config", &self.config)
            .field("layout", &self.layout)
            .field("streaming", &self.streaming)
            .field("frames", &self.frames)
            .finish_non_exhaustive()
    }
}

impl V4lCamera {
    /// Opens the device, sets its format and controls and maps its buffers.
    ///
    /// # Errors
    /// [`RigError::Device`] naming the device when it cannot be opened, refuses the format or
    /// size (the message lists what it offers), or lacks a control;
    /// [`RigError::InvalidParameter`] for a value out of a control's range.
    pub fn open(config: V4lCameraConfig) -> Result<Self, RigError> {
        let path = config.path.clone();
        let device =
            Device::with_path(&path).map_err(|e| dev_err(&path, format!("cannot open: {e}")))?;
        let caps = device
            .query_caps()
            .map_err(|e| dev_err(&path, format!("cannot query capabilities: {e}")))?;
        if !caps.capabilities.contains(CapabilityFlags::VIDEO_CAPTURE) {
            return Err(dev_err(&path, "not a video capture device".to_owned()));
        }
        if !caps.capabilities.contains(CapabilityFlags::STREAMING) {
            return Err(dev_err(&path, "does not support streaming I/O".to_owned()));
        }
        if config.buffers == 0 {
            return Err(RigError::param("buffers", "at least one buffer is needed"));
        }
        let wanted = Format::new(
            config.width,
            config.height,
            FourCC::new(&config.pixel_format.fourcc()),
        );
        let got = device
            .set_format(&wanted)
            .map_err(|e| dev_err(&path, format!("cannot set the format: {e}")))?;
        if got.fourcc != wanted.fourcc || got.width != wanted.width || got.height != wanted.height {
            return Err(dev_err(
                &path,
                format!(
                    "asked for {}x{} {}, the driver chose {}x{} {}; offered: {}",
                    config.width,
                    config.height,
                    config.pixel_format,
                    got.width,
                    got.height,
                    fourcc_text(got.fourcc),
                    offered_formats(&path)
                ),
            ));
        }
        let layout = FrameLayout {
            format: config.pixel_format,
            width: got.width,
            height: got.height,
            stride: got.stride,
        };
        let stream = Stream::with_buffers(&device, BufferType::VideoCapture, config.buffers)
            .map_err(|e| dev_err(&path, format!("cannot map {} buffers: {e}", config.buffers)))?;
        let mut camera = Self {
            stream,
            device,
            config,
            layout,
            streaming: false,
            frames: 0,
        };
        camera.apply_controls()?;
        let timeout = camera.config.timeout;
        camera.stream.set_timeout(timeout);
        Ok(camera)
    }

    /// The configuration the camera was opened with.
    pub fn config(&self) -> &V4lCameraConfig {
        &self.config
    }

    /// The layout of the raw frames (format, size, bytes per line).
    pub fn layout(&self) -> FrameLayout {
        self.layout
    }

    /// Auto exposure off (and its frame-rate priority), then the exposure time `ms`.
    fn apply_exposure(&mut self, controls: &[V4lControlInfo], ms: f64) -> Result<(), RigError> {
        let has = |id: u32| controls.iter().any(|c| c.id == id);
        let units = exposure_ms_to_v4l(ms)?;
        if has(CID_EXPOSURE_AUTO) {
            self.set_control_id(controls, CID_EXPOSURE_AUTO, EXPOSURE_MANUAL, "exposure_ms")?;
        }
        if has(CID_EXPOSURE_AUTO_PRIORITY) {
            self.set_control_id(controls, CID_EXPOSURE_AUTO_PRIORITY, 0, "exposure_ms")?;
        }
        self.set_control_id(controls, CID_EXPOSURE_ABSOLUTE, units, "exposure_ms")
    }

    fn apply_controls(&mut self) -> Result<(), RigError> {
        let controls = self.controls()?;
        let has = |id: u32| controls.iter().any(|c| c.id == id);
        if let Some(ms) = self.config.exposure_ms {
            self.apply_exposure(&controls, ms)?;
        }
        if let Some(gain) = self.config.gain {
            if has(CID_AUTOGAIN) {
                self.set_control_id(&controls, CID_AUTOGAIN, 0, "gain")?;
            }
            self.set_control_id(&controls, CID_GAIN, gain, "gain")?;
        }
        if let Some(kelvin) = self.config.white_balance_kelvin {
            if has(CID_AUTO_WHITE_BALANCE) {
                self.set_control_id(&controls, CID_AUTO_WHITE_BALANCE, 0, "white_balance_kelvin")?;
            }
            self.set_control_id(
                &controls,
                CID_WHITE_BALANCE_TEMPERATURE,
                kelvin,
                "white_balance_kelvin",
            )?;
        }
        for (key, value) in self.config.controls.clone() {
            self.set_control(&key, value)?;
        }
        Ok(())
    }

    fn set_control_id(
        &self,
        controls: &[V4lControlInfo],
        id: u32,
        value: i64,
        parameter: &str,
    ) -> Result<(), RigError> {
        let Some(info) = controls.iter().find(|c| c.id == id) else {
            return Err(dev_err(
                &self.config.path,
                format!(
                    "`{parameter}` needs control {id:#010x}, which the camera does not have; it has: {}",
                    control_names(controls)
                ),
            ));
        };
        self.write_control(info, value)
    }

    fn write_control(&self, info: &V4lControlInfo, value: i64) -> Result<(), RigError> {
        if value < info.minimum || value > info.maximum {
            return Err(RigError::param(
                format!("control `{}`", info.name),
                format!(
                    "{value} is outside [{}, {}] on {}",
                    info.minimum,
                    info.maximum,
                    self.config.path.display()
                ),
            ));
        }
        self.device
            .set_control(Control {
                id: info.id,
                value: Value::Integer(value),
            })
            .map_err(|e| {
                dev_err(
                    &self.config.path,
                    format!("cannot set control `{}` to {value}: {e}", info.name),
                )
            })
    }

    /// The integer, boolean and menu controls of the device.
    ///
    /// # Errors
    /// [`RigError::Device`] when the driver cannot list them.
    pub fn controls(&self) -> Result<Vec<V4lControlInfo>, RigError> {
        let list = self
            .device
            .query_controls()
            .map_err(|e| dev_err(&self.config.path, format!("cannot list controls: {e}")))?;
        Ok(list
            .into_iter()
            .filter(|d| {
                use v4l::control::Type;
                matches!(
                    d.typ,
                    Type::Integer
                        | Type::Integer64
                        | Type::Boolean
                        | Type::Menu
                        | Type::IntegerMenu
                )
            })
            .map(|d| V4lControlInfo {
                id: d.id,
                name: d.name,
                minimum: d.minimum,
                maximum: d.maximum,
                step: d.step,
                default: d.default,
            })
            .collect())
    }

    /// Sets the control named `key` (a name or an id, see [`ControlKey`]) to `value`.
    ///
    /// # Errors
    /// [`RigError::Device`] when the camera has no such control (the message lists those it
    /// has) or refuses the value; [`RigError::InvalidParameter`] when `value` is out of range.
    pub fn set_control(&mut self, key: &str, value: i64) -> Result<(), RigError> {
        let info = self.find_control(key)?;
        self.write_control(&info, value)
    }

    /// The control named `key`, or an error listing the controls the camera has.
    fn find_control(&self, key: &str) -> Result<V4lControlInfo, RigError> {
        let mut controls = self.controls()?;
        let parsed = ControlKey::parse(key);
        match controls.iter().position(|c| parsed.matches(c.id, &c.name)) {
            Some(i) => Ok(controls.swap_remove(i)),
            None => Err(dev_err(
                &self.config.path,
                format!(
                    "no control `{key}`; the camera has: {}",
                    control_names(&controls)
                ),
            )),
        }
    }

    /// The value of the control named `key`.
    ///
    /// # Errors
    /// [`RigError::Device`] when the camera has no such control or cannot read it.
    pub fn control(&self, key: &str) -> Result<i64, RigError> {
        let info = self.find_control(key)?;
        let control = self.device.control(info.id).map_err(|e| {
            dev_err(
                &self.config.path,
                format!("cannot read control `{}`: {e}", info.name),
            )
        })?;
        match control.value {
            Value::Integer(v) => Ok(v),
            Value::Boolean(b) => Ok(i64::from(b)),
            other => Err(dev_err(
                &self.config.path,
                format!("control `{}` has a non-integer value {other:?}", info.name),
            )),
        }
    }

    /// Drops every frame whose exposure may have begun before this call.
    ///
    /// The choice: **count, not timestamps**. First the frames the driver already filled are
    /// dequeued without waiting (the *drain*); then the next
    /// [`in_flight_frames`](V4lCameraConfig::in_flight_frames) frames are dropped: those being
    /// exposed or transferred when this was called. Driver timestamps are not used because
    /// what they mark (start or end of exposure, or the USB transfer for UVC) differs between
    /// drivers, and a wrong guess keeps a stale frame silently; counting costs at most
    /// `in_flight_frames` frame times and is right for any driver once `in_flight_frames` is.
    ///
    /// The display's own latency (the projector showing the new image some milliseconds after
    /// the window presented it) is not the camera's to know: wait for it *before* flushing.
    ///
    /// # Errors
    /// [`RigError::Device`] when the driver fails or no frame comes within the timeout.
    pub fn flush(&mut self) -> Result<(), RigError> {
        if !self.streaming {
            // Nothing is buffered before the stream starts: the first frame comes after now.
            return Ok(());
        }
        let path = self.config.path.clone();
        self.stream.set_timeout(Duration::ZERO);
        let mut waiting_dequeue = false;
        for _ in 0..self.config.buffers.saturating_mul(MAX_DRAINED_PER_BUFFER) {
            match self.stream.next() {
                Ok(_) => self.frames += 1,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                    // `next` re-queued the previous buffer and found nothing ready.
                    waiting_dequeue = true;
                    break;
                }
                Err(e) => {
                    self.stream.set_timeout(self.config.timeout);
                    return Err(dev_err(&path, format!("drain failed: {e}")));
                }
            }
        }
        self.stream.set_timeout(self.config.timeout);
        let mut to_skip = self.config.in_flight_frames;
        if waiting_dequeue {
            // Complete the interrupted `next`: dequeue (and drop) the frame in flight, so that
            // the stream's bookkeeping is consistent again.
            CaptureStream::dequeue(&mut self.stream).map_err(|e| {
                dev_err(
                    &path,
                    format!("no frame within {:?}: {e}", self.config.timeout),
                )
            })?;
            self.frames += 1;
            to_skip = to_skip.saturating_sub(1);
        }
        for _ in 0..to_skip {
            self.next_raw()?;
        }
        Ok(())
    }

    /// The next frame the driver delivers, converted to grey, without flushing.
    ///
    /// # Errors
    /// [`RigError::Device`] when the driver fails or times out; [`RigError::FrameData`] when
    /// the frame's bytes do not convert.
    pub fn next_frame(&mut self) -> Result<GreyImage, RigError> {
        self.next_converted(convert_frame)
    }

    /// The next frame the driver delivers, converted to colour ([`convert_frame_colour`]:
    /// YUYV by BT.601's limited range as OpenCV does, MJPG decoded, RGB3/BGR3 as they are, a
    /// grey format grey in the three channels), without flushing.
    ///
    /// # Errors
    /// As [`V4lCamera::next_frame`].
    pub fn next_colour_frame(&mut self) -> Result<ColourImage, RigError> {
        self.next_converted(convert_frame_colour)
    }

    /// The next frame the driver delivers, converted by `convert`.
    fn next_converted<T>(
        &mut self,
        convert: impl FnOnce(&[u8], &FrameLayout, &str) -> Result<T, RigError>,
    ) -> Result<T, RigError> {
        let what = format!("{} frame {}", self.config.path.display(), self.frames);
        let layout = self.layout;
        let path = self.config.path.clone();
        self.streaming = true;
        let (data, meta) = self
            .stream
            .next()
            .map_err(|e| dev_err(&path, format!("no frame: {e}")))?;
        self.frames += 1;
        let used = usize::try_from(meta.bytesused).unwrap_or(usize::MAX);
        let bytes = data.get(..used).unwrap_or(data);
        convert(bytes, &layout, &what)
    }

    fn next_raw(&mut self) -> Result<(), RigError> {
        let path = self.config.path.clone();
        self.streaming = true;
        self.stream
            .next()
            .map_err(|e| dev_err(&path, format!("no frame: {e}")))?;
        self.frames += 1;
        Ok(())
    }
}

impl Camera for V4lCamera {
    fn frame_size(&self) -> (u32, u32) {
        (self.layout.width, self.layout.height)
    }

    /// Flushes (when [`V4lCameraConfig::flush_before_capture`]) and returns the next frame.
    fn capture(&mut self) -> Result<GreyImage, RigError> {
        if self.config.flush_before_capture {
            self.flush()?;
        }
        self.next_frame()
    }

    /// Flushes (when [`V4lCameraConfig::flush_before_capture`]) and returns the next frame in
    /// colour ([`V4lCamera::next_colour_frame`]). A camera opened in a grey format (`GREY`,
    /// `Y16`) gives grey colour frames: open it in `YUYV`, `MJPG`, `RGB3` or `BGR3` for
    /// colour.
    fn capture_colour(&mut self) -> Result<ColourImage, RigError> {
        if self.config.flush_before_capture {
            self.flush()?;
        }
        self.next_colour_frame()
    }

    /// Sets `exposure_time_absolute` (100 µs units) with auto exposure off.
    fn set_exposure_ms(&mut self, exposure_ms: f64) -> Result<(), RigError> {
        let controls = self.controls()?;
        self.apply_exposure(&controls, exposure_ms)?;
        self.config.exposure_ms = Some(exposure_ms);
        Ok(())
    }

    fn exposure_ms(&self) -> Option<f64> {
        self.config.exposure_ms
    }
}

fn dev_err(path: &Path, reason: String) -> RigError {
    RigError::Device {
        device: path.display().to_string(),
        reason,
    }
}

fn control_names(controls: &[V4lControlInfo]) -> String {
    let names: Vec<String> = controls
        .iter()
        .map(|c| crate::v4l_camera_controls::normalise_control_name(&c.name))
        .collect();
    if names.is_empty() {
        "no controls".to_owned()
    } else {
        names.join(", ")
    }
}

fn offered_formats(path: &Path) -> String {
    match query_device(path) {
        Ok(Some(info)) => info
            .formats
            .iter()
            .map(|f| {
                let sizes: Vec<String> = f.sizes.iter().map(|(w, h)| format!("{w}x{h}")).collect();
                format!("{} ({})", f.fourcc, sizes.join(" "))
            })
            .collect::<Vec<_>>()
            .join("; "),
        _ => "unknown".to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn listing_a_folder_without_video_nodes_is_empty() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("videoX"), b"").unwrap();
        std::fs::write(dir.path().join("ttyUSB0"), b"").unwrap();
        assert!(list_v4l_cameras_in(dir.path()).unwrap().is_empty());
        let err = list_v4l_cameras_in(&dir.path().join("missing")).unwrap_err();
        assert!(err.to_string().contains("missing"), "{err}");
    }

    #[test]
    fn a_regular_file_named_like_a_node_is_listed_with_its_error() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("video3"), b"not a device").unwrap();
        let list = list_v4l_cameras_in(dir.path()).unwrap();
        assert_eq!(list.len(), 1);
        assert!(list[0].error.is_some(), "{list:?}");
    }

    #[test]
    fn opening_a_missing_device_names_it() {
        let config = V4lCameraConfig {
            path: PathBuf::from("/dev/video-does-not-exist"),
            ..V4lCameraConfig::default()
        };
        let err = V4lCamera::open(config).unwrap_err().to_string();
        assert!(err.contains("/dev/video-does-not-exist"), "{err}");
    }

    #[test]
    fn real_cameras_open_and_capture_when_present() {
        let cameras = list_v4l_cameras().unwrap();
        let Some(info) = cameras.iter().find(|c| c.error.is_none()) else {
            eprintln!("no V4L2 camera in /dev: skipping the real-camera test");
            return;
        };
        let Some((format, (w, h))) = info
            .formats
            .iter()
            .find_map(|f| Some((f.pixel_format?, *f.sizes.first()?)))
        else {
            eprintln!(
                "{}: no format this crate converts: skipping",
                info.path.display()
            );
            return;
        };
        let mut camera = V4lCamera::open(V4lCameraConfig {
            path: info.path.clone(),
            width: w,
            height: h,
            pixel_format: format,
            ..V4lCameraConfig::default()
        })
        .unwrap();
        let frame = camera.capture().unwrap();
        assert_eq!((frame.width(), frame.height()), (w as usize, h as usize));
        camera.flush().unwrap();
        let frame = camera.capture().unwrap();
        assert_eq!((frame.width(), frame.height()), (w as usize, h as usize));
    }
}
