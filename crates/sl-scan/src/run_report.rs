//! The `report.json` a step writes beside its outputs (what ran, its figures, how long each
//! stage took), and the atomic file writes every output goes through.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::error::{ScanError, io};
use crate::progress::StageTime;

/// The `report.json` of a step: what ran, its figures and its per-stage timings.
///
/// ```
/// let dir = tempfile::tempdir()?;
/// let mut report = sl_scan::RunReport::new("calibrate camera");
/// let sum = report.stage("add", || 2 + 2);
/// report.figure("sum", sum);
/// let path = report.write(dir.path())?;
/// let text = std::fs::read_to_string(path)?;
/// assert!(text.contains("\"sum\": 4"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Serialize)]
pub struct RunReport {
    /// What ran (`calibrate camera`, `scan`, …).
    pub command: String,
    /// The version of the toolkit that wrote it.
    pub version: &'static str,
    /// Figures of the run (counts, errors, fractions), by name.
    pub figures: BTreeMap<String, serde_json::Value>,
    /// Timed stages, in the order they ran.
    pub stages: Vec<StageTime>,
    /// Total wall time in milliseconds, from [`RunReport::new`] to [`RunReport::write`].
    pub total_ms: f64,
    #[serde(skip)]
    started: Option<Instant>,
}

impl RunReport {
    /// Starts a report for `command`; the total time runs from now.
    #[must_use]
    pub fn new(command: &str) -> Self {
        Self {
            command: command.to_owned(),
            version: env!("CARGO_PKG_VERSION"),
            figures: BTreeMap::new(),
            stages: Vec::new(),
            total_ms: 0.0,
            started: Some(Instant::now()),
        }
    }

    /// Counts the total time from `ms` milliseconds ago: for a report written after a
    /// pipeline timed its stages itself.
    pub fn started_before(&mut self, ms: f64) {
        self.started = std::time::Duration::try_from_secs_f64(ms / 1e3)
            .ok()
            .and_then(|d| Instant::now().checked_sub(d))
            .or(self.started);
    }

    /// Runs `f` as the stage `name` and records its wall time.
    pub fn stage<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.stages.push(StageTime::since(name, t));
        out
    }

    /// Records the stages a pipeline timed itself, after the ones recorded so far.
    pub fn add_stages(&mut self, stages: &[StageTime]) {
        self.stages.extend_from_slice(stages);
    }

    /// Records a figure (replacing one of the same name).
    pub fn figure(&mut self, name: &str, value: impl Into<serde_json::Value>) {
        self.figures.insert(name.to_owned(), value.into());
    }

    /// Writes `report.json` into `out` (atomically: [`write_atomically`]) and returns its path.
    ///
    /// # Errors
    /// [`ScanError::Io`] naming the file when it cannot be written.
    pub fn write(&mut self, out: &Path) -> Result<PathBuf, ScanError> {
        if let Some(t) = self.started {
            self.total_ms = t.elapsed().as_secs_f64() * 1e3;
        }
        let path = out.join("report.json");
        let text =
            serde_json::to_string_pretty(self).map_err(|e| io(&path)(std::io::Error::other(e)))?;
        write_atomically(&path, text.as_bytes())?;
        Ok(path)
    }
}

/// The mode an output file is created with before the user's umask masks it: read and write
/// for everyone, as `File::create` (and `touch`, and every other tool) does, so that outputs
/// written through a temporary file get the same mode as the ones written directly (0644 under
/// the usual umask 022). `tempfile` alone creates 0600, which is right for secrets, not outputs.
#[cfg(unix)]
const OUTPUT_FILE_MODE: u32 = 0o666;

/// Writes `bytes` to `path` through a temporary file in the same folder, renamed into place,
/// so that a failure never leaves a half-written file in place of a good one. The file's mode
/// follows the user's umask like every other output (0644 under umask 022).
///
/// # Errors
/// [`ScanError::Io`] naming the folder (no temporary file) or the file.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), ScanError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut builder = tempfile::Builder::new();
    // The kernel masks the mode given to open(2) with the umask: no need to read the umask.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(
        OUTPUT_FILE_MODE,
    ));
    let mut tmp = builder.tempfile_in(dir).map_err(io(dir))?;
    std::io::Write::write_all(&mut tmp, bytes).map_err(io(path))?;
    tmp.persist(path).map_err(|e| io(path)(e.error))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_lists_its_stages_in_order_and_its_figures() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = RunReport::new("test");
        r.stage("one", || ());
        r.add_stages(&[StageTime {
            name: "two".into(),
            ms: 5.0,
        }]);
        r.figure("n", 3);
        let path = r.write(dir.path()).unwrap();
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let names: Vec<&str> = v["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["name"].as_str().unwrap())
            .collect();
        assert_eq!(names, ["one", "two"]);
        assert_eq!(v["figures"]["n"], 3);
        assert_eq!(v["command"], "test");
        assert!(v["total_ms"].as_f64().unwrap() >= 0.0);
    }

    #[test]
    fn a_write_into_a_missing_folder_names_it_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no/such");
        let err = write_atomically(&missing.join("a.json"), b"{}").unwrap_err();
        assert!(err.to_string().contains("no/such"), "{err}");
        assert!(!missing.exists());
    }
}
