//! The thinly sampled rim of a gap in smooth surface put on the quadric fitted to the
//! well-sampled surface nearby, before the fairing continues it (Poisson bends the surface
//! outwards for a millimetre or so past the last samples); left alone next to a crease.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::TriangleMesh;

use super::cotangent::Operator;
use super::curvature::{CURVATURE_RINGS, fit_around};
use crate::curvature::{IdMap, IdSet, LocalQuadric};
use crate::measure::vertex_normals;

/// Rings of thinly sampled fixed vertices around the free ones that [`project_rim`] puts on
/// the well-sampled surface.
const RIM_RINGS: usize = 4;

/// A fixed vertex is part of the rim when its sampling density is below this fraction of the
/// median: past the last samples, where Poisson bends the surface (1.0 moved scanned surface
/// of the two-placement pebble: 0.0543 → 0.092 mm over its area; 0.5: 0.0556).
pub(super) const RIM_DENSITY: f64 = 0.5;

/// A rim vertex is moved onto the fitted quadric only when that is at most this many mean
/// edges away: Poisson's bend is a few hundredths of a millimetre, while a quadric fitted
/// across a bend it does not follow (the Stanford bunny's ears and legs) put rim vertices
/// millimetres off, spikes in the mesh.
const RIM_MAX_MOVE_EDGES: f64 = 0.5;

/// A quadric fits "as well as is typical" ([`project_rim`]) when its residual is at most this
/// many times the median residual of the fits at well-sampled vertices
/// ([`typical_fit_residual`]). A quadric does not describe a crease, and one fitted next to
/// it (the two-placement pebble's gaps lie where its flat bottom meets its side, 50–70° of
/// bend within 4 mm) moved the rim inwards by 0.1–0.2 mm, which the fairing then carried into
/// the gap. Measured: the default scan's rim fits 0.008–0.011 mm against a typical
/// 0.0082 mm, the pebble's 0.012–0.09 mm against 0.0090 mm with none between 0.015 and
/// 0.03 mm; 1.5 already lost a little of the scan's gain, 2–3 gave the same meshes
/// (docs/meshing.md).
const RIM_FIT_RESIDUAL: f64 = 2.0;

/// A gap counts as in smooth surface ([`project_rim`]) when at least this share of the fixed
/// vertices next to it find a quadric that fits as well as is typical. Measured: the default
/// scan's two unseen patches 100 %, the test sphere's cap 94 % (77 % when the support ratio
/// frees down to 0.2 of the median); gaps on a crease 48 % (`rim_next_to_a_crease_stays`)
/// and 18 % (the two-placement pebble's).
const SMOOTH_GAP_SHARE: f64 = 0.7;

/// A fit residual below this fraction of the mean edge is round-off (real scans: about 1 %, the
/// default scan 0.0082 mm on 0.83 mm edges).
const ROUND_OFF_RESIDUAL: f64 = 1e-6;

/// [`typical_fit_residual`] fits at every this many-th vertex (the vertices are numbered in
/// cell order, so this samples the surface evenly).
const TYPICAL_FIT_STRIDE: usize = 8;

/// What [`project_rim`] reads of the fairing's set-up.
#[derive(Clone, Copy)]
pub(super) struct RimInput<'a> {
    pub(super) free: &'a [bool],
    /// The pieces of free vertices.
    pub(super) gaps: &'a [Vec<usize>],
    pub(super) densities: &'a [f64],
    pub(super) median: f64,
    /// From [`well_sampled`](super::curvature::well_sampled).
    pub(super) well: &'a [bool],
    pub(super) support: &'a [f64],
}

/// What [`project_rim`] did: the rim vertices moved with their positions before, which fixed
/// vertices' curvature rows keep their tangential part, and how many gaps were smooth.
pub(super) struct RimProjection {
    pub(super) originals: Vec<(usize, Point3<f64>)>,
    pub(super) tangential: Vec<bool>,
    pub(super) smooth_gaps: usize,
}

impl RimProjection {
    /// Nothing moved, no row tangential, on a mesh of `nv` vertices.
    pub(super) fn none(nv: usize) -> Self {
        Self {
            originals: Vec::new(),
            tangential: vec![false; nv],
            smooth_gaps: 0,
        }
    }
}

/// Puts the thinly sampled rim of every gap in smooth surface onto the surface fitted to the
/// well-sampled vertices nearby; returns the vertices moved with their positions before, and
/// the fixed vertices within two rings of those gaps (whose curvature rows then keep their
/// tangential part, see [`curvature_fairing`](super::curvature::curvature_fairing)).
///
/// A gap (a piece of free vertices) is in smooth surface when, for at least
/// [`SMOOTH_GAP_SHARE`] of the fixed vertices next to it, the quadric fitted (as for the
/// curvature, [`fit_quadric`](crate::curvature::fit_quadric)) around the nearest well-sampled vertex has a residual of at most
/// [`RIM_FIT_RESIDUAL`] times the typical one ([`typical_fit_residual`]). Its rim is the fixed
/// vertices within [`RIM_RINGS`] rings whose sampling density is below [`RIM_DENSITY`] of the
/// median; each is put on its fitted quadric along the fitted vertex's normal, when that fit
/// passes the same test and the move is at most [`RIM_MAX_MOVE_EDGES`] mean edges.
///
/// Poisson bends the surface outwards where the samples stop, over a millimetre or so that the
/// density kernel still counts as supported: on the test sphere the fixed vertices just past
/// the last samples sit +0.06 mm out. The fairing continues the rim it is given, tangent and
/// all, so that bend went into the whole patch (and, with the umbrella rows' own inward pull,
/// made the result depend on where the support ratio cut: 0.20 / 0.11 / 0.47 / 0.53 mm on the
/// test cap for 0.2 / 0.3 / 0.4 / 0.5 of the median). With the rim on the well-sampled
/// surface (and the fixed rows keeping their tangential part): 0.040 / 0.028 / 0.051 /
/// 0.029 mm. Next to a crease both hurt (`rim_next_to_a_crease_stays`), hence the test.
pub(super) fn project_rim(
    mesh: &mut TriangleMesh,
    op: &Operator,
    input: &RimInput<'_>,
) -> RimProjection {
    let RimInput {
        free,
        gaps,
        densities,
        median,
        well,
        support,
    } = *input;
    let nv = mesh.vertices.len();
    let normals = vertex_normals(mesh);
    let vertices = &mesh.vertices;
    let Some(typical) = typical_fit_residual(vertices, op, &normals, well, support) else {
        return RimProjection::none(nv);
    };
    // On an exact surface (a test's plane or sphere) every residual is round-off, and which
    // fits pass would be chance: round-off passes.
    let largest_residual = RIM_FIT_RESIDUAL * typical.max(ROUND_OFF_RESIDUAL * op.edge_scale);
    // The quadric fitted around the well-sampled vertex nearest to `u` through the mesh, if
    // it fits as well as is typical.
    let good_fit = |u: usize| -> Option<LocalQuadric> {
        let mut seen: IdSet<usize> = IdSet::default();
        seen.insert(u);
        let mut layer = vec![u];
        for _ in 0..CURVATURE_RINGS {
            let mut next = Vec::new();
            for &v in &layer {
                for &a in op.ring(v) {
                    if seen.insert(a as usize) {
                        next.push(a as usize);
                    }
                }
            }
            if let Some(&v) = next.iter().filter(|&&a| well[a]).min() {
                let quadric = fit_around(vertices, op, &normals, support, v)?;
                return (quadric.residual() <= largest_residual).then_some(quadric);
            }
            layer = next;
        }
        None
    };
    // The fits of the fixed vertices next to the smooth gaps, kept for the rim (most of them
    // are rim vertices too): `None` where there is no typical fit.
    let mut fits: IdMap<usize, Option<LocalQuadric>> = IdMap::default();
    let (mut smooth, mut smooth_gaps) = (Vec::new(), 0);
    for piece in gaps {
        let mut next_to: Vec<usize> = piece
            .iter()
            .flat_map(|&v| op.ring(v).iter().map(|&a| a as usize))
            .filter(|&a| !free[a] && !op.boundary[a])
            .collect();
        next_to.sort_unstable();
        next_to.dedup();
        let found: Vec<(usize, Option<LocalQuadric>)> =
            next_to.par_iter().map(|&u| (u, good_fit(u))).collect();
        let good = found.iter().filter(|(_, q)| q.is_some()).count();
        if !next_to.is_empty() && good as f64 >= SMOOTH_GAP_SHARE * next_to.len() as f64 {
            smooth.extend(piece);
            smooth_gaps += 1;
            fits.extend(found);
        }
    }
    if smooth.is_empty() {
        return RimProjection::none(nv);
    }
    let in_rim = op.rings_around(&smooth, RIM_RINGS, |a| {
        !free[a] && !op.boundary[a] && densities[a] < RIM_DENSITY * median
    });
    let rim: Vec<usize> = (0..nv).filter(|&v| in_rim[v]).collect();
    let moved: Vec<Option<Point3<f64>>> = rim
        .par_iter()
        .map(|&u| {
            let p = match fits.get(&u) {
                Some(known) => known.as_ref()?.project(&vertices[u])?,
                None => good_fit(u)?.project(&vertices[u])?,
            };
            ((p - vertices[u]).norm() <= RIM_MAX_MOVE_EDGES * op.edge_scale).then_some(p)
        })
        .collect();
    let mut originals = Vec::new();
    for (&u, p) in rim.iter().zip(moved) {
        if let Some(p) = p {
            originals.push((u, mesh.vertices[u]));
            mesh.vertices[u] = p;
        }
    }
    RimProjection {
        originals,
        tangential: op.rings_around(&smooth, 2, |a| !free[a]),
        smooth_gaps,
    }
}

/// The median residual of the quadrics fitted ([`fit_around`]) at every
/// [`TYPICAL_FIT_STRIDE`]-th well-sampled vertex not on a boundary: how far the surface
/// departs from a quadric where nothing is wrong (its noise and small detail; 0.008 mm on the
/// default scan, 0.06 mm on the Stanford bunny's scans). `None` without any such fit.
fn typical_fit_residual(
    vertices: &[Point3<f64>],
    op: &Operator,
    normals: &[Vector3<f64>],
    well: &[bool],
    support: &[f64],
) -> Option<f64> {
    let residuals: Vec<f64> = (0..vertices.len())
        .into_par_iter()
        .step_by(TYPICAL_FIT_STRIDE)
        .filter(|&v| well[v] && !op.boundary[v])
        .filter_map(|v| fit_around(vertices, op, normals, support, v).map(|q| q.residual()))
        .collect();
    (!residuals.is_empty()).then(|| crate::trim::median_density(&residuals))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fair::tests::cap_rms;
    use crate::test_shapes::{cut_ball_distance, cut_ball_surface, partial_sphere_surface};
    use crate::{FairConfig, SimplifyConfig, fair_unsupported, simplify};

    /// With `project_rim` (the default), where the support ratio cuts hardly matters: on the
    /// 10 mm sphere without its 60° cap, freeing the vertices below 0.2, 0.3, 0.4 or 0.5 of
    /// the median density closes the cap within 0.0075 r RMS each time (measured 0.040,
    /// 0.028, 0.051, 0.029 mm; from Poisson's rim 0.20, 0.11, 0.47, 0.53 mm) — and only the
    /// rim moves besides the free vertices, by less than 0.02 r.
    #[test]
    fn support_ratio_hardly_matters() {
        let r = 10.0;
        let mut s = partial_sphere_surface(r, |_, n| n.z < 0.5);
        let d = simplify(&mut s.mesh, &s.densities, &SimplifyConfig::default()).unwrap();
        for ratio in [0.2, 0.3, 0.4, 0.5] {
            let mut m = s.mesh.clone();
            let cfg = FairConfig {
                support_ratio: ratio,
                project_rim: true,
                ..FairConfig::default()
            };
            let f = fair_unsupported(&mut m, &d.densities, &cfg).unwrap();
            let (rms, n) = cap_rms(&m, r, 0.6 * r);
            assert!(f.curvature_converged && n > 20, "{ratio}: {f:?}");
            assert!(rms < 0.0075 * r, "ratio {ratio}: cap RMS {rms}");
            // Besides the free vertices only the rim moves (density below half the median),
            // onto the sphere by about the bend Poisson left there.
            let mut sorted = d.densities.clone();
            sorted.sort_unstable_by(f64::total_cmp);
            let median = sorted[sorted.len() / 2];
            let (mut rim, mut largest) = (0, 0.0f64);
            for (v, (a, b)) in s.mesh.vertices.iter().zip(&m.vertices).enumerate() {
                let density = d.densities[v];
                if density >= RIM_DENSITY * median {
                    assert_eq!(a, b, "ratio {ratio}: vertex {v} of density {density} moved");
                } else if density >= ratio * median && a != b {
                    rim += 1;
                    largest = largest.max((a - b).norm());
                }
            }
            assert!(
                rim <= f.rim_moved && (rim > 0 || ratio >= RIM_DENSITY),
                "{rim} {f:?}"
            );
            assert!(
                largest < 0.02 * r,
                "ratio {ratio}: a rim vertex moved {largest}"
            );
        }
    }

    /// A gap where a flat bottom meets a ball's side (radius 10, bottom at z = −5.5; the
    /// two-placement pebble's gaps lie on such a crease): no quadric describes the surface
    /// there. Projecting the rim and keeping the fixed rows' tangential part made the gap
    /// twice as far off (0.138 → 0.277 mm RMS over the vertices near it, also with only
    /// the rim fits that pass the residual test moved: 0.276 mm); less than half of the
    /// fixed vertices next to it find a typical fit (29 of 60), so the gap is not taken
    /// for smooth surface and is faired from Poisson's rim: the same mesh as with
    /// `project_rim` off.
    #[test]
    fn rim_next_to_a_crease_stays() {
        let (r, cut) = (10.0f64, -5.5f64);
        let rho = (r * r - cut * cut).sqrt();
        let in_gap = |p: &Point3<f64>| {
            p.x > 0.0 && p.y.abs() < 0.6 * p.x && p.z < cut + 2.5 && p.x.hypot(p.y) > rho - 2.5
        };
        let mut s = cut_ball_surface(r, cut, |p, _| !in_gap(p));
        let d = simplify(&mut s.mesh, &s.densities, &SimplifyConfig::default()).unwrap();
        let near = |p: &Point3<f64>| {
            p.x > 0.0 && p.y.abs() < 0.9 * p.x && p.z < cut + 4.0 && p.x.hypot(p.y) > rho - 4.0
        };
        let rms = |m: &TriangleMesh| {
            let e: Vec<f64> = m
                .vertices
                .iter()
                .filter(|p| near(p))
                .map(|p| cut_ball_distance(p, r, cut))
                .collect();
            (
                (e.iter().map(|e| e * e).sum::<f64>() / e.len() as f64).sqrt(),
                e.len(),
            )
        };
        let mut plain = s.mesh.clone();
        let cfg = FairConfig {
            project_rim: false,
            ..FairConfig::default()
        };
        let f0 = fair_unsupported(&mut plain, &d.densities, &cfg).unwrap();
        let mut m = s.mesh.clone();
        let f = fair_unsupported(&mut m, &d.densities, &FairConfig::default()).unwrap();
        let (before, n) = rms(&s.mesh);
        let (rms0, _) = rms(&plain);
        eprintln!("near the gap ({n} vertices): {before:.4} → {rms0:.4}; {f0:?} {f:?}");
        assert!(
            n > 100 && f.vertices_moved > 50 && rms0 < before,
            "{n} {f:?}"
        );
        assert_eq!(f.rim_moved, 0);
        assert!(f.gaps == 1 && f.smooth_gaps == 0, "{f:?}");
        assert_eq!(m.vertices, plain.vertices);
    }
}
