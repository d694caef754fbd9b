//! Calibration of a structured-light rig.
//!
//! **Status: placeholder.** This crate exists so that the workspace has its final shape; it
//! contains no code yet, and nothing in it pretends to work.
//!
//! It will hold checkerboard detection with sub-pixel saddle-point refinement, Zhang's camera
//! calibration with Levenberg–Marquardt over all parameters, projector calibration by local
//! homographies (Moreno & Taubin 2012), camera–projector stereo calibration and the calibration
//! of the turntable axis. Results are written as `sl-camera` calibration files.
//!
//! Tracked by issue 5.
#![deny(missing_docs)]
