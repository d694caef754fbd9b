//! Structured-light 3-D scanning with a projector, a camera and a turntable, in pure Rust.
//!
//! This crate re-exports the crates of the workspace under short names, so that an application
//! needs one dependency:
//!
//! | module | crate | what it holds |
//! |---|---|---|
//! | [`image`] | `sl-image` | the shared image types: image size, grey frames, grey images |
//! | [`camera`] | `sl-camera` | pinhole intrinsics, OpenCV distortion, projection, poses, calibration files |
//! | [`cloud`] | `sl-cloud` | point clouds, PLY, voxel grid, neighbours, normals, outliers |
//! | [`codec`] | `sl-codec` | pattern sequences and decoders |
//! | [`calib`] | `sl-calib` | checkerboards, Zhang's camera calibration, projector calibration by local homographies, stereo, two cameras, turntable axis |
//! | [`tri`] | `sl-tri` | triangulation into metric clouds, with one camera and a projector or with two cameras |
//! | [`icp`] | `sl-icp` | ICP, turntable merging, global registration with no initial pose |
//! | [`rig`] | `sl-rig` | device traits, drivers (V4L2 camera, projector window, Dynamixel turntable), capture sessions |
//! | [`sim`] | `sl-sim` | the virtual rig: scenes, rendering, ground truth, virtual devices behind `sl-rig`'s traits |
//! | [`metrology`] | `sl-metrology` | VDI/VDE 2634 part 2 figures of a cloud or mesh against a truth description |
//! | [`mesh`] | `sl-mesh` | screened Poisson surfaces, mesh clean-up, STL/OBJ/PLY, 3-D viewer page |
//! | [`scan`] | `sl-scan` | the scan pipeline: calibration capture, calibrate, capture, reconstruct, merge, mesh, measure, report |
//!
//! [`scan`] holds the scan pipeline (calibrate, capture, reconstruct, merge, mesh, measure, report)
//! that `slscan scan` runs on the virtual rig and on real devices.
//!
//! The command line `slscan` (in `examples/slscan`) composes them; run
//! `cargo run --release --example slscan -- --help`.
#![deny(missing_docs)]

pub use sl_calib as calib;
pub use sl_camera as camera;
pub use sl_cloud as cloud;
pub use sl_codec as codec;
pub use sl_icp as icp;
pub use sl_image as image;
pub use sl_mesh as mesh;
pub use sl_metrology as metrology;
pub use sl_rig as rig;
pub use sl_scan as scan;
pub use sl_sim as sim;
pub use sl_tri as tri;
