//! ICP registration and the 360° merge of a turntable scan.
//!
//! **Status: placeholder.** This crate exists so that the workspace has its final shape; it
//! contains no code yet, and nothing in it pretends to work.
//!
//! It will hold point-to-point, point-to-plane and generalized ICP with kd-tree, projective and
//! normal-shooting correspondences, trimmed and robust variants, and the merge of a turntable's
//! views with a pose graph initialised from the calibrated turntable axis.
//!
//! Tracked by issue 7.
#![deny(missing_docs)]
