//! Integration tests of `sl-scan`, linked as one binary (`cargo test -p sl-scan --test it`): one
//! module per subject; `cargo test -p sl-scan --test it MODULE` runs one of them.

mod binocular_scan;
mod binocular_sdk;
mod calibration_capture;
mod colour;
mod exposures;
mod frame_checks;
mod placements;
mod response;
mod scan_pipeline;
mod session_scan;
