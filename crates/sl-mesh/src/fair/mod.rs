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
//! The thin plate under a clamped rim is not a sphere: it misses the middle of a spherical
//! gap of half-width `a` by about `a⁴ / (16 r³)` (0.35 mm on a sphere of radius 10 without a
//! 60° cap; 0.4 mm over the unseen patch of the default scan). So it is followed by the
//! curvature fairing of Schneider & Kobbelt (2001), `ΔH = 0`, split into two second-order
//! problems: the mean curvature `H` of the well-sampled surface around the gap (density at
//! least the median; a quadric fitted over four mean edges, the thinly sampled rim hardly
//! weighing) is continued harmonically over the free vertices, then the free
//! vertices are placed, with the same fixed rings, so that every umbrella vector
//! `x_i − mean_j x_j` is `H n_i mean_j |x_j − x_i|² / 2` — exact for a sphere whatever the
//! triangles' shapes, where the cotangent Laplacian of a simplified mesh is not (its
//! obtuse and sliver triangles put errors of tens of times the sphere's `2H` into single
//! vertices). Normals and neighbour distances follow the surface, so the placement is
//! repeated until no vertex moves by more than a hundredth of the mean edge (7–9 steps on
//! the default scan); if it does not settle within
//! [`curvature_iterations`](FairConfig::curvature_iterations) steps (or a step is not finite
//! or grows twice running), or the curvature cannot be continued over the gap (no
//! well-sampled surface within 16 rings of part of it), the thin plate stays.
//! A gap in a sphere is closed by the sphere (the cap above: 0.11 mm instead of 0.35 mm; the
//! default scan's unseen patch 0.063 mm over its area, the data's own accuracy, instead of
//! 0.41 mm), a gap in a plane by the plane.
//!
//! The fairing continues the rim it is given, and Poisson bends the surface outwards for a
//! millimetre or so past the last samples; so ([`FairConfig::project_rim`], on by default)
//! that rim is first put on the quadric fitted to the well-sampled surface nearby, wherever
//! such a quadric fits about as well as it does elsewhere on the mesh (not next to a crease):
//! the default scan's unseen patch 0.063 → 0.040 mm over its area (docs/meshing.md).
//!
//! Each system lives on the unsupported vertices only (the fixed ones enter its right-hand
//! side through the two rings around them) and is factored once by sparse Cholesky (faer):
//! the bi-Laplacian's condition grows with the fourth power of a hole's width in vertices,
//! which iterative solvers pay for (see `thin_plate::FreeSystem`). Run it on a simplified mesh
//! ([`simplify`](crate::simplify) leaves few vertices on that surface).

//!
//! The pieces, one file each: `cotangent` (the cotangent Laplace–Beltrami operator and the
//! walks over the mesh's rings), `thin_plate` (the bi-Laplacian system on the free vertices),
//! `rim` (the projection of a gap's thinly sampled rim) and `curvature` (the continued mean
//! curvature and the curvature fairing's steps).

mod cotangent;
mod curvature;
mod rim;
mod thin_plate;

use nalgebra::{Point3, Vector3};
use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::check_indices;
use cotangent::Operator;
use curvature::{FairingSystem, continued_curvature, curvature_fairing, well_sampled};
use rim::{RimInput, RimProjection, project_rim};
use thin_plate::{FreeSystem, fixed_pull};

/// Parameters of [`fair_unsupported`].
#[derive(Debug, Clone, PartialEq)]
pub struct FairConfig {
    /// A vertex whose sampling density is below this fraction of the median density of the
    /// vertices is free to move. 0.3: three times `trim_by_density`'s and `simplify`'s 0.1,
    /// so that the thinly sampled rim of a gap, where Poisson's membrane already sags, moves
    /// too (docs/meshing.md, "Fairing", has the figures for 0.1, 0.3 and 0.5).
    pub support_ratio: f64,
    /// Most steps of the curvature fairing that follows the thin plate (0: the thin plate
    /// only). 30: it settles in 7–9 on the default scan and on the test sphere.
    pub curvature_iterations: usize,
    /// Put the thinly sampled rim of each gap on the well-sampled surface first (see
    /// `project_rim`; only where a quadric fitted nearby fits about as well as elsewhere on
    /// the mesh), and let the fixed vertices' rows keep their tangential part: closes a gap in
    /// a smooth, rounded object much better (the default scan's unseen patch 0.063 → 0.040 mm
    /// over its area, all its vertices 0.0662 → 0.0633 mm; the test sphere's cap 0.11 →
    /// 0.028 mm, 0.03–0.05 mm whatever the support ratio) and leaves gaps next to a crease as
    /// they were (the two-placement pebble: the same mesh either way). On by default.
    pub project_rim: bool,
}

impl Default for FairConfig {
    fn default() -> Self {
        Self {
            support_ratio: 0.3,
            curvature_iterations: 30,
            project_rim: true,
        }
    }
}

/// What [`fair_unsupported`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Fairing {
    /// Vertices moved (the unsupported ones not on a rim or a non-manifold place).
    pub vertices_moved: usize,
    /// Gaps: the pieces of moved vertices (connected through the mesh).
    pub gaps: usize,
    /// Of those, the gaps in smooth surface, whose rim was projected (see
    /// [`FairConfig::project_rim`]); 0 without it, and when the curvature fairing did not
    /// settle.
    pub smooth_gaps: usize,
    /// Fixed vertices of the thinly sampled rim around them (density below half the median,
    /// within four rings) put on the surface fitted to the well-sampled vertices nearby before
    /// the fairing (where Poisson bends the surface past the last samples, and the fit is
    /// good); 0 without [`FairConfig::project_rim`], and when the curvature fairing did not
    /// settle (the rim is then put back under the thin plate).
    pub rim_moved: usize,
    /// The largest distance a vertex moved, in the mesh's units.
    pub largest_move: f64,
    /// Relative residual of the thin plate's solution, `|b − K x| / |b|` (a check of the
    /// direct solve: round-off only).
    pub residual: f64,
    /// Curvature-fairing steps made.
    pub curvature_steps: usize,
    /// Whether the curvature fairing reached its fixed point (if not, the thin plate stays).
    pub curvature_converged: bool,
    /// The mean curvature continued over the moved vertices (their mean, in the inverse of
    /// the mesh's units; `1/r` for a gap in a sphere of radius `r`), 0 without curvature steps.
    pub mean_curvature: f64,
}

/// Moves the vertices of `mesh` whose density is below `cfg.support_ratio` times the median
/// of `densities` (one per vertex: [`PoissonSurface::densities`](crate::PoissonSurface) or
/// [`Simplification::densities`](crate::Simplification)) to the thin-plate surface spanned by
/// the others (see the module documentation). Vertices on a boundary edge stay where they are.
/// A mesh without unsupported vertices is left unchanged, and so is one whose thin-plate
/// system cannot be factored (degenerate triangles all round a free vertex).
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a ratio outside `[0, 1)`; [`MeshError::InvalidMesh`]
/// for a triangle index out of range or a density count that is not the vertex count.
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
        gaps: 0,
        smooth_gaps: 0,
        rim_moved: 0,
        largest_move: 0.0,
        residual: 0.0,
        curvature_steps: 0,
        curvature_converged: false,
        mean_curvature: 0.0,
    };
    if nv == 0 {
        return Ok(unchanged);
    }
    let median = crate::trim::median_density(densities);
    let threshold = cfg.support_ratio * median;

    let op = Operator::new(mesh);
    let mut free: Vec<bool> = (0..nv)
        .map(|v| densities[v] < threshold && !op.boundary[v])
        .collect();
    // A piece of free vertices that touches no fixed one (an island the data never reached)
    // has nothing to span: it stays as it is.
    let mut gaps = Vec::new();
    for piece in op.pieces(&free) {
        let anchored = piece
            .iter()
            .any(|&v| op.ring(v).iter().any(|&a| !free[a as usize]));
        if anchored {
            gaps.push(piece);
        } else {
            for v in piece {
                free[v] = false;
            }
        }
    }
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
    let before: Vec<Vector3<f64>> = free_ids.iter().map(|&v| mesh.vertices[v].coords).collect();

    // The thin plate: `K_ff x_f = −K_fc x_c`, factored once (sparse Cholesky). Not positive
    // definite only where every triangle around a free vertex is degenerate (all its cotangent
    // weights clamped to zero): then nothing is moved.
    let Some(plate) = FreeSystem::new(&op, &free_ids, &active_ids) else {
        return Ok(unchanged);
    };
    let pull = fixed_pull(&op, mesh, &free, &active_ids, &free_ids);
    let mut x = plate.solve(&pull);
    let residual = plate.relative_residual(&x, &pull);
    let mut curvature_steps = 0;
    let mut curvature_converged = false;
    let mut mean_curvature = 0.0;
    let (mut rim_moved, mut smooth_gaps) = (0, 0);
    if cfg.curvature_iterations > 0 {
        // The thinly sampled rim around the gap, put on the well-sampled surface first (see
        // `project_rim`); the curvature fairing continues it, from the thin plate under it.
        let (well, support) = well_sampled(densities, &free, median);
        let rim = if cfg.project_rim {
            let input = RimInput {
                free: &free,
                gaps: &gaps,
                densities,
                median,
                well: &well,
                support: &support,
            };
            project_rim(mesh, &op, &input)
        } else {
            RimProjection::none(nv)
        };
        let start = if rim.originals.is_empty() {
            x.clone()
        } else {
            plate.solve(&fixed_pull(&op, mesh, &free, &active_ids, &free_ids))
        };
        for (i, &v) in free_ids.iter().enumerate() {
            mesh.vertices[v] = Point3::from(start[i]);
        }
        // Without well-sampled surface near the gap there is no curvature to continue.
        if let Some(h) = continued_curvature(mesh, &op, &free, &free_ids, &well, &support) {
            mean_curvature = free_ids.iter().map(|&v| h[v]).sum::<f64>() / free_ids.len() as f64;
            let system = FairingSystem {
                free: &free,
                free_ids: &free_ids,
                active_ids: &active_ids,
                tangential: &rim.tangential,
            };
            let faired = curvature_fairing(mesh, &op, &system, &h, cfg);
            curvature_steps = faired.steps;
            curvature_converged = faired.converged;
            if faired.converged {
                x = faired.positions;
            }
        }
        // The thin plate that stays is the one under Poisson's rim: a clamped plate sags into
        // a curved surface, and the rim's outward bend makes up for part of that (the test
        // sphere's cap 0.39 mm under Poisson's rim, 0.61 mm under the projected one).
        if curvature_converged {
            rim_moved = rim.originals.len();
            smooth_gaps = rim.smooth_gaps;
        } else {
            for (v, p) in rim.originals {
                mesh.vertices[v] = p;
            }
        }
    }
    for (i, &v) in free_ids.iter().enumerate() {
        mesh.vertices[v] = Point3::from(x[i]);
    }
    let largest_move = x
        .iter()
        .zip(&before)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    Ok(Fairing {
        vertices_moved: free_ids.len(),
        gaps: gaps.len(),
        smooth_gaps,
        rim_moved,
        largest_move,
        residual,
        curvature_steps,
        curvature_converged,
        mean_curvature,
    })
}

#[cfg(test)]
mod tests {
    use super::rim::RIM_DENSITY;
    use super::*;
    use crate::test_shapes::{partial_sphere_surface, sphere_mesh};
    use crate::{SimplifyConfig, check_topology, simplify};

    /// RMS of `|p| − r` over the vertices with `z > z_min`.
    pub(super) fn cap_rms(mesh: &TriangleMesh, r: f64, z_min: f64) -> (f64, usize) {
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
    /// into the sphere (RMS 0.84 mm over the vertices of the cap z > 0.6 r). The thin plate
    /// alone (no curvature steps) continues the sphere's curvature but cannot be a sphere: a
    /// clamped plate of half-width `a` under the sphere's curvature misses its middle by about
    /// `a⁴ / (16 r³)`, 0.35 mm here (measured 0.39). The curvature fairing continues the
    /// sphere's mean curvature `1/r` and so closes the gap by the sphere itself, up to the
    /// estimate of `H` (1 % of `H` is about 0.05 mm at the middle of this cap) and the
    /// simplified mesh's facets: measured 0.11 mm from Poisson's rim (`project_rim` off), so
    /// it must be below 0.02 r and below half the thin plate's, and 0.028 mm with the rim put
    /// on the sphere first (the default), which must be below 0.005 r; the curvature it
    /// continued is `1/r` within 2 % (measured 0.3 % high). Allowed one step, which does not
    /// settle, it leaves the thin plate under Poisson's rim exactly (the projected rim is put
    /// back). The direct solve's residual is round-off (below 1e-9). Besides the free
    /// vertices only the rim moves, and the mesh stays closed and manifold with the same
    /// triangles.
    #[test]
    fn gap_follows_the_sphere() {
        let r = 10.0;
        let mut s = partial_sphere_surface(r, |_, n| n.z < 0.5);
        let d = simplify(&mut s.mesh, &s.densities, &SimplifyConfig::default()).unwrap();
        let before = s.mesh.clone();
        let (rms0, n0) = cap_rms(&before, r, 0.6 * r);
        let mut plate = before.clone();
        let thin = FairConfig {
            curvature_iterations: 0,
            ..FairConfig::default()
        };
        let fp = fair_unsupported(&mut plate, &d.densities, &thin).unwrap();
        let (rms_plate, _) = cap_rms(&plate, r, 0.6 * r);
        let mut plain = before.clone();
        let from_poisson_rim = FairConfig {
            project_rim: false,
            ..FairConfig::default()
        };
        let f0 = fair_unsupported(&mut plain, &d.densities, &from_poisson_rim).unwrap();
        let (rms_plain, _) = cap_rms(&plain, r, 0.6 * r);
        let f = fair_unsupported(&mut s.mesh, &d.densities, &FairConfig::default()).unwrap();
        let (rms1, n1) = cap_rms(&s.mesh, r, 0.6 * r);
        eprintln!(
            "cap RMS {rms0:.4} mm ({n0} vertices) → thin plate {rms_plate:.4} mm → curvature \
             {rms_plain:.4} mm, with the rim projected {rms1:.4} mm ({n1}); {f:?}"
        );
        assert!(n0 > 20 && n1 > 20, "{n0} {n1}");
        assert_eq!(fp.curvature_steps, 0);
        assert_eq!(fp.rim_moved, 0);
        assert!(
            rms_plate * 2.0 < rms0 && rms_plate < 0.05 * r,
            "thin plate: cap RMS {rms0} → {rms_plate}"
        );
        for f in [&f, &f0] {
            assert!(f.curvature_converged && f.curvature_steps > 0, "{f:?}");
            assert!((f.mean_curvature * r - 1.0).abs() < 0.02, "{f:?}");
            assert!(f.residual < 1e-9, "{f:?}");
        }
        assert!(
            rms_plain * 2.0 < rms_plate && rms_plain < 0.02 * r,
            "curvature: cap RMS {rms_plate} → {rms_plain}"
        );
        assert!(rms1 < 0.005 * r, "rim projected: cap RMS {rms1}");
        assert!(f0.rim_moved == 0 && f.rim_moved > 0, "{f0:?} {f:?}");
        assert!(
            f.gaps == 1 && f.smooth_gaps == 1 && f0.smooth_gaps == 0,
            "{f0:?} {f:?}"
        );
        // One step does not settle: the thin plate stays, exactly, under Poisson's rim.
        let mut one = before.clone();
        let cfg1 = FairConfig {
            curvature_iterations: 1,
            ..FairConfig::default()
        };
        let f1 = fair_unsupported(&mut one, &d.densities, &cfg1).unwrap();
        assert!(!f1.curvature_converged && f1.curvature_steps == 1, "{f1:?}");
        assert!(f1.rim_moved == 0 && f1.smooth_gaps == 0, "{f1:?}");
        assert_eq!(one.vertices, plate.vertices);
        assert!(fp.residual < 1e-9, "{fp:?}");
        assert_eq!(s.mesh.triangles, before.triangles);
        assert!(check_topology(&s.mesh).is_watertight_manifold());
        let mut sorted = d.densities.clone();
        sorted.sort_unstable_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let threshold = FairConfig::default().support_ratio * median;
        let (mut moved, mut rim) = (0, 0);
        for (v, (a, b)) in before.vertices.iter().zip(&s.mesh.vertices).enumerate() {
            let density = d.densities[v];
            if density >= RIM_DENSITY * median {
                assert_eq!(a, b, "supported vertex {v} moved");
            } else if a != b {
                if density >= threshold {
                    rim += 1;
                } else {
                    moved += 1;
                }
            }
            if density >= threshold {
                assert_eq!(
                    a, &plain.vertices[v],
                    "vertex {v} moved without the rim's projection"
                );
            }
        }
        assert_eq!(moved, f.vertices_moved);
        assert_eq!(rim, f.rim_moved);
    }

    /// A gap in a plane closes by the plane: the top face of a cube (exact planes, every fit's
    /// residual round-off) with its middle unsupported and sagged by 0.2 comes back flat to
    /// round-off (measured 1e-13), with the rim projection and without; no other vertex
    /// moves. (The faces are 40 edges wide: on a 12-edge cube the curvature fits around the
    /// gap reach over the cube's edges and the patch bends by 1e-3.)
    #[test]
    fn gap_in_a_plane_closes_flat() {
        let s = 1.0;
        let mut mesh = crate::test_shapes::cube_mesh(s, 40);
        let gap = |p: &Point3<f64>| p.z > s - 1e-9 && p.x.abs() < 0.5 && p.y.abs() < 0.5;
        let d: Vec<f64> = mesh
            .vertices
            .iter()
            .map(|p| if gap(p) { 0.0 } else { 1.0 })
            .collect();
        for p in &mut mesh.vertices {
            if gap(p) {
                p.z -= 0.2;
            }
        }
        for project_rim in [true, false] {
            let mut m = mesh.clone();
            let cfg = FairConfig {
                project_rim,
                ..FairConfig::default()
            };
            let f = fair_unsupported(&mut m, &d, &cfg).unwrap();
            assert!(f.vertices_moved > 10 && f.curvature_converged, "{f:?}");
            let mut worst = 0.0f64;
            for (v, (a, b)) in mesh.vertices.iter().zip(&m.vertices).enumerate() {
                if d[v] > 0.0 {
                    assert_eq!(a, b, "vertex {v} moved");
                } else {
                    worst = worst.max((b.z - s).abs());
                }
            }
            eprintln!("{project_rim}: off the plane by {worst:e}; {f:?}");
            assert!(worst < 1e-9, "{project_rim}: off the plane by {worst}");
        }
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
                    support_ratio: -0.1,
                    ..FairConfig::default()
                },
                "support_ratio",
            ),
        ] {
            let e = fair_unsupported(&mut mesh, &d, &cfg).unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
        }
        let e = fair_unsupported(&mut mesh, &d[1..], &FairConfig::default()).unwrap_err();
        assert!(matches!(e, MeshError::InvalidMesh(_)), "{e}");
    }
}
