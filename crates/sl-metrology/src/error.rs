//! The one error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong in `sl-metrology`. Messages name the feature of the truth
/// description (or the file) at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MetrologyError {
    /// The truth description is inconsistent (a bad radius, an unknown sphere name, ...).
    #[error("truth, feature `{feature}`: {reason}")]
    InvalidTruth {
        /// The feature (or `truth` for the description as a whole).
        feature: String,
        /// What is wrong.
        reason: String,
    },
    /// A feature's selection region holds too few points to measure it.
    #[error("feature `{feature}`: {found} points in its selection region, need at least {needed}")]
    TooFewPoints {
        /// The feature.
        feature: String,
        /// Points found.
        found: usize,
        /// Points needed.
        needed: usize,
    },
    /// A feature without a nominal position could not be found in the cloud.
    #[error("feature `{feature}` not found: {reason}")]
    NotFound {
        /// The feature.
        feature: String,
        /// Why (best candidate's support, ...).
        reason: String,
    },
    /// A least-squares fit of a feature failed (degenerate points).
    #[error("feature `{feature}`: {source}")]
    Fit {
        /// The feature.
        feature: String,
        /// The fit's error (boxed: it is large, and rare).
        source: Box<sl_cloud::CloudError>,
    },
    /// An option is out of range.
    #[error("option `{parameter}`: {reason}")]
    InvalidParameter {
        /// The option.
        parameter: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// A truth file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A truth file is not valid JSON of the expected shape.
    #[error("{}: {source}", path.display())]
    Json {
        /// The file (`<string>` when parsed from memory).
        path: PathBuf,
        /// The parser's error (line and column).
        source: serde_json::Error,
    },
    /// Point clouds and previews.
    #[error(transparent)]
    Cloud(#[from] sl_cloud::CloudError),
}

impl MetrologyError {
    pub(crate) fn truth(feature: &str, reason: impl Into<String>) -> Self {
        Self::InvalidTruth {
            feature: feature.to_owned(),
            reason: reason.into(),
        }
    }

    pub(crate) fn fit(feature: &str, source: sl_cloud::CloudError) -> Self {
        Self::Fit {
            feature: feature.to_owned(),
            source: Box::new(source),
        }
    }
}
