//! `slscan calibrate camera|projector|turntable|all`: calibration from checkerboard pictures,
//! writing `calibration.json` (and OpenCV YAML on request), `report.json` and pictures: the
//! detected corners on every image, the per-view RMS bars and the residual vector plot. The
//! steps are sl-scan's (`calibrate_session`, `calibrate_camera_files`, …); this file turns the
//! arguments into their inputs and prints their figures.

use std::path::{Path, PathBuf};

use anyhow::Context;
use sl_calib::sl_camera::{Calibration, ImageSize};
use sl_calib::{BoardSize, CornerRefiner, ProcamCalibration, TurntableConfig, ZhangConfig};
use sl_scan::{
    CalibrationFilesConfig, CalibrationLayout, ProcamFiles, SkippedImage, TurntableFiles,
    calibrate_camera_files, calibrate_procam_files, calibrate_session, calibrate_turntable_files,
    camera_images, layout_white_frames, session_poses, turntable_views,
};

use crate::common::StageBars;
use crate::values;

/// Arguments of `slscan calibrate`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(subcommand)]
    pub(crate) what: What,
}

/// What to calibrate.
#[derive(Debug, clap::Subcommand)]
pub(crate) enum What {
    /// Capture a calibration session on the virtual rig (`--virtual`) or real devices: the
    /// board at guided poses under the patterns, then on the turntable (`SESSION/board/`,
    /// `SESSION/turntable/`, as `calibrate all` reads them). Interactive, or `--auto`.
    Capture(crate::calibrate_capture::Args),
    /// The camera (Zhang's method) from checkerboard pictures: image files, folders of
    /// images, folders of capture folders holding `white.png`, an `slscan simulate`
    /// calibration session (its `board/` poses), or the white frames of a session described
    /// by `--layout`.
    Camera(CameraArgs),
    /// The projector and the camera together (Moreno & Taubin): one capture folder per board
    /// pose, each with the decoded pattern sequence's `manifest.json` and frames (as `slscan
    /// simulate --scene board` writes them) and, if the capture has one, `white.png`; without
    /// it the board is found in the capture's own texture (the fringe mean). Another
    /// program's session is read through `--layout`.
    Projector(ProjectorArgs),
    /// The turntable axis from a board standing on the platter at several motor angles, added
    /// to an existing calibration.
    Turntable(TurntableArgs),
    /// Camera and projector, then the turntable axis, on an `slscan simulate --scene board`
    /// session (camera alone when the pose folders hold no pattern captures), or on another
    /// program's session described by `--layout`; without a turntable folder, camera and
    /// projector only.
    All(AllArgs),
    /// The two cameras of a binocular rig from board poses both saw: each pose folder holds
    /// the left camera's `white.png` and, in `right/`, the right camera's (as `calibrate
    /// capture --right-camera` writes them). Writes `stereo.json` (a two-camera calibration:
    /// both models and `T_left_right`, with the projector when `--projector` asks for it and
    /// the turntable axis when the session has `turntable/`) and `report.json`.
    Stereo(StereoArgs),
    /// The projector's response from a grey ramp: captured on the virtual rig (`--virtual`)
    /// or on devices (`--camera`, `--projector-monitor`: point the projector at a matte wall),
    /// or read from a ramp folder (`--from`). Writes `response/`, `response.json` and, with
    /// `--calib`, the calibration with the response, whose scans correct their phase with it.
    Response(crate::calibrate_response::Args),
}

/// Arguments of `slscan calibrate stereo`.
#[derive(Debug, clap::Args)]
pub(crate) struct StereoArgs {
    /// Session folder: its `board/` subfolder, or the folder itself, holds one folder per
    /// board pose, each with `white.png` and `right/white.png`.
    pub(crate) session: PathBuf,
    /// Also calibrate the projector from the left camera's pattern captures of the poses
    /// (`manifest.json` and frames in each pose folder): three devices in one file.
    #[arg(long)]
    pub(crate) projector: bool,
    #[command(flatten)]
    pub(crate) common: BoardArgs,
}

/// Board and output options shared by the subcommands.
#[derive(Debug, clap::Args)]
pub(crate) struct BoardArgs {
    /// Inner corners of the board, `COLSxROWS` (2 to 100 each).
    #[arg(long, default_value = "9x6", value_parser = values::board_size)]
    pub(crate) board: BoardSize,
    /// Side of a square (mm, > 0, at most 1000).
    #[arg(long, default_value_t = 20.0, value_parser = values::positive_up_to(values::MAX_SQUARE_MM))]
    pub(crate) square: f64,
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Write into `--out` even where that replaces an input (the calibration a turntable
    /// axis is added to) or what another command wrote there.
    #[arg(long)]
    pub(crate) force: bool,
    /// Also write the calibration as OpenCV FileStorage YAML (`calibration.yml`).
    #[arg(long)]
    pub(crate) yaml: bool,
    /// How the board's corners are refined: `junction` (a model of two blurred edges fitted
    /// in a wide window: the lower calibration RMS on every real board set measured) or
    /// `saddle` (the saddle point in a small window).
    #[arg(long, default_value_t = CornerRefiner::default())]
    pub(crate) corners: CornerRefiner,
}

impl BoardArgs {
    /// `--out`, opened for the run (`crate::common::open_out`).
    fn open_out(&self, command: &str, read: &[&Path]) -> anyhow::Result<sl_scan::OutputFolder> {
        crate::common::open_out(&self.out, command, read, &[], self.force)
    }

    /// The board and files these options ask for.
    fn files_config(&self) -> anyhow::Result<CalibrationFilesConfig> {
        Ok(CalibrationFilesConfig {
            board: self.board,
            square_mm: self.square,
            corners: self.corners,
            yaml: self.yaml,
        })
    }
}

/// Arguments of `slscan calibrate camera`.
#[derive(Debug, clap::Args)]
pub(crate) struct CameraArgs {
    /// Image files or folders.
    #[arg(required = true)]
    pub(crate) inputs: Vec<PathBuf>,
    #[command(flatten)]
    pub(crate) common: BoardArgs,
    /// Keep the principal point at the image centre.
    #[arg(long)]
    pub(crate) fix_principal_point: bool,
    /// Keep k3 at zero.
    #[arg(long)]
    pub(crate) fix_k3: bool,
    /// Estimate the 8-coefficient rational distortion model.
    #[arg(long)]
    pub(crate) rational: bool,
    #[command(flatten)]
    pub(crate) layout: LayoutArgs,
}

/// A session written by another program.
#[derive(Debug, clap::Args)]
pub(crate) struct LayoutArgs {
    /// Layout file (`"format": "sl-calibration-layout"`) describing the session folder: which
    /// subfolders are the board poses (a pattern such as `capture_*`), the capture manifest
    /// of every pose folder, and its white (and black) frame. The files are read where they
    /// are. See docs/capture-format.md.
    #[arg(long, value_name = "FILE")]
    pub(crate) layout: Option<PathBuf>,
}

impl LayoutArgs {
    fn load(&self) -> anyhow::Result<Option<CalibrationLayout>> {
        self.layout
            .as_deref()
            .map(CalibrationLayout::load)
            .transpose()
            .map_err(Into::into)
    }
}

/// Arguments of `slscan calibrate projector`.
#[derive(Debug, clap::Args)]
pub(crate) struct ProjectorArgs {
    /// Session folder: its `board/` subfolder, or the folder itself, holds one capture folder
    /// per board pose (or the folders `--layout` names).
    pub(crate) session: PathBuf,
    /// Projector size, `WIDTHxHEIGHT` (default: the capture manifest's; another size is an
    /// error, the decoded coordinates being in the manifest's pixels).
    #[arg(long, value_parser = values::projector_size)]
    pub(crate) projector: Option<ImageSize>,
    #[command(flatten)]
    pub(crate) common: BoardArgs,
    #[command(flatten)]
    pub(crate) layout: LayoutArgs,
}

/// Arguments of `slscan calibrate turntable`.
#[derive(Debug, clap::Args)]
pub(crate) struct TurntableArgs {
    /// Session folder: its `turntable/` subfolder, or the folder itself, holds one folder per
    /// motor angle (with `white.png`) or the images themselves.
    pub(crate) session: PathBuf,
    /// The calibration (JSON, OpenCV YAML/XML) whose camera sees the board; the axis is added
    /// to it.
    #[arg(long)]
    pub(crate) calib: PathBuf,
    /// Motor angles in degrees, one per view in name order (default: each view folder's
    /// `board.json` field `motor_angle_deg`); each finite.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = values::finite)]
    pub(crate) angles: Option<Vec<f64>>,
    /// Smallest accepted span of the motor angles (degrees, 0 to 360).
    #[arg(long, default_value_t = TurntableConfig::default().min_span_deg,
          value_parser = values::in_range(0.0..=360.0))]
    pub(crate) min_span: f64,
    #[command(flatten)]
    pub(crate) common: BoardArgs,
}

/// Arguments of `slscan calibrate all`.
#[derive(Debug, clap::Args)]
pub(crate) struct AllArgs {
    /// An `slscan calibrate capture` or `slscan simulate --scene board` session (with
    /// `board/` and, for the turntable axis, `turntable/`), or the folder `--layout` describes.
    pub(crate) session: PathBuf,
    #[command(flatten)]
    pub(crate) common: BoardArgs,
    #[command(flatten)]
    pub(crate) layout: LayoutArgs,
}

/// Runs `slscan calibrate`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut bars = StageBars::new();
    let result = run_with(args, &mut |p| bars.update(p));
    bars.clear();
    result
}

fn run_with(
    args: &Args,
    progress: &mut dyn FnMut(sl_scan::ScanProgress<'_>),
) -> anyhow::Result<()> {
    match &args.what {
        What::Capture(a) => crate::calibrate_capture::run(a),
        What::Response(a) => crate::calibrate_response::run(a),
        What::Camera(a) => {
            let zhang = ZhangConfig {
                fix_principal_point: a.fix_principal_point,
                fix_k3: a.fix_k3,
                rational_model: a.rational,
                ..ZhangConfig::default()
            };
            let cfg = a.common.files_config()?;
            let images = match a.layout.load()? {
                Some(layout) => {
                    let [session] = a.inputs.as_slice() else {
                        anyhow::bail!(
                            "--layout: give one session folder, not {} inputs",
                            a.inputs.len()
                        );
                    };
                    layout_white_frames(&layout, session)?
                }
                None => camera_images(&a.inputs)?,
            };
            let read: Vec<&Path> = images.iter().map(PathBuf::as_path).collect();
            let folder = a.common.open_out("calibrate camera", &read)?;
            let files = calibrate_camera_files(
                &images,
                &cfg,
                &zhang,
                folder.path(),
                "calibrate camera",
                progress,
            )?;
            folder.commit()?;
            print_skipped(&files.skipped);
            outln!(
                "camera calibrated: RMS {:.4} px over {} views ({} without a board skipped); {}",
                files.camera.rms,
                files.camera.view_rms.len(),
                images.len() - files.camera.view_rms.len(),
                a.common.out.join("calibration.json").display()
            );
            Ok(())
        }
        What::Projector(a) => {
            let cfg = a.common.files_config()?;
            let layout = a.layout.load()?;
            let poses = session_poses(&a.session, layout.as_ref())?;
            let given = a.projector;
            let projector_size = sl_scan::projector_size(&poses, given)?;
            let folder = a.common.open_out("calibrate projector", &[])?;
            let files = calibrate_procam_files(
                &poses,
                &cfg,
                projector_size,
                layout.as_ref(),
                folder.path(),
                "calibrate projector",
                progress,
            )?;
            folder.commit()?;
            print_procam_notes(&files);
            let cal = &files.procam;
            outln!(
                "camera RMS {:.4} px, projector RMS {:.4} px, stereo RMS {:.4} px over {} views; {}",
                cal.rms_camera,
                cal.rms_projector,
                cal.rms_stereo,
                cal.views.len(),
                a.common.out.join("calibration.json").display()
            );
            print_predicted(cal);
            Ok(())
        }
        What::Turntable(a) => {
            let cfg = a.common.files_config()?;
            let calib = Calibration::load(&a.calib)
                .with_context(|| format!("cannot read the calibration {}", a.calib.display()))?;
            let tcfg = TurntableConfig {
                min_span_deg: a.min_span,
                ..TurntableConfig::default()
            };
            let views = turntable_views(&a.session, a.angles.as_deref()).with_context(|| {
                if a.angles.is_some() {
                    "--angles"
                } else {
                    "the motor angles (give them with --angles)"
                }
            })?;
            let folder = a.common.open_out("calibrate turntable", &[&a.calib])?;
            let files = calibrate_turntable_files(
                calib,
                &views,
                &cfg,
                &tcfg,
                folder.path(),
                "calibrate turntable",
                progress,
            )?;
            folder.commit()?;
            print_axis(&files, &a.common.out);
            Ok(())
        }
        What::Stereo(a) => {
            let cfg = a.common.files_config()?;
            let folder = a.common.open_out("calibrate stereo", &[])?;
            let files = sl_scan::calibrate_stereo_files(
                &a.session,
                &cfg,
                a.projector,
                folder.path(),
                "calibrate stereo",
                progress,
            )?;
            folder.commit()?;
            let s = &files.stereo;
            for v in &s.skipped_views {
                outln!("left out: {}: {}", v.name, v.reason);
            }
            let t = s.t_left_right.translation.vector;
            outln!(
                "left camera RMS {:.4} px, right camera RMS {:.4} px, stereo RMS {:.4} px over {} of {} poses; baseline {:.2} mm ({:+.2}, {:+.2}, {:+.2}), turned {:.3}°",
                s.rms_left,
                s.rms_right,
                s.rms_stereo,
                s.views.len(),
                files.poses,
                t.norm(),
                t.x,
                t.y,
                t.z,
                s.t_left_right.rotation.angle().to_degrees()
            );
            if let Some(p) = &files.projector {
                print_procam(&p.procam);
            }
            if let Some(t) = &files.turntable {
                print_axis(t, &a.common.out.join("turntable"));
            }
            outln!("{}", a.common.out.join(sl_scan::STEREO_FILE).display());
            Ok(())
        }
        What::All(a) => {
            let cfg = a.common.files_config()?;
            let layout = a.layout.load()?;
            let out = &a.common.out;
            let folder = a.common.open_out("calibrate all", &[])?;
            let done =
                calibrate_session(&a.session, layout.as_ref(), &cfg, folder.path(), progress)?;
            folder.commit()?;
            if let Some(c) = &done.camera {
                print_skipped(&c.skipped);
                outln!(
                    "camera: RMS {:.4} px over {} views",
                    c.camera.rms,
                    c.camera.view_rms.len()
                );
            }
            if let Some(p) = &done.procam {
                print_procam_notes(p);
                print_procam(&p.procam);
            }
            match &done.turntable {
                Some(t) => print_axis(t, out),
                None => outln!(
                    "no turntable folder ({}): {} only; {}. Add the turntable axis with \
                     `slscan calibrate turntable TURNTABLE_FOLDER --calib {} --out DIR`",
                    a.session.join(sl_scan::TURNTABLE_DIR).display(),
                    if done.procam.is_some() {
                        "camera and projector"
                    } else {
                        "camera"
                    },
                    out.join("calibration.json").display(),
                    out.join("calibration.json").display()
                ),
            }
            Ok(())
        }
    }
}

fn print_skipped(skipped: &[SkippedImage]) {
    for s in skipped {
        errln!("slscan: skipping {}", s.reason);
    }
}

/// The projector step's notes: the poses whose board was found in their own texture, and the
/// poses the calibration skipped.
fn print_procam_notes(files: &ProcamFiles) {
    if let Some(first) = files.textured.first() {
        outln!(
            "board images: {} of {} poses have no white frame; their corners are found in the \
             capture's own texture ({first})",
            files.textured.len(),
            files.poses
        );
    }
    for s in &files.procam.skipped_views {
        // The detector's reasons begin with the view's name.
        if s.reason.starts_with(&s.name) {
            errln!("slscan: skipping board pose {}", s.reason);
        } else {
            errln!("slscan: skipping board pose {}: {}", s.name, s.reason);
        }
    }
}

fn print_procam(cal: &ProcamCalibration) {
    outln!(
        "camera RMS {:.4} px, projector RMS {:.4} px, stereo RMS {:.4} px over {} views",
        cal.rms_camera,
        cal.rms_projector,
        cal.rms_stereo,
        cal.views.len()
    );
    print_predicted(cal);
}

/// The accuracy the calibration predicts for itself, or why there is none.
fn print_predicted(cal: &ProcamCalibration) {
    match &cal.predicted_error {
        Some(p) => outln!("{}", p.sentence()),
        None => outln!(
            "no accuracy prediction: the joint refinement's normal equations are singular (too few or too similar board poses)"
        ),
    }
}

fn print_axis(files: &TurntableFiles, out: &Path) {
    let fit = &files.turntable;
    print_skipped(&files.skipped);
    let d = fit.axis.direction;
    let p = fit.axis.point_mm;
    outln!(
        "turntable axis: direction ({:.5}, {:.5}, {:.5}) ± {:.4}°, through ({:.2}, {:.2}, {:.2}) mm ± {:.3} mm, scale {:.5}, RMS {:.4} px; {}",
        d.x,
        d.y,
        d.z,
        fit.std_dev.direction_deg,
        p.x,
        p.y,
        p.z,
        fit.std_dev.point_mm,
        fit.axis.angle_scale,
        fit.rms,
        out.join("calibration.json").display()
    );
}

#[cfg(test)]
mod tests {
    //! `slscan calibrate` itself, on a session the virtual rig renders at a quarter of its
    //! resolution (320x180 camera, 480x270 projector): the files it promises, and figures
    //! compared with the rig's own parameters (the truth), never with an earlier output.

    use std::path::Path;

    use sl_calib::CalibError;
    use sl_calib::sl_camera::Calibration;
    use sl_calib::sl_codec::{Axis, BitDepth, HybridSpec, ImageSize, Pattern, PatternSequence};
    use sl_sim::{CalibrationSession, Scene, VirtualRig, simulate_calibration};
    use structured_light::scan::scaled_rig_config;

    /// Quarter resolution: a 20 mm square still spans ~15 camera pixels at 450 mm.
    const DOWNSCALE: u32 = 4;

    pub(super) fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    /// Board poses of the shared session ([`rendered_session`]).
    pub(super) const SESSION_POSES: usize = 10;

    /// A rendered session kept in memory: its files (path relative to the session, bytes)
    /// and the rig that rendered it.
    struct Rendered {
        rig: VirtualRig,
        files: Vec<(std::path::PathBuf, Vec<u8>)>,
    }

    /// Writes the calibration session the `calibrate` tests read into `dir` and returns the
    /// rig that rendered it: [`SESSION_POSES`] `board/` poses with both projector axes
    /// coded, the default `turntable/` views, and its `rig.json`, as `slscan simulate --scene
    /// board` writes them. Rendered once per test process and kept in memory (rendering is
    /// most of a `calibrate all` test's time); each test gets its own copy, which it may
    /// change. A test that needs fewer poses reads the first ones.
    pub(super) fn rendered_session(dir: &Path) -> VirtualRig {
        static SESSION: std::sync::OnceLock<Rendered> = std::sync::OnceLock::new();
        let rendered = SESSION.get_or_init(|| {
            let tmp = tempfile::tempdir().unwrap();
            let rig = simulate(tmp.path(), SESSION_POSES);
            let files = crate::common::files_below(tmp.path())
                .into_iter()
                .map(|p| {
                    let bytes = std::fs::read(&p).unwrap();
                    (p.strip_prefix(tmp.path()).unwrap().to_path_buf(), bytes)
                })
                .collect();
            Rendered { rig, files }
        });
        for (relative, bytes) in &rendered.files {
            let path = dir.join(relative);
            if let Some(parent) = path.parent() {
                std::fs::create_dir_all(parent).unwrap();
            }
            std::fs::write(path, bytes).unwrap();
        }
        rendered.rig.clone()
    }

    /// Renders a calibration session (`board/` poses with both projector axes coded,
    /// `turntable/` views at the default angles) and its `rig.json`, as `slscan simulate
    /// --scene board` does.
    fn simulate(dir: &Path, poses: usize) -> VirtualRig {
        let mut config = scaled_rig_config(DOWNSCALE);
        config.render.supersampling = 4;
        config.angle_scale = 1.02;
        config.angle_offset_deg = 3.0;
        let rig = VirtualRig::new(config, Scene::plane()).unwrap();
        let p = rig.config().projector.size;
        let p = ImageSize::new(p.width, p.height);
        let code = |axis, extent: u32| {
            Pattern::Hybrid(HybridSpec::complementary(
                axis,
                p,
                4,
                f64::from(extent) / 30.0,
            ))
        };
        let manifest = PatternSequence::new(p)
            .with(code(Axis::Column, p.width))
            .with(code(Axis::Row, p.height))
            .manifest(BitDepth::Eight);
        let mut session = CalibrationSession::default();
        session.poses.count = poses;
        simulate_calibration(&rig, &session, &manifest, dir, |_| {}).unwrap();
        std::fs::write(
            dir.join("rig.json"),
            serde_json::to_string(rig.config()).unwrap(),
        )
        .unwrap();
        rig
    }

    fn is_png(path: &Path) -> bool {
        sl_calib::load_grey(path).is_ok()
    }

    /// The whole of `calibrate all` on 10 board poses and 7 table views.
    #[test]
    fn calibrate_all_writes_a_calibration_near_the_truth_and_its_pictures() {
        let tmp = tempfile::tempdir().unwrap();
        let session = tmp.path().join("session");
        let rig = rendered_session(&session);
        let out = tmp.path().join("calib");
        slscan(&[
            "calibrate",
            "all",
            session.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap();

        let c = Calibration::load(out.join("calibration.json")).unwrap();
        let truth = rig.config();
        // Quarter resolution quadruples the corner noise in mm; the sl-calib targets at full
        // resolution are 0.1 % on fx and 0.05° on the axis.
        let fx = c.camera.intrinsics.fx;
        assert!(
            (fx / truth.camera.intrinsics.fx - 1.0).abs() < 0.005,
            "{fx}"
        );
        let proj = c.projector.unwrap();
        let pfx = proj.intrinsics.fx;
        assert!(
            (pfx / truth.projector.intrinsics.fx - 1.0).abs() < 0.01,
            "{pfx}"
        );
        let t = c.t_cam_proj.unwrap().translation.vector - truth.t_cam_proj.translation.vector;
        assert!(t.norm() < 2.0, "baseline off by {t:?} mm");
        let axis = c.turntable.unwrap();
        let d_true = truth.turntable_axis().direction;
        let angle = axis
            .direction
            .dot(&d_true)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        assert!(angle < 0.2, "axis direction {angle} deg off");
        assert!((axis.angle_scale - 1.02).abs() < 0.005, "{axis:?}");

        // report.json of the turntable step, and of the projector step under projector/.
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        let rms = report["figures"]["rms_px"].as_f64().unwrap();
        assert!(rms > 0.0 && rms < 0.5, "{report}");
        assert_eq!(report["figures"]["views_used"].as_u64(), Some(7));
        let procam: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join("projector/report.json")).unwrap(),
        )
        .unwrap();
        for key in ["rms_camera_px", "rms_projector_px", "rms_stereo_px"] {
            let v = procam["figures"][key].as_f64().unwrap();
            assert!(v > 0.0 && v < 0.5, "{key} = {v}");
        }

        // The pictures exist and decode.
        let mut pngs = 0;
        for dir in [out.clone(), out.join("projector")] {
            for e in crate::common::files_below(&dir) {
                if e.extension().is_some_and(|x| x == "png") {
                    assert!(is_png(&e), "{} does not decode", e.display());
                    pngs += 1;
                }
            }
        }
        // Corners on each of the 10 poses and 7 table views, plus error bars and residuals.
        assert!(pngs >= 17 + 4, "{pngs} pictures");
    }

    /// `calibrate all` on a session saved as BMP (SLStudio's format): every `white.png` and
    /// pattern frame converted to `.bmp` and the PNGs deleted, the manifests still naming
    /// `.png`. The white frames are found as `white.bmp`, the frames under their BMP names,
    /// and the calibration is the rig's.
    #[test]
    fn calibrate_all_on_a_session_saved_as_bmp() {
        let tmp = tempfile::tempdir().unwrap();
        let session = tmp.path().join("session");
        let rig = rendered_session(&session);
        let mut converted = 0;
        for f in crate::common::files_below(&session) {
            if f.extension().is_some_and(|e| e == "png") {
                let img = image::open(&f).unwrap();
                img.save(f.with_extension("bmp")).unwrap();
                std::fs::remove_file(&f).unwrap();
                converted += 1;
            }
        }
        assert!(converted > SESSION_POSES * 2, "{converted} files converted");
        let out = tmp.path().join("calib");
        slscan(&[
            "calibrate",
            "all",
            session.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap();
        let procam: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join("projector/report.json")).unwrap(),
        )
        .unwrap();
        let images = procam["figures"]["board_images"].as_array().unwrap();
        assert_eq!(images.len(), SESSION_POSES);
        for b in images {
            assert_eq!(b["board_image"].as_str(), Some("white.bmp"), "{b}");
        }
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(report["figures"]["views_used"].as_u64(), Some(7));
        let c = Calibration::load(out.join("calibration.json")).unwrap();
        let truth = rig.config();
        let fx = c.camera.intrinsics.fx;
        assert!(
            (fx / truth.camera.intrinsics.fx - 1.0).abs() < 0.005,
            "{fx}"
        );
        let pfx = c.projector.unwrap().intrinsics.fx;
        assert!(
            (pfx / truth.projector.intrinsics.fx - 1.0).abs() < 0.01,
            "{pfx}"
        );
    }

    /// `calibrate projector` on a session whose `white.png` files are deleted (as SLStudio's
    /// calibration sequences have none) finds the boards in the captures' fringe means and
    /// calibrates to an RMS close to the one with the white frames, near the rig's truth.
    #[test]
    fn calibrate_projector_without_white_frames_uses_the_fringe_mean() {
        let tmp = tempfile::tempdir().unwrap();
        let session = tmp.path().join("session");
        let rig = rendered_session(&session);
        let run = |out: &str| {
            let out = tmp.path().join(out);
            slscan(&[
                "calibrate",
                "projector",
                session.to_str().unwrap(),
                "--projector",
                "480x270",
                "--out",
                out.to_str().unwrap(),
            ])
            .unwrap();
            let report: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                    .unwrap();
            let calib = Calibration::load(out.join("calibration.json")).unwrap();
            (report, calib)
        };
        let (with_white, _) = run("white");
        let mut deleted = 0;
        for f in crate::common::files_below(&session.join("board")) {
            if f.file_name().is_some_and(|n| n == "white.png") {
                std::fs::remove_file(f).unwrap();
                deleted += 1;
            }
        }
        assert_eq!(deleted, SESSION_POSES);
        let (without, calib) = run("fringe_mean");
        let images = without["figures"]["board_images"].as_array().unwrap();
        assert_eq!(images.len(), SESSION_POSES);
        for b in images {
            let source = b["board_image"].as_str().unwrap();
            assert!(source.starts_with("fringe mean of block 0"), "{source}");
        }
        for key in ["rms_camera_px", "rms_projector_px", "rms_stereo_px"] {
            let a = with_white["figures"][key].as_f64().unwrap();
            let b = without["figures"][key].as_f64().unwrap();
            eprintln!("{key}: {a:.4} px with white.png, {b:.4} px with the fringe mean");
            // The fringe mean is the board under half the light: a little more corner noise
            // at worst, never a different calibration.
            assert!(b < 0.5 && b < 1.5 * a + 0.02, "{key}: {b} vs {a}");
        }
        let truth = rig.config();
        let pfx = calib.projector.unwrap().intrinsics.fx;
        assert!(
            (pfx / truth.projector.intrinsics.fx - 1.0).abs() < 0.01,
            "projector fx {pfx} vs {}",
            truth.projector.intrinsics.fx
        );
        let fx = calib.camera.intrinsics.fx;
        assert!(
            (fx / truth.camera.intrinsics.fx - 1.0).abs() < 0.005,
            "camera fx {fx}"
        );
    }

    /// The light part, on in debug: `calibrate camera` on the white images of a few rendered
    /// poses, against the rig's focal length.
    #[test]
    fn calibrate_camera_on_rendered_boards_finds_the_focal_length() {
        let tmp = tempfile::tempdir().unwrap();
        let mut config = scaled_rig_config(DOWNSCALE);
        config.render.supersampling = 4;
        let rig = VirtualRig::new(config, Scene::plane()).unwrap();
        let board = sl_sim::Checkerboard::default();
        let poses = sl_sim::random_board_poses(
            rig.config(),
            &board,
            &sl_sim::BoardPoseConfig {
                count: 6,
                ..sl_sim::BoardPoseConfig::default()
            },
        )
        .unwrap();
        let images = tmp.path().join("images");
        std::fs::create_dir_all(&images).unwrap();
        for (k, pose) in poses.iter().enumerate() {
            let cap = sl_sim::capture_board(&rig, &board, pose, None, k as u64).unwrap();
            sl_codec::write_png_grey(&images.join(format!("board_{k}.png")), &cap.white).unwrap();
        }
        let out = tmp.path().join("out");
        slscan(&[
            "calibrate",
            "camera",
            images.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap();
        let c = Calibration::load(out.join("calibration.json")).unwrap();
        let fx = c.camera.intrinsics.fx;
        // Six poses at quarter resolution: 1 % (the full-resolution target is 0.1 %).
        assert!(
            (fx / rig.config().camera.intrinsics.fx - 1.0).abs() < 0.01,
            "fx {fx} vs {}",
            rig.config().camera.intrinsics.fx
        );
        let pictures: Vec<_> = crate::common::files_below(&out)
            .into_iter()
            .filter(|p| p.extension().is_some_and(|x| x == "png"))
            .collect();
        assert!(pictures.len() >= 6 + 2, "{pictures:?}");
        assert!(pictures.iter().all(|p| is_png(p)));
    }

    /// A folder whose images hold no board: a typed calibration error that names the folder's
    /// images, and no calibration file.
    #[test]
    fn a_folder_without_boards_is_a_named_error() {
        let tmp = tempfile::tempdir().unwrap();
        let images = tmp.path().join("blank");
        std::fs::create_dir_all(&images).unwrap();
        for k in 0..3 {
            let img = sl_codec::Frame::filled(160, 120, 128).unwrap();
            sl_codec::write_png_grey8(&images.join(format!("blank_{k}.png")), &img).unwrap();
        }
        let out = tmp.path().join("out");
        let err = slscan(&[
            "calibrate",
            "camera",
            images.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap_err();
        assert!(
            err.chain()
                .any(|e| e.downcast_ref::<CalibError>().is_some()),
            "{err:#}"
        );
        let text = format!("{err:#}");
        assert!(text.contains("blank_0.png"), "{text}");
        assert!(!out.join("calibration.json").exists());
    }

    /// `--square` is a square's side in mm, finite and > 0, in every subcommand, refused by its
    /// name before anything is read: before, `calibrate camera --square -20` calibrated (exit
    /// 0) and 0 or NaN failed later in terms the user never gave.
    #[test]
    fn every_subcommand_refuses_a_square_that_is_no_length_by_its_name() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("out");
        let (out, missing) = (out.to_str().unwrap(), "no-such-session");
        let subcommands: [&[&str]; 5] = [
            &["camera", missing],
            &["projector", missing],
            &["turntable", missing, "--calib", "no-such.json"],
            &["all", missing],
            &["capture", "--virtual", "--auto"],
        ];
        for sub in subcommands {
            for bad in ["-20", "0", "NaN", "inf", "-inf"] {
                let square = format!("--square={bad}");
                let mut args = vec!["calibrate"];
                args.extend_from_slice(sub);
                args.extend(["--out", out, &square]);
                let err = slscan(&args).unwrap_err();
                let text = format!("{err:#}");
                assert!(
                    text.contains("--square") && text.contains(bad),
                    "{sub:?} {bad}: {text}"
                );
            }
        }
        assert!(!tmp.path().join("out").exists());
    }
}

#[cfg(test)]
#[path = "calibrate_layout_tests.rs"]
mod layout_tests;
