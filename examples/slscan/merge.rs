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

use crate::common::{Report, StageBars, open_out};
use crate::register::{check_cloud, check_voxel, read_scaled, with_options};
use crate::values;

/// Arguments of `slscan merge`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The views, in turntable order: PLY files, or folders holding `cloud.ply` (as written by
    /// `slscan reconstruct`); two at least.
    #[arg(required = true, num_args = 2..)]
    pub(crate) views: Vec<PathBuf>,
    /// The merged cloud (`*.ply`; `report.json`, `poses.json` and `preview.png` go beside it),
    /// or an output folder (the cloud is then `merged.ply` in it).
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Write even where that replaces a view or the calibration.
    #[arg(long)]
    pub(crate) force: bool,
    /// Calibration file whose turntable axis gives the initial poses.
    #[arg(long)]
    pub(crate) calib: Option<PathBuf>,
    /// Turntable axis direction in the camera frame, "dx,dy,dz" (overrides the calibration's).
    #[arg(long, value_delimiter = ',', num_args = 1, allow_negative_numbers = true,
          value_parser = values::finite)]
    pub(crate) axis: Option<Vec<f64>>,
    /// A point of the turntable axis in the camera frame, "x,y,z" in mm (with --axis).
    #[arg(long, value_delimiter = ',', num_args = 1, allow_negative_numbers = true,
          value_parser = values::finite)]
    pub(crate) axis_point: Option<Vec<f64>>,
    /// Motor angle of each view in degrees, "a0,a1,..." (one per view; finite).
    #[arg(long, value_delimiter = ',', num_args = 1, allow_negative_numbers = true,
          value_parser = values::finite)]
    pub(crate) angles: Option<Vec<f64>>,
    /// Motor step between consecutive views in degrees (view i at i * step), instead of
    /// --angles; from -360 to 360.
    #[arg(long, allow_negative_numbers = true, value_parser = values::in_range(-360.0..=360.0))]
    pub(crate) step: Option<f64>,
    /// Voxel size the views are downsampled to for registration (mm; from 0.001 to a tenth of
    /// each view's extent).
    #[arg(long, default_value_t = DEFAULT_REGISTRATION_VOXEL_MM, value_parser = values::length_mm)]
    pub(crate) registration_voxel: f64,
    /// Voxel size of the merged cloud (mm; 0 keeps every point, else from 0.001 to a tenth of
    /// each view's extent).
    #[arg(long, default_value_t = 0.5, value_parser = values::voxel_or_zero)]
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
    /// Multiply coordinates by this when reading (1000 for clouds in metres; 1e-6 to 1e6).
    #[arg(long, default_value_t = 1.0, value_parser = values::scale)]
    pub(crate) scale: f64,
}

/// The three numbers of `--axis` or `--axis-point` (`what`).
fn triple(v: &[f64], what: &str) -> anyhow::Result<Vector3<f64>> {
    match v {
        [x, y, z] => Ok(Vector3::new(*x, *y, *z)),
        _ => anyhow::bail!("{what}: expected three numbers X,Y,Z, found {}", v.len()),
    }
}

/// The checks of `slscan merge` that need more than one value.
pub(crate) fn check(args: &Args) -> anyhow::Result<()> {
    if let Some(d) = &args.axis {
        let d = triple(d, "--axis")?;
        anyhow::ensure!(
            d.norm() > 0.0 && d.norm().is_finite(),
            "--axis {},{},{}: a direction needs a length > 0",
            d.x,
            d.y,
            d.z
        );
        let point = args
            .axis_point
            .as_deref()
            .context("--axis needs --axis-point")?;
        triple(point, "--axis-point")?;
    }
    anyhow::ensure!(
        args.angles.is_none() || args.step.is_none(),
        "give --angles or --step, not both"
    );
    let given = match (&args.angles, args.step) {
        (Some(_), _) => Some("--angles"),
        (None, Some(_)) => Some("--step"),
        (None, None) => None,
    };
    if let Some(flag) = given {
        anyhow::ensure!(
            args.calib.is_some() || args.axis.is_some(),
            "{flag}: view angles need a turntable axis (--calib or --axis)"
        );
    }
    if let Some(angles) = &args.angles {
        anyhow::ensure!(
            angles.len() == args.views.len(),
            "--angles gives {} angles for {} views",
            angles.len(),
            args.views.len()
        );
    }
    Ok(())
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
    if let (Some(d), Some(point)) = (&args.axis, &args.axis_point) {
        axis = Some(TurntableAxis::new(
            triple(d, "--axis")?,
            Point3::from(triple(point, "--axis-point")?),
        )?);
    }
    let angles: Option<Vec<f64>> = match (&args.angles, args.step) {
        (Some(list), _) => Some(list.clone()),
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
    check(args)?;
    let mut report = Report::new("merge");
    let is_ply = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    let (dir, ply_name) = if is_ply {
        let dir = args
            .out
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        (dir, args.out.file_name().map(PathBuf::from))
    } else {
        (args.out.as_path(), None)
    };
    let view_files: Vec<PathBuf> = args.views.iter().map(|v| view_file(v)).collect();
    let mut read: Vec<&Path> = view_files.iter().map(PathBuf::as_path).collect();
    read.extend(args.calib.as_deref());
    let written: Vec<&Path> = ply_name.iter().map(PathBuf::as_path).collect();
    let folder = open_out(dir, "merge", &read, &written, args.force)?;
    let ply = folder
        .path()
        .join(ply_name.as_deref().unwrap_or(Path::new("merged.ply")));
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
                for (flag, voxel) in [
                    ("--registration-voxel", args.registration_voxel),
                    ("--voxel", args.voxel),
                ] {
                    check_voxel(flag, voxel, args.scale, &[&c], &[&path])?;
                }
                Ok(c)
            })
            .collect::<anyhow::Result<_>>()
    })?;
    let names: Vec<String> = args.views.iter().map(|p| p.display().to_string()).collect();
    let mut options = vec![
        ("--registration-voxel", args.registration_voxel.to_string()),
        ("--voxel", args.voxel.to_string()),
    ];
    if args.scale != 1.0 {
        options.push(("--scale", args.scale.to_string()));
    }
    if let Some(step) = args.step {
        options.push(("--step", step.to_string()));
    }
    if args.angles.is_some() {
        options.push(("--angles", "as given".to_owned()));
    }
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
            report.write(folder.path())?;
            let path = folder.keep_as_failed()?.join("report.json");
            let lost: Vec<String> = lost.iter().map(|&v| name(v)).collect();
            anyhow::bail!(
                "{} of {n} views could not be placed {}: {} ({why}); every pair's fitness, RMSE and reason are in {}",
                lost.len(),
                with_options(&options),
                lost.join(", "),
                path.display()
            );
        }
        Err(e) => return Err(anyhow::Error::new(e).context(with_options(&options))),
    };
    let mut merged = merged;
    merged.cloud = folder.final_path(&merged.cloud);
    merged.record(&mut report);
    report.write(folder.path())?;
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    for line in merged.summary() {
        outln!("{line}");
    }
    outln!("report: {}", out.join("report.json").display());
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

    /// A merge needs two views at least, and says so naming the argument (before, one view
    /// ended "0 of 1 views could not be placed:  (no pair …)").
    #[test]
    fn one_view_is_refused_naming_the_views() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("one.ply");
        let cloud = PointCloud::from_positions(crate::blob_support::blob(2_000));
        write_ply(&path, &cloud, PlyFormat::default()).unwrap();
        let out = tmp.path().join("merged");
        let err = slscan(&[
            "merge",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("<VIEWS>") && text.contains('2'), "{text}");
        assert!(!out.exists());
    }
}
