//! Scans given in any order with no poses (`slscan align`): sl-icp's multiway global
//! registration at the scans' voxel size, the placed scans combined into one cloud (and one
//! painted a colour per scan), and the figures of the alignment for `report.json`.

use serde_json::{Value, json};
use sl_cloud::{MergePolicy, PointCloud, with_normals_towards};
use sl_icp::{GlobalConfig, MultiwayAlignment, MultiwayConfig};

use crate::ScanError;
use nalgebra::{Isometry3, Point3};

/// One colour per scan in the painted cloud (cycled): blue-grey, orange, green, red, violet,
/// yellow.
pub const SCAN_PALETTE: [[u8; 3]; 6] = [
    [120, 150, 200],
    [240, 150, 40],
    [110, 190, 110],
    [210, 90, 90],
    [170, 120, 210],
    [200, 200, 90],
];

/// sl-icp's multiway configuration with every distance scaled to scans downsampled to
/// `voxel_mm` (the defaults are for `GlobalConfig::default().voxel_size`): the descriptor
/// radius, the RANSAC and ICP distances, the largest RMSE and edge disagreement; ICP refines
/// every placed pair.
#[must_use]
pub fn multiway_config_at(voxel_mm: f64) -> MultiwayConfig {
    let d = GlobalConfig::default();
    let k = voxel_mm / d.voxel_size;
    let mut global = d;
    global.voxel_size = voxel_mm;
    global.fpfh.radius *= k;
    global.ransac.inlier_distance *= k;
    global.icp.max_correspondence_distance *= k;
    let base = MultiwayConfig::default();
    MultiwayConfig {
        global,
        max_rmse: base.max_rmse * k,
        max_edge_disagreement: base.max_edge_disagreement * k,
        refine: Some(global.icp),
        ..base
    }
}

/// The placed scans in the first scan's frame.
#[derive(Debug, Clone)]
pub struct CombinedScans {
    /// Every placed scan moved by its pose, with its own attributes (normals, colours,
    /// quality) where every scan has them; normals estimated instead when asked.
    pub aligned: PointCloud,
    /// The same positions, each scan painted its [`SCAN_PALETTE`] colour.
    pub painted: PointCloud,
}

/// Moves each scan with a pose (`None`: not placed, left out) into the first scan's frame and
/// combines them; with `normals_towards` (`(where the scanner stood in each scan's frame,
/// neighbours)`) each scan's normals are estimated facing that point first. `name` names
/// scan `i` in errors.
///
/// # Errors
/// [`ScanError::Step`] naming the scan whose normals cannot be estimated; the cloud's errors.
pub fn combine_aligned(
    clouds: &[PointCloud],
    poses: &[Option<Isometry3<f64>>],
    normals_towards: Option<(Point3<f64>, usize)>,
    name: &dyn Fn(usize) -> String,
) -> Result<CombinedScans, ScanError> {
    let mut aligned = PointCloud::new();
    let mut painted = PointCloud::new();
    for (i, (c, pose)) in clouds.iter().zip(poses).enumerate() {
        let Some(pose) = pose else { continue };
        let mut moved = match normals_towards {
            Some((eye, k)) => with_normals_towards(c, eye, k).map_err(|e| ScanError::Step {
                what: format!("{}: cannot estimate normals", name(i)),
                source: Box::new(e.into()),
            })?,
            None => c.clone(),
        };
        moved.transform(pose);
        aligned.extend(&moved, MergePolicy::DropMismatched)?;
        let bare = PointCloud::from_positions(moved.positions().to_vec());
        let colour = SCAN_PALETTE[i % SCAN_PALETTE.len()];
        painted.extend(
            &bare.with_colors(vec![colour; moved.len()])?,
            MergePolicy::DropMismatched,
        )?;
    }
    Ok(CombinedScans { aligned, painted })
}

/// The figures of a multiway alignment for `report.json`, by name: every pair tried (scans by
/// `name`, descriptor distance, verified, pruned, used, fitness, RMSE, matches, inliers,
/// `T_target_source`, why), the counts, the unplaced scans and why, the pose graph's costs.
pub fn multiway_figures(
    a: &MultiwayAlignment,
    name: &dyn Fn(usize) -> String,
) -> Vec<(&'static str, Value)> {
    let pairs: Vec<Value> = a
        .pairs
        .iter()
        .map(|p| {
            let r = p.registration.as_ref();
            json!({
                "source": name(p.source),
                "target": name(p.target),
                "descriptor_distance": p.descriptor_distance,
                "verified": p.verified,
                "pruned": p.pruned,
                "used": p.used(),
                "fitness": p.fitness(),
                "rmse_mm": p.rmse(),
                "descriptor_matches": r.map(|r| r.correspondences),
                "ransac_inliers": r.map(|r| r.ransac.inliers),
                "ransac_iterations": r.map(|r| r.ransac.iterations),
                "T_target_source": r.map(|r| sl_camera::pose_to_matrix(&r.pose)),
                "reason": p.reason,
            })
        })
        .collect();
    let mut f = vec![
        ("placed_views", (a.poses.len() - a.unplaced.len()).into()),
        ("pairs_tried", a.pairs.len().into()),
        (
            "pairs_verified",
            a.pairs.iter().filter(|p| p.verified).count().into(),
        ),
        ("pairs_pruned", a.pruned_edges.into()),
        (
            "pairs_used",
            a.pairs.iter().filter(|p| p.used()).count().into(),
        ),
        ("pairs", Value::Array(pairs)),
        (
            "unplaced",
            a.unplaced
                .iter()
                .map(|u| json!({"view": name(u.view), "why": u.why}))
                .collect(),
        ),
    ];
    if let Some(g) = &a.pose_graph {
        f.push(("pose_graph_initial_cost", g.initial_cost.into()));
        f.push(("pose_graph_final_cost", g.final_cost.into()));
        f.push(("pose_graph_iterations", g.iterations.into()));
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_configuration_scales_every_distance_with_the_voxel() {
        let d = GlobalConfig::default();
        let base = MultiwayConfig::default();
        let c = multiway_config_at(3.0 * d.voxel_size);
        assert_eq!(c.global.voxel_size, 3.0 * d.voxel_size);
        assert!((c.global.fpfh.radius - 3.0 * d.fpfh.radius).abs() < 1e-12);
        assert!((c.global.ransac.inlier_distance - 3.0 * d.ransac.inlier_distance).abs() < 1e-12);
        assert!((c.max_rmse - 3.0 * base.max_rmse).abs() < 1e-12);
        assert!(c.refine.is_some());
    }

    #[test]
    fn unplaced_scans_are_left_out_and_each_placed_one_is_moved_and_painted() {
        let a = PointCloud::from_positions(vec![Point3::new(0.0, 0.0, 0.0); 2]);
        let b = PointCloud::from_positions(vec![Point3::new(1.0, 0.0, 0.0); 3]);
        let c = PointCloud::from_positions(vec![Point3::new(2.0, 0.0, 0.0); 5]);
        let shift = Isometry3::translation(0.0, 10.0, 0.0);
        let poses = [Some(Isometry3::identity()), None, Some(shift)];
        let name = |i: usize| format!("scan {i}");
        let out = combine_aligned(&[a, b, c], &poses, None, &name).unwrap();
        assert_eq!(out.aligned.len(), 7);
        assert_eq!(out.painted.len(), 7);
        let last = out.aligned.positions()[6];
        assert!((last - Point3::new(2.0, 10.0, 0.0)).norm() < 1e-12);
        let colours = out.painted.colors().unwrap();
        assert_eq!(colours[0], SCAN_PALETTE[0]);
        assert_eq!(colours[6], SCAN_PALETTE[2]);
    }
}
