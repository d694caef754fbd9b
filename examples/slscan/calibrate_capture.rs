//! `slscan calibrate capture --out SESSION`: capture a calibration session (the board at varied
//! poses under the patterns, then on the turntable) on the virtual rig (`--virtual`) or on real
//! devices (`--camera /dev/videoN --projector-monitor N --turntable /dev/ttyUSB0`), in the
//! layout `slscan calibrate all SESSION` reads.
//!
//! Interactive by default, in the terminal: each frame is checked (`board found: 54/54
//! corners, tilt 23 degrees`), the coverage of the image and the tilts is drawn with a hint for
//! the next pose; space or enter takes the pose, `d` drops the last one, `q` goes on to the
//! turntable. `--auto` takes the poses without keys. The engine is `sl_scan`'s
//! [`CalibrationCapture`]; this file is the user interface.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use sl_codec::{MANIFEST_FILE, Manifest};
use sl_rig::{Camera, Projector, Turntable};
use sl_scan::{
    AutoConfig, AutoEvent, BoardMover, CalibrationCapture, CalibrationCaptureConfig, HandHeld,
    TakeOutcome, VirtualBoardRig, calibration_turntable_angles, capture_poses_auto_with,
    wait_for_still_board,
};
use sl_sim::{BoardPoseConfig, Checkerboard};
use structured_light::scan::scaled_rig_config;

use crate::capture::HardwareArgs;
use crate::common::{Report, ensure_out_dir, open_out_in_place, write_atomically};
use crate::values;

/// Super-sampling of the virtual rig: corner accuracy needs well anti-aliased edges (as
/// `slscan simulate --scene board`).
const BOARD_SUPERSAMPLING: u32 = 4;

/// Fewest poses Zhang's calibration accepts (focal lengths, principal point and distortion
/// need three views of a plane).
const MIN_CALIBRATION_POSES: usize = 3;

/// How long a key is waited for between two frames of the interactive view: short, so the
/// view follows the board, long enough not to spin.
const KEY_POLL: Duration = Duration::from_millis(30);

/// Arguments of `slscan calibrate capture`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct Args {
    /// Session folder (created; an existing session continues: its poses are kept and
    /// numbering goes on).
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Board poses wanted in the session (at least 1).
    #[arg(long, default_value_t = 15, value_parser = values::at_least::<usize>(1))]
    pub(crate) poses: usize,
    /// Turntable views of the board on the platter, spread over -45..45 motor degrees (at most
    /// 360).
    #[arg(long, default_value_t = 7, value_parser = values::count_in::<usize>(0..=360))]
    pub(crate) turntable_angles: usize,
    /// Take each pose without a key press: the virtual board moves itself; a hand-held board
    /// is taken once it has been still for a second.
    #[arg(long)]
    pub(crate) auto: bool,
    /// Use the virtual rig (its board moves through seeded random poses).
    #[arg(long = "virtual")]
    pub(crate) virtual_rig: bool,
    /// With `--virtual`: the rig's second camera takes its own picture of every pose
    /// (`board/pose_NNN/right/white.png`, for `slscan calibrate stereo`); a pose it does not
    /// see whole is refused. On devices, name the second camera with `--right-camera`.
    #[arg(long)]
    pub(crate) binocular: bool,
    /// Inner corners of the board, `COLSxROWS` (2 to 100 each).
    #[arg(long, default_value = "9x6", value_parser = values::board_size)]
    pub(crate) board: sl_calib::BoardSize,
    /// Side of a square (mm, > 0, at most 1000).
    #[arg(long, default_value_t = 20.0, value_parser = values::positive_up_to(values::MAX_SQUARE_MM))]
    pub(crate) square: f64,
    /// Folder with the patterns' `manifest.json` (default: hybrid code on the columns and on
    /// the rows, 4 phase steps, 30 periods across).
    #[arg(long)]
    pub(crate) patterns: Option<PathBuf>,
    /// Virtual rig: divide its resolution by this (1 to 8).
    #[arg(long, default_value_t = 1, value_parser = values::downscale())]
    pub(crate) downscale: u32,
    /// Virtual rig: seed of the board poses and of the noise.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Wait after showing a pattern (ms, at most 10000); default 100 on hardware, 0 on the
    /// virtual rig.
    #[arg(long, value_parser = values::latency_ms())]
    pub(crate) latency_ms: Option<u64>,
    #[command(flatten)]
    pub(crate) hardware: HardwareArgs,
}

/// The checks of `slscan calibrate capture` that need more than one value.
pub(crate) fn check(args: &Args) -> anyhow::Result<()> {
    match (args.virtual_rig, args.hardware.any()) {
        (true, true) => anyhow::bail!(
            "--virtual and the device options (--camera, --projector-monitor, --turntable) exclude each other"
        ),
        (false, false) => anyhow::bail!(
            "give --virtual, or the devices: --camera /dev/videoN --projector-monitor N --turntable /dev/ttyUSB0"
        ),
        (false, true) if args.binocular => anyhow::bail!(
            "--binocular is the virtual rig's second camera: on devices, name the second camera with --right-camera"
        ),
        _ => Ok(()),
    }
}

/// Runs `slscan calibrate capture`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    check(args)?;
    // One run at a time in a session folder: two would mix their poses.
    let folder = open_out_in_place(&args.out, "calibrate capture")?;
    if args.virtual_rig {
        run_virtual(args)?;
    } else {
        run_hardware(args)?;
    }
    folder.commit()?;
    Ok(())
}

/// The board of `--board` and `--square`.
fn board(args: &Args) -> anyhow::Result<(sl_calib::BoardSize, f64)> {
    let size = args.board;
    anyhow::ensure!(
        args.square.is_finite() && args.square > 0.0,
        "--square {}: a square's side in mm, positive",
        args.square
    );
    Ok((size, args.square))
}

fn run_virtual(args: &Args) -> anyhow::Result<()> {
    let mut config = scaled_rig_config(args.downscale);
    config.render.supersampling = BOARD_SUPERSAMPLING;
    config.render.seed = args.seed;
    let (size, square_mm) = board(args)?;
    let board = Checkerboard {
        inner_cols: size.cols,
        inner_rows: size.rows,
        square_mm,
        ..Checkerboard::default()
    };
    let rig = VirtualBoardRig::new(
        config,
        board,
        &BoardPoseConfig {
            count: args.poses,
            seed: args.seed,
            ..BoardPoseConfig::default()
        },
    )?;
    let second = rig.rig().config().default_second_camera();
    let rig = if args.binocular {
        rig.with_second_camera(second)?
    } else {
        rig
    };
    let binocular = args.binocular;
    let out = args.out.clone();
    // The truth beside the session, as `slscan simulate` writes it: `rig.json` (which
    // `calibrate all` reads the projector size from) and the exact calibration; written once
    // the session has accepted the capture, so that a refused one leaves them as they were.
    let truth = rig.rig().config().clone();
    let write_truth = move || -> anyhow::Result<()> {
        let rig_json = serde_json::to_string_pretty(&truth).context("cannot serialise rig.json")?;
        write_atomically(&out.join("rig.json"), rig_json.as_bytes())?;
        truth
            .calibration()
            .save(out.join("calibration_true.json"))?;
        if binocular {
            truth
                .binocular_calibration()
                .save(out.join("calibration_true_pair.json"))?;
        }
        Ok(())
    };
    let (mut camera, mut projector, mut table, mut mover) = rig.devices();
    let mut right = rig.right_camera();
    run_devices(
        args,
        "virtual rig",
        &mut camera,
        right.as_mut().map(|r| r as &mut dyn Camera),
        &mut projector,
        &mut table,
        &mut mover,
        Duration::ZERO,
        write_truth,
    )
}

/// The capture on any devices: poses (interactive or `--auto`), then the turntable. The real
/// devices and the tests' virtual devices behind the same traits run this. `opened` runs once
/// the session folder has accepted the capture (files to write beside it).
#[allow(clippy::too_many_arguments)] // the devices, each its own trait
pub(crate) fn run_devices<C, P, T, M>(
    args: &Args,
    devices: &str,
    camera: &mut C,
    mut right: Option<&mut dyn Camera>,
    projector: &mut P,
    turntable: &mut T,
    mover: &mut M,
    default_latency: Duration,
    opened: impl FnOnce() -> anyhow::Result<()>,
) -> anyhow::Result<()>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
    T: Turntable + ?Sized,
    M: BoardMover + ?Sized,
{
    let mut report = Report::new("calibrate capture");
    let out = ensure_out_dir(&args.out)?;
    let (size, square_mm) = board(args)?;
    let mut config = CalibrationCaptureConfig::new(size, square_mm, projector.image_size());
    if let Some(dir) = &args.patterns {
        config.manifest = Manifest::load(&dir.join(MANIFEST_FILE))?;
    }
    config.display_latency = args
        .latency_ms
        .map_or(default_latency, Duration::from_millis);
    let mut session =
        CalibrationCapture::open(&out, config, camera.frame_size(), projector.image_size())?;
    opened()?;
    let kept = session.poses().len();
    outln!(
        "calibration capture into {} with the {devices}: {} poses wanted{}",
        out.display(),
        args.poses,
        if kept > 0 {
            format!(", {kept} kept from an earlier run")
        } else {
            String::new()
        }
    );
    let auto = AutoConfig {
        poses: args.poses,
        ..AutoConfig::default()
    };
    let counts = if args.auto {
        let mut refused = 0usize;
        let taken = report.stage("poses", || {
            let second = right.as_mut().map(|r| &mut **r as &mut dyn Camera);
            capture_poses_auto_with(&mut session, camera, second, projector, mover, &auto, |e| {
                match e {
                    AutoEvent::Taken { index, dir } => {
                        outln!("pose {index} taken: {}", dir.display());
                    }
                    AutoEvent::Refused(r) => {
                        refused += 1;
                        outln!("pose refused: {r}");
                    }
                    AutoEvent::Looked(_) => {}
                }
            })
        })?;
        Counts {
            taken,
            refused,
            dropped: 0,
        }
    } else {
        report.stage("poses", || {
            let second = right.as_mut().map(|r| &mut **r as &mut dyn Camera);
            interactive(&mut session, camera, second, projector, mover, args.poses)
        })?
    };
    let coverage = session.coverage();
    outln!("{}", coverage.draw());
    if session.poses().len() < MIN_CALIBRATION_POSES {
        outln!(
            "warning: {} poses; calibrate all needs at least {MIN_CALIBRATION_POSES} (10-20 give a good calibration): run again to add poses",
            session.poses().len()
        );
    }

    // The board on the platter; the turntable steps through its angles on its own.
    let angles = calibration_turntable_angles(args.turntable_angles);
    if !angles.is_empty() {
        mover.onto_turntable()?;
        if !mover.moves_itself() {
            outln!(
                "lay the board on the platter, upright and facing the camera{}",
                if args.auto {
                    " (taken once it is still)"
                } else {
                    ", then press enter"
                }
            );
            if args.auto {
                wait_for_still_board(&session, camera, projector, &auto, |_| {})?;
            } else {
                wait_for_enter()?;
            }
        }
        let views = report.stage("turntable", || {
            session.capture_turntable(camera, projector, turntable, &angles, |v| {
                outln!(
                    "turntable view at {:.2} degrees: {}{}",
                    v.motor_angle_deg,
                    if v.board_found {
                        "board found"
                    } else {
                        "board NOT found (calibrate skips this view)"
                    },
                    if v.kept {
                        " (kept from an earlier run)"
                    } else {
                        ""
                    }
                );
            })
        })?;
        report.figure("turntable_views", views.len());
        report.figure(
            "turntable_views_with_board",
            views.iter().filter(|v| v.board_found).count(),
        );
        turntable.rotate_to(0.0)?;
    }
    report.figure("poses", session.poses().len());
    report.figure("poses_taken_now", counts.taken);
    report.figure("poses_refused", counts.refused);
    report.figure("poses_dropped", counts.dropped);
    report.figure("coverage", serde_json::to_value(&coverage)?);
    report.figure("devices", devices);
    let path = report.write(&out)?;
    outln!(
        "{}: {} poses, {} turntable views (report: {}); next: slscan calibrate all {} --out calib",
        out.display(),
        session.poses().len(),
        angles.len(),
        path.display(),
        out.display()
    );
    Ok(())
}

/// Poses taken, refused and dropped in an interactive run.
#[derive(Debug, Default)]
struct Counts {
    taken: usize,
    refused: usize,
    dropped: usize,
}

/// The interactive pose loop: look, draw, act on a key.
fn interactive<C, P, M>(
    session: &mut CalibrationCapture,
    camera: &mut C,
    mut right: Option<&mut dyn Camera>,
    projector: &mut P,
    mover: &mut M,
    target: usize,
) -> anyhow::Result<Counts>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
    M: BoardMover + ?Sized,
{
    let keys = terminal::Keys::raw().context(
        "the interactive capture needs a terminal on standard input; use --auto in scripts",
    )?;
    let mut counts = Counts::default();
    let mut message = String::from("ready");
    loop {
        let check = session.look(camera, projector)?;
        let mut out = std::io::stdout().lock();
        // A terminal that cannot be written to has nothing to show: the capture goes on.
        let _ = out.write_all(
            session
                .screen(&check, target, &message, mover.moves_itself())
                .as_bytes(),
        );
        let _ = out.flush();
        let Some(key) = keys.next(KEY_POLL)? else {
            continue;
        };
        match key {
            b' ' | b'\r' | b'\n' => {
                let second = right.as_mut().map(|r| &mut **r as &mut dyn Camera);
                match session.take_with(&check, camera, second, projector)? {
                    TakeOutcome::Taken { index, dir } => {
                        counts.taken += 1;
                        message = format!("pose {index} taken: {}", dir.display());
                    }
                    TakeOutcome::Refused(r) => {
                        counts.refused += 1;
                        message = format!("refused: {r}");
                    }
                }
                if mover.moves_itself()
                    && let Err(e) = mover.next_pose()
                {
                    message = format!("{message}; {e}");
                }
            }
            b'd' => {
                message = match session.drop_last()? {
                    Some(dir) => {
                        counts.dropped += 1;
                        format!("dropped {}", dir.display())
                    }
                    None => "no pose to drop".to_owned(),
                };
            }
            b'n' if mover.moves_itself() => {
                message = match mover.next_pose() {
                    Ok(()) => "board moved".to_owned(),
                    Err(e) => e.to_string(),
                };
            }
            b'q' => break,
            _ => {}
        }
    }
    Ok(counts)
}

/// Waits for enter on standard input (line mode).
fn wait_for_enter() -> anyhow::Result<()> {
    let mut line = String::new();
    std::io::stdin()
        .read_line(&mut line)
        .context("cannot read standard input")?;
    Ok(())
}

/// Single key presses from the terminal: canonical mode and echo off while the capture runs,
/// restored on drop. rustix's termios (already the turntable driver's) instead of a terminal
/// crate: two flags and a poll are all that is needed.
#[cfg(unix)]
mod terminal {
    use std::io::Read;
    use std::os::fd::AsFd;
    use std::time::Duration;

    use rustix::event::{PollFd, PollFlags, Timespec, poll};
    use rustix::termios::{LocalModes, OptionalActions, Termios, tcgetattr, tcsetattr};

    /// The terminal in single-key mode.
    pub(super) struct Keys {
        saved: Termios,
    }

    impl Keys {
        /// Switches standard input to single keys without echo; fails when it is no terminal.
        pub(super) fn raw() -> std::io::Result<Self> {
            let stdin = std::io::stdin();
            let saved = tcgetattr(stdin.as_fd())?;
            let mut raw = saved.clone();
            raw.local_modes &= !(LocalModes::ICANON | LocalModes::ECHO);
            tcsetattr(stdin.as_fd(), OptionalActions::Now, &raw)?;
            Ok(Self { saved })
        }

        /// The next key, waiting at most `timeout`.
        pub(super) fn next(&self, timeout: Duration) -> std::io::Result<Option<u8>> {
            let stdin = std::io::stdin();
            let ts = Timespec {
                tv_sec: timeout.as_secs() as _,
                tv_nsec: i64::from(timeout.subsec_nanos()) as _,
            };
            let mut fds = [PollFd::new(&stdin, PollFlags::IN)];
            if poll(&mut fds, Some(&ts))? == 0 {
                return Ok(None);
            }
            let mut byte = [0u8; 1];
            match stdin.lock().read(&mut byte)? {
                0 => Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    "standard input closed",
                )),
                _ => Ok(Some(byte[0])),
            }
        }
    }

    impl Drop for Keys {
        fn drop(&mut self) {
            // Restoring can only fail when the terminal is gone: nothing left to restore.
            let _ = tcsetattr(std::io::stdin().as_fd(), OptionalActions::Now, &self.saved);
        }
    }
}

#[cfg(not(unix))]
mod terminal {
    use std::time::Duration;

    pub(super) struct Keys;

    impl Keys {
        pub(super) fn raw() -> std::io::Result<Self> {
            Err(std::io::Error::other("single keys need a Unix terminal"))
        }

        pub(super) fn next(&self, _timeout: Duration) -> std::io::Result<Option<u8>> {
            Ok(None)
        }
    }
}

/// Real devices: camera, projector and turntable together (as `slscan capture`).
fn run_hardware(args: &Args) -> anyhow::Result<()> {
    let description = args.hardware.description("calibrate capture on hardware")?;
    let devices = description.summary();
    let args = args.clone();
    let failed = |e: anyhow::Error| sl_rig::RigError::Device {
        device: "calibration capture".to_owned(),
        reason: format!("{e:#}"),
    };
    // The window lives on the main thread's event loop; the capture runs in the worker.
    sl_rig::with_described_devices(&description, move |camera, right, projector, table| {
        run_devices(
            &args,
            &devices,
            camera,
            right,
            projector,
            table,
            &mut HandHeld,
            sl_rig::DEFAULT_DISPLAY_LATENCY,
            || Ok(()),
        )
        .map_err(failed)
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The command on the virtual rig (`--virtual --auto` then `calibrate all`, against the
    //! rig's truth), the real-device path on virtual devices with the emulated MX-64 as the
    //! turntable, and the interactive keys in a terminal under tmux.

    use std::path::{Path, PathBuf};
    use std::process::Command as Process;
    use std::time::{Duration, Instant};

    use clap::Parser;
    use sl_calib::sl_camera::Calibration;
    use sl_rig::{EmulatorConfig, Mx64Emulator, RigError, Turntable};
    use sl_scan::{BoardMover, BoardTurntable, CaptureError, VirtualBoardMover, VirtualBoardRig};
    use sl_sim::{BoardPoseConfig, Checkerboard};
    use structured_light::scan::scaled_rig_config;

    use crate::{Cli, Command};

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    fn capture_args(args: &[&str]) -> super::Args {
        let mut argv = vec!["slscan", "calibrate", "capture"];
        argv.extend_from_slice(args);
        match Cli::try_parse_from(argv).unwrap().command {
            Command::Calibrate(crate::calibrate::Args {
                what: crate::calibrate::What::Capture(a),
            }) => a,
            other => panic!("parsed as {other:?}"),
        }
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    fn figure(report: &Path, key: &str) -> f64 {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap();
        v["figures"][key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key} in {}", report.display()))
    }

    /// Angle (degrees) between the fitted and the true axis, and the distance (mm) of the true
    /// axis point from the fitted line.
    fn axis_errors(fit: &Calibration, truth: &Calibration) -> (f64, f64) {
        let (a, t) = (fit.turntable.unwrap(), truth.turntable.unwrap());
        let (d, dt) = (a.direction.normalize(), t.direction.normalize());
        let angle = d.dot(&dt).clamp(-1.0, 1.0).acos().to_degrees();
        let off = t.point_mm - a.point_mm;
        (angle, (off - d * off.dot(&d)).norm())
    }

    /// `--virtual --auto --poses 12 --turntable-angles 7` then `calibrate all`: the accuracy of
    /// a simulated session (issue 14), against the rig's exact calibration written beside the
    /// session.
    /// `--binocular`: every pose folder holds the second camera's picture in `right/`, and
    /// `calibrate stereo` on the session finds the rig's pair (baseline within 0.5 mm and
    /// 0.05°) with the turntable axis; the option is refused on devices.
    #[test]
    #[cfg_attr(
        debug_assertions,
        ignore = "a full simulation, minutes unoptimised: .ci/run runs it (step \"full simulations\")"
    )]
    fn a_binocular_virtual_session_calibrates_both_cameras() {
        let tmp = tempfile::tempdir().unwrap();
        let session = tmp.path().join("session");
        let s = session.to_str().unwrap();
        slscan(&[
            "calibrate",
            "capture",
            "--virtual",
            "--binocular",
            "--auto",
            "--poses",
            "8",
            "--turntable-angles",
            "5",
            "--downscale",
            DOWNSCALE_A,
            "--out",
            s,
        ])
        .unwrap();
        let poses = names(&session.join("board"));
        assert_eq!(poses.len(), 8);
        for p in &poses {
            assert!(
                session
                    .join("board")
                    .join(p)
                    .join("right/white.png")
                    .is_file(),
                "{p}"
            );
        }
        let out = tmp.path().join("stereo");
        slscan(&["calibrate", "stereo", s, "--out", out.to_str().unwrap()]).unwrap();
        let fit = sl_calib::sl_camera::BinocularCalibration::load(out.join("stereo.json")).unwrap();
        let truth = sl_calib::sl_camera::BinocularCalibration::load(
            session.join("calibration_true_pair.json"),
        )
        .unwrap();
        let d = truth.t_left_right.inverse() * fit.t_left_right;
        let (angle, shift) = (d.rotation.angle().to_degrees(), d.translation.vector.norm());
        outln!("T_left_right {angle:.4} degrees and {shift:.4} mm from the truth");
        assert!(angle < 0.05 && shift < 0.5, "{angle} deg, {shift} mm");
        let axis = fit.turntable.unwrap();
        let true_axis = truth.turntable.unwrap();
        let tilt = axis.direction.angle(&true_axis.direction).to_degrees();
        assert!(tilt < 0.05, "axis {tilt} degrees off");

        let err = slscan(&[
            "calibrate",
            "capture",
            "--binocular",
            "--camera",
            "/dev/video0",
            "--out",
            s,
        ])
        .unwrap_err();
        assert!(format!("{err:#}").contains("--right-camera"), "{err:#}");
    }

    #[test]
    #[cfg_attr(
        debug_assertions,
        ignore = "a full simulation, minutes unoptimised: .ci/run runs it (step \"full simulations\")"
    )]
    fn virtual_auto_session_calibrates_to_the_truth() {
        let tmp = tempfile::tempdir().unwrap();
        let session = tmp.path().join("session");
        let s = session.to_str().unwrap();
        slscan(&[
            "calibrate",
            "capture",
            "--virtual",
            "--auto",
            "--poses",
            "12",
            "--turntable-angles",
            "7",
            "--downscale",
            DOWNSCALE_A,
            "--out",
            s,
        ])
        .unwrap();
        assert_eq!(names(&session.join("board")).len(), 12);
        assert_eq!(
            names(&session.join("turntable")),
            (0..7).map(|k| format!("angle_{k:03}")).collect::<Vec<_>>()
        );
        let out = tmp.path().join("calib");
        slscan(&["calibrate", "all", s, "--out", out.to_str().unwrap()]).unwrap();
        let fit = Calibration::load(out.join("calibration.json")).unwrap();
        let truth = Calibration::load(session.join("calibration_true.json")).unwrap();
        for key in ["rms_camera_px", "rms_projector_px", "rms_stereo_px"] {
            let v = figure(&out.join("projector/report.json"), key);
            assert!(v > 0.0 && v < 0.2, "{key} = {v}");
        }
        let rms = figure(&out.join("report.json"), "rms_px");
        assert!(rms > 0.0 && rms < 0.2, "turntable RMS {rms}");
        let (angle, offset) = axis_errors(&fit, &truth);
        outln!("axis {angle:.4} degrees and {offset:.4} mm from the truth");
        assert!(angle < 0.05, "axis direction {angle} degrees off");
        assert!(offset < 0.1, "axis {offset} mm off");
        let fx = fit.camera.intrinsics.fx / truth.camera.intrinsics.fx;
        assert!((fx - 1.0).abs() < 0.002, "fx ratio {fx}");
    }

    /// Resolution divider of the accuracy test: half resolution, 34 s in the test build
    /// instead of 138 s at full resolution (the longest test of the workspace, issue 29); the
    /// axis lands 0.006° and 0.07 mm from the truth, inside the bounds below.
    const DOWNSCALE_A: &str = "2";

    /// The emulated MX-64 turning the virtual board: the servo's reported angle is what the
    /// virtual turntable is turned to, so the frames show the angle the driver recorded.
    struct EmulatedTurntable {
        servo: sl_rig::BoxedTurntable,
        table: BoardTurntable,
    }

    impl Turntable for EmulatedTurntable {
        fn rotate_to(&mut self, angle_deg: f64) -> Result<f64, RigError> {
            let reached = self.servo.rotate_to(angle_deg)?;
            self.table.rotate_to(reached)?;
            Ok(reached)
        }

        fn angle_deg(&mut self) -> Result<f64, RigError> {
            self.servo.angle_deg()
        }
    }

    /// A person moving the virtual board: it does not move by itself (the capture waits for
    /// it to be still, as on real devices), but it is moved after each pose.
    struct Person(VirtualBoardMover);

    impl BoardMover for Person {
        fn moves_itself(&self) -> bool {
            false
        }

        fn next_pose(&mut self) -> Result<(), CaptureError> {
            self.0.next_pose()
        }

        fn onto_turntable(&mut self) -> Result<(), CaptureError> {
            self.0.onto_turntable()
        }
    }

    /// The real-device path (`run_devices` with a hand-held board, waiting for a still board,
    /// the Dynamixel driver opened as `--turntable` opens it) on the virtual camera and
    /// projector with the emulated MX-64 on a pseudo-terminal.
    #[test]
    fn hardware_path_with_the_emulated_turntable() {
        let tmp = tempfile::tempdir().unwrap();
        let servo = Mx64Emulator::spawn(EmulatorConfig::default()).unwrap();
        let session = tmp.path().join("session");
        let args = capture_args(&[
            "--out",
            session.to_str().unwrap(),
            "--auto",
            "--poses",
            "4",
            "--turntable-angles",
            "3",
            "--turntable",
            servo.port_path().to_str().unwrap(),
        ]);
        let mut config = scaled_rig_config(4);
        config.render.supersampling = super::BOARD_SUPERSAMPLING;
        let rig = VirtualBoardRig::new(
            config,
            Checkerboard::default(),
            &BoardPoseConfig {
                count: 4,
                ..BoardPoseConfig::default()
            },
        )
        .unwrap();
        let (mut camera, mut projector, table, mover) = rig.devices();
        let mut turntable = EmulatedTurntable {
            servo: sl_rig::open_turntable(servo.port_path(), args.hardware.servo_id).unwrap(),
            table,
        };
        super::run_devices(
            &args,
            "virtual camera and projector, emulated MX-64",
            &mut camera,
            None,
            &mut projector,
            &mut turntable,
            &mut Person(mover),
            Duration::ZERO,
            || Ok(()),
        )
        .unwrap();
        assert_eq!(
            names(&session.join("board")),
            ["pose_000", "pose_001", "pose_002", "pose_003"]
        );
        // The motor angles recorded are the servo's: within its 4-tick tolerance (0.35°) of
        // -45, 0 and 45 degrees, and the board was found at each.
        for (k, target) in [-45.0, 0.0, 45.0].into_iter().enumerate() {
            let text =
                std::fs::read_to_string(session.join(format!("turntable/angle_{k:03}/board.json")))
                    .unwrap();
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            let a = v["motor_angle_deg"].as_f64().unwrap();
            assert!((a - target).abs() < 0.36, "{k}: {a}");
            assert_eq!(v["detected_corners_px"].as_array().unwrap().len(), 54);
        }
        // The table went back to 0 at the end.
        let ticks = servo.snapshot().present_ticks;
        assert!(ticks.abs() <= 4, "{ticks}");
        let report = session.join("report.json");
        assert_eq!(figure(&report, "poses"), 4.0);
        assert_eq!(figure(&report, "turntable_views_with_board"), 3.0);
    }

    /// The interactive command in a terminal: this test runs inside tmux, started by
    /// `interactive_keys_under_tmux` (ignored when run alone: it needs the keys).
    #[test]
    #[ignore = "run by interactive_keys_under_tmux inside a terminal"]
    fn interactive_child() {
        let Some(out) = std::env::var_os(CHILD_OUT) else {
            return;
        };
        let out = PathBuf::from(out);
        slscan(&[
            "calibrate",
            "capture",
            "--virtual",
            "--poses",
            "3",
            "--turntable-angles",
            "2",
            "--downscale",
            "4",
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap();
        outln!("CHILD DONE");
    }

    /// Environment variable naming the session folder of [`interactive_child`].
    const CHILD_OUT: &str = "SLSCAN_INTERACTIVE_TEST_OUT";

    /// Longest wait for a screen text: the virtual rig renders a frame in well under a second;
    /// a loaded 2-core machine is slower, and the wait ends as soon as the text shows.
    const SCREEN_WAIT: Duration = Duration::from_secs(120);

    struct Tmux {
        socket: String,
        session: String,
    }

    impl Tmux {
        fn cmd(&self, args: &[&str]) -> std::process::Output {
            Process::new("tmux")
                .arg("-L")
                .arg(&self.socket)
                .args(args)
                .output()
                .unwrap()
        }

        fn screen(&self) -> String {
            let o = self.cmd(&["capture-pane", "-p", "-t", &self.session]);
            String::from_utf8_lossy(&o.stdout).into_owned()
        }

        fn keys(&self, keys: &str) {
            assert!(
                self.cmd(&["send-keys", "-t", &self.session, keys])
                    .status
                    .success()
            );
        }

        /// Waits until the screen shows `text`; returns the screen.
        fn wait_for(&self, text: &str) -> String {
            let start = Instant::now();
            loop {
                let s = self.screen();
                if s.contains(text) {
                    return s;
                }
                assert!(
                    start.elapsed() < SCREEN_WAIT,
                    "no `{text}` on the screen:\n{s}"
                );
                std::thread::sleep(Duration::from_millis(200));
            }
        }
    }

    impl Drop for Tmux {
        fn drop(&mut self) {
            let _ = self.cmd(&["kill-server"]);
        }
    }

    /// Take, take, drop, take, quit in a real terminal (tmux): the screen shows the checks,
    /// the coverage and what each key did; the folders are those of the keys.
    #[test]
    fn interactive_keys_under_tmux() {
        if Process::new("tmux").arg("-V").output().is_err() {
            outln!("note: tmux not installed: interactive_keys_under_tmux skipped");
            return;
        }
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("session");
        let exe = std::env::current_exe().unwrap();
        let tmux = Tmux {
            socket: format!("slscan-test-{}", std::process::id()),
            session: "capture".to_owned(),
        };
        let command = format!(
            "env {CHILD_OUT}='{}' '{}' --ignored --exact calibrate_capture::tests::interactive_child --nocapture --test-threads 1; sleep 600",
            out.display(),
            exe.display()
        );
        let started = tmux.cmd(&[
            "new-session",
            "-d",
            "-s",
            &tmux.session,
            "-x",
            "120",
            "-y",
            "50",
            &command,
        ]);
        assert!(started.status.success(), "{started:?}");

        let screen = tmux.wait_for("board found: 54/54 corners, tilt");
        assert!(screen.contains("image coverage"), "{screen}");
        assert!(
            screen.contains("hint: hold the board facing the camera"),
            "{screen}"
        );
        tmux.keys("Space");
        tmux.wait_for("pose 0 taken");
        tmux.keys("Enter");
        tmux.wait_for("pose 1 taken");
        tmux.keys("d");
        let screen = tmux.wait_for("dropped");
        assert!(screen.contains("pose_001"), "{screen}");
        assert!(screen.contains("pose 1 of 3"), "{screen}");
        tmux.keys("Space");
        tmux.wait_for("pose 1 taken");
        tmux.keys("q");
        let screen = tmux.wait_for("CHILD DONE");
        assert!(
            screen.contains("turntable view at 45.00 degrees: board found"),
            "{screen}"
        );
        assert_eq!(names(&out.join("board")), ["pose_000", "pose_001"]);
        assert_eq!(names(&out.join("turntable")), ["angle_000", "angle_001"]);
    }
}
