//! Camera and projector models (in progress).
#![deny(missing_docs)]
