//! Isotropic remeshing: triangles of one edge length, every vertex standing for the same area.
//!
//! The incremental remeshing of Botsch & Kobbelt ("A remeshing approach to multiresolution
//! modeling", SGP 2004), repeated a few times: split the edges longer than `4/3 L`, collapse
//! those shorter than `4/5 L` (when no edge longer than `4/3 L` results, the link condition
//! holds and no triangle folds over), flip edges where that brings the valences closer to 6,
//! move each vertex towards the mean of its neighbours within its tangent plane, and put it
//! back on the surface: the closest point of the mesh given (a bounding-volume hierarchy of
//! `parry3d-f64`, the ray casting and distance crate of the workspace).
//!
//! Why a mesh needs it after an error-bounded simplification: that keeps vertices where the
//! surface bends or is rough and few where it is flat, so a figure over the vertices (the RMS
//! of their distances to a truth, a mesh-to-cloud comparison in CloudCompare) weighs the
//! surface unevenly. On the default scan the error of the cloud itself is a calibration
//! displacement of about 0.1 mm that varies over each sphere; the simplified mesh is
//! 0.0634 mm from the truth over its area but 0.066 mm at its vertices, which sit where that
//! displacement is larger (docs/meshing.md, "Figures"). Remeshed, the vertices sample the
//! surface evenly and the two agree. Even triangles are also what finite-element solvers,
//! slicers and subdivision want.
//!
//! Edges with other than two triangles (a boundary, a non-manifold place) and their vertices
//! stay as they are; a closed manifold mesh stays closed and manifold.

use nalgebra::{Point3, Vector3};
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::TriMesh;
use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::check_indices;
use crate::measure::surface_area;

/// Most vertices a remeshing may aim at: a target edge far below the mesh's scale (a typo in
/// the units) is an error rather than an attempt to allocate gigabytes.
const MAX_TARGET_VERTICES: f64 = 2e7;

/// Parameters of [`remesh_isotropic`].
#[derive(Debug, Clone, PartialEq)]
pub struct RemeshConfig {
    /// Target edge length `L`, in the mesh's units; 0 chooses the length that keeps the
    /// number of vertices (`L = sqrt(2 A / (√3 N))` for area `A` and `N` vertices).
    pub target_edge: f64,
    /// Rounds of split, collapse, flip, relax and project. 5: the edge lengths and valences
    /// settle by then on the default scan (docs/meshing.md).
    pub iterations: usize,
}

impl Default for RemeshConfig {
    fn default() -> Self {
        Self {
            target_edge: 0.0,
            iterations: 5,
        }
    }
}

/// What [`remesh_isotropic`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Remeshing {
    /// The edge length aimed at.
    pub target_edge: f64,
    /// Vertices before and after.
    pub vertices_before: usize,
    /// Vertices after.
    pub vertices_after: usize,
    /// Triangles after.
    pub triangles_after: usize,
    /// Edges split, collapsed and flipped over all rounds.
    pub splits: usize,
    /// Edges collapsed.
    pub collapses: usize,
    /// Edges flipped.
    pub flips: usize,
    /// The RMS and the largest distance of the final vertices from the surface given (those
    /// that could be projected), in the mesh's units.
    pub rms_distance: f64,
    /// Largest such distance.
    pub largest_distance: f64,
}

/// Remeshes `mesh` in place to triangles of edge length about `cfg.target_edge` whose
/// vertices lie on the surface given (see the module documentation).
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a target edge that is negative, not finite, or so small
/// that more than 20 million vertices would result; [`MeshError::InvalidMesh`] for a triangle
/// index out of range.
///
/// ```
/// use sl_mesh::{RemeshConfig, TriangleMesh, remesh_isotropic};
/// # use nalgebra::Point3;
/// // A square of two triangles, remeshed to edges of about 0.25.
/// let mut mesh = TriangleMesh {
///     vertices: vec![
///         Point3::new(0.0, 0.0, 0.0),
///         Point3::new(1.0, 0.0, 0.0),
///         Point3::new(1.0, 1.0, 0.0),
///         Point3::new(0.0, 1.0, 0.0),
///     ],
///     triangles: vec![[0, 1, 2], [0, 2, 3]],
/// };
/// let cfg = RemeshConfig { target_edge: 0.25, ..RemeshConfig::default() };
/// let r = remesh_isotropic(&mut mesh, &cfg)?;
/// assert!(r.splits > 0 && mesh.triangles.len() > 2);
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn remesh_isotropic(
    mesh: &mut TriangleMesh,
    cfg: &RemeshConfig,
) -> Result<Remeshing, MeshError> {
    check_indices(mesh)?;
    let invalid = |reason| MeshError::InvalidParameter {
        parameter: "target_edge",
        value: cfg.target_edge.to_string(),
        reason,
    };
    if !cfg.target_edge.is_finite() || cfg.target_edge < 0.0 {
        return Err(invalid("must be a length ≥ 0 (0: keep the number of vertices)"));
    }
    let vertices_before = mesh.vertices.len();
    let area = surface_area(mesh);
    let target_edge = if cfg.target_edge > 0.0 {
        cfg.target_edge
    } else if vertices_before > 0 && area > 0.0 {
        (2.0 * area / (3f64.sqrt() * vertices_before as f64)).sqrt()
    } else {
        0.0
    };
    let unchanged = Remeshing {
        target_edge,
        vertices_before,
        vertices_after: vertices_before,
        triangles_after: mesh.triangles.len(),
        splits: 0,
        collapses: 0,
        flips: 0,
        rms_distance: 0.0,
        largest_distance: 0.0,
    };
    if target_edge <= 0.0 || mesh.triangles.is_empty() || cfg.iterations == 0 {
        return Ok(unchanged);
    }
    if area / (3f64.sqrt() / 2.0 * target_edge * target_edge) > MAX_TARGET_VERTICES {
        return Err(invalid(
            "would make more than 20 million vertices of the mesh's area (check the units)",
        ));
    }
    // The surface the vertices are put back on: the mesh as given, without its degenerate
    // triangles (parry drops nothing itself, and a zero-area triangle has no normal).
    let reference_triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .copied()
        .filter(|t| triangle_normal(&mesh.vertices, t).norm() > 0.0)
        .collect();
    let Ok(reference) = TriMesh::new(mesh.vertices.clone(), reference_triangles) else {
        return Ok(unchanged);
    };
    let mut work = Work::new(mesh);
    let (lo, hi) = (0.8 * target_edge, 4.0 / 3.0 * target_edge);
    let (mut splits, mut collapses, mut flips) = (0, 0, 0);
    let mut distances = Vec::new();
    for _ in 0..cfg.iterations {
        splits += work.split_long(hi);
        collapses += work.collapse_short(lo, hi);
        flips += work.flip_to_valence_six();
        work.relax_tangentially();
        distances = work.project(&reference, target_edge);
    }
    *mesh = work.into_mesh();
    let rms_distance = if distances.is_empty() {
        0.0
    } else {
        (distances.iter().map(|d| d * d).sum::<f64>() / distances.len() as f64).sqrt()
    };
    Ok(Remeshing {
        target_edge,
        vertices_before,
        vertices_after: mesh.vertices.len(),
        triangles_after: mesh.triangles.len(),
        splits,
        collapses,
        flips,
        rms_distance,
        largest_distance: distances.iter().copied().fold(0.0, f64::max),
    })
}

fn triangle_normal(pos: &[Point3<f64>], t: &[u32; 3]) -> Vector3<f64> {
    let p = t.map(|i| pos[i as usize]);
    (p[1] - p[0]).cross(&(p[2] - p[0]))
}

/// The mesh being remeshed: triangles with the triangles of each vertex, so that an edge's
/// two triangles and a vertex's ring are found without a half-edge structure.
struct Work {
    pos: Vec<Point3<f64>>,
    tris: Vec<[u32; 3]>,
    alive: Vec<bool>,
    /// Alive triangles of each vertex.
    vt: Vec<Vec<u32>>,
    /// Vertices on a boundary, a non-manifold edge or a degenerate triangle: never moved, and
    /// no edge of theirs is collapsed or flipped.
    locked: Vec<bool>,
    /// Vertices merged away by a collapse.
    dead: Vec<bool>,
}

impl Work {
    fn new(mesh: &TriangleMesh) -> Self {
        let nv = mesh.vertices.len();
        let mut vt = vec![Vec::new(); nv];
        let mut locked = vec![false; nv];
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 3);
        for (i, t) in mesh.triangles.iter().enumerate() {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                for &v in t {
                    locked[v as usize] = true;
                }
            }
            for k in 0..3 {
                vt[t[k] as usize].push(i as u32);
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.push((a.min(b), a.max(b)));
            }
        }
        edges.sort_unstable();
        let mut i = 0;
        while i < edges.len() {
            let mut j = i;
            while j < edges.len() && edges[j] == edges[i] {
                j += 1;
            }
            if j - i != 2 {
                locked[edges[i].0 as usize] = true;
                locked[edges[i].1 as usize] = true;
            }
            i = j;
        }
        // A vertex whose triangles do not form one closed fan (two cones meeting at a point)
        // is non-manifold although each of its edges has two triangles.
        for v in 0..nv {
            if !locked[v] && !single_fan(&mesh.triangles, &vt[v], v as u32) {
                locked[v] = true;
            }
        }
        Self {
            pos: mesh.vertices.clone(),
            tris: mesh.triangles.clone(),
            alive: vec![true; mesh.triangles.len()],
            vt,
            locked,
            dead: vec![false; nv],
        }
    }

    /// The alive triangles holding edge `ab`.
    fn edge_triangles(&self, a: u32, b: u32) -> Vec<u32> {
        self.vt[a as usize]
            .iter()
            .copied()
            .filter(|&t| self.tris[t as usize].contains(&b))
            .collect()
    }

    /// The vertices joined to `v` by an edge.
    fn ring(&self, v: u32) -> Vec<u32> {
        let mut r: Vec<u32> = self.vt[v as usize]
            .iter()
            .flat_map(|&t| self.tris[t as usize])
            .filter(|&u| u != v)
            .collect();
        r.sort_unstable();
        r.dedup();
        r
    }

    /// The undirected edges of the alive triangles, each once.
    fn edges(&self) -> Vec<(u32, u32)> {
        let mut e: Vec<(u32, u32)> = Vec::with_capacity(self.tris.len() * 3);
        for (t, tri) in self.tris.iter().enumerate() {
            if self.alive[t] {
                for k in 0..3 {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    e.push((a.min(b), a.max(b)));
                }
            }
        }
        e.sort_unstable();
        e.dedup();
        e
    }

    fn len(&self, a: u32, b: u32) -> f64 {
        (self.pos[a as usize] - self.pos[b as usize]).norm()
    }

    /// `tri` rotated so that it starts with the directed edge `a → b`, if it has it.
    fn starting_with(tri: [u32; 3], a: u32, b: u32) -> Option<[u32; 3]> {
        (0..3)
            .map(|k| [tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]])
            .find(|r| r[0] == a && r[1] == b)
    }

    /// Splits every edge longer than `hi` (with two triangles) at its midpoint.
    fn split_long(&mut self, hi: f64) -> usize {
        let mut long: Vec<(f64, u32, u32)> = self
            .edges()
            .into_iter()
            .map(|(a, b)| (self.len(a, b), a, b))
            .filter(|e| e.0 > hi)
            .collect();
        long.sort_unstable_by(|x, y| y.0.total_cmp(&x.0));
        let mut count = 0;
        for (_, a, b) in long {
            let ts = self.edge_triangles(a, b);
            if ts.len() != 2 || self.len(a, b) <= hi {
                continue;
            }
            let m = self.pos.len() as u32;
            self.pos
                .push(nalgebra::center(&self.pos[a as usize], &self.pos[b as usize]));
            self.vt.push(Vec::new());
            self.locked.push(false);
            self.dead.push(false);
            for t in ts {
                let tri = self.tris[t as usize];
                let [u, w, c] = Self::starting_with(tri, a, b)
                    .or_else(|| Self::starting_with(tri, b, a))
                    .expect("an edge's triangle holds it in one direction");
                let new = self.tris.len() as u32;
                self.tris[t as usize] = [u, m, c];
                self.tris.push([m, w, c]);
                self.alive.push(true);
                let vw = &mut self.vt[w as usize];
                if let Some(slot) = vw.iter_mut().find(|x| **x == t) {
                    *slot = new;
                }
                self.vt[c as usize].push(new);
                self.vt[m as usize].extend([t, new]);
            }
            count += 1;
        }
        count
    }

    /// Collapses every edge shorter than `lo` to its midpoint where that leaves no edge longer
    /// than `hi`, keeps the mesh manifold (the link condition: the two ends share exactly the
    /// two vertices opposite the edge, each of which keeps three or more edges) and folds no
    /// triangle over.
    fn collapse_short(&mut self, lo: f64, hi: f64) -> usize {
        let mut short: Vec<(f64, u32, u32)> = self
            .edges()
            .into_iter()
            .map(|(a, b)| (self.len(a, b), a, b))
            .filter(|e| e.0 < lo)
            .collect();
        short.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
        let mut count = 0;
        for (_, a, b) in short {
            let (ai, bi) = (a as usize, b as usize);
            if self.dead[ai] || self.dead[bi] || self.locked[ai] || self.locked[bi] {
                continue;
            }
            let ts = self.edge_triangles(a, b);
            if ts.len() != 2 || self.len(a, b) >= lo {
                continue;
            }
            let opposite: Vec<u32> = ts
                .iter()
                .map(|&t| {
                    self.tris[t as usize]
                        .into_iter()
                        .find(|&v| v != a && v != b)
                        .expect("a triangle of an edge has a third vertex")
                })
                .collect();
            if opposite[0] == opposite[1] {
                continue;
            }
            let (ra, rb) = (self.ring(a), self.ring(b));
            let shared = ra.iter().filter(|v| rb.binary_search(v).is_ok()).count();
            if shared != 2
                || opposite
                    .iter()
                    .any(|&c| self.vt[c as usize].len() <= 3 || self.locked[c as usize])
                || ra.len() + rb.len() < 8
            {
                continue;
            }
            let p = nalgebra::center(&self.pos[ai], &self.pos[bi]);
            if ra
                .iter()
                .chain(&rb)
                .any(|&v| v != a && v != b && (self.pos[v as usize] - p).norm() > hi)
            {
                continue;
            }
            let folds = self.vt[ai].iter().chain(&self.vt[bi]).any(|&t| {
                if ts.contains(&t) {
                    return false;
                }
                let tri = self.tris[t as usize];
                let before = triangle_normal(&self.pos, &tri);
                let moved = tri.map(|v| {
                    if v == a || v == b {
                        p
                    } else {
                        self.pos[v as usize]
                    }
                });
                let after = (moved[1] - moved[0]).cross(&(moved[2] - moved[0]));
                after.dot(&before) <= 0.2 * before.norm() * after.norm()
            });
            if folds {
                continue;
            }
            for &t in &ts {
                self.alive[t as usize] = false;
                for v in self.tris[t as usize] {
                    self.vt[v as usize].retain(|&x| x != t);
                }
            }
            let moved: Vec<u32> = std::mem::take(&mut self.vt[ai]);
            for &t in &moved {
                for v in self.tris[t as usize].iter_mut() {
                    if *v == a {
                        *v = b;
                    }
                }
            }
            self.vt[bi].extend(moved);
            self.pos[bi] = p;
            self.dead[ai] = true;
            count += 1;
        }
        count
    }

    /// Flips every edge whose flip brings the valences of its four vertices closer to 6 and
    /// leaves both triangles facing the way the two before did.
    fn flip_to_valence_six(&mut self) -> usize {
        let mut count = 0;
        for (a, b) in self.edges() {
            if self.locked[a as usize] || self.locked[b as usize] {
                continue;
            }
            let ts = self.edge_triangles(a, b);
            if ts.len() != 2 {
                continue;
            }
            // t1 = (a, b, c) and t2 = (b, a, d), oriented alike.
            let (mut t1, mut t2) = (ts[0], ts[1]);
            let Some(r1) = Self::starting_with(self.tris[t1 as usize], a, b).or_else(|| {
                std::mem::swap(&mut t1, &mut t2);
                Self::starting_with(self.tris[t1 as usize], a, b)
            }) else {
                continue;
            };
            let Some(r2) = Self::starting_with(self.tris[t2 as usize], b, a) else {
                continue;
            };
            let (c, d) = (r1[2], r2[2]);
            if c == d || self.ring(c).binary_search(&d).is_ok() {
                continue;
            }
            let valence = |v: u32| self.vt[v as usize].len() as i64;
            let deviation = |va: i64, vb: i64, vc: i64, vd: i64| {
                (va - 6).abs() + (vb - 6).abs() + (vc - 6).abs() + (vd - 6).abs()
            };
            let (va, vb, vc, vd) = (valence(a), valence(b), valence(c), valence(d));
            if va <= 3 || vb <= 3 || deviation(va - 1, vb - 1, vc + 1, vd + 1) >= deviation(va, vb, vc, vd)
            {
                continue;
            }
            let (new1, new2) = ([a, d, c], [d, b, c]);
            let old = triangle_normal(&self.pos, &r1) + triangle_normal(&self.pos, &r2);
            let (n1, n2) = (
                triangle_normal(&self.pos, &new1),
                triangle_normal(&self.pos, &new2),
            );
            let agrees = |n: &Vector3<f64>| n.dot(&old) > 0.5 * n.norm() * old.norm();
            if !agrees(&n1) || !agrees(&n2) || n1.dot(&n2) <= 0.5 * n1.norm() * n2.norm() {
                continue;
            }
            self.tris[t1 as usize] = new1;
            self.tris[t2 as usize] = new2;
            self.vt[a as usize].retain(|&x| x != t2);
            self.vt[b as usize].retain(|&x| x != t1);
            self.vt[c as usize].push(t2);
            self.vt[d as usize].push(t1);
            count += 1;
        }
        count
    }

    fn vertex_normal(&self, v: usize) -> Vector3<f64> {
        self.vt[v]
            .iter()
            .map(|&t| triangle_normal(&self.pos, &self.tris[t as usize]))
            .sum::<Vector3<f64>>()
    }

    /// Moves every free vertex towards the mean of its neighbours, within its tangent plane.
    fn relax_tangentially(&mut self) {
        let moved: Vec<Option<Point3<f64>>> = (0..self.pos.len())
            .map(|v| {
                if self.dead[v] || self.locked[v] || self.vt[v].is_empty() {
                    return None;
                }
                let ring = self.ring(v as u32);
                let mean = ring
                    .iter()
                    .map(|&u| self.pos[u as usize].coords)
                    .sum::<Vector3<f64>>()
                    / ring.len() as f64;
                let n = self.vertex_normal(v).try_normalize(0.0)?;
                let d = mean - self.pos[v].coords;
                Some(self.pos[v] + (d - n * n.dot(&d)))
            })
            .collect();
        for (v, p) in moved.into_iter().enumerate() {
            if let Some(p) = p {
                self.pos[v] = p;
            }
        }
    }

    /// Puts every free vertex on the closest point of `reference` facing the same way (within
    /// `reach`); returns the distances moved.
    fn project(&mut self, reference: &TriMesh, reach: f64) -> Vec<f64> {
        let mut distances = Vec::new();
        for v in 0..self.pos.len() {
            if self.dead[v] || self.locked[v] || self.vt[v].is_empty() {
                continue;
            }
            let p = self.pos[v];
            let Some((proj, (part, _))) =
                reference.project_local_point_and_get_location_with_max_dist(&p, false, reach)
            else {
                continue;
            };
            let facing = reference.triangle(part).scaled_normal();
            if facing.dot(&self.vertex_normal(v)) <= 0.0 {
                continue;
            }
            distances.push((proj.point - p).norm());
            self.pos[v] = proj.point;
        }
        distances
    }

    /// The remeshed mesh: alive triangles, the vertices they use renumbered in order.
    fn into_mesh(self) -> TriangleMesh {
        let mut index = vec![u32::MAX; self.pos.len()];
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for (t, tri) in self.tris.iter().enumerate() {
            if !self.alive[t] {
                continue;
            }
            triangles.push(tri.map(|v| {
                let v = v as usize;
                if index[v] == u32::MAX {
                    index[v] = vertices.len() as u32;
                    vertices.push(self.pos[v]);
                }
                index[v]
            }));
        }
        TriangleMesh {
            vertices,
            triangles,
        }
    }
}

/// Whether the triangles `star` of vertex `v` form one fan (closed or open) around it.
fn single_fan(tris: &[[u32; 3]], star: &[u32], v: u32) -> bool {
    if star.is_empty() {
        return true;
    }
    // Each triangle of the star is the edge (next, previous) of the ring around v.
    let spokes: Vec<(u32, u32)> = star
        .iter()
        .filter_map(|&t| {
            let r = (0..3)
                .map(|k| {
                    let tri = tris[t as usize];
                    [tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]]
                })
                .find(|r| r[0] == v)?;
            Some((r[1], r[2]))
        })
        .collect();
    // Walk from the first spoke: a single fan visits all of them.
    let mut visited = vec![false; spokes.len()];
    visited[0] = true;
    let mut at = spokes[0].1;
    let mut walked = 1;
    while let Some(k) = spokes
        .iter()
        .enumerate()
        .position(|(k, s)| !visited[k] && s.0 == at)
    {
        visited[k] = true;
        at = spokes[k].1;
        walked += 1;
    }
    let mut at = spokes[0].0;
    while let Some(k) = spokes
        .iter()
        .enumerate()
        .position(|(k, s)| !visited[k] && s.1 == at)
    {
        visited[k] = true;
        at = spokes[k].0;
        walked += 1;
    }
    walked == spokes.len()
}
