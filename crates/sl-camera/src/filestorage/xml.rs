//! OpenCV FileStorage XML reader.

use super::{Document, MAX_NESTING, Node, Value};
use crate::CameraError;

struct Lexer<'a> {
    file: &'a str,
    text: &'a str,
    pos: usize,
    line: usize,
}

/// An element as read: name, `type_id` attribute, line, and either text or children.
struct Element {
    name: String,
    type_id: Option<String>,
    line: usize,
    text: String,
    text_line: usize,
    children: Vec<Element>,
}

/// Parses an OpenCV FileStorage XML text (`<opencv_storage>` root). `file` names it in
/// error messages.
pub(crate) fn parse_xml(text: &str, file: &str) -> Result<Document, CameraError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lx = Lexer {
        file,
        text,
        pos: 0,
        line: 1,
    };
    lx.skip_misc()?;
    if !lx.rest().starts_with('<') {
        return Err(lx.error("not an OpenCV FileStorage XML file: expected `<opencv_storage>`"));
    }
    let root = lx.element(0)?;
    if root.name != "opencv_storage" {
        return Err(CameraError::Syntax {
            file: file.to_owned(),
            line: root.line,
            message: format!(
                "not an OpenCV FileStorage XML file: root element is `<{}>`, expected `<opencv_storage>`",
                root.name
            ),
        });
    }
    lx.skip_misc()?;
    if !lx.rest().is_empty() {
        return Err(lx.error("unexpected content after `</opencv_storage>`"));
    }
    if !root.text.trim().is_empty() {
        return Err(CameraError::Syntax {
            file: file.to_owned(),
            line: root.text_line,
            message: "text directly inside `<opencv_storage>`".into(),
        });
    }
    let mut entries = Vec::new();
    for child in root.children {
        let key = child.name.clone();
        entries.push((key, to_node(child, file)?));
    }
    Ok(Document {
        file: file.to_owned(),
        entries,
    })
}

fn to_node(e: Element, file: &str) -> Result<Node, CameraError> {
    if !e.children.is_empty() {
        if !e.text.trim().is_empty() {
            return Err(CameraError::Syntax {
                file: file.to_owned(),
                line: e.text_line,
                message: format!("element `<{}>` mixes text and elements", e.name),
            });
        }
        let line = e.line;
        let all_items = e.children.iter().all(|c| c.name == "_");
        if all_items && e.type_id.is_none() {
            let items = e
                .children
                .into_iter()
                .map(|c| to_node(c, file))
                .collect::<Result<Vec<_>, _>>()?;
            return Ok(Node {
                line,
                value: Value::Seq(items),
            });
        }
        let tag = e.type_id;
        let mut entries = Vec::new();
        for c in e.children {
            let key = c.name.clone();
            entries.push((key, to_node(c, file)?));
        }
        return Ok(Node {
            line,
            value: Value::Map { tag, entries },
        });
    }
    if e.type_id.is_some() {
        return Ok(Node {
            line: e.line,
            value: Value::Map {
                tag: e.type_id,
                entries: Vec::new(),
            },
        });
    }
    let tokens = tokens(&e.text).ok_or_else(|| CameraError::Syntax {
        file: file.to_owned(),
        line: e.text_line,
        message: format!("unterminated string in `<{}>`", e.name),
    })?;
    let mut nodes: Vec<Node> = tokens
        .into_iter()
        .map(|t| Node {
            line: e.text_line,
            value: t,
        })
        .collect();
    let value = match nodes.len() {
        0 => Value::Scalar(String::new()),
        1 => nodes.remove(0).value,
        _ => Value::Seq(nodes),
    };
    Ok(Node {
        line: e.line,
        value,
    })
}

/// Whitespace-separated tokens of raw element text; `"..."` are strings (a quote inside a
/// string is written `&quot;`, so the first literal quote ends it). Entities are decoded
/// inside each token.
fn tokens(raw: &str) -> Option<Vec<Value>> {
    let mut out = Vec::new();
    let mut rest = raw.trim_start();
    while !rest.is_empty() {
        if let Some(inner) = rest.strip_prefix('"') {
            let end = inner.find('"')?;
            out.push(Value::Str(decode_entities(&inner[..end])));
            rest = inner[end + 1..].trim_start();
        } else {
            let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            out.push(Value::Scalar(decode_entities(&rest[..end])));
            rest = rest[end..].trim_start();
        }
    }
    Some(out)
}

impl<'a> Lexer<'a> {
    fn rest(&self) -> &'a str {
        &self.text[self.pos..]
    }

    fn error(&self, message: impl Into<String>) -> CameraError {
        CameraError::Syntax {
            file: self.file.to_owned(),
            line: self.line,
            message: message.into(),
        }
    }

    fn advance(&mut self, n: usize) {
        let end = (self.pos + n).min(self.text.len());
        self.line += self.text[self.pos..end].matches('\n').count();
        self.pos = end;
    }

    fn skip_ws(&mut self) {
        let n = self.rest().len() - self.rest().trim_start().len();
        self.advance(n);
    }

    /// Skips whitespace, comments, the `<?xml ...?>` declaration and `<!DOCTYPE ...>`.
    fn skip_misc(&mut self) -> Result<(), CameraError> {
        loop {
            self.skip_ws();
            let rest = self.rest();
            let close = if rest.starts_with("<!--") {
                "-->"
            } else if rest.starts_with("<?") {
                "?>"
            } else if rest.starts_with("<!") {
                ">"
            } else {
                return Ok(());
            };
            match rest.find(close) {
                Some(i) => self.advance(i + close.len()),
                None => return Err(self.error("unterminated comment or declaration")),
            }
        }
    }

    /// Reads an element starting at `<`.
    fn element(&mut self, depth: usize) -> Result<Element, CameraError> {
        if depth >= MAX_NESTING {
            return Err(self.error(format!("nested deeper than {MAX_NESTING} levels")));
        }
        let line = self.line;
        self.advance(1); // <
        let name = self.name()?;
        let mut type_id = None;
        // attributes
        loop {
            self.skip_ws();
            let rest = self.rest();
            if rest.starts_with("/>") {
                self.advance(2);
                return Ok(Element {
                    name,
                    type_id,
                    line,
                    text: String::new(),
                    text_line: line,
                    children: Vec::new(),
                });
            }
            if rest.starts_with('>') {
                self.advance(1);
                break;
            }
            let attr = self.name()?;
            self.skip_ws();
            if !self.rest().starts_with('=') {
                return Err(self.error(format!("expected `=` after attribute `{attr}`")));
            }
            self.advance(1);
            self.skip_ws();
            let q = self.rest().chars().next();
            let Some(q @ ('"' | '\'')) = q else {
                return Err(self.error(format!("attribute `{attr}` value must be quoted")));
            };
            self.advance(1);
            let end = self
                .rest()
                .find(q)
                .ok_or_else(|| self.error("unterminated attribute value"))?;
            let value = decode_entities(&self.rest()[..end]);
            self.advance(end + 1);
            if attr == "type_id" {
                type_id = Some(value);
            }
        }
        // content
        let mut text = String::new();
        let mut text_line = self.line;
        let mut children = Vec::new();
        loop {
            let rest = self.rest();
            if rest.is_empty() {
                return Err(CameraError::Syntax {
                    file: self.file.to_owned(),
                    line,
                    message: format!("element `<{name}>` is not closed"),
                });
            }
            if rest.starts_with("<!--") {
                let i = rest
                    .find("-->")
                    .ok_or_else(|| self.error("unterminated comment"))?;
                self.advance(i + 3);
            } else if rest.starts_with("</") {
                self.advance(2);
                let close = self.name()?;
                self.skip_ws();
                if !self.rest().starts_with('>') {
                    return Err(self.error("expected `>`"));
                }
                self.advance(1);
                if close != name {
                    return Err(self.error(format!(
                        "`</{close}>` closes `<{name}>` (opened on line {line})"
                    )));
                }
                return Ok(Element {
                    name,
                    type_id,
                    line,
                    text,
                    text_line,
                    children,
                });
            } else if rest.starts_with('<') {
                children.push(self.element(depth + 1)?);
            } else {
                let end = rest.find('<').unwrap_or(rest.len());
                let chunk = &rest[..end];
                if text.trim().is_empty() && !chunk.trim().is_empty() {
                    text_line = self.line
                        + chunk[..chunk.len() - chunk.trim_start().len()]
                            .matches('\n')
                            .count();
                }
                text.push_str(chunk); // raw: entities are decoded per token
                self.advance(end);
            }
        }
    }

    fn name(&mut self) -> Result<String, CameraError> {
        let rest = self.rest();
        let end = rest
            .find(|c: char| !(c.is_alphanumeric() || matches!(c, '_' | '-' | '.' | ':')))
            .unwrap_or(rest.len());
        if end == 0 {
            return Err(self.error("expected an element or attribute name"));
        }
        let name = rest[..end].to_owned();
        self.advance(end);
        Ok(name)
    }
}

/// Replaces the XML entities OpenCV writes (and numeric ones).
fn decode_entities(s: &str) -> String {
    if !s.contains('&') {
        return s.to_owned();
    }
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find('&') {
        out.push_str(&rest[..i]);
        rest = &rest[i..];
        let Some(end) = rest.find(';') else {
            out.push_str(rest);
            return out;
        };
        let entity = &rest[1..end];
        let decoded = match entity {
            "lt" => Some('<'),
            "gt" => Some('>'),
            "amp" => Some('&'),
            "quot" => Some('"'),
            "apos" => Some('\''),
            e if e.starts_with("#x") => u32::from_str_radix(&e[2..], 16)
                .ok()
                .and_then(char::from_u32),
            e if e.starts_with('#') => e[1..].parse().ok().and_then(char::from_u32),
            _ => None,
        };
        match decoded {
            Some(c) => {
                out.push(c);
                rest = &rest[end + 1..];
            }
            None => {
                out.push('&');
                rest = &rest[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = r#"<?xml version="1.0"?>
<opencv_storage>
<calibration_time>"Sat Nov 22 03:08:00 2025"</calibration_time>
<image_width>1280</image_width>
<camera_matrix type_id="opencv-matrix">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    1440.4000000000001 0. 667.79999999999995 0. 1437.0999999999999
    354.19999999999999 0. 0. 1.</data></camera_matrix>
<!-- a comment -->
<str2>"a &quot;q&quot; b: c # d"</str2>
<nested>
  <x>1</x></nested>
<seq>
  1 2.5</seq>
<items><_>1</_><_>"two"</_></items>
</opencv_storage>
"#;

    #[test]
    fn parses_the_opencv_subset() {
        let doc = parse_xml(SAMPLE, "s.xml").unwrap();
        assert_eq!(
            doc.string("calibration_time").unwrap().unwrap(),
            "Sat Nov 22 03:08:00 2025"
        );
        assert_eq!(doc.unsigned("image_width").unwrap(), Some(1280));
        let m = doc.matrix("camera_matrix").unwrap().unwrap();
        assert_eq!((m.rows, m.cols, m.line), (3, 3, 5));
        assert_eq!(m.data[2], 667.8);
        assert_eq!(doc.string("str2").unwrap().unwrap(), "a \"q\" b: c # d");
        let Value::Seq(items) = &doc.get("seq").unwrap().value else {
            panic!("not a seq")
        };
        assert_eq!(items.len(), 2);
        let Value::Seq(items) = &doc.get("items").unwrap().value else {
            panic!("not a seq")
        };
        assert_eq!(items[1].value, Value::Str("two".into()));
    }

    #[test]
    fn errors_name_line_and_key() {
        let bad = SAMPLE.replace(" 0. 0. 1.</data>", " 0. 0.</data>");
        let doc = parse_xml(&bad, "calib.xml").unwrap();
        let e = doc.matrix("camera_matrix").unwrap_err().to_string();
        assert_eq!(
            e,
            "calib.xml line 5: key `camera_matrix`: expected 9 values (3x3), found 8"
        );
        let bad = SAMPLE.replace("</nested>", "</nestedd>");
        let e = parse_xml(&bad, "calib.xml").unwrap_err().to_string();
        assert!(
            e.starts_with("calib.xml line 15: `</nestedd>` closes `<nested>`"),
            "{e}"
        );
        let e = parse_xml("<root></root>", "r.xml").unwrap_err().to_string();
        assert!(e.contains("root element is `<root>`"), "{e}");
        let e = parse_xml("<opencv_storage><a>1</a>", "r.xml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not closed"), "{e}");
    }

    #[test]
    fn entities() {
        assert_eq!(
            decode_entities("a &lt;b&gt; &amp; &#65;&#x42; &bogus;"),
            "a <b> & AB &bogus;"
        );
    }
}
