//! Integration tests of `sl-calib`, linked as one binary (`cargo test -p sl-calib --test it`): one
//! module per subject; `cargo test -p sl-calib --test it MODULE` runs one of them.

mod support;

#[cfg(feature = "pictures")]
mod pictures;
mod procam;
mod properties;
mod real_chessboard;
mod real_kamino;
mod realistic_corners;
mod rig_calibration_truth;
mod rig_corner_truth;
mod stereo_cameras;
mod turntable;
mod virtual_rig;
