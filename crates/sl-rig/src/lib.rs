//! The hardware of a structured-light rig, and a virtual rig with ground truth.
#![deny(missing_docs)]

mod blur;
mod board;
mod calib;
mod config;
mod device;
mod error;
mod files;
mod geometry;
mod image;
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
pub use config::{
    DEFAULT_AIM_HEIGHT_MM, DEFAULT_BASELINE_MM, DEFAULT_TILT_DEG, DEFAULT_WORKING_DISTANCE_MM,
    MAX_SUPERSAMPLING, RenderConfig, RigConfig,
};
pub use device::{Camera, Projector, Turntable, capture_sequence};
pub use error::RigError;
pub use files::{TRUTH_DIR, VIEW_JSON, pose_matrix, write_capture_set, write_view_truth};
pub use geometry::{CameraRays, ViewGeometry};
pub use image::{GreyImage, Pixels};
pub use raycast::{Hit, PlacedScene};
pub use render::{Illumination, ProjectorSampling};
pub use scene::{
    DEFAULT_ALBEDO, DUMBBELL_CENTRE_DISTANCE_MM, Mount, Scene, SceneObject, Shape, Texture,
    upright_facing_camera,
};
pub use sensor::{BitDepth, CameraEffects, Defocus, GlobalIllumination, NoiseKey, SensorConfig};
pub use simulate::{
    CalibrationSession, SimulatedCapture, projector_images, simulate_calibration, simulate_scan,
    turntable_angles,
};
pub use truth::{NO_OBJECT, ObjectPose, ViewTruth};
pub use virtual_rig::{View, VirtualCamera, VirtualProjector, VirtualRig, VirtualTurntable};
