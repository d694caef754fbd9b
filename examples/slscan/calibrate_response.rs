//! `slscan calibrate response --out DIR`: the projector's response from a grey ramp, captured
//! on the virtual rig (`--virtual`) or on real devices (`--camera /dev/videoN
//! --projector-monitor N`), or read from a ramp folder (`--from DIR`); with `--calib FILE`
//! the calibration is written again with the response, and every scan that uses it corrects
//! its phase. The engine is `sl_scan`'s `capture_ramp`, `measure_ramp_folder` and
//! `write_response_files`.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use sl_camera::Calibration;
use sl_scan::{RESPONSE_DIR, RampConfig};

use crate::common::open_out;
use crate::scan::ResponseArg;
use crate::values;

/// Arguments of `slscan calibrate response`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct Args {
    /// Output folder: `response/` (the ramp's captures and `ramp.json`), `response.json` (the
    /// curve and its figures) and, with `--calib`, `calibration.json`.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// The calibration (JSON, OpenCV YAML/XML) to write again, with the response, into
    /// `--out`.
    #[arg(long)]
    pub(crate) calib: Option<PathBuf>,
    /// Measure a ramp folder already captured (its `ramp.json` lists the grey values shown
    /// and the capture of each) instead of capturing one.
    #[arg(long)]
    pub(crate) from: Option<PathBuf>,
    /// Capture the ramp on the virtual rig (its projector lights a flat plate).
    #[arg(long = "virtual")]
    pub(crate) virtual_rig: bool,
    /// V4L2 camera device, e.g. /dev/video0 (needs `--features v4l`).
    #[arg(long)]
    pub(crate) camera: Option<PathBuf>,
    /// Monitor index of the projector, as `slscan devices` lists them (needs `--features
    /// window`).
    #[arg(long)]
    pub(crate) projector_monitor: Option<usize>,
    /// Grey levels of the ramp, black to white (3 to 256).
    #[arg(long, default_value_t = sl_calib::RESPONSE_LEVELS,
          value_parser = values::count_in::<usize>(3..=256))]
    pub(crate) levels: usize,
    /// Wait after each level before capturing (milliseconds, at most 10000; default 100, the
    /// capture session's).
    #[arg(long, value_parser = values::latency_ms())]
    pub(crate) latency_ms: Option<u64>,
    /// Virtual rig: exponent of its projector's response (0.2 to 5).
    #[arg(long, default_value_t = 1.0, value_parser = values::in_range(0.2..=5.0))]
    pub(crate) projector_gamma: f64,
    /// Virtual rig: the shape of its projector's response (`power` of --projector-gamma, or
    /// `measured`).
    #[arg(long, value_enum, default_value_t = ResponseArg::Power)]
    pub(crate) projector_response: ResponseArg,
    /// Virtual rig: divide its resolution by this (1 to 8).
    #[arg(long, default_value_t = 1, value_parser = values::downscale())]
    pub(crate) downscale: u32,
    /// Write into `--out` even where that replaces the calibration read, or what another
    /// command wrote there.
    #[arg(long)]
    pub(crate) force: bool,
}

/// Runs `slscan calibrate response`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let sources = usize::from(args.from.is_some())
        + usize::from(args.virtual_rig)
        + usize::from(args.camera.is_some() || args.projector_monitor.is_some());
    anyhow::ensure!(
        sources == 1,
        "give one source of the ramp: --from DIR, --virtual, or --camera /dev/videoN with --projector-monitor N"
    );
    anyhow::ensure!(
        args.virtual_rig
            || (args.projector_gamma == 1.0
                && args.projector_response == ResponseArg::Power
                && args.downscale == 1),
        "--projector-gamma, --projector-response and --downscale are options of the virtual rig (--virtual)"
    );
    let calibration = match &args.calib {
        Some(path) => Some(
            Calibration::load(path)
                .with_context(|| format!("cannot read the calibration {}", path.display()))?,
        ),
        None => None,
    };
    let mut read: Vec<&std::path::Path> = args.calib.iter().map(PathBuf::as_path).collect();
    if let Some(from) = &args.from {
        read.push(from.as_path());
    }
    let folder = open_out(&args.out, "calibrate response", &read, &[], args.force)?;
    let ramp_dir = folder.path().join(RESPONSE_DIR);
    let (measurement, ramp_name) = if let Some(from) = &args.from {
        (sl_scan::measure_ramp_folder(from)?, from.clone())
    } else if args.virtual_rig {
        let mut config = sl_scan::scaled_rig_config(args.downscale);
        config.render.illumination.gamma = args.projector_gamma;
        config.render.illumination.response = args.projector_response.into();
        (
            sl_scan::capture_virtual_ramp(&config, &ramp_dir, args.levels)?,
            PathBuf::from(RESPONSE_DIR),
        )
    } else {
        let (Some(camera), Some(monitor)) = (&args.camera, args.projector_monitor) else {
            anyhow::bail!("a ramp on devices needs --camera and --projector-monitor together");
        };
        let config = RampConfig {
            levels: args.levels,
            display_latency: args
                .latency_ms
                .map_or(sl_rig::DEFAULT_DISPLAY_LATENCY, Duration::from_millis),
            flush_frames: 0,
        };
        let dir = ramp_dir.clone();
        let m = sl_rig::with_camera_and_projector(camera, monitor, move |camera, projector| {
            sl_scan::capture_ramp(&dir, camera, projector, &config).map_err(|e| {
                sl_rig::RigError::Device {
                    device: "projector response ramp".to_owned(),
                    reason: e.to_string(),
                }
            })
        })?;
        (m, PathBuf::from(RESPONSE_DIR))
    };
    let files =
        sl_scan::write_response_files(&measurement, &ramp_name, calibration, folder.path())?;
    folder.commit()?;
    let s = &files.summary;
    outln!(
        "projector response: {} levels measured on {} pixels (contrast {:.3} of full scale); equivalent gamma {:.3}",
        s.levels.len(),
        s.pixels,
        s.contrast,
        s.equivalent_gamma
    );
    for (steps, error) in &s.phase_error_rad {
        match error {
            Some(e) => outln!(
                "  {steps}-step fringes: uncorrected, up to {e:.4} rad ({:.2} % of a period); corrected by the calibration's response",
                100.0 * e / std::f64::consts::TAU
            ),
            None => outln!(
                "  {steps}-step fringes: the response folds the phase; no correction can undo it (pre-compensate the patterns)"
            ),
        }
    }
    outln!("  {}", args.out.join(sl_scan::RESPONSE_FILE).display());
    match &files.calibration {
        Some(_) => outln!(
            "calibration with the response: {} (scans with it correct their phase)",
            args.out.join("calibration.json").display()
        ),
        None => outln!(
            "no --calib given: the curve is in response.json; give --calib FILE to add it to a calibration"
        ),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use sl_camera::Calibration;

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    fn s(p: &Path) -> &str {
        p.to_str().unwrap()
    }

    /// On the virtual rig with a gamma of 2.2: the ramp, `response.json` and a calibration
    /// holding the response; the same from the ramp folder with `--from`; what a user can
    /// get wrong named.
    #[test]
    fn response_on_the_virtual_rig_and_from_its_folder() {
        let tmp = tempfile::tempdir().unwrap();
        let calib = tmp.path().join("calib.json");
        sl_sim::RigConfig::default()
            .calibration()
            .save(&calib)
            .unwrap();
        let out = tmp.path().join("response");
        slscan(&[
            "calibrate",
            "response",
            "--virtual",
            "--downscale",
            "4",
            "--projector-gamma",
            "2.2",
            "--levels",
            "17",
            "--calib",
            s(&calib),
            "--out",
            s(&out),
        ])
        .unwrap();
        let written = Calibration::load(out.join("calibration.json")).unwrap();
        let curve = written
            .projector_response
            .clone()
            .expect("the response is kept");
        assert!(
            (curve.equivalent_gamma() - 2.2).abs() < 0.05,
            "{}",
            curve.equivalent_gamma()
        );
        // Everything else of the calibration is as it was.
        let before = Calibration::load(&calib).unwrap();
        assert_eq!(written.camera, before.camera);
        let (a, b) = (written.t_cam_proj.unwrap(), before.t_cam_proj.unwrap());
        // The pose goes through a rotation matrix and back: a few ulps.
        assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
        assert_eq!(a.translation, b.translation);
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("response.json")).unwrap())
                .unwrap();
        assert_eq!(summary["levels"].as_array().unwrap().len(), 17);
        assert!(out.join("response").join("ramp.json").is_file());

        // From the folder: the same curve.
        let again = tmp.path().join("again");
        slscan(&[
            "calibrate",
            "response",
            "--from",
            s(&out.join("response")),
            "--calib",
            s(&calib),
            "--out",
            s(&again),
        ])
        .unwrap();
        let from_folder = Calibration::load(again.join("calibration.json")).unwrap();
        assert_eq!(from_folder.projector_response, Some(curve));

        // Two sources, none, a virtual-rig option on a folder, devices this build lacks.
        let e = slscan(&[
            "calibrate",
            "response",
            "--virtual",
            "--from",
            "x",
            "--out",
            "y",
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("one source"), "{e}");
        let e = slscan(&["calibrate", "response", "--out", "y"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("one source"), "{e}");
        let e = slscan(&[
            "calibrate",
            "response",
            "--from",
            s(&out.join("response")),
            "--projector-gamma",
            "2",
            "--out",
            s(&tmp.path().join("z")),
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("--projector-gamma"), "{e}");
        let e = slscan(&[
            "calibrate",
            "response",
            "--camera",
            "/dev/video-none",
            "--out",
            s(&tmp.path().join("w")),
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("--projector-monitor"), "{e}");
    }
}
