//! The one error type of the scan stages.

use std::path::PathBuf;

/// Everything that can stop a stage of the scan: the error of the crate that failed, or a file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScanError {
    /// The devices or the capture session.
    #[error(transparent)]
    Rig(#[from] sl_rig::RigError),
    /// The virtual rig.
    #[cfg(feature = "sim")]
    #[error(transparent)]
    Sim(#[from] sl_sim::SimError),
    /// Calibration.
    #[error("calibration: {0}")]
    Calib(#[from] sl_calib::CalibError),
    /// Patterns, decoding or image files.
    #[error(transparent)]
    Codec(#[from] sl_codec::CodecError),
    /// Triangulation.
    #[error(transparent)]
    Tri(#[from] sl_tri::TriError),
    /// Measuring the result against the truth.
    #[error("report: {0}")]
    Metrology(#[from] sl_metrology::MetrologyError),
    /// The mesh (`sl-mesh`).
    #[cfg(feature = "mesh")]
    #[error("mesh: {0}")]
    Mesh(#[from] sl_mesh::MeshError),
    /// A step of the mesh chain ([`mesh_chain`](crate::mesh_chain)) failed.
    #[cfg(feature = "mesh")]
    #[error("mesh {step}: {source}")]
    MeshStep {
        /// The step: `reconstruct`, `trim`, `simplify`, `fair`, `remesh`, `fill holes`,
        /// `smooth`, `decimate` or `orientation`.
        step: &'static str,
        /// What `sl-mesh` refused.
        #[source]
        source: sl_mesh::MeshError,
    },
    /// No piece of the surface the Poisson reconstruction extracted has the triangles a piece
    /// must keep ([`MeshChainConfig::min_piece`](crate::MeshChainConfig)): the octree is too
    /// coarse for the cloud (its parts fall between the nodes of the finest cells), or the
    /// pieces asked for are larger than any depth makes of this cloud.
    #[cfg(feature = "mesh")]
    #[error(
        "no triangle is left of the mesh: at octree depth {depth} (finest cells {cell_mm:.3} mm) \
         the surface extracted has {extracted} triangles, its largest piece {largest_piece}, \
         fewer than the {min_piece} a piece must keep; {}",
        deeper_depth(.meshes_at, .searched_to)
    )]
    MeshTooCoarse {
        /// The octree depth of the reconstruction.
        depth: u32,
        /// The edge of its finest cells (mm).
        cell_mm: f64,
        /// Triangles extracted.
        extracted: usize,
        /// Triangles of their largest connected piece.
        largest_piece: usize,
        /// Fewest triangles a piece must have to be kept.
        min_piece: usize,
        /// The smallest deeper depth at which the whole chain leaves a mesh, if one up to
        /// `searched_to` does.
        meshes_at: Option<u32>,
        /// The deepest depth considered (the default depth, or the one asked if deeper).
        searched_to: u32,
    },
    /// An error of the merge (`sl-icp`).
    #[error("merge: {0}")]
    Icp(#[from] sl_icp::IcpError),
    /// Point-cloud files and previews.
    #[error(transparent)]
    Cloud(#[from] sl_cloud::CloudError),
    /// Calibration files.
    #[error(transparent)]
    Camera(#[from] sl_camera::CameraError),
    /// A stage found nothing to work on (no board found, an empty view, ...).
    #[error("{stage}: {reason}")]
    Stage {
        /// The stage (`calibrate`, `reconstruct`, ...).
        stage: String,
        /// What went wrong.
        reason: String,
    },
    /// The output folder: held by another run, or holding this run's inputs.
    #[error(transparent)]
    Output(#[from] crate::OutputError),
    /// A calibration session's layout, pose folders or pose files.
    #[error(transparent)]
    Layout(#[from] crate::LayoutError),
    /// A session's or an input's file or folder is missing or is not what the step expects.
    #[error("{}: {reason}", path.display())]
    Session {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A step failed: which one, on what (`camera calibration from 7 views with a board`,
    /// `board pose SESSION/board/pose_003`), and why.
    #[error("{what}: {source}")]
    Step {
        /// The step and what it worked on.
        what: String,
        /// Why it failed.
        #[source]
        source: Box<ScanError>,
    },
    /// A parameter of a configuration is out of its range.
    #[error("{name} {reason}")]
    InvalidParameter {
        /// The parameter (`views`, ...).
        name: String,
        /// What is wrong with its value.
        reason: String,
    },
    /// A file could not be written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// The end of [`ScanError::MeshTooCoarse`]'s message: the depth that meshes, or none.
#[cfg(feature = "mesh")]
fn deeper_depth(meshes_at: &Option<u32>, searched_to: &u32) -> String {
    meshes_at.map_or_else(
        || format!("no depth up to {searched_to} would make a piece that large"),
        |d| format!("depth {d} meshes the cloud"),
    )
}

/// Shorthand for [`ScanError::Stage`].
pub(crate) fn stage_err(stage: &str, reason: impl Into<String>) -> ScanError {
    ScanError::Stage {
        stage: stage.to_owned(),
        reason: reason.into(),
    }
}

/// Maps an I/O error on `path` to [`ScanError::Io`].
pub(crate) fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> ScanError + '_ {
    move |source| ScanError::Io {
        path: path.to_path_buf(),
        source,
    }
}
