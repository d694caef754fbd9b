//! The mesh stage: a watertight surface of the merged cloud (screened Poisson, `sl-mesh`),
//! simplified under an error bound (`sl_mesh::simplify`: coarser where no samples support it),
//! the surface that closes what no view saw faired (`sl_mesh::fair_unsupported`), written
//! beside it (`mesh.ply`, `mesh.stl`), pictured (`mesh_preview.png`), measured against
//! the truth when there is one, and shown with the cloud in an interactive 3-D page
//! (`view3d.html`, self-contained) that `index.html` embeds.

use std::path::{Path, PathBuf};

use serde::Serialize;
use sl_cloud::{PointCloud, PreviewConfig};
use sl_codec::write_png_rgb8;
use sl_mesh::{
    FairConfig, MeshColoring, PoissonConfig, SimplifyConfig, TextureConfig, TriangleMesh,
    ViewerConfig, ViewerLayer, bake_texture, render_mesh, vertex_normals, viewer_html,
    write_obj_textured, write_ply_mesh, write_ply_mesh_coloured, write_stl,
};
use sl_metrology::{EvaluateConfig, MeshSampling, Report, Truth, evaluate_mesh};

use crate::error::io;
use crate::run_report::write_atomically;
use crate::{MeshChainConfig, ScanColours, ScanError, UNSEEN_COLOUR, mesh_chain};

/// What the mesh stage made and measured.
#[derive(Debug, Clone, Serialize)]
pub struct MeshSummary {
    /// Vertices of the mesh.
    pub vertices: usize,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Closed: every edge shared by two triangles.
    pub watertight: bool,
    /// Every edge of at most two triangles, every vertex one fan.
    pub manifold: bool,
    /// Vertices of the surface as extracted, before the simplification.
    pub vertices_extracted: usize,
    /// Triangles of the surface as extracted.
    pub triangles_extracted: usize,
    /// Wall time of the simplification (ms); `None` when it was off.
    pub simplify_ms: Option<f64>,
    /// Wall time of the fairing of the unsupported surface (ms), which follows the
    /// simplification; `None` when it was off.
    pub fair_ms: Option<f64>,
    /// Octree depth of the reconstruction.
    pub depth: u32,
    /// Edge of a finest cell (mm).
    pub cell_size_mm: f64,
    /// Wall time of the solve and of the surface extraction (ms).
    pub solve_ms: f64,
    /// See `solve_ms`.
    pub contour_ms: f64,
    /// The mesh measured against the truth at its vertices (RMS, probing errors).
    pub accuracy_vertices: Option<Report>,
    /// The mesh measured against the truth over area-weighted samples.
    pub accuracy_area: Option<Report>,
    /// The mesh's colour, when the views had colour ([`mesh_stage_coloured`]).
    pub colour: Option<MeshColourSummary>,
}

/// How the mesh was coloured ([`mesh_stage_coloured`]).
#[derive(Debug, Clone, Serialize)]
pub struct MeshColourSummary {
    /// Views with a colour image.
    pub views: usize,
    /// Vertices no view sees (given [`crate::UNSEEN_COLOUR`]).
    pub unseen_vertices: usize,
    /// Width and height of the texture (texels).
    pub texture_size: [usize; 2],
    /// Texels of the texture no view sees (filled from their triangle's seen texels).
    pub unseen_texels: usize,
    /// Wall time of the vertex colours and of the texture (ms).
    pub vertex_ms: f64,
    /// See `vertex_ms`.
    pub texture_ms: f64,
}

/// The files of the mesh stage, relative to the output folder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeshFiles {
    /// The mesh as PLY (with vertex normals).
    pub ply: String,
    /// The mesh as binary STL.
    pub stl: String,
    /// A shaded picture of the mesh.
    pub preview: String,
    /// The interactive 3-D page of the merged cloud and the mesh.
    pub view3d: String,
    /// The textured mesh as OBJ (its `.mtl` and `.png` beside it), when coloured.
    pub obj: Option<String>,
    /// The texture image of `obj`.
    pub texture: Option<String>,
}

/// Largest finest-cell edge of a scan's mesh as a fraction of the merged cloud's sample
/// spacing. A cell finer than the samples adds triangles but no detail (the surface between
/// samples is interpolated either way); at most three quarters of the spacing keeps every
/// sample in a cell of its own.
pub const MESH_CELL_PER_SPACING: f64 = 0.75;

/// The screened-Poisson settings of a scan's mesh: depth `max_depth`, or the shallowest depth
/// below it whose finest cell (the cloud's bounding cube, times the reconstruction's margin,
/// over `2^depth`) is at most [`MESH_CELL_PER_SPACING`] of `spacing_mm`, the merged cloud's
/// sample spacing (the merge's output voxel; `None` keeps `max_depth`). The default dumbbell
/// scan (≈ 170 mm, 0.5 mm voxels) keeps depth 9 (0.37 mm cells); an 80 mm object gets depth 8
/// instead of 9: a quarter of the triangles, the same detail.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::PointCloud;
/// use sl_scan::scan_poisson_config;
/// let corners = |e: f64| PointCloud::from_positions(vec![Point3::origin(), Point3::new(e, e / 2.0, e / 3.0)]);
/// assert_eq!(scan_poisson_config(&corners(170.0), Some(0.5), 9).depth, 9);
/// assert_eq!(scan_poisson_config(&corners(85.0), Some(0.5), 9).depth, 8);
/// assert_eq!(scan_poisson_config(&corners(85.0), None, 9).depth, 9);
/// assert_eq!(scan_poisson_config(&corners(400.0), Some(0.5), 9).depth, 9);
/// ```
pub fn scan_poisson_config(
    cloud: &PointCloud,
    spacing_mm: Option<f64>,
    max_depth: u32,
) -> PoissonConfig {
    let base = PoissonConfig {
        depth: max_depth,
        ..PoissonConfig::default()
    };
    let (Some(spacing), Some(b)) = (spacing_mm, cloud.bounding_box()) else {
        return base;
    };
    let cube = (b.max - b.min).max() * base.scale;
    if !(spacing.is_finite() && spacing > 0.0 && cube.is_finite() && cube > 0.0) {
        return base;
    }
    let target = MESH_CELL_PER_SPACING * spacing;
    let depth = (1..=max_depth)
        .find(|&d| cube / f64::from(1u32 << d) <= target)
        .unwrap_or(max_depth);
    PoissonConfig { depth, ..base }
}

/// What the mesh stage does to the reconstructed surface before it writes it: the steps
/// `slscan mesh` runs by default, each of which can be left out (`slscan scan --no-simplify`,
/// `--no-fair`, `--no-fair-rim`).
#[derive(Debug, Clone, PartialEq)]
pub struct MeshConfig {
    /// The error-bounded simplification (`sl_mesh::simplify`); `None` keeps every vertex of
    /// the extraction. Default: `SimplifyConfig::default()` (0.01 mm where samples support the
    /// surface, 0.03 mm where they do not).
    pub simplify: Option<SimplifyConfig>,
    /// The fairing of the surface no sample supports (`sl_mesh::fair_unsupported`), which
    /// works on the simplified mesh and so is made only with `simplify`; `None` leaves
    /// Poisson's membrane there. Default: `FairConfig::default()` (the rim of a gap in smooth
    /// surface put on its local quadric first).
    pub fair: Option<FairConfig>,
}

impl Default for MeshConfig {
    fn default() -> Self {
        Self {
            simplify: Some(SimplifyConfig::default()),
            fair: Some(FairConfig::default()),
        }
    }
}

/// Runs the mesh stage on `merged` into `out` with the default [`MeshConfig`]
/// (simplified, then faired): [`mesh_stage_with`] with `&MeshConfig::default()`.
///
/// # Errors
/// As [`mesh_stage_with`].
pub fn mesh_stage(
    merged: &PointCloud,
    merged_errors_mm: Option<&[f32]>,
    truth: Option<&Truth>,
    cfg: &PoissonConfig,
    out: &Path,
) -> Result<(MeshSummary, MeshFiles), ScanError> {
    mesh_stage_with(
        merged,
        merged_errors_mm,
        truth,
        cfg,
        &MeshConfig::default(),
        out,
    )
}

/// Runs the mesh stage on `merged` into `out`: the reconstruction, then what `options` asks
/// for (the error-bounded simplification, and after it the fairing of the unsupported
/// surface), the files, the measures and the 3-D page.
///
/// # Errors
/// [`ScanError::Mesh`] when the cloud cannot be meshed (no normals, too few points),
/// [`ScanError::Metrology`] when the mesh cannot be measured, [`ScanError::Io`] naming a file
/// that cannot be written.
pub fn mesh_stage_with(
    merged: &PointCloud,
    merged_errors_mm: Option<&[f32]>,
    truth: Option<&Truth>,
    cfg: &PoissonConfig,
    options: &MeshConfig,
    out: &Path,
) -> Result<(MeshSummary, MeshFiles), ScanError> {
    mesh_stage_coloured(merged, merged_errors_mm, truth, cfg, options, None, out)
}

/// [`mesh_stage_with`], the mesh coloured from the views' `colours` when given: `mesh.ply`
/// with vertex colours, `mesh.obj` with its texture (`mesh.mtl`, `mesh.png`, baked by
/// `sl_mesh::bake_texture` from [`ScanColours::colour_at`]) and the 3-D page in colour.
///
/// # Errors
/// As [`mesh_stage_with`].
pub fn mesh_stage_coloured(
    merged: &PointCloud,
    merged_errors_mm: Option<&[f32]>,
    truth: Option<&Truth>,
    cfg: &PoissonConfig,
    options: &MeshConfig,
    colours: Option<&ScanColours>,
    out: &Path,
) -> Result<(MeshSummary, MeshFiles), ScanError> {
    // The chain of `slscan mesh` with this stage's steps: the reconstruction, then the
    // simplification and the fairing of the surface that closes the unseen part (on the
    // simplified mesh: few vertices there, so the bi-Laplacian system is small).
    let chain = mesh_chain(
        merged,
        &MeshChainConfig {
            poisson: cfg.clone(),
            simplify: options.simplify,
            fair: options.fair.clone(),
            min_piece: 0,
            ..MeshChainConfig::default()
        },
    )?;
    let simplify_ms = chain.simplified.as_ref().map(|s| s.1);
    let fair_ms = chain.faired.as_ref().map(|f| f.1);
    let (vertices_extracted, triangles_extracted) =
        (chain.vertices_extracted, chain.triangles_extracted);
    let mesh = &chain.mesh;
    let topo = &chain.topology;
    let mut files = MeshFiles {
        ply: "mesh.ply".into(),
        stl: "mesh.stl".into(),
        preview: "mesh_preview.png".into(),
        view3d: "view3d.html".into(),
        obj: None,
        texture: None,
    };
    let coloured = match colours {
        Some(c) => Some(colour_mesh(mesh, c, out, &mut files)?),
        None => None,
    };
    // The views' blend when the scan has them, else the cloud's own colours, if any.
    let vertex_colours = coloured
        .as_ref()
        .map(|(_, c)| c.as_slice())
        .or(chain.vertex_colours.as_deref());
    match vertex_colours {
        Some(c) => write_ply_mesh_coloured(&out.join(&files.ply), mesh, c)?,
        None => write_ply_mesh(&out.join(&files.ply), mesh)?,
    }
    write_stl(&out.join(&files.stl), mesh)?;
    let (accuracy_vertices, accuracy_area) = match truth {
        Some(t) => {
            let e = EvaluateConfig::default();
            (
                Some(evaluate_mesh(mesh, t, MeshSampling::Vertices, &e)?),
                Some(evaluate_mesh(mesh, t, MeshSampling::default(), &e)?),
            )
        }
        None => (None, None),
    };
    let img = render_mesh(mesh, MeshColoring::Grey, &PreviewConfig::default())?;
    write_png_rgb8(
        &out.join(&files.preview),
        img.width as usize,
        img.height as usize,
        &img.rgb,
    )?;
    let page = viewer_html(
        &[
            ViewerLayer::Mesh {
                name: "mesh",
                mesh,
                errors_mm: accuracy_vertices
                    .as_ref()
                    .map(|r| r.signed_distances_mm.as_slice()),
                colours: vertex_colours,
            },
            ViewerLayer::Cloud {
                name: "merged cloud",
                cloud: merged,
                errors_mm: merged_errors_mm,
            },
        ],
        &ViewerConfig {
            title: "slscan scan: merged cloud and mesh".into(),
            error_range_mm: sl_metrology::DEFAULT_HEAT_MAP_RANGE_MM,
            ..ViewerConfig::default()
        },
    )?;
    let view = out.join(&files.view3d);
    std::fs::write(&view, page).map_err(io(&view))?;
    Ok((
        MeshSummary {
            vertices: mesh.vertices.len(),
            triangles: mesh.triangles.len(),
            vertices_extracted,
            triangles_extracted,
            simplify_ms,
            fair_ms,
            watertight: topo.is_watertight(),
            manifold: topo.is_manifold(),
            depth: cfg.depth,
            cell_size_mm: chain.cell_size,
            solve_ms: chain.solve_ms,
            contour_ms: chain.contour_ms,
            accuracy_vertices,
            accuracy_area,
            colour: coloured.map(|(summary, _)| summary),
        },
        files,
    ))
}

/// The mesh's vertex colours and its textured OBJ (`mesh.obj`, `mesh.mtl`, `mesh.png` in
/// `out`, named in `files`) from the views' `colours`.
fn colour_mesh(
    mesh: &TriangleMesh,
    colours: &ScanColours,
    out: &Path,
    files: &mut MeshFiles,
) -> Result<(MeshColourSummary, Vec<[u8; 3]>), ScanError> {
    colours.config.validate()?;
    let t = std::time::Instant::now();
    let normals = vertex_normals(mesh);
    let seen: Vec<Option<[u8; 3]>> = {
        use rayon::prelude::*;
        mesh.vertices
            .par_iter()
            .zip(&normals)
            .map(|(p, n)| colours.colour_at(p, n))
            .collect()
    };
    let unseen_vertices = seen.iter().filter(|c| c.is_none()).count();
    let vertex_colours: Vec<[u8; 3]> = seen
        .into_iter()
        .map(|c| c.unwrap_or(UNSEEN_COLOUR))
        .collect();
    let vertex_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = std::time::Instant::now();
    let texture = TextureConfig {
        texels_per_edge: colours.texels_per_edge(mesh),
        ..TextureConfig::default()
    };
    let atlas = bake_texture(mesh, &texture, |p, n| colours.colour_at(p, n))?;
    let obj = "mesh.obj";
    let written = write_obj_textured(&out.join(obj), mesh, &atlas)?;
    files.obj = Some(obj.to_owned());
    files.texture = written
        .png
        .file_name()
        .map(|n| n.to_string_lossy().into_owned());
    let texture_ms = t.elapsed().as_secs_f64() * 1e3;
    Ok((
        MeshColourSummary {
            views: colours.views.len(),
            unseen_vertices,
            texture_size: [atlas.image.width(), atlas.image.height()],
            unseen_texels: atlas.unknown_texels,
            vertex_ms,
            texture_ms,
        },
        vertex_colours,
    ))
}

/// Writes the pictures of a mesh into `out`: `preview.png` (shaded, seen from `view`),
/// `mesh.html` (the interactive 3-D page titled `title`, coloured by `errors_mm` when given,
/// in the vertex `colours` when given)
/// and, with errors, `error_map.png` (the signed error at the vertices on the scale of the
/// cloud's error maps, with its legend). Returns the page's path.
///
/// # Errors
/// [`ScanError::Mesh`] when the mesh cannot be drawn, [`ScanError::Codec`] or
/// [`ScanError::Io`] naming a file that cannot be written.
pub fn write_mesh_pictures(
    out: &Path,
    mesh: &TriangleMesh,
    errors_mm: Option<&[f32]>,
    colours: Option<&[[u8; 3]]>,
    view: &PreviewConfig,
    title: String,
) -> Result<PathBuf, ScanError> {
    let img = render_mesh(mesh, MeshColoring::Grey, view)?;
    let png = out.join("preview.png");
    write_png_rgb8(&png, img.width as usize, img.height as usize, &img.rgb)?;
    let page = viewer_html(
        &[ViewerLayer::Mesh {
            name: "mesh",
            mesh,
            errors_mm,
            colours,
        }],
        &ViewerConfig {
            title,
            ..ViewerConfig::default()
        },
    )?;
    let html = out.join("mesh.html");
    write_atomically(&html, page.as_bytes())?;
    if let Some(e) = errors_mm {
        let range = sl_metrology::DEFAULT_HEAT_MAP_RANGE_MM;
        let coloring = MeshColoring::Scalar {
            values: e,
            min: -range,
            max: range,
        };
        let mut img = render_mesh(mesh, coloring, view)?;
        sl_metrology::draw_legend(&mut img, range);
        let map = out.join("error_map.png");
        write_png_rgb8(&map, img.width as usize, img.height as usize, &img.rgb)?;
    }
    Ok(html)
}

/// What [`MeshChain::write_outputs`](crate::MeshChain::write_outputs) wrote and measured.
#[derive(Debug, Clone)]
pub struct MeshOutputs {
    /// The mesh as PLY.
    pub ply: PathBuf,
    /// The mesh as binary STL.
    pub stl: PathBuf,
    /// The interactive 3-D page.
    pub page: PathBuf,
    /// The mesh measured against the truth, at its vertices and over its area (when a truth
    /// was given).
    pub measured: Option<(Report, Report)>,
    /// Wall time per stage: `write`, `measure` (with a truth), `preview`.
    pub stages: Vec<crate::StageTime>,
}

impl crate::MeshChain {
    /// Writes the chain's mesh into `out` (`mesh.ply`, with the vertex colours when the cloud
    /// had colours; `mesh.stl`), measures it against
    /// `truth` when given (at its vertices and over its area) and draws its pictures
    /// ([`write_mesh_pictures`], coloured by the error at the vertices when measured).
    ///
    /// # Errors
    /// The files'; the measurement's.
    pub fn write_outputs(
        &self,
        out: &Path,
        truth: Option<&Truth>,
        view: &PreviewConfig,
        title: String,
    ) -> Result<MeshOutputs, ScanError> {
        let mut stages = Vec::new();
        let mut timed = |name: &str, t: std::time::Instant| {
            stages.push(crate::StageTime::since(name, t));
        };
        let (ply, stl) = (out.join("mesh.ply"), out.join("mesh.stl"));
        let t = std::time::Instant::now();
        match &self.vertex_colours {
            Some(c) => write_ply_mesh_coloured(&ply, &self.mesh, c)?,
            None => write_ply_mesh(&ply, &self.mesh)?,
        }
        write_stl(&stl, &self.mesh)?;
        timed("write", t);
        let measured = match truth {
            Some(truth) => {
                let cfg = EvaluateConfig::default();
                let t = std::time::Instant::now();
                let by_vertex = evaluate_mesh(&self.mesh, truth, MeshSampling::Vertices, &cfg)?;
                timed("measure", t);
                let by_area = evaluate_mesh(&self.mesh, truth, MeshSampling::default(), &cfg)?;
                Some((by_vertex, by_area))
            }
            None => None,
        };
        let t = std::time::Instant::now();
        let errors = measured
            .as_ref()
            .map(|(v, _)| v.signed_distances_mm.as_slice());
        let page = write_mesh_pictures(
            out,
            &self.mesh,
            errors,
            self.vertex_colours.as_deref(),
            view,
            title,
        )?;
        timed("preview", t);
        Ok(MeshOutputs {
            ply,
            stl,
            page,
            measured,
            stages,
        })
    }

    /// What the fairing did, in a sentence, when it moved vertices.
    #[must_use]
    pub fn fairing_summary(&self) -> Option<String> {
        let (f, _) = self.faired.as_ref()?;
        if f.curvature_converged {
            Some(format!(
                "faired {} unseen vertices in {} gap(s), {} of them in smooth surface ({} rim \
                 vertices put on the surface nearby first)",
                f.vertices_moved, f.gaps, f.smooth_gaps, f.rim_moved
            ))
        } else if f.vertices_moved > 0 {
            Some(format!(
                "faired {} unseen vertices in {} gap(s) by the thin plate (the curvature steps \
                 did not settle)",
                f.vertices_moved, f.gaps
            ))
        } else {
            None
        }
    }
}
