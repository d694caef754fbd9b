//! The one error type of the crate.

use std::path::PathBuf;

use sl_cloud::CloudError;

/// Everything that can go wrong in `sl-mesh`.
///
/// Every variant names what is at fault: the file (or `<memory>`), the line of an OBJ file, the
/// byte offset in a binary STL, the parameter, or the cloud's missing attribute.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// An error of the point-cloud layer (PLY files, k-d tree).
    #[error(transparent)]
    Cloud(#[from] CloudError),
    /// The operating system refused to read or write a file.
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// What we were doing (`"read"`, `"write"`).
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// Surface reconstruction needs one oriented normal per point.
    #[error(
        "the cloud of {points} points has no normals: surface reconstruction needs oriented normals (estimate them first: `slscan merge` writes them, `--normals-towards X,Y,Z` of `slscan mesh` or `slscan align` estimates them, facing where the scanner stood)"
    )]
    NoNormals {
        /// Number of points of the cloud.
        points: usize,
    },
    /// Too few usable points (finite, with a non-zero normal) to reconstruct a surface.
    #[error("{found} usable points (finite, with a non-zero normal); at least {min} are needed")]
    TooFewPoints {
        /// Usable points found.
        found: usize,
        /// The minimum.
        min: usize,
    },
    /// The usable points all lie at one position: there is no extent to build an octree over.
    #[error("the {points} usable points of the cloud span no volume (all at one position)")]
    DegenerateCloud {
        /// Usable points found.
        points: usize,
    },
    /// A configuration parameter is out of its valid range.
    #[error("invalid parameter '{parameter}' = {value}: {reason}")]
    InvalidParameter {
        /// Name of the parameter (field of a config struct).
        parameter: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// A binary or ASCII STL file is malformed or truncated.
    #[error("{file}: STL, byte offset {offset}: {message}")]
    Stl {
        /// The file (or `<memory>`).
        file: String,
        /// Byte offset where the fault was found.
        offset: u64,
        /// What is wrong.
        message: String,
    },
    /// An OBJ file is malformed.
    #[error("{file}: OBJ, line {line}: {message}")]
    Obj {
        /// The file (or `<memory>`).
        file: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A mesh handed to a function is inconsistent (a triangle index out of range).
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// A per-vertex or per-triangle attribute does not have one value per vertex (triangle).
    #[error("{found} {attribute} for {expected} {of}")]
    AttributeLength {
        /// The attribute (`"colours"`, `"texture coordinates"`).
        attribute: &'static str,
        /// Values given.
        found: usize,
        /// Values needed.
        expected: usize,
        /// What they are counted against (`"vertices"`, `"triangles"`).
        of: &'static str,
    },
    /// An image of the image layer could not be built (a texture atlas of no texel).
    #[error(transparent)]
    Image(#[from] sl_image::ImageError),
    /// A texture image could not be encoded as PNG.
    #[cfg(feature = "image-files")]
    #[error("{path}: PNG encoding failed: {source}")]
    Png {
        /// The file we were writing.
        path: PathBuf,
        /// The encoder's error.
        #[source]
        source: png::EncodingError,
    },
}

impl MeshError {
    pub(crate) fn io(
        path: impl Into<PathBuf>,
        action: &'static str,
        source: std::io::Error,
    ) -> Self {
        Self::Io {
            path: path.into(),
            action,
            source,
        }
    }

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
