//! Opening a rig's real devices from a description: the V4L2 camera, the projector window on a
//! monitor and the Dynamixel turntable, each behind its cargo feature.
//!
//! The description builds whatever features are on, so a program can read it from a file or a
//! command line and report a missing feature as a typed error ([`RigError::FeatureNotBuilt`])
//! instead of failing to compile.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::{Camera, Projector, RigError, SessionDevices, Turntable};

/// Name prefixes of the serial device nodes a USB–serial adapter (U2D2, FTDI: `ttyUSB`) or a
/// CDC-ACM board (`ttyACM`) gets.
const SERIAL_PREFIXES: [&str; 2] = ["ttyUSB", "ttyACM"];

/// The serial ports a turntable can be on: the `ttyUSB*` and `ttyACM*` nodes of `dev` (`/dev`),
/// sorted; none when `dev` cannot be read.
#[must_use]
pub fn serial_ports(dev: &std::path::Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dev) else {
        return Vec::new();
    };
    let mut ports: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .filter(|e| {
            e.file_name()
                .to_str()
                .is_some_and(|n| SERIAL_PREFIXES.iter().any(|p| n.starts_with(p)))
        })
        .map(|e| e.path())
        .collect();
    ports.sort();
    ports
}

/// The real devices of a rig: which camera, which monitor the projector is, which serial port
/// and servo id the turntable answers on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceDescription {
    /// V4L2 camera device, e.g. `/dev/video0` (feature `v4l`).
    pub camera: PathBuf,
    /// Monitor index of the projector, as `list_monitors` lists them (feature `window`).
    pub projector_monitor: usize,
    /// Serial port of the Dynamixel turntable, e.g. `/dev/ttyUSB0` (feature `dynamixel`).
    pub turntable_port: PathBuf,
    /// Dynamixel servo id of the turntable.
    pub servo_id: u8,
    /// The second camera of a binocular rig, e.g. `/dev/video2` (feature `v4l`); opened with
    /// the first by [`with_binocular_devices`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub right_camera: Option<PathBuf>,
}

impl DeviceDescription {
    /// Checks what can be checked before anything opens: the turntable's serial port exists.
    ///
    /// # Errors
    /// [`RigError::InvalidParameter`] naming `turntable_port` when there is no such port.
    pub fn check(&self) -> Result<(), RigError> {
        if self.turntable_port.exists() {
            Ok(())
        } else {
            Err(RigError::InvalidParameter {
                name: "turntable_port".to_owned(),
                reason: format!(
                    "{}: no such serial port (check the cable and the udev rule of docs/hardware-turntable.md)",
                    self.turntable_port.display()
                ),
            })
        }
    }

    /// The features this description needs that this build lacks, in the order camera,
    /// projector, turntable.
    pub fn missing_features(&self) -> Vec<&'static str> {
        let mut missing = Vec::new();
        if !cfg!(feature = "v4l") {
            missing.push("v4l");
        }
        if !cfg!(feature = "window") {
            missing.push("window");
        }
        if !cfg!(all(feature = "dynamixel", unix)) {
            missing.push("dynamixel");
        }
        missing
    }

    /// The devices as a capture session records them in `session.json`.
    pub fn session_devices(&self) -> SessionDevices {
        SessionDevices {
            camera: self.camera.display().to_string(),
            projector: format!("monitor {}", self.projector_monitor),
            turntable: format!("{} id {}", self.turntable_port.display(), self.servo_id),
            right_camera: self.right_camera.as_ref().map(|c| c.display().to_string()),
        }
    }

    /// One line naming the three devices, for reports.
    pub fn summary(&self) -> String {
        format!(
            "camera {}, projector on monitor {}, turntable {} id {}",
            self.camera.display(),
            self.projector_monitor,
            self.turntable_port.display(),
            self.servo_id
        )
    }
}

/// How errors name the turntable: its port and servo id.
fn turntable_name(port: &std::path::Path, servo_id: u8) -> String {
    format!("turntable {} id {servo_id}", port.display())
}

/// A device trait object that can move to the worker thread of the projector window.
pub type BoxedCamera = Box<dyn Camera + Send>;
/// A turntable trait object that can move to the worker thread of the projector window.
pub type BoxedTurntable = Box<dyn Turntable + Send>;

/// Opens the V4L2 camera at `path` with the driver's defaults.
///
/// # Errors
/// [`RigError::FeatureNotBuilt`] without the `v4l` feature; the driver's error otherwise.
pub fn open_camera(path: &std::path::Path) -> Result<BoxedCamera, RigError> {
    #[cfg(feature = "v4l")]
    {
        let camera = crate::V4lCamera::open(crate::V4lCameraConfig {
            path: path.to_path_buf(),
            ..crate::V4lCameraConfig::default()
        })?;
        Ok(Box::new(camera))
    }
    #[cfg(not(feature = "v4l"))]
    {
        Err(RigError::FeatureNotBuilt {
            device: format!("camera {}", path.display()),
            feature: "v4l",
        })
    }
}

/// Opens the Dynamixel turntable on `port` with servo id `servo_id` and the driver's defaults.
///
/// # Errors
/// [`RigError::FeatureNotBuilt`] without the `dynamixel` feature (or off Unix); the driver's
/// error, naming the port, otherwise.
pub fn open_turntable(port: &std::path::Path, servo_id: u8) -> Result<BoxedTurntable, RigError> {
    #[cfg(all(feature = "dynamixel", unix))]
    {
        let table = crate::DynamixelTurntable::open(
            port,
            crate::DynamixelConfig {
                id: servo_id,
                ..crate::DynamixelConfig::default()
            },
        )
        .map_err(|e| RigError::Device {
            device: turntable_name(port, servo_id),
            reason: e.to_string(),
        })?;
        Ok(Box::new(table))
    }
    #[cfg(not(all(feature = "dynamixel", unix)))]
    {
        Err(RigError::FeatureNotBuilt {
            device: turntable_name(port, servo_id),
            feature: "dynamixel",
        })
    }
}

/// What [`with_devices`] and [`with_binocular_devices`] check before anything opens: the
/// turntable's port exists and this build has every device's feature.
fn check_buildable(description: &DeviceDescription) -> Result<(), RigError> {
    description.check()?;
    if let Some(feature) = description.missing_features().first() {
        let device = match *feature {
            "v4l" => format!("camera {}", description.camera.display()),
            "window" => format!("projector on monitor {}", description.projector_monitor),
            _ => turntable_name(&description.turntable_port, description.servo_id),
        };
        return Err(RigError::FeatureNotBuilt { device, feature });
    }
    Ok(())
}

/// [`with_devices`] for a binocular rig: both cameras (the description's `camera` and
/// `right_camera`), the projector window and the turntable, handed to `work` on a worker
/// thread.
///
/// # Errors
/// [`RigError::InvalidParameter`] naming `right_camera` when the description has none; as
/// [`with_devices`] otherwise, the second camera's errors naming it as the right camera.
pub fn with_binocular_devices<T, F>(description: &DeviceDescription, work: F) -> Result<T, RigError>
where
    T: Send + 'static,
    F: FnOnce(
            &mut dyn Camera,
            &mut dyn Camera,
            &mut dyn Projector,
            &mut dyn Turntable,
        ) -> Result<T, RigError>
        + Send
        + 'static,
{
    let Some(right_path) = description.right_camera.clone() else {
        return Err(RigError::InvalidParameter {
            name: "right_camera".to_owned(),
            reason: "a binocular rig needs its second camera (e.g. /dev/video2)".to_owned(),
        });
    };
    check_buildable(description)?;
    let mut camera = open_camera(&description.camera)?;
    let mut right = open_camera(&right_path)
        .map_err(|e| e.of_right_camera(&right_path.display().to_string()))?;
    let mut table = open_turntable(&description.turntable_port, description.servo_id)?;
    run_window(description.projector_monitor, move |projector| {
        work(camera.as_mut(), right.as_mut(), projector, table.as_mut())
    })
}

/// The devices `description` names, one camera or two: [`with_devices`], or
/// [`with_binocular_devices`] when it names a `right_camera`, whose camera `work` then gets as
/// `Some`. For a program that takes both rigs through one path.
///
/// # Errors
/// Those of [`with_devices`] or [`with_binocular_devices`].
pub fn with_described_devices<T, F>(description: &DeviceDescription, work: F) -> Result<T, RigError>
where
    T: Send + 'static,
    F: FnOnce(
            &mut dyn Camera,
            Option<&mut dyn Camera>,
            &mut dyn Projector,
            &mut dyn Turntable,
        ) -> Result<T, RigError>
        + Send
        + 'static,
{
    if description.right_camera.is_some() {
        with_binocular_devices(description, move |camera, right, projector, table| {
            work(camera, Some(right), projector, table)
        })
    } else {
        with_devices(description, move |camera, projector, table| {
            work(camera, None, projector, table)
        })
    }
}

/// Opens the three devices of `description` and runs `work` on them.
///
/// The projector window lives on the calling (main) thread's event loop, so `work` runs on a
/// worker thread while the window shows its images; this returns when `work` does. The serial
/// port is checked first, then the camera and the turntable open, then the window.
///
/// # Errors
/// [`RigError::FeatureNotBuilt`] naming the first device whose feature this build lacks (checked
/// before anything opens); the check's, a driver's or `work`'s error otherwise.
pub fn with_devices<T, F>(description: &DeviceDescription, work: F) -> Result<T, RigError>
where
    T: Send + 'static,
    F: FnOnce(&mut dyn Camera, &mut dyn Projector, &mut dyn Turntable) -> Result<T, RigError>
        + Send
        + 'static,
{
    check_buildable(description)?;
    let mut camera = open_camera(&description.camera)?;
    let mut table = open_turntable(&description.turntable_port, description.servo_id)?;
    run_window(description.projector_monitor, move |projector| {
        work(camera.as_mut(), projector, table.as_mut())
    })
}

/// Opens the camera at `camera` and the projector window on monitor `projector_monitor` (no
/// turntable: what a measurement of the projector alone needs, such as its response) and runs
/// `work` on them, on a worker thread as [`with_devices`] does.
///
/// # Errors
/// [`RigError::FeatureNotBuilt`] naming the camera or the projector when this build lacks its
/// feature (checked before anything opens); a driver's or `work`'s error otherwise.
pub fn with_camera_and_projector<T, F>(
    camera: &std::path::Path,
    projector_monitor: usize,
    work: F,
) -> Result<T, RigError>
where
    T: Send + 'static,
    F: FnOnce(&mut dyn Camera, &mut dyn Projector) -> Result<T, RigError> + Send + 'static,
{
    if !cfg!(feature = "v4l") {
        return Err(RigError::FeatureNotBuilt {
            device: format!("camera {}", camera.display()),
            feature: "v4l",
        });
    }
    if !cfg!(feature = "window") {
        return Err(RigError::FeatureNotBuilt {
            device: format!("projector on monitor {projector_monitor}"),
            feature: "window",
        });
    }
    let mut camera = open_camera(camera)?;
    run_window(projector_monitor, move |projector| {
        work(camera.as_mut(), projector)
    })
}

#[cfg(feature = "window")]
fn run_window<T, F>(monitor: usize, work: F) -> Result<T, RigError>
where
    T: Send + 'static,
    F: FnOnce(&mut dyn Projector) -> Result<T, RigError> + Send + 'static,
{
    crate::run_projector(
        crate::ProjectorWindowConfig {
            monitor,
            ..crate::ProjectorWindowConfig::default()
        },
        move |mut projector| work(&mut projector),
    )
}

#[cfg(not(feature = "window"))]
fn run_window<T, F>(monitor: usize, _work: F) -> Result<T, RigError>
where
    T: Send + 'static,
    F: FnOnce(&mut dyn Projector) -> Result<T, RigError> + Send + 'static,
{
    Err(RigError::FeatureNotBuilt {
        device: format!("projector on monitor {monitor}"),
        feature: "window",
    })
}

#[cfg(test)]
mod tests {
    #[cfg(not(all(feature = "v4l", feature = "window")))]
    #[test]
    fn camera_and_projector_without_their_features_are_named() {
        let e =
            super::with_camera_and_projector(std::path::Path::new("/dev/video7"), 2, |_, _| Ok(()))
                .unwrap_err()
                .to_string();
        assert!(e.contains("/dev/video7") || e.contains("monitor 2"), "{e}");
    }

    #[test]
    fn serial_ports_are_usb_and_acm_nodes_sorted() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["ttyUSB1", "ttyS0", "ttyACM0", "ttyUSB0", "video0"] {
            std::fs::write(dir.path().join(name), b"").unwrap();
        }
        let names: Vec<String> = super::serial_ports(dir.path())
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["ttyACM0", "ttyUSB0", "ttyUSB1"]);
        assert!(super::serial_ports(&dir.path().join("missing")).is_empty());
    }

    use super::*;

    fn description(port: PathBuf) -> DeviceDescription {
        DeviceDescription {
            camera: PathBuf::from("/dev/video-none"),
            projector_monitor: 1,
            turntable_port: port,
            servo_id: 3,
            right_camera: None,
        }
    }

    #[test]
    fn a_missing_port_is_named_before_anything_opens() {
        let desc = description(PathBuf::from("/dev/ttyUSB-none"));
        let err = with_devices(&desc, |_, _, _| Ok(()))
            .err()
            .map(|e| e.to_string());
        let text = err.unwrap_or_default();
        assert!(text.contains("turntable_port"), "{text}");
        assert!(text.contains("/dev/ttyUSB-none"), "{text}");
    }

    #[test]
    fn a_missing_feature_is_a_typed_error_naming_it() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let desc = description(dir.path().to_path_buf());
        let missing = desc.missing_features();
        if let Some(first) = missing.first() {
            match with_devices(&desc, |_, _, _| Ok(())) {
                Err(RigError::FeatureNotBuilt { feature, .. }) => assert_eq!(feature, *first),
                other => panic!("expected FeatureNotBuilt, got {other:?}"),
            }
        }
    }

    #[test]
    fn the_description_round_trips_through_json() {
        let desc = description(PathBuf::from("/dev/ttyUSB0"));
        let text = serde_json::to_string(&desc).unwrap_or_default();
        let back: DeviceDescription =
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"));
        assert_eq!(back, desc);
        assert_eq!(desc.session_devices().turntable, "/dev/ttyUSB0 id 3");
        assert_eq!(desc.session_devices().right_camera, None);
        // With a second camera: recorded, and read back.
        let two = DeviceDescription {
            right_camera: Some(PathBuf::from("/dev/video2")),
            ..desc
        };
        let text = serde_json::to_string(&two).unwrap_or_default();
        let back: DeviceDescription =
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"));
        assert_eq!(back, two);
        assert_eq!(
            two.session_devices().right_camera.as_deref(),
            Some("/dev/video2")
        );
    }

    #[test]
    fn a_binocular_rig_without_its_second_camera_is_named() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let desc = description(dir.path().to_path_buf());
        match with_binocular_devices(&desc, |_, _, _, _| Ok(())) {
            Err(RigError::InvalidParameter { name, .. }) => assert_eq!(name, "right_camera"),
            other => panic!("expected the missing right camera, got {other:?}"),
        }
        // Without the v4l feature the first camera is the first device that cannot open, and
        // is named by its own path, not taken for the right one.
        if !cfg!(feature = "v4l") {
            let desc = DeviceDescription {
                right_camera: Some(PathBuf::from("/dev/video-right")),
                ..description(dir.path().to_path_buf())
            };
            match with_binocular_devices(&desc, |_, _, _, _| Ok(())) {
                Err(RigError::FeatureNotBuilt { device, .. }) => {
                    assert_eq!(device, "camera /dev/video-none");
                }
                other => panic!("expected FeatureNotBuilt, got {other:?}"),
            }
        }
        // The second camera's failures to open are named as the right camera's.
        let missing = RigError::FeatureNotBuilt {
            device: "camera /dev/video-right".to_owned(),
            feature: "v4l",
        };
        match missing.of_right_camera("/dev/video-right") {
            RigError::FeatureNotBuilt { device, feature } => {
                assert_eq!(
                    (device.as_str(), feature),
                    ("right camera /dev/video-right", "v4l")
                );
            }
            other => panic!("expected FeatureNotBuilt, got {other:?}"),
        }
        let busy = RigError::Device {
            device: "camera /dev/video-right".to_owned(),
            reason: "VIDIOC_S_FMT: Device or resource busy".to_owned(),
        };
        let text = busy.of_right_camera("/dev/video-right").to_string();
        assert!(
            text.starts_with("right camera /dev/video-right: "),
            "{text}"
        );
        assert!(text.contains("busy"), "{text}");
    }
}
