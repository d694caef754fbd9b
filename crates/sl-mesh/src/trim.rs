//! Density trimming: removing the surface that Poisson reconstruction invents where there are
//! no samples (it closes every opening, such as the underside of an object on the turntable).

use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::topology::{compact_vertices, remove_small_components};

/// What [`trim_by_density`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Trimmed {
    /// The trimmed mesh (open where surface was removed).
    pub mesh: TriangleMesh,
    /// The density of each kept vertex.
    pub densities: Vec<f64>,
    /// The density below which vertices were removed (samples per unit area).
    pub threshold: f64,
    /// Triangles removed.
    pub triangles_removed: usize,
}

/// Pieces left with fewer triangles than this after trimming are specks and go too.
const MIN_PIECE_TRIANGLES: usize = 50;

/// Removes the triangles with a vertex whose sampling density (from
/// [`PoissonSurface::densities`](crate::PoissonSurface::densities)) is below `min_ratio`
/// times the median density of the vertices, then the specks left (fewer than 50
/// triangles) and unused vertices. Relative to the median, one ratio suits any scan
/// resolution: 0.1 removes surface supported by a tenth of the typical sampling.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a ratio outside `[0, 1)`; [`MeshError::InvalidMesh`]
/// when there is not one density per vertex.
///
/// ```
/// use sl_mesh::trim_by_density;
/// # let mesh = sl_cloud::TriangleMesh::default();
/// let trimmed = trim_by_density(&mesh, &[], 0.1)?;
/// assert_eq!(trimmed.triangles_removed, 0);
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn trim_by_density(
    mesh: &TriangleMesh,
    densities: &[f64],
    min_ratio: f64,
) -> Result<Trimmed, MeshError> {
    if !(0.0..1.0).contains(&min_ratio) {
        return Err(MeshError::invalid(
            "min_ratio",
            min_ratio,
            "must be in [0, 1): a fraction of the median sampling density",
        ));
    }
    if densities.len() != mesh.vertices.len() {
        return Err(MeshError::InvalidMesh(format!(
            "{} densities for {} vertices",
            densities.len(),
            mesh.vertices.len()
        )));
    }
    crate::adjacency::check_indices(mesh)?;
    let threshold = min_ratio * median_density(densities);
    let low: Vec<bool> = densities
        .iter()
        .map(|&d| d.is_nan() || d < threshold)
        .collect();
    let mut out = mesh.clone();
    out.triangles
        .retain(|t| !t.iter().any(|&i| low[i as usize]));
    let after_cut = out.triangles.len();
    if after_cut < mesh.triangles.len() {
        remove_small_components(&mut out, MIN_PIECE_TRIANGLES);
    }
    // Carry the densities through the renumbering.
    let old = compact_vertices(&mut out);
    let dens = old.iter().map(|&i| densities[i as usize]).collect();
    Ok(Trimmed {
        triangles_removed: mesh.triangles.len() - out.triangles.len(),
        mesh: out,
        densities: dens,
        threshold,
    })
}

/// The median of the finite `densities` (0 when there is none): the reference of the support
/// ratios of `trim_by_density`, `simplify` and `fair_unsupported`.
pub(crate) fn median_density(densities: &[f64]) -> f64 {
    let mut finite: Vec<f64> = densities
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .collect();
    if finite.is_empty() {
        return 0.0;
    }
    // The element a full sort would put in the middle, in linear time.
    let middle = finite.len() / 2;
    *finite.select_nth_unstable_by(middle, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check_topology;
    use crate::test_shapes::partial_sphere_surface;

    /// The lower half of a sphere only (as a scan sees an object from above): Poisson closes
    /// the top with invented surface; trimming at a tenth of the median density removes it
    /// (no vertex kept is more than a few cells above the data) and keeps the data's part.
    #[test]
    fn invented_surface_is_removed() {
        let s = partial_sphere_surface(10.0, |p, _| p.z < 0.0);
        assert!(s.mesh.vertices.iter().any(|p| p.z > 3.0));
        let t = trim_by_density(&s.mesh, &s.densities, 0.1).unwrap();
        assert!(t.triangles_removed > 0);
        assert_eq!(t.densities.len(), t.mesh.vertices.len());
        // The density is a splat over cells four times the finest: it fades over two of them
        // (eight finest cells) past the data's rim at z = 0.
        let top = t.mesh.vertices.iter().map(|p| p.z).fold(f64::MIN, f64::max);
        assert!(
            top < 8.0 * s.cell_size,
            "kept up to z = {top}, cell {}",
            s.cell_size
        );
        // What is kept is the half sphere (area 2π r²) and the fading rim.
        let area = crate::surface_area(&t.mesh);
        let half = 2.0 * std::f64::consts::PI * 100.0;
        assert!(area > half && area < 1.25 * half, "{area} vs {half}");
        let low = t.mesh.vertices.iter().map(|p| p.z).fold(f64::MAX, f64::min);
        assert!(low < -9.5, "{low}");
        let topo = check_topology(&t.mesh);
        assert!(topo.boundary_edges > 0 && topo.is_manifold(), "{topo:?}");
        // Nothing to trim on a closed, evenly sampled sphere.
        let s = partial_sphere_surface(10.0, |_, _| true);
        let t = trim_by_density(&s.mesh, &s.densities, 0.1).unwrap();
        assert_eq!(t.triangles_removed, 0);
        assert!(trim_by_density(&s.mesh, &s.densities, 1.5).is_err());
        assert!(trim_by_density(&s.mesh, &s.densities[1..], 0.1).is_err());
    }
}
