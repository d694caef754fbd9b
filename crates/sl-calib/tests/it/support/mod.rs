//! Helpers shared by the test modules (some also included by benches and examples with
//! `#[path]`).
// Test helpers: a failure is the calling test failing (as when each test file included them).
#![allow(clippy::unwrap_used, clippy::expect_used)]

pub(crate) mod board_render;
pub(crate) mod held_out;
pub(crate) mod procam_render;
