//! The virtual structured-light rig: scenes, rendering, ray casting, ground truth and the virtual
//! devices that implement [`sl_rig`]'s device traits.
//!
//! The simulator is being moved here from `sl-rig` (issue 14); until the move is complete this
//! crate re-exports the simulator's items from `sl-rig` under their final paths, so code written
//! against `sl_sim::…` keeps working when the move lands.
#![deny(missing_docs)]

pub use sl_rig::{
    BOARD_DARK_ALBEDO, BOARD_LIGHT_ALBEDO, BoardCapture, BoardPoseConfig, BoardTruth, Checkerboard,
    CalibrationSession, Hit, Illumination, NO_OBJECT, ObjectPose, PlacedScene, ProjectorSampling,
    RenderConfig, RigConfig, Scene, SceneObject, SensorConfig, Shape, SimulatedCapture, Texture,
    View, ViewTruth, VirtualCamera, VirtualProjector, VirtualRig, VirtualTurntable, capture_board,
    capture_board_on_table, projector_images, random_board_poses, simulate_calibration,
    simulate_scan, turntable_angles,
};
