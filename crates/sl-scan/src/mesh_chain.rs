//! The mesh chain of `slscan mesh`: a cloud with oriented normals, rid of its far stray points,
//! to a closed surface through screened Poisson, then the optional trim, simplification, fairing of the unseen surface,
//! isotropic remeshing, hole filling, removal of small pieces, smoothing and decimation, each
//! step timed and its figures kept.

use std::borrow::Cow;

use serde_json::json;
use sl_cloud::{FarPointConfig, PointCloud, remove_far_points};
use sl_mesh::{
    BilateralConfig, Decimation, FairConfig, Fairing, HoleFilling, MeshError, PoissonConfig,
    RemeshConfig, Remeshing, Simplification, SimplifyConfig, TaubinConfig, Topology, TriangleMesh,
    check_topology, decimate, fair_unsupported, fill_holes, inconsistent_normal_fraction,
    largest_piece, poisson_reconstruct, remesh_isotropic, remove_small_components, simplify,
    smooth_bilateral, smooth_taubin, trim_by_density,
};

use crate::progress::timed;
use crate::{ScanError, StageTime};

/// The orientation check of the normals (`sl_mesh::inconsistent_normal_fraction`): every
/// `ORIENTATION_STRIDE`-th point with its `ORIENTATION_NEIGHBOURS` nearest among those.
const ORIENTATION_NEIGHBOURS: usize = 8;
/// See [`ORIENTATION_NEIGHBOURS`].
const ORIENTATION_STRIDE: usize = 4;

/// Smoothing applied after the reconstruction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum MeshSmoothing {
    /// None.
    #[default]
    None,
    /// Bilateral: removes noise, keeps edges.
    Bilateral(BilateralConfig),
    /// Taubin λ|μ: removes noise, rounds edges.
    Taubin(TaubinConfig),
}

/// The steps of [`mesh_chain`] and their settings; `None` leaves a step out.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshChainConfig {
    /// Drop the points far from the rest of the cloud before the octree is sized to its box
    /// (`sl_cloud::remove_far_points`): two stray points at ±1e30 mm would otherwise make
    /// the finest cells 1e28 mm wide and the surface nonsense. `None` keeps every point.
    pub far_points: Option<FarPointConfig>,
    /// The screened Poisson reconstruction.
    pub poisson: PoissonConfig,
    /// Remove surface whose sampling density is below this fraction of the median.
    pub trim: Option<f64>,
    /// The error-bounded simplification.
    pub simplify: Option<SimplifyConfig>,
    /// The fairing of the surface no sample supports (only after a simplification).
    pub fair: Option<FairConfig>,
    /// The isotropic remeshing.
    pub remesh: Option<RemeshConfig>,
    /// Close holes whose rim has at most this many edges.
    pub fill_holes: Option<usize>,
    /// Remove pieces of fewer triangles than this (0 leaves the mesh as it is).
    pub min_piece: usize,
    /// Smoothing after the steps above.
    pub smooth: MeshSmoothing,
    /// Decimate to at most this many triangles (quadric error).
    pub triangles: Option<usize>,
}

impl Default for MeshChainConfig {
    /// The defaults of `slscan mesh`: simplified and faired, pieces under 100 triangles removed.
    fn default() -> Self {
        Self {
            far_points: Some(FarPointConfig::default()),
            poisson: PoissonConfig::default(),
            trim: None,
            simplify: Some(SimplifyConfig::default()),
            fair: Some(FairConfig::default()),
            remesh: None,
            fill_holes: None,
            min_piece: 100,
            smooth: MeshSmoothing::None,
            triangles: None,
        }
    }
}

/// What [`mesh_chain`] made: the mesh, what each step did and how long it took.
#[derive(Debug, Clone)]
pub struct MeshChain {
    /// The final mesh (mm).
    pub mesh: TriangleMesh,
    /// Its topology.
    pub topology: Topology,
    /// Fraction of the points whose normal faces away from the largest consistently oriented
    /// patch around them (`None` when the cloud is too small to tell).
    pub normals_inconsistent: Option<f64>,
    /// The far points dropped before the reconstruction (none when
    /// [`MeshChainConfig::far_points`] is `None`).
    pub far_points: FarPointsDropped,
    /// Samples the reconstruction used.
    pub samples: usize,
    /// Size of the finest octree cell (mm).
    pub cell_size: f64,
    /// Milliseconds of the Poisson solve.
    pub solve_ms: f64,
    /// Milliseconds of the contouring.
    pub contour_ms: f64,
    /// Vertices of the extracted surface.
    pub vertices_extracted: usize,
    /// Triangles of the extracted surface.
    pub triangles_extracted: usize,
    /// The trim: triangles removed and the density threshold (per mm²).
    pub trimmed: Option<(usize, f64)>,
    /// The simplification and its milliseconds.
    pub simplified: Option<(Simplification, f64)>,
    /// The fairing and its milliseconds.
    pub faired: Option<(Fairing, f64)>,
    /// The remeshing and its milliseconds.
    pub remeshed: Option<(Remeshing, f64)>,
    /// The hole filling.
    pub holes: Option<HoleFilling>,
    /// Pieces removed for being smaller than `min_piece`.
    pub small_pieces_removed: usize,
    /// The decimation.
    pub decimated: Option<Decimation>,
    /// Per-step timings, in the order run.
    pub stages: Vec<StageTime>,
    /// The mesh's vertex colours from the cloud's, when it has colours: each vertex the mean
    /// of its [`COLOUR_NEIGHBOURS`] nearest points' (`slscan mesh` of a colour scan's
    /// `merged.ply`; a scan itself blends its views' images instead,
    /// [`ScanColours`](crate::ScanColours)).
    pub vertex_colours: Option<Vec<[u8; 3]>>,
}

/// The far points [`mesh_chain`] dropped (`sl_cloud::remove_far_points`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FarPointsDropped {
    /// Points dropped, non-finite ones included.
    pub count: usize,
    /// The largest distance (mm) of a dropped finite point from the cloud's median centre.
    pub farthest_mm: f64,
    /// The robust radius (mm): the distance from the median centre within which the
    /// configured quantile of the points lie.
    pub radius_mm: f64,
    /// The distance (mm) beyond which points were dropped.
    pub threshold_mm: f64,
}

impl MeshChain {
    /// The line to print when far points were dropped (`None` when none was).
    #[must_use]
    pub fn far_points_summary(&self) -> Option<String> {
        let f = &self.far_points;
        (f.count > 0).then(|| {
            format!(
                "dropped {} far point(s) before meshing (the farthest {:.3e} mm from the \
                 cloud's median centre; 99 % of the points lie within {:.1} mm, points beyond \
                 {:.1} mm are dropped)",
                f.count, f.farthest_mm, f.radius_mm, f.threshold_mm
            )
        })
    }

    /// The figures of the steps that ran, by name, as `report.json` holds them (what each step
    /// did, its settings and milliseconds), in the order of the chain.
    #[must_use]
    pub fn figures(&self, cfg: &MeshChainConfig) -> Vec<(&'static str, serde_json::Value)> {
        let mut f: Vec<(&'static str, serde_json::Value)> = Vec::new();
        f.push(("far_points_dropped", self.far_points.count.into()));
        if self.far_points.count > 0 {
            f.push((
                "far_points",
                json!({
                    "farthest_mm": self.far_points.farthest_mm,
                    "robust_radius_mm": self.far_points.radius_mm,
                    "threshold_mm": self.far_points.threshold_mm,
                }),
            ));
        }
        if let Some(x) = self.normals_inconsistent {
            f.push(("normals_inconsistent", x.into()));
        }
        if let Some((removed, threshold)) = self.trimmed {
            f.push(("trimmed_triangles", removed.into()));
            f.push(("trim_density_per_mm2", threshold.into()));
        }
        if let (Some((s, ms)), Some(c)) = (&self.simplified, &cfg.simplify) {
            f.push(("simplify_ms", (*ms).into()));
            f.push((
                "simplify",
                json!({
                    "vertices_before": s.vertices_before,
                    "vertices_after": s.vertices_after,
                    "triangles_before": s.triangles_before,
                    "triangles_after": s.triangles_after,
                    "unsupported_vertices_before": s.unsupported_before,
                    "unsupported_vertices_after": s.unsupported_after,
                    "support_density_per_mm2": s.support_threshold,
                    "max_error_mm": c.max_error,
                    "unsupported_max_error_mm": c.unsupported_max_error,
                    "largest_error_mm": s.largest_error,
                    "largest_unsupported_error_mm": s.largest_unsupported_error,
                    "passes": s.passes,
                }),
            ));
        }
        if let (Some((d, ms)), Some(c)) = (&self.faired, &cfg.fair) {
            f.push(("fair_ms", (*ms).into()));
            f.push((
                "fair",
                json!({
                    "support_ratio": c.support_ratio,
                    "vertices_moved": d.vertices_moved,
                    "gaps": d.gaps,
                    "smooth_gaps": d.smooth_gaps,
                    "project_rim": c.project_rim,
                    "rim_moved": d.rim_moved,
                    "largest_move_mm": d.largest_move,
                    "residual": d.residual,
                    "curvature_steps": d.curvature_steps,
                    "curvature_converged": d.curvature_converged,
                    "mean_curvature_per_mm": d.mean_curvature,
                }),
            ));
        }
        if let Some((r, ms)) = &self.remeshed {
            f.push(("remesh_ms", (*ms).into()));
            f.push((
                "remesh",
                json!({
                    "target_edge_mm": r.target_edge,
                    "vertices_before": r.vertices_before,
                    "vertices_after": r.vertices_after,
                    "splits": r.splits,
                    "collapses": r.collapses,
                    "flips": r.flips,
                    "rms_distance_mm": r.rms_distance,
                    "largest_distance_mm": r.largest_distance,
                }),
            ));
        }
        if let Some(h) = &self.holes {
            f.push(("holes_filled", h.filled.into()));
            f.push(("holes_left_open", (h.holes - h.filled).into()));
        }
        f.push(("small_pieces_removed", self.small_pieces_removed.into()));
        if let Some(d) = &self.decimated {
            f.push(("decimation_max_error_mm2", d.max_error.into()));
        }
        let t = &self.topology;
        f.extend([
            ("samples", self.samples.into()),
            ("depth", cfg.poisson.depth.into()),
            ("cell_size_mm", self.cell_size.into()),
            ("vertices_extracted", self.vertices_extracted.into()),
            ("triangles_extracted", self.triangles_extracted.into()),
            ("vertices", self.mesh.vertices.len().into()),
            ("triangles", self.mesh.triangles.len().into()),
            ("watertight", t.is_watertight().into()),
            ("manifold", t.is_manifold().into()),
            ("oriented", (t.misoriented_edges == 0).into()),
            ("components", t.components.into()),
            ("boundary_edges", t.boundary_edges.into()),
            ("solve_ms", self.solve_ms.into()),
            ("contour_ms", self.contour_ms.into()),
        ]);
        f
    }
}

fn step(name: &'static str) -> impl FnOnce(MeshError) -> ScanError {
    move |source| ScanError::MeshStep { step: name, source }
}

/// Milliseconds of the step [`timed`] recorded last.
fn last_ms(stages: &[StageTime]) -> f64 {
    stages.last().map_or(0.0, |s| s.ms)
}

/// Meshes `cloud` (mm, with oriented normals) through the steps of `cfg`: the chain of
/// `slscan mesh`.
///
/// When no piece of the extracted surface has `cfg.min_piece` triangles, the octree is too
/// coarse for the cloud: the chain is run again at the next depths, up to the default depth
/// (or the one asked, if deeper), and the error says the smallest that leaves a mesh. A depth
/// multiplies a surface's triangles by about 4, so a depth at which even that growth could not
/// reach `min_piece` is not tried: the search costs at most about one run at the default depth.
///
/// # Errors
/// [`ScanError::MeshStep`] naming the step that failed (`reconstruct`, `trim`, `simplify`,
/// `fair`, `remesh`, `fill holes`, `smooth`, `decimate`); [`ScanError::MeshTooCoarse`] when
/// the surface extracted has no piece of `min_piece` triangles (with the depth that meshes the
/// cloud, if one does); [`ScanError::Stage`] when the steps after the reconstruction leave no
/// piece of `min_piece` triangles.
pub fn mesh_chain(cloud: &PointCloud, cfg: &MeshChainConfig) -> Result<MeshChain, ScanError> {
    match run_chain(cloud, cfg) {
        Err(ScanError::MeshTooCoarse {
            depth,
            cell_mm,
            extracted,
            largest_piece,
            min_piece,
            ..
        }) => {
            let (meshes_at, searched_to) = depth_that_meshes(cloud, cfg, largest_piece);
            Err(ScanError::MeshTooCoarse {
                depth,
                cell_mm,
                extracted,
                largest_piece,
                min_piece,
                meshes_at,
                searched_to,
            })
        }
        other => other,
    }
}

/// Growth of a surface's triangle count from one octree depth to the next: the cells halve, so
/// a surface crosses about four times as many.
const TRIANGLES_PER_LEVEL: f64 = 4.0;

/// Margin of the search of [`depth_that_meshes`] over [`TRIANGLES_PER_LEVEL`]: one more level's
/// worth, so that a surface growing faster than a closed one (thin parts that a coarser octree
/// missed appear) is not given up too early.
const GROWTH_SLACK: f64 = 4.0;

/// The smallest depth deeper than `cfg`'s at which the chain leaves a mesh of `cloud`, if one
/// up to the default depth (or `cfg`'s, if deeper) does, and that last depth. `largest` is the
/// largest piece extracted at `cfg`'s depth.
fn depth_that_meshes(
    cloud: &PointCloud,
    cfg: &MeshChainConfig,
    largest: usize,
) -> (Option<u32>, u32) {
    let last = PoissonConfig::default().depth.max(cfg.poisson.depth);
    let mut largest = largest;
    for depth in cfg.poisson.depth + 1..=last {
        // The largest piece at the depth before this one, grown to the last depth.
        let levels = f64::from(last + 1 - depth);
        let reachable = largest as f64 * TRIANGLES_PER_LEVEL.powf(levels) * GROWTH_SLACK;
        if largest > 0 && reachable < cfg.min_piece as f64 {
            break;
        }
        let deeper = MeshChainConfig {
            poisson: PoissonConfig {
                depth,
                ..cfg.poisson.clone()
            },
            ..cfg.clone()
        };
        match run_chain(cloud, &deeper) {
            Ok(_) => return (Some(depth), last),
            Err(ScanError::MeshTooCoarse { largest_piece, .. }) => largest = largest_piece,
            // A later step left nothing at this depth; a deeper one may still mesh.
            Err(_) => {}
        }
    }
    (None, last)
}

/// [`mesh_chain`] at `cfg`'s depth only ([`ScanError::MeshTooCoarse`] without a search).
fn run_chain(cloud: &PointCloud, cfg: &MeshChainConfig) -> Result<MeshChain, ScanError> {
    let mut stages = Vec::new();
    let mut far_points = FarPointsDropped::default();
    let cloud: Cow<'_, PointCloud> = match &cfg.far_points {
        Some(c) => {
            let far = timed(&mut stages, "far points", || remove_far_points(cloud, c))?;
            far_points = FarPointsDropped {
                count: far.outliers.len(),
                farthest_mm: far.farthest,
                radius_mm: far.radius,
                threshold_mm: far.threshold,
            };
            if far.outliers.is_empty() {
                Cow::Borrowed(cloud)
            } else {
                Cow::Owned(far.cloud)
            }
        }
        None => Cow::Borrowed(cloud),
    };
    let cloud = cloud.as_ref();
    let normals_inconsistent = timed(&mut stages, "orientation", || {
        inconsistent_normal_fraction(cloud, ORIENTATION_NEIGHBOURS, ORIENTATION_STRIDE)
    })
    .map_err(step("orientation"))?;
    let mut surface = timed(&mut stages, "reconstruct", || {
        poisson_reconstruct(cloud, &cfg.poisson)
    })
    .map_err(step("reconstruct"))?;
    let (vertices_extracted, triangles_extracted) =
        (surface.mesh.vertices.len(), surface.mesh.triangles.len());
    let largest_extracted = if cfg.min_piece > 0 {
        largest_piece(&surface.mesh)
    } else {
        triangles_extracted
    };
    let mut mesh = std::mem::take(&mut surface.mesh);
    let mut densities = std::mem::take(&mut surface.densities);
    let mut trimmed = None;
    if let Some(ratio) = cfg.trim {
        let t = timed(&mut stages, "trim", || {
            trim_by_density(&mesh, &densities, ratio)
        })
        .map_err(step("trim"))?;
        trimmed = Some((t.triangles_removed, t.threshold));
        mesh = t.mesh;
        densities = t.densities;
    }
    let (mut simplified, mut faired) = (None, None);
    if let Some(s) = &cfg.simplify {
        let done = timed(&mut stages, "simplify", || {
            simplify(&mut mesh, &densities, s)
        })
        .map_err(step("simplify"))?;
        densities = done.densities.clone();
        simplified = Some((done, last_ms(&stages)));
        if let Some(f) = &cfg.fair {
            let done = timed(&mut stages, "fair", || {
                fair_unsupported(&mut mesh, &densities, f)
            })
            .map_err(step("fair"))?;
            faired = Some((done, last_ms(&stages)));
        }
    }
    let mut remeshed = None;
    if let Some(r) = &cfg.remesh {
        let done = timed(&mut stages, "remesh", || {
            remesh_isotropic(&mut mesh, &mut densities, r)
        })
        .map_err(step("remesh"))?;
        remeshed = Some((done, last_ms(&stages)));
    }
    let holes = match cfg.fill_holes {
        Some(max_edges) => Some(
            timed(&mut stages, "fill holes", || {
                fill_holes(&mut mesh, max_edges)
            })
            .map_err(step("fill holes"))?,
        ),
        None => None,
    };
    // Pieces of fewer than 0 triangles: none, and the mesh is left as it is (not compacted).
    let small_pieces_removed = if cfg.min_piece > 0 {
        timed(&mut stages, "small pieces", || {
            remove_small_components(&mut mesh, cfg.min_piece)
        })
    } else {
        0
    };
    match &cfg.smooth {
        MeshSmoothing::None => {}
        MeshSmoothing::Bilateral(c) => {
            timed(&mut stages, "smooth", || smooth_bilateral(&mut mesh, c))
                .map_err(step("smooth"))?;
        }
        MeshSmoothing::Taubin(c) => {
            timed(&mut stages, "smooth", || smooth_taubin(&mut mesh, c)).map_err(step("smooth"))?;
        }
    }
    let decimated = match cfg.triangles {
        Some(n) => Some(
            timed(&mut stages, "decimate", || decimate(&mut mesh, n)).map_err(step("decimate"))?,
        ),
        None => None,
    };
    if mesh.triangles.is_empty() {
        if largest_extracted < cfg.min_piece.max(1) {
            return Err(ScanError::MeshTooCoarse {
                depth: cfg.poisson.depth,
                cell_mm: surface.cell_size,
                extracted: triangles_extracted,
                largest_piece: largest_extracted,
                min_piece: cfg.min_piece,
                meshes_at: None,
                searched_to: cfg.poisson.depth,
            });
        }
        // The extraction had a piece large enough: the steps after it (whose bounds are in
        // mm) left nothing of it.
        return Err(ScanError::Stage {
            stage: "mesh".to_owned(),
            reason: format!(
                "no triangle is left of the mesh ({triangles_extracted} extracted, its largest \
                 piece {largest_extracted}; the steps after the reconstruction left no piece of \
                 {} triangles): is the cloud in mm?",
                cfg.min_piece
            ),
        });
    }
    let vertex_colours = match cloud.colors() {
        Some(colours) => Some(timed(&mut stages, "colour", || {
            colours_from_cloud(cloud.positions(), colours, &mesh.vertices)
        })?),
        None => None,
    };
    let topology = timed(&mut stages, "check", || check_topology(&mesh));
    Ok(MeshChain {
        mesh,
        topology,
        normals_inconsistent,
        far_points,
        samples: surface.samples,
        cell_size: surface.cell_size,
        solve_ms: surface.solve_ms,
        contour_ms: surface.contour_ms,
        vertices_extracted,
        triangles_extracted,
        trimmed,
        simplified,
        faired,
        remeshed,
        vertex_colours,
        holes,
        small_pieces_removed,
        decimated,
        stages,
    })
}

/// Nearest cloud points whose colours a mesh vertex takes the mean of
/// ([`MeshChain::vertex_colours`]): a few, so that one point's noise does not show, the
/// colour blurred by no more than the cloud's spacing.
pub const COLOUR_NEIGHBOURS: usize = 4;

/// Each of `vertices` coloured with the rounded mean colour of its [`COLOUR_NEIGHBOURS`]
/// nearest `points` (whose colours are `colours`).
///
/// # Errors
/// [`ScanError::Cloud`] when the points cannot be indexed.
fn colours_from_cloud(
    points: &[nalgebra::Point3<f64>],
    colours: &[[u8; 3]],
    vertices: &[nalgebra::Point3<f64>],
) -> Result<Vec<[u8; 3]>, ScanError> {
    use rayon::prelude::*;
    let index = sl_cloud::KdIndex::new(points)?;
    Ok(vertices
        .par_iter()
        .map_init(Vec::new, |near, v| {
            index.knn_into(v, COLOUR_NEIGHBOURS, near);
            let mut sum = [0u32; 3];
            for n in near.iter() {
                let c = colours
                    .get(n.index)
                    .copied()
                    .unwrap_or(crate::UNSEEN_COLOUR);
                for k in 0..3 {
                    sum[k] += u32::from(c[k]);
                }
            }
            let n = near.len().max(1) as u32;
            sum.map(|s| ((s + n / 2) / n) as u8)
        })
        .collect())
}

#[cfg(test)]
mod colour_tests {
    use super::*;
    use nalgebra::Point3;

    #[test]
    fn vertices_take_their_nearest_points_colours() {
        // Red points at x < 0, blue at x > 0, on a line 1 mm apart.
        let points: Vec<Point3<f64>> = (-10..=10)
            .filter(|&i| i != 0)
            .map(|i| Point3::new(f64::from(i), 0.0, 0.0))
            .collect();
        let colours: Vec<[u8; 3]> = points
            .iter()
            .map(|p| if p.x < 0.0 { [200, 0, 0] } else { [0, 0, 200] })
            .collect();
        let vertices = [Point3::new(-7.2, 0.3, 0.0), Point3::new(6.6, 0.0, -0.2)];
        let got = colours_from_cloud(&points, &colours, &vertices).unwrap();
        assert_eq!(got, vec![[200, 0, 0], [0, 0, 200]]);
        // At the boundary, the mean of two of each.
        let mid = colours_from_cloud(&points, &colours, &[Point3::origin()]).unwrap();
        assert_eq!(mid, vec![[100, 0, 100]]);
    }
}
