//! Triangle meshes from structured-light scans: the surface users print, import into CAD or
//! measure.
//!
//! - [`poisson_reconstruct`]: screened Poisson reconstruction (Kazhdan & Hoppe 2013) of a
//!   cloud with oriented normals on an adaptive octree, extracted by marching tetrahedra: a
//!   watertight, manifold, consistently oriented mesh; per-vertex sampling densities for
//!   `trim_by_density`.
//! - [`simplify`]: error-bounded simplification of the extracted surface (0.01 mm where samples
//!   support it, 0.03 mm where they do not), closed manifolds kept closed and manifold.
//! - [`fair_unsupported`]: the surface that closes what no view saw moved onto the thin-plate
//!   surface spanned by the scanned one, then onto the surface that continues its mean
//!   curvature (`ΔH = 0`), instead of sagging as Poisson's membrane.
//! - [`remesh_isotropic`]: near-equilateral triangles of one edge length, each vertex on the
//!   surface and standing for the same area of it.
//! - Clean-up: [`trim_by_density`] (surface the data does not support), [`smooth_bilateral`]
//!   (feature-preserving) and [`smooth_taubin`], [`decimate`] (quadric error, to a triangle
//!   count), [`fill_holes`], [`remove_small_components`].
//! - Measures: [`check_topology`] (watertight, manifold, orientation), [`vertex_normals`],
//!   [`surface_area`], [`signed_volume`], [`sample_surface`]; [`render_mesh`] draws a shaded
//!   picture.
//! - Files: binary STL, OBJ and PLY with faces ([`write_stl`], [`read_stl`], [`write_obj`],
//!   [`read_obj`], [`write_ply_mesh`], [`read_mesh`]; PLY reading is
//!   [`sl_cloud::read_ply_mesh`]).
//! - Colour: PLY vertex colours ([`write_ply_mesh_coloured`], read back by
//!   [`sl_cloud::read_ply`]); a texture atlas baked from any colour lookup by a trivial
//!   per-triangle parametrisation ([`bake_texture`]) and the textured OBJ with its MTL and PNG
//!   (`write_obj_textured`, feature `image-files`; [`textured_obj_to_strings`]).
//!
//! - [`viewer_html`]: a self-contained interactive 3-D page (WebGL, script inline, works from
//!   `file://`) of meshes and clouds, in grey, in their scan colours or coloured by their error
//!   against a truth.
//!
//! The mesh type is [`TriangleMesh`] of `sl-cloud` (re-exported), where the PLY mesh reader
//! lives: one type from the PLY file to the STL.
//!
//! ```
//! use nalgebra::{Point3, Vector3};
//! use sl_cloud::PointCloud;
//! use sl_mesh::{PoissonConfig, check_topology, poisson_reconstruct, read_stl_from_bytes, stl_to_bytes};
//!
//! // Points of a sphere of radius 5 with outward normals.
//! let (pts, nrm): (Vec<_>, Vec<_>) = (0..3000)
//!     .map(|i| {
//!         let z = 1.0 - 2.0 * (i as f64 + 0.5) / 3000.0;
//!         let t = 2.399_963 * i as f64;
//!         let n = Vector3::new((1.0 - z * z).sqrt() * t.cos(), (1.0 - z * z).sqrt() * t.sin(), z);
//!         (Point3::from(n * 5.0), n)
//!     })
//!     .unzip();
//! let cloud = PointCloud::from_positions(pts).with_normals(nrm)?;
//! let surface = poisson_reconstruct(&cloud, &PoissonConfig { depth: 6, ..PoissonConfig::default() })?;
//! assert!(check_topology(&surface.mesh).is_watertight_manifold());
//! let back = read_stl_from_bytes(&stl_to_bytes(&surface.mesh)?)?;
//! assert_eq!(back.triangles.len(), surface.mesh.triangles.len());
//! # Ok::<(), sl_mesh::MeshError>(())
//! ```
//!
//! # Conventions
//!
//! - Geometry is `f64` in the cloud's units (millimetres for the scanner), in the cloud's frame.
//! - Triangles wind counter-clockwise seen from outside: normals (right-hand rule) point out of
//!   the solid, as STL requires.
//! - Heavy loops run on the global rayon pool.
//! - Colours are 8-bit RGB ([`ColourImage`] of `sl-image`, `[u8; 3]` per vertex). Texture
//!   coordinates follow OBJ: `u` from the image's left edge (0) to its right edge (1), `v` from
//!   its bottom edge (0) to its top edge (1); image row 0 is the top.

#![deny(missing_docs)]

mod adjacency;
mod atlas;
mod bilateral;
mod contour;
mod curvature;
mod decimate;
mod error;
mod fair;
mod files;
mod grid;
mod holes;
mod measure;
mod orientation;
mod poisson;
mod quadric;
mod remesh;
mod render;
mod simplify;
mod taubin;
#[cfg(test)]
mod test_shapes;
mod textured_obj;
mod topology;
mod trim;
mod viewer;

pub use atlas::{MAX_TEXTURE_SIDE, TextureAtlas, TextureConfig, UNKNOWN_COLOUR, bake_texture};
pub use bilateral::{BilateralConfig, smooth_bilateral};
pub use decimate::{Decimation, decimate};
pub use error::MeshError;
pub use fair::{FairConfig, Fairing, fair_unsupported};
pub use files::{
    obj_to_string, ply_mesh_to_bytes, ply_mesh_to_bytes_coloured, read_mesh, read_obj,
    read_obj_from_bytes, read_stl, read_stl_from_bytes, stl_to_bytes, write_obj, write_ply_mesh,
    write_ply_mesh_coloured, write_stl,
};
pub use holes::{HoleFilling, fill_holes};
pub use measure::{signed_volume, surface_area, vertex_normals};
pub use orientation::inconsistent_normal_fraction;
pub use poisson::{MIN_POISSON_POINTS, PoissonConfig, PoissonSurface, poisson_reconstruct};
pub use remesh::{RemeshConfig, Remeshing, remesh_isotropic};
pub use render::{MeshColoring, render_mesh};
pub use simplify::{Simplification, SimplifyConfig, simplify};
pub use sl_cloud::sample_surface;
pub use sl_cloud::{TriangleMesh, read_ply_mesh};
pub use sl_image::ColourImage;
pub use taubin::{TaubinConfig, smooth_taubin};
#[cfg(feature = "image-files")]
pub use textured_obj::write_obj_textured;
pub use textured_obj::{TexturedObjFiles, TexturedObjText, textured_obj_to_strings};
pub use topology::{
    Topology, check_topology, compact_vertices, largest_piece, remove_small_components,
};
pub use trim::{Trimmed, trim_by_density};
pub use viewer::{ViewerConfig, ViewerLayer, viewer_html};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
