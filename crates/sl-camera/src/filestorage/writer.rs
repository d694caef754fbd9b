//! OpenCV FileStorage YAML and XML writers (the layout `cv::FileStorage` writes, so OpenCV
//! reads our files back).

use std::fmt::Write as _;

/// A top-level value to write.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Item {
    Int(i64),
    Real(f64),
    Str(String),
    /// A `rows × cols` matrix of doubles (`dt: d`), row-major.
    Matrix {
        rows: usize,
        cols: usize,
        data: Vec<f64>,
    },
}

/// Values per line of matrix data.
const VALUES_PER_LINE: usize = 4;

/// A real number that OpenCV parses as a real and that reads back exactly: Rust's shortest
/// round-trip form, which always has a `.` or a lowercase `e` (OpenCV decides "real" on
/// those characters).
fn real(v: f64) -> String {
    if v.is_nan() {
        ".nan".into()
    } else if v.is_infinite() {
        if v > 0.0 {
            ".inf".into()
        } else {
            "-.inf".into()
        }
    } else {
        let s = format!("{v:?}");
        if s.contains(['.', 'e']) {
            s
        } else {
            format!("{s}.")
        }
    }
}

fn yaml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '&' => out.push_str("&amp;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // OpenCV's XML reader wants a string on one line: control characters as
            // numeric references, as cv::FileStorage writes them.
            c if u32::from(c) < 0x20 => {
                let _ = write!(out, "&#x{:02x};", u32::from(c));
            }
            c => out.push(c),
        }
    }
    out
}

/// Writes items as OpenCV FileStorage YAML with the classic `%YAML:1.0` header, which every
/// OpenCV version reads.
pub(crate) fn to_yaml(items: &[(&str, Item)]) -> String {
    let mut out = String::from("%YAML:1.0\n---\n");
    for (key, item) in items {
        match item {
            Item::Int(i) => {
                let _ = writeln!(out, "{key}: {i}");
            }
            Item::Real(v) => {
                let _ = writeln!(out, "{key}: {}", real(*v));
            }
            Item::Str(s) => {
                let _ = writeln!(out, "{key}: {}", yaml_string(s));
            }
            Item::Matrix { rows, cols, data } => {
                let _ = writeln!(out, "{key}: !!opencv-matrix");
                let _ = writeln!(out, "   rows: {rows}");
                let _ = writeln!(out, "   cols: {cols}");
                let _ = writeln!(out, "   dt: d");
                out.push_str("   data: [");
                for (i, v) in data.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                        if i % VALUES_PER_LINE == 0 {
                            out.push_str("\n      ");
                        }
                    }
                    out.push(' ');
                    out.push_str(&real(*v));
                }
                out.push_str(" ]\n");
            }
        }
    }
    out
}

/// Writes items as OpenCV FileStorage XML.
pub(crate) fn to_xml(items: &[(&str, Item)]) -> String {
    let mut out = String::from("<?xml version=\"1.0\"?>\n<opencv_storage>\n");
    for (key, item) in items {
        match item {
            Item::Int(i) => {
                let _ = writeln!(out, "<{key}>{i}</{key}>");
            }
            Item::Real(v) => {
                let _ = writeln!(out, "<{key}>{}</{key}>", real(*v));
            }
            Item::Str(s) => {
                let _ = writeln!(out, "<{key}>\"{}\"</{key}>", xml_escape(s));
            }
            Item::Matrix { rows, cols, data } => {
                let _ = writeln!(out, "<{key} type_id=\"opencv-matrix\">");
                let _ = writeln!(out, "  <rows>{rows}</rows>");
                let _ = writeln!(out, "  <cols>{cols}</cols>");
                let _ = writeln!(out, "  <dt>d</dt>");
                out.push_str("  <data>");
                for (i, v) in data.iter().enumerate() {
                    if i % VALUES_PER_LINE == 0 {
                        out.push_str("\n    ");
                    } else {
                        out.push(' ');
                    }
                    out.push_str(&real(*v));
                }
                let _ = writeln!(out, "</data></{key}>");
            }
        }
    }
    out.push_str("</opencv_storage>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::super::{parse_xml, parse_yaml};
    use super::*;

    fn items() -> Vec<(&'static str, Item)> {
        vec![
            ("w", Item::Int(1280)),
            ("e", Item::Real(0.1873)),
            ("tiny", Item::Real(1e-300)),
            ("whole", Item::Real(2210.0)),
            (
                "s",
                Item::Str("quote \" back \\ <tag> & 'x'\nline 2".into()),
            ),
            (
                "m",
                Item::Matrix {
                    rows: 2,
                    cols: 3,
                    data: vec![1.0, -2.5, 1.0 / 3.0, 1e20, -0.0, 0.1 + 0.2],
                },
            ),
        ]
    }

    #[test]
    fn written_files_read_back_exactly() {
        let items = items();
        for (text, doc) in [
            (
                to_yaml(&items),
                parse_yaml(&to_yaml(&items), "w.yml").unwrap(),
            ),
            (to_xml(&items), parse_xml(&to_xml(&items), "w.xml").unwrap()),
        ] {
            assert_eq!(doc.unsigned("w").unwrap(), Some(1280), "{text}");
            assert_eq!(doc.number("e").unwrap(), Some(0.1873));
            assert_eq!(doc.number("tiny").unwrap(), Some(1e-300));
            assert_eq!(doc.number("whole").unwrap(), Some(2210.0));
            assert_eq!(
                doc.string("s").unwrap().unwrap(),
                "quote \" back \\ <tag> & 'x'\nline 2"
            );
            let m = doc.matrix("m").unwrap().unwrap();
            assert_eq!((m.rows, m.cols), (2, 3));
            assert_eq!(m.data, vec![1.0, -2.5, 1.0 / 3.0, 1e20, -0.0, 0.1 + 0.2]);
        }
    }

    #[test]
    fn reals_always_look_real() {
        assert_eq!(real(2210.0), "2210.0");
        assert_eq!(real(1e20), "1e20");
        assert_eq!(real(-0.5), "-0.5");
        assert_eq!(real(f64::NEG_INFINITY), "-.inf");
    }
}
