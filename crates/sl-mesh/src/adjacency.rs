//! Vertex neighbourhoods of a triangle mesh in compressed rows (one allocation), shared by the
//! smoothing filters.

use sl_cloud::TriangleMesh;

/// The vertices joined to each vertex by an edge (its 1-ring), and whether it lies on a
/// boundary (an edge used by one triangle).
pub(crate) struct VertexRings {
    start: Vec<usize>,
    ring: Vec<u32>,
    /// Whether each vertex has a boundary edge.
    pub(crate) boundary: Vec<bool>,
}

impl VertexRings {
    /// Builds the rings; triangle indices must be in range.
    pub(crate) fn new(mesh: &TriangleMesh) -> Self {
        let nv = mesh.vertices.len();
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 6);
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if a != b {
                    pairs.push((a, b));
                    pairs.push((b, a));
                }
            }
        }
        pairs.sort_unstable();
        // An undirected edge used by one triangle appears once in each direction; by two, twice.
        let mut boundary = vec![false; nv];
        let mut start = vec![0usize; nv + 1];
        let mut ring = Vec::with_capacity(pairs.len() / 2);
        let mut i = 0;
        while i < pairs.len() {
            let mut j = i;
            while j < pairs.len() && pairs[j] == pairs[i] {
                j += 1;
            }
            let (a, b) = pairs[i];
            if j - i == 1 {
                boundary[a as usize] = true;
                boundary[b as usize] = true;
            }
            ring.push(b);
            start[a as usize + 1] += 1;
            i = j;
        }
        for v in 0..nv {
            start[v + 1] += start[v];
        }
        Self {
            start,
            ring,
            boundary,
        }
    }

    /// The neighbours of vertex `v`.
    #[inline]
    pub(crate) fn of(&self, v: usize) -> &[u32] {
        &self.ring[self.start[v]..self.start[v + 1]]
    }
}

/// Checks that every triangle index is in range.
pub(crate) fn check_indices(mesh: &TriangleMesh) -> Result<(), crate::MeshError> {
    let n = mesh.vertices.len();
    match mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= n))
    {
        Some(k) => Err(crate::MeshError::InvalidMesh(format!(
            "triangle {k} has a vertex index out of range (the mesh has {n} vertices)"
        ))),
        None => Ok(()),
    }
}
