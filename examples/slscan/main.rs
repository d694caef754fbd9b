//! `slscan`: the command line of the structured-light scanner.
//!
//! Thin by design: each subcommand parses its arguments, calls the libraries of the workspace
//! and writes files. Conventions shared by every subcommand (see `common.rs`):
//! - outputs go to the folder given by `--out` (created when missing);
//! - a `report.json` there holds the figures and the per-stage timings in milliseconds;
//! - anything that can take more than a second shows a progress bar on stderr;
//! - a bad input ends with one line `slscan: error: …` naming the file or parameter, and exit
//!   code 1 (2 for a malformed command line, as clap does).

/// `println!` that a closed pipe does not end (`slscan info cloud.ply | head -1`): see
/// [`common::print_line`].
macro_rules! outln {
    () => {
        $crate::common::print_line(format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::common::print_line(format_args!($($arg)*))
    };
}

/// `print!` that a closed pipe does not end: see [`common::print_text`].
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::common::print_text(format_args!($($arg)*))
    };
}

/// `eprintln!` that a closed standard error does not end: see [`common::print_error_line`].
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::common::print_error_line(format_args!($($arg)*))
    };
}

mod align;
/// The synthetic blob of sl-icp's registration tests, for the align, merge and register tests.
#[cfg(test)]
#[path = "../../crates/sl-icp/tests/it/support/blob.rs"]
mod blob_support;
/// The Stanford bunny loader of sl-icp's tests (`$SL_DATA/bunny`), for the mesh tests.
#[cfg(test)]
#[path = "../../crates/sl-icp/tests/it/support/bunny.rs"]
mod bunny_support;
mod calibrate;
mod calibrate_capture;
mod calibrate_response;
#[cfg(test)]
mod calibrate_stereo_tests;
mod capture;
mod common;
mod decode;
mod devices;
mod info;
mod merge;
mod mesh;
#[cfg(test)]
mod outputs_tests;
mod patterns;
mod reconstruct;
mod register;
mod report;
mod scan;
mod scan_hardware;
mod simulate;
#[cfg(test)]
mod sweep_tests;
mod values;

use clap::{Parser, Subcommand};

/// Structured-light 3-D scanning with a projector, a camera and a turntable.
#[derive(Debug, Parser)]
#[command(name = "slscan", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Summarise a point cloud (PLY) or a calibration file (JSON, OpenCV YAML/XML).
    Info(info::Args),
    /// List the V4L2 cameras, monitors and serial ports a rig can use, and the features not built.
    Devices(devices::Args),
    /// Calibrate the camera or the turntable axis from checkerboard pictures: calibration.json,
    /// report.json and pictures.
    Calibrate(calibrate::Args),
    /// Write pattern images and their manifest.json for a projector.
    Patterns(patterns::Args),
    /// Decode a capture set into projector column/row maps, pictures and report.json.
    Decode(decode::Args),
    /// Render capture sets and their ground truth with the virtual rig.
    Simulate(simulate::Args),
    /// Decode a capture set and triangulate it: PLY, depth maps, preview, report.
    Reconstruct(reconstruct::Args),
    /// Register one cloud onto another (ICP): moved cloud, transform, preview, report.
    Register(register::Args),
    /// Align scans given in any order with no poses (global registration): aligned cloud,
    /// poses, preview, report.
    Align(align::Args),
    /// Register and merge the views of a turntable scan: merged cloud, poses, preview, report.
    Merge(merge::Args),
    /// A watertight mesh from a cloud with normals (screened Poisson): mesh.ply, mesh.stl,
    /// preview.png, an interactive 3-D view (mesh.html) and report.json.
    Mesh(mesh::Args),
    /// Run one capture session (virtual rig by default, or real devices); resumes when
    /// interrupted.
    Capture(capture::Args),
    /// The whole scan on the virtual rig: calibrate, capture, decode, triangulate, merge,
    /// accuracy report, previews and index.html.
    Scan(scan::Args),
    /// Measure a cloud against a truth file (VDI/VDE 2634 part 2: probing form and size,
    /// sphere spacing, flatness): report.json and an error heat map.
    Report(report::Args),
}

fn main() -> std::process::ExitCode {
    match run(Cli::parse().command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            common::print_error(&err);
            std::process::ExitCode::FAILURE
        }
    }
}

/// The checks of a subcommand's options that need more than one value (`--period-px` against
/// `--projector`, `--min-depth` against `--max-depth`, …): each subcommand's `run` makes them
/// first, before anything is read or written; each names the options as given. The checks of
/// single values are clap's (`values.rs`); those that need the data (a depth scale against the
/// cloud's depths) are made where the data is. The sweep of every option (`sweep_tests.rs`)
/// calls this for the subcommands too slow to run.
#[cfg(test)]
fn validate(command: &Command) -> anyhow::Result<()> {
    match command {
        Command::Patterns(args) => patterns::check(args),
        Command::Reconstruct(args) => reconstruct::check(args),
        Command::Calibrate(args) => match &args.what {
            calibrate::What::Capture(a) => calibrate_capture::check(a),
            _ => Ok(()),
        },
        Command::Scan(args) => scan::check(args),
        Command::Merge(args) => merge::check(args),
        Command::Capture(args) => capture::check(args),
        Command::Info(_)
        | Command::Devices(_)
        | Command::Decode(_)
        | Command::Simulate(_)
        | Command::Register(_)
        | Command::Mesh(_)
        | Command::Align(_)
        | Command::Report(_) => Ok(()),
    }
}

/// Runs one subcommand.
fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Info(args) => info::run(&args),
        Command::Devices(args) => devices::run(&args),
        Command::Calibrate(args) => calibrate::run(&args),
        Command::Patterns(args) => patterns::run(&args),
        Command::Decode(args) => decode::run(&args),
        Command::Simulate(args) => simulate::run(&args),
        Command::Reconstruct(args) => reconstruct::run(&args),
        Command::Register(args) => register::run(&args),
        Command::Merge(args) => merge::run(&args),
        Command::Mesh(args) => mesh::run(&args),
        Command::Align(args) => align::run(&args),
        Command::Capture(args) => capture::run(&args),
        Command::Scan(args) => scan::run(&args),
        Command::Report(args) => report::run(&args),
    }
}

/// Runs `slscan ARGS…` in this process, as the shell would (the tests' way in): the command
/// line parsed, then the subcommand.
#[cfg(test)]
fn run_cli(args: &[&str]) -> anyhow::Result<()> {
    let argv = std::iter::once("slscan").chain(args.iter().copied());
    run(Cli::try_parse_from(argv)?.command)
}
