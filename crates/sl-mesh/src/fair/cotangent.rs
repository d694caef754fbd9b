//! The cotangent Laplace–Beltrami operator of a mesh (and its umbrella sibling) in compressed
//! rows, with the walks over its rings that the fairing's set-up makes: the operator `L` and
//! the vertex areas `M` of the thin plate `K = L M⁻¹ L`.

use nalgebra::Vector3;
use sl_cloud::TriangleMesh;

/// The cotangent Laplacian `L` (symmetric, `L_ii = Σ_j w_ij`, `L_ij = −w_ij`) and the
/// barycentric vertex areas `M` of a mesh, in compressed rows.
pub(super) struct Operator {
    /// Where each vertex's row starts in `ring` and `weight` (one more than the vertices).
    pub(super) start: Vec<usize>,
    /// The neighbours of each vertex, row after row.
    pub(super) ring: Vec<u32>,
    /// `w_ij` of each neighbour in `ring`.
    pub(super) weight: Vec<f64>,
    /// `L_ii = Σ_j w_ij`.
    pub(super) diagonal: Vec<f64>,
    /// The barycentric vertex areas (`M`).
    pub(super) area: Vec<f64>,
    /// Vertices on a boundary or non-manifold edge.
    pub(super) boundary: Vec<bool>,
    /// Mean edge length.
    pub(super) edge_scale: f64,
}

impl Operator {
    pub(super) fn new(mesh: &TriangleMesh) -> Self {
        let nv = mesh.vertices.len();
        // (a, b, half cotangent of the angle opposite edge ab in one triangle)
        let mut entries: Vec<(u32, u32, f64)> = Vec::with_capacity(mesh.triangles.len() * 6);
        let mut area = vec![0.0; nv];
        for t in &mesh.triangles {
            let p = t.map(|i| mesh.vertices[i as usize]);
            let twice_area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
            for k in 0..3 {
                area[t[k] as usize] += twice_area / 6.0;
            }
            for k in 0..3 {
                let (a, b, o) = (k, (k + 1) % 3, (k + 2) % 3);
                let (u, w) = (p[a] - p[o], p[b] - p[o]);
                let cross = u.cross(&w).norm();
                // Clamped at zero (obtuse angles) and at a large value (slivers): the
                // operator stays a symmetric M-matrix, so the system stays positive definite.
                let cot = if cross > 0.0 {
                    (u.dot(&w) / cross).clamp(0.0, 1e3)
                } else {
                    0.0
                };
                if t[a] != t[b] {
                    entries.push((t[a], t[b], 0.5 * cot));
                    entries.push((t[b], t[a], 0.5 * cot));
                }
            }
        }
        entries.sort_unstable_by_key(|e| (e.0, e.1));
        let mut start = vec![0usize; nv + 1];
        let mut ring = Vec::with_capacity(entries.len() / 2);
        let mut weight = Vec::with_capacity(entries.len() / 2);
        let mut diagonal = vec![0.0; nv];
        let mut boundary = vec![false; nv];
        let mut i = 0;
        while i < entries.len() {
            let (a, b) = (entries[i].0, entries[i].1);
            let mut w = 0.0;
            let mut uses = 0;
            while i < entries.len() && (entries[i].0, entries[i].1) == (a, b) {
                w += entries[i].2;
                uses += 1;
                i += 1;
            }
            if uses != 2 {
                // A boundary edge (one triangle) or a non-manifold one (more than two).
                boundary[a as usize] = true;
                boundary[b as usize] = true;
            }
            ring.push(b);
            weight.push(w);
            diagonal[a as usize] += w;
            start[a as usize + 1] += 1;
        }
        for v in 0..nv {
            start[v + 1] += start[v];
        }
        let edge_scale = {
            let (mut sum, mut n) = (0.0, 0usize);
            for t in &mesh.triangles {
                for k in 0..3 {
                    let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
                    sum += (mesh.vertices[a] - mesh.vertices[b]).norm();
                    n += 1;
                }
            }
            if n > 0 { sum / n as f64 } else { 0.0 }
        };
        Self {
            start,
            ring,
            weight,
            diagonal,
            area,
            boundary,
            edge_scale,
        }
    }

    /// The same connectivity with uniform (umbrella) weights: `M⁻¹ L x` is `x_i` minus the
    /// mean of its neighbours, whatever the triangles' shapes.
    pub(super) fn umbrella(&self) -> Self {
        let valence: Vec<f64> = (0..self.area.len())
            .map(|v| (self.start[v + 1] - self.start[v]) as f64)
            .collect();
        Self {
            start: self.start.clone(),
            ring: self.ring.clone(),
            weight: vec![1.0; self.weight.len()],
            diagonal: valence.clone(),
            area: valence,
            boundary: self.boundary.clone(),
            edge_scale: self.edge_scale,
        }
    }

    /// The connected pieces of the vertices where `inside` holds.
    pub(super) fn pieces(&self, inside: &[bool]) -> Vec<Vec<usize>> {
        let mut seen = vec![false; inside.len()];
        let mut pieces = Vec::new();
        for v0 in 0..inside.len() {
            if !inside[v0] || seen[v0] {
                continue;
            }
            seen[v0] = true;
            let (mut piece, mut stack) = (vec![v0], vec![v0]);
            while let Some(v) = stack.pop() {
                for &a in self.ring(v) {
                    let a = a as usize;
                    if inside[a] && !seen[a] {
                        seen[a] = true;
                        piece.push(a);
                        stack.push(a);
                    }
                }
            }
            pieces.push(piece);
        }
        pieces
    }

    pub(super) fn ring(&self, v: usize) -> &[u32] {
        &self.ring[self.start[v]..self.start[v + 1]]
    }

    /// The vertices within `rings` rings of `seeds` reached through vertices that `accept`
    /// (the seeds themselves not included unless reached again and accepted).
    pub(super) fn rings_around(
        &self,
        seeds: &[usize],
        rings: usize,
        accept: impl Fn(usize) -> bool,
    ) -> Vec<bool> {
        let mut reached = vec![false; self.area.len()];
        let mut frontier = seeds.to_vec();
        for _ in 0..rings {
            let mut next = Vec::new();
            for &v in &frontier {
                for &a in self.ring(v) {
                    let a = a as usize;
                    if !reached[a] && accept(a) {
                        reached[a] = true;
                        next.push(a);
                    }
                }
            }
            frontier = next;
        }
        reached
    }

    /// `L x` at vertex `v`.
    pub(super) fn laplace(&self, x: &[Vector3<f64>], v: usize) -> Vector3<f64> {
        let mut s = x[v] * self.diagonal[v];
        for k in self.start[v]..self.start[v + 1] {
            s -= x[self.ring[k] as usize] * self.weight[k];
        }
        s
    }

    /// `out = L M⁻¹ L x` on `active` (the free vertices and their two rings; `x` must be zero
    /// elsewhere where it matters); `scratch` holds `M⁻¹ L x`.
    pub(super) fn apply(
        &self,
        x: &[Vector3<f64>],
        active: &[usize],
        scratch: &mut [Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        for &v in active {
            let a = self.area[v];
            scratch[v] = if a > 0.0 {
                self.laplace(x, v) / a
            } else {
                Vector3::zeros()
            };
        }
        for &v in active {
            out[v] = self.laplace(scratch, v);
        }
    }
}
