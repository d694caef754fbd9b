//! Helpers shared by every `slscan` subcommand: the output folder, `report.json` with
//! per-stage timings, progress bars and the one-line error report.

use std::collections::HashMap;
use std::fmt;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use sl_scan::{Inputs, OutputError, OutputFolder};
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
    print_error_line(format_args!("slscan: error: {line}"));
}

/// Set once standard output could not be written (a closed pipe, a full disk).
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);
/// Set once standard error could not be written.
static STDERR_CLOSED: AtomicBool = AtomicBool::new(false);

/// Writes one line to standard output, as `println!` does, except that a reader that went away
/// (`slscan info cloud.ply | head -1`) does not end the program: `println!` panics there ("failed
/// printing to stdout: Broken pipe", exit 101, outputs half written). The first failed write
/// closes standard output for the rest of the run; the command carries on, writes its files in
/// full and exits as it would have.
pub(crate) fn print_line(args: fmt::Arguments<'_>) {
    emit(Stream::Out, args, true);
}

/// [`print_line`] without the newline.
pub(crate) fn print_text(args: fmt::Arguments<'_>) {
    emit(Stream::Out, args, false);
}

/// [`print_line`] for standard error (warnings, the error line).
pub(crate) fn print_error_line(args: fmt::Arguments<'_>) {
    emit(Stream::Err, args, true);
}

/// Standard output or error.
#[derive(Clone, Copy)]
enum Stream {
    Out,
    Err,
}

/// Writes `args` (and a newline) to `stream`, which a failed write closes for the run.
fn emit(stream: Stream, args: fmt::Arguments<'_>, newline: bool) {
    #[cfg(test)]
    if !pipe_tests::DIRECT.load(Ordering::Relaxed) {
        // The test harness captures the print macros, not writes to the streams.
        let end = if newline { "\n" } else { "" };
        match stream {
            Stream::Out => print!("{args}{end}"),
            Stream::Err => eprint!("{args}{end}"),
        }
        return;
    }
    match stream {
        Stream::Out => write_or_close(&STDOUT_CLOSED, &mut std::io::stdout().lock(), args, newline),
        Stream::Err => write_or_close(&STDERR_CLOSED, &mut std::io::stderr().lock(), args, newline),
    }
}

/// Writes `args` (and a newline) to `stream` unless `closed` is set; sets it when the write
/// fails.
fn write_or_close(
    closed: &AtomicBool,
    stream: &mut dyn Write,
    args: fmt::Arguments<'_>,
    newline: bool,
) {
    if closed.load(Ordering::Relaxed) {
        return;
    }
    let written = stream
        .write_fmt(args)
        .and_then(|()| {
            if newline {
                stream.write_all(b"\n")
            } else {
                Ok(())
            }
        })
        .and_then(|()| stream.flush());
    if written.is_err() {
        closed.store(true, Ordering::Relaxed);
    }
}

/// Creates the output folder (and its parents) if needed, naming it on failure.
pub(crate) fn ensure_out_dir(out: &Path) -> anyhow::Result<PathBuf> {
    fs::create_dir_all(out)
        .with_context(|| format!("cannot create output folder {}", out.display()))?;
    Ok(out.to_path_buf())
}

/// Opens `--out` for a run of `slscan COMMAND` that writes its outputs only when it succeeds
/// ([`OutputFolder::staged`]): nothing of an earlier run is lost when this one fails, a second
/// run into the folder is refused naming the first, and a run whose outputs would replace
/// the files it reads (`read`; `written`: output files named before the run) is refused
/// unless `force` (`--force`). Write into [`OutputFolder::path`], then
/// [`OutputFolder::commit`].
pub(crate) fn open_out(
    out: &Path,
    command: &str,
    read: &[&Path],
    written: &[&Path],
    force: bool,
) -> anyhow::Result<OutputFolder> {
    let inputs = Inputs {
        read: read.to_vec(),
        written: written.to_vec(),
        force,
    };
    OutputFolder::staged(out, &format!("slscan {command}"), &inputs).map_err(out_error)
}

/// Opens `--out` for a run that writes in place (a capture session, resumed when
/// interrupted): locked like [`open_out`], nothing staged.
pub(crate) fn open_out_in_place(out: &Path, command: &str) -> anyhow::Result<OutputFolder> {
    OutputFolder::in_place(out, &format!("slscan {command}")).map_err(out_error)
}

/// The manifest of a capture given as its folder or as the manifest itself: the file a
/// command reads, for [`open_out`]'s check.
pub(crate) fn manifest_file(capture: &Path) -> PathBuf {
    if capture.is_dir() {
        capture.join(sl_codec::MANIFEST_FILE)
    } else {
        capture.to_path_buf()
    }
}

/// `--out`'s error, with the option that overrides a refusal.
fn out_error(e: OutputError) -> anyhow::Error {
    match e {
        e @ (OutputError::InputInOutput { .. } | OutputError::OtherCommand { .. }) => {
            anyhow::Error::new(e).context("--out (--force writes all the same)")
        }
        e => anyhow::Error::new(e).context("--out"),
    }
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

#[cfg(all(test, unix))]
mod pipe_tests {
    //! `slscan … | head -1`: a reader that goes away does not end a command, which finishes
    //! its files. The commands run in a child process (this test binary, re-run on one test)
    //! whose standard output and error are pipes nobody reads any more.

    use std::path::Path;
    use std::process::Command;
    use std::sync::atomic::{AtomicBool, Ordering};

    /// Set in the child: the commands write to the process's streams themselves, as the
    /// binary does, instead of through the harness's capture.
    pub(super) static DIRECT: AtomicBool = AtomicBool::new(false);

    /// Tells the child half which folder to work in.
    const DIR_ENV: &str = "SLSCAN_PIPE_PROBE_DIR";

    /// The child half of [`a_closed_pipe_ends_nothing`]: points standard output and error at
    /// pipes whose reading ends are closed, runs `patterns`, `decode`, `info`, `devices` and
    /// `reconstruct`, then writes `finished` naming each command that returned `Ok`.
    #[test]
    #[ignore = "run by a_closed_pipe_ends_nothing in a child process"]
    fn closed_pipe_child() {
        let Some(dir) = std::env::var_os(DIR_ENV) else {
            return;
        };
        let dir = Path::new(&dir);
        let s = |p: &Path| p.to_str().unwrap().to_owned();
        let (patterns, decoded, view) =
            (dir.join("patterns"), dir.join("decoded"), dir.join("view"));
        let rebuilt = dir.join("rebuilt");
        std::fs::create_dir_all(&view).unwrap();
        let (capture, calib) = crate::reconstruct::tests::column_only_capture(&view);
        let commands: Vec<Vec<String>> = vec![
            [
                "patterns",
                "--projector",
                "64x32",
                "--axes",
                "columns",
                "--out",
            ]
            .iter()
            .map(ToString::to_string)
            .chain([s(&patterns)])
            .collect(),
            vec!["decode".into(), s(&patterns), "--out".into(), s(&decoded)],
            vec!["info".into(), s(&calib)],
            vec!["devices".into()],
            vec![
                "reconstruct".into(),
                s(&capture),
                "--calib".into(),
                s(&calib),
                "--out".into(),
                s(&rebuilt),
            ],
            vec!["info".into(), s(&rebuilt.join("cloud.ply"))],
        ];
        let (out_read, out_write) = rustix::pipe::pipe().unwrap();
        let (err_read, err_write) = rustix::pipe::pipe().unwrap();
        drop((out_read, err_read));
        rustix::stdio::dup2_stdout(&out_write).unwrap();
        rustix::stdio::dup2_stderr(&err_write).unwrap();
        DIRECT.store(true, Ordering::Relaxed);
        let mut finished = Vec::new();
        for argv in &commands {
            let argv: Vec<&str> = argv.iter().map(String::as_str).collect();
            if crate::run_cli(&argv).is_ok() {
                finished.push(argv[0]);
            }
        }
        std::fs::write(dir.join("finished"), finished.join(" ")).unwrap();
    }

    /// Every command finishes and writes all its files when nobody reads what it prints:
    /// before, the first line printed after the reader left panicked ("failed printing to
    /// stdout: Broken pipe", exit 101), and `decode` left no `report.json`.
    #[test]
    fn a_closed_pipe_ends_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let exe = std::env::current_exe().unwrap();
        let output = Command::new(exe)
            .args([
                "--exact",
                "common::pipe_tests::closed_pipe_child",
                "--ignored",
                "--nocapture",
            ])
            .env(DIR_ENV, dir.path())
            .output()
            .unwrap();
        let finished = std::fs::read_to_string(dir.path().join("finished")).unwrap_or_else(|_| {
            panic!(
                "the child did not finish ({}): {}",
                output.status,
                String::from_utf8_lossy(&output.stderr)
            )
        });
        assert_eq!(finished, "patterns decode info devices reconstruct info");
        for file in [
            "decoded/report.json",
            "rebuilt/report.json",
            "rebuilt/cloud.ply",
        ] {
            assert!(dir.path().join(file).is_file(), "{file} missing");
        }
    }
}
