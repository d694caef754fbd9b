//! The structured-light scan pipeline as a library: each stage is a function over session folders
//! and `sl-rig`'s device traits (capture a calibration session, calibrate, capture a scan session,
//! reconstruct the views, merge, measure), one path for the virtual and the real rig.
//!
//! The stages are being moved here from the facade package (issue 14).
#![deny(missing_docs)]
