//! Helpers shared by every `slscan` subcommand: the output folder, `report.json` with
//! per-stage timings, progress bars and the one-line error report.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::Context;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use structured_light::scan::ScanProgress;

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

/// The `report.json` of a command, and the atomic writes of every output: sl-scan's, shared
/// with the library pipelines.
pub(crate) use sl_scan::{RunReport as Report, write_atomically};

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

#[cfg(all(test, unix))]
mod tests {
    //! Output files follow the user's umask. The umask belongs to the whole process, so each
    //! umask is tried in a child process (this test binary, re-run through `sh -c 'umask …'`)
    //! rather than by changing it under the other tests running in parallel.

    use std::os::unix::fs::PermissionsExt;
    use std::path::PathBuf;
    use std::process::Command;

    use clap::Parser;

    /// Tells the child half which folder to write into.
    const PROBE_DIR_ENV: &str = "SLSCAN_UMASK_PROBE_DIR";

    /// The child half of [`outputs_follow_the_umask`]: runs `slscan patterns` (PNGs written
    /// directly, `report.json` through [`super::write_atomically`]) into the folder named by
    /// [`PROBE_DIR_ENV`]; does nothing when it is unset (a plain `cargo test --ignored`).
    #[test]
    #[ignore = "run by outputs_follow_the_umask in a child process with a chosen umask"]
    fn umask_probe_child() {
        let Some(dir) = std::env::var_os(PROBE_DIR_ENV) else {
            return;
        };
        let dir = PathBuf::from(dir);
        let argv = [
            "slscan",
            "patterns",
            "--projector",
            "64x32",
            "--axes",
            "columns",
            "--out",
            dir.to_str().unwrap(),
        ];
        match crate::Cli::try_parse_from(argv).unwrap().command {
            crate::Command::Patterns(a) => crate::patterns::run(&a).unwrap(),
            other => panic!("parsed as {other:?}"),
        }
    }

    /// With umask 022 every output, `report.json` included, is 0644; with 077 every one is 0600.
    #[test]
    fn outputs_follow_the_umask() {
        let exe = std::env::current_exe().unwrap();
        for (umask, mode) in [("022", 0o644), ("077", 0o600)] {
            let dir = tempfile::tempdir().unwrap();
            let status = Command::new("sh")
                .arg("-c")
                .arg(format!("umask {umask} && exec \"$0\" \"$@\""))
                .arg(&exe)
                .args([
                    "--exact",
                    "common::tests::umask_probe_child",
                    "--ignored",
                    "--quiet",
                ])
                .env(PROBE_DIR_ENV, dir.path())
                .status()
                .unwrap();
            assert!(status.success(), "child with umask {umask}: {status}");
            let files = super::files_below(dir.path());
            assert!(
                files.iter().any(|f| f.ends_with("report.json")),
                "no report.json in {files:?}"
            );
            assert!(files.len() > 2, "only {files:?}");
            for f in files {
                let got = std::fs::metadata(&f).unwrap().permissions().mode() & 0o777;
                assert_eq!(got, mode, "{} under umask {umask}: {got:o}", f.display());
            }
        }
    }
}
