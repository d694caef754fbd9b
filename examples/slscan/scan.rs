//! `slscan scan --out DIR`: the whole scan in one command. Without hardware options it runs on
//! the virtual rig (`structured_light::scan::scan_virtual`): calibrates from simulated
//! board captures, captures a turntable session of a dumbbell, decodes, triangulates, merges,
//! measures the result against the truth (sl-metrology; `truth.json` beside `merged.ply`, so
//! `slscan report` reproduces the figures), captures a tilted flat plate for the flatness,
//! and writes the merged PLY, previews, error heat maps, `report.json` and `index.html`.
//! `--placements 2` scans an object with a top and a bottom twice — standing, then laid on its
//! side — and merges both placements into one complete model (`placement_1/`, `placement_2/`;
//! on the virtual rig the pebble, measured by the coverage of its true surface).

use std::path::PathBuf;

use structured_light::mesh::{FairConfig, SimplifyConfig};
use structured_light::scan::{
    MeshConfig, VirtualScanConfig, check_placements, scan_virtual, scan_virtual_placements,
    write_summary_html,
};

use crate::capture::HardwareArgs;
use crate::common::{Report, StageBars, open_out_in_place};
use crate::values;

/// Arguments of `slscan scan`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Turntable views over a full turn (1 to 3600).
    #[arg(long, default_value_t = 36, value_parser = values::views())]
    pub(crate) views: usize,
    /// Board poses of the simulated calibration (at least 3: Zhang's method needs three views
    /// of a plane).
    #[arg(long, default_value_t = 12, value_parser = values::at_least::<usize>(3))]
    pub(crate) calibration_poses: usize,
    /// Divide the virtual rig's resolution by this (2 or 4 for a quick look; 1 to 8).
    #[arg(long, default_value_t = 1, value_parser = values::downscale())]
    pub(crate) downscale: u32,
    /// Seed of the board poses and the sensor noise.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Recapture views that an earlier run of the same scan already captured.
    #[arg(long)]
    pub(crate) overwrite: bool,
    /// Do not average overlapping views in the merge (moving least squares along the
    /// normals, on by default).
    #[arg(long)]
    pub(crate) no_average: bool,
    /// Drop points whose surface normal is more than this many degrees from the direction to
    /// the camera or the projector (90 keeps every point; > 0).
    #[arg(long, default_value_t = VirtualScanConfig::default().max_view_angle_deg,
          value_parser = values::positive_up_to(90.0))]
    pub(crate) max_view_angle: f64,
    /// Diagnostic: triangulate with the virtual rig's true calibration (nothing estimated).
    #[arg(long)]
    pub(crate) true_calibration: bool,
    /// Diagnostic: merge with the virtual rig's true turntable poses (no registration).
    #[arg(long)]
    pub(crate) true_poses: bool,
    /// Neighbours of each merged point for its normal and the moving-least-squares surface
    /// the averaging moves it onto (more: smoother; 3 to 1000).
    #[arg(long, default_value_t = VirtualScanConfig::default().smoothing_neighbours,
          value_parser = values::count_in::<usize>(3..=1000))]
    pub(crate) smoothing_neighbours: usize,
    /// Drop the points within this many pixels of the edge of the valid region of each view
    /// (silhouettes, plate edges, hole rims; at most 100).
    #[arg(long, default_value_t = VirtualScanConfig::default().edge_erosion_px,
          value_parser = values::count_in::<usize>(0..=100))]
    pub(crate) edge_erosion: usize,
    /// Keep every vertex of the mesh's extraction (no error-bounded simplification, which is
    /// on by default: see `slscan mesh --no-simplify`).
    #[arg(long)]
    pub(crate) no_simplify: bool,
    /// Leave the surface that closes what the scanner never saw as the reconstruction made it
    /// (see `slscan mesh --no-fair`; the fairing follows the simplification, so
    /// `--no-simplify` leaves it too).
    #[arg(long)]
    pub(crate) no_fair: bool,
    /// Fair every gap from Poisson's rim as it is, without first putting the rim of a gap in
    /// smooth surface on its local quadric (see `slscan mesh --no-fair-rim`).
    #[arg(long)]
    pub(crate) no_fair_rim: bool,
    /// Do not capture the flat plate (no flatness figure).
    #[arg(long)]
    pub(crate) no_plate: bool,
    /// Half-width (pixels) of the window that smooths each view's decoded projector
    /// coordinates before triangulation (a local plane fitted to the valid neighbours, 1 =
    /// 3 × 3; at most 4); 0 triangulates each pixel's own decode.
    #[arg(long, default_value_t = 1,
          value_parser = values::count_in::<usize>(0..=structured_light::codec::MAX_SMOOTH_RADIUS as u64))]
    pub(crate) smooth: usize,
    /// How the simulated calibration refines the board's corners: `junction` or `saddle`
    /// (see `slscan calibrate camera --corners`).
    #[arg(long, default_value_t = structured_light::calib::CornerRefiner::default())]
    pub(crate) corners: structured_light::calib::CornerRefiner,
    /// Turntable sessions of the object, re-placed in between: 1, or 2 to scan it standing
    /// and then laid on its side and merge both into one complete model (on the virtual rig:
    /// the pebble, an object with a flat bottom; on real devices the command waits for you to
    /// lay the object on its side).
    #[arg(long, default_value_t = 1)]
    pub(crate) placements: usize,
    /// Between two placements on real devices, wait this many seconds instead of asking to
    /// press Enter (for scripts; 0 to 86400).
    #[arg(long, value_parser = values::in_range(0.0..=86_400.0))]
    pub(crate) placement_wait: Option<f64>,
    /// Scan with two cameras (binocular structured light) on the virtual rig: a second camera
    /// on the other side of the projector, both calibrated from the board captures, each view
    /// matched between the cameras; the projector only labels the surface. The same scene,
    /// merge and figures as the one-camera scan, for comparing the two.
    #[arg(long)]
    pub(crate) binocular: bool,
    /// Exponent of the virtual projector's response, which the patterns do not pre-compensate
    /// (1: a linear projector; 2.2: a display-calibrated one run as it comes; 0.2 to 5).
    #[arg(long, default_value_t = 1.0, value_parser = values::in_range(0.2..=5.0))]
    pub(crate) projector_gamma: f64,
    /// The shape of the virtual projector's response: `power` (a power law of
    /// --projector-gamma) or `measured` (a consumer DLP's curve: blacks crushed below 3 %, a
    /// gamma of about 2.4, the whites rolled off).
    #[arg(long, value_enum, default_value_t = ResponseArg::Power)]
    pub(crate) projector_response: ResponseArg,
    /// What the virtual scan does about its projector's response: `none`; `decode` (measure
    /// it first with a grey ramp on a flat plate, `response/`, keep it in calibration.json
    /// and correct every decoded phase with it); `precompensate` (measure it, keep it, and
    /// pre-compensate it in the fringes: full fringe contrast). On devices the calibration's
    /// response (`slscan calibrate response`) is used whenever it holds one.
    #[arg(long, value_enum, default_value_t = CorrectionArg::None)]
    pub(crate) correct_response: CorrectionArg,
    /// Phase steps of the virtual rig's scan patterns (3 to 16; default 8, the recommended
    /// capture's).
    #[arg(long, default_value_t = structured_light::scan::SCAN_PHASE_STEPS,
          value_parser = values::count_in::<u32>(3..=16))]
    pub(crate) phase_steps: u32,
    /// The virtual projector's lens distortion instead of the rig's: OpenCV's coefficients
    /// `k1,k2,p1,p2,k3` or, for the rational model, `k1,k2,p1,p2,k3,k4,k5,k6` (the
    /// calibration estimates 5 coefficients; `docs/binocular.md` compares the two scans).
    #[arg(long, value_parser = values::distortion)]
    pub(crate) projector_distortion: Option<structured_light::camera::Distortion>,
    /// Turn the virtual projector by this many degrees (about its vertical axis) between the
    /// calibration and the scan, as a projector warming up or knocked does (-5 to 5).
    #[arg(long, default_value_t = 0.0, value_parser = values::in_range(-5.0..=5.0))]
    pub(crate) projector_drift: f64,
    /// Width of one fringe period of the virtual rig's scan patterns (projector pixels; the
    /// hybrid code, 4 phase steps; 4 to 480). A projector response the patterns do not
    /// pre-compensate bends the phase by a fraction of a period: longer periods turn it into
    /// more millimetres. Default 15 (`sl_scan::SCAN_PERIOD_PX`). On devices, --patterns sets
    /// the patterns.
    #[arg(long, value_parser = values::in_range(4.0..=480.0))]
    pub(crate) period: Option<f64>,
    /// The virtual dumbbell's surface: `matte` (plaster), `dark` (albedo 0.04), `glossy`
    /// (a plastic whose highlights saturate the camera) or `coloured` (patches of four
    /// colours, scanned in colour and measured against the true albedo). With --exposures, the
    /// figures of one exposure against several (docs/user-guide.md, "Difficult surfaces").
    #[arg(long, value_enum, default_value_t = crate::capture::FinishArg::Matte)]
    pub(crate) finish: crate::capture::FinishArg,
    #[command(flatten)]
    pub(crate) exposure: crate::capture::ExposureArgs,
    #[command(flatten)]
    pub(crate) hardware: HardwareArgs,
    #[command(flatten)]
    pub(crate) rig: crate::scan_hardware::ScanHardwareArgs,
}

/// The shape of the virtual projector's response (`--projector-response`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ResponseArg {
    /// `v^gamma`, the exponent `--projector-gamma`.
    Power,
    /// A measured projector's curve.
    Measured,
}

impl From<ResponseArg> for sl_sim::ResponseShape {
    fn from(a: ResponseArg) -> Self {
        match a {
            ResponseArg::Power => Self::Power,
            ResponseArg::Measured => Self::Measured,
        }
    }
}

/// What the virtual scan does about the projector's response (`--correct-response`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum CorrectionArg {
    /// Nothing.
    None,
    /// Correct the decoded phase with the measured response.
    Decode,
    /// Pre-compensate the measured response in the fringes.
    Precompensate,
}

impl From<CorrectionArg> for structured_light::scan::ResponseCorrection {
    fn from(a: CorrectionArg) -> Self {
        match a {
            CorrectionArg::None => Self::None,
            CorrectionArg::Decode => Self::Decode,
            CorrectionArg::Precompensate => Self::Precompensate,
        }
    }
}

/// The checks of `slscan scan` that need more than one value.
pub(crate) fn check(args: &Args) -> anyhow::Result<()> {
    check_placements(args.placements).map_err(|e| anyhow::anyhow!("--placements: {e}"))?;
    if crate::scan_hardware::wanted(args)? {
        anyhow::ensure!(
            !args.binocular
                && args.projector_gamma == 1.0
                && args.projector_response == ResponseArg::Power
                && args.correct_response == CorrectionArg::None
                && args.phase_steps == structured_light::scan::SCAN_PHASE_STEPS
                && args.projector_distortion.is_none()
                && args.projector_drift == 0.0
                && args.period.is_none()
                && args.finish == crate::capture::FinishArg::Matte,
            "--binocular, --projector-gamma, --projector-response, --correct-response, --phase-steps, --projector-distortion, --projector-drift, --period and --finish are options of the virtual rig's scan: on devices, a scan with two cameras names the second with --right-camera and takes the two-camera calibration (stereo.json) as --calib; the projector's response is the calibration's (slscan calibrate response); --patterns sets the patterns"
        );
        return Ok(());
    }
    anyhow::ensure!(
        args.placement_wait.is_none(),
        "--placement-wait is for a scan on hardware: the virtual rig re-places its object itself"
    );
    anyhow::ensure!(
        args.placements == 1 || !args.true_poses,
        "--true-poses is a diagnostic of the single-placement scan"
    );
    anyhow::ensure!(
        !(args.binocular && args.correct_response != CorrectionArg::None),
        "--correct-response applies to one camera: two cameras match codes that the projector's response bends alike in both"
    );
    anyhow::ensure!(
        args.placements == 1 || !args.binocular,
        "--binocular scans one placement: a two-camera scan in several placements is not built yet"
    );
    Ok(())
}

/// Runs `slscan scan`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    check(args)?;
    if crate::scan_hardware::wanted(args)? {
        // Locks the folder itself, once the options are checked.
        return crate::scan_hardware::run(args);
    }
    // One run at a time in a scan folder; its sessions resume, so it is written in place.
    let folder = open_out_in_place(&args.out, "scan")?;
    if args.placements > 1 {
        run_placements(args)?;
    } else {
        run_single(args)?;
    }
    folder.commit()?;
    Ok(())
}

/// `slscan scan` on the virtual rig, one placement.
fn run_single(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("scan");
    let out = args.out.clone();
    let cfg = VirtualScanConfig {
        flatness_plate: !args.no_plate,
        ..virtual_config(args)
    };
    let mut bars = StageBars::new();
    let result = scan_virtual(&cfg, &out, |p| bars.update(p))?;
    bars.clear();
    result.record(&mut report, args.views)?;
    report.write(&out)?;
    let html = write_summary_html(&out, &result)?;
    for line in result.summary(&out, args.views) {
        outln!("{line}");
    }
    outln!("summary: {}", html.display());
    Ok(())
}

/// The options of the virtual scan common to one and several placements.
fn virtual_config(args: &Args) -> VirtualScanConfig {
    VirtualScanConfig {
        views: args.views,
        calibration_poses: args.calibration_poses,
        resolution_divisor: args.downscale,
        seed: args.seed,
        overwrite: args.overwrite,
        average_overlaps: !args.no_average,
        max_view_angle_deg: args.max_view_angle,
        true_calibration: args.true_calibration,
        true_poses: args.true_poses,
        flatness_plate: false,
        smoothing_neighbours: args.smoothing_neighbours,
        edge_erosion_px: args.edge_erosion,
        mesh_options: mesh_options(args),
        corners: args.corners,
        smoothing: smoothing(args),
        binocular: args.binocular,
        projector_gamma: args.projector_gamma,
        projector_response: args.projector_response.into(),
        response_correction: args.correct_response.into(),
        phase_steps: args.phase_steps,
        projector_distortion: args.projector_distortion,
        projector_drift_deg: args.projector_drift,
        period_px: args
            .period
            .unwrap_or(structured_light::scan::SCAN_PERIOD_PX),
        finish: args.finish.into(),
        exposures: args.exposure.exposures(),
        fusion: args.exposure.fusion(),
        colour: args.exposure.colour || args.finish == crate::capture::FinishArg::Coloured,
        ..VirtualScanConfig::default()
    }
}

/// The smoothing `--smooth` asks for, the same on the virtual rig and on real devices.
pub(crate) fn smoothing(args: &Args) -> Option<structured_light::codec::SmoothConfig> {
    (args.smooth > 0).then(|| structured_light::codec::SmoothConfig {
        radius: args.smooth,
        ..structured_light::codec::SmoothConfig::default()
    })
}

/// The mesh stage's steps as the flags ask, the same on the virtual rig and on real devices.
pub(crate) fn mesh_options(args: &Args) -> MeshConfig {
    MeshConfig {
        simplify: (!args.no_simplify).then(SimplifyConfig::default),
        fair: (!args.no_fair).then(|| FairConfig {
            project_rim: !args.no_fair_rim,
            ..FairConfig::default()
        }),
    }
}

/// `slscan scan --placements 2` on the virtual rig: the pebble standing, then laid on its side.
fn run_placements(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("scan");
    let out = args.out.clone();
    let cfg = virtual_config(args);
    let mut bars = StageBars::new();
    let r = scan_virtual_placements(&cfg, args.placements, &out, |p| bars.update(p))?;
    bars.clear();
    r.record(&mut report, args.placements, args.views)?;
    report.write(&out)?;
    for line in r.summary(&out) {
        outln!("{line}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::{Cli, Command};

    fn options(flags: &[&str]) -> MeshConfig {
        let argv = ["slscan", "scan", "--out", "x"].iter().chain(flags);
        match Cli::try_parse_from(argv).map(|c| c.command) {
            Ok(Command::Scan(a)) => mesh_options(&a),
            other => panic!("parsed as {other:?}"),
        }
    }

    /// The mesh flags of `slscan scan` turn off the steps `slscan mesh`'s flags of the same
    /// names do, and nothing else.
    #[test]
    fn mesh_flags_turn_off_their_step() {
        assert_eq!(options(&[]), MeshConfig::default());
        let o = options(&["--no-fair-rim"]);
        assert_eq!(o.simplify, Some(SimplifyConfig::default()));
        let fair = o.fair.expect("still faired");
        assert!(!fair.project_rim && FairConfig::default().project_rim);
        assert_eq!(
            fair,
            FairConfig {
                project_rim: false,
                ..FairConfig::default()
            }
        );
        let o = options(&["--no-fair"]);
        assert!(o.fair.is_none() && o.simplify.is_some());
        let o = options(&["--no-simplify"]);
        assert!(o.simplify.is_none() && o.fair.is_some());
    }
}
