//! Triangulation of decoded correspondences into metric point clouds.
//!
//! **Status: placeholder.** This crate exists so that the workspace has its final shape; it
//! contains no code yet, and nothing in it pretends to work.
//!
//! It will hold ray–plane triangulation (with projector distortion handled), the linear and
//! midpoint methods, optimal (reprojection-error) triangulation, filters for reprojection error,
//! depth range, quality and mixed pixels, and depth-map output. Clouds are `sl-cloud` point
//! clouds in the camera frame, in millimetres.
//!
//! Tracked by issue 6.
#![deny(missing_docs)]
