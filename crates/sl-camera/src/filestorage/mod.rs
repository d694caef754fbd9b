//! A reader and writer for the subset of OpenCV's `cv::FileStorage` formats that calibration
//! files use: YAML (`%YAML:1.0` or `%YAML 1.2` header, `!!opencv-matrix` maps, flow and block
//! sequences, scalars, quoted strings, comments) and XML (`<opencv_storage>`,
//! `type_id="opencv-matrix"`, `<_>` sequence items, comments).
//!
//! Generic YAML crates reject OpenCV's `%YAML:1.0` header, and we need line numbers in error
//! messages, hence this small dedicated reader.

mod writer;
mod xml;
mod yaml;

pub(crate) use writer::{Item, to_xml, to_yaml};
pub(crate) use xml::parse_xml;
pub(crate) use yaml::parse_yaml;

use crate::CameraError;

/// Deepest nesting of maps and sequences the readers accept. Calibration files nest two
/// levels; the limit keeps the recursive readers from exhausting the stack on hostile input.
pub(crate) const MAX_NESTING: usize = 64;

/// A value of the tree, with the 1-based line where it starts.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Node {
    pub(crate) line: usize,
    pub(crate) value: Value,
}

#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Value {
    /// An unquoted scalar (number, identifier), as written.
    Scalar(String),
    /// A quoted string, unescaped.
    Str(String),
    Seq(Vec<Node>),
    /// A map; `tag` is `opencv-matrix` for matrices.
    Map {
        tag: Option<String>,
        entries: Vec<(String, Node)>,
    },
}

/// A parsed file: the top-level map and the file name for messages.
#[derive(Clone, Debug)]
pub(crate) struct Document {
    pub(crate) file: String,
    pub(crate) entries: Vec<(String, Node)>,
}

/// A numeric matrix read from an `opencv-matrix` node.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MatrixData {
    pub(crate) rows: usize,
    pub(crate) cols: usize,
    pub(crate) data: Vec<f64>,
    /// Line of the key, for messages of the caller.
    pub(crate) line: usize,
}

impl Document {
    /// The node of a top-level key (the last one if repeated, as OpenCV does).
    pub(crate) fn get(&self, key: &str) -> Option<&Node> {
        self.entries
            .iter()
            .rev()
            .find(|(k, _)| k == key)
            .map(|(_, n)| n)
    }

    pub(crate) fn has(&self, key: &str) -> bool {
        self.get(key).is_some()
    }

    pub(crate) fn bad(&self, key: &str, line: usize, message: impl Into<String>) -> CameraError {
        CameraError::BadValue {
            file: self.file.clone(),
            line: Some(line),
            key: key.to_owned(),
            message: message.into(),
        }
    }

    pub(crate) fn missing(&self, key: &str, hint: Option<&str>) -> CameraError {
        CameraError::MissingKey {
            file: self.file.clone(),
            key: key.to_owned(),
            hint: hint.map(str::to_owned),
        }
    }

    /// A real number (integers are accepted).
    pub(crate) fn number(&self, key: &str) -> Result<Option<f64>, CameraError> {
        let Some(node) = self.get(key) else {
            return Ok(None);
        };
        match &node.value {
            Value::Scalar(s) => parse_real(s)
                .map(Some)
                .ok_or_else(|| self.bad(key, node.line, format!("expected a number, found `{s}`"))),
            other => Err(self.bad(
                key,
                node.line,
                format!("expected a number, found {}", describe(other)),
            )),
        }
    }

    /// A non-negative integer that fits `u32`.
    pub(crate) fn unsigned(&self, key: &str) -> Result<Option<u32>, CameraError> {
        let Some(node) = self.get(key) else {
            return Ok(None);
        };
        match &node.value {
            Value::Scalar(s) => s.parse::<u32>().map(Some).map_err(|_| {
                self.bad(
                    key,
                    node.line,
                    format!("expected a non-negative integer, found `{s}`"),
                )
            }),
            other => Err(self.bad(
                key,
                node.line,
                format!("expected an integer, found {}", describe(other)),
            )),
        }
    }

    /// A string (quoted or not).
    pub(crate) fn string(&self, key: &str) -> Result<Option<String>, CameraError> {
        let Some(node) = self.get(key) else {
            return Ok(None);
        };
        match &node.value {
            Value::Str(s) | Value::Scalar(s) => Ok(Some(s.clone())),
            other => Err(self.bad(
                key,
                node.line,
                format!("expected a string, found {}", describe(other)),
            )),
        }
    }

    /// An `opencv-matrix` of real numbers, with its element count checked.
    pub(crate) fn matrix(&self, key: &str) -> Result<Option<MatrixData>, CameraError> {
        let Some(node) = self.get(key) else {
            return Ok(None);
        };
        let Value::Map { tag, entries } = &node.value else {
            return Err(self.bad(
                key,
                node.line,
                format!("expected an opencv-matrix, found {}", describe(&node.value)),
            ));
        };
        if tag.as_deref() != Some("opencv-matrix") {
            return Err(self.bad(
                key,
                node.line,
                "expected an opencv-matrix (a map tagged `!!opencv-matrix` or `type_id=\"opencv-matrix\"`)",
            ));
        }
        let field = |name: &str| {
            entries
                .iter()
                .rev()
                .find(|(k, _)| k == name)
                .map(|(_, n)| n)
        };
        let dim = |name: &str| -> Result<usize, CameraError> {
            let n = field(name)
                .ok_or_else(|| self.bad(key, node.line, format!("matrix has no `{name}`")))?;
            match &n.value {
                Value::Scalar(s) => s.parse::<usize>().map_err(|_| {
                    self.bad(
                        key,
                        n.line,
                        format!("matrix `{name}` must be an integer, found `{s}`"),
                    )
                }),
                other => Err(self.bad(
                    key,
                    n.line,
                    format!(
                        "matrix `{name}` must be an integer, found {}",
                        describe(other)
                    ),
                )),
            }
        };
        let rows = dim("rows")?;
        let cols = dim("cols")?;
        let dt_node = field("dt").ok_or_else(|| self.bad(key, node.line, "matrix has no `dt`"))?;
        let dt = match &dt_node.value {
            Value::Scalar(s) | Value::Str(s) => s.clone(),
            other => {
                return Err(self.bad(
                    key,
                    dt_node.line,
                    format!(
                        "matrix `dt` must be a type string, found {}",
                        describe(other)
                    ),
                ));
            }
        };
        let channels = parse_dt(&dt)
            .ok_or_else(|| self.bad(key, dt_node.line, format!("unknown matrix type dt `{dt}`")))?;
        let data_node =
            field("data").ok_or_else(|| self.bad(key, node.line, "matrix has no `data`"))?;
        let items: Vec<&Node> = match &data_node.value {
            Value::Seq(items) => items.iter().collect(),
            Value::Scalar(s) if s.is_empty() => Vec::new(),
            Value::Scalar(_) => vec![data_node],
            other => {
                return Err(self.bad(
                    key,
                    data_node.line,
                    format!(
                        "matrix `data` must be a list of numbers, found {}",
                        describe(other)
                    ),
                ));
            }
        };
        let expected = rows * cols * channels;
        if items.len() != expected {
            return Err(self.bad(
                key,
                node.line,
                format!(
                    "expected {expected} values ({rows}x{cols}{}), found {}",
                    if channels > 1 {
                        format!("x{channels} channels")
                    } else {
                        String::new()
                    },
                    items.len()
                ),
            ));
        }
        let mut data = Vec::with_capacity(expected);
        for (i, item) in items.iter().enumerate() {
            let value = match &item.value {
                Value::Scalar(s) => parse_real(s),
                _ => None,
            };
            match value {
                Some(v) => data.push(v),
                None => {
                    return Err(self.bad(
                        key,
                        item.line,
                        format!("data value {} is not a number", i + 1),
                    ));
                }
            }
        }
        Ok(Some(MatrixData {
            rows,
            cols: cols * channels,
            data,
            line: node.line,
        }))
    }
}

/// Channels of an OpenCV `dt` string: an optional count followed by one type letter
/// (`u c w s i f d h`).
fn parse_dt(dt: &str) -> Option<usize> {
    let digits: String = dt.chars().take_while(char::is_ascii_digit).collect();
    let rest = &dt[digits.len()..];
    let channels = if digits.is_empty() {
        1
    } else {
        digits.parse().ok()?
    };
    (rest.len() == 1 && "ucwsifdhr".contains(rest) && channels >= 1).then_some(channels)
}

/// A real number as OpenCV writes it, including `.nan`, `.inf`, `-.inf` (any case).
pub(crate) fn parse_real(s: &str) -> Option<f64> {
    match s.to_ascii_lowercase().as_str() {
        ".nan" => Some(f64::NAN),
        ".inf" | "+.inf" => Some(f64::INFINITY),
        "-.inf" => Some(f64::NEG_INFINITY),
        lower => {
            // Rust accepts "inf"/"nan"/"infinity" words; OpenCV never writes them bare.
            if lower.chars().any(|c| c.is_ascii_alphabetic() && c != 'e') {
                return None;
            }
            lower.parse::<f64>().ok()
        }
    }
}

fn describe(v: &Value) -> &'static str {
    match v {
        Value::Scalar(_) => "a scalar",
        Value::Str(_) => "a string",
        Value::Seq(_) => "a sequence",
        Value::Map { tag: Some(_), .. } => "a matrix",
        Value::Map { tag: None, .. } => "a map",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reals_as_opencv_writes_them() {
        assert_eq!(parse_real("1."), Some(1.0));
        assert_eq!(parse_real("-2.5e-3"), Some(-2.5e-3));
        assert_eq!(parse_real("9.9999999999999995e-21"), Some(1e-20));
        assert_eq!(parse_real("1280"), Some(1280.0));
        assert!(parse_real(".Nan").unwrap().is_nan());
        assert_eq!(parse_real("-.Inf"), Some(f64::NEG_INFINITY));
        assert_eq!(parse_real("inf"), None);
        assert_eq!(parse_real("abc"), None);
        assert_eq!(parse_real(""), None);
    }

    #[test]
    fn deep_nesting_is_an_error_not_a_stack_overflow() {
        let deep_flow = format!(
            "%YAML:1.0\na: {}{}\n",
            "[".repeat(10_000),
            "]".repeat(10_000)
        );
        let e = parse_yaml(&deep_flow, "d.yml").unwrap_err().to_string();
        assert!(e.contains("nested deeper"), "{e}");
        let mut deep_block = String::from("%YAML:1.0\n");
        for i in 0..200 {
            deep_block.push_str(&format!("{}k{i}:\n", " ".repeat(i)));
        }
        let e = parse_yaml(&deep_block, "d.yml").unwrap_err().to_string();
        assert!(e.contains("nested deeper"), "{e}");
        let deep_xml = format!(
            "<opencv_storage>{}{}</opencv_storage>",
            "<a>".repeat(10_000),
            "</a>".repeat(10_000)
        );
        let e = parse_xml(&deep_xml, "d.xml").unwrap_err().to_string();
        assert!(e.contains("nested deeper"), "{e}");
    }

    const FRAGMENTS: [&str; 34] = [
        "%YAML:1.0\n",
        "---\n",
        "Kc: ",
        "kc: ",
        "!!opencv-matrix",
        "\n   rows: 3",
        "\n   cols: 3",
        "\n   dt: d",
        "\n   data: [",
        "1.5, ",
        "]",
        "{",
        "}",
        ",",
        "\"",
        "'",
        "\\",
        "#",
        "\n",
        "   ",
        "- ",
        "<",
        ">",
        "</",
        "/>",
        "&quot;",
        "&#x",
        "<opencv_storage>",
        "</opencv_storage>",
        "<Kc type_id=\"opencv-matrix\">",
        "<data>",
        "</data>",
        "é",
        "\t",
    ];

    proptest::proptest! {
        /// The readers never panic, whatever they are fed: they return a tree or an error.
        #[test]
        fn readers_never_panic(picks in proptest::collection::vec(0..FRAGMENTS.len(), 0..80)) {
            let text: String = picks.iter().map(|&i| FRAGMENTS[i]).collect();
            let _ = parse_yaml(&text, "fuzz.yml");
            let _ = parse_xml(&text, "fuzz.xml");
            let _ = crate::Calibration::from_opencv_yaml(&text, "fuzz.yml");
            let _ = crate::Calibration::from_opencv_xml(&text, "fuzz.xml");
        }
    }

    #[test]
    fn dt_channels() {
        assert_eq!(parse_dt("d"), Some(1));
        assert_eq!(parse_dt("2f"), Some(2));
        assert_eq!(parse_dt("dd"), None);
        assert_eq!(parse_dt("x"), None);
    }
}
