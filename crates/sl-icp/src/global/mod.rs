//! Global registration: aligning clouds with no initial pose, from local shape descriptors.
//!
//! The pipeline of one pair ([`register_global`]): voxel downsampling and normals whose sign
//! moves with the cloud ([`orientation`]), FPFH descriptors ([`fpfh`]), correspondences by
//! mutual nearest neighbours in descriptor space with a ratio test ([`correspondences`]),
//! RANSAC with edge-length checks ([`ransac`]), then point-to-plane ICP. Several unordered
//! clouds: [`align_unordered`] ([`multiway`]).

pub(crate) mod correspondences;
pub(crate) mod fpfh;
pub(crate) mod multiway;
pub(crate) mod orientation;
pub(crate) mod pairwise;
pub(crate) mod ransac;

pub use correspondences::{Correspondence, FeatureIndex, MatchConfig, match_features};
pub use fpfh::{FPFH_BINS, Fpfh, FpfhConfig, compute_fpfh};
pub use multiway::{
    MultiwayAlignment, MultiwayConfig, MultiwayPair, UnplacedView, align_unordered, place_views,
};
pub use orientation::orient_normals_outward;
pub use pairwise::{
    GlobalCloud, GlobalConfig, GlobalRegistration, MIN_GLOBAL_POINTS, register_global,
    register_global_prepared,
};
pub use ransac::{RansacConfig, RansacResult, ransac_pose};
