//! Helpers shared by every `slscan` subcommand: the output folder, `report.json` with
//! per-stage timings, progress bars and the one-line error report.

use std::collections::{BTreeMap, HashMap};
use std::fs;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use serde::Serialize;
use structured_light::pipeline::{ScanProgress, StageTime};

/// Prints an error and its causes on one line: `slscan: error: a: b: c`.
pub(crate) fn print_error(err: &anyhow::Error) {
    let chain: Vec<String> = err.chain().map(ToString::to_string).collect();
    // Library errors often repeat their source in their own message; drop exact repeats.
    let mut line = String::new();
    for part in chain {
        if !line.contains(&part) {
            if !line.is_empty() {
                line.push_str(": ");
            }
            line.push_str(&part);
        }
    }
    eprintln!("slscan: error: {line}");
}

/// Creates the output folder (and its parents) if needed, naming it on failure.
pub(crate) fn ensure_out_dir(out: &Path) -> anyhow::Result<PathBuf> {
    fs::create_dir_all(out)
        .with_context(|| format!("cannot create output folder {}", out.display()))?;
    Ok(out.to_path_buf())
}

/// One timed stage of a command.
#[derive(Debug, Serialize)]
pub(crate) struct Stage {
    /// Stage name, e.g. `read`, `decode`.
    pub(crate) name: String,
    /// Wall time in milliseconds.
    pub(crate) ms: f64,
}

/// The `report.json` of a command: what ran, its figures and its per-stage timings.
#[derive(Debug, Serialize)]
pub(crate) struct Report {
    /// Subcommand name.
    pub(crate) command: String,
    /// `slscan` version.
    pub(crate) version: &'static str,
    /// Figures of the run (counts, errors, fractions), by name.
    pub(crate) figures: BTreeMap<String, serde_json::Value>,
    /// Timed stages, in the order they ran.
    pub(crate) stages: Vec<Stage>,
    /// Total wall time in milliseconds.
    pub(crate) total_ms: f64,
    #[serde(skip)]
    started: Option<Instant>,
}

impl Report {
    /// Starts a report for `command`; the total time runs from now.
    pub(crate) fn new(command: &str) -> Self {
        Self {
            command: command.to_owned(),
            version: env!("CARGO_PKG_VERSION"),
            figures: BTreeMap::new(),
            stages: Vec::new(),
            total_ms: 0.0,
            started: Some(Instant::now()),
        }
    }

    /// Runs `f` as the stage `name` and records its wall time.
    pub(crate) fn stage<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.stages.push(Stage {
            name: name.to_owned(),
            ms: ms(t.elapsed()),
        });
        out
    }

    /// Records the stages a library pipeline timed itself, after the ones recorded so far.
    pub(crate) fn add_stages(&mut self, stages: &[StageTime]) {
        self.stages.extend(stages.iter().map(|s| Stage {
            name: s.name.clone(),
            ms: s.ms,
        }));
    }

    /// Records a figure.
    pub(crate) fn figure(&mut self, name: &str, value: impl Into<serde_json::Value>) {
        self.figures.insert(name.to_owned(), value.into());
    }

    /// Writes `report.json` into `out` (atomically: a temporary file renamed into place).
    pub(crate) fn write(&mut self, out: &Path) -> anyhow::Result<PathBuf> {
        if let Some(t) = self.started {
            self.total_ms = ms(t.elapsed());
        }
        let path = out.join("report.json");
        let text = serde_json::to_string_pretty(self).context("cannot serialise report.json")?;
        write_atomically(&path, text.as_bytes())?;
        Ok(path)
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Writes `bytes` to `path` through a temporary file in the same folder, so that a failure
/// never leaves a half-written file in place of a good one.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut tmp = tempfile::NamedTempFile::new_in(dir)
        .with_context(|| format!("cannot write into {}", dir.display()))?;
    std::io::Write::write_all(&mut tmp, bytes)
        .with_context(|| format!("cannot write {}", path.display()))?;
    tmp.persist(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// A progress bar on stderr for `len` steps (hidden automatically when stderr is not a terminal).
#[allow(dead_code)] // used by the subcommands that take long; `info` does not.
pub(crate) fn progress(len: u64, message: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    let style = ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {elapsed}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    bar.set_style(style);
    bar.set_message(message.to_owned());
    bar
}

/// One progress bar per stage of a library pipeline that reports [`ScanProgress`]
/// (`scan_virtual`, `reconstruct_session`), created when the stage first reports.
pub(crate) struct StageBars {
    bars: MultiProgress,
    by_stage: HashMap<String, ProgressBar>,
}

impl StageBars {
    /// No bars yet.
    pub(crate) fn new() -> Self {
        Self {
            bars: MultiProgress::new(),
            by_stage: HashMap::new(),
        }
    }

    /// Moves the bar of `p.stage` (creating it) to `p.done` of `p.total`.
    pub(crate) fn update(&mut self, p: ScanProgress<'_>) {
        let bars = &self.bars;
        let bar = self
            .by_stage
            .entry(p.stage.to_owned())
            .or_insert_with(|| bars.add(progress(p.total as u64, p.stage)));
        bar.set_position(p.done as u64);
        if p.done == p.total {
            bar.finish();
        }
    }

    /// Removes every bar from the terminal.
    pub(crate) fn clear(self) {
        for bar in self.by_stage.values() {
            bar.finish_and_clear();
        }
    }
}

/// Every file below `dir` (recursively, in no particular order): for tests of what a command
/// wrote.
#[cfg(test)]
pub(crate) fn files_below(dir: &Path) -> Vec<PathBuf> {
    let mut all = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                all.push(p);
            }
        }
    }
    all
}
