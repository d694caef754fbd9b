//! Helpers shared by the test modules (also included by benches and examples with `#[path]`).

pub(crate) mod blob;
pub(crate) mod bunny;
pub(crate) mod turntable_scene;
