//! What the stages report while they run, and how long each took.

use std::time::Instant;

use serde::Serialize;

/// Progress of a stage: `done` of `total` steps of `stage`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScanProgress<'a> {
    /// The stage: `calibrate`, `capture`, `reconstruct`, `merge`, `plate` (when
    /// [`VirtualScanConfig::flatness_plate`](crate::VirtualScanConfig::flatness_plate)), `report`.
    pub stage: &'a str,
    /// Steps done.
    pub done: usize,
    /// Steps of the stage.
    pub total: usize,
}

/// Wall time of one stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageTime {
    /// Stage name.
    pub name: String,
    /// Milliseconds.
    pub ms: f64,
}

impl StageTime {
    /// The stage `name`, started at `start`, ending now.
    pub(crate) fn since(name: &str, start: Instant) -> Self {
        Self {
            name: name.to_owned(),
            ms: start.elapsed().as_secs_f64() * 1e3,
        }
    }
}

/// Runs `f` as the stage `name`, recording its wall time in `stages`.
pub(crate) fn timed<T>(stages: &mut Vec<StageTime>, name: &str, f: impl FnOnce() -> T) -> T {
    let t = std::time::Instant::now();
    let out = f();
    stages.push(StageTime::since(name, t));
    out
}
