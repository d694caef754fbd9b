//! Integration tests of `sl-camera`, linked as one binary (`cargo test -p sl-camera --test it`): one
//! module per subject; `cargo test -p sl-camera --test it MODULE` runs one of them.

mod calibration_files;
mod layouts;
mod opencv_reference;
mod round_trip;
