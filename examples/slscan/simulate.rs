//! `slscan simulate`: capture sets of a virtual rig (turntable scans or calibration
//! sessions) with their ground truth.

use std::path::{Path, PathBuf};

use anyhow::Context;
use nalgebra::Vector3;
use serde_json::json;
use sl_codec::{MANIFEST_FILE, Manifest};
use sl_rig::turntable_angles;
use sl_sim::{
    BitDepth, CalibrationSession, Checkerboard, GlobalIllumination, MeshUnits, RigConfig, Scene,
    SimulatedCapture, VirtualRig, simulate_calibration, simulate_scan,
};

use crate::common::{Report, open_out, progress, write_atomically};
use crate::values;

/// Super-sampling for checkerboards: corner accuracy needs well anti-aliased edges.
const BOARD_SUPERSAMPLING: u32 = 4;

/// Arguments of `slscan simulate`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Scene: plane, sphere, dumbbell, box, cylinder, bunny, board, or a mesh FILE.ply.
    #[arg(long)]
    pub(crate) scene: String,
    /// Folder holding the patterns' `manifest.json` (as `slscan patterns` writes it).
    #[arg(long)]
    pub(crate) patterns: PathBuf,
    /// Number of views: turntable positions over a full turn, or board poses for `board` (1 to
    /// 3600).
    #[arg(long, default_value_t = 1, value_parser = values::views())]
    pub(crate) views: usize,
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Write into `--out` even where that replaces the patterns' manifest.
    #[arg(long)]
    pub(crate) force: bool,
    /// Seed of the noise (and of the board poses).
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Camera rays per pixel along each axis (default 2, or 4 for `board`; 1 to 16).
    #[arg(long, value_parser = values::count_in::<u32>(1..=16))]
    pub(crate) supersampling: Option<u32>,
    /// Bits per camera pixel: 8 or 16.
    #[arg(long, default_value_t = 8, value_parser = values::bit_depth::<u32>)]
    pub(crate) bits: u32,
    /// Add a global-illumination term of this weight (e.g. 0.2; 0 to 1).
    #[arg(long, value_parser = values::in_range(0.0..=1.0))]
    pub(crate) global_light: Option<f64>,
    /// Depth-dependent defocus (a 3 mm pupil focused at 450 mm).
    #[arg(long)]
    pub(crate) defocus: bool,
    /// Projector gamma (default 1: linear; 0.1 to 10).
    #[arg(long, value_parser = values::in_range(0.1..=10.0))]
    pub(crate) gamma: Option<f64>,
    /// Inner corners of the `board` scene, `COLSxROWS` (2 to 100 each).
    #[arg(long, default_value = "9x6", value_parser = values::board_size)]
    pub(crate) board: sl_calib::BoardSize,
    /// Square size of the `board` scene (mm, > 0, at most 1000).
    #[arg(long, default_value_t = 20.0, value_parser = values::positive_up_to(values::MAX_SQUARE_MM))]
    pub(crate) square_mm: f64,
    /// No photon or read noise.
    #[arg(long)]
    pub(crate) no_noise: bool,
}

/// Runs `slscan simulate`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("simulate");
    let manifest_path = args.patterns.join(MANIFEST_FILE);
    let folder = open_out(&args.out, "simulate", &[&manifest_path], &[], args.force)?;
    let out = folder.path().to_path_buf();
    let manifest = report.stage("read patterns", || Manifest::load(&manifest_path))?;
    let board = args.scene == "board";
    let config = config(args, board)?;
    let scene = if board {
        Scene::plane()
    } else {
        scene(&args.scene)?
    };
    let rig = VirtualRig::new(config, scene).context("cannot build the virtual rig")?;
    report.stage("camera rays", || rig.camera_rays());

    let calibration = rig.config().calibration();
    calibration
        .save(out.join("calibration.json"))
        .with_context(|| format!("cannot write {}", out.join("calibration.json").display()))?;
    let rig_json =
        serde_json::to_string_pretty(rig.config()).context("cannot serialise rig.json")?;
    write_atomically(&out.join("rig.json"), rig_json.as_bytes())?;

    let captures = if board {
        let mut session = CalibrationSession {
            board: checkerboard(args.board, args.square_mm)?,
            ..CalibrationSession::default()
        };
        session.poses.count = args.views;
        session.poses.seed = args.seed;
        let bar = progress(
            (args.views + session.turntable_angles_deg.len()) as u64,
            "capturing",
        );
        let c = report.stage("captures", || {
            simulate_calibration(&rig, &session, &manifest, &out, |_| bar.inc(1))
        })?;
        bar.finish_and_clear();
        report.figure("board", serde_json::to_value(session.board)?);
        report.figure("board_poses", args.views);
        report.figure("turntable_angles_deg", session.turntable_angles_deg.clone());
        c
    } else {
        let angles = turntable_angles(args.views);
        let bar = progress(angles.len() as u64, "rendering");
        let c = report.stage("views", || {
            simulate_scan(&rig, &manifest, &angles, &out, |_| bar.inc(1))
        })?;
        bar.finish_and_clear();
        c
    };
    summarise(&mut report, args, &manifest, &captures, &folder);
    report.write(&out)?;
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    outln!(
        "{} capture sets of {} frames written to {} (report: {})",
        captures.len(),
        manifest.frame_count(),
        out.display(),
        out.join("report.json").display()
    );
    Ok(())
}

fn config(args: &Args, board: bool) -> anyhow::Result<RigConfig> {
    let mut c = RigConfig::default();
    c.render.seed = args.seed;
    c.render.supersampling =
        args.supersampling
            .unwrap_or(if board { BOARD_SUPERSAMPLING } else { 2 });
    c.render.effects.sensor.bit_depth = match args.bits {
        8 => BitDepth::Eight,
        16 => BitDepth::Sixteen,
        b => anyhow::bail!("--bits {b}: expected 8 or 16"),
    };
    if let Some(w) = args.global_light {
        c.render.effects.global_illumination = Some(GlobalIllumination {
            weight: w,
            ..GlobalIllumination::default()
        });
    }
    if args.defocus {
        c.render.effects.defocus = Some(sl_sim::Defocus::default());
    }
    if let Some(g) = args.gamma {
        c.render.illumination.gamma = g;
    }
    if args.no_noise {
        c.render.effects.sensor.photon_noise = false;
        c.render.effects.sensor.read_noise_electrons = 0.0;
    }
    Ok(c)
}

fn checkerboard(size: sl_calib::BoardSize, square_mm: f64) -> anyhow::Result<Checkerboard> {
    let board = Checkerboard {
        inner_cols: size.cols,
        inner_rows: size.rows,
        square_mm,
        ..Checkerboard::default()
    };
    board.validate()?;
    Ok(board)
}

fn scene(name: &str) -> anyhow::Result<Scene> {
    if let Some(scene) = Scene::named(name) {
        return Ok(scene);
    }
    match name {
        "bunny" => mesh_scene(&bunny_path()?),
        file if file.to_ascii_lowercase().ends_with(".ply") => mesh_scene(Path::new(file)),
        other => anyhow::bail!(
            "--scene {other}: expected {}, bunny, board or a .ply file",
            Scene::NAMES.join(", ")
        ),
    }
}

/// `bun000.ply` of the Stanford bunny in `$SL_DATA/bunny` (or `../shared/data/bunny`).
fn bunny_path() -> anyhow::Result<PathBuf> {
    let root =
        std::env::var_os("SL_DATA").map_or_else(|| PathBuf::from("../shared/data"), PathBuf::from);
    let p = root.join("bunny").join("bun000.ply");
    anyhow::ensure!(
        p.exists(),
        "{}: not found (set SL_DATA to the shared data folder)",
        p.display()
    );
    Ok(p)
}

fn mesh_scene(path: &Path) -> anyhow::Result<Scene> {
    // Scans (the Stanford bunny among them) are y-up; units in metres are detected.
    Scene::ply_mesh(path, MeshUnits::Auto, Vector3::y())
        .with_context(|| format!("cannot build a scene from {}", path.display()))
}

/// The report's figures; the capture folders named where they will be once `folder` is
/// committed.
fn summarise(
    report: &mut Report,
    args: &Args,
    manifest: &Manifest,
    captures: &[SimulatedCapture],
    folder: &sl_scan::OutputFolder,
) {
    report.figure("scene", args.scene.clone());
    report.figure("patterns", args.patterns.display().to_string());
    report.figure("frames_per_view", manifest.frame_count());
    report.figure("capture_sets", captures.len());
    let n = captures.len().max(1) as f64;
    let mean = |f: &dyn Fn(&SimulatedCapture) -> f64| captures.iter().map(f).sum::<f64>() / n;
    report.figure("mean_render_ms_per_view", mean(&|c| c.render_ms));
    report.figure("mean_cast_ms_per_view", mean(&|c| c.cast_ms));
    report.figure("mean_write_ms_per_view", mean(&|c| c.write_ms));
    report.figure(
        "captures",
        captures
            .iter()
            .map(|c| {
                json!({
                    "dir": folder.final_path(&c.dir).display().to_string(),
                    "motor_angle_deg": c.motor_angle_deg,
                    "visible_pixels": c.visible_pixels,
                    "lit_pixels": c.lit_pixels,
                })
            })
            .collect::<Vec<_>>(),
    );
}
