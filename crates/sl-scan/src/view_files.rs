//! Clouds already read from files, registered or merged, and their results written: what
//! `slscan register` and `slscan merge` run. The clouds are in millimetres; reading them (and
//! the checks of their units) is the caller's.

use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use serde_json::json;
use sl_cloud::{
    MergePolicy, PlyFormat, PointCloud, PreviewColoring, PreviewConfig, render_preview, write_ply,
};
use sl_icp::{IcpConfig, MergeConfig, Registration, ViewAlignment, align_views, merge_aligned};

use crate::error::io;
use crate::progress::timed;
use crate::{
    RunReport, ScanError, ScanProgress, StageTime, alignment_figures, largest_pose_correction_deg,
    write_atomically,
};

/// The file `register_and_write` writes the motion into, and the key of its matrix.
pub const TRANSFORM_FILE: &str = "transform.json";

/// Writes a shaded picture of `cloud` as `out/preview.png` (through a temporary file renamed
/// into place) and returns its path.
///
/// # Errors
/// The renderer's and the PNG writer's; [`ScanError::Io`] naming the file.
pub fn write_preview_png(
    out: &Path,
    cloud: &PointCloud,
    coloring: PreviewColoring<'_>,
) -> Result<PathBuf, ScanError> {
    let preview = render_preview(cloud, coloring, &PreviewConfig::default())?;
    let path = out.join("preview.png");
    let tmp = out.join(".preview.partial.png");
    sl_codec::write_png_rgb8(
        &tmp,
        preview.width as usize,
        preview.height as usize,
        &preview.rgb,
    )?;
    std::fs::rename(&tmp, &path).map_err(io(&path))?;
    Ok(path)
}

/// Reads `T_target_source` from a JSON file holding it as a 4x4 row-major matrix under the
/// key `"T_target_source"` (the [`TRANSFORM_FILE`] that [`register_and_write`] writes).
///
/// # Errors
/// [`ScanError::Session`] naming the file: unreadable, not JSON, no such matrix, an entry
/// that is not a number, or a matrix that is not a rigid motion.
pub fn read_transform(path: &Path) -> Result<Isometry3<f64>, ScanError> {
    let bad = |reason: String| ScanError::Session {
        path: path.to_path_buf(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read: {e}")))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let rows = json
        .get("T_target_source")
        .and_then(|v| v.as_array())
        .ok_or_else(|| bad("no \"T_target_source\" array".to_owned()))?;
    let mut m = [[f64::NAN; 4]; 4];
    for (r, row) in rows.iter().enumerate().take(4) {
        for (c, v) in row.as_array().into_iter().flatten().enumerate().take(4) {
            m[r][c] = v
                .as_f64()
                .ok_or_else(|| bad(format!("T_target_source[{r}][{c}] is not a number")))?;
        }
    }
    sl_camera::pose_from_matrix(&m).map_err(|e| {
        bad(format!("T_target_source is not a rigid motion (4x4 rows, rotation part orthonormal, last row 0 0 0 1): {e}"))
    })
}

/// What [`register_and_write`] found and wrote.
#[derive(Debug, Clone)]
pub struct CloudRegistration {
    /// The registration: `T_target_source`, RMSE, fitness, iterations, ...
    pub result: Registration,
    /// Points of the source and the target.
    pub source_points: usize,
    /// Points of the target.
    pub target_points: usize,
    /// Source points the registration used (after the voxel grid).
    pub registered_points: usize,
    /// The moved source, `out/registered.ply`.
    pub cloud: PathBuf,
    /// Wall time per stage: `register`, `write`, `preview`.
    pub stages: Vec<StageTime>,
}

/// Registers `source` onto `target` from `initial` (sl-icp's `register_clouds`, on a voxel grid
/// of `voxel_mm` when given) and writes into `out`: the moved source (`registered.ply`), the
/// motion with its figures ([`TRANSFORM_FILE`]) and a picture of both clouds (`preview.png`,
/// the target blue-grey, the moved source orange: where they interleave, they agree).
///
/// # Errors
/// [`ScanError::Stage`] (`register`) with the registration's error (its settings, too few
/// points or correspondences); the files'.
pub fn register_and_write(
    source: &PointCloud,
    target: &PointCloud,
    initial: &Isometry3<f64>,
    config: &IcpConfig,
    voxel_mm: Option<f64>,
    out: &Path,
) -> Result<CloudRegistration, ScanError> {
    let mut stages = Vec::new();
    let (r, registered_points) = timed(&mut stages, "register", || {
        sl_icp::register_clouds(source, target, initial, config, voxel_mm)
    })
    .map_err(|e| ScanError::Stage {
        stage: "register".into(),
        reason: e.to_string(),
    })?;
    let moved = source.transformed(&r.pose);
    let ply = out.join("registered.ply");
    timed(&mut stages, "write", || -> Result<(), ScanError> {
        write_ply(&ply, &moved, PlyFormat::default())?;
        let transform = json!({
            "T_target_source": sl_camera::pose_to_matrix(&r.pose),
            "units": "mm",
            "rmse_mm": r.rmse,
            "fitness": r.fitness,
            "inliers": r.inliers,
            "iterations": r.iterations,
            "converged": r.converged,
            "information": (0..6).map(|i| (0..6).map(|j| r.information[(i, j)]).collect::<Vec<_>>()).collect::<Vec<_>>(),
        });
        let path = out.join(TRANSFORM_FILE);
        let text = serde_json::to_string_pretty(&transform)
            .map_err(|e| io(&path)(std::io::Error::other(e)))?;
        write_atomically(&path, text.as_bytes())
    })?;
    timed(&mut stages, "preview", || -> Result<(), ScanError> {
        let paint = |c: &PointCloud, rgb: [u8; 3]| -> Result<PointCloud, ScanError> {
            let bare = PointCloud::from_positions(c.positions().to_vec());
            Ok(bare.with_colors(vec![rgb; c.len()])?)
        };
        let mut both = paint(target, [120, 150, 200])?;
        both.extend(&paint(&moved, [240, 150, 40])?, MergePolicy::DropMismatched)?;
        write_preview_png(out, &both, PreviewColoring::Colors).map(|_| ())
    })?;
    Ok(CloudRegistration {
        result: r,
        source_points: source.len(),
        target_points: target.len(),
        registered_points,
        cloud: ply,
        stages,
    })
}

impl CloudRegistration {
    /// Records the figures of `slscan register`'s `report.json` (`metric`: the metric's name
    /// as the user gave it) and the stage times in `report`.
    pub fn record(&self, report: &mut RunReport, metric: &str) {
        let r = &self.result;
        report.add_stages(&self.stages);
        report.figure("metric", metric);
        report.figure("source_points", self.source_points);
        report.figure("target_points", self.target_points);
        report.figure("registered_points", self.registered_points);
        report.figure("rmse_mm", r.rmse);
        report.figure("fitness", r.fitness);
        report.figure("iterations", r.iterations);
        report.figure("converged", r.converged);
        report.figure("rotation_deg", r.pose.rotation.angle().to_degrees());
        report.figure("translation_mm", r.pose.translation.vector.norm());
        report.figure("T_target_source", json!(sl_camera::pose_to_matrix(&r.pose)));
    }

    /// The registration in one line: the moved cloud, iterations, motion, RMSE and fitness.
    #[must_use]
    pub fn summary(&self) -> String {
        let r = &self.result;
        format!(
            "{}: {} iterations ({}), rotation {:.3} deg, translation {:.3} mm, RMSE {:.4} mm, fitness {:.3}",
            self.cloud.display(),
            r.iterations,
            if r.converged {
                "converged"
            } else {
                "NOT converged"
            },
            r.pose.rotation.angle().to_degrees(),
            r.pose.translation.vector.norm(),
            r.rmse,
            r.fitness
        )
    }
}

/// What [`merge_and_write`] found and wrote.
#[derive(Debug, Clone)]
pub struct ViewsMerge {
    /// The views' names (their files, as given).
    pub names: Vec<String>,
    /// The initial poses `T_world_view`.
    pub initial: Vec<Isometry3<f64>>,
    /// Where the initial poses came from (`turntable`, `identity`).
    pub initial_from: String,
    /// Points of all views together.
    pub input_points: usize,
    /// The alignment: poses, the pairs registered.
    pub alignment: ViewAlignment,
    /// Points of the merged cloud.
    pub merged_points: usize,
    /// The merged cloud's file.
    pub cloud: PathBuf,
    /// Wall time per stage: `register views`, `merge`, `write`, `preview`.
    pub stages: Vec<StageTime>,
}

/// Aligns `views` (named `names`, in mm) from their `initial` poses `T_world_view` (which came
/// from `initial_from`), merges them and writes the merged cloud to `ply`, and beside it the
/// poses (`poses.json`) and a picture (`preview.png`), reporting each step as progress of the
/// stage `merge`.
///
/// # Errors
/// The alignment's — [`sl_icp::IcpError::ViewsNotPlaced`] (inside [`ScanError::Icp`]) with
/// every pair's figures when some view could not be placed; the merge's; the files'.
pub fn merge_and_write(
    views: &[PointCloud],
    names: &[String],
    initial: &[Isometry3<f64>],
    initial_from: &str,
    config: &MergeConfig,
    ply: &Path,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<ViewsMerge, ScanError> {
    let dir = ply
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut step = |done| {
        progress(ScanProgress {
            stage: "merge",
            done,
            total: 3,
        });
    };
    let mut stages = Vec::new();
    step(0);
    let alignment = timed(&mut stages, "register views", || {
        align_views(views, initial, config)
    })?;
    step(1);
    let merged = timed(&mut stages, "merge", || {
        merge_aligned(views, &alignment.poses, config)
    })?;
    step(2);
    timed(&mut stages, "write", || -> Result<(), ScanError> {
        write_ply(ply, &merged, PlyFormat::default())?;
        let poses = json!({
            "world": "camera frame of view 0",
            "units": "mm",
            "initial_poses_from": initial_from,
            "views": names.iter().zip(&alignment.poses).map(|(v, p)| json!({
                "view": v,
                "T_world_view": sl_camera::pose_to_matrix(p),
            })).collect::<Vec<_>>(),
        });
        let path = dir.join("poses.json");
        let text = serde_json::to_string_pretty(&poses)
            .map_err(|e| io(&path)(std::io::Error::other(e)))?;
        write_atomically(&path, text.as_bytes())
    })?;
    timed(&mut stages, "preview", || {
        write_preview_png(dir, &merged, PreviewColoring::Grey)
    })?;
    step(3);
    Ok(ViewsMerge {
        names: names.to_vec(),
        initial: initial.to_vec(),
        initial_from: initial_from.to_owned(),
        input_points: views.iter().map(PointCloud::len).sum(),
        alignment,
        merged_points: merged.len(),
        cloud: ply.to_path_buf(),
        stages,
    })
}

impl ViewsMerge {
    /// The name of view `i` (its file), or `view i`.
    fn name(&self, i: usize) -> String {
        self.names
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("view {i}"))
    }

    /// Records the figures of `slscan merge`'s `report.json` and the stage times in `report`.
    pub fn record(&self, report: &mut RunReport) {
        report.add_stages(&self.stages);
        report.figure("views", self.names.len());
        report.figure("input_points", self.input_points);
        report.figure("merged_points", self.merged_points);
        report.figure("initial_poses_from", self.initial_from.as_str());
        for (key, value) in alignment_figures(&self.alignment, &self.initial, &|i| self.name(i)) {
            report.figure(key, value);
        }
    }

    /// What the merge did, a line each: where the poses came from, then the merged cloud.
    #[must_use]
    pub fn summary(&self) -> Vec<String> {
        let pairs = &self.alignment.pairs;
        let used = pairs.iter().filter(|p| p.used).count();
        let global = pairs.iter().filter(|p| p.used && p.global).count();
        vec![
            format!("poses: {}", self.alignment.pose_summary()),
            format!(
                "{}: {} views ({} pairs used of {}, {} by global registration), {} points; largest pose correction {:.3} deg",
                self.cloud.display(),
                self.names.len(),
                used,
                pairs.len(),
                global,
                self.merged_points,
                largest_pose_correction_deg(&self.initial, &self.alignment.poses)
            ),
        ]
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use nalgebra::{Point3, Vector3};
    use sl_icp::Metric;

    use super::*;

    /// A wavy surface, and the same surface moved by a known motion: the transform written is
    /// that motion, and reading the file back gives it again; a file without the matrix is
    /// named.
    #[test]
    fn the_written_transform_reads_back_as_the_motion() {
        let pts: Vec<Point3<f64>> = (0..3000)
            .map(|i| {
                let (x, y) = (f64::from(i % 60) - 30.0, f64::from(i / 60) - 25.0);
                Point3::new(x, y, 4.0 * (x / 7.0).cos() + 0.05 * y * y)
            })
            .collect();
        let truth = Isometry3::new(
            Vector3::new(1.0, 0.5, -0.4),
            Vector3::new(0.01, -0.02, 0.03),
        );
        let source = PointCloud::from_positions(pts.iter().map(|p| truth.inverse() * p).collect());
        let target = PointCloud::from_positions(pts);
        let config = IcpConfig {
            metric: Metric::PointToPlane,
            ..IcpConfig::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let r = register_and_write(
            &source,
            &target,
            &Isometry3::identity(),
            &config,
            None,
            dir.path(),
        )
        .unwrap();
        assert!(r.cloud.is_file() && dir.path().join("preview.png").is_file());
        let read = read_transform(&dir.path().join(TRANSFORM_FILE)).unwrap();
        assert!((read.translation.vector - truth.translation.vector).norm() < 1e-3);
        assert!(read.rotation.angle_to(&truth.rotation) < 1e-5);
        assert!(r.summary().contains("converged"));

        let bad = dir.path().join("bad.json");
        std::fs::write(&bad, "{\"rmse_mm\": 1}").unwrap();
        let e = read_transform(&bad).unwrap_err().to_string();
        assert!(
            e.contains("bad.json") && e.contains("T_target_source"),
            "{e}"
        );
    }
}
