//! The one error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong in `sl-cloud`.
///
/// Every variant names what is at fault: the file (or `<memory>` for byte slices), the line of an
/// ASCII PLY, the byte offset in a binary PLY, the attribute or the parameter.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CloudError {
    /// The operating system refused to read, write or rename a file.
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// What we were doing (`"read"`, `"write"`, `"rename"`, ...).
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A least-squares fit got too few usable points, or points in a degenerate arrangement.
    #[error("{what} fit: {message}")]
    Fit {
        /// `plane` or `sphere`.
        what: &'static str,
        /// What is wrong (counts, degeneracy).
        message: String,
    },
    /// The PLY header is malformed (bad magic, unknown format, bad `element`/`property` line...).
    #[error("{file}: PLY header, line {line}: {message}")]
    PlyHeader {
        /// The file (or `<memory>`).
        file: String,
        /// 1-based line number in the file.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The body of an ASCII PLY is malformed or truncated.
    #[error("{file}: ASCII PLY data, line {line}: {message}")]
    PlyAscii {
        /// The file (or `<memory>`).
        file: String,
        /// 1-based line number in the file (header lines included).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The body of a binary PLY is malformed or truncated.
    #[error("{file}: binary PLY data, byte offset {offset}: {message}")]
    PlyBinary {
        /// The file (or `<memory>`).
        file: String,
        /// Byte offset from the start of the file where the fault was found.
        offset: u64,
        /// What is wrong.
        message: String,
    },
    /// The PLY file lacks something we need (the `vertex` element, or `x`/`y`/`z`).
    #[error("{file}: PLY file has no {what}")]
    PlyMissing {
        /// The file (or `<memory>`).
        file: String,
        /// What is missing, e.g. `"element 'vertex'"` or `"property 'x' in element 'vertex'"`.
        what: String,
    },
    /// A cloud spans less than a tool expects of one in millimetres: its coordinates are
    /// almost surely metres.
    #[error(
        "{file}: the cloud spans {extent:.4} units (the diagonal of its box), less than {limit} mm: its coordinates are probably metres (multiply them by 1000)"
    )]
    NotMillimetres {
        /// The file.
        file: String,
        /// The diagonal of its bounding box, in its units.
        extent: f64,
        /// The smallest diagonal expected (mm).
        limit: f64,
    },
    /// A cloud cannot serve whatever its units: no finite point, too few, all at one place
    /// (see [`crate::degeneracy`]).
    #[error("{file}: {reason}")]
    Degenerate {
        /// The file.
        file: String,
        /// What is wrong with it.
        reason: crate::Degeneracy,
    },
    /// An optional attribute was given with a length different from the number of points.
    #[error("attribute '{attribute}' has {found} values but the cloud has {expected} points")]
    AttributeLength {
        /// `"normals"`, `"colors"` or `"quality"`.
        attribute: &'static str,
        /// Number of points.
        expected: usize,
        /// Number of attribute values given.
        found: usize,
    },
    /// Two clouds being merged disagree on which optional attributes they carry.
    #[error(
        "cannot merge clouds: attribute '{attribute}' is present in one cloud only (use MergePolicy::DropMismatched to drop it)"
    )]
    AttributeMismatch {
        /// `"normals"`, `"colors"` or `"quality"`.
        attribute: &'static str,
    },
    /// An index passed to a selection is out of range.
    #[error(
        "index {index} (position {position} in the index list) is out of range for a cloud of {len} points"
    )]
    IndexOutOfRange {
        /// The offending index.
        index: usize,
        /// Where it sits in the list of indices.
        position: usize,
        /// Number of points in the cloud.
        len: usize,
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
    /// More points than the k-d tree can index (its item ids are `u32`).
    #[error("cloud of {len} points is too large to index (at most {max})")]
    TooManyPoints {
        /// Number of points given.
        len: usize,
        /// The maximum supported.
        max: usize,
    },
}

impl CloudError {
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
