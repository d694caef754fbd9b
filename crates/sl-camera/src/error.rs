//! The one error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong in `sl-camera`.
///
/// Messages name what is at fault: the file, the line when there is one, the key or the
/// parameter, and what was expected, e.g.
/// ``calib.yml line 7: key `Kc`: expected 9 values, found 8``.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CameraError {
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },

    /// The file name does not say which format to read or write.
    #[error(
        "{}: unknown calibration file extension (expected .json, .yml, .yaml or .xml)",
        path.display()
    )]
    UnknownExtension {
        /// The file.
        path: PathBuf,
    },

    /// A file is not well-formed (OpenCV FileStorage YAML or XML syntax).
    #[error("{file} line {line}: {message}")]
    Syntax {
        /// The file (or the name given to an in-memory text).
        file: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },

    /// A key of a calibration file holds a value of the wrong shape or an invalid value.
    #[error("{file}{}: key `{key}`: {message}", line_suffix(.line))]
    BadValue {
        /// The file (or the name given to an in-memory text).
        file: String,
        /// 1-based line of the key, when the format keeps it.
        line: Option<usize>,
        /// The key, dotted for nested JSON keys (`camera.intrinsics.fx`).
        key: String,
        /// What is wrong.
        message: String,
    },

    /// A calibration file's camera or projector makes no physical sense (see
    /// [`CameraModel::check_physical`](crate::CameraModel::check_physical)): a field of view
    /// of 1e-303°, a distortion that folds inside the image or decides alone where rays land.
    #[error("{file}{}: {device} key `{key}`: {message}", line_suffix(.line))]
    Implausible {
        /// The file (or the name given to an in-memory text).
        file: String,
        /// 1-based line of the key, when the format keeps it.
        line: Option<usize>,
        /// `camera` or `projector`.
        device: &'static str,
        /// The key as the file spells it: `camera.intrinsics.fx` in JSON, `Kc` or
        /// `distortion_coefficients` in OpenCV FileStorage.
        key: String,
        /// What is wrong, naming the parameter and its value (`fx = 1e308 px: …`).
        message: String,
    },

    /// A key that the format requires is absent.
    #[error("{file}: missing key `{key}`{}", hint_suffix(.hint))]
    MissingKey {
        /// The file (or the name given to an in-memory text).
        file: String,
        /// The key.
        key: String,
        /// Why it is needed, or what else would do.
        hint: Option<String>,
    },

    /// A JSON calibration file does not parse or does not have the expected fields
    /// (the message of `serde_json` gives line and column).
    #[error("{file}: {source}")]
    Json {
        /// The file (or the name given to an in-memory text).
        file: String,
        /// The error of `serde_json`.
        source: serde_json::Error,
    },

    /// A JSON calibration file has a format version this build does not know.
    #[error(
        "{file}: calibration format version {found} is not supported (this build of sl-camera \
         reads version {supported}; a newer sl-camera wrote this file?)"
    )]
    UnsupportedVersion {
        /// The file (or the name given to an in-memory text).
        file: String,
        /// The version found in the file.
        found: u64,
        /// The version this build writes and reads.
        supported: u32,
    },

    /// A parameter given through the API is invalid (not finite, out of range, wrong count).
    #[error("parameter `{parameter}`: {message}")]
    InvalidParameter {
        /// The parameter (`fx`, `distortion`, `T_cam_proj.rotation`, ...).
        parameter: String,
        /// What is wrong.
        message: String,
    },
}

fn line_suffix(line: &Option<usize>) -> String {
    line.map_or_else(String::new, |l| format!(" line {l}"))
}

fn hint_suffix(hint: &Option<String>) -> String {
    hint.as_ref()
        .map_or_else(String::new, |h| format!(" ({h})"))
}

/// An invalid image size or buffer becomes [`CameraError::InvalidParameter`] naming the same
/// parameter (`width`, `height`), so `size.validate()?` reads as it did when the size was this
/// crate's.
impl From<sl_image::ImageError> for CameraError {
    fn from(e: sl_image::ImageError) -> Self {
        match e {
            sl_image::ImageError::InvalidParameter { name, reason } => Self::InvalidParameter {
                parameter: name,
                message: reason,
            },
            other => Self::InvalidParameter {
                parameter: "image".to_owned(),
                message: other.to_string(),
            },
        }
    }
}

impl CameraError {
    /// Shorthand for [`CameraError::InvalidParameter`].
    pub(crate) fn invalid(parameter: impl Into<String>, message: impl Into<String>) -> Self {
        Self::InvalidParameter {
            parameter: parameter.into(),
            message: message.into(),
        }
    }

    /// Puts an API-level [`CameraError::InvalidParameter`] into the context of a file: the
    /// parameter becomes a key of `file` (prefixed with `key_prefix`); other errors are kept.
    pub(crate) fn in_file(self, file: &str, key_prefix: &str, line: Option<usize>) -> Self {
        match self {
            Self::InvalidParameter { parameter, message } => Self::BadValue {
                file: file.to_owned(),
                line,
                key: if key_prefix.is_empty() {
                    parameter
                } else {
                    format!("{key_prefix}.{parameter}")
                },
                message,
            },
            other => other,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_file_line_and_key() {
        let e = CameraError::BadValue {
            file: "calib.yml".into(),
            line: Some(7),
            key: "Kc".into(),
            message: "expected 9 values, found 8".into(),
        };
        assert_eq!(
            e.to_string(),
            "calib.yml line 7: key `Kc`: expected 9 values, found 8"
        );
        let e = CameraError::invalid("fx", "must be positive, found -1").in_file(
            "c.json",
            "camera.intrinsics",
            None,
        );
        assert_eq!(
            e.to_string(),
            "c.json: key `camera.intrinsics.fx`: must be positive, found -1"
        );
        let e = CameraError::MissingKey {
            file: "a.xml".into(),
            key: "image_width".into(),
            hint: None,
        };
        assert_eq!(e.to_string(), "a.xml: missing key `image_width`");
    }
}
