//! The virtual structured-light rig: it renders exactly the frames a real rig would capture,
//! together with the truth behind them.
//!
//! Without hardware nothing in a scanner can be trusted unless it is tested against ground
//! truth. This crate holds:
//!
//! - **scenes** ([`Scene`]): planes, spheres, boxes, cylinders, two spheres at a known
//!   distance, triangle meshes (the [`Scene::pebble`], whose flat bottom one turntable
//!   placement never sees; [`Scene::laid_on_side`] re-places it) and printed checkerboards ([`Checkerboard`]), with uniform or
//!   textured Lambertian albedo ([`Texture`], grey or in colour: [`Texture::albedo_rgb_at`],
//!   [`Finish::Coloured`]), standing on the turntable or fixed in front of the camera
//!   ([`Mount`]);
//! - the **virtual rig** ([`VirtualRig`], configured by [`RigConfig`]): `sl-camera` models for
//!   the camera and the projector (intrinsics, distortion, pose), rays cast with `parry3d-f64`
//!   once per view into a geometry cache ([`ViewGeometry`]) so that each projected image
//!   renders as a cheap lookup, then camera effects ([`CameraEffects`]: global illumination,
//!   defocus, photon and read noise, exposure, saturation, 8/16-bit quantisation), seeded and
//!   reproducible;
//! - **virtual devices** ([`VirtualCamera`], [`VirtualProjector`], [`VirtualTurntable`], from
//!   [`VirtualRig::devices`]) that implement `sl-rig`'s device traits [`Camera`],
//!   [`Projector`] and [`Turntable`], so that code written for real hardware (`sl-rig`'s
//!   capture sessions, `sl-scan`'s pipeline) runs unchanged on the virtual rig;
//! - **colour frames** ([`View::capture_colour`], the virtual camera's
//!   [`Camera::capture_colour`]): each channel rendered with its albedo through the same optics
//!   and sensor, so that the luma of a colour frame is the grey frame;
//! - **ground truth** ([`ViewTruth`], [`BoardTruth`], the true colour of the surface nearest a
//!   point, [`VirtualRig::true_colour`]): depth, 3-D points, the exact projector
//!   coordinate of every camera pixel, masks and poses, the rig's exact calibration
//!   ([`RigConfig::calibration`]), and calibration captures ([`capture_board`],
//!   [`capture_board_on_table`], [`simulate_calibration`]; a session's captures one at a
//!   time with its noise keys, [`CalibrationCaptures`], and the patterns of a projector
//!   calibration, [`calibration_sequence`]);
//! - **files**: capture sets in `sl-codec`'s format with their truth ([`simulate_scan`],
//!   [`write_view_truth`]). `docs/virtual-rig.md` describes scenes, parameters and files.
//!
//! Errors are [`SimError`]s; through the device traits the virtual devices report `sl-rig`'s
//! [`RigError`] as real drivers do. The image type and the device traits of `sl-rig` are
//! re-exported, so one import serves a user of the virtual rig.
//!
//! ```
//! use sl_sim::{GreyImage, RigConfig, Scene, VirtualRig};
//! # fn main() -> Result<(), sl_sim::SimError> {
//! // The default rig (1280x720 camera, 1920x1080 projector), shrunk for a quick example.
//! let mut config = RigConfig::default();
//! config.camera.size = sl_camera::ImageSize::new(64, 36);
//! config.camera.intrinsics = sl_camera::Intrinsics::new(72.0, 72.0, 31.5, 17.5);
//! let rig = VirtualRig::new(config, Scene::sphere())?;
//! // Cast the view with the turntable at 30 degrees, then render a frame under full white.
//! let view = rig.view(30.0, 0)?;
//! let white = GreyImage::filled_u8(1920, 1080, 255)?;
//! let frame = view.capture(&white, 0)?;
//! assert_eq!((frame.width(), frame.height()), (64, 36));
//! // The truth: the centre pixel sees the sphere, lit by the projector.
//! let centre = 18 * 64 + 32;
//! assert!(view.truth.lit(centre));
//! assert!(view.truth.depth_mm[centre] > 350.0 && view.truth.depth_mm[centre] < 450.0);
//! # Ok(())
//! # }
//! ```
//!
//! # Conventions
//! - Camera and projector frames as OpenCV: `x` right, `y` down, `z` forward; the projector is
//!   an inverse camera (`sl-camera`'s model). The camera frame is the rig's reference.
//! - Lengths in millimetres (`f64`), angles in degrees at the API surface; poses are
//!   `Isometry3<f64>` named `T_a_b` (maps `b` coordinates into `a`): `t_cam_proj`,
//!   `t_cam_table`, `T_cam_board`, `T_cam_object`.
//! - Pixel `(0, 0)` is the centre of the top-left pixel; an image spans
//!   `[-0.5, w - 0.5) × [-0.5, h - 0.5)`, for the camera and the projector alike. A projector
//!   pixel `(i, j)` lights the square `[i - 0.5, i + 0.5) × [j - 0.5, j + 0.5)` of projector
//!   coordinates (a real projector shows square pixels), blurred by the projection lens
//!   (`Illumination::projector_blur_px`, a Gaussian of 0.5 px by default).
//! - `table` frame: origin on the turntable axis at the table top, `z` up along the axis;
//!   positive angles turn right-handedly about `z`. `board` frame: origin at the first inner
//!   corner, `x` along the first row, `y` along the columns, `z` into the board.
//! - Maps are row-major, pixel `(x, y)` at index `y · width + x`, NaN where there is no value.
//! - Radiance is in units of the projector's full white at normal incidence; camera frames
//!   are 8- or 16-bit grey, colour frames 8-bit RGB. Albedos are fractions in `[0, 1]`, RGB
//!   albedos `[red, green, blue]`; a colour texture's grey albedo is its luma
//!   ([`LUMA_WEIGHTS`]).
#![deny(missing_docs)]

mod blur;
mod board;
mod calib;
mod calibration_captures;
mod config;
mod error;
mod files;
mod footprint;
mod geometry;
mod placement;
mod raycast;
mod render;
mod scene;
mod sensor;
mod simulate;
mod truth;
mod virtual_rig;

pub use board::{BOARD_DARK_ALBEDO, BOARD_LIGHT_ALBEDO, Checkerboard};
pub use calib::{
    BoardCapture, BoardPoseConfig, BoardTruth, capture_board, capture_board_on_table,
    random_board_poses,
};
pub use calibration_captures::{
    CALIBRATION_PERIOD_PX, CALIBRATION_PHASE_STEPS, CalibrationCaptures, calibration_sequence,
};
pub use config::{
    DEFAULT_AIM_HEIGHT_MM, DEFAULT_BASELINE_MM, DEFAULT_TILT_DEG, DEFAULT_WORKING_DISTANCE_MM,
    MAX_SUPERSAMPLING, RenderConfig, RigConfig, SecondCamera,
};
pub use error::SimError;
pub use files::{TRUTH_DIR, VIEW_JSON, pose_matrix, write_view_truth};
pub use geometry::{CameraRays, ViewGeometry};
pub use placement::{PEBBLE_CUT_MM, PEBBLE_RADIUS_MM, pebble_mesh, pebble_object};
pub use raycast::{Hit, PlacedScene};
pub use render::{Illumination, ProjectorSampling, ResponseShape};
pub use scene::{
    AUTO_METRES_BELOW, COLOURED_ALBEDOS, COLOURED_CELL_MM, DARK_ALBEDO, DEFAULT_ALBEDO,
    DUMBBELL_CENTRE_DISTANCE_MM, Finish, GLOSSY_ALBEDO, GLOSSY_EXPONENT, GLOSSY_STRENGTH, Gloss,
    LUMA_WEIGHTS, MeshUnits, Mount, Scene, SceneObject, Shape, Texture, luma_of,
    upright_facing_camera,
};
pub use sensor::{BitDepth, CameraEffects, Defocus, GlobalIllumination, NoiseKey, SensorConfig};
pub use simulate::{
    CalibrationSession, SimulatedCapture, projector_images, simulate_calibration, simulate_scan,
};
pub use truth::{NO_OBJECT, ObjectPose, TrueColour, ViewTruth};
pub use virtual_rig::{
    DeviceFaults, VIRTUAL_EXPOSURE_MS, VIRTUAL_MAX_EXPOSURE_MS, View, VirtualCamera,
    VirtualProjector, VirtualRig, VirtualTurntable,
};

// The device layer the virtual devices implement, re-exported so that one import serves.
pub use sl_rig::{
    Camera, ColourImage, GreyImage, Projector, RigError, Turntable, turntable_angles,
    write_capture_set,
};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
