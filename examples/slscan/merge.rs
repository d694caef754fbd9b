//! `slscan merge VIEW... --out merged.ply`: register the views of a turntable scan with one
//! another (initial poses from the turntable axis and angles when known), spread the drift
//! with a pose graph, merge, downsample and estimate normals; writes the merged cloud, the
//! view poses, a preview and `report.json`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use nalgebra::{Isometry3, Point3, Vector3};
use sl_camera::{Calibration, TurntableAxis};
use sl_cloud::PointCloud;
use sl_icp::{IcpError, MergeConfig, PoseModel, TurntablePrior, turntable_poses};
use sl_scan::{ScanError, merge_and_write, pair_figures};

use crate::common::{Report, StageBars, ensure_out_dir};
use crate::register::{check_cloud, read_scaled};

/// Arguments of `slscan merge`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The views, in turntable order: PLY files, or folders holding `cloud.ply` (as written by
    /// `slscan reconstruct`).
    #[arg(required = true)]
    pub(crate) views: Vec<PathBuf>,
    /// The merged cloud (`*.ply`; `report.json`, `poses.json` and `preview.png` go beside it),
    /// or an output folder (the cloud is then `merged.ply` in it).
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Calibration file whose turntable axis gives the initial poses.
    #[arg(long)]
    pub(crate) calib: Option<PathBuf>,
    /// Turntable axis direction in the camera frame, "dx,dy,dz" (overrides the calibration's).
    #[arg(long)]
    pub(crate) axis: Option<String>,
    /// A point of the turntable axis in the camera frame, "x,y,z" in mm (with --axis).
    #[arg(long)]
    pub(crate) axis_point: Option<String>,
    /// Motor angle of each view in degrees, "a0,a1,..." (one per view).
    #[arg(long)]
    pub(crate) angles: Option<String>,
    /// Motor step between consecutive views in degrees (view i at i * step), instead of
    /// --angles.
    #[arg(long)]
    pub(crate) step: Option<f64>,
    /// Voxel size the views are downsampled to for registration (mm).
    #[arg(long, default_value_t = DEFAULT_REGISTRATION_VOXEL_MM)]
    pub(crate) registration_voxel: f64,
    /// Voxel size of the merged cloud (mm; 0 keeps every point).
    #[arg(long, default_value_t = 0.5)]
    pub(crate) voxel: f64,
    /// Average overlapping points along the normals (moving least squares of degree 2).
    #[arg(long)]
    pub(crate) average: bool,
    /// Do not register the first view onto the last (for a scan that is not a full turn).
    #[arg(long)]
    pub(crate) no_loop: bool,
    /// Give each view its own 6-degree-of-freedom pose (the free pose graph) instead of the
    /// default turntable model (an axis and one angle per view; the calibrated turntable
    /// kept wherever the registrations agree with it, docs/registration.md).
    #[arg(long, conflicts_with = "turntable_model")]
    pub(crate) free_pose_graph: bool,
    /// The turntable model: the default since issue 28; accepted for old scripts.
    #[arg(long, hide = true)]
    pub(crate) turntable_model: bool,
    /// Multiply coordinates by this when reading (1000 for clouds in metres).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) scale: f64,
}

fn triple(arg: &str, what: &str) -> anyhow::Result<Vector3<f64>> {
    let v: Vec<f64> = arg
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{what} \"{arg}\": expected three comma-separated numbers"))?;
    match v.as_slice() {
        [x, y, z] => Ok(Vector3::new(*x, *y, *z)),
        _ => anyhow::bail!(
            "{what} \"{arg}\": expected three numbers, found {}",
            v.len()
        ),
    }
}

fn view_file(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join("cloud.ply")
    } else {
        path.to_path_buf()
    }
}

/// The initial poses `T_world_view`: from the turntable when an axis is known, else identity
/// (views already in one frame).
fn initial_poses(args: &Args, n: usize) -> anyhow::Result<(Vec<Isometry3<f64>>, &'static str)> {
    let mut axis: Option<TurntableAxis> = match &args.calib {
        Some(path) => {
            let calib = Calibration::load(path)?;
            Some(calib.turntable.with_context(|| {
                format!("{}: the calibration has no turntable axis", path.display())
            })?)
        }
        None => None,
    };
    if let Some(d) = &args.axis {
        let point = args
            .axis_point
            .as_deref()
            .context("--axis needs --axis-point")?;
        axis = Some(TurntableAxis::new(
            triple(d, "--axis")?,
            Point3::from(triple(point, "--axis-point")?),
        )?);
    }
    let angles: Option<Vec<f64>> = match (&args.angles, args.step) {
        (Some(_), Some(_)) => anyhow::bail!("give --angles or --step, not both"),
        (Some(list), None) => Some(
            list.split(',')
                .map(|s| s.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .with_context(|| {
                    format!("--angles \"{list}\": expected comma-separated degrees")
                })?,
        ),
        (None, Some(step)) => Some((0..n).map(|i| i as f64 * step).collect()),
        (None, None) => None,
    };
    match (axis, angles) {
        (Some(axis), Some(angles)) => {
            if angles.len() != n {
                anyhow::bail!("--angles gives {} angles for {n} views", angles.len());
            }
            Ok((turntable_poses(&axis, &angles)?, "turntable"))
        }
        (Some(_), None) => {
            anyhow::bail!("a turntable axis needs the view angles (--angles or --step)")
        }
        (None, Some(_)) => anyhow::bail!("view angles need a turntable axis (--calib or --axis)"),
        (None, None) => Ok((vec![Isometry3::identity(); n], "identity")),
    }
}

/// Default `--registration-voxel` (mm), also the scale below which a cloud is taken for one
/// in metres.
const DEFAULT_REGISTRATION_VOXEL_MM: f64 = 1.0;

/// Runs `slscan merge`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("merge");
    let is_ply = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    let (dir, ply) = if is_ply {
        let dir = args
            .out
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        (ensure_out_dir(dir)?, args.out.clone())
    } else {
        let dir = ensure_out_dir(&args.out)?;
        let ply = dir.join("merged.ply");
        (dir, ply)
    };
    let n = args.views.len();
    let (initial, source_of_poses) = initial_poses(args, n)?;
    let config = MergeConfig {
        registration_voxel_size: args.registration_voxel,
        output_voxel_size: (args.voxel > 0.0).then_some(args.voxel),
        average_overlaps: args.average,
        loop_closure: !args.no_loop,
        pose_model: if args.free_pose_graph {
            PoseModel::Free
        } else {
            PoseModel::Turntable(TurntablePrior::default())
        },
        ..MergeConfig::default()
    };
    let views: Vec<PointCloud> = report.stage("read", || {
        args.views
            .iter()
            .map(|v| {
                let path = view_file(v);
                let c = read_scaled(&path, args.scale)?;
                check_cloud(
                    &c,
                    &path,
                    DEFAULT_REGISTRATION_VOXEL_MM,
                    "a registration",
                    sl_icp::MIN_CORRESPONDENCES,
                )?;
                Ok(c)
            })
            .collect::<anyhow::Result<_>>()
    })?;
    let names: Vec<String> = args.views.iter().map(|p| p.display().to_string()).collect();
    let mut bars = StageBars::new();
    let merged = merge_and_write(
        &views,
        &names,
        &initial,
        source_of_poses,
        &config,
        &ply,
        |p| bars.update(p),
    );
    bars.clear();
    let merged = match merged {
        Ok(m) => m,
        Err(ScanError::Icp(IcpError::ViewsNotPlaced {
            views: lost,
            why,
            pairs,
        })) => {
            // A failed merge still says what every pair measured.
            let name = |i: usize| names.get(i).cloned().unwrap_or_else(|| format!("view {i}"));
            report.figure("views", n);
            report.figure("initial_poses_from", source_of_poses);
            report.figure("pairs", pair_figures(&pairs, &name));
            report.figure("pairs_used", pairs.iter().filter(|p| p.used).count());
            report.figure(
                "unplaced",
                serde_json::Value::Array(lost.iter().map(|&v| name(v).into()).collect()),
            );
            report.figure("unplaced_because", why.clone());
            let path = report.write(&dir)?;
            let lost: Vec<String> = lost.iter().map(|&v| name(v)).collect();
            anyhow::bail!(
                "{} of {n} views could not be placed: {} ({why}); every pair's fitness, RMSE and reason are in {}",
                lost.len(),
                lost.join(", "),
                path.display()
            );
        }
        Err(e) => return Err(e.into()),
    };
    merged.record(&mut report);
    let path = report.write(&dir)?;
    for line in merged.summary() {
        outln!("{line}");
    }
    outln!("report: {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    //! `slscan merge` on turntable views of a synthetic blob: the views are the blob turned
    //! about a known axis, each in its camera's frame; the merge must place them where the
    //! turntable put them and say so in `report.json` and `poses.json`.

    use nalgebra::{Point3, Vector3};
    use sl_camera::TurntableAxis;
    use sl_cloud::{PlyFormat, PointCloud, write_ply};

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    #[test]
    fn views_of_a_turntable_land_where_the_turntable_put_them() {
        let tmp = tempfile::tempdir().unwrap();
        let axis_point = Point3::new(5.0, 0.0, 300.0);
        let axis = TurntableAxis::new(Vector3::new(0.0, -1.0, 0.05), axis_point).unwrap();
        let step = 40.0;
        let angles: Vec<f64> = (0..4).map(|k| f64::from(k) * step).collect();
        let truth = sl_icp::turntable_poses(&axis, &angles).unwrap();
        let world: Vec<Point3<f64>> = crate::blob_support::blob(20_000)
            .into_iter()
            .map(|p| p + axis_point.coords)
            .collect();
        let mut files = Vec::new();
        for (k, t_world_view) in truth.iter().enumerate() {
            let inv = t_world_view.inverse();
            let view: Vec<Point3<f64>> = world.iter().map(|p| inv * p).collect();
            let path = tmp.path().join(format!("view_{k}.ply"));
            write_ply(
                &path,
                &PointCloud::from_positions(view),
                PlyFormat::default(),
            )
            .unwrap();
            files.push(path.display().to_string());
        }
        let out = tmp.path().join("merged");
        let mut args: Vec<&str> = vec!["merge"];
        args.extend(files.iter().map(String::as_str));
        let step_arg = step.to_string();
        args.extend([
            "--axis",
            "0,-1,0.05",
            "--axis-point",
            "5,0,300",
            "--step",
            &step_arg,
            "--no-loop",
            "--out",
            out.to_str().unwrap(),
        ]);
        slscan(&args).unwrap();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        let f = &report["figures"];
        assert_eq!(f["views"], 4);
        assert_eq!(f["initial_poses_from"], "turntable");
        assert!(f["pairs_used"].as_u64().unwrap() >= 3, "{f}");
        assert_eq!(f["pose_sources"].as_array().unwrap().len(), 4, "{f}");
        assert_eq!(f["pose_sources"][0]["source"], "reference", "{f}");
        assert!(
            f["largest_pose_correction_deg"].as_f64().unwrap() < 0.05,
            "{f}"
        );
        let poses: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("poses.json")).unwrap())
                .unwrap();
        for (k, t) in truth.iter().enumerate() {
            let rows = &poses["views"][k]["T_world_view"];
            let m: [[f64; 4]; 4] = serde_json::from_value(rows.clone()).unwrap();
            let got = sl_camera::pose_from_matrix(&m).unwrap();
            let turn = got.rotation.angle_to(&t.rotation).to_degrees();
            let shift = (got.translation.vector - t.translation.vector).norm();
            assert!(
                turn < 0.05 && shift < 0.1,
                "view {k}: {turn} deg, {shift} mm"
            );
        }
        assert!(out.join("merged.ply").is_file());
        assert!(out.join("preview.png").is_file());
    }
}
