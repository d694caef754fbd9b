//! The one error type of the crate.

use sl_camera::CameraError;
use sl_cloud::CloudError;

/// Everything that can go wrong in `sl-icp`.
///
/// Every variant names what is at fault: the parameter, the cloud (`"source"`, `"target"`,
/// `"view 7"`), the iteration, or the pair of views.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IcpError {
    /// An error of the point-cloud layer (PLY, voxel grid, normals, index).
    #[error(transparent)]
    Cloud(#[from] CloudError),
    /// An error of the camera layer (an invalid turntable axis).
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// A configuration parameter is out of its valid range.
    #[error("invalid parameter '{parameter}' = {value}: {reason}")]
    InvalidParameter {
        /// Name of the parameter (field of a config struct, or argument).
        parameter: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// A cloud has no finite point.
    #[error("{cloud} has no finite point")]
    EmptyCloud {
        /// Which cloud (`"source"`, `"target"`, `"view 3"`).
        cloud: String,
    },
    /// The chosen metric or association needs normals that the cloud does not have.
    #[error("{cloud} has no normals, but {needed_by} needs them (prepare it with normals)")]
    MissingNormals {
        /// Which cloud.
        cloud: &'static str,
        /// What needs them, e.g. `"point-to-plane"`.
        needed_by: &'static str,
    },
    /// Projective association was asked for but the target is not organised.
    #[error(
        "projective association needs an organised target (PreparedCloud::from_organized), but the target is unorganised"
    )]
    NotOrganized,
    /// An organised grid's size disagrees with the number of points given.
    #[error(
        "organised grid is {width} x {height} = {expected} pixels but {found} points were given"
    )]
    GridSize {
        /// Grid width in pixels.
        width: usize,
        /// Grid height in pixels.
        height: usize,
        /// `width * height`.
        expected: usize,
        /// Number of points given.
        found: usize,
    },
    /// Too few correspondences survived the distance gate and the trimming to estimate a pose.
    #[error(
        "iteration {iteration}: only {found} correspondences within the maximum distance (at least {needed} needed); is the initial pose close enough?"
    )]
    TooFewCorrespondences {
        /// 0-based iteration at which it happened.
        iteration: usize,
        /// Correspondences found.
        found: usize,
        /// Minimum needed.
        needed: usize,
    },
    /// The normal equations of an iteration were singular (a degenerate geometry such as a
    /// single plane, which leaves some motions unconstrained).
    #[error(
        "iteration {iteration}: the {metric} normal equations are singular (degenerate geometry leaves a motion unconstrained)"
    )]
    Degenerate {
        /// 0-based iteration at which it happened.
        iteration: usize,
        /// The metric being solved.
        metric: &'static str,
    },
    /// The number of views and of initial poses (or angles) differ.
    #[error("{views} views but {poses} initial poses")]
    ViewPoseCount {
        /// Number of views.
        views: usize,
        /// Number of poses or angles.
        poses: usize,
    },
    /// The registration of one pair of views failed while merging.
    #[error("registering view {source_view} onto view {target_view}: {error}")]
    Pair {
        /// Index of the source view.
        source_view: usize,
        /// Index of the target view.
        target_view: usize,
        /// What went wrong.
        #[source]
        error: Box<IcpError>,
    },
    /// A pose-graph edge refers to a node that does not exist.
    #[error("pose graph edge {edge} refers to node {node}, but the graph has {nodes} nodes")]
    BadEdge {
        /// Index of the edge.
        edge: usize,
        /// The node index at fault.
        node: usize,
        /// Number of nodes.
        nodes: usize,
    },
    /// A cloud is too small for the voxel size of a registration: after downsampling it has
    /// too few points to describe its shape. A cloud spanning a fraction of a voxel is almost
    /// surely in metres while the workspace works in millimetres.
    #[error(
        "{cloud} spans {extent_mm:.4} mm and keeps {points} points on the {voxel_size} mm voxel grid ({needed} needed){hint}"
    )]
    CloudTooSmall {
        /// Which cloud (`"source"`, `"view 2"`).
        cloud: String,
        /// Diagonal of its bounding box, in its own units (taken for mm).
        extent_mm: f64,
        /// Points left after downsampling.
        points: usize,
        /// Fewest points needed.
        needed: usize,
        /// The voxel size, mm.
        voxel_size: f64,
        /// `": it is almost surely in metres (scale it by 1000)"` when the extent is a
        /// fraction of the voxel size, else empty.
        hint: &'static str,
    },
    /// Global registration found no pose: too few descriptor matches, or no RANSAC hypothesis
    /// with enough inliers.
    #[error(
        "global registration of {source_cloud} onto {target_cloud} failed: {reason} ({correspondences} descriptor matches)"
    )]
    GlobalRegistrationFailed {
        /// The source cloud.
        source_cloud: String,
        /// The target cloud.
        target_cloud: String,
        /// Descriptor matches found.
        correspondences: usize,
        /// Why it failed.
        reason: &'static str,
    },
    /// Some views could not be placed: no registration tied them (through other views) to
    /// view 0. `why` gives, per view, the best pair tried and why it was rejected.
    #[error("views {views:?} could not be placed: {why}")]
    ViewsNotPlaced {
        /// The views (0-based) left without a pose.
        views: Vec<usize>,
        /// For each, why (semicolon-separated).
        why: String,
        /// Every pair registration tried, for the report.
        pairs: Vec<crate::PairRegistration>,
    },
    /// A pose-graph node is not tied to node 0 by any chain of edges, so nothing fixes it.
    #[error("pose graph: node {node} is not connected to node 0 by any chain of edges")]
    PoseGraphDisconnected {
        /// The first node found unreachable.
        node: usize,
    },
}

impl IcpError {
    pub(crate) fn invalid(
        parameter: &'static str,
        value: impl std::fmt::Display,
        reason: &'static str,
    ) -> Self {
        Self::InvalidParameter {
            parameter,
            value: value.to_string(),
            reason,
        }
    }
}
