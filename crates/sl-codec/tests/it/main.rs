//! Integration tests of `sl-codec`, linked as one binary (`cargo test -p sl-codec --test it`): one
//! module per subject; `cargo test -p sl-codec --test it MODULE` runs one of them.

mod capture_files;
mod export_formats;
mod exposure;
mod image_formats;
mod opencv_graycode;
mod resolutions;
mod round_trip;
mod slmaster;
