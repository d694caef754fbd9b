//! Fairing of the surface a reconstruction invents where the scanner saw nothing.
//!
//! A closed reconstruction must close what no view saw (the lower back of an object on a
//! turntable). Poisson's indicator spans such a hole as a membrane: the harmonic answer, which
//! sags into a curved object (docs/meshing.md, "Figures"). Here the vertices of that surface
//! (sampling density below a fraction of the median, the rule of
//! [`trim_by_density`](crate::trim_by_density)) are moved to minimise the thin-plate energy
//! `Σ_i A_i |Δx_i|²` (`Δ` the cotangent Laplace–Beltrami operator of the mesh, `A_i` the
//! vertex areas) with every supported vertex fixed: the bi-Laplacian fairing of hole filling
//! (Liepa 2003; Botsch & Kobbelt 2004). The two rings of fixed vertices around the hole fix
//! position and tangent plane on its rim, so the patch continues the curvature of the scanned
//! surface instead of spanning it flat. The connectivity is not changed: a closed manifold
//! stays closed and manifold.
//!
//! The system is solved by conjugate gradients on the unsupported vertices only (their
//! operator is applied through the two rings around them). Run it on a simplified mesh
//! ([`simplify`](crate::simplify) leaves few vertices on that surface): the condition of the
//! bi-Laplacian grows with the fourth power of the hole's width in vertices.

use nalgebra::{Point3, Vector3};
use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::check_indices;

/// Parameters of [`fair_unsupported`].
#[derive(Debug, Clone, PartialEq)]
pub struct FairConfig {
    /// A vertex whose sampling density is below this fraction of the median density of the
    /// vertices is free to move. 0.3: three times `trim_by_density`'s and `simplify`'s 0.1,
    /// so that the thinly sampled rim of a gap, where Poisson's membrane already sags, moves
    /// too (on the default scan the closing surface's RMS over its vertices is 0.335 mm with
    /// 0.1, 0.173 mm with 0.3, 0.166 mm with 0.5; docs/meshing.md).
    pub support_ratio: f64,
    /// Most conjugate-gradient iterations.
    pub max_iterations: usize,
    /// Relative residual at which the iterations stop.
    pub tolerance: f64,
}

impl Default for FairConfig {
    fn default() -> Self {
        Self {
            support_ratio: 0.3,
            max_iterations: 5000,
            tolerance: 1e-10,
        }
    }
}

/// What [`fair_unsupported`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Fairing {
    /// Vertices moved (the unsupported ones not on a rim or a non-manifold place).
    pub vertices_moved: usize,
    /// The largest distance a vertex moved, in the mesh's units.
    pub largest_move: f64,
    /// Conjugate-gradient iterations made.
    pub iterations: usize,
    /// Relative residual reached.
    pub residual: f64,
}

/// Moves the vertices of `mesh` whose density is below `cfg.support_ratio` times the median
/// of `densities` (one per vertex: [`PoissonSurface::densities`](crate::PoissonSurface) or
/// [`Simplification::densities`](crate::Simplification)) to the thin-plate surface spanned by
/// the others (see the module documentation). Vertices on a boundary edge stay where they are.
/// A mesh without unsupported vertices is left unchanged.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a ratio outside `[0, 1)`, no iterations or a
/// non-positive tolerance; [`MeshError::InvalidMesh`] for a triangle index out of range or a
/// density count that is not the vertex count.
///
/// ```
/// use sl_mesh::{FairConfig, fair_unsupported};
/// # let mut mesh = sl_cloud::TriangleMesh::default();
/// let done = fair_unsupported(&mut mesh, &[], &FairConfig::default())?;
/// assert_eq!(done.vertices_moved, 0);
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn fair_unsupported(
    mesh: &mut TriangleMesh,
    densities: &[f64],
    cfg: &FairConfig,
) -> Result<Fairing, MeshError> {
    if !(0.0..1.0).contains(&cfg.support_ratio) {
        return Err(MeshError::invalid(
            "support_ratio",
            cfg.support_ratio,
            "must be in [0, 1): a fraction of the median sampling density",
        ));
    }
    if cfg.max_iterations == 0 {
        return Err(MeshError::invalid(
            "max_iterations",
            0.0,
            "must be at least 1",
        ));
    }
    if !(cfg.tolerance.is_finite() && cfg.tolerance > 0.0) {
        return Err(MeshError::invalid(
            "tolerance",
            cfg.tolerance,
            "must be a finite relative residual > 0",
        ));
    }
    check_indices(mesh)?;
    let nv = mesh.vertices.len();
    if densities.len() != nv {
        return Err(MeshError::InvalidMesh(format!(
            "{} densities for {nv} vertices",
            densities.len()
        )));
    }
    let unchanged = Fairing {
        vertices_moved: 0,
        largest_move: 0.0,
        iterations: 0,
        residual: 0.0,
    };
    if nv == 0 {
        return Ok(unchanged);
    }
    let threshold = cfg.support_ratio * crate::trim::median_density(densities);

    let op = Operator::new(mesh);
    let free: Vec<bool> = (0..nv)
        .map(|v| densities[v] < threshold && !op.boundary[v])
        .collect();
    let free_ids: Vec<usize> = (0..nv).filter(|&v| free[v]).collect();
    if free_ids.is_empty() {
        return Ok(unchanged);
    }
    // Every vertex the operator reaches from a free one (two rings).
    let mut active = vec![false; nv];
    for &v in &free_ids {
        active[v] = true;
        for &a in op.ring(v) {
            active[a as usize] = true;
            for &b in op.ring(a as usize) {
                active[b as usize] = true;
            }
        }
    }
    let active_ids: Vec<usize> = (0..nv).filter(|&v| active[v]).collect();

    // b = −K x_C on the free rows (the fixed vertices' pull), K = L M⁻¹ L.
    let mut fixed_part: Vec<Vector3<f64>> = vec![Vector3::zeros(); nv];
    for &v in &active_ids {
        if !free[v] {
            fixed_part[v] = mesh.vertices[v].coords;
        }
    }
    let mut scratch = vec![Vector3::zeros(); nv];
    let mut out = vec![Vector3::zeros(); nv];
    op.apply(&fixed_part, &active_ids, &mut scratch, &mut out);
    let b: Vec<Vector3<f64>> = free_ids.iter().map(|&v| -out[v]).collect();

    // Conjugate gradients on the free vertices, from where they are (the membrane).
    let mut x: Vec<Vector3<f64>> = free_ids.iter().map(|&v| mesh.vertices[v].coords).collect();
    let mut full = vec![Vector3::zeros(); nv];
    let mut k_of = |p: &[Vector3<f64>], full: &mut Vec<Vector3<f64>>| -> Vec<Vector3<f64>> {
        for (i, &v) in free_ids.iter().enumerate() {
            full[v] = p[i];
        }
        op.apply(full, &active_ids, &mut scratch, &mut out);
        free_ids.iter().map(|&v| out[v]).collect()
    };
    // Jacobi preconditioner: the diagonal of K, Σ_j L_ji² / M_j (the simplified mesh's cells
    // differ in size by orders of magnitude, which plain CG pays for in iterations).
    let diag: Vec<f64> = free_ids
        .iter()
        .map(|&v| {
            let own = if op.area[v] > 0.0 {
                op.diagonal[v] * op.diagonal[v] / op.area[v]
            } else {
                0.0
            };
            let ring: f64 = (op.start[v]..op.start[v + 1])
                .map(|k| {
                    let j = op.ring[k] as usize;
                    if op.area[j] > 0.0 {
                        op.weight[k] * op.weight[k] / op.area[j]
                    } else {
                        0.0
                    }
                })
                .sum();
            let d = own + ring;
            if d > 0.0 { 1.0 / d } else { 1.0 }
        })
        .collect();
    let kx = k_of(&x, &mut full);
    let mut r: Vec<Vector3<f64>> = b.iter().zip(&kx).map(|(b, k)| b - k).collect();
    let mut z: Vec<Vector3<f64>> = r.iter().zip(&diag).map(|(r, d)| r * *d).collect();
    let mut p = z.clone();
    let dot = |a: &[Vector3<f64>], b: &[Vector3<f64>]| -> Vector3<f64> {
        a.iter()
            .zip(b)
            .fold(Vector3::zeros(), |s, (a, b)| s + a.component_mul(b))
    };
    let b_norm = dot(&b, &b).sum().sqrt().max(f64::MIN_POSITIVE);
    let mut rz = dot(&r, &z);
    let mut r_norm = dot(&r, &r).sum().sqrt();
    let mut iterations = 0;
    while iterations < cfg.max_iterations && r_norm > cfg.tolerance * b_norm {
        let kp = k_of(&p, &mut full);
        let pkp = dot(&p, &kp);
        // The three coordinates are three independent systems with the same matrix.
        let alpha = Vector3::from_fn(|c, _| if pkp[c] > 0.0 { rz[c] / pkp[c] } else { 0.0 });
        for i in 0..x.len() {
            x[i] += p[i].component_mul(&alpha);
            r[i] -= kp[i].component_mul(&alpha);
            z[i] = r[i] * diag[i];
        }
        let rz_new = dot(&r, &z);
        let beta = Vector3::from_fn(|c, _| if rz[c] > 0.0 { rz_new[c] / rz[c] } else { 0.0 });
        for i in 0..p.len() {
            p[i] = z[i] + p[i].component_mul(&beta);
        }
        rz = rz_new;
        r_norm = dot(&r, &r).sum().sqrt();
        iterations += 1;
    }
    let mut largest_move: f64 = 0.0;
    for (i, &v) in free_ids.iter().enumerate() {
        largest_move = largest_move.max((x[i] - mesh.vertices[v].coords).norm());
        mesh.vertices[v] = Point3::from(x[i]);
    }
    Ok(Fairing {
        vertices_moved: free_ids.len(),
        largest_move,
        iterations,
        residual: r_norm / b_norm,
    })
}

/// The cotangent Laplacian `L` (symmetric, `L_ii = Σ_j w_ij`, `L_ij = −w_ij`) and the
/// barycentric vertex areas `M` of a mesh, in compressed rows.
struct Operator {
    start: Vec<usize>,
    ring: Vec<u32>,
    weight: Vec<f64>,
    diagonal: Vec<f64>,
    area: Vec<f64>,
    boundary: Vec<bool>,
}

impl Operator {
    fn new(mesh: &TriangleMesh) -> Self {
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
        Self {
            start,
            ring,
            weight,
            diagonal,
            area,
            boundary,
        }
    }

    fn ring(&self, v: usize) -> &[u32] {
        &self.ring[self.start[v]..self.start[v + 1]]
    }

    /// `L x` at vertex `v`.
    fn laplace(&self, x: &[Vector3<f64>], v: usize) -> Vector3<f64> {
        let mut s = x[v] * self.diagonal[v];
        for k in self.start[v]..self.start[v + 1] {
            s -= x[self.ring[k] as usize] * self.weight[k];
        }
        s
    }

    /// `out = L M⁻¹ L x` on `active` (the free vertices and their two rings; `x` must be zero
    /// elsewhere where it matters); `scratch` holds `M⁻¹ L x`.
    fn apply(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_shapes::{partial_sphere_cloud, sphere_mesh};
    use crate::{PoissonConfig, SimplifyConfig, check_topology, poisson_reconstruct, simplify};

    /// RMS of `|p| − r` over the vertices with `z > z_min`.
    fn cap_rms(mesh: &TriangleMesh, r: f64, z_min: f64) -> (f64, usize) {
        let e: Vec<f64> = mesh
            .vertices
            .iter()
            .filter(|p| p.z > z_min)
            .map(|p| p.coords.norm() - r)
            .collect();
        (
            (e.iter().map(|e| e * e).sum::<f64>() / e.len() as f64).sqrt(),
            e.len(),
        )
    }

    /// A sphere of radius 10 whose top (a cap of 60° around +z) has no samples, reconstructed
    /// and simplified as `slscan mesh` does: Poisson spans the gap as a membrane that sags
    /// into the sphere. Faired, the cap continues the sphere's curvature: its RMS over the
    /// vertices of the cap z > 0.6 r falls more than twofold (measured 0.85 → 0.35 mm) and
    /// below 0.05 r. It does not vanish: the thin-plate surface through a clamped rim is not a
    /// sphere — for a cap of half-width `a` the clamped plate under the sphere's curvature
    /// misses its middle by about `a⁴ / (16 r³)`, 0.35 mm here. The supported vertices do not
    /// move, and the mesh stays closed and manifold with the same triangles.
    #[test]
    fn gap_follows_the_sphere() {
        let r = 10.0;
        let cloud = partial_sphere_cloud(20_000, r, Point3::origin(), |_, n| n.z < 0.5);
        let cfg = PoissonConfig {
            depth: 6,
            ..PoissonConfig::default()
        };
        let mut s = poisson_reconstruct(&cloud, &cfg).unwrap();
        let d = simplify(&mut s.mesh, &s.densities, &SimplifyConfig::default()).unwrap();
        let before = s.mesh.clone();
        let (rms0, n0) = cap_rms(&before, r, 0.6 * r);
        let f = fair_unsupported(&mut s.mesh, &d.densities, &FairConfig::default()).unwrap();
        let (rms1, n1) = cap_rms(&s.mesh, r, 0.6 * r);
        eprintln!("cap RMS {rms0:.4} mm ({n0} vertices) → {rms1:.4} mm ({n1}); {f:?}");
        assert!(n0 > 20 && n1 > 20, "{n0} {n1}");
        assert!(
            rms1 * 2.0 < rms0 && rms1 < 0.05 * r,
            "cap RMS {rms0} → {rms1}"
        );
        assert!(f.residual <= FairConfig::default().tolerance, "{f:?}");
        assert_eq!(s.mesh.triangles, before.triangles);
        assert!(check_topology(&s.mesh).is_watertight_manifold());
        let mut sorted = d.densities.clone();
        sorted.sort_unstable_by(f64::total_cmp);
        let threshold = FairConfig::default().support_ratio * sorted[sorted.len() / 2];
        let mut moved = 0;
        for (v, (a, b)) in before.vertices.iter().zip(&s.mesh.vertices).enumerate() {
            if d.densities[v] >= threshold {
                assert_eq!(a, b, "supported vertex {v} moved");
            } else if a != b {
                moved += 1;
            }
        }
        assert_eq!(moved, f.vertices_moved);
    }

    /// An open mesh: the vertices on its rim stay even when unsupported; a mesh whose vertices
    /// are all supported is left as it is.
    #[test]
    fn rims_and_supported_meshes_stay() {
        let mut mesh = sphere_mesh(1.0, 3);
        let top: Vec<bool> = mesh.vertices.iter().map(|p| p.z > 0.9).collect();
        mesh.triangles
            .retain(|t| t.iter().all(|&i| !top[i as usize]));
        let before = mesh.clone();
        let d: Vec<f64> = mesh
            .vertices
            .iter()
            .map(|p| if p.z > 0.3 { 0.0 } else { 1.0 })
            .collect();
        let done = fair_unsupported(&mut mesh, &d, &FairConfig::default()).unwrap();
        assert!(done.vertices_moved > 0, "{done:?}");
        let ops = Operator::new(&before);
        assert!(ops.boundary.iter().any(|&b| b));
        for (v, (a, b)) in before.vertices.iter().zip(&mesh.vertices).enumerate() {
            if ops.boundary[v] || d[v] > 0.0 {
                assert_eq!(a, b, "vertex {v} moved");
            }
        }
        let mut all = before.clone();
        let ones = vec![1.0; all.vertices.len()];
        let done = fair_unsupported(&mut all, &ones, &FairConfig::default()).unwrap();
        assert_eq!(done.vertices_moved, 0);
        assert_eq!(all.vertices, before.vertices);
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut mesh = sphere_mesh(1.0, 2);
        let d = vec![1.0; mesh.vertices.len()];
        for (cfg, name) in [
            (
                FairConfig {
                    support_ratio: 1.0,
                    ..FairConfig::default()
                },
                "support_ratio",
            ),
            (
                FairConfig {
                    max_iterations: 0,
                    ..FairConfig::default()
                },
                "max_iterations",
            ),
            (
                FairConfig {
                    tolerance: 0.0,
                    ..FairConfig::default()
                },
                "tolerance",
            ),
        ] {
            let e = fair_unsupported(&mut mesh, &d, &cfg).unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
        }
        let e = fair_unsupported(&mut mesh, &d[1..], &FairConfig::default()).unwrap_err();
        assert!(matches!(e, MeshError::InvalidMesh(_)), "{e}");
    }
}
