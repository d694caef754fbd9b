//! Metrology of a scanned point cloud: the acceptance figures of VDI/VDE 2634 part 2 measured
//! against a [`Truth`] — what the scanned artefacts are known to be.
//!
//! - A [`Truth`] lists [`Feature`]s: spheres of calibrated radius (with a nominal centre, or
//!   without one: the sphere is then found by RANSAC with the known radius), sphere pairs of
//!   calibrated centre distance, and planes (with or without a nominal plane). It reads and
//!   writes JSON (`docs/metrology.md` documents the file).
//! - [`evaluate`] selects each feature's points and reports ([`Report`]) the probing error
//!   form and size of each sphere, the sphere-spacing error of each pair, the flatness of each
//!   plane — over all points and with 0.3 % left out, as the guideline allows — the RMS and
//!   per-point signed distances to the reference surfaces, and point counts.
//! - [`heat_map`] renders the cloud coloured by those signed distances.
//! - [`evaluate_mesh`] measures a triangle mesh (`sl-mesh`'s surfaces) the same way, over its
//!   vertices or over points spread evenly over its area ([`MeshSampling`]).
//! - [`surface_coverage`] measures how much of a true surface (a triangle mesh) a scan
//!   covers, and [`distance_to_surface`] how far the scan lies from it.
//!
//! ```
//! use nalgebra::{Point3, Vector3};
//! use sl_cloud::PointCloud;
//! use sl_metrology::{Feature, SphereSpec, Truth, evaluate};
//!
//! // The camera-facing half of a sphere of radius 25 mm at 400 mm, sampled exactly, but
//! // 0.01 mm too large.
//! let centre = Point3::new(0.0, 0.0, 400.0);
//! let pts: Vec<_> = (0..2000)
//!     .map(|k| {
//!         let (t, p) = (1.5 * (k % 40) as f64 / 40.0, 0.157 * (k / 40) as f64);
//!         centre + Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), -t.cos()) * 25.01
//!     })
//!     .collect();
//! // The user knows the radius, not where the sphere is.
//! let truth = Truth::new("a 50 mm reference sphere").with(Feature::Sphere(SphereSpec {
//!     name: "ball".into(),
//!     radius_mm: 25.0,
//!     centre_mm: None,
//!     select_mm: 1.0,
//! }));
//! let report = evaluate(&PointCloud::from_positions(pts), &truth)?;
//! let ball = &report.spheres[0];
//! assert!((ball.probing_size_mm - 0.02).abs() < 1e-9);
//! assert!(ball.probing_form_mm < 1e-9);
//! assert!((ball.centre_mm - centre).norm() < 1e-9);
//! # Ok::<(), sl_metrology::MetrologyError>(())
//! ```
//!
//! # Conventions
//!
//! - Millimetres throughout, in the frame of the evaluated cloud (a nominal position in the
//!   truth must be in that frame); `f64` geometry.
//! - Signed distances are positive outside a sphere and on the side of a plane its normal
//!   points to.
//! - The least-squares fits are `sl_cloud::fit_sphere` (geometric, free radius) and
//!   `sl_cloud::fit_plane` (orthogonal distances).
//! - Reports are deterministic: RANSAC draws from a seeded generator.

#![deny(missing_docs)]

mod coverage;
mod error;
mod evaluate;
mod find;
mod heat_map;
mod legend;
mod mesh;
mod truth;

pub use coverage::{
    COVERAGE_SPACINGS, CoverageConfig, DEFAULT_TRUTH_SAMPLE_AREA_MM2, SurfaceCoverage,
    SurfaceDistance, distance_to_surface, surface_coverage,
};
pub use error::MetrologyError;
pub use evaluate::{
    EvaluateConfig, Located, MIN_FEATURE_POINTS, PlaneReport, Report, SpherePairReport,
    SphereReport, VDI_TRIM_FRACTION, evaluate, evaluate_with,
};
pub use heat_map::{DEFAULT_HEAT_MAP_RANGE_MM, heat_map};
pub use legend::{draw_legend, draw_scale};
pub use mesh::{MeshSampling, evaluate_mesh, mesh_samples};
pub use sl_cloud::TriangleMesh;
pub use truth::{
    DEFAULT_SELECT_MM, Feature, PlaneNominal, PlaneSpec, SpherePairSpec, SphereSpec, Truth,
};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
