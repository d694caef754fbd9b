//! `slscan register SOURCE.ply TARGET.ply --out DIR`: ICP of one cloud onto another; writes
//! the moved source, the transform, a preview and `report.json`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use nalgebra::{Isometry3, Point3};
use sl_cloud::PointCloud;
use sl_icp::{IcpConfig, Metric, RobustKernel, Trimming};
use sl_scan::{read_transform, register_and_write};

use crate::common::{Report, open_out};
use crate::values;

/// Default voxel size of `register` (mm): a 100 mm object keeps ~10k points.
const DEFAULT_VOXEL_MM: f64 = 1.0;

/// Error metric on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum MetricArg {
    /// Closed-form point-to-point (SVD).
    PointToPoint,
    /// Linearised point-to-plane (needs target normals; estimated when missing).
    PointToPlane,
    /// Generalized ICP, plane-to-plane (normals on both sides).
    Generalized,
}

impl From<MetricArg> for Metric {
    fn from(m: MetricArg) -> Self {
        match m {
            MetricArg::PointToPoint => Metric::PointToPoint,
            MetricArg::PointToPlane => Metric::PointToPlane,
            MetricArg::Generalized => Metric::Generalized,
        }
    }
}

/// Arguments of `slscan register`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The cloud to move (PLY).
    pub(crate) source: PathBuf,
    /// The cloud it is registered onto (PLY).
    pub(crate) target: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Write into `--out` even where that replaces an input.
    #[arg(long)]
    pub(crate) force: bool,
    /// Error metric.
    #[arg(long, value_enum, default_value_t = MetricArg::PointToPlane)]
    pub(crate) metric: MetricArg,
    /// Voxel size for downsampling both clouds first (mm; 0 keeps every point, else from
    /// 0.001 to a tenth of the clouds' extent).
    #[arg(long, default_value_t = DEFAULT_VOXEL_MM, value_parser = values::voxel_or_zero)]
    pub(crate) voxel: f64,
    /// Correspondences farther apart than this are ignored (mm, at least 0.001).
    #[arg(long, default_value_t = 5.0, value_parser = values::length_mm)]
    pub(crate) max_distance: f64,
    /// Maximum number of iterations (1 to 10000).
    #[arg(long, default_value_t = 50, value_parser = values::count_in::<usize>(1..=10_000))]
    pub(crate) iterations: usize,
    /// Huber kernel threshold (mm, at least 0.001); off by default.
    #[arg(long, value_parser = values::length_mm)]
    pub(crate) huber: Option<f64>,
    /// Trimmed ICP: expected overlap of the source with the target, 0.05 to 1; "auto" for the
    /// trimmed-ICP estimate of the overlap. Off by default.
    #[arg(long, value_parser = parse_trim)]
    pub(crate) trim: Option<Trimming>,
    /// Initial `T_target_source`: a JSON file with a 4x4 row-major matrix under
    /// `"T_target_source"` (the `transform.json` this command writes). Default: identity.
    #[arg(long)]
    pub(crate) init: Option<PathBuf>,
    /// Multiply the coordinates of both clouds by this when reading (1000 for clouds in
    /// metres, such as the Stanford scans: the workspace works in mm; 1e-6 to 1e6).
    #[arg(long, default_value_t = 1.0, value_parser = values::scale)]
    pub(crate) scale: f64,
}

/// Reads a PLY and scales its positions (units to mm).
pub(crate) fn read_scaled(path: &Path, scale: f64) -> anyhow::Result<PointCloud> {
    anyhow::ensure!(
        scale.is_finite() && scale > 0.0,
        "--scale {scale}: must be finite and > 0"
    );
    let cloud = sl_cloud::read_ply_scaled(path, scale)?;
    let bad = cloud
        .positions()
        .iter()
        .filter(|p| !p.iter().all(|c| c.is_finite()))
        .count();
    // `--scale` is named only where it took part: a huge scale can overflow finite
    // coordinates, a cloud stored with NaNs has them at any scale.
    let stored_so = cloud.is_empty() || scale == 1.0 || {
        let raw = sl_cloud::read_ply(path)?;
        raw.positions()
            .iter()
            .filter(|p| !p.iter().all(|c| c.is_finite()))
            .count()
            == bad
    };
    anyhow::ensure!(
        bad == 0,
        "{}: {bad} of {} points have coordinates that are not finite numbers{}",
        path.display(),
        cloud.len(),
        if stored_so {
            String::new()
        } else {
            format!(" once read with --scale {scale}")
        }
    );
    Ok(cloud)
}

/// The largest voxel, as a fraction of a cloud's extent (the diagonal of its box): a tenth,
/// so that a cloud keeps at least some hundreds of points for registration.
const MAX_VOXEL_OF_EXTENT: f64 = 0.1;

/// Refuses a voxel (`flag`, mm; 0 = none) larger than [`MAX_VOXEL_OF_EXTENT`] of the extent of
/// any of `clouds` (named by `paths`, read with `--scale scale`): it would leave a handful of
/// points.
pub(crate) fn check_voxel(
    flag: &str,
    voxel: f64,
    scale: f64,
    clouds: &[&PointCloud],
    paths: &[&Path],
) -> anyhow::Result<()> {
    // The extent depends on the scale too: a wrong --scale is as likely the cause.
    let scaled = if scale == 1.0 {
        String::new()
    } else {
        format!(" once read with --scale {scale}")
    };
    for (c, p) in clouds.iter().zip(paths) {
        let extent = c.bounding_box().map_or(0.0, |b| b.extent().norm());
        anyhow::ensure!(
            voxel <= MAX_VOXEL_OF_EXTENT * extent,
            "{flag} {voxel}: a voxel must be at most a tenth of each cloud's extent; {} spans \
             {extent:.3} mm{scaled} (the diagonal of its box), so at most {:.3} mm",
            p.display(),
            MAX_VOXEL_OF_EXTENT * extent
        );
    }
    Ok(())
}

/// The options a registration of `slscan register`, `merge` or `align` was made with, for its
/// failures: `(flag, value)` pairs, those given as they were given.
pub(crate) fn with_options(options: &[(&str, String)]) -> String {
    let given: Vec<String> = options.iter().map(|(f, v)| format!("{f} {v}")).collect();
    format!("with {}", given.join(", "))
}

/// A cloud whose bounding-box diagonal is below this many default voxels is taken for one in
/// metres (the workspace works in mm): any object worth scanning spans tens of voxels
/// (a 100 mm object, 100 voxels of 1 mm), while the same object in metres spans 0.1 "mm".
const METRES_EXTENT_VOXELS: f64 = 1.0;

/// Refuses `cloud` (read from `path`) when it cannot serve `purpose`, which needs `min_points`
/// finite points: for what it is whatever its units (no finite point, too few, all at one
/// place), else, with the hint `--scale 1000`, when it spans only a fraction of `voxel` mm (the
/// command's default voxel size, or for `slscan mesh` a millimetre): it is then almost surely
/// in metres.
pub(crate) fn check_cloud(
    cloud: &PointCloud,
    path: &Path,
    voxel: f64,
    purpose: &'static str,
    min_points: usize,
) -> anyhow::Result<()> {
    let needs = sl_cloud::CloudNeeds {
        purpose,
        min_points,
        min_extent_mm: Some(METRES_EXTENT_VOXELS * voxel),
    };
    match sl_cloud::check_cloud(cloud, path, &needs) {
        Err(e @ sl_cloud::CloudError::NotMillimetres { .. }) => {
            anyhow::bail!("{e}; read it with --scale 1000")
        }
        other => Ok(other?),
    }
}

/// Neighbours of the normals `--normals-towards` estimates (`slscan align`, `slscan mesh`).
pub(crate) const NORMAL_NEIGHBOURS: usize = 20;

/// `--normals-towards X,Y,Z` of `slscan align` and `slscan mesh`.
#[derive(Debug, clap::Args)]
pub(crate) struct NormalsTowards {
    /// Estimate each cloud's normals (20 neighbours) facing this point of its own frame (mm,
    /// after `--scale`): where the scanner stood, e.g. `0,0,0` for clouds in the camera frame
    /// as `slscan reconstruct` writes them, `0,0,1000` for the Stanford scans. Without it the
    /// clouds' own normals are kept, if they have them.
    #[arg(
        long,
        value_delimiter = ',',
        num_args = 1,
        allow_negative_numbers = true,
        value_parser = values::finite
    )]
    pub(crate) normals_towards: Option<Vec<f64>>,
}

impl NormalsTowards {
    /// The point given, if any: three finite coordinates.
    pub(crate) fn viewpoint(&self) -> anyhow::Result<Option<Point3<f64>>> {
        match self.normals_towards.as_deref() {
            None => Ok(None),
            Some(&[x, y, z]) if [x, y, z].iter().all(|c| c.is_finite()) => {
                Ok(Some(Point3::new(x, y, z)))
            }
            Some(v) => anyhow::bail!(
                "--normals-towards {v:?}: needs three finite coordinates X,Y,Z (mm, in the cloud's frame)"
            ),
        }
    }
}

/// `cloud` with normals estimated from [`NORMAL_NEIGHBOURS`] neighbours and turned towards
/// `viewpoint` (where the scanner stood); `name` names the cloud in the error.
pub(crate) fn with_normals_towards(
    cloud: &PointCloud,
    viewpoint: Point3<f64>,
    name: &str,
) -> anyhow::Result<PointCloud> {
    sl_cloud::with_normals_towards(cloud, viewpoint, NORMAL_NEIGHBOURS)
        .with_context(|| format!("{name}: cannot estimate normals"))
}

/// The least overlap `--trim` takes: 5 %; fewer correspondences register noise.
const MIN_OVERLAP: f64 = 0.05;

/// `--trim`: "auto", or an overlap in [`MIN_OVERLAP`], 1.
fn parse_trim(s: &str) -> Result<Trimming, String> {
    if s.trim() == "auto" {
        return Ok(Trimming::Auto { min_overlap: 0.3 });
    }
    let overlap = values::in_range(MIN_OVERLAP..=1.0)(s)
        .map_err(|_| format!("must be an overlap from {MIN_OVERLAP} to 1, or \"auto\""))?;
    Ok(Trimming::Fixed { overlap })
}

/// Runs `slscan register`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    let mut report = Report::new("register");
    let mut read = vec![args.source.as_path(), args.target.as_path()];
    read.extend(args.init.as_deref());
    let folder = open_out(&args.out, "register", &read, &[], args.force)?;
    let metric = Metric::from(args.metric);
    let config = IcpConfig {
        metric,
        max_correspondence_distance: args.max_distance,
        max_iterations: args.iterations,
        kernel: args
            .huber
            .map_or(RobustKernel::L2, |k| RobustKernel::Huber { k }),
        trimming: args.trim.unwrap_or_default(),
        ..IcpConfig::default()
    };
    config.validate()?;
    let initial = match &args.init {
        Some(p) => read_transform(p)?,
        None => Isometry3::identity(),
    };
    let (source, target) = report.stage("read", || -> anyhow::Result<_> {
        Ok((
            read_scaled(&args.source, args.scale)?,
            read_scaled(&args.target, args.scale)?,
        ))
    })?;
    for (cloud, path) in [(&source, &args.source), (&target, &args.target)] {
        check_cloud(
            cloud,
            path,
            DEFAULT_VOXEL_MM,
            "a registration",
            sl_icp::MIN_CORRESPONDENCES,
        )?;
    }
    check_voxel(
        "--voxel",
        args.voxel,
        args.scale,
        &[&source, &target],
        &[&args.source, &args.target],
    )?;
    let voxel = (args.voxel > 0.0).then_some(args.voxel);
    let mut options = vec![
        ("--max-distance", args.max_distance.to_string()),
        ("--voxel", args.voxel.to_string()),
        ("--iterations", args.iterations.to_string()),
    ];
    if args.scale != 1.0 {
        options.push(("--scale", args.scale.to_string()));
    }
    if let Some(t) = args.trim {
        let t = match t {
            Trimming::Fixed { overlap } => overlap.to_string(),
            _ => "auto".to_owned(),
        };
        options.push(("--trim", t));
    }
    if let Some(k) = args.huber {
        options.push(("--huber", k.to_string()));
    }
    if let Some(p) = &args.init {
        options.push(("--init", p.display().to_string()));
    }
    let mut r = register_and_write(&source, &target, &initial, &config, voxel, folder.path())
        .with_context(|| with_options(&options))?;
    r.cloud = folder.final_path(&r.cloud);
    r.record(&mut report, &format!("{:?}", args.metric));
    report.write(folder.path())?;
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    outln!("{}", r.summary());
    outln!("report: {}", out.join("report.json").display());
    Ok(())
}

#[cfg(test)]
mod tests {
    //! `slscan register` on a bumpy blob and the same blob moved by a known small motion: the
    //! transform it writes is that motion; an initial pose that is not a rigid motion is
    //! refused naming the file.

    use nalgebra::{Isometry3, Point3, Vector3};
    use sl_cloud::{PlyFormat, PointCloud, write_ply};

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    #[test]
    fn the_written_transform_is_the_motion_between_the_clouds() {
        let tmp = tempfile::tempdir().unwrap();
        let target: Vec<Point3<f64>> = crate::blob_support::blob(20_000);
        let truth = Isometry3::new(
            Vector3::new(1.5, -0.8, 0.6),
            Vector3::new(0.02, -0.03, 0.04),
        );
        let source: Vec<Point3<f64>> = target.iter().map(|p| truth.inverse() * p).collect();
        let (s, t) = (tmp.path().join("s.ply"), tmp.path().join("t.ply"));
        for (path, pts) in [(&s, source), (&t, target)] {
            write_ply(path, &PointCloud::from_positions(pts), PlyFormat::default()).unwrap();
        }
        let out = tmp.path().join("out");
        let (sp, tp, op) = (
            s.to_str().unwrap(),
            t.to_str().unwrap(),
            out.to_str().unwrap(),
        );
        slscan(&["register", sp, tp, "--out", op]).unwrap();
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("transform.json")).unwrap())
                .unwrap();
        let m: [[f64; 4]; 4] = serde_json::from_value(json["T_target_source"].clone()).unwrap();
        let got = sl_camera::pose_from_matrix(&m).unwrap();
        let turn = got.rotation.angle_to(&truth.rotation).to_degrees();
        let shift = (got.translation.vector - truth.translation.vector).norm();
        assert!(turn < 0.01 && shift < 0.01, "{turn} deg, {shift} mm");
        assert_eq!(json["converged"], true, "{json}");
        assert!(out.join("registered.ply").is_file() && out.join("preview.png").is_file());

        let init = tmp.path().join("init.json");
        std::fs::write(
            &init,
            r#"{"T_target_source": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#,
        )
        .unwrap();
        let err = slscan(&[
            "register",
            sp,
            tp,
            "--out",
            op,
            "--init",
            init.to_str().unwrap(),
        ])
        .unwrap_err();
        let text = format!("{err:#}");
        assert!(
            text.contains("init.json") && text.contains("not a rigid motion"),
            "{text}"
        );
    }
}
