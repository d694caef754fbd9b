//! Least-squares fits of planes and spheres, for accuracy measurements (flatness, sphere
//! radius and spacing as in VDI/VDE 2634). The fits live in `sl-cloud` (fits of points belong
//! with the points); these are the same functions with this crate's error type.

use nalgebra::Point3;
use sl_cloud::CloudError;

pub use sl_cloud::{PlaneFit, SphereFit};

use crate::TriError;

/// A fit's error of `sl-cloud` as this crate's [`TriError::Fit`] (any other error passes
/// through as [`TriError::Cloud`]).
fn tri_error(e: CloudError) -> TriError {
    match e {
        CloudError::Fit { what, message } => TriError::Fit { what, message },
        other => TriError::Cloud(other),
    }
}

/// Fits a plane to the finite points (non-finite ones are skipped): [`sl_cloud::fit_plane`].
///
/// # Errors
/// [`TriError::Fit`] for fewer than 3 finite points or collinear points.
pub fn fit_plane(points: &[Point3<f64>]) -> Result<PlaneFit, TriError> {
    sl_cloud::fit_plane(points).map_err(tri_error)
}

/// Fits a sphere to the finite points (non-finite ones are skipped): [`sl_cloud::fit_sphere`].
///
/// # Errors
/// [`TriError::Fit`] for fewer than 4 finite points or coplanar points.
pub fn fit_sphere(points: &[Point3<f64>]) -> Result<SphereFit, TriError> {
    sl_cloud::fit_sphere(points).map_err(tri_error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn too_few_points_is_a_tri_fit_error() {
        let p = [Point3::origin(), Point3::new(1.0, 0.0, 0.0)];
        assert!(matches!(
            fit_plane(&p),
            Err(TriError::Fit { what: "plane", .. })
        ));
        assert!(matches!(
            fit_sphere(&p),
            Err(TriError::Fit { what: "sphere", .. })
        ));
    }
}
