//! Hole filling: each hole's rim (a loop of edges used by one triangle) is closed by ear
//! clipping, always cutting the ear of smallest angle first (as Liepa's and MeshLab's fillers
//! start), without adding vertices.

use std::collections::HashSet;

use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::check_indices;
use crate::topology::edge_uses;

/// What [`fill_holes`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct HoleFilling {
    /// Holes found (closed rim loops).
    pub holes: usize,
    /// Holes closed.
    pub filled: usize,
    /// Triangles added.
    pub triangles_added: usize,
    /// Holes left open because their rim has more edges than the limit.
    pub too_large: usize,
    /// Rims left alone because they pass twice through one vertex or a cut would duplicate an
    /// existing edge.
    pub skipped: usize,
}

/// Closes the holes of `mesh` whose rim has at most `max_edges` edges (a large opening is
/// usually real — the bottom of an object standing on the turntable — and should stay open).
/// The new triangles wind as their neighbours, so a mesh with only small holes becomes
/// watertight.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for `max_edges` below 3; [`MeshError::InvalidMesh`] for a
/// triangle index out of range.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// // A tetrahedron with one face missing.
/// let mut mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0), Point3::new(0.0, 0.0, 1.0)],
///     triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2]],
/// };
/// let done = sl_mesh::fill_holes(&mut mesh, 100)?;
/// assert_eq!((done.filled, done.triangles_added), (1, 1));
/// assert!(sl_mesh::check_topology(&mesh).is_watertight_manifold());
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn fill_holes(mesh: &mut TriangleMesh, max_edges: usize) -> Result<HoleFilling, MeshError> {
    if max_edges < 3 {
        return Err(MeshError::invalid(
            "max_edges",
            max_edges,
            "at least 3 (the smallest hole is a triangle)",
        ));
    }
    check_indices(mesh)?;
    let mut done = HoleFilling::default();
    let uses = edge_uses(mesh);
    let mut edges: HashSet<(u32, u32)> = uses.iter().map(|&(a, b, _, _)| (a, b)).collect();
    let rim: HashSet<(u32, u32)> = uses
        .iter()
        .filter(|e| e.2 == 1)
        .map(|&(a, b, _, _)| (a, b))
        .collect();
    // Directed rim edges of the hole: the reverse of the triangle's edge.
    let mut next: Vec<Option<u32>> = vec![None; mesh.vertices.len()];
    let mut branching: HashSet<u32> = HashSet::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if rim.contains(&(a.min(b), a.max(b))) {
                if next[b as usize].is_some() {
                    branching.insert(b);
                }
                next[b as usize] = Some(a);
            }
        }
    }
    let mut seen = vec![false; mesh.vertices.len()];
    let mut added = Vec::new();
    for start in 0..mesh.vertices.len() {
        if seen[start] || next[start].is_none() {
            continue;
        }
        let mut ring = vec![start as u32];
        seen[start] = true;
        let mut v = start;
        let mut closed = false;
        while let Some(n) = next[v] {
            if n as usize == start {
                closed = true;
                break;
            }
            if seen[n as usize] {
                break;
            }
            seen[n as usize] = true;
            ring.push(n);
            v = n as usize;
        }
        if !closed {
            continue;
        }
        done.holes += 1;
        if ring.len() > max_edges {
            done.too_large += 1;
            continue;
        }
        if ring.iter().any(|v| branching.contains(v)) {
            done.skipped += 1;
            continue;
        }
        match clip_ears(mesh, &ring, &mut edges) {
            Some(tris) => {
                done.filled += 1;
                done.triangles_added += tris.len();
                added.extend(tris);
            }
            None => done.skipped += 1,
        }
    }
    mesh.triangles.extend(added);
    Ok(done)
}

/// Triangulates the loop `ring` (in the hole's direction) by ear clipping, smallest angle
/// first; `None` (and `edges` unchanged) when every remaining ear would duplicate an edge.
fn clip_ears(
    mesh: &TriangleMesh,
    ring: &[u32],
    edges: &mut HashSet<(u32, u32)>,
) -> Option<Vec<[u32; 3]>> {
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut poly = ring.to_vec();
    let mut out = Vec::with_capacity(ring.len() - 2);
    let mut new_edges = Vec::new();
    while poly.len() > 3 {
        let m = poly.len();
        let mut best: Option<(f64, usize)> = None;
        for i in 0..m {
            let (p, c, n) = (poly[(i + m - 1) % m], poly[i], poly[(i + 1) % m]);
            if edges.contains(&key(p, n)) {
                continue;
            }
            let (vp, vc, vn) = (
                mesh.vertices[p as usize],
                mesh.vertices[c as usize],
                mesh.vertices[n as usize],
            );
            let (d1, d2) = (vp - vc, vn - vc);
            let angle = d1.angle(&d2);
            if best.is_none_or(|(a, _)| angle < a) {
                best = Some((angle, i));
            }
        }
        let Some((_, i)) = best else {
            for e in new_edges {
                edges.remove(&e);
            }
            return None;
        };
        let m = poly.len();
        let (p, c, n) = (poly[(i + m - 1) % m], poly[i], poly[(i + 1) % m]);
        out.push([p, c, n]);
        edges.insert(key(p, n));
        new_edges.push(key(p, n));
        poly.remove(i);
    }
    out.push([poly[0], poly[1], poly[2]]);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check_topology;
    use crate::test_shapes::sphere_mesh;

    /// A sphere with a cap cut away (a hole of a few dozen rim edges) and one small hole: both
    /// close, the mesh is watertight and manifold again, and the area comes back to within 1 %
    /// of the whole sphere's (the flat patch is smaller than the cap by its sagitta).
    #[test]
    fn cut_sphere_is_closed_again() {
        let whole = sphere_mesh(10.0, 5);
        let area = crate::surface_area(&whole);
        let mut mesh = whole.clone();
        mesh.triangles
            .retain(|t| t.iter().any(|&i| mesh.vertices[i as usize].z < 9.5));
        let removed = whole.triangles.len() - mesh.triangles.len();
        assert!(removed > 20, "{removed}");
        mesh.triangles.remove(100);
        let before = check_topology(&mesh);
        assert!(before.boundary_edges > 0);
        let done = fill_holes(&mut mesh, 1000).unwrap();
        assert_eq!((done.holes, done.filled), (2, 2), "{done:?}");
        let topo = check_topology(&mesh);
        assert!(topo.is_watertight_manifold(), "{topo:?}");
        let a = crate::surface_area(&mesh);
        assert!((a - area).abs() < 0.01 * area, "{a} vs {area}");
    }

    #[test]
    fn large_holes_stay_open() {
        let mut mesh = sphere_mesh(10.0, 5);
        let v = mesh.vertices.clone();
        mesh.triangles
            .retain(|t| t.iter().any(|&i| v[i as usize].z < 0.0));
        let done = fill_holes(&mut mesh, 20).unwrap();
        assert_eq!((done.holes, done.too_large, done.filled), (1, 1, 0));
        assert!(check_topology(&mesh).boundary_edges > 20);
        assert!(fill_holes(&mut mesh, 2).is_err());
    }
}
