//! Output folders that nothing destroys: a failed run leaves the last good outputs in place, two
//! runs never write into one folder at once, and a run does not replace its own inputs.
//!
//! A command opens its `--out` folder as an [`OutputFolder`]:
//! - **Staged** ([`OutputFolder::staged`]): the command writes into a staging folder inside the
//!   output folder ([`OutputFolder::path`]); [`OutputFolder::commit`] renames each file into
//!   place when the command has succeeded and removes the files the previous run there wrote
//!   and this one did not, so the folder holds one run's outputs, whole. Dropped without a commit
//!   (an error, a panic), the staging folder goes and the folder is as it was; a run killed
//!   outright leaves a staging folder that the next run into the folder removes.
//! - **In place** ([`OutputFolder::in_place`]): for capture sessions, which are written frame by
//!   frame so that an interrupted capture resumes. Locked like a staged folder; the session
//!   checks its own plan before it writes (`sl_rig::CaptureSession::check`).
//!
//! Either way the folder is locked for the run: a lock on [`LOCK_FILE`] (released by the
//! operating system when the process ends, however it ends), which also names the holder, so
//! that a second run is refused with the holder's process id instead of mixing its files with
//! the first's.
//!
//! The list of the files a staged run wrote is kept in [`OUTPUTS_FILE`]. A staged run whose
//! inputs include one of those files (`slscan mesh D/mesh.ply --out D`) or whose declared output
//! is one of its inputs (`slscan merge a.ply b.ply --out a.ply`) is refused before it writes
//! anything, unless it is forced ([`Inputs::force`]): its commit would replace or remove them.

use std::fs::{self, File, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The lock file of an output folder: locked for the length of a run; it holds the holder's
/// process id and command, for the message of a refused second run.
pub const LOCK_FILE: &str = ".slscan.lock";
/// The files the last staged run wrote into an output folder (JSON: the command and the paths
/// relative to the folder).
pub const OUTPUTS_FILE: &str = ".slscan-outputs.json";
/// Where a failed staged run's outputs are kept, when the command asks for it
/// ([`OutputFolder::keep_as_failed`]), for the diagnosis.
pub const FAILED_RUN_DIR: &str = "failed-run";
/// The staging folders: `.slscan-staging-<pid>`.
const STAGING_PREFIX: &str = ".slscan-staging-";
/// Marks a [`FAILED_RUN_DIR`] as written by this module, so that the next one may replace it.
const FAILED_RUN_MARK: &str = ".slscan-failed-run";

/// Why an output folder could not be opened or its outputs put in place.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// Another run holds the folder.
    #[error(
        "{}: another run is writing into this folder ({holder}); wait for it to end or choose another output folder",
        dir.display()
    )]
    Busy {
        /// The output folder.
        dir: PathBuf,
        /// The holder, as its lock file names it (`pid 1234, slscan reconstruct`).
        holder: String,
    },
    /// An input of the run would be replaced or removed when its outputs are put in place.
    #[error(
        "{}: the output folder holds the input {}, which this run would {}; choose another output folder, or force it",
        dir.display(),
        input.display(),
        if *replaced { "replace" } else { "remove (an earlier run wrote it there)" }
    )]
    InputInOutput {
        /// The output folder.
        dir: PathBuf,
        /// The input.
        input: PathBuf,
        /// `true` when the run writes a file of that name; `false` when the file is an output
        /// of the previous run there that the commit removes.
        replaced: bool,
    },
    /// The folder holds what another command wrote, which this run's outputs would mix with.
    #[error(
        "{}: the output folder holds what `{command}` wrote; choose another output folder, or force it",
        dir.display()
    )]
    OtherCommand {
        /// The output folder.
        dir: PathBuf,
        /// The command that wrote the folder's outputs.
        command: String,
    },
    /// The output path exists and is not a folder.
    #[error("{}: exists and is not a folder", path.display())]
    NotAFolder {
        /// The path.
        path: PathBuf,
    },
    /// Reading or writing a file or folder.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The error.
        #[source]
        source: std::io::Error,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// What a staged run reads and what it will certainly write, for the check that it does not
/// replace its own inputs. Name the files read: a folder given as input is compared as a
/// whole (the outputs list holds files only), so give a capture's `manifest.json`, not the
/// capture folder.
#[derive(Debug, Clone, Default)]
pub struct Inputs<'a> {
    /// The files and folders the run reads.
    pub read: Vec<&'a Path>,
    /// Files the run writes whose names are known before it starts (relative to the output
    /// folder, or absolute inside it): `slscan merge --out a.ply`'s `a.ply`.
    pub written: Vec<&'a Path>,
    /// Replace inputs all the same (`--force`).
    pub force: bool,
}

/// The list kept in [`OUTPUTS_FILE`].
#[derive(Debug, Serialize, Deserialize)]
struct OutputList {
    /// The command that wrote the files.
    command: String,
    /// The files, relative to the output folder, `/`-separated (none for a run in place).
    files: Vec<String>,
    /// Written in place (a capture session): its files are not listed.
    #[serde(default)]
    in_place: bool,
}

/// An output folder opened for one run; see the [module documentation](self).
#[derive(Debug)]
pub struct OutputFolder {
    dir: PathBuf,
    staging: Option<PathBuf>,
    command: String,
    /// The run created the folder: one that fails removes it again when it is left empty.
    created: bool,
    /// The outputs were put in place.
    committed: bool,
    /// Held for the run; closing it releases the lock.
    _lock: File,
}

impl OutputFolder {
    /// Opens `dir` for a staged run of `command` (a name for the lock file and the output list,
    /// `slscan reconstruct`): checks `inputs`, creates the folder if needed, locks it, removes
    /// what killed runs left, and creates the staging folder.
    ///
    /// # Errors
    /// [`OutputError::InputInOutput`] (nothing written), [`OutputError::Busy`],
    /// [`OutputError::NotAFolder`], [`OutputError::Io`].
    pub fn staged(dir: &Path, command: &str, inputs: &Inputs<'_>) -> Result<Self, OutputError> {
        check_inputs(dir, command, inputs)?;
        let mut folder = Self::lock(dir, command)?;
        // Checked again under the lock: a run that ended meanwhile may have changed the list.
        check_inputs(dir, command, inputs)?;
        remove_stale_staging(dir)?;
        let staging = dir.join(format!("{STAGING_PREFIX}{}", std::process::id()));
        fs::create_dir(&staging).map_err(io(&staging))?;
        folder.staging = Some(staging);
        Ok(folder)
    }

    /// Opens `dir` for a run that writes in place (a capture session, resumed when interrupted):
    /// creates the folder if needed and locks it.
    ///
    /// # Errors
    /// [`OutputError::Busy`], [`OutputError::NotAFolder`], [`OutputError::Io`].
    pub fn in_place(dir: &Path, command: &str) -> Result<Self, OutputError> {
        Self::lock(dir, command)
    }

    fn lock(dir: &Path, command: &str) -> Result<Self, OutputError> {
        if dir.exists() && !dir.is_dir() {
            return Err(OutputError::NotAFolder {
                path: dir.to_path_buf(),
            });
        }
        let created = !dir.exists();
        fs::create_dir_all(dir).map_err(io(dir))?;
        let path = dir.join(LOCK_FILE);
        let mut file = loop {
            let mut file = File::options()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io(&path))?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let mut holder = String::new();
                    // The holder wrote its line right after it locked; a read that races it
                    // gives an empty name, not a wrong one.
                    let _ = file.read_to_string(&mut holder);
                    let holder = holder.trim();
                    return Err(OutputError::Busy {
                        dir: dir.to_path_buf(),
                        holder: if holder.is_empty() {
                            "a process that has not yet said which".to_owned()
                        } else {
                            holder.to_owned()
                        },
                    });
                }
                // A file system without locks (some network shares): the run goes on
                // unlocked, as it would have before locks existed, rather than not at all.
                Err(TryLockError::Error(e)) if e.kind() == std::io::ErrorKind::Unsupported => {}
                Err(TryLockError::Error(e)) => return Err(io(&path)(e)),
            }
            // The holder before us removes the file before it lets go: if we locked a file
            // that is no longer the one at `path`, another run may hold the new one.
            if same_file(&file, &path) {
                break file;
            }
        };
        file.set_len(0).map_err(io(&path))?;
        file.rewind().map_err(io(&path))?;
        writeln!(file, "pid {}, {command}", std::process::id()).map_err(io(&path))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            staging: None,
            command: command.to_owned(),
            created,
            committed: false,
            _lock: file,
        })
    }

    /// Where the run writes now: the staging folder of a staged run, the folder itself
    /// otherwise. Nothing written here should name this path (it is gone after the commit):
    /// name files relative to it, or through [`OutputFolder::dir`].
    pub fn path(&self) -> &Path {
        self.staging.as_deref().unwrap_or(&self.dir)
    }

    /// The output folder, where the outputs are once committed.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Where a file written at `staged` (under [`OutputFolder::path`]) will be once committed.
    pub fn final_path(&self, staged: &Path) -> PathBuf {
        match staged.strip_prefix(self.path()) {
            Ok(rel) => self.dir.join(rel),
            Err(_) => staged.to_path_buf(),
        }
    }

    /// Puts a staged run's outputs in place: renames each file into the folder (one file at a
    /// time, each rename atomic), removes the files the previous run of the same command there
    /// wrote and this one did not, and records this run's list. Returns the files, in place.
    /// For an in-place run, records that the command wrote the folder and releases the lock.
    ///
    /// # Errors
    /// [`OutputError::Io`] naming the file that could not be moved (the files moved before it
    /// stay; the rest stay in the staging folder until the next run there).
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        self.committed = true;
        let Some(staging) = self.staging.take() else {
            self.write_list(Vec::new(), true)?;
            return Ok(Vec::new());
        };
        let files = files_below(&staging)?;
        let previous = read_output_list(&self.dir);
        let mut moved = Vec::with_capacity(files.len());
        let mut names = Vec::with_capacity(files.len());
        for rel in &files {
            let from = staging.join(rel);
            let to = self.dir.join(rel);
            if let Some(parent) = to.parent() {
                fs::create_dir_all(parent).map_err(io(parent))?;
            }
            if to.is_dir() {
                return Err(io(&to)(std::io::Error::other(
                    "a folder is in the way of an output file of that name",
                )));
            }
            fs::rename(&from, &to).map_err(io(&to))?;
            names.push(slash_path(rel));
            moved.push(to);
        }
        if let Some(previous) = previous.filter(|p| p.command == self.command) {
            for old in previous.files.iter().filter(|f| !names.contains(f)) {
                let Some(rel) = safe_relative(old) else {
                    continue;
                };
                let path = self.dir.join(&rel);
                if path.is_file() && fs::remove_file(&path).is_ok() {
                    remove_empty_parents(&self.dir, &rel);
                }
            }
        }
        self.write_list(names, false)?;
        fs::remove_dir_all(&staging).map_err(io(&staging))?;
        // A failure kept for the diagnosis is history once a run has succeeded.
        let failed = self.dir.join(FAILED_RUN_DIR);
        if failed.join(FAILED_RUN_MARK).is_file() {
            fs::remove_dir_all(&failed).map_err(io(&failed))?;
        }
        Ok(moved)
    }

    /// Records this run's files in [`OUTPUTS_FILE`].
    fn write_list(&self, files: Vec<String>, in_place: bool) -> Result<(), OutputError> {
        let path = self.dir.join(OUTPUTS_FILE);
        let list = OutputList {
            command: self.command.clone(),
            files,
            in_place,
        };
        let text = serde_json::to_string_pretty(&list)
            .map_err(|e| io(&path)(std::io::Error::other(e.to_string())))?;
        crate::write_atomically(&path, text.as_bytes())
            .map_err(|e| io(&path)(std::io::Error::other(e.to_string())))
    }

    /// Ends a failed staged run keeping what it wrote, for the diagnosis, in
    /// [`FAILED_RUN_DIR`] inside the folder (replacing the one an earlier failed run left);
    /// the folder's outputs stay as they were. Returns that folder.
    ///
    /// # Errors
    /// [`OutputError::Io`] naming the folder.
    pub fn keep_as_failed(mut self) -> Result<PathBuf, OutputError> {
        let Some(staging) = self.staging.take() else {
            return Ok(self.dir.clone());
        };
        let failed = self.dir.join(FAILED_RUN_DIR);
        if failed.join(FAILED_RUN_MARK).is_file() {
            fs::remove_dir_all(&failed).map_err(io(&failed))?;
        }
        fs::write(staging.join(FAILED_RUN_MARK), format!("{}\n", self.command))
            .map_err(io(&staging))?;
        fs::rename(&staging, &failed).map_err(io(&failed))?;
        Ok(failed)
    }
}

impl Drop for OutputFolder {
    fn drop(&mut self) {
        // Not committed: the outputs already in the folder stay as they were.
        if let Some(staging) = self.staging.take() {
            let _ = fs::remove_dir_all(staging);
        }
        // The lock file goes while still locked (a run that opened it meanwhile sees, once it
        // has the lock, that it is no longer the file at the path, and starts over): the
        // folder is left as the run found it, or with its outputs only.
        let _ = fs::remove_file(self.dir.join(LOCK_FILE));
        // A folder this run made and left empty goes with it.
        if self.created && !self.committed {
            let _ = fs::remove_dir(&self.dir);
        }
    }
}

/// Whether `file` is the file at `path` now.
#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// Whether `file` is the file at `path` now (elsewhere: assumed; the race it guards against
/// needs two runs starting within microseconds of a third ending).
#[cfg(not(unix))]
fn same_file(_file: &File, _path: &Path) -> bool {
    true
}

/// Refuses a run of `command` that would replace or remove one of its inputs, or mix its
/// outputs with another command's.
fn check_inputs(dir: &Path, command: &str, inputs: &Inputs<'_>) -> Result<(), OutputError> {
    if inputs.force {
        return Ok(());
    }
    let previous = read_output_list(dir);
    if let Some(p) = previous.as_ref().filter(|p| p.command != command) {
        return Err(OutputError::OtherCommand {
            dir: dir.to_path_buf(),
            command: p.command.clone(),
        });
    }
    let read: Vec<PathBuf> = inputs
        .read
        .iter()
        .filter_map(|p| fs::canonicalize(p).ok())
        .collect();
    // Files only: an output below an input folder (`decode CAPTURE --out CAPTURE/decoded`)
    // replaces nothing the run reads; commands name the files they read in a folder.
    let clash = |candidate: &Path| {
        let c = fs::canonicalize(candidate).ok()?;
        read.iter().find(|r| c == **r).cloned()
    };
    for w in &inputs.written {
        let path = if w.is_absolute() {
            w.to_path_buf()
        } else {
            dir.join(w)
        };
        if let Some(input) = clash(&path) {
            return Err(OutputError::InputInOutput {
                dir: dir.to_path_buf(),
                input,
                replaced: true,
            });
        }
    }
    if let Some(previous) = previous {
        for rel in previous.files.iter().filter_map(|f| safe_relative(f)) {
            if let Some(input) = clash(&dir.join(rel)) {
                return Err(OutputError::InputInOutput {
                    dir: dir.to_path_buf(),
                    input,
                    replaced: false,
                });
            }
        }
    }
    Ok(())
}

/// The previous staged run's list, if there is a readable one.
fn read_output_list(dir: &Path) -> Option<OutputList> {
    let text = fs::read_to_string(dir.join(OUTPUTS_FILE)).ok()?;
    serde_json::from_str(&text).ok()
}

/// A listed path, if it stays inside the folder (no `..`, not absolute): a list edited by hand
/// must not make a commit remove files elsewhere.
fn safe_relative(listed: &str) -> Option<PathBuf> {
    let p = PathBuf::from(listed);
    p.components()
        .all(|c| matches!(c, Component::Normal(_)))
        .then_some(p)
}

/// `rel` with `/` separators, as the list stores it.
fn slash_path(rel: &Path) -> String {
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// Every file below `root`, relative to it, in a stable order.
fn files_below(root: &Path) -> Result<Vec<PathBuf>, OutputError> {
    let mut files = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        let dir = root.join(&rel);
        for entry in fs::read_dir(&dir).map_err(io(&dir))? {
            let entry = entry.map_err(io(&dir))?;
            let child = rel.join(entry.file_name());
            if entry.file_type().map_err(io(&dir))?.is_dir() {
                stack.push(child);
            } else {
                files.push(child);
            }
        }
    }
    files.sort();
    Ok(files)
}

/// Removes the folders of `rel` below `root` that its removal left empty.
fn remove_empty_parents(root: &Path, rel: &Path) {
    let mut parent = rel.parent();
    while let Some(p) = parent.filter(|p| !p.as_os_str().is_empty()) {
        if fs::remove_dir(root.join(p)).is_err() {
            break;
        }
        parent = p.parent();
    }
}

/// Removes the staging folders of runs that were killed (the caller holds the lock, so no live
/// run owns one).
fn remove_stale_staging(dir: &Path) -> Result<(), OutputError> {
    for entry in fs::read_dir(dir).map_err(io(dir))? {
        let entry = entry.map_err(io(dir))?;
        if entry
            .file_name()
            .to_string_lossy()
            .starts_with(STAGING_PREFIX)
        {
            let path = entry.path();
            fs::remove_dir_all(&path).map_err(io(&path))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(path: &Path, text: &str) {
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(path, text).unwrap();
    }

    fn read(path: &Path) -> String {
        fs::read_to_string(path).unwrap()
    }

    /// A committed run replaces the previous run's files and removes the ones it did not write;
    /// a run dropped without a commit leaves the folder as it was.
    #[test]
    fn commit_replaces_a_failure_keeps() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        let first = OutputFolder::staged(&dir, "decode", &Inputs::default()).unwrap();
        write(&first.path().join("a.txt"), "a1");
        write(&first.path().join("sub/b.txt"), "b1");
        assert!(!dir.join("a.txt").exists(), "visible before the commit");
        first.commit().unwrap();
        assert_eq!(read(&dir.join("a.txt")), "a1");
        assert_eq!(read(&dir.join("sub/b.txt")), "b1");

        let failed = OutputFolder::staged(&dir, "decode", &Inputs::default()).unwrap();
        write(&failed.path().join("a.txt"), "a2");
        drop(failed);
        assert_eq!(read(&dir.join("a.txt")), "a1");
        assert_eq!(read(&dir.join("sub/b.txt")), "b1");

        let second = OutputFolder::staged(&dir, "decode", &Inputs::default()).unwrap();
        write(&second.path().join("a.txt"), "a2");
        let moved = second.commit().unwrap();
        assert_eq!(moved, vec![dir.join("a.txt")]);
        assert_eq!(read(&dir.join("a.txt")), "a2");
        assert!(
            !dir.join("sub").exists(),
            "the first run's b.txt and its folder stay"
        );
        let names: Vec<String> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with(".slscan"))
            .collect();
        assert_eq!(names, ["a.txt"]);
    }

    /// A second opening of a held folder is refused naming the holder; once the holder is gone
    /// it opens.
    #[test]
    fn a_held_folder_is_refused_with_its_holder() {
        let tmp = tempfile::tempdir().unwrap();
        let held = OutputFolder::in_place(tmp.path(), "slscan capture").unwrap();
        let err = OutputFolder::staged(tmp.path(), "slscan decode", &Inputs::default())
            .unwrap_err()
            .to_string();
        let pid = std::process::id();
        assert!(err.contains(&format!("pid {pid}, slscan capture")), "{err}");
        drop(held);
        OutputFolder::staged(tmp.path(), "slscan decode", &Inputs::default()).unwrap();
    }

    /// An input among the previous run's outputs, or an output named as an input, is refused
    /// before anything is written; forced, the run goes on.
    #[test]
    fn inputs_are_not_replaced_unless_forced() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        let run = OutputFolder::staged(&dir, "mesh", &Inputs::default()).unwrap();
        write(&run.path().join("mesh.ply"), "m1");
        run.commit().unwrap();
        let input = dir.join("mesh.ply");
        let inputs = Inputs {
            read: vec![&input],
            ..Inputs::default()
        };
        let err = OutputFolder::staged(&dir, "mesh", &inputs).unwrap_err();
        assert!(
            matches!(
                err,
                OutputError::InputInOutput {
                    replaced: false,
                    ..
                }
            ),
            "{err}"
        );
        assert!(fs::read_dir(&dir).unwrap().all(|e| {
            !e.unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(STAGING_PREFIX)
        }));

        let elsewhere = tmp.path().join("a.ply");
        write(&elsewhere, "a");
        let inputs = Inputs {
            read: vec![&elsewhere],
            written: vec![Path::new("a.ply")],
            force: false,
        };
        let err = OutputFolder::staged(tmp.path(), "merge", &inputs).unwrap_err();
        assert!(
            matches!(err, OutputError::InputInOutput { replaced: true, .. }),
            "{err}"
        );
        let forced = Inputs {
            force: true,
            ..inputs
        };
        OutputFolder::staged(tmp.path(), "merge", &forced).unwrap();
    }

    /// A folder another command wrote (in place or staged) is refused; forced, the run
    /// replaces files of the same names and removes none of the other's.
    #[test]
    fn another_commands_folder_is_refused_unless_forced() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let scan = OutputFolder::in_place(dir, "slscan scan").unwrap();
        write(&scan.path().join("report.json"), "scan");
        write(&scan.path().join("merged.ply"), "cloud");
        scan.commit().unwrap();
        let err = OutputFolder::staged(dir, "slscan report", &Inputs::default()).unwrap_err();
        assert!(err.to_string().contains("`slscan scan`"), "{err}");
        assert_eq!(read(&dir.join("report.json")), "scan");
        let forced = Inputs {
            force: true,
            ..Inputs::default()
        };
        let report = OutputFolder::staged(dir, "slscan report", &forced).unwrap();
        write(&report.path().join("report.json"), "report");
        report.commit().unwrap();
        assert_eq!(read(&dir.join("report.json")), "report");
        assert_eq!(read(&dir.join("merged.ply")), "cloud");
    }

    /// A failed run into a folder it created leaves no folder behind.
    #[test]
    fn a_failed_run_leaves_no_new_folder() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("new");
        let run = OutputFolder::staged(&dir, "decode", &Inputs::default()).unwrap();
        write(&run.path().join("report.json"), "x");
        drop(run);
        assert!(!dir.exists());
        let run = OutputFolder::in_place(&dir, "capture").unwrap();
        drop(run);
        assert!(!dir.exists());
    }

    /// A killed run's staging folder is removed by the next run; a failed run kept for the
    /// diagnosis replaces the previous failed run, not the outputs.
    #[test]
    fn leftovers_are_cleared_and_failures_kept_apart() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        fs::create_dir_all(dir.join(".slscan-staging-999999/x")).unwrap();
        let run = OutputFolder::staged(dir, "decode", &Inputs::default()).unwrap();
        assert!(!dir.join(".slscan-staging-999999").exists());
        write(&run.path().join("report.json"), "good");
        run.commit().unwrap();
        for text in ["bad1", "bad2"] {
            let run = OutputFolder::staged(dir, "decode", &Inputs::default()).unwrap();
            write(&run.path().join("report.json"), text);
            let kept = run.keep_as_failed().unwrap();
            assert_eq!(kept, dir.join(FAILED_RUN_DIR));
            assert_eq!(read(&kept.join("report.json")), text);
        }
        assert_eq!(read(&dir.join("report.json")), "good");
    }
}
