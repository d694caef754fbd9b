//! Screened Poisson surface reconstruction (Kazhdan & Hoppe, "Screened Poisson surface
//! reconstruction", ACM Transactions on Graphics 2013) on an adaptive octree.
//!
//! The indicator function `χ` of the solid minimises
//! `∫ |∇χ − V|² + α Σ_s a_s χ(s)²`: its gradient follows the vector field `V` of the oriented
//! samples, and the screening term pulls its zero set through the samples. `χ` is a sum of
//! trilinear B-splines over the nodes of an octree:
//!
//! - levels `0..=full_depth` (default 5) cover the whole (padded) bounding cube: the far
//!   field, where the surface has no data, comes from them;
//! - deeper levels hold nodes only in a band of one cell around the cells holding samples.
//!
//! Where the scanner saw nothing (the lower back of the default scan's spheres, a patch some
//! 45 × 40 mm), the surface is the zero set of the deepest level reaching there: level
//! `full_depth` in the middle of a wide gap. A level solved to convergence over a gap gives
//! plain Poisson's answer there, the harmonic membrane spanning the gap's rim, which is flat;
//! the coarser the level, the more its restricted normal field spreads over the gap and the
//! more its zero set keeps the curvature around it. On two spheres of radius 25 mm sampled
//! exactly without their lower back (`y > 0.4 r`, `z > 0`; depth 9; the test `gap_profile`
//! prints it) the zero crossing along rays through the gap lies on average 1.2 mm inside the
//! sphere with level 5 (5.8 mm cells, RMS 1.42 mm), 0.2 mm outside with level 4 (11.7 mm,
//! RMS 0.49 mm); with `full_depth` 4 the extracted surface is at 0.65 mm RMS there instead of
//! 1.40. The shape is not the data's, though: one sphere filling the cube (the usual single
//! scanned object, its gap near the cube's faces) is closed by a surface bulging outwards at
//! either full depth, more at 4 (0.93 mm RMS) than at 5 (0.82 mm). So 5 stays the default and
//! 4 is the better choice for objects small in the cube.
//!
//! The finite-element system of every level is the Galerkin projection of the same energy (the
//! right-hand side of a level is the restriction of the finest one), solved coarse to fine
//! (cascadic multigrid): a level starts from the prolongation of the coarser solution and
//! Jacobi-preconditioned conjugate gradients relax it (6 iterations per band level by
//! default). A band level's domain is the union of its cells that have all eight corners; on
//! its rim the condition is the natural one (as on the cube's faces), so the coarser solution
//! enters only as the starting point. Keeping the rim nodes at the coarser level's values
//! instead (as until 2026-11-26) held the finest zero set a few hundredths of a cell off: on
//! exact spheres the vertices near the samples were at 3.3 % of a cell RMS with that, 1.2 %
//! with the natural rim (0.0120 → 0.0045 mm at 0.365 mm cells), and 6 iterations give the
//! same figures as 25. The surface is the level set of `χ` at the weighted mean of `χ` over
//! the samples, extracted on the finest grid by
//! [`contour`](crate::contour) — one value per grid node, so the mesh is watertight. Where a
//! grid node lies outside the finest band (a gap in the data), its value comes from the deepest
//! level that reaches it, measured against that level's own iso-value (the mean of that level's
//! `χ` over the samples): a coarse level's `χ` is a more blurred indicator, and its own
//! iso-value keeps the closing surface from shrinking by that blur.
//!
//! Samples carry an area `a_s` (the inverse of the local sampling density, estimated two levels
//! above the finest), so that overlapping views of a merged scan do not weigh twice.

use std::time::Instant;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::{PointCloud, TriangleMesh};

use crate::MeshError;
use crate::contour::{ContourInput, contour};
use crate::grid::{MAX_DEPTH, NodeSet};

/// Fewest usable points (finite, with a normal) accepted: fewer cannot outline a closed surface
/// at any useful depth, and the density estimate needs several points per cell.
pub const MIN_POISSON_POINTS: usize = 16;

/// The sampling density is estimated this many levels above the finest: cells four times the
/// finest hold enough samples (tens) for a stable count even where a merged scan is thin.
const DENSITY_LEVELS_UP: u32 = 2;

/// Mean over the offset `t` of a plane in a cell of `(1 − t)² + t²`: the interpolated trilinear
/// splat of a uniformly sampled plane is this fraction of `ρ h²` (ρ samples per area).
const DENSITY_KERNEL_MEAN: f64 = 2.0 / 3.0;

/// The coarsest level solved: below it the grid has too few nodes to matter (9 at level 1).
const COARSEST_LEVEL: u32 = 2;

/// Conjugate-gradient iterations at the fully populated levels (at most 17³ nodes at the
/// default `full_depth`, 129³ at its largest, 7); they start the cascade and must converge.
const FULL_LEVEL_ITERATIONS: usize = 200;

/// Relative residual at which a level's conjugate gradients stop early.
const CG_TOLERANCE: f64 = 1e-7;

/// Parameters of [`poisson_reconstruct`].
#[derive(Debug, Clone, PartialEq)]
pub struct PoissonConfig {
    /// Depth of the finest octree level: its cells are the bounding cube (times
    /// [`scale`](Self::scale)) divided by `2^depth`. 9 (as Open3D's comparison here) gives
    /// 0.3 mm cells on the 130 mm scene of the default scan. At most 10.
    pub depth: u32,
    /// Levels `0..=full_depth` cover the whole cube; deeper ones only a band around the samples.
    /// 4 by default: the surface closing a gap in the data comes from this level (see the
    /// module documentation for why 4 and not 5).
    pub full_depth: u32,
    /// Ratio of the cube's edge to the largest extent of the samples (≥ 1): the margin keeps the
    /// surface away from the cube's faces. 1.1 as Kazhdan's and Open3D's default.
    pub scale: f64,
    /// Screening weight `α` (Kazhdan & Hoppe's default 4): how strongly the surface is pulled
    /// through the samples rather than only following their normals. 0 is plain Poisson.
    pub screening: f64,
    /// Conjugate-gradient iterations per band level (each starts from the coarser solution).
    /// 6 by default: on the default scan's cloud and on exact spheres 4, 6, 10 and 25 give the
    /// same surface to 0.0002 mm where the data is (the level starts from the coarser solution
    /// and only corrects it near the samples).
    pub iterations: usize,
}

impl Default for PoissonConfig {
    fn default() -> Self {
        Self {
            depth: 9,
            full_depth: 5,
            scale: 1.1,
            screening: 4.0,
            iterations: 6,
        }
    }
}

/// What [`poisson_reconstruct`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct PoissonSurface {
    /// The closed surface, in the cloud's frame and units; triangles wind counter-clockwise
    /// seen from outside (normals point out of the solid).
    pub mesh: TriangleMesh,
    /// Sampling density at each vertex, in samples per unit area of the cloud's units (per mm²
    /// for a scan): low where the surface bridges a gap in the data. See
    /// `trim_by_density`.
    pub densities: Vec<f64>,
    /// Nodes of each solved octree level, coarse to fine (starting at level 2).
    pub nodes_per_level: Vec<usize>,
    /// Number of usable samples (finite, with a normal).
    pub samples: usize,
    /// Edge of a finest cell, in the cloud's units.
    pub cell_size: f64,
    /// Wall time of the solve (octree, system, conjugate gradients), milliseconds.
    pub solve_ms: f64,
    /// Wall time of the surface extraction, milliseconds.
    pub contour_ms: f64,
}

/// One octree level: its nodes, solution and right-hand side.
struct Level {
    depth: u32,
    nodes: NodeSet,
    /// Whether every node of the level's grid is present.
    full: bool,
    /// Solution at each node slot.
    x: Vec<f64>,
    /// Right-hand side `∫ ∇B_i · V` at each node slot.
    b: Vec<f64>,
    /// Iso-value of this level's own `χ`: the area-weighted mean of it over the samples.
    iso: f64,
}

impl Level {
    fn cells(&self) -> i64 {
        1 << self.depth
    }
}

/// A cluster of samples: all those of one finest cell, at their area-weighted centroid.
#[derive(Debug, Clone, Copy)]
struct SuperSample {
    /// Position in the unit cube.
    u: [f64; 3],
    /// Sum of the sample areas.
    area: f64,
    /// Finest cell.
    cell: [i64; 3],
}

/// Reconstructs a closed surface from a cloud with oriented normals (screened Poisson).
///
/// Points with a non-finite coordinate or without a normal (zero or non-finite) are ignored.
///
/// # Errors
/// [`MeshError::NoNormals`] when the cloud has no normals, [`MeshError::TooFewPoints`] with
/// fewer than [`MIN_POISSON_POINTS`] usable points, [`MeshError::DegenerateCloud`] when they are
/// all at one position, [`MeshError::InvalidParameter`] for a parameter out of range.
///
/// ```
/// use nalgebra::{Point3, Vector3};
/// use sl_cloud::PointCloud;
/// use sl_mesh::{PoissonConfig, check_topology, poisson_reconstruct};
///
/// // 4000 points of a sphere of radius 10 with outward normals.
/// let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
/// let (pts, nrm): (Vec<_>, Vec<_>) = (0..4000)
///     .map(|i| {
///         let z = 1.0 - 2.0 * (i as f64 + 0.5) / 4000.0;
///         let r = (1.0 - z * z).sqrt();
///         let n = Vector3::new(r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z);
///         (Point3::from(n * 10.0), n)
///     })
///     .unzip();
/// let cloud = PointCloud::from_positions(pts).with_normals(nrm)?;
/// let cfg = PoissonConfig { depth: 6, ..PoissonConfig::default() };
/// let surface = poisson_reconstruct(&cloud, &cfg)?;
/// assert!(check_topology(&surface.mesh).is_watertight_manifold());
/// let worst = surface.mesh.vertices.iter().map(|p| (p.coords.norm() - 10.0).abs()).fold(0.0, f64::max);
/// assert!(worst < 0.3, "{worst}");
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn poisson_reconstruct(
    cloud: &PointCloud,
    cfg: &PoissonConfig,
) -> Result<PoissonSurface, MeshError> {
    let t0 = Instant::now();
    let Solved {
        levels,
        supers,
        density,
        h_dd,
        centre,
        size,
        samples,
        nodes_per_level,
    } = solve(cloud, cfg)?;
    let depth = cfg.depth;
    let finest = 1i64 << depth;
    let solve_ms = t0.elapsed().as_secs_f64() * 1e3;

    let t1 = Instant::now();
    let finest_level = &levels[depth as usize];
    let seeds: Vec<[i64; 3]> = supers.iter().map(|s| s.cell).collect();
    let coarser = &levels[..depth as usize];
    let value = |x: i64, y: i64, z: i64| -> f64 {
        let v = match finest_level.nodes.slot(x, y, z) {
            Some(s) => finest_level.x[s as usize],
            None => {
                let h = 1.0 / finest as f64;
                return eval_above_iso(coarser, [x as f64 * h, y as f64 * h, z as f64 * h]);
            }
        };
        v - finest_level.iso
    };
    let unit_mesh = contour(&ContourInput {
        cells: finest,
        seeds: &seeds,
        value: &value,
    });
    let contour_ms = t1.elapsed().as_secs_f64() * 1e3;
    let unit_area = size * size;
    let densities = unit_mesh
        .vertices
        .iter()
        .map(|u| {
            let u = [u.x, u.y, u.z];
            density.at(&u) / (DENSITY_KERNEL_MEAN * h_dd * h_dd) / unit_area
        })
        .collect();
    let vertices = unit_mesh
        .vertices
        .iter()
        .map(|u| centre + Vector3::new(u.x - 0.5, u.y - 0.5, u.z - 0.5) * size)
        .collect();
    Ok(PoissonSurface {
        mesh: TriangleMesh {
            vertices,
            triangles: unit_mesh.triangles,
        },
        densities,
        nodes_per_level,
        samples,
        cell_size: size / finest as f64,
        solve_ms,
        contour_ms,
    })
}

/// The solved octree and what extraction needs of the set-up.
struct Solved {
    levels: Vec<Level>,
    supers: Vec<SuperSample>,
    density: DensityGrid,
    /// Cell edge of the density grid, in the unit cube.
    h_dd: f64,
    centre: Point3<f64>,
    /// Edge of the cube, in the cloud's units.
    size: f64,
    samples: usize,
    nodes_per_level: Vec<usize>,
}

/// Builds the octree, the system of every level and solves it coarse to fine.
fn solve(cloud: &PointCloud, cfg: &PoissonConfig) -> Result<Solved, MeshError> {
    validate(cfg)?;
    let Some(normals) = cloud.normals() else {
        return Err(MeshError::NoNormals {
            points: cloud.len(),
        });
    };
    let samples: Vec<(Point3<f64>, Vector3<f64>)> = cloud
        .positions()
        .iter()
        .zip(normals)
        .filter(|(p, n)| {
            p.coords.iter().all(|c| c.is_finite())
                && n.iter().all(|c| c.is_finite())
                && n.norm() > 0.5
        })
        .map(|(p, n)| (*p, n.normalize()))
        .collect();
    if samples.len() < MIN_POISSON_POINTS {
        return Err(MeshError::TooFewPoints {
            found: samples.len(),
            min: MIN_POISSON_POINTS,
        });
    }
    let (mut lo, mut hi) = (samples[0].0, samples[0].0);
    for (p, _) in &samples {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let extent = (hi - lo).max();
    if extent.is_nan() || extent <= 0.0 {
        return Err(MeshError::DegenerateCloud {
            points: samples.len(),
        });
    }
    let size = extent * cfg.scale;
    let centre = nalgebra::center(&lo, &hi);
    let to_unit = |p: &Point3<f64>| -> [f64; 3] {
        let q = (p - centre) / size;
        [q.x + 0.5, q.y + 0.5, q.z + 0.5]
    };
    let depth = cfg.depth;
    let finest = 1i64 << depth;
    let units: Vec<[f64; 3]> = samples.iter().map(|(p, _)| to_unit(p)).collect();

    // Sample areas from the density two levels up.
    let dd = depth.saturating_sub(DENSITY_LEVELS_UP);
    let density = DensityGrid::new(dd, &units);
    let h_dd = 1.0 / f64::from(1u32 << dd);
    let areas: Vec<f64> = units
        .iter()
        .map(|u| DENSITY_KERNEL_MEAN * h_dd * h_dd / density.at(u).max(f64::MIN_POSITIVE))
        .collect();

    // Finest cells and their super-samples.
    let cell_of = |u: &[f64; 3]| -> [i64; 3] {
        let c = |v: f64| ((v * finest as f64).floor() as i64).clamp(0, finest - 1);
        [c(u[0]), c(u[1]), c(u[2])]
    };
    let mut order: Vec<(u64, u32)> = units
        .iter()
        .enumerate()
        .map(|(i, u)| {
            let c = cell_of(u);
            ((((c[2] * finest) + c[1]) * finest + c[0]) as u64, i as u32)
        })
        .collect();
    order.par_sort_unstable();
    let mut supers: Vec<SuperSample> = Vec::new();
    let mut i = 0;
    while i < order.len() {
        let key = order[i].0;
        let mut acc = [0.0; 3];
        let mut area = 0.0;
        let first = order[i].1 as usize;
        while i < order.len() && order[i].0 == key {
            let s = order[i].1 as usize;
            for a in 0..3 {
                acc[a] += areas[s] * units[s][a];
            }
            area += areas[s];
            i += 1;
        }
        supers.push(SuperSample {
            u: [acc[0] / area, acc[1] / area, acc[2] / area],
            area,
            cell: cell_of(&units[first]),
        });
    }

    // Node sets of every level (each level on its own, in parallel).
    let mut levels: Vec<Level> = (0..=depth)
        .into_par_iter()
        .map(|d| {
            let n = (1usize << d) + 1;
            let mut nodes = NodeSet::empty(n);
            let full = d <= cfg.full_depth;
            if full {
                nodes.fill();
            } else {
                let shift = depth - d;
                let mut cells: Vec<u64> = supers
                    .iter()
                    .map(|s| {
                        let c = s.cell.map(|v| (v >> shift) as u64);
                        (c[2] << 42) | (c[1] << 21) | c[0]
                    })
                    .collect();
                cells.sort_unstable();
                cells.dedup();
                let last = n as i64 - 1;
                for key in cells {
                    let c = [
                        (key & 0x1F_FFFF) as i64,
                        ((key >> 21) & 0x1F_FFFF) as i64,
                        (key >> 42) as i64,
                    ];
                    for z in (c[2] - 1).max(0)..=(c[2] + 2).min(last) {
                        for y in (c[1] - 1).max(0)..=(c[1] + 2).min(last) {
                            for x in (c[0] - 1).max(0)..=(c[0] + 2).min(last) {
                                nodes.insert(x as usize, y as usize, z as usize);
                            }
                        }
                    }
                }
            }
            nodes.finish();
            let len = nodes.len();
            Level {
                depth: d,
                nodes,
                full,
                x: vec![0.0; len],
                b: vec![0.0; len],
                iso: 0.0,
            }
        })
        .collect();

    // Right-hand side at the finest level, restricted to the coarser ones.
    let finest_neighbours = neighbour_slots(&levels[depth as usize].nodes);
    finest_rhs(
        &mut levels[depth as usize],
        &finest_neighbours,
        &units,
        &samples,
        &areas,
    );
    let mut finest_neighbours = Some(finest_neighbours);
    for d in (1..=depth as usize).rev() {
        let (coarse, fine) = levels.split_at_mut(d);
        restrict(&fine[0], &mut coarse[d - 1]);
    }

    // Cascadic solve, coarse to fine.
    let alpha = cfg.screening * finest as f64;
    let first = COARSEST_LEVEL.min(depth) as usize;
    let mut nodes_per_level = Vec::new();
    for d in first..=depth as usize {
        if d > first {
            let (coarse, fine) = levels.split_at_mut(d);
            let level = &mut fine[0];
            let h = 1.0 / level.cells() as f64;
            let x: Vec<f64> = (0..level.nodes.len())
                .into_par_iter()
                .map(|s| {
                    let c = level.nodes.coords(s);
                    eval(coarse, [c[0] as f64 * h, c[1] as f64 * h, c[2] as f64 * h])
                })
                .collect();
            level.x = x;
        }
        let iterations = if levels[d].full {
            FULL_LEVEL_ITERATIONS
        } else {
            cfg.iterations
        };
        let nb = if d == depth as usize {
            finest_neighbours.take()
        } else {
            None
        }
        .unwrap_or_else(|| neighbour_slots(&levels[d].nodes));
        solve_level(&mut levels[d], &nb, &supers, alpha, iterations);
        nodes_per_level.push(levels[d].nodes.len());
    }

    // Iso-values: the area-weighted mean of each level's χ over the samples.
    levels[first..].par_iter_mut().for_each(|level| {
        let (mut num, mut den) = (0.0, 0.0);
        for sup in &supers {
            if let Some(v) = level_value(level, sup.u) {
                num += sup.area * v;
                den += sup.area;
            }
        }
        level.iso = if den > 0.0 { num / den } else { 0.0 };
    });
    Ok(Solved {
        levels,
        supers,
        density,
        h_dd,
        centre,
        size,
        samples: samples.len(),
        nodes_per_level,
    })
}

fn validate(cfg: &PoissonConfig) -> Result<(), MeshError> {
    if !(COARSEST_LEVEL..=MAX_DEPTH).contains(&cfg.depth) {
        return Err(MeshError::invalid(
            "PoissonConfig::depth",
            cfg.depth,
            "must be between 2 and 10 (the finest grid of depth 10 has 1025³ nodes)",
        ));
    }
    if cfg.full_depth < COARSEST_LEVEL {
        return Err(MeshError::invalid(
            "PoissonConfig::full_depth",
            cfg.full_depth,
            "at least 2 (the cascade starts from a full level-2 grid)",
        ));
    }
    if cfg.full_depth > 7 {
        return Err(MeshError::invalid(
            "PoissonConfig::full_depth",
            cfg.full_depth,
            "at most 7 (a full grid of 129³ nodes); deeper levels are adaptive",
        ));
    }
    if !(cfg.scale.is_finite() && cfg.scale >= 1.0) {
        return Err(MeshError::invalid(
            "PoissonConfig::scale",
            cfg.scale,
            "must be a finite ratio of at least 1",
        ));
    }
    if !(cfg.screening.is_finite() && cfg.screening >= 0.0) {
        return Err(MeshError::invalid(
            "PoissonConfig::screening",
            cfg.screening,
            "must be finite and not negative",
        ));
    }
    if cfg.iterations == 0 {
        return Err(MeshError::invalid(
            "PoissonConfig::iterations",
            cfg.iterations,
            "at least one iteration per level",
        ));
    }
    Ok(())
}

/// Trilinear weights and the lower cell corner of unit-cube position `u` at a level of `cells`
/// cells per axis.
#[inline]
fn cell_weights(u: [f64; 3], cells: i64) -> ([i64; 3], [f64; 8]) {
    let mut c = [0i64; 3];
    let mut f = [0.0f64; 3];
    for a in 0..3 {
        let g = u[a] * cells as f64;
        c[a] = (g.floor() as i64).clamp(0, cells - 1);
        f[a] = (g - c[a] as f64).clamp(0.0, 1.0);
    }
    let mut w = [0.0; 8];
    for (k, wk) in w.iter_mut().enumerate() {
        let wx = if k & 1 != 0 { f[0] } else { 1.0 - f[0] };
        let wy = if k & 2 != 0 { f[1] } else { 1.0 - f[1] };
        let wz = if k & 4 != 0 { f[2] } else { 1.0 - f[2] };
        *wk = wx * wy * wz;
    }
    (c, w)
}

#[inline]
fn corner(c: [i64; 3], k: usize) -> [i64; 3] {
    [
        c[0] + (k & 1) as i64,
        c[1] + ((k >> 1) & 1) as i64,
        c[2] + ((k >> 2) & 1) as i64,
    ]
}

/// `χ` at unit-cube position `u`: the deepest of `levels` whose cell around `u` has all eight
/// nodes (the fully populated levels always do).
fn eval(levels: &[Level], u: [f64; 3]) -> f64 {
    for level in levels.iter().rev() {
        let (c, w) = cell_weights(u, level.cells());
        let mut v = 0.0;
        let mut complete = true;
        for (k, wk) in w.iter().enumerate() {
            let q = corner(c, k);
            match level.nodes.slot(q[0], q[1], q[2]) {
                Some(s) => v += wk * level.x[s as usize],
                None => {
                    complete = false;
                    break;
                }
            }
        }
        if complete {
            return v;
        }
    }
    0.0
}

/// `χ` of one level at `u`, when the level's cell around `u` has all eight nodes.
fn level_value(level: &Level, u: [f64; 3]) -> Option<f64> {
    let (c, w) = cell_weights(u, level.cells());
    let mut v = 0.0;
    for (k, wk) in w.iter().enumerate() {
        let q = corner(c, k);
        v += wk * level.x[level.nodes.slot(q[0], q[1], q[2])? as usize];
    }
    Some(v)
}

/// `χ` minus the level's iso-value, from the deepest of `levels` whose cell around `u` is
/// complete. Each level's `χ` is a blurred indicator at its own scale; measured against its own
/// iso-value, a coarse level's zero set is where that level puts the surface, so where only a
/// coarse level reaches (a gap in the data) the surface keeps its curvature instead of
/// shrinking by the coarse level's blur.
fn eval_above_iso(levels: &[Level], u: [f64; 3]) -> f64 {
    levels
        .iter()
        .rev()
        .find_map(|l| level_value(l, u).map(|v| v - l.iso))
        .unwrap_or(0.0)
}

/// Sampling density (trilinear splat of sample counts) on a full grid.
struct DensityGrid {
    cells: i64,
    n: usize,
    counts: Vec<f32>,
}

impl DensityGrid {
    fn new(depth: u32, units: &[[f64; 3]]) -> Self {
        let cells = 1i64 << depth;
        let n = cells as usize + 1;
        let mut counts = vec![0.0f32; n * n * n];
        for u in units {
            let (c, w) = cell_weights(*u, cells);
            for (k, wk) in w.iter().enumerate() {
                let q = corner(c, k);
                counts[(q[2] as usize * n + q[1] as usize) * n + q[0] as usize] += *wk as f32;
            }
        }
        Self { cells, n, counts }
    }

    fn at(&self, u: &[f64; 3]) -> f64 {
        let (c, w) = cell_weights(*u, self.cells);
        let n = self.n;
        w.iter()
            .enumerate()
            .map(|(k, wk)| {
                let q = corner(c, k);
                wk * f64::from(self.counts[(q[2] as usize * n + q[1] as usize) * n + q[0] as usize])
            })
            .sum()
    }
}

/// Offset index of a 27-neighbourhood: `(dz + 1) * 9 + (dy + 1) * 3 + (dx + 1)`.
#[inline]
fn offset_index(d: [i64; 3]) -> usize {
    ((d[2] + 1) * 9 + (d[1] + 1) * 3 + (d[0] + 1)) as usize
}

/// The 27 offsets, in [`offset_index`] order.
fn offsets() -> [[i64; 3]; 27] {
    let mut o = [[0i64; 3]; 27];
    for (i, oi) in o.iter_mut().enumerate() {
        *oi = [
            (i % 3) as i64 - 1,
            ((i / 3) % 3) as i64 - 1,
            (i / 9) as i64 - 1,
        ];
    }
    o
}

/// The right-hand side `b_i = ∫ ∇B_i · V` at the finest level, with `V` the trilinear splat of
/// the samples' area-weighted normals (`V = Σ_j v_j B_j`, `v_j = Σ_s a_s n_s B_j(s) / h³`).
fn finest_rhs(
    level: &mut Level,
    nb: &[[u32; 27]],
    units: &[[f64; 3]],
    samples: &[(Point3<f64>, Vector3<f64>)],
    areas: &[f64],
) {
    let cells = level.cells();
    let h = 1.0 / cells as f64;
    let mut w = vec![[0.0f64; 3]; level.nodes.len()];
    for ((u, (_, n)), a) in units.iter().zip(samples).zip(areas) {
        let (c, wt) = cell_weights(*u, cells);
        for (k, wk) in wt.iter().enumerate() {
            let q = corner(c, k);
            if let Some(s) = level.nodes.slot(q[0], q[1], q[2]) {
                let v = &mut w[s as usize];
                for a_ in 0..3 {
                    v[a_] += a * wk * n[a_];
                }
            }
        }
    }
    // 1-D integrals on a unit spacing: ∫ B_i' B_{i+o} and ∫ B_i B_{i+o} / h.
    let d1 = |o: i64| match o {
        1 => -0.5,
        -1 => 0.5,
        _ => 0.0,
    };
    let m1 = |o: i64| if o == 0 { 2.0 / 3.0 } else { 1.0 / 6.0 };
    let offs = offsets();
    // G(o) = ∫ ∇B_i B_{i+o} = h² (d1 m1 m1, m1 d1 m1, m1 m1 d1); b = Σ G·v = Σ G·w / h³.
    let g: Vec<[f64; 3]> = offs
        .iter()
        .map(|o| {
            [
                d1(o[0]) * m1(o[1]) * m1(o[2]) / h,
                m1(o[0]) * d1(o[1]) * m1(o[2]) / h,
                m1(o[0]) * m1(o[1]) * d1(o[2]) / h,
            ]
        })
        .collect();
    level.b = nb
        .par_iter()
        .enumerate()
        .map(|(s, nb)| {
            let mut acc = 0.0;
            for (i, gi) in g.iter().enumerate() {
                // An absent neighbour's slot is the node's own.
                if i == 13 || nb[i] != s as u32 {
                    let v = &w[nb[i] as usize];
                    acc += gi[0] * v[0] + gi[1] * v[1] + gi[2] * v[2];
                }
            }
            acc
        })
        .collect();
}

/// Galerkin restriction of the right-hand side: a coarse B-spline is the sum of the fine ones
/// with weights 1 (same node) and ½ per axis (the fine nodes halfway).
fn restrict(fine: &Level, coarse: &mut Level) {
    coarse.b.iter_mut().for_each(|v| *v = 0.0);
    for (s, &bv) in fine.b.iter().enumerate() {
        if bv == 0.0 {
            continue;
        }
        let c = fine.nodes.coords(s);
        let options = |v: i64| -> [(i64, f64); 2] {
            if v % 2 == 0 {
                [(v / 2, 1.0), (-1, 0.0)]
            } else {
                [((v - 1) / 2, 0.5), ((v + 1) / 2, 0.5)]
            }
        };
        let (ox, oy, oz) = (options(c[0]), options(c[1]), options(c[2]));
        for &(z, wz) in &oz {
            for &(y, wy) in &oy {
                for &(x, wx) in &ox {
                    if wx * wy * wz == 0.0 {
                        continue;
                    }
                    if let Some(t) = coarse.nodes.slot(x, y, z) {
                        coarse.b[t as usize] += wx * wy * wz * bv;
                    }
                }
            }
        }
    }
}

/// Element stiffness of the trilinear cube of unit edge between two corners `hamming` bits
/// apart: `∫ ∇B_a·∇B_b`.
fn element_stiffness(hamming: u32) -> f64 {
    match hamming {
        0 => 1.0 / 3.0,
        1 => 0.0,
        _ => -1.0 / 12.0,
    }
}

/// Stiffness coefficients of a node towards its 27 neighbours (unit spacing, [`offset_index`]
/// order), summed over the cells around it whose bit is set in `cells` (bit `k`: the cell
/// whose lower corner is at offset `(k & 1, k >> 1 & 1, k >> 2 & 1) − 1` from the node). With
/// the cells that have all their corners, the rim of a band and the faces of the cube get the
/// natural (Neumann) condition.
fn stiffness_row(cells: u8) -> [f64; 27] {
    let mut row = [0.0; 27];
    for cell in 0..8usize {
        if cells & (1 << cell) == 0 {
            continue;
        }
        // Lower corner of the cell relative to the node, in {-1, 0}³.
        let lo = [
            (cell & 1) as i64 - 1,
            ((cell >> 1) & 1) as i64 - 1,
            ((cell >> 2) & 1) as i64 - 1,
        ];
        let pl = (0..3).fold(0u32, |acc, a| acc | ((-lo[a] as u32) << a));
        for q in 0..8usize {
            row[offset_index(corner(lo, q))] += element_stiffness((pl ^ q as u32).count_ones());
        }
    }
    row
}

/// For each of the eight cells around a node (numbered as in [`stiffness_row`]), the bits
/// (in [`offset_index`] order) of its eight corners.
fn cell_corners() -> [u32; 8] {
    let mut masks = [0u32; 8];
    for (cell, mask) in masks.iter_mut().enumerate() {
        let lo = [
            (cell & 1) as i64 - 1,
            ((cell >> 1) & 1) as i64 - 1,
            ((cell >> 2) & 1) as i64 - 1,
        ];
        for q in 0..8 {
            *mask |= 1 << offset_index(corner(lo, q));
        }
    }
    masks
}

/// Nodes per chunk of the parallel construction of [`solve_level`]'s system.
const SOLVE_CHUNK: usize = 4096;

/// `Σ f(i)` over `0..len`, in order. The sums of the conjugate gradients stay serial: a
/// parallel sum rounds differently with the number of threads, and the iteration count of the
/// fully populated levels (to a relative residual) with it.
fn ordered_sum(len: usize, f: impl Fn(usize) -> f64) -> f64 {
    (0..len).map(f).sum()
}

/// The slots of every node's 27 neighbours ([`offset_index`] order), the node's own where a
/// neighbour is absent (outside the set or the grid).
fn neighbour_slots(nodes: &NodeSet) -> Vec<[u32; 27]> {
    let offs = offsets();
    let mut nb = vec![[0u32; 27]; nodes.len()];
    nb.par_chunks_mut(SOLVE_CHUNK)
        .enumerate()
        .for_each(|(chunk, nbs)| {
            for (k, nb) in nbs.iter_mut().enumerate() {
                let s = chunk * SOLVE_CHUNK + k;
                let c = nodes.coords(s);
                *nb = [s as u32; 27];
                for (i, o) in offs.iter().enumerate() {
                    if let Some(t) = nodes.slot(c[0] + o[0], c[1] + o[1], c[2] + o[2]) {
                        nb[i] = t;
                    }
                }
            }
        });
    nb
}

/// Relaxes one level with Jacobi-preconditioned conjugate gradients. Every node of a complete
/// cell is free; on the rim of a band the stiffness sums only the complete cells (the natural
/// condition); nodes of no complete cell keep their values.
///
/// The system is stored by node slot: for every node its 27 neighbours' slots (its own where
/// a neighbour is absent) and their coefficients, all zero on a node that is not free, so that
/// the vectors of the iteration are indexed like the level's and its products and updates run
/// in parallel (its sums in order, see [`ordered_sum`]).
fn solve_level(
    level: &mut Level,
    nb: &[[u32; 27]],
    supers: &[SuperSample],
    alpha: f64,
    iterations: usize,
) {
    let nodes = &level.nodes;
    let len = nodes.len();
    let cells = level.cells();
    let h = 1.0 / cells as f64;
    // The row of every combination of complete cells around a node.
    let corners_of = cell_corners();
    let rows: Vec<[f32; 27]> = (0..=255u8)
        .map(|cells| stiffness_row(cells).map(|v| (v * h) as f32))
        .collect();
    // Stiffness coefficients from the cells around each node that have all their corners (all
    // eight inside a band, fewer on its rim and on the cube's faces; a node of no complete cell
    // keeps a zero row).
    let mut coef = vec![[0.0f32; 27]; len];
    coef.par_iter_mut()
        .zip(nb)
        .enumerate()
        .for_each(|(s, (cf, nb))| {
            let present = nb
                .iter()
                .enumerate()
                .filter(|&(i, &t)| i == 13 || t != s as u32)
                .fold(0u32, |acc, (i, _)| acc | (1 << i));
            let complete = corners_of
                .iter()
                .enumerate()
                .filter(|(_, m)| present & **m == **m)
                .fold(0u8, |acc, (cell, _)| acc | (1 << cell));
            if complete != 0 {
                *cf = rows[complete as usize];
            }
        });
    // Screening: α Σ_s a_s B_i(s) B_j(s), from the super-samples, on the free rows.
    for sup in supers {
        let (c, w) = cell_weights(sup.u, cells);
        for k in 0..8 {
            let qk = corner(c, k);
            let Some(slot) = nodes.slot(qk[0], qk[1], qk[2]) else {
                continue;
            };
            let row = &mut coef[slot as usize];
            if row[13] == 0.0 {
                continue;
            }
            for (l, wl) in w.iter().enumerate() {
                let ql = corner(c, l);
                let d = [ql[0] - qk[0], ql[1] - qk[1], ql[2] - qk[2]];
                row[offset_index(d)] += (alpha * sup.area * w[k] * wl) as f32;
            }
        }
    }
    // Zero the coefficients towards the grid outside (their slot is the node's own).
    coef.par_iter_mut()
        .zip(nb)
        .enumerate()
        .for_each(|(s, (cf, nb))| {
            for i in 0..27 {
                if i != 13 && nb[i] == s as u32 {
                    cf[i] = 0.0;
                }
            }
        });
    let free: Vec<bool> = coef.par_iter().map(|cf| cf[13] > 0.0).collect();
    if !free.contains(&true) {
        return;
    }
    let x = &mut level.x;
    let b = &level.b;
    let apply = |v: &[f64], out: &mut [f64]| {
        out.par_iter_mut()
            .zip(nb.par_iter().zip(coef.par_iter()))
            .for_each(|(o, (nb, cf))| {
                let mut acc = 0.0;
                for i in 0..27 {
                    acc += f64::from(cf[i]) * v[nb[i] as usize];
                }
                *o = acc;
            });
    };
    let diag: Vec<f64> = coef
        .par_iter()
        .map(|c| {
            if c[13] > 0.0 {
                1.0 / f64::from(c[13])
            } else {
                0.0
            }
        })
        .collect();
    let mut r = vec![0.0; len];
    apply(x, &mut r);
    r.par_iter_mut()
        .zip(b.par_iter().zip(&free))
        .for_each(|(ri, (bi, f))| *ri = if *f { bi - *ri } else { 0.0 });
    let bnorm = ordered_sum(len, |i| if free[i] { b[i] * b[i] } else { 0.0 })
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let mut z: Vec<f64> = r.par_iter().zip(&diag).map(|(a, d)| a * d).collect();
    let mut p = z.clone();
    let mut rz = ordered_sum(len, |i| r[i] * z[i]);
    let mut q = vec![0.0; len];
    for _ in 0..iterations {
        apply(&p, &mut q);
        let pq = ordered_sum(len, |i| if free[i] { p[i] * q[i] } else { 0.0 });
        if pq.is_nan() || pq <= 0.0 {
            break;
        }
        let a = rz / pq;
        x.par_iter_mut()
            .zip(r.par_iter_mut())
            .zip(p.par_iter().zip(q.par_iter().zip(&free)))
            .for_each(|((xi, ri), (pi, (qi, f)))| {
                if *f {
                    *xi += a * pi;
                    *ri -= a * qi;
                }
            });
        let rnorm = ordered_sum(len, |i| r[i] * r[i]).sqrt();
        if rnorm < CG_TOLERANCE * bnorm {
            break;
        }
        z.par_iter_mut()
            .zip(r.par_iter().zip(&diag))
            .for_each(|(zi, (ri, d))| *zi = ri * d);
        let rz_new = ordered_sum(len, |i| r[i] * z[i]);
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_iter_mut()
            .zip(&z)
            .for_each(|(pi, zi)| *pi = zi + beta * *pi);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check_topology;
    use crate::test_shapes::{
        partial_sphere_cloud, partial_sphere_surface, sphere_cloud as sphere,
    };

    #[test]
    fn interior_stiffness_row_sums_to_zero() {
        let row = stiffness_row(0xFF);
        approx::assert_relative_eq!(row[13], 8.0 / 3.0, epsilon = 1e-12);
        approx::assert_relative_eq!(row.iter().sum::<f64>(), 0.0, epsilon = 1e-12);
        // A corner of the cube: one cell only (the one on the +x +y +z side).
        let corner_row = stiffness_row(1 << 7);
        approx::assert_relative_eq!(corner_row[13], 1.0 / 3.0, epsilon = 1e-12);
        approx::assert_relative_eq!(corner_row.iter().sum::<f64>(), 0.0, epsilon = 1e-12);
    }

    /// The solve's sums run in order and the extraction's rounds are merged in order: a sphere
    /// without its top (so the extraction follows the surface into a gap, where coarser levels
    /// give the values) comes out the same, vertex for vertex and in the same order, on 1 and
    /// on 3 threads; and it is closed and manifold.
    #[test]
    fn same_surface_on_any_number_of_threads() {
        let cloud = partial_sphere_cloud(8000, 10.0, Point3::origin(), |p, _| p.z < 6.0);
        let cfg = PoissonConfig {
            depth: 7,
            ..PoissonConfig::default()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| poisson_reconstruct(&cloud, &cfg)).unwrap()
        };
        let (one, three) = (run(1), run(3));
        assert!(one.mesh.triangles.len() > 1000);
        assert_eq!(one.mesh.vertices, three.mesh.vertices);
        assert_eq!(one.mesh.triangles, three.mesh.triangles);
        assert_eq!(one.densities, three.densities);
        assert!(check_topology(&one.mesh).is_watertight_manifold());
    }

    /// A sphere of radius 20 mm sampled with 20 000 exact points (0.5 mm apart): the mesh is
    /// closed, manifold, oriented outwards, and its vertices lie within 2.5 % of a finest cell
    /// (depth 7: cells of 0.34 mm) of the sphere in RMS, unbiased to 1 % of a cell. Measured:
    /// 1.7 % and 0.1 % (3.2 % with the bands' rim nodes fixed to the coarser solution, 6.0 %
    /// with vertices also interpolated linearly along the tetrahedra's diagonals); a wrong
    /// screening or a misplaced iso-value costs tens of per cent.
    #[test]
    fn sphere_mesh_is_close_to_the_sphere() {
        let centre = Point3::new(5.0, -3.0, 300.0);
        let cloud = sphere(20_000, 20.0, centre);
        let cfg = PoissonConfig {
            depth: 7,
            ..PoissonConfig::default()
        };
        let s = poisson_reconstruct(&cloud, &cfg).unwrap();
        let topo = check_topology(&s.mesh);
        assert!(topo.is_watertight_manifold(), "{topo:?}");
        assert_eq!(topo.components, 1);
        let errs: Vec<f64> = s
            .mesh
            .vertices
            .iter()
            .map(|p| (p - centre).norm() - 20.0)
            .collect();
        let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
        let mean = errs.iter().sum::<f64>() / errs.len() as f64;
        assert!(
            rms < 0.025 * s.cell_size,
            "rms {rms} mm, cell {}",
            s.cell_size
        );
        assert!(
            mean.abs() < 0.01 * s.cell_size,
            "mean {mean} mm, cell {}",
            s.cell_size
        );
        // Oriented outwards: the signed volume is that of the sphere.
        let vol = crate::signed_volume(&s.mesh);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 20f64.powi(3);
        assert!(
            (vol - exact).abs() < 0.01 * exact,
            "volume {vol} vs {exact}"
        );
    }

    /// Two separate spheres give two closed pieces; an open cap (the camera-facing half of a
    /// sphere, as one view sees it) is still closed by the reconstruction.
    #[test]
    fn separate_and_partial_shapes_stay_closed() {
        let a = sphere(6000, 10.0, Point3::origin());
        let b = sphere(6000, 8.0, Point3::new(40.0, 0.0, 0.0));
        let mut pts = a.positions().to_vec();
        pts.extend_from_slice(b.positions());
        let mut nrm = a.normals().unwrap().to_vec();
        nrm.extend_from_slice(b.normals().unwrap());
        let two = PointCloud::from_positions(pts).with_normals(nrm).unwrap();
        let cfg = PoissonConfig {
            depth: 7,
            ..PoissonConfig::default()
        };
        let s = poisson_reconstruct(&two, &cfg).unwrap();
        let topo = check_topology(&s.mesh);
        assert!(topo.is_watertight_manifold(), "{topo:?}");
        assert_eq!(topo.components, 2, "{topo:?}");

        let cap = partial_sphere_cloud(8000, 10.0, Point3::origin(), |p, _| p.z < 2.0);
        let s = poisson_reconstruct(&cap, &cfg).unwrap();
        let topo = check_topology(&s.mesh);
        assert!(topo.is_watertight_manifold(), "{topo:?}");
        // Where the data is, the surface follows it: vertices near samples (z < 0) are on the
        // sphere to 6 % of a cell (measured 3.2 %).
        let near: Vec<f64> = s
            .mesh
            .vertices
            .iter()
            .filter(|p| p.z < -2.0)
            .map(|p| p.coords.norm() - 10.0)
            .collect();
        assert!(near.len() > 100);
        let rms = (near.iter().map(|e| e * e).sum::<f64>() / near.len() as f64).sqrt();
        assert!(rms < 0.06 * s.cell_size, "rms {rms}, cell {}", s.cell_size);
    }

    /// A sphere whose lower back (`y > 0.4 r` and `z > 0`, what the default scan never sees)
    /// has no samples: the mesh is still closed and manifold, the vertices near the samples are
    /// on the sphere to 1.8 % of a cell in RMS (measured 1.25 %; 2.0 % with the bands' rim
    /// nodes fixed to the coarser solution, 4 % with vertices also interpolated linearly along
    /// the tetrahedra's diagonals, see `contour`), and the surface that closes
    /// the gap stays within 0.3 r of the sphere, 0.1 r in RMS (measured: 2.72 mm outwards at
    /// worst for r = 10 mm, 0.14 mm inwards, RMS 0.84 mm: the sphere nearly fills the cube, and
    /// the closing surface bulges towards the cube's edge behind the gap; it is a bounded
    /// guess, not the sphere — these bounds guard against it getting worse).
    #[test]
    fn sphere_missing_its_lower_back_is_closed_and_bounded() {
        let r = 10.0;
        let s = partial_sphere_surface(r, |_, n| !(n.y > 0.4 && n.z > 0.0));
        let topo = check_topology(&s.mesh);
        assert!(topo.is_watertight_manifold(), "{topo:?}");
        let (mut seen, mut gap) = (Vec::new(), Vec::new());
        for p in &s.mesh.vertices {
            let e = p.coords.norm() - r;
            let n = p.coords / p.coords.norm();
            // A margin of 0.1 r around the edge of the gap, where the two meet.
            if n.y > 0.3 && n.z > -0.1 {
                gap.push(e);
            } else if !(n.y > 0.4 && n.z > 0.0) {
                seen.push(e);
            }
        }
        assert!(gap.len() > 100 && seen.len() > 1000);
        let rms = (seen.iter().map(|e| e * e).sum::<f64>() / seen.len() as f64).sqrt();
        assert!(rms < 0.018 * s.cell_size, "rms {rms}, cell {}", s.cell_size);
        let worst = gap.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        let gap_rms = (gap.iter().map(|e| e * e).sum::<f64>() / gap.len() as f64).sqrt();
        assert!(worst < 0.3 * r, "gap deviates {worst} mm");
        assert!(gap_rms < 0.1 * r, "gap RMS {gap_rms} mm");
    }

    /// Diagnostic (`cargo test -p sl-mesh --release --lib gap_profile -- --ignored
    /// --nocapture`): two spheres of radius 25 mm, 120 mm apart, sampled exactly without their
    /// lower back (`y > 0.4 r`, `z > 0`) as the default scan; for `full_depth` 5 and 4, where
    /// each level's `χ` (against its own iso-value) and the extracted field cross zero along
    /// rays through the gap, and how far from the sphere (RMS and mean over the rays).
    #[test]
    #[ignore]
    fn gap_profile() {
        let r = 25.0;
        let mut pts = Vec::new();
        let mut nrm = Vec::new();
        for cx in [-60.0, 60.0] {
            let full = sphere(40_000, r, Point3::new(cx, 0.0, 450.0));
            for (p, n) in full.positions().iter().zip(full.normals().unwrap()) {
                if !(n.y > 0.4 && n.z > 0.0) {
                    pts.push(*p);
                    nrm.push(*n);
                }
            }
        }
        let cloud = PointCloud::from_positions(pts).with_normals(nrm).unwrap();
        let centre = Point3::new(60.0, 0.0, 450.0);
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        for full_depth in [5, 4] {
            let cfg = PoissonConfig {
                full_depth,
                ..PoissonConfig::default()
            };
            let s = solve(&cloud, &cfg).unwrap();
            let extracted = s.levels.len();
            let mut stats = vec![(0usize, 0.0f64, 0.0f64); extracted + 1];
            for i in 0..2000 {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / 2000.0;
                let rr = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                let n = Vector3::new(rr * t.cos(), rr * t.sin(), z);
                if !(n.y > 0.5 && n.z > 0.1) {
                    continue;
                }
                let at = |t: f64| {
                    let q = (centre + n * t - s.centre) / s.size;
                    [q.x + 0.5, q.y + 0.5, q.z + 0.5]
                };
                for (li, st) in stats.iter_mut().enumerate().skip(3) {
                    let f = |t: f64| -> Option<f64> {
                        if li == extracted {
                            Some(eval_above_iso(&s.levels, at(t)))
                        } else {
                            level_value(&s.levels[li], at(t)).map(|v| v - s.levels[li].iso)
                        }
                    };
                    let step = 0.02;
                    let mut t = 15.0;
                    let mut prev = f(t);
                    while t < 35.0 {
                        let cur = f(t + step);
                        if let (Some(a), Some(b)) = (prev, cur)
                            && a < 0.0
                            && b >= 0.0
                        {
                            let e = t + step * a / (a - b) - r;
                            st.0 += 1;
                            st.1 += e * e;
                            st.2 += e;
                            break;
                        }
                        prev = cur;
                        t += step;
                    }
                }
            }
            println!("full_depth {full_depth}:");
            for (li, st) in stats.iter().enumerate().skip(3) {
                let name = if li == extracted {
                    "extracted".to_string()
                } else {
                    format!("level {li}")
                };
                println!(
                    "  {name:9}: {:4} rays, RMS {:.3} mm, mean {:+.3} mm",
                    st.0,
                    (st.1 / st.0.max(1) as f64).sqrt(),
                    st.2 / st.0.max(1) as f64
                );
            }
        }
    }

    #[test]
    fn bad_input_is_named() {
        let c = sphere(100, 1.0, Point3::origin());
        let bare = PointCloud::from_positions(c.positions().to_vec());
        let e = poisson_reconstruct(&bare, &PoissonConfig::default()).unwrap_err();
        assert!(matches!(e, MeshError::NoNormals { points: 100 }), "{e}");
        let few = sphere(10, 1.0, Point3::origin());
        let e = poisson_reconstruct(&few, &PoissonConfig::default()).unwrap_err();
        assert!(
            matches!(e, MeshError::TooFewPoints { found: 10, .. }),
            "{e}"
        );
        let bad = PoissonConfig {
            depth: 11,
            ..PoissonConfig::default()
        };
        let e = poisson_reconstruct(&c, &bad).unwrap_err().to_string();
        assert!(e.contains("PoissonConfig::depth"), "{e}");
        let same = PointCloud::from_positions(vec![Point3::new(1.0, 2.0, 3.0); 50])
            .with_normals(vec![Vector3::x(); 50])
            .unwrap();
        let e = poisson_reconstruct(&same, &PoissonConfig::default()).unwrap_err();
        assert!(
            matches!(e, MeshError::DegenerateCloud { points: 50 }),
            "{e}"
        );
    }
}
