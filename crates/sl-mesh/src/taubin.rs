//! Taubin's λ|μ smoothing (Taubin, "A signal processing approach to fair surface design",
//! SIGGRAPH 1995): a shrinking Laplacian step followed by an inflating one, a low-pass filter
//! that removes noise without the shrinkage of plain Laplacian smoothing.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::{VertexRings, check_indices};

/// Parameters of [`smooth_taubin`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaubinConfig {
    /// Pairs of λ and μ steps.
    pub iterations: usize,
    /// The shrinking step, in `(0, 1)`: 0.5 as Taubin's examples.
    pub lambda: f64,
    /// The inflating step, negative with `|μ| > λ`: −0.53 puts the pass-band frequency
    /// `1/λ + 1/μ` at 0.11, Taubin's recommended range (0.01–0.1 plus a margin).
    pub mu: f64,
    /// Leaves the vertices of a hole's rim where they are (otherwise the rim shrinks).
    pub keep_boundary: bool,
}

impl Default for TaubinConfig {
    fn default() -> Self {
        Self {
            iterations: 10,
            lambda: 0.5,
            mu: -0.53,
            keep_boundary: true,
        }
    }
}

/// Smooths `mesh` in place with Taubin's λ|μ filter on the uniform (umbrella) Laplacian. It
/// rounds sharp edges as it removes noise: see [`smooth_bilateral`](crate::smooth_bilateral)
/// for a filter that keeps them.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for `λ` outside `(0, 1)` or `μ` not below `−λ`;
/// [`MeshError::InvalidMesh`] for a triangle index out of range.
///
/// ```
/// use sl_mesh::{TaubinConfig, smooth_taubin};
/// # let mut mesh = sl_cloud::TriangleMesh::default();
/// smooth_taubin(&mut mesh, &TaubinConfig::default())?;
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn smooth_taubin(mesh: &mut TriangleMesh, cfg: &TaubinConfig) -> Result<(), MeshError> {
    if !(cfg.lambda > 0.0 && cfg.lambda < 1.0) {
        return Err(MeshError::invalid(
            "TaubinConfig::lambda",
            cfg.lambda,
            "must be in (0, 1)",
        ));
    }
    if !(cfg.mu.is_finite() && cfg.mu < -cfg.lambda) {
        return Err(MeshError::invalid(
            "TaubinConfig::mu",
            cfg.mu,
            "must be negative with |mu| > lambda (else the filter shrinks the mesh)",
        ));
    }
    check_indices(mesh)?;
    let rings = VertexRings::new(mesh);
    for _ in 0..cfg.iterations {
        for factor in [cfg.lambda, cfg.mu] {
            mesh.vertices = laplacian_step(&mesh.vertices, &rings, factor, cfg.keep_boundary);
        }
    }
    Ok(())
}

fn laplacian_step(
    vertices: &[Point3<f64>],
    rings: &VertexRings,
    factor: f64,
    keep_boundary: bool,
) -> Vec<Point3<f64>> {
    (0..vertices.len())
        .into_par_iter()
        .map(|v| {
            let ring = rings.of(v);
            let p = vertices[v];
            if ring.is_empty() || (keep_boundary && rings.boundary[v]) {
                return p;
            }
            let mean: Vector3<f64> = ring
                .iter()
                .map(|&q| vertices[q as usize].coords)
                .sum::<Vector3<f64>>()
                / ring.len() as f64;
            p + (mean - p.coords) * factor
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_shapes::{add_noise, sphere_mesh};

    fn rms_to_sphere(m: &TriangleMesh, r: f64) -> f64 {
        let s: f64 = m
            .vertices
            .iter()
            .map(|p| (p.coords.norm() - r).powi(2))
            .sum();
        (s / m.vertices.len() as f64).sqrt()
    }

    /// A sphere with noise of a third of its edge length: Taubin smoothing takes the RMS
    /// distance to the sphere down by more than half and keeps the volume within 1 % (plain
    /// Laplacian smoothing of the same strength would shrink it by several per cent).
    #[test]
    fn removes_noise_without_shrinking() {
        let clean = sphere_mesh(10.0, 5);
        let mut mesh = clean.clone();
        add_noise(&mut mesh, 0.1, 7);
        let before = rms_to_sphere(&mesh, 10.0);
        smooth_taubin(&mut mesh, &TaubinConfig::default()).unwrap();
        let after = rms_to_sphere(&mesh, 10.0);
        assert!(after < 0.5 * before, "{before} -> {after}");
        let (v0, v1) = (crate::signed_volume(&clean), crate::signed_volume(&mesh));
        assert!((v1 - v0).abs() < 0.01 * v0, "{v0} -> {v1}");
        assert!(crate::check_topology(&mesh).is_watertight_manifold());
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut m = sphere_mesh(1.0, 3);
        let bad = TaubinConfig {
            mu: -0.4,
            ..TaubinConfig::default()
        };
        let e = smooth_taubin(&mut m, &bad).unwrap_err().to_string();
        assert!(e.contains("TaubinConfig::mu"), "{e}");
    }
}
