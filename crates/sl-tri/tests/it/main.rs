//! Integration tests of `sl-tri`, linked as one binary (`cargo test -p sl-tri --test it`): one
//! module per subject; `cargo test -p sl-tri --test it MODULE` runs one of them.

mod filters;
mod noise_free;
mod rendered;
mod slmaster;
