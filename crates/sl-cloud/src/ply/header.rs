//! Parsing and formatting of the PLY header.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::{PlyElement, PlyEncoding, PlyHeader, PlyProperty, PlyPropertyKind, PlyScalarType};
use crate::CloudError;

/// Longest header we accept. Real headers are a few hundred bytes to a few KiB (Cyberware scans
/// with many `obj_info` lines are under 1 KiB); 16 MiB leaves room for absurd comment blocks
/// while stopping a reader that was handed a non-PLY file without newlines from scanning it all.
pub(crate) const MAX_HEADER_BYTES: usize = 16 << 20;

fn header_err(file: &str, line: usize, message: impl Into<String>) -> CloudError {
    CloudError::PlyHeader {
        file: file.to_owned(),
        line,
        message: message.into(),
    }
}

/// Parses the header at the start of `bytes` (which may hold more: the body).
pub(crate) fn parse_header(bytes: &[u8], file: &str) -> Result<PlyHeader, CloudError> {
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut encoding = None;
    let mut version = String::new();
    let mut comments = Vec::new();
    let mut obj_info = Vec::new();
    let mut elements: Vec<PlyElement> = Vec::new();
    loop {
        let rest = bytes.get(pos..).unwrap_or(&[]);
        let Some(nl) = rest.iter().take(MAX_HEADER_BYTES).position(|&b| b == b'\n') else {
            return Err(header_err(
                file,
                line_no + 1,
                if pos + rest.len() >= MAX_HEADER_BYTES {
                    "header longer than 16 MiB without 'end_header'"
                } else {
                    "file ends before 'end_header'"
                },
            ));
        };
        let raw = rest.get(..nl).unwrap_or(&[]);
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        pos += nl + 1;
        line_no += 1;
        if pos > MAX_HEADER_BYTES {
            return Err(header_err(file, line_no, "header longer than 16 MiB"));
        }
        let text = String::from_utf8_lossy(raw);
        let text = text.trim();
        if line_no == 1 {
            if text != "ply" {
                return Err(header_err(
                    file,
                    1,
                    "not a PLY file: the first line is not 'ply'",
                ));
            }
            continue;
        }
        let mut words = text.split_ascii_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "format" => {
                if encoding.is_some() {
                    return Err(header_err(file, line_no, "second 'format' line"));
                }
                encoding = Some(match words.next() {
                    Some("ascii") => PlyEncoding::Ascii,
                    Some("binary_little_endian") => PlyEncoding::BinaryLittleEndian,
                    Some("binary_big_endian") => PlyEncoding::BinaryBigEndian,
                    other => {
                        return Err(header_err(
                            file,
                            line_no,
                            format!("unknown format '{}'", other.unwrap_or("")),
                        ));
                    }
                });
                version = words.next().unwrap_or("").to_owned();
            }
            "comment" | "obj_info" => {
                let body = text.get(keyword.len()..).unwrap_or("").trim().to_owned();
                if keyword == "comment" {
                    comments.push(body)
                } else {
                    obj_info.push(body)
                }
            }
            "element" => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(header_err(
                        file,
                        line_no,
                        "expected 'element <name> <count>'",
                    ));
                };
                let count: u64 = count.parse().map_err(|_| {
                    header_err(
                        file,
                        line_no,
                        format!("element '{name}': bad count '{count}'"),
                    )
                })?;
                elements.push(PlyElement {
                    name: name.to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(header_err(file, line_no, "'property' before any 'element'"));
                };
                let ty = |w: Option<&str>| {
                    let w = w.unwrap_or("");
                    PlyScalarType::from_name(w).ok_or_else(|| {
                        header_err(file, line_no, format!("unknown property type '{w}'"))
                    })
                };
                let first = words.next();
                let kind = if first == Some("list") {
                    let count = ty(words.next())?;
                    if count.is_float() {
                        return Err(header_err(
                            file,
                            line_no,
                            "list count type must be an integer type",
                        ));
                    }
                    PlyPropertyKind::List {
                        count,
                        item: ty(words.next())?,
                    }
                } else {
                    PlyPropertyKind::Scalar(ty(first)?)
                };
                let (Some(name), None) = (words.next(), words.next()) else {
                    return Err(header_err(
                        file,
                        line_no,
                        "expected 'property <type> <name>'",
                    ));
                };
                if element.property(name).is_some() {
                    return Err(header_err(
                        file,
                        line_no,
                        format!("property '{name}' repeated in element '{}'", element.name),
                    ));
                }
                element.properties.push(PlyProperty {
                    name: name.to_owned(),
                    kind,
                });
            }
            "end_header" => break,
            other => {
                return Err(header_err(
                    file,
                    line_no,
                    format!("unknown header keyword '{other}'"),
                ));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(header_err(
            file,
            line_no,
            "no 'format' line before 'end_header'",
        ));
    };
    Ok(PlyHeader {
        encoding,
        version,
        comments,
        obj_info,
        elements,
        body_offset: pos as u64,
    })
}

/// Reads and parses only the header of the PLY file at `path` (the body is not touched, so this
/// is fast even for huge files).
///
/// ```no_run
/// let h = sl_cloud::read_ply_header(std::path::Path::new("scan.ply"))?;
/// println!("{:?}, {} vertices", h.encoding, h.vertex_count());
/// for e in &h.elements {
///     println!("element {} {} ({} properties)", e.name, e.count, e.properties.len());
/// }
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn read_ply_header(path: &Path) -> Result<PlyHeader, CloudError> {
    let file = std::fs::File::open(path).map_err(|e| CloudError::io(path, "open", e))?;
    let mut reader = BufReader::new(file).take(MAX_HEADER_BYTES as u64);
    let mut buf = Vec::new();
    loop {
        let start = buf.len();
        let n = reader
            .read_until(b'\n', &mut buf)
            .map_err(|e| CloudError::io(path, "read", e))?;
        let line = buf.get(start..).unwrap_or(&[]);
        if n == 0 || line.trim_ascii() == b"end_header" {
            break;
        }
        // Bail out early on files that are not PLY at all instead of reading 16 MiB.
        if start == 0 && line.trim_ascii() != b"ply" {
            break;
        }
    }
    parse_header(&buf, &path.display().to_string())
}

/// The header text for `elements` in `encoding`, with our comment line.
pub(crate) fn format_header(encoding: PlyEncoding, elements: &[PlyElement]) -> String {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(256);
    s.push_str("ply\n");
    let _ = writeln!(s, "format {} 1.0", encoding.keyword());
    let _ = writeln!(
        s,
        "comment written by sl-cloud {}",
        env!("CARGO_PKG_VERSION")
    );
    for e in elements {
        let _ = writeln!(s, "element {} {}", e.name, e.count);
        for p in &e.properties {
            match p.kind {
                PlyPropertyKind::Scalar(t) => {
                    let _ = writeln!(s, "property {} {}", t.name(), p.name);
                }
                PlyPropertyKind::List { count, item } => {
                    let _ = writeln!(
                        s,
                        "property list {} {} {}",
                        count.name(),
                        item.name(),
                        p.name
                    );
                }
            }
        }
    }
    s.push_str("end_header\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_bunny_like_header() {
        let text = b"ply\r\nformat ascii 1.0\r\ncomment hello world\r\nobj_info num_cols 512\r\n\
element vertex 3\r\nproperty float x\r\nproperty float32 y\r\nproperty float z\r\n\
element range_grid 10\r\nproperty list uchar int vertex_indices\r\nend_header\r\n1 2 3\r\n";
        let h = parse_header(text, "t.ply").unwrap();
        assert_eq!(h.encoding, PlyEncoding::Ascii);
        assert_eq!(h.version, "1.0");
        assert_eq!(h.comments, vec!["hello world"]);
        assert_eq!(h.obj_info, vec!["num_cols 512"]);
        assert_eq!(h.vertex_count(), 3);
        assert_eq!(h.elements[1].name, "range_grid");
        assert_eq!(
            h.elements[1].properties[0].kind,
            PlyPropertyKind::List {
                count: PlyScalarType::UChar,
                item: PlyScalarType::Int
            }
        );
        assert_eq!(h.elements[0].fixed_size(), Some(12));
        assert_eq!(h.elements[1].fixed_size(), None);
        // The body starts right after "end_header\r\n".
        assert_eq!(&text[h.body_offset as usize..], b"1 2 3\r\n");
    }

    #[test]
    fn header_errors_name_the_line() {
        let cases: &[(&[u8], usize)] = &[
            (b"plx\n", 1),
            (b"ply\nformat ascii 1.0\n", 3),
            (b"ply\nformat foo 1.0\nend_header\n", 2),
            (b"ply\nformat ascii 1.0\nproperty float x\nend_header\n", 3),
            (b"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", 3),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot x\nend_header\n", 4),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\nend_header\n", 4),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\nend_header\n", 5),
            (b"ply\nformat ascii 1.0\nbogus\nend_header\n", 3),
            (b"ply\nelement vertex 1\nend_header\n", 3),
        ];
        for (text, want_line) in cases {
            match parse_header(text, "bad.ply") {
                Err(CloudError::PlyHeader {
                    file,
                    line,
                    message,
                }) => {
                    assert_eq!(file, "bad.ply");
                    assert_eq!(
                        line,
                        *want_line,
                        "{message} for {:?}",
                        String::from_utf8_lossy(text)
                    );
                }
                other => panic!("expected a header error, got {other:?}"),
            }
        }
    }

    #[test]
    fn format_then_parse_is_identity() {
        let elements = vec![
            PlyElement {
                name: "vertex".into(),
                count: 7,
                properties: vec![
                    PlyProperty {
                        name: "x".into(),
                        kind: PlyPropertyKind::Scalar(PlyScalarType::Double),
                    },
                    PlyProperty {
                        name: "red".into(),
                        kind: PlyPropertyKind::Scalar(PlyScalarType::UChar),
                    },
                ],
            },
            PlyElement {
                name: "face".into(),
                count: 0,
                properties: vec![PlyProperty {
                    name: "vertex_indices".into(),
                    kind: PlyPropertyKind::List {
                        count: PlyScalarType::UChar,
                        item: PlyScalarType::UInt,
                    },
                }],
            },
        ];
        let text = format_header(PlyEncoding::BinaryBigEndian, &elements);
        let h = parse_header(text.as_bytes(), "x").unwrap();
        assert_eq!(h.elements, elements);
        assert_eq!(h.encoding, PlyEncoding::BinaryBigEndian);
        assert_eq!(h.body_offset as usize, text.len());
    }
}
