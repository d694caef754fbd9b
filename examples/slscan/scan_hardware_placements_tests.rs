//! `slscan scan --placements 2` on devices, run as a user runs it — the options of a real rig,
//! the prompt between the placements answered with Enter — with the virtual rig's camera,
//! projector and turntable (`sl_scan::VirtualObjectRig::devices`, behind `sl-rig`'s traits) in
//! place of the V4L2 camera, the projector window and the Dynamixel table. The person at the rig is
//! simulated too: it lays the pebble on its side when the screen asks for it, not before.
//! A single-placement scan runs through the same seam, without a question.
//!
//! Small, as `crates/sl-scan/tests/it/placements.rs`: half resolution, 8 views per placement,
//! the rig's true calibration as `--calib` (the calibration is tested elsewhere). The truth is
//! the pebble's own mesh: the merged model must cover it (`sl_metrology::surface_coverage`).

use std::cell::RefCell;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Duration;

use clap::Parser;
use sl_cloud::{PointCloud, read_ply};
use sl_metrology::{
    CoverageConfig, DEFAULT_SELECT_MM, DEFAULT_TRUTH_SAMPLE_AREA_MM2, SurfaceCoverage,
    SurfaceDistance, TriangleMesh, distance_to_surface, surface_coverage,
};
use sl_sim::{DEFAULT_WORKING_DISTANCE_MM, Scene, VirtualRig};
use structured_light::scan::{
    MergeStageConfig, VirtualObjectRig, full_turn_motor_angles, scaled_rig_config,
};

use crate::{Cli, Command};

/// Resolution divisor of the virtual rig: half resolution, as the library's placements test.
const DOWNSCALE: u32 = 2;

/// What the person at the rig reacts to on the screen: both the Enter prompt and the message
/// of `--placement-wait` say it.
const LAY_ON_SIDE: &str = "lay the object on its side";

/// The person at the rig and the rig on its turntable: the object stands as the person left
/// it; the screen is what the command printed to them.
struct Person {
    rig: VirtualObjectRig,
    screen: RefCell<String>,
    replaced: RefCell<usize>,
}

impl Person {
    /// Reads the screen: for each request to lay the object on its side not yet done, lays
    /// the object on its side.
    fn look(&self) -> anyhow::Result<()> {
        let asked = self.screen.borrow().matches(LAY_ON_SIDE).count();
        while *self.replaced.borrow() < asked {
            self.rig.lay_on_side()?;
            *self.replaced.borrow_mut() += 1;
        }
        Ok(())
    }
}

/// The terminal the command writes its questions to: the person reads it as it is written.
struct Screen(Rc<Person>);

impl Write for Screen {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0
            .screen
            .borrow_mut()
            .push_str(&String::from_utf8_lossy(buf));
        self.0.look().map_err(std::io::Error::other)?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn scan_args(args: &[&str]) -> crate::scan::Args {
    let mut argv = vec!["slscan", "scan"];
    argv.extend_from_slice(args);
    match Cli::try_parse_from(argv).map(|c| c.command) {
        Ok(Command::Scan(a)) => a,
        other => panic!("parsed as {other:?}"),
    }
}

/// Coverage of the true surface and distance to it.
fn measure(
    cloud: &PointCloud,
    truth: &TriangleMesh,
    cfg: &CoverageConfig,
) -> (SurfaceCoverage, SurfaceDistance) {
    (
        surface_coverage(truth, cloud, cfg).unwrap(),
        distance_to_surface(
            cloud,
            truth,
            DEFAULT_TRUTH_SAMPLE_AREA_MM2,
            DEFAULT_SELECT_MM,
        )
        .unwrap(),
    )
}

fn figures(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("report.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["figures"].clone()
}

/// The hardware placements loop end to end: two sessions, the person lays the pebble on its
/// side when asked and presses Enter, the placements are reconstructed, aligned with no pose
/// hint and merged, and the merged model covers the pebble where one placement cannot.
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "a full simulation, minutes unoptimised: .ci/run runs it (step \"full simulations\")"
)]
fn two_placements_on_devices_with_enter_between() {
    let mut keys: &[u8] = b"\n";
    let screen = two_placements(&[], &mut keys);
    assert!(
        screen.contains(&format!(
            "placement 2 of 2: {}",
            structured_light::scan::REPLACE_PROMPT
        )),
        "{screen}"
    );
    assert!(keys.is_empty(), "Enter was not read");
}

/// The same with `--placement-wait` (for scripts): the command says what to do and waits
/// instead of reading the keyboard; the person re-places the object in that time. Only the
/// wait differs from the test above, which measures the merged model: this one runs the two
/// placements small (quarter resolution) and checks the sessions, the message, the
/// keyboard left unread and the files of a merged scan.
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "a full simulation, minutes unoptimised: .ci/run runs it (step \"full simulations\")"
)]
fn two_placements_on_devices_with_placement_wait() {
    let mut keys: &[u8] = b"not read\n";
    let scan = scan_on_virtual_devices(
        4,
        8,
        &["--placements", "2", "--placement-wait", "0.5"],
        &mut keys,
    );
    assert!(
        scan.screen
            .contains("placement 2 of 2: lay the object on its side; scanning again in 0.5 s"),
        "{}",
        scan.screen
    );
    assert_eq!(keys, b"not read\n");
    assert_eq!(scan.sessions, 2);
    assert_eq!(scan.replaced, 1);
    for f in ["placement_2/merged.ply", "merged.ply", "mesh.ply"] {
        assert!(scan.out.join(f).is_file(), "{f} missing");
    }
    assert_eq!(figures(&scan.out)["placements"], 2);
}

/// A scan run on the virtual devices, and the truth to measure it against.
struct DeviceScan {
    /// Keeps the scan's folder while the test reads it.
    _tmp: tempfile::TempDir,
    /// The output folder.
    out: PathBuf,
    /// Everything the command printed to the person.
    screen: String,
    /// How often the person laid the object on its side.
    replaced: usize,
    /// Sessions captured.
    sessions: usize,
    /// The standing pebble's surface in the camera frame of the first view, the frame of the
    /// merged clouds.
    truth: TriangleMesh,
    /// Coverage distance: twice the sample spacing, the larger of the camera pixel's footprint
    /// at the working distance and the merge voxel (as the virtual scan's).
    coverage: CoverageConfig,
}

/// Runs `slscan scan` on the virtual devices (the pebble standing on the table) with the
/// options of a real rig, the rig at `1/downscale` of its resolution, `views` views, and
/// `extra`; `keys` is the keyboard.
fn scan_on_virtual_devices(
    downscale: u32,
    views: usize,
    extra: &[&str],
    keys: &mut &[u8],
) -> DeviceScan {
    let tmp = tempfile::tempdir().unwrap();
    let config = scaled_rig_config(downscale);
    let views_arg = views.to_string();
    let calib = tmp.path().join("calibration.json");
    let calibration = config.calibration();
    calibration.save(&calib).unwrap();
    let out = tmp.path().join("scan");
    // The options a user gives on a real rig; the device paths are not opened here: the
    // virtual devices stand in for them.
    let args = scan_args(
        &[
            "--out",
            out.to_str().unwrap(),
            "--camera",
            "/dev/video0",
            "--projector-monitor",
            "1",
            "--turntable",
            "/dev/ttyUSB0",
            "--calib",
            calib.to_str().unwrap(),
            "--views",
            &views_arg,
        ]
        .iter()
        .chain(extra)
        .copied()
        .collect::<Vec<_>>(),
    );
    let standing = Scene::pebble().unwrap();
    let person = Rc::new(Person {
        rig: VirtualObjectRig::new(VirtualRig::new(config.clone(), standing.clone()).unwrap()),
        screen: RefCell::new(String::new()),
        replaced: RefCell::new(0),
    });
    // Opened once, as `sl_rig::with_devices` opens the real devices; no display latency, as a
    // virtual projector has none.
    let on_virtual_devices = |mut cfg: structured_light::scan::DeviceScanConfig| {
        cfg.capture.display_latency = Duration::ZERO;
        let (mut camera, mut projector, mut table) = person.rig.devices();
        let terminal = structured_light::scan::TerminalOperator::new(
            keys,
            Screen(person.clone()),
            args.placement_wait,
        );
        Ok(super::scan_on(
            &cfg,
            &args.out,
            (&mut camera, None),
            &mut projector,
            &mut table,
            terminal,
        )?)
    };
    super::run_on(&args, on_virtual_devices).unwrap();
    let sessions = crate::common::files_below(&out)
        .iter()
        .filter(|p| p.ends_with("session/session.json"))
        .count();

    let angles = full_turn_motor_angles(calibration.turntable.as_ref(), views).unwrap();
    let truth = standing
        .surface_mesh(&config.t_cam_table_at(angles[0]))
        .unwrap();
    let footprint = DEFAULT_WORKING_DISTANCE_MM / calibration.camera.intrinsics.fx;
    let voxel = MergeStageConfig::scan(true, args.smoothing_neighbours, true)
        .merge
        .output_voxel_size
        .unwrap_or(0.0);
    let screen = person.screen.borrow().clone();
    outln!("{screen}");
    let replaced = *person.replaced.borrow();
    DeviceScan {
        _tmp: tmp,
        out,
        screen,
        replaced,
        sessions,
        truth,
        coverage: CoverageConfig::for_spacing(footprint.max(voxel)),
    }
}

/// Runs `slscan scan --placements 2` on the virtual devices with `extra` options and `keys` as
/// the keyboard; checks the files, the report and the merged model against the truth; returns
/// what the screen showed.
fn two_placements(extra: &[&str], keys: &mut &[u8]) -> String {
    let options: Vec<&str> = ["--placements", "2"].iter().chain(extra).copied().collect();
    let scan = scan_on_virtual_devices(DOWNSCALE, 8, &options, keys);
    let out = &scan.out;

    // Asked once, between the two sessions; the object was laid on its side once.
    assert_eq!(scan.sessions, 2);
    assert_eq!(
        scan.screen.matches(LAY_ON_SIDE).count(),
        1,
        "{}",
        scan.screen
    );
    assert_eq!(scan.replaced, 1);

    for f in [
        "placement_1/session/session.json",
        "placement_2/session/view_007/manifest.json",
        "placement_1/merged.ply",
        "placement_2/merged.ply",
        "merged.ply",
        "mesh.ply",
        "mesh.stl",
        "report.json",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let fig = figures(out);
    assert_eq!(fig["rig"], "hardware");
    assert_eq!(fig["placements"], 2);
    let fitness = fig["per_placement"][1]["alignment"]["fitness"]
        .as_f64()
        .unwrap();
    assert!(fitness >= 0.3, "{fitness}");
    assert!(fig["mesh"]["triangles"].as_u64().unwrap() > 1000);

    let (single, single_d) = measure(
        &read_ply(&out.join("placement_1/merged.ply")).unwrap(),
        &scan.truth,
        &scan.coverage,
    );
    let (whole, whole_d) = measure(
        &read_ply(&out.join("merged.ply")).unwrap(),
        &scan.truth,
        &scan.coverage,
    );
    outln!("placement 1: {single:?} {single_d:?}\nmerged: {whole:?} {whole_d:?}");
    // One placement misses the flat bottom (15.5 % of the area); the two merged cover 99 %
    // or more, the target of issue 16, and lie as close to the truth: within 1.5 times the
    // single placement's RMS.
    assert!(single.covered_fraction < 0.9, "{single:?}");
    assert!(whole.covered_fraction >= 0.99, "{whole:?}");
    assert!(
        whole_d.rms_mm <= 1.5 * single_d.rms_mm,
        "merged {whole_d:?} vs single {single_d:?}"
    );
    scan.screen
}

/// One placement on the devices, through the same seam: one session in `session/`, no
/// question asked, the keyboard not read; the merged cloud lies on the pebble and covers all
/// but its flat bottom. `--no-fair` reaches the mesh stage of the devices' path as it does the
/// virtual rig's: simplified, not faired.
#[test]
fn one_placement_on_devices() {
    let mut keys: &[u8] = b"not read\n";
    let scan = scan_on_virtual_devices(DOWNSCALE, 8, &["--no-fair"], &mut keys);
    assert_eq!(scan.sessions, 1);
    assert_eq!(scan.replaced, 0);
    assert!(!scan.screen.contains(LAY_ON_SIDE), "{}", scan.screen);
    assert_eq!(keys, b"not read\n");
    for f in [
        "session/session.json",
        "session/view_007/manifest.json",
        "merged.ply",
        "mesh.ply",
        "report.json",
    ] {
        assert!(scan.out.join(f).is_file(), "{f} missing");
    }
    let fig = figures(&scan.out);
    assert_eq!(fig["rig"], "hardware");
    assert_eq!(fig["views"], 8);
    let mesh = &fig["mesh"];
    assert!(mesh["simplify_ms"].as_f64().is_some(), "{mesh}");
    assert!(mesh["fair_ms"].is_null(), "{mesh}");
    assert!(
        mesh["vertices"].as_u64().unwrap() < mesh["vertices_extracted"].as_u64().unwrap(),
        "{mesh}"
    );
    let (c, d) = measure(
        &read_ply(&scan.out.join("merged.ply")).unwrap(),
        &scan.truth,
        &scan.coverage,
    );
    outln!("{c:?} {d:?}");
    // The flat bottom (15.5 % of the area) is never seen; of the rest, a turntable scan of 8
    // views sees at least nine tenths: 0.9 × 0.845 = 0.76.
    assert!(
        c.covered_fraction > 0.76 && c.covered_fraction < 0.85,
        "{c:?}"
    );
    // On its true surface as tightly as a placement of the virtual path (placements.rs).
    assert!(d.rms_mm < 0.3, "{d:?}");
}

/// `slscan scan` with two cameras on devices, as a user runs it on a real rig
/// (`--right-camera` beside `--camera`, the two-camera calibration as `--calib`), with the
/// virtual rig's two cameras, projector and turntable behind the traits at quarter resolution:
/// both cameras capture each pattern, the report says two cameras, the merged model lies on the
/// pebble's true surface. Options that do not fit are refused by name before anything opens.
#[test]
fn two_cameras_on_devices() {
    let tmp = tempfile::tempdir().unwrap();
    let config = scaled_rig_config(4);
    let second = config.default_second_camera();
    let pair = config.binocular_calibration();
    let stereo = tmp.path().join("stereo.json");
    pair.save(&stereo).unwrap();
    let mono = tmp.path().join("calibration.json");
    config.calibration().save(&mono).unwrap();
    let out = tmp.path().join("scan");
    let devices = [
        "--camera",
        "/dev/video0",
        "--right-camera",
        "/dev/video2",
        "--projector-monitor",
        "1",
        "--turntable",
        "/dev/ttyUSB0",
    ];
    let with = |calib: &Path, extra: &[&str]| {
        let mut a = vec![
            "--out",
            out.to_str().unwrap(),
            "--calib",
            calib.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        scan_args(&a)
    };
    let never = |_: structured_light::scan::DeviceScanConfig| -> anyhow::Result<_> {
        panic!("the devices were opened")
    };
    // One camera's calibration with two cameras, and the pair with one camera.
    let e = super::run_on(&with(&mono, &devices), never).unwrap_err();
    assert!(format!("{e:#}").contains("calibration.json"), "{e:#}");
    let one_camera: Vec<&str> = devices[..2].iter().chain(&devices[4..]).copied().collect();
    let e = super::run_on(&with(&stereo, &one_camera), never).unwrap_err();
    assert!(format!("{e:#}").contains("stereo.json"), "{e:#}");
    // --binocular is the virtual rig's.
    let mut both = devices.to_vec();
    both.push("--binocular");
    let e = crate::scan::check(&with(&stereo, &both)).unwrap_err();
    assert!(format!("{e:#}").contains("--right-camera"), "{e:#}");
    // So is --period (on devices --patterns sets the patterns).
    let mut period = devices.to_vec();
    period.extend(["--period", "60"]);
    let e = crate::scan::check(&with(&stereo, &period)).unwrap_err();
    assert!(format!("{e:#}").contains("--period"), "{e:#}");
    assert!(!out.exists());

    // The smooth pebble's registrations are weak at this size: placed by the calibrated
    // turntable (see sl-scan's `two_cameras_scan_onto_the_true_surface`).
    let mut extra = devices.to_vec();
    extra.extend(["--views", "12", "--no-refine"]);
    let args = with(&stereo, &extra);
    crate::scan::check(&args).unwrap();
    let scene = Scene::pebble().unwrap();
    let left = VirtualRig::new(config.clone(), scene.clone()).unwrap();
    let right = VirtualRig::new(config.seen_from(&second), scene.seen_from(&second)).unwrap();
    let on_virtual_devices = |mut cfg: structured_light::scan::DeviceScanConfig| {
        assert_eq!(
            cfg.capture.devices.right_camera.as_deref(),
            Some("/dev/video2")
        );
        cfg.capture.display_latency = Duration::ZERO;
        let (mut l, mut r, mut projector, mut table) = left.binocular_devices(&right)?;
        let terminal = structured_light::scan::TerminalOperator::new(&b""[..], Vec::new(), None);
        Ok(super::scan_on(
            &cfg,
            &args.out,
            (&mut l, Some(&mut r)),
            &mut projector,
            &mut table,
            terminal,
        )?)
    };
    super::run_on(&args, on_virtual_devices).unwrap();
    let f = figures(&out);
    assert_eq!(f["cameras"], 2, "{f}");
    assert_eq!(f["views"], 12, "{f}");
    assert!(out.join("session/view_011/right/manifest.json").is_file());
    let session = std::fs::read_to_string(out.join("session/session.json")).unwrap();
    assert!(session.contains("/dev/video2"), "{session}");

    let merged = read_ply(&out.join("merged.ply")).unwrap();
    let truth = scene.surface_mesh(&config.t_cam_table_at(0.0)).unwrap();
    let footprint = DEFAULT_WORKING_DISTANCE_MM / config.camera.intrinsics.fx;
    let (c, d) = measure(&merged, &truth, &CoverageConfig::for_spacing(footprint));
    outln!("two cameras on devices: {c:?}\n{d:?}");
    // As the library's test of the same scan: 0.70 covered, 0.055 mm RMS measured.
    assert!(c.covered_fraction > 0.6, "{c:?}");
    assert!(d.rms_mm < 0.2, "{d:?}");
}
