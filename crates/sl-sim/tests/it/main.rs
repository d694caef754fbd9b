//! Integration tests of `sl-sim`, linked as one binary (`cargo test -p sl-sim --test it`): one
//! module per subject; `cargo test -p sl-sim --test it MODULE` runs one of them.

mod colour;
mod exposures;
mod mesh;
mod session;
mod simulate;
mod virtual_rig;
