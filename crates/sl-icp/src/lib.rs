//! ICP registration of point clouds and the 360° merge of a turntable scan.
//!
//! A turntable scan yields one cloud per platter angle. This crate registers them and merges
//! them into one metric model:
//!
//! - **Registration** ([`register`], [`Icp`]): point-to-point (closed form by SVD),
//!   point-to-plane (linearised 6x6 solve) and generalized ICP (plane-to-plane) metrics;
//!   closest-point (k-d tree), projective (organised targets) and normal-shooting association;
//!   trimmed ICP and Huber / Tukey kernels; a maximum correspondence distance; convergence on
//!   the change of pose and of error. The result ([`Registration`]) carries the pose, RMSE,
//!   fitness, iterations, a converged flag and the information matrix for pose graphs.
//!   Iterations run in parallel on the rayon pool and allocate nothing.
//! - **Turntable merge** ([`turntable_poses`], [`align_views`], [`merge_aligned`],
//!   [`merge_views`]): initial poses from the calibrated axis and the motor angles, pairwise
//!   registration of neighbouring views with a loop closure, then the poses: by default the
//!   turntable model ([`PoseModel::Turntable`]: the axis and one angle per view; the
//!   calibrated turntable kept wherever the registrations agree with it within both
//!   uncertainties and corrected where they do not, each registration weighted by what it
//!   measures along the surface normals, with the motions it leaves free — a sphere turning
//!   on itself — given no weight; [`ViewAlignment::sources`] says where each view's pose came
//!   from), or a free pose graph ([`optimize_pose_graph`], [`PoseModel::Free`]); then
//!   merge, voxel downsampling, normals and optional averaging of overlapping points.
//!   `docs/registration.md` has the figures.
//!
//! ```
//! use nalgebra::{Isometry3, Point3, Vector3};
//! use sl_icp::{register, IcpConfig, PoseError, PrepareConfig, PreparedCloud, PointCloud};
//!
//! // A smooth bumpy patch (mm) and the same patch seen after a small rigid motion.
//! let surface: Vec<Point3<f64>> = (0..4900)
//!     .map(|i| {
//!         let (x, y) = ((i % 70) as f64 * 0.8, (i / 70) as f64 * 0.8);
//!         Point3::new(x, y, 300.0 + 6.0 * (x / 9.0).sin() * (y / 13.0).cos())
//!     })
//!     .collect();
//! let t_target_source = Isometry3::new(Vector3::new(0.8, -0.5, 0.3), Vector3::new(0.02, -0.01, 0.03));
//! let seen: Vec<Point3<f64>> = surface.iter().map(|p| t_target_source.inverse() * p).collect();
//!
//! // Normals are estimated while preparing (point-to-plane needs the target's).
//! let target = PreparedCloud::new(&PointCloud::from_positions(surface), &PrepareConfig::default())?;
//! let source = PreparedCloud::new(&PointCloud::from_positions(seen.clone()), &PrepareConfig::default())?;
//! let result = register(&source, &target, &Isometry3::identity(), &IcpConfig::default())?;
//!
//! assert!(result.converged && result.fitness > 0.99);
//! let error = PoseError::between(&result.pose, &t_target_source, &seen);
//! assert!(error.rotation_deg < 1e-4 && error.rms_displacement_mm < 1e-4);
//! # Ok::<(), sl_icp::IcpError>(())
//! ```
//!
//! # Conventions
//!
//! - Lengths in **millimetres**, `f64` throughout (the Stanford scans, in metres, are scaled
//!   by 1000 when loaded). Angles in the API are radians except where a name says `_deg`.
//! - Poses are [`nalgebra::Isometry3<f64>`] named `T_a_b`: they map frame-`b` coordinates into
//!   frame `a`. A registration of `source` onto `target` returns `T_target_source`; the views
//!   of a merge get `T_world_view` with the world frame the camera frame of view 0.
//! - Camera frame as OpenCV: x right, y down, z forward; a view's cloud is in its camera frame,
//!   so normals are estimated facing the origin by default.
//! - Small motions are `(ω, t)` 6-vectors, rotation first (rad, mm), applied on the left as
//!   `x -> R(ω) x + t`, as Open3D orders its information matrices.
//! - The turntable turns right-handedly about its axis direction ([`TurntableAxis`], from
//!   `sl-camera`); the initial pose of a view at platter angle `θ` is the rotation by `-θ`
//!   about the axis (relative to view 0).
//! - Heavy loops run on the global rayon pool.

#![deny(missing_docs)]

mod association;
mod config;
mod error;
mod global;
mod icp;
mod merge;
mod metric;
mod normals;
mod pair_information;
mod pose_error;
mod pose_graph;
mod prepared;
mod se3;
mod trimming;
mod turntable;
mod turntable_model;

pub use config::{Association, IcpConfig, Metric, RobustKernel, Trimming};
pub use error::IcpError;
pub use global::{
    Correspondence, FPFH_BINS, FeatureIndex, Fpfh, FpfhConfig, GlobalCloud, GlobalConfig,
    GlobalRegistration, MIN_GLOBAL_POINTS, MatchConfig, MultiwayAlignment, MultiwayConfig,
    MultiwayPair, RansacConfig, RansacResult, UnplacedView, align_unordered, compute_fpfh,
    match_features, orient_normals_outward, place_views, ransac_pose, register_global,
    register_global_prepared,
};
pub use icp::{
    Evaluation, Icp, IcpStep, MIN_CORRESPONDENCES, Registration, register, register_clouds,
};
pub use merge::{
    MergeConfig, MergedScan, PairRegistration, ViewAlignment, ViewPoseSource, align_views,
    merge_aligned, merge_views,
};
pub use pair_information::FreeMotion;
pub use pose_error::PoseError;
pub use pose_graph::{
    PoseGraph, PoseGraphConfig, PoseGraphEdge, PoseGraphSolution, optimize_pose_graph,
};
pub use prepared::{NormalSource, PinholeGrid, PrepareConfig, PreparedCloud};
pub use sl_camera::TurntableAxis;
pub use sl_cloud::{NormalConfig, NormalOrientation, PointCloud};
pub use turntable::turntable_poses;
pub use turntable_model::{PoseModel, TurntableFit, TurntablePrior};

/// The README's example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
