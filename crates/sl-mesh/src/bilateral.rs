//! Bilateral mesh denoising (Fleishman, Drori & Cohen-Or, "Bilateral mesh denoising",
//! SIGGRAPH 2003): each vertex moves along its normal by a weighted mean of its neighbours'
//! heights over its tangent plane, the weights falling with distance (closeness) and with the
//! height itself (similarity). Neighbours across a sharp edge stand high over the plane and get
//! little weight, so edges and corners stay sharp while noise is averaged away.

use nalgebra::Point3;
use rayon::prelude::*;
use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::{VertexRings, check_indices};
use crate::measure::vertex_normals;

/// Parameters of [`smooth_bilateral`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BilateralConfig {
    /// Passes of the filter; normals are recomputed between passes.
    pub iterations: usize,
    /// Closeness scale `σ_c` in the mesh's units; `None`: the mean edge length. Neighbours
    /// within `2 σ_c` (over at most [`rings`](Self::rings) edges) take part.
    pub sigma_closeness: Option<f64>,
    /// Similarity scale `σ_s`: heights over the tangent plane much larger than it count as
    /// another surface (a feature) and are ignored. `None`: twice the noise estimated from the
    /// mesh (the median height of neighbours over the tangent planes).
    pub sigma_similarity: Option<f64>,
    /// How many edges away neighbours are searched (2: the 2-ring, as Fleishman's examples).
    pub rings: usize,
    /// Leaves the vertices of a hole's rim where they are.
    pub keep_boundary: bool,
}

impl Default for BilateralConfig {
    fn default() -> Self {
        Self {
            iterations: 3,
            sigma_closeness: None,
            sigma_similarity: None,
            rings: 2,
            keep_boundary: true,
        }
    }
}

/// The mean length of the edges of `mesh` (each triangle's three edges).
pub(crate) fn mean_edge_length(mesh: &TriangleMesh) -> f64 {
    if mesh.triangles.is_empty() {
        return 0.0;
    }
    let sum: f64 = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
            (b - a).norm() + (c - b).norm() + (a - c).norm()
        })
        .sum();
    sum / (3 * mesh.triangles.len()) as f64
}

/// Smooths `mesh` in place with the bilateral filter, keeping sharp edges and corners.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a non-positive scale or `rings` of 0;
/// [`MeshError::InvalidMesh`] for a triangle index out of range.
///
/// ```
/// use sl_mesh::{BilateralConfig, smooth_bilateral};
/// # let mut mesh = sl_cloud::TriangleMesh::default();
/// smooth_bilateral(&mut mesh, &BilateralConfig::default())?;
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn smooth_bilateral(mesh: &mut TriangleMesh, cfg: &BilateralConfig) -> Result<(), MeshError> {
    for (name, v) in [
        ("BilateralConfig::sigma_closeness", cfg.sigma_closeness),
        ("BilateralConfig::sigma_similarity", cfg.sigma_similarity),
    ] {
        if let Some(s) = v
            && !(s.is_finite() && s > 0.0)
        {
            return Err(MeshError::invalid(name, s, "must be positive and finite"));
        }
    }
    if cfg.rings == 0 {
        return Err(MeshError::invalid(
            "BilateralConfig::rings",
            cfg.rings,
            "at least 1 (the vertices joined by an edge)",
        ));
    }
    check_indices(mesh)?;
    if mesh.triangles.is_empty() {
        return Ok(());
    }
    let edge = mean_edge_length(mesh);
    let sc = cfg.sigma_closeness.unwrap_or(edge);
    let rings = VertexRings::new(mesh);
    let ss = match cfg.sigma_similarity {
        Some(s) => s,
        None => NOISE_TO_SIMILARITY * noise_level(mesh, &rings).max(MIN_NOISE_FRACTION * edge),
    };
    let reach = 2.0 * sc;
    for _ in 0..cfg.iterations {
        let normals = vertex_normals(mesh);
        let verts = &mesh.vertices;
        let moved: Vec<Point3<f64>> = (0..verts.len())
            .into_par_iter()
            .map_init(Vec::new, |scratch: &mut Vec<u32>, v| {
                let p = verts[v];
                let n = normals[v];
                if n.norm_squared() == 0.0 || (cfg.keep_boundary && rings.boundary[v]) {
                    return p;
                }
                neighbourhood(&rings, v, cfg.rings, scratch);
                // The vertex itself counts with height 0 and weight 1: where every neighbour
                // is dissimilar (a corner, an edge) it stays where it is.
                let (mut sum, mut norm) = (0.0, 1.0);
                for &q in scratch.iter() {
                    let d = verts[q as usize] - p;
                    let t = d.norm();
                    if t > reach {
                        continue;
                    }
                    let h = n.dot(&d);
                    let w = (-t * t / (2.0 * sc * sc)).exp() * (-h * h / (2.0 * ss * ss)).exp();
                    sum += w * h;
                    norm += w;
                }
                if norm > 0.0 { p + n * (sum / norm) } else { p }
            })
            .collect();
        mesh.vertices = moved;
    }
    Ok(())
}

/// `σ_s` is this many times the estimated noise: heights within the noise weigh nearly fully,
/// a step of several noise levels (a feature) hardly at all.
const NOISE_TO_SIMILARITY: f64 = 2.0;

/// Floor of the noise estimate, as a fraction of the mean edge length: a noise-free mesh still
/// gets a positive `σ_s` and can be smoothed of its faceting.
const MIN_NOISE_FRACTION: f64 = 0.02;

/// A robust estimate of the noise normal to the surface: 1.4826 times the median absolute
/// height of the 1-ring neighbours over each vertex's tangent plane (the median ignores the
/// minority of vertices on edges and corners), divided by √2 (a height is the difference of
/// two noisy positions).
fn noise_level(mesh: &TriangleMesh, rings: &VertexRings) -> f64 {
    let normals = vertex_normals(mesh);
    let mut h: Vec<f64> = (0..mesh.vertices.len())
        .flat_map(|v| {
            let p = mesh.vertices[v];
            let n = normals[v];
            rings
                .of(v)
                .iter()
                .map(move |&q| n.dot(&(mesh.vertices[q as usize] - p)).abs())
                .collect::<Vec<_>>()
        })
        .collect();
    if h.is_empty() {
        return 0.0;
    }
    let mid = h.len() / 2;
    let (_, m, _) = h.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *m / std::f64::consts::SQRT_2
}

/// The vertices within `depth` edges of `v` (without `v`), into `out`.
fn neighbourhood(rings: &VertexRings, v: usize, depth: usize, out: &mut Vec<u32>) {
    out.clear();
    out.push(v as u32);
    let mut from = 0;
    for _ in 0..depth {
        let to = out.len();
        for i in from..to {
            for &q in rings.of(out[i] as usize) {
                if !out.contains(&q) {
                    out.push(q);
                }
            }
        }
        from = to;
    }
    out.swap_remove(0);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_shapes::{add_noise, cube_distance, cube_mesh};
    use crate::{TaubinConfig, smooth_taubin};

    /// RMS distance to the cube of the vertices within `band` of an edge of the cube, and of
    /// all vertices.
    fn errors(m: &TriangleMesh, s: f64, band: f64) -> (f64, f64) {
        let (mut e_edge, mut n_edge, mut e_all) = (0.0, 0usize, 0.0);
        for p in &m.vertices {
            let d = cube_distance(p, s).powi(2);
            e_all += d;
            let near_faces = p
                .coords
                .iter()
                .filter(|c| (c.abs() - s).abs() < band)
                .count();
            if near_faces >= 2 {
                e_edge += d;
                n_edge += 1;
            }
        }
        (
            (e_edge / n_edge as f64).sqrt(),
            (e_all / m.vertices.len() as f64).sqrt(),
        )
    }

    /// A noisy cube (edge 20, grid spacing 0.5, noise 0.05): the bilateral filter removes
    /// noise on the faces and keeps the edges — near them its error is below half of Taubin's,
    /// which rounds them.
    #[test]
    fn keeps_edges_that_taubin_rounds() {
        let s = 10.0;
        let mut noisy = cube_mesh(s, 40);
        add_noise(&mut noisy, 0.05, 3);
        let band = 1.0;
        let (edge0, all0) = errors(&noisy, s, band);
        let mut bil = noisy.clone();
        smooth_bilateral(&mut bil, &BilateralConfig::default()).unwrap();
        let (edge_b, all_b) = errors(&bil, s, band);
        let mut tau = noisy.clone();
        smooth_taubin(&mut tau, &TaubinConfig::default()).unwrap();
        let (edge_t, _) = errors(&tau, s, band);
        assert!(all_b < 0.7 * all0, "all: {all0} -> {all_b}");
        assert!(
            edge_b < 0.5 * edge_t,
            "near edges: bilateral {edge_b}, Taubin {edge_t} (noisy {edge0})"
        );
        assert!(crate::check_topology(&bil).is_watertight_manifold());
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut m = cube_mesh(1.0, 2);
        let bad = BilateralConfig {
            sigma_similarity: Some(-1.0),
            ..BilateralConfig::default()
        };
        let e = smooth_bilateral(&mut m, &bad).unwrap_err().to_string();
        assert!(e.contains("sigma_similarity"), "{e}");
    }
}
