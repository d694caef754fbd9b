//! Clouds in millimetres: read a PLY scaling its units to mm, refuse a cloud that is almost
//! surely in metres, and give a cloud normals facing where the scanner stood — what every tool
//! reading other programs' clouds does first.

use std::path::Path;

use nalgebra::Point3;

use crate::{CloudError, NormalConfig, NormalOrientation, PointCloud, estimate_normals, read_ply};

/// Reads a PLY and multiplies its positions by `scale` (its units to mm: 1000 for metres).
///
/// # Errors
/// [`CloudError::InvalidParameter`] naming `scale` when it is not finite and positive; the
/// reader's errors; [`CloudError::PlyMissing`] when the cloud has no point.
pub fn read_ply_scaled(path: &Path, scale: f64) -> Result<PointCloud, CloudError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(CloudError::invalid(
            "scale",
            scale,
            "must be finite and > 0",
        ));
    }
    let mut cloud = read_ply(path)?;
    if scale != 1.0 {
        for p in cloud.positions_mut() {
            p.coords *= scale;
        }
    }
    if cloud.is_empty() {
        return Err(CloudError::PlyMissing {
            file: path.display().to_string(),
            what: "point".to_owned(),
        });
    }
    Ok(cloud)
}

/// Refuses a cloud whose bounding-box diagonal is under `min_extent_mm`: any object worth
/// scanning spans tens of millimetres, while the same object in metres spans a fraction of one.
/// A cloud that spans nothing whatever its units (no finite point, one point, every point at one
/// place) is refused for that first, never taken for one in metres. `path` names the cloud in
/// the error. [`check_cloud`](crate::check_cloud) with [`CloudNeeds`](crate::CloudNeeds) says
/// what the cloud is for and how many points it needs.
///
/// ```
/// use std::path::Path;
/// use sl_cloud::{PointCloud, check_millimetres};
/// use nalgebra::Point3;
/// let metres = PointCloud::from_positions(vec![Point3::origin(), Point3::new(0.1, 0.05, 0.0)]);
/// assert!(check_millimetres(&metres, Path::new("a.ply"), 1.0).is_err());
/// let mm = PointCloud::from_positions(vec![Point3::origin(), Point3::new(100.0, 50.0, 0.0)]);
/// assert!(check_millimetres(&mm, Path::new("a.ply"), 1.0).is_ok());
/// ```
///
/// # Errors
/// [`CloudError::Degenerate`]; [`CloudError::NotMillimetres`] naming the file, its extent and
/// the limit.
pub fn check_millimetres(
    cloud: &PointCloud,
    path: &Path,
    min_extent_mm: f64,
) -> Result<(), CloudError> {
    crate::check_cloud(
        cloud,
        path,
        &crate::CloudNeeds {
            min_extent_mm: Some(min_extent_mm),
            ..crate::CloudNeeds::default()
        },
    )
}

/// `cloud` with normals estimated from `k` neighbours and turned towards `viewpoint` (where the
/// scanner stood, in the cloud's frame), in place of its own; its other attributes stay.
///
/// # Errors
/// The estimation's errors (too few points, `k` out of range).
pub fn with_normals_towards(
    cloud: &PointCloud,
    viewpoint: Point3<f64>,
    k: usize,
) -> Result<PointCloud, CloudError> {
    let cfg = NormalConfig {
        k,
        orientation: NormalOrientation::TowardViewpoint(viewpoint),
    };
    let est = estimate_normals(cloud, &cfg)?;
    cloud.clone().with_normals(est.normals)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn a_scaled_read_multiplies_and_refuses_bad_scales_and_empty_clouds() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.ply");
        let cloud = PointCloud::from_positions(vec![Point3::new(0.001, 0.002, 0.003)]);
        crate::write_ply(&path, &cloud, crate::PlyFormat::default()).unwrap();
        let mm = read_ply_scaled(&path, 1000.0).unwrap();
        assert!((mm.positions()[0] - Point3::new(1.0, 2.0, 3.0)).norm() < 1e-9);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let err = read_ply_scaled(&path, bad).unwrap_err().to_string();
            assert!(err.contains("scale"), "{bad}: {err}");
        }
        let empty = dir.path().join("empty.ply");
        crate::write_ply(&empty, &PointCloud::default(), crate::PlyFormat::default()).unwrap();
        let err = read_ply_scaled(&empty, 1.0).unwrap_err().to_string();
        assert!(err.contains("empty.ply") && err.contains("point"), "{err}");
    }

    #[test]
    fn normals_face_the_viewpoint() {
        let pts: Vec<_> = (0..100)
            .map(|i| Point3::new(f64::from(i % 10), f64::from(i / 10), 0.0))
            .collect();
        let cloud = PointCloud::from_positions(pts);
        for (eye, z) in [
            (Point3::new(5.0, 5.0, 100.0), 1.0),
            (Point3::new(5.0, 5.0, -100.0), -1.0),
        ] {
            let with = with_normals_towards(&cloud, eye, 8).unwrap();
            let normals = with.normals().unwrap();
            assert!(
                normals
                    .iter()
                    .all(|n| (n - Vector3::new(0.0, 0.0, z)).norm() < 1e-9)
            );
        }
    }
}
