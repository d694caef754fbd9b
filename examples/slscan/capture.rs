//! `slscan capture --out DIR`: one capture session (`sl_rig::CaptureSession`), on the virtual
//! rig by default or on real devices with `--camera /dev/videoN --projector-monitor N
//! --turntable /dev/ttyUSB0 --servo-id 1`. An interrupted session resumes when run again with
//! the same options; `--overwrite` recaptures finished views.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use sl_camera::{BinocularCalibration, Calibration};
use sl_codec::{MANIFEST_FILE, Manifest};
use sl_rig::{Camera, DeviceDescription, LatencyConfig, Projector, SessionDevices, Turntable};
use sl_sim::{Scene, VirtualRig};
use structured_light::scan::{
    DeviceCaptureConfig, capture_binocular_device_session, capture_device_session,
    scaled_rig_config,
};

use crate::common::{open_out_in_place, progress};
use crate::values;

/// The exposure options shared by `capture` and `scan`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct ExposureArgs {
    /// Capture each view at several exposures and fuse them per pixel, for dark and shiny
    /// objects: `auto` (chosen from a white and a black frame of the object at the first
    /// view), or exposure times in milliseconds (`2,8,32`). Each exposure's frames go to
    /// `view_NNN/exposure_<i>/`, the fused ones to `view_NNN/`. Default: one, the camera's own.
    /// A real camera needs a manual exposure control (V4L2 `exposure_time_absolute`).
    #[arg(long, value_parser = values::exposures)]
    pub(crate) exposures: Option<structured_light::scan::Exposures>,
    /// How several exposures are fused: `longest` (each pixel from its longest unsaturated
    /// exposure; holds on cameras that are not linear) or `radiance` (every unsaturated
    /// exposure averaged, scaled by its time: less noise, for linear cameras).
    #[arg(long, value_enum, default_value_t = FusionArg::Longest)]
    pub(crate) fusion: FusionArg,
    /// Capture each view's colour too: a colour frame under full white after the patterns
    /// (`view_NNN/colour.png`); the clouds, the mesh (vertex colours, a textured `mesh.obj`)
    /// and the 3-D page are then in colour. A real camera must capture in colour (YUYV,
    /// MJPEG, RGB). On the virtual rig `--finish coloured` implies it.
    #[arg(long)]
    pub(crate) colour: bool,
}

impl ExposureArgs {
    /// The exposures asked for (one, the camera's own, by default).
    pub(crate) fn exposures(&self) -> structured_light::scan::Exposures {
        self.exposures.clone().unwrap_or_default()
    }

    /// The fusion settings.
    pub(crate) fn fusion(&self) -> sl_codec::FusionSettings {
        sl_codec::FusionSettings {
            method: match self.fusion {
                FusionArg::Longest => sl_codec::FusionMethod::Longest,
                FusionArg::Radiance => sl_codec::FusionMethod::Radiance,
            },
            ..sl_codec::FusionSettings::default()
        }
    }
}

/// `--fusion`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FusionArg {
    /// Each pixel from its longest unsaturated exposure.
    Longest,
    /// Every unsaturated exposure, scaled and averaged.
    Radiance,
}

/// The hardware options shared by `capture` and `scan`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct HardwareArgs {
    /// V4L2 camera device, e.g. /dev/video0 (needs `--features v4l`).
    #[arg(long)]
    pub(crate) camera: Option<PathBuf>,
    /// Monitor index of the projector, as `slscan devices` lists them (needs `--features window`).
    #[arg(long)]
    pub(crate) projector_monitor: Option<usize>,
    /// Serial port of the Dynamixel turntable, e.g. /dev/ttyUSB0.
    #[arg(long)]
    pub(crate) turntable: Option<PathBuf>,
    /// Dynamixel servo id (0 to 252, the protocol's ids).
    #[arg(long, default_value_t = 1, value_parser = values::count_in::<u8>(0..=252))]
    pub(crate) servo_id: u8,
    /// The second camera of a binocular rig, e.g. /dev/video2 (needs `--features v4l`): each
    /// view is captured by both cameras, the second into `view_NNN/right/`.
    #[arg(long)]
    pub(crate) right_camera: Option<PathBuf>,
}

impl HardwareArgs {
    /// Whether any device is given.
    pub(crate) fn any(&self) -> bool {
        self.camera.is_some()
            || self.projector_monitor.is_some()
            || self.turntable.is_some()
            || self.right_camera.is_some()
    }

    /// The devices, all three required (`what` names the command in the error).
    pub(crate) fn description(&self, what: &str) -> anyhow::Result<DeviceDescription> {
        let (Some(camera), Some(monitor), Some(port)) =
            (&self.camera, self.projector_monitor, &self.turntable)
        else {
            anyhow::bail!("{what} needs --camera, --projector-monitor and --turntable together");
        };
        Ok(DeviceDescription {
            camera: camera.clone(),
            projector_monitor: monitor,
            turntable_port: port.clone(),
            servo_id: self.servo_id,
            right_camera: self.right_camera.clone(),
        })
    }
}

/// Arguments of `slscan capture`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct Args {
    /// Session folder (created; an existing session with the same plan is resumed).
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Turntable views over a full turn (1 to 3600).
    #[arg(long, default_value_t = 36, value_parser = values::views())]
    pub(crate) views: usize,
    /// Folder with the patterns' `manifest.json` (default: hybrid code on the columns, 15 px
    /// periods).
    #[arg(long)]
    pub(crate) patterns: Option<PathBuf>,
    /// Virtual scene: sphere, dumbbell, plane, box or cylinder.
    #[arg(long, default_value = "dumbbell")]
    pub(crate) scene: String,
    /// Divide the virtual rig's resolution by this (1 to 8).
    #[arg(long, default_value_t = 1, value_parser = values::downscale())]
    pub(crate) downscale: u32,
    /// Wait after showing a pattern (ms, at most 10000); default 100 on hardware, 0 on the
    /// virtual rig.
    #[arg(long, value_parser = values::latency_ms())]
    pub(crate) latency_ms: Option<u64>,
    /// Measure the display-to-camera latency first (flashes) and flush that many frames.
    #[arg(long)]
    pub(crate) measure_latency: bool,
    /// Calibration file to record in session.json.
    #[arg(long)]
    pub(crate) calib: Option<PathBuf>,
    /// Recapture views that are already complete.
    #[arg(long)]
    pub(crate) overwrite: bool,
    /// On the virtual rig: capture with its second camera too (binocular structured light),
    /// into `view_NNN/right/`, and write the pair's true calibration
    /// (`calibration_true_pair.json`) beside the session. On devices, `--right-camera`.
    #[arg(long)]
    pub(crate) binocular: bool,
    /// The virtual scene's surface: `matte` (plaster), `dark` (albedo 0.04), `glossy` (a
    /// plastic whose highlights saturate the camera) or `coloured` (patches of four colours,
    /// captured in colour).
    #[arg(long, value_enum, default_value_t = FinishArg::Matte)]
    pub(crate) finish: FinishArg,
    #[command(flatten)]
    pub(crate) exposure: ExposureArgs,
    #[command(flatten)]
    pub(crate) hardware: HardwareArgs,
}

/// `--finish`: the virtual object's surface ([`sl_sim::Finish`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FinishArg {
    /// Bright matte plaster.
    Matte,
    /// A black part (albedo 0.04).
    Dark,
    /// A glossy plastic with saturating highlights.
    Glossy,
    /// Matte paint in patches of four colours (with `--colour`: a colour scan against the
    /// true albedo).
    Coloured,
}

impl From<FinishArg> for sl_sim::Finish {
    fn from(f: FinishArg) -> Self {
        match f {
            FinishArg::Matte => Self::Matte,
            FinishArg::Dark => Self::Dark,
            FinishArg::Glossy => Self::Glossy,
            FinishArg::Coloured => Self::Coloured,
        }
    }
}

/// The pattern sequence in `dir`'s `manifest.json` (`--patterns`); `None` without a folder (the
/// library's default: hybrid code on the columns, 15 px periods).
pub(crate) fn load_patterns(dir: Option<&Path>) -> anyhow::Result<Option<Manifest>> {
    Ok(dir
        .map(|d| Manifest::load(&d.join(MANIFEST_FILE)))
        .transpose()?)
}

/// Runs one session on any devices (`sl_scan::capture_device_session`), with progress and
/// report. The motor angles turn the *platter* a full turn in `--views` equal steps, through
/// the calibrated angle scale of `--calib` when it holds a turntable axis.
pub(crate) fn run_session<C, P, T>(
    args: &Args,
    devices: SessionDevices,
    camera: &mut C,
    right: Option<&mut dyn Camera>,
    projector: &mut P,
    turntable: &mut T,
    default_latency: Duration,
) -> anyhow::Result<()>
where
    C: Camera + ?Sized,
    P: Projector + ?Sized,
    T: Turntable + ?Sized,
{
    // The axis (a two-camera calibration, `calibrate stereo`, holds it too) and the projector's
    // response, which the default patterns pre-compensate.
    let (axis, projector_response) = match &args.calib {
        Some(path) => match BinocularCalibration::load(path) {
            Ok(pair) => (pair.turntable, None),
            Err(_) => {
                let c = Calibration::load(path)
                    .with_context(|| format!("cannot read the calibration {}", path.display()))?;
                (c.turntable, c.projector_response)
            }
        },
        None => (None, None),
    };
    let config = DeviceCaptureConfig {
        views: args.views,
        patterns: load_patterns(args.patterns.as_deref())?,
        projector_response,
        display_latency: args
            .latency_ms
            .map_or(default_latency, Duration::from_millis),
        measure_latency: args.measure_latency.then(LatencyConfig::default),
        overwrite: args.overwrite,
        devices,
        calibration_file: args.calib.clone(),
        exposures: args.exposure.exposures(),
        fusion: args.exposure.fusion(),
        colour: args.exposure.colour || args.finish == FinishArg::Coloured,
    };
    let bar = progress(args.views as u64, "capture");
    let capture = match right {
        None => capture_device_session(
            &config,
            axis.as_ref(),
            &args.out,
            camera,
            projector,
            turntable,
            |_| bar.inc(1),
        )?,
        Some(right) => capture_binocular_device_session(
            &config,
            axis.as_ref(),
            &args.out,
            (camera, right),
            projector,
            turntable,
            |_| bar.inc(1),
        )?,
    };
    bar.finish_and_clear();
    let path = capture.write_report()?;
    for line in capture.summary(&path) {
        outln!("{line}");
    }
    Ok(())
}

fn scene(name: &str) -> anyhow::Result<Scene> {
    Scene::named(name).with_context(|| {
        format!(
            "--scene {name}: expected one of {}",
            Scene::NAMES.join(", ")
        )
    })
}

/// The checks of `slscan capture` that need more than one value.
pub(crate) fn check(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        !(args.binocular && args.hardware.any()),
        "--binocular is the virtual rig's second camera: on devices, name the second camera with --right-camera"
    );
    anyhow::ensure!(
        !(args.finish != FinishArg::Matte && args.hardware.any()),
        "--finish is the virtual scene's surface: on devices, the object is what it is (--exposures serves dark and shiny ones)"
    );
    Ok(())
}

/// Runs `slscan capture`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    check(args)?;
    if args.hardware.any() {
        return run_hardware(args);
    }
    let config = scaled_rig_config(args.downscale);
    let scene = scene(&args.scene)?.finished(args.finish.into());
    let second = config.default_second_camera();
    let rig =
        VirtualRig::new(config.clone(), scene.clone()).context("cannot build the virtual rig")?;
    let mut devices = rig.session_devices(&format!("virtual turntable, scene {}", args.scene));
    // One run at a time in a session folder.
    let folder = open_out_in_place(&args.out, "capture")?;
    if args.binocular {
        let right = VirtualRig::new(config.seen_from(&second), scene.seen_from(&second))
            .context("cannot build the virtual rig's second camera")?;
        let c = right.config().camera.size;
        devices.right_camera = Some(format!("virtual second camera {}x{}", c.width, c.height));
        let (mut camera, mut right_camera, mut projector, mut table) =
            rig.binocular_devices(&right)?;
        run_session(
            args,
            devices,
            &mut camera,
            Some(&mut right_camera),
            &mut projector,
            &mut table,
            Duration::ZERO,
        )?;
    } else {
        let (mut camera, mut projector, mut table) = rig.devices();
        run_session(
            args,
            devices,
            &mut camera,
            None,
            &mut projector,
            &mut table,
            Duration::ZERO,
        )?;
    }
    // The rig's exact calibration beside the session, for `slscan reconstruct`: written once
    // the session has been captured, so that a refused session (another `--downscale`) leaves
    // the one that fits it.
    config
        .calibration()
        .save(args.out.join("calibration_true.json"))?;
    if args.binocular {
        config
            .binocular_calibration()
            .save(args.out.join("calibration_true_pair.json"))?;
    }
    folder.commit()?;
    Ok(())
}

/// Real devices: all three must be given.
pub(crate) fn run_hardware(args: &Args) -> anyhow::Result<()> {
    let description = args.hardware.description("a capture on hardware")?;
    let devices = description.session_devices();
    let folder = open_out_in_place(&args.out, "capture")?;
    let args = args.clone();
    // The window lives on the main thread's event loop; the session runs in the worker.
    let failed = |e: anyhow::Error| sl_rig::RigError::Device {
        device: "capture session".to_owned(),
        reason: format!("{e:#}"),
    };
    sl_rig::with_described_devices(&description, move |camera, right, projector, table| {
        run_session(
            &args,
            devices,
            camera,
            right,
            projector,
            table,
            DEFAULT_HARDWARE_LATENCY,
        )
        .map_err(failed)
    })?;
    folder.commit()?;
    Ok(())
}

/// Display latency on hardware when not given: `sl_rig::DEFAULT_DISPLAY_LATENCY`.
const DEFAULT_HARDWARE_LATENCY: Duration = sl_rig::DEFAULT_DISPLAY_LATENCY;

#[cfg(test)]
mod tests {
    //! `slscan capture --binocular` on the virtual rig: both cameras' capture sets, each
    //! decoding to the projector coordinates its own camera's truth gives; the pair they
    //! reconstruct with; and the option refused on devices.

    use sl_codec::{CaptureSet, DecodeConfig, MANIFEST_FILE, decode};
    use sl_sim::{Scene, VirtualRig};
    use structured_light::scan::scaled_rig_config;

    #[test]
    fn a_binocular_capture_holds_both_cameras_and_their_pair() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("session");
        let s = out.to_str().unwrap();
        crate::run_cli(&[
            "capture",
            "--binocular",
            "--views",
            "2",
            "--downscale",
            "4",
            "--out",
            s,
        ])
        .unwrap();
        let plan = sl_rig::read_session_plan(&out).unwrap();
        assert!(plan.devices.right_camera.is_some());
        // The right camera's view 1 decodes to the projector columns its rig's truth gives.
        let config = scaled_rig_config(4);
        let second = config.default_second_camera();
        let right = VirtualRig::new(
            config.seen_from(&second),
            Scene::dumbbell().seen_from(&second),
        )
        .unwrap();
        let truth = right.view(plan.angles_deg[1], 0).unwrap().truth;
        let errors = column_errors(&out.join("view_001/right"), &truth);
        assert!(errors.len() > 200, "{} decoded lit pixels", errors.len());
        let median = errors[errors.len() / 2];
        assert!(median < 0.5, "median column error {median} projector px");
        // The pair's truth beside the session reconstructs the view.
        let pair = out.join("calibration_true_pair.json");
        assert!(
            structured_light::camera::BinocularCalibration::load(&pair)
                .unwrap()
                .turntable
                .is_some()
        );
        let rec = tmp.path().join("rec");
        crate::run_cli(&[
            "reconstruct",
            out.join("view_000").to_str().unwrap(),
            "--right",
            out.join("view_000/right").to_str().unwrap(),
            "--calib",
            pair.to_str().unwrap(),
            "--out",
            rec.to_str().unwrap(),
        ])
        .unwrap();
        assert!(rec.join("cloud.ply").is_file());
        // On devices the second camera is named, not `--binocular`.
        let err = crate::run_cli(&[
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

    /// `slscan capture --finish dark --exposures auto` on the virtual rig, then `slscan decode
    /// --fuse` of a view: the black dumbbell, which one exposure leaves undecoded, decodes to
    /// the projector columns the rig's truth gives.
    #[test]
    fn a_dark_object_captured_at_chosen_exposures_decodes_against_the_truth() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("session");
        let s = out.to_str().unwrap();
        let args = [
            "capture",
            "--views",
            "2",
            "--downscale",
            "4",
            "--finish",
            "dark",
        ];
        crate::run_cli(&[&args[..], &["--out", s, "--exposures", "auto"]].concat()).unwrap();
        let plan = sl_rig::read_session_plan(&out).unwrap();
        assert_eq!(plan.exposures.times_ms.len(), 1, "{:?}", plan.exposures);
        assert!(plan.exposures.times_ms[0] > 40.0, "{:?}", plan.exposures);
        let view = out.join("view_001");
        let decoded = tmp.path().join("decoded");
        crate::run_cli(&[
            "decode",
            view.to_str().unwrap(),
            "--fuse",
            "--out",
            decoded.to_str().unwrap(),
        ])
        .unwrap();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(decoded.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(
            report["figures"]["exposure_fusion"]["exposures_ms"],
            serde_json::json!(plan.exposures.times_ms)
        );
        let rig = VirtualRig::new(
            scaled_rig_config(4),
            Scene::dumbbell().finished(sl_sim::Finish::Dark),
        )
        .unwrap();
        let truth = rig.view(plan.angles_deg[1], 0).unwrap().truth;
        let errors = column_errors(&view, &truth);
        assert!(errors.len() > 200, "{} decoded lit pixels", errors.len());
        let median = errors[errors.len() / 2];
        assert!(median < 0.5, "median column error {median} projector px");
        // The same view at the camera's own exposure decodes (almost) nothing of it.
        let one = tmp.path().join("one");
        crate::run_cli(&[&args[..], &["--out", one.to_str().unwrap()]].concat()).unwrap();
        let alone = column_errors(&one.join("view_001"), &truth).len();
        assert!(
            alone * 10 < errors.len(),
            "{alone} against {}",
            errors.len()
        );
    }

    /// `slscan capture --finish coloured` on the virtual rig (colour implied), then `slscan
    /// reconstruct` of a view with the rig's calibration: the cloud takes its colours from the
    /// view's colour frame, and they are the patches' (against the rig's true albedo).
    #[test]
    fn a_coloured_capture_reconstructs_in_its_colours() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("session");
        let s = out.to_str().unwrap();
        let args = [
            "capture",
            "--views",
            "2",
            "--downscale",
            "4",
            "--finish",
            "coloured",
        ];
        crate::run_cli(&[&args[..], &["--out", s]].concat()).unwrap();
        assert!(sl_rig::read_session_plan(&out).unwrap().colour);
        let view = out.join("view_001");
        assert!(view.join(sl_rig::COLOUR_FILE).is_file());
        let rec = tmp.path().join("rec");
        crate::run_cli(&[
            "reconstruct",
            view.to_str().unwrap(),
            "--calib",
            out.join("calibration_true.json").to_str().unwrap(),
            "--out",
            rec.to_str().unwrap(),
        ])
        .unwrap();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(rec.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(report["figures"]["colour_source"], "colour_frame");
        let cloud = sl_cloud::read_ply(&rec.join("cloud.ply")).unwrap();
        let rig = VirtualRig::new(
            scaled_rig_config(4),
            Scene::dumbbell().finished(sl_sim::Finish::Coloured),
        )
        .unwrap();
        let angle = sl_rig::read_session_plan(&out).unwrap().angles_deg[1];
        let acc = sl_scan::colour_accuracy(cloud.positions(), cloud.colors().unwrap(), |p| {
            rig.true_colour(angle, p)
                .filter(|t| t.distance_mm <= 1.0)
                .map(|t| t.rgb)
        })
        .unwrap();
        assert!(acc.points > cloud.len() / 2, "{acc:?}");
        assert!(acc.angle_median_deg < 8.0, "{acc:?}");
    }

    /// The capture in `dir` decoded: the column errors (projector px) of its decoded pixels
    /// that `truth` says are lit, sorted.
    fn column_errors(dir: &std::path::Path, truth: &sl_sim::ViewTruth) -> Vec<f64> {
        let set = CaptureSet::load(&dir.join(MANIFEST_FILE)).unwrap();
        let map = decode(&set, &DecodeConfig::default()).unwrap();
        let mut errors: Vec<f64> = (0..map.col.len())
            .filter(|&i| truth.lit(i) && map.col[i].is_finite())
            .map(|i| (f64::from(map.col[i]) - truth.projector[i].x).abs())
            .collect();
        errors.sort_by(f64::total_cmp);
        errors
    }
}
