//! The curvature fairing that follows the thin plate (Schneider & Kobbelt 2001): `ΔH = 0`
//! split into two second-order problems. The mean curvature `H` of the well-sampled surface
//! around a gap (quadrics fitted over a few mean edges) is continued harmonically over the
//! free vertices; then the free vertices are placed, with the fixed rings, so that every
//! umbrella vector carries it, step after step until they settle.

use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::TriangleMesh;

use super::FairConfig;
use super::cotangent::Operator;
use super::thin_plate::{FreeSystem, fixed_pull};
use crate::curvature::{LocalQuadric, fit_quadric};
use crate::measure::vertex_normals;

/// A curvature step that moves no vertex by more than this fraction of the mean edge length
/// ends the curvature fairing.
const CURVATURE_STEP_TOLERANCE: f64 = 1e-2;

/// Rings of fixed vertices around the free ones whose mean curvature is continued over them.
pub(super) const CURVATURE_RINGS: usize = 16;

/// Radius, in mean edge lengths, of the neighbourhood the curvature is fitted over.
const CURVATURE_RADIUS_EDGES: f64 = 4.0;

/// Fewest fixed vertices a curvature fit takes (it has six unknowns).
const CURVATURE_MIN_NEIGHBOURS: usize = 12;

/// A fixed vertex weighs in a curvature fit by its sampling density over the median, to this
/// power (at most 1): the thinly sampled rim of a gap, already flattened towards Poisson's
/// membrane, hardly counts. Powers 1, 2, 4 continue 0.0395, 0.0397, 0.0400 mm⁻¹ over the
/// default scan's unseen patch (spheres of 0.04) and 0.095, 0.097, 0.0997 over the test
/// sphere's cap (0.1).
const CURVATURE_SUPPORT_POWER: i32 = 4;

/// Neighbour-averaging passes of that curvature before it is continued.
const CURVATURE_SMOOTHING: usize = 4;

/// Which vertices are well sampled (density at least the median) and how much each fixed one
/// counts in a quadric fit (its density over the median, at most 1; the free ones 0).
pub(super) fn well_sampled(densities: &[f64], free: &[bool], median: f64) -> (Vec<bool>, Vec<f64>) {
    let well = densities.iter().map(|&d| d >= median).collect();
    let support = densities
        .iter()
        .zip(free)
        .map(|(&d, &f)| if f { 0.0 } else { (d / median).clamp(0.0, 1.0) })
        .collect();
    (well, support)
}

/// The quadric fitted around vertex `v` over [`CURVATURE_RADIUS_EDGES`] mean edges, each
/// fixed vertex weighing by its `support` to the power [`CURVATURE_SUPPORT_POWER`]: the fit
/// the curvature is read from and the rim projected onto.
pub(super) fn fit_around(
    vertices: &[Point3<f64>],
    op: &Operator,
    normals: &[Vector3<f64>],
    support: &[f64],
    v: usize,
) -> Option<LocalQuadric> {
    fit_quadric(
        vertices,
        &|i| op.ring(i),
        &|i| support[i].powi(CURVATURE_SUPPORT_POWER),
        v,
        normals[v],
        CURVATURE_RADIUS_EDGES * op.edge_scale,
        CURVATURE_MIN_NEIGHBOURS,
    )
}

/// What [`curvature_fairing`] reached.
pub(super) struct CurvatureFairing {
    /// The free vertices' positions after the last step.
    pub(super) positions: Vec<Vector3<f64>>,
    /// Steps made.
    pub(super) steps: usize,
    /// Whether the last step moved no vertex by more than [`CURVATURE_STEP_TOLERANCE`] of the
    /// mean edge.
    pub(super) converged: bool,
}

/// The vertices [`curvature_fairing`] works on.
pub(super) struct FairingSystem<'a> {
    pub(super) free: &'a [bool],
    pub(super) free_ids: &'a [usize],
    /// The free vertices and the two rings of fixed ones around them.
    pub(super) active_ids: &'a [usize],
    /// The fixed vertices whose rows keep their tangential part (next to a gap whose rim was
    /// projected: [`project_rim`](super::rim::project_rim)).
    pub(super) tangential: &'a [bool],
}

/// The curvature fairing's steps from the mesh as it is (the thin plate): the free vertices
/// placed, with the two fixed rings, so that their umbrella vectors carry the mean curvature
/// `h` (see the module documentation), until they settle or `cfg.curvature_iterations`
/// steps are made. Moves the mesh's free vertices.
pub(super) fn curvature_fairing(
    mesh: &mut TriangleMesh,
    op: &Operator,
    system: &FairingSystem<'_>,
    h: &[f64],
    cfg: &FairConfig,
) -> CurvatureFairing {
    let FairingSystem {
        free,
        free_ids,
        active_ids,
        tangential,
    } = *system;
    let nv = mesh.vertices.len();
    let mut x: Vec<Vector3<f64>> = free_ids.iter().map(|&v| mesh.vertices[v].coords).collect();
    let mut curvature_steps = 0;
    let mut curvature_converged = false;
    let umbrella = op.umbrella();
    let pull = fixed_pull(&umbrella, mesh, free, active_ids, free_ids);
    let Some(system) = FreeSystem::new(&umbrella, free_ids, active_ids) else {
        return CurvatureFairing {
            positions: x,
            steps: 0,
            converged: false,
        };
    };
    let (mut last_step, mut growing) = (f64::INFINITY, 0);
    while curvature_steps < cfg.curvature_iterations {
        curvature_steps += 1;
        // The umbrella vector `x_i − mean_j x_j` of a surface of mean curvature H is
        // `H n_i mean_j |x_j − x_i|² / 2` (each neighbour lies `κ d²/2` below the tangent
        // plane, and every normal curvature κ of a sphere is H): the target of every row
        // the free vertices enter.
        let normals = vertex_normals(mesh);
        let mut target = vec![Vector3::zeros(); nv];
        for &v in active_ids {
            let p = mesh.vertices[v];
            let ring = umbrella.ring(v);
            let mean_sq = ring
                .iter()
                .map(|&j| (mesh.vertices[j as usize] - p).norm_squared())
                .sum::<f64>()
                / ring.len().max(1) as f64;
            target[v] = normals[v] * (h[v] * mean_sq / 2.0);
            // With the rim projected: a fixed vertex's ring cannot move round it, so its row
            // asks for the tangential part its umbrella has (on an irregular ring even an exact
            // sphere has one) and only the normal part, the curvature, pulls on the free
            // vertices. (Without the projection the bent rim's outward pull and this row's
            // inward one cancel in part, and keeping the tangential part alone is worse.)
            if tangential[v] {
                let mean = ring
                    .iter()
                    .map(|&j| mesh.vertices[j as usize].coords)
                    .sum::<Vector3<f64>>()
                    / ring.len().max(1) as f64;
                let u = p.coords - mean;
                let n = normals[v];
                target[v] += u - n * n.dot(&u);
            }
        }
        let b: Vec<Vector3<f64>> = free_ids
            .iter()
            .zip(&pull)
            .map(|(&v, p)| p + umbrella.laplace(&target, v))
            .collect();
        let next = system.solve(&b);
        let step = next
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        x = next;
        for (i, &v) in free_ids.iter().enumerate() {
            mesh.vertices[v] = Point3::from(x[i]);
        }
        // A step not finite, or growing twice running (the steps shrink geometrically when
        // they settle), ends the fairing unsettled: the thin plate stays.
        if !step.is_finite() {
            break;
        }
        growing = if step > last_step { growing + 1 } else { 0 };
        if growing >= 2 {
            break;
        }
        last_step = step;
        if step <= CURVATURE_STEP_TOLERANCE * op.edge_scale {
            curvature_converged = true;
            break;
        }
    }
    CurvatureFairing {
        positions: x,
        steps: curvature_steps,
        converged: curvature_converged,
    }
}

/// The mean curvature `H` of every vertex the free ones reach (zero elsewhere), continued
/// from the well-supported surface around them (`None` if there is none within
/// [`CURVATURE_RINGS`] rings):
///
/// - measured on the fixed vertices within [`CURVATURE_RINGS`] rings of the free ones whose
///   sampling density is at least the median (`well`): a quadric fitted to the fixed
///   vertices within [`CURVATURE_RADIUS_EDGES`] mean edges ([`fit_around`]; a
///   vertex's discrete Laplacian is far noisier on a simplified mesh), each weighing by its
///   support (sampling density over the median, to the power [`CURVATURE_SUPPORT_POWER`]),
///   then smoothed over those vertices; the thinly sampled rim next to a gap is left out, as
///   the reconstruction there is already flattened towards Poisson's membrane. A fit over a
///   distance, not the circles through the neighbours within two rings (`−2 d·n / |d|²`,
///   until 2026-11-27): those divide the surface's wiggles by the squared edge length, so
///   their spread per vertex on the default scan's spheres (`1/r` = 0.04 mm⁻¹) grew from
///   0.033 mm⁻¹ (1.36 mm edges) to 1.9 mm⁻¹ on the unsimplified extraction (0.33 mm), and
///   what they continued over the gap went from 0.0398 (simplified to 0.01 mm) to 0.0374
///   (0.005 mm), which left the patch 0.15 mm RMS off instead of 0.09. The fit continues
///   0.0400, 0.0401 and 0.0396 mm⁻¹ at 0.01, 0.005 and 0.002 mm;
/// - continued harmonically (`ΔH = 0`, cotangent weights) over the free vertices and the
///   thin rim, with the natural condition where the band ends.
pub(super) fn continued_curvature(
    mesh: &TriangleMesh,
    op: &Operator,
    free: &[bool],
    free_ids: &[usize],
    well: &[bool],
    support: &[f64],
) -> Option<Vec<f64>> {
    let nv = mesh.vertices.len();
    let normals = vertex_normals(mesh);
    let near = op.rings_around(free_ids, CURVATURE_RINGS, |a| !free[a]);
    let mut measured: Vec<bool> = (0..nv).map(|v| near[v] && well[v]).collect();
    let mut unknown: Vec<bool> = (0..nv).map(|v| free[v] || (near[v] && !well[v])).collect();
    let measured_ids: Vec<usize> = (0..nv).filter(|&v| measured[v]).collect();
    if measured_ids.is_empty() {
        return None;
    }
    let fitted: Vec<Option<f64>> = measured_ids
        .par_iter()
        .map(|&v| fit_around(&mesh.vertices, op, &normals, support, v)?.mean_curvature())
        .collect();
    let mut h = vec![0.0; nv];
    // A vertex whose fit failed (too few well-sampled neighbours) takes the continued value.
    for (&v, fit) in measured_ids.iter().zip(&fitted) {
        match fit {
            Some(value) => h[v] = *value,
            None => {
                measured[v] = false;
                unknown[v] = true;
            }
        }
    }
    let measured_ids: Vec<usize> = (0..nv).filter(|&v| measured[v]).collect();
    if measured_ids.is_empty() {
        return None;
    }
    for _ in 0..CURVATURE_SMOOTHING {
        let prev = h.clone();
        for &v in &measured_ids {
            let (mut s, mut a) = (prev[v] * op.area[v], op.area[v]);
            for &j in op.ring(v) {
                let j = j as usize;
                if measured[j] {
                    s += prev[j] * op.area[j];
                    a += op.area[j];
                }
            }
            if a > 0.0 {
                h[v] = s / a;
            }
        }
    }
    // A piece of unknown vertices that no measured one borders (a gap whose rim is thinly
    // sampled all round) takes the mean curvature of the measured surface.
    let mut known = measured.clone();
    let mean = measured_ids.iter().map(|&v| h[v]).sum::<f64>() / measured_ids.len() as f64;
    for piece in op.pieces(&unknown) {
        let bordered = piece
            .iter()
            .any(|&v| op.ring(v).iter().any(|&a| measured[a as usize]));
        if !bordered {
            for v in piece {
                unknown[v] = false;
                known[v] = true;
                h[v] = mean;
            }
        }
    }
    let unknown_ids: Vec<usize> = (0..nv).filter(|&v| unknown[v]).collect();
    let hu = harmonic_continuation(op, &unknown, &known, &unknown_ids, &h)?;
    for (i, &v) in unknown_ids.iter().enumerate() {
        h[v] = hu[i];
    }
    Some(h)
}

/// The harmonic continuation of `values` (given on `known`) over `unknown_ids`:
/// `Σ_j w_ij (y_i − y_j) = 0` over the neighbours `j` that are unknown or known (the others
/// left out: the natural condition), by sparse Cholesky. `None` if a piece of unknown vertices
/// touches no known one (the system is then singular).
fn harmonic_continuation(
    op: &Operator,
    unknown: &[bool],
    known: &[bool],
    unknown_ids: &[usize],
    values: &[f64],
) -> Option<Vec<f64>> {
    let mut pos = vec![usize::MAX; unknown.len()];
    for (i, &v) in unknown_ids.iter().enumerate() {
        pos[v] = i;
    }
    let n = unknown_ids.len();
    let mut triplets = Vec::new();
    let mut b = Mat::<f64>::zeros(n, 1);
    for (i, &v) in unknown_ids.iter().enumerate() {
        let mut diagonal = 0.0;
        for k in op.start[v]..op.start[v + 1] {
            let j = op.ring[k] as usize;
            if unknown[j] || known[j] {
                diagonal += op.weight[k];
            }
            if known[j] {
                b[(i, 0)] += op.weight[k] * values[j];
            } else if unknown[j] {
                triplets.push(Triplet::new(i, pos[j], -op.weight[k]));
            }
        }
        triplets.push(Triplet::new(i, i, diagonal));
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).ok()?;
    let llt = a.sp_cholesky(Side::Lower).ok()?;
    llt.solve_in_place(b.as_mut());
    let y: Vec<f64> = (0..n).map(|i| b[(i, 0)]).collect();
    y.iter().all(|v| v.is_finite()).then_some(y)
}
