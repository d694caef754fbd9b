//! Integration tests of `sl-icp`, linked as one binary (`cargo test -p sl-icp --test it`): one
//! module per subject; `cargo test -p sl-icp --test it MODULE` runs one of them.

mod support;

mod bunny;
mod global;
mod merge_fallback;
mod multiway;
mod registration;
mod turntable;
