//! Topology checks (watertight, manifold, consistently oriented), connected pieces and the
//! removal of small ones.

use sl_cloud::TriangleMesh;

/// What [`check_topology`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Topology {
    /// Number of vertices.
    pub vertices: usize,
    /// Number of triangles.
    pub triangles: usize,
    /// Edges used by one triangle only (a hole's rim).
    pub boundary_edges: usize,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: usize,
    /// Vertices whose triangles do not form one fan (two surfaces touching at a point).
    pub non_manifold_vertices: usize,
    /// Edges shared by two triangles that traverse it in the same direction (inconsistent
    /// orientation).
    pub misoriented_edges: usize,
    /// Triangles with a repeated vertex index.
    pub degenerate_triangles: usize,
    /// Connected pieces (triangles joined through shared vertices).
    pub components: usize,
}

impl Topology {
    /// No boundary edge: every edge is shared (closed surface). Also requires manifold edges.
    pub fn is_watertight(&self) -> bool {
        self.boundary_edges == 0 && self.non_manifold_edges == 0 && self.triangles > 0
    }

    /// Every edge has one or two triangles, every vertex one fan, no degenerate triangle.
    pub fn is_manifold(&self) -> bool {
        self.non_manifold_edges == 0
            && self.non_manifold_vertices == 0
            && self.degenerate_triangles == 0
    }

    /// Closed, manifold and consistently oriented: what a 3-D printer or a CAD import needs.
    pub fn is_watertight_manifold(&self) -> bool {
        self.is_watertight() && self.is_manifold() && self.misoriented_edges == 0
    }
}

/// Undirected edges with the number of triangles using each and how many of them traverse it
/// from the smaller to the larger index: `(a, b, uses, forward)` with `a < b`.
pub(crate) fn edge_uses(mesh: &TriangleMesh) -> Vec<(u32, u32, u32, u32)> {
    let mut all: Vec<(u32, u32, bool)> = Vec::with_capacity(mesh.triangles.len() * 3);
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a != b {
                all.push((a.min(b), a.max(b), a < b));
            }
        }
    }
    all.sort_unstable_by_key(|e| (e.0, e.1));
    let mut out = Vec::with_capacity(all.len() / 2 + 1);
    let mut i = 0;
    while i < all.len() {
        let (a, b) = (all[i].0, all[i].1);
        let (mut uses, mut fwd) = (0, 0);
        while i < all.len() && all[i].0 == a && all[i].1 == b {
            uses += 1;
            fwd += u32::from(all[i].2);
            i += 1;
        }
        out.push((a, b, uses, fwd));
    }
    out
}

/// A union-find over `n` items.
pub(crate) struct UnionFind(Vec<u32>);

impl UnionFind {
    pub(crate) fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }
    pub(crate) fn find(&mut self, mut i: u32) -> u32 {
        while self.0[i as usize] != i {
            let p = self.0[self.0[i as usize] as usize];
            self.0[i as usize] = p;
            i = p;
        }
        i
    }
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb) as usize] = ra.min(rb);
        }
    }
}

/// Checks the topology of a mesh. Triangle indices must be in range (as the readers and the
/// algorithms of this crate guarantee); out-of-range ones are counted as degenerate.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// // A tetrahedron: closed, manifold, oriented.
/// let mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0), Point3::new(0.0, 0.0, 1.0)],
///     triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
/// };
/// let t = sl_mesh::check_topology(&mesh);
/// assert!(t.is_watertight_manifold());
/// let open = TriangleMesh { vertices: mesh.vertices.clone(), triangles: mesh.triangles[..3].to_vec() };
/// assert_eq!(sl_mesh::check_topology(&open).boundary_edges, 3);
/// ```
pub fn check_topology(mesh: &TriangleMesh) -> Topology {
    let nv = mesh.vertices.len();
    let mut topo = Topology {
        vertices: nv,
        triangles: mesh.triangles.len(),
        ..Topology::default()
    };
    let valid: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .filter(|t| {
            let ok = t.iter().all(|&i| (i as usize) < nv)
                && t[0] != t[1]
                && t[1] != t[2]
                && t[0] != t[2];
            if !ok {
                topo.degenerate_triangles += 1;
            }
            ok
        })
        .copied()
        .collect();
    let clean = TriangleMesh {
        vertices: Vec::new(),
        triangles: valid,
    };
    for (_, _, uses, fwd) in edge_uses(&clean) {
        match uses {
            1 => topo.boundary_edges += 1,
            2 => {
                if fwd != 1 {
                    topo.misoriented_edges += 1;
                }
            }
            _ => topo.non_manifold_edges += 1,
        }
    }
    // Components and vertex fans.
    let mut uf = UnionFind::new(nv);
    for t in &clean.triangles {
        uf.union(t[0], t[1]);
        uf.union(t[1], t[2]);
    }
    let mut used = vec![false; nv];
    for t in &clean.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    topo.components = (0..nv as u32)
        .filter(|&i| used[i as usize] && uf.find(i) == i)
        .count();
    topo.non_manifold_vertices = count_non_manifold_vertices(&clean.triangles, nv);
    topo
}

/// Vertices whose link (the opposite edges of their triangles) is not one connected path or
/// cycle.
fn count_non_manifold_vertices(triangles: &[[u32; 3]], nv: usize) -> usize {
    let mut start = vec![0u32; nv + 1];
    for t in triangles {
        for &i in t {
            start[i as usize + 1] += 1;
        }
    }
    for i in 0..nv {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut inc = vec![0u32; start[nv] as usize];
    for (ti, t) in triangles.iter().enumerate() {
        for &i in t {
            inc[fill[i as usize] as usize] = ti as u32;
            fill[i as usize] += 1;
        }
    }
    let mut bad = 0;
    let mut local: Vec<u32> = Vec::new();
    let mut parent: Vec<usize> = Vec::new();
    for v in 0..nv {
        let tris = &inc[start[v] as usize..start[v + 1] as usize];
        if tris.len() <= 1 {
            continue;
        }
        local.clear();
        let mut link = Vec::with_capacity(tris.len());
        for &ti in tris {
            let t = triangles[ti as usize];
            let k = t.iter().position(|&i| i as usize == v).unwrap_or(0);
            let (b, c) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            link.push((b, c));
            local.push(b);
            local.push(c);
        }
        local.sort_unstable();
        local.dedup();
        parent.clear();
        parent.extend(0..local.len());
        let find = |parent: &mut Vec<usize>, mut i: usize| {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        };
        for (b, c) in link {
            let (Ok(ib), Ok(ic)) = (local.binary_search(&b), local.binary_search(&c)) else {
                continue;
            };
            let (rb, rc) = (find(&mut parent, ib), find(&mut parent, ic));
            parent[rb.max(rc)] = rb.min(rc);
        }
        let roots = (0..local.len())
            .filter(|&i| find(&mut parent, i) == i)
            .count();
        if roots > 1 {
            bad += 1;
        }
    }
    bad
}

/// Triangles of the largest connected piece (triangles joined through shared vertices); 0 for a
/// mesh without triangles. What [`remove_small_components`] keeps something of when it is at
/// least its `min_triangles`. Triangle indices must be in range.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// let p = |x: f64| Point3::new(x, 0.0, 0.0);
/// let mesh = TriangleMesh {
///     vertices: vec![p(0.0), p(1.0), Point3::new(0.0, 1.0, 0.0), p(5.0), p(6.0), Point3::new(5.0, 1.0, 0.0), Point3::new(6.0, 1.0, 0.0)],
///     triangles: vec![[0, 1, 2], [3, 4, 5], [4, 6, 5]],
/// };
/// assert_eq!(sl_mesh::largest_piece(&mesh), 2);
/// ```
pub fn largest_piece(mesh: &TriangleMesh) -> usize {
    let mut uf = UnionFind::new(mesh.vertices.len());
    for t in &mesh.triangles {
        uf.union(t[0], t[1]);
        uf.union(t[1], t[2]);
    }
    let mut size = vec![0usize; mesh.vertices.len()];
    for t in &mesh.triangles {
        size[uf.find(t[0]) as usize] += 1;
    }
    size.into_iter().max().unwrap_or(0)
}

/// Removes the connected pieces with fewer than `min_triangles` triangles (the specks a
/// reconstruction leaves around outliers), and the vertices no triangle uses. Returns the number
/// of pieces removed.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// let p = |x: f64| Point3::new(x, 0.0, 0.0);
/// let mut mesh = TriangleMesh {
///     vertices: vec![p(0.0), p(1.0), Point3::new(0.0, 1.0, 0.0), p(5.0), p(6.0), Point3::new(5.0, 1.0, 0.0), Point3::new(6.0, 1.0, 0.0)],
///     triangles: vec![[0, 1, 2], [3, 4, 5], [4, 6, 5]],
/// };
/// assert_eq!(sl_mesh::remove_small_components(&mut mesh, 2), 1);
/// assert_eq!(mesh.triangles.len(), 2);
/// assert_eq!(mesh.vertices.len(), 4);
/// ```
pub fn remove_small_components(mesh: &mut TriangleMesh, min_triangles: usize) -> usize {
    let nv = mesh.vertices.len();
    let mut uf = UnionFind::new(nv);
    for t in &mesh.triangles {
        uf.union(t[0], t[1]);
        uf.union(t[1], t[2]);
    }
    let mut size = vec![0usize; nv];
    for t in &mesh.triangles {
        size[uf.find(t[0]) as usize] += 1;
    }
    let removed = size.iter().filter(|&&s| s > 0 && s < min_triangles).count();
    let keep: Vec<bool> = mesh
        .triangles
        .iter()
        .map(|t| size[uf.find(t[0]) as usize] >= min_triangles)
        .collect();
    let mut k = keep.iter();
    mesh.triangles.retain(|_| *k.next().unwrap_or(&false));
    compact_vertices(mesh);
    removed
}

/// Drops the vertices no triangle uses, renumbering the triangles. Returns the old index of
/// each kept vertex.
pub fn compact_vertices(mesh: &mut TriangleMesh) -> Vec<u32> {
    let mut new_id = vec![u32::MAX; mesh.vertices.len()];
    let mut old = Vec::new();
    for t in &mut mesh.triangles {
        for i in t.iter_mut() {
            if new_id[*i as usize] == u32::MAX {
                new_id[*i as usize] = old.len() as u32;
                old.push(*i);
            }
            *i = new_id[*i as usize];
        }
    }
    mesh.vertices = old.iter().map(|&i| mesh.vertices[i as usize]).collect();
    old
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    fn tetra() -> TriangleMesh {
        TriangleMesh {
            vertices: vec![
                Point3::origin(),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn closed_tetrahedron_is_watertight_manifold() {
        let t = check_topology(&tetra());
        assert!(t.is_watertight_manifold(), "{t:?}");
        assert_eq!(t.components, 1);
    }

    #[test]
    fn defects_are_counted() {
        // A flipped face: three edges traversed twice the same way.
        let mut m = tetra();
        m.triangles[3] = [1, 3, 2];
        let t = check_topology(&m);
        assert_eq!(t.misoriented_edges, 3);
        assert!(t.is_watertight() && !t.is_watertight_manifold());
        // A fin: a third triangle on edge 0-1.
        let mut m = tetra();
        m.vertices.push(Point3::new(0.5, -1.0, 0.0));
        m.triangles.push([0, 1, 4]);
        let t = check_topology(&m);
        assert_eq!(t.non_manifold_edges, 1);
        assert!(!t.is_manifold() && !t.is_watertight());
        // Two tetrahedra sharing one vertex: a non-manifold vertex, one piece.
        let mut m = tetra();
        let off = nalgebra::Vector3::new(-1.0, -1.0, -1.0);
        for k in 1..4 {
            let p = m.vertices[k] + off * 2.0;
            m.vertices.push(p);
        }
        m.triangles
            .extend([[0, 5, 4], [0, 4, 6], [0, 6, 5], [4, 5, 6]]);
        let t = check_topology(&m);
        assert_eq!(t.non_manifold_vertices, 1, "{t:?}");
        assert_eq!(t.components, 1);
        assert!(!t.is_manifold());
        // A degenerate triangle.
        let mut m = tetra();
        m.triangles.push([1, 1, 2]);
        assert_eq!(check_topology(&m).degenerate_triangles, 1);
    }

    #[test]
    fn compact_drops_unused_vertices() {
        let mut m = tetra();
        m.vertices.insert(0, Point3::new(9.0, 9.0, 9.0));
        for t in &mut m.triangles {
            for i in t.iter_mut() {
                *i += 1;
            }
        }
        let old = compact_vertices(&mut m);
        assert_eq!(m.vertices.len(), 4);
        assert!(!old.contains(&0));
        assert!(check_topology(&m).is_watertight_manifold());
    }
}
