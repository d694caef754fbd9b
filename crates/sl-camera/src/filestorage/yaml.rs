//! OpenCV FileStorage YAML reader.

use super::{Document, MAX_NESTING, Node, Value};
use crate::CameraError;

/// One non-blank line with its comment removed.
struct Line<'a> {
    number: usize,
    indent: usize,
    text: &'a str,
}

struct Parser<'a> {
    file: &'a str,
    lines: Vec<Line<'a>>,
    pos: usize,
    depth: usize,
}

/// Parses an OpenCV FileStorage YAML text. `file` names it in error messages.
pub(crate) fn parse_yaml(text: &str, file: &str) -> Result<Document, CameraError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = Vec::new();
    let mut header_seen = false;
    for (i, raw) in text.lines().enumerate() {
        let number = i + 1;
        let content = strip_comment(raw).trim_end();
        if content.trim().is_empty() {
            continue;
        }
        if !header_seen {
            let ok = content.starts_with("%YAML:1.") || content.starts_with("%YAML 1.");
            if !ok {
                return Err(CameraError::Syntax {
                    file: file.to_owned(),
                    line: number,
                    message: "not an OpenCV FileStorage YAML file: expected a `%YAML:1.0` \
                              (or `%YAML 1.x`) header"
                        .into(),
                });
            }
            header_seen = true;
            continue;
        }
        if content == "---" || content == "..." {
            continue;
        }
        if content.starts_with('%') || content.starts_with("--- ") {
            return Err(CameraError::Syntax {
                file: file.to_owned(),
                line: number,
                message: "unsupported YAML directive or document marker".into(),
            });
        }
        let indent = content.len() - content.trim_start().len();
        if content[..indent].contains('\t') {
            return Err(CameraError::Syntax {
                file: file.to_owned(),
                line: number,
                message: "tab in indentation".into(),
            });
        }
        lines.push(Line {
            number,
            indent,
            text: content.trim_start(),
        });
    }
    if !header_seen {
        return Err(CameraError::Syntax {
            file: file.to_owned(),
            line: 1,
            message: "empty file: expected a `%YAML:1.0` header".into(),
        });
    }
    let mut parser = Parser {
        file,
        lines,
        pos: 0,
        depth: 0,
    };
    let entries = if parser.lines.is_empty() {
        Vec::new()
    } else {
        let indent = parser.lines[0].indent;
        if parser.lines[0].text.starts_with('-') {
            return Err(parser.error(
                parser.lines[0].number,
                "the top level must be a map of keys",
            ));
        }
        let entries = parser.map(indent)?;
        if let Some(line) = parser.lines.get(parser.pos) {
            return Err(parser.error(line.number, "unexpected indentation"));
        }
        entries
    };
    Ok(Document {
        file: file.to_owned(),
        entries,
    })
}

/// Removes a `#` comment (outside quotes, at the start or after whitespace).
fn strip_comment(line: &str) -> &str {
    let mut quote: Option<char> = None;
    let mut prev_space = true;
    let mut escaped = false;
    for (i, c) in line.char_indices() {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if c == '\\' && q == '"' {
                    escaped = true;
                } else if c == q {
                    quote = None;
                }
            }
            None => {
                if c == '#' && prev_space {
                    return &line[..i];
                }
                if c == '"' || c == '\'' {
                    quote = Some(c);
                }
            }
        }
        prev_space = c.is_whitespace();
    }
    line
}

impl<'a> Parser<'a> {
    fn error(&self, line: usize, message: impl Into<String>) -> CameraError {
        CameraError::Syntax {
            file: self.file.to_owned(),
            line,
            message: message.into(),
        }
    }

    /// A block map whose keys sit at `indent`.
    fn map(&mut self, indent: usize) -> Result<Vec<(String, Node)>, CameraError> {
        let mut entries = Vec::new();
        while let Some(line) = self.lines.get(self.pos) {
            if line.indent < indent {
                break;
            }
            if line.indent > indent {
                return Err(self.error(line.number, "unexpected indentation"));
            }
            if line.text.starts_with("- ") || line.text == "-" {
                return Err(self.error(line.number, "sequence item where a key was expected"));
            }
            let (number, text) = (line.number, line.text);
            let (key, rest) = split_key(text).ok_or_else(|| {
                self.error(number, format!("expected `key: value`, found `{text}`"))
            })?;
            self.pos += 1;
            let value = self.value_after_key(rest, number, indent)?;
            entries.push((key.to_owned(), value));
        }
        Ok(entries)
    }

    /// A block sequence whose dashes sit at `indent`.
    fn seq(&mut self, indent: usize) -> Result<Vec<Node>, CameraError> {
        let mut items = Vec::new();
        while let Some(line) = self.lines.get(self.pos) {
            if line.indent < indent {
                break;
            }
            if line.indent > indent {
                return Err(self.error(line.number, "unexpected indentation"));
            }
            let (number, text) = (line.number, line.text);
            let rest = if text == "-" {
                ""
            } else if let Some(r) = text.strip_prefix("- ") {
                r.trim()
            } else {
                return Err(self.error(number, "expected a sequence item `- ...`"));
            };
            self.pos += 1;
            if !rest.is_empty()
                && !rest.starts_with(['"', '\'', '[', '{', '!'])
                && split_key(rest).is_some()
            {
                return Err(self.error(
                    number,
                    "compact maps in sequence items (`- key: value`) are not supported",
                ));
            }
            items.push(self.value_after_key(rest, number, indent)?);
        }
        Ok(items)
    }

    /// The value that follows `key:` (or `-`) on line `number`, possibly continued by a more
    /// indented block or by the continuation lines of a flow collection.
    fn value_after_key(
        &mut self,
        rest: &str,
        number: usize,
        indent: usize,
    ) -> Result<Node, CameraError> {
        if self.depth >= MAX_NESTING {
            return Err(self.error(number, format!("nested deeper than {MAX_NESTING} levels")));
        }
        self.depth += 1;
        let node = self.value_after_key_at_depth(rest, number, indent);
        self.depth -= 1;
        node
    }

    fn value_after_key_at_depth(
        &mut self,
        rest: &str,
        number: usize,
        indent: usize,
    ) -> Result<Node, CameraError> {
        let rest = rest.trim();
        if let Some(tagged) = rest.strip_prefix("!!") {
            let (tag, after) = tagged
                .split_once(char::is_whitespace)
                .unwrap_or((tagged, ""));
            if !after.trim().is_empty() {
                if after.trim().starts_with('{') {
                    let node = self.flow(after.trim(), number)?;
                    return match node.value {
                        Value::Map { entries, .. } => Ok(Node {
                            line: number,
                            value: Value::Map {
                                tag: Some(tag.to_owned()),
                                entries,
                            },
                        }),
                        _ => Err(self.error(number, "expected a map after the tag")),
                    };
                }
                return Err(self.error(number, format!("unexpected text after tag `!!{tag}`")));
            }
            let entries = match self.lines.get(self.pos) {
                Some(next) if next.indent > indent => {
                    let child = next.indent;
                    self.map(child)?
                }
                _ => Vec::new(),
            };
            return Ok(Node {
                line: number,
                value: Value::Map {
                    tag: Some(tag.to_owned()),
                    entries,
                },
            });
        }
        if rest.is_empty() {
            return match self.lines.get(self.pos) {
                Some(next) if next.indent > indent => {
                    let child = next.indent;
                    if next.text.starts_with("- ") || next.text == "-" {
                        Ok(Node {
                            line: number,
                            value: Value::Seq(self.seq(child)?),
                        })
                    } else {
                        Ok(Node {
                            line: number,
                            value: Value::Map {
                                tag: None,
                                entries: self.map(child)?,
                            },
                        })
                    }
                }
                // `key:` then a sequence at the same indentation (valid YAML).
                Some(next)
                    if next.indent == indent
                        && (next.text.starts_with("- ") || next.text == "-") =>
                {
                    Ok(Node {
                        line: number,
                        value: Value::Seq(self.seq(indent)?),
                    })
                }
                _ => Ok(Node {
                    line: number,
                    value: Value::Scalar(String::new()),
                }),
            };
        }
        if rest.starts_with(['[', '{']) {
            // Gather continuation lines until the brackets close.
            let mut text = rest.to_owned();
            while !brackets_closed(&text) {
                let Some(next) = self.lines.get(self.pos) else {
                    return Err(self.error(number, "unterminated `[` or `{`"));
                };
                text.push(' ');
                text.push_str(next.text);
                self.pos += 1;
            }
            return self.flow(&text, number);
        }
        if rest.starts_with(['"', '\'']) {
            let (s, used) =
                quoted(rest).ok_or_else(|| self.error(number, "unterminated string"))?;
            if !rest[used..].trim().is_empty() {
                return Err(self.error(number, "unexpected text after the string"));
            }
            return Ok(Node {
                line: number,
                value: Value::Str(s),
            });
        }
        Ok(Node {
            line: number,
            value: Value::Scalar(rest.to_owned()),
        })
    }

    /// A complete flow collection (`[...]` or `{...}`) in `text`, starting on line `number`.
    fn flow(&self, text: &str, number: usize) -> Result<Node, CameraError> {
        let chars: Vec<char> = text.chars().collect();
        let mut pos = 0;
        let node = self.flow_value(&chars, &mut pos, number, self.depth)?;
        skip_ws(&chars, &mut pos);
        if pos != chars.len() {
            return Err(self.error(number, "unexpected text after `]` or `}`"));
        }
        Ok(node)
    }

    fn flow_value(
        &self,
        c: &[char],
        pos: &mut usize,
        number: usize,
        depth: usize,
    ) -> Result<Node, CameraError> {
        if depth >= MAX_NESTING {
            return Err(self.error(number, format!("nested deeper than {MAX_NESTING} levels")));
        }
        skip_ws(c, pos);
        let node = |value| Node {
            line: number,
            value,
        };
        match c.get(*pos) {
            Some('[') => {
                *pos += 1;
                let mut items = Vec::new();
                loop {
                    skip_ws(c, pos);
                    if c.get(*pos) == Some(&']') {
                        *pos += 1;
                        break;
                    }
                    items.push(self.flow_value(c, pos, number, depth + 1)?);
                    skip_ws(c, pos);
                    match c.get(*pos) {
                        Some(',') => *pos += 1,
                        Some(']') => {}
                        _ => return Err(self.error(number, "expected `,` or `]` in a sequence")),
                    }
                }
                Ok(node(Value::Seq(items)))
            }
            Some('{') => {
                *pos += 1;
                let mut entries = Vec::new();
                loop {
                    skip_ws(c, pos);
                    if c.get(*pos) == Some(&'}') {
                        *pos += 1;
                        break;
                    }
                    let start = *pos;
                    while *pos < c.len() && c[*pos] != ':' && c[*pos] != '}' && c[*pos] != ',' {
                        *pos += 1;
                    }
                    if c.get(*pos) != Some(&':') {
                        return Err(self.error(number, "expected `key: value` in a map"));
                    }
                    let key: String = c[start..*pos].iter().collect::<String>().trim().to_owned();
                    *pos += 1;
                    let value = self.flow_value(c, pos, number, depth + 1)?;
                    entries.push((key, value));
                    skip_ws(c, pos);
                    match c.get(*pos) {
                        Some(',') => *pos += 1,
                        Some('}') => {}
                        _ => return Err(self.error(number, "expected `,` or `}` in a map")),
                    }
                }
                Ok(node(Value::Map { tag: None, entries }))
            }
            Some('"') | Some('\'') => {
                let rest: String = c[*pos..].iter().collect();
                let (s, used) =
                    quoted(&rest).ok_or_else(|| self.error(number, "unterminated string"))?;
                *pos += rest[..used].chars().count();
                Ok(node(Value::Str(s)))
            }
            Some(_) => {
                let start = *pos;
                while *pos < c.len() && !matches!(c[*pos], ',' | ']' | '}') {
                    *pos += 1;
                }
                let s: String = c[start..*pos].iter().collect();
                let s = s.trim();
                if s.is_empty() {
                    return Err(self.error(number, "empty item in a flow collection"));
                }
                Ok(node(Value::Scalar(s.to_owned())))
            }
            None => Err(self.error(number, "unexpected end of a flow collection")),
        }
    }
}

fn skip_ws(c: &[char], pos: &mut usize) {
    while *pos < c.len() && c[*pos].is_whitespace() {
        *pos += 1;
    }
}

/// `key` and the rest of a `key: rest` line (the colon must be followed by a space or end
/// the line). Keys are not quoted in OpenCV files.
fn split_key(text: &str) -> Option<(&str, &str)> {
    let bytes = text.as_bytes();
    for (i, &b) in bytes.iter().enumerate() {
        if b == b'"' || b == b'\'' || b == b'[' || b == b'{' {
            return None;
        }
        if b == b':' && (i + 1 == bytes.len() || bytes[i + 1] == b' ') {
            let key = text[..i].trim();
            if key.is_empty() {
                return None;
            }
            return Some((key, &text[i + 1..]));
        }
    }
    None
}

/// Whether every `[`/`{` opened outside quotes in `text` is closed.
fn brackets_closed(text: &str) -> bool {
    let mut depth = 0i64;
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for c in text.chars() {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if c == '\\' && q == '"' {
                    escaped = true;
                } else if c == q {
                    quote = None;
                }
            }
            None => match c {
                '"' | '\'' => quote = Some(c),
                '[' | '{' => depth += 1,
                ']' | '}' => depth -= 1,
                _ => {}
            },
        }
    }
    depth <= 0
}

/// A quoted string at the start of `s`: its unescaped content and the number of bytes used.
pub(super) fn quoted(s: &str) -> Option<(String, usize)> {
    let mut chars = s.char_indices();
    let (_, q) = chars.next()?;
    let mut out = String::new();
    while let Some((i, c)) = chars.next() {
        if c == q {
            if q == '\'' && s[i + 1..].starts_with('\'') {
                // '' inside single quotes is one quote
                chars.next();
                out.push('\'');
                continue;
            }
            return Some((out, i + c.len_utf8()));
        }
        if c == '\\' && q == '"' {
            let (_, e) = chars.next()?;
            out.push(match e {
                'n' => '\n',
                't' => '\t',
                'r' => '\r',
                '0' => '\0',
                other => other, // \" \\ and anything else: the character itself
            });
        } else {
            out.push(c);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "%YAML:1.0
---
# a comment
calibration_time: \"Sat Nov 22 03:08:00 2025\"
image_width: 1280   # trailing comment
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1440.4000000000001, 0., 667.79999999999995, 0.,
       1437.0999999999999, 354.19999999999999, 0., 0., 1. ]
str2: \"a \\\"q\\\" b: c # d\"
nested:
   x: 1
   inner: { a: 1, b: [ 2, 3 ] }
seq:
   - 1
   - 2.5
   -
      y: 2
empty:
";

    #[test]
    fn parses_the_opencv_subset() {
        let doc = parse_yaml(SAMPLE, "s.yml").unwrap();
        assert_eq!(
            doc.string("calibration_time").unwrap().unwrap(),
            "Sat Nov 22 03:08:00 2025"
        );
        assert_eq!(doc.unsigned("image_width").unwrap(), Some(1280));
        let m = doc.matrix("camera_matrix").unwrap().unwrap();
        assert_eq!((m.rows, m.cols, m.line), (3, 3, 6));
        assert_eq!(m.data[0], 1440.4);
        assert_eq!(m.data[5], 354.2);
        assert_eq!(doc.string("str2").unwrap().unwrap(), "a \"q\" b: c # d");
        let Value::Seq(items) = &doc.get("seq").unwrap().value else {
            panic!("not a seq")
        };
        assert_eq!(items.len(), 3);
        assert!(matches!(
            doc.get("nested").unwrap().value,
            Value::Map { .. }
        ));
        assert_eq!(
            doc.get("empty").unwrap().value,
            Value::Scalar(String::new())
        );
    }

    #[test]
    fn errors_name_line_and_key() {
        let bad = SAMPLE.replace(" 0., 0., 1. ]", " 0., 0. ]");
        let doc = parse_yaml(&bad, "calib.yml").unwrap();
        let e = doc.matrix("camera_matrix").unwrap_err().to_string();
        assert_eq!(
            e,
            "calib.yml line 6: key `camera_matrix`: expected 9 values (3x3), found 8"
        );
        let e = parse_yaml("camera: 1\n", "x.yml").unwrap_err().to_string();
        assert!(
            e.starts_with("x.yml line 1: not an OpenCV FileStorage YAML"),
            "{e}"
        );
        let e = parse_yaml("%YAML:1.0\na: [1, 2\n", "x.yml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("unterminated"), "{e}");
        let e = parse_yaml("%YAML:1.0\na: 1\n    b: 2\n", "x.yml")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "x.yml line 3: unexpected indentation");
        let e = parse_yaml("%YAML:1.0\na 1\n", "x.yml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.yml line 2: expected `key: value`"), "{e}");
        let doc = parse_yaml("%YAML:1.0\nw: abc\n", "x.yml").unwrap();
        let e = doc.number("w").unwrap_err().to_string();
        assert_eq!(e, "x.yml line 2: key `w`: expected a number, found `abc`");
    }

    #[test]
    fn comments_and_quotes() {
        assert_eq!(strip_comment("a: 1 # c"), "a: 1 ");
        assert_eq!(strip_comment("a: \"x # y\""), "a: \"x # y\"");
        assert_eq!(strip_comment("a: x#y"), "a: x#y");
        assert_eq!(quoted("'it''s' tail"), Some(("it's".to_owned(), 7)));
    }
}
