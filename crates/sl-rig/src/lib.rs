//! The hardware of a structured-light rig, and a virtual rig with ground truth.
//!
//! **Status: placeholder.** This crate exists so that the workspace has its final shape; it
//! contains no code yet, and nothing in it pretends to work.
//!
//! It will hold the device traits (camera, projector, turntable), the virtual rig that renders
//! captures of known scenes with their ground truth (issue 4), and the real drivers: a Dynamixel
//! turntable, a V4L2 camera and a full-screen projector window, with resumable capture sessions
//! (issue 8). It is the top of the workspace: no other crate depends on it.
#![deny(missing_docs)]
