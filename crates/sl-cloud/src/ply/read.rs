//! PLY reader: header, then the `vertex` element decoded in bulk.

use std::io::Read;
use std::path::Path;

use nalgebra::{Point3, Vector3};

use super::header::parse_header;
use super::scalar::{decode_column, read_dyn};
use super::{PlyElement, PlyEncoding, PlyPropertyKind, PlyScalarType};
use crate::{CloudError, PointCloud};

/// Name used in errors for data that did not come from a file.
const MEMORY: &str = "<memory>";

/// Reads the points of a PLY file (ASCII, binary little- or big-endian).
///
/// The `vertex` element gives the points: `x y z` (any scalar type), optional normals
/// (`nx ny nz` or `normal_x normal_y normal_z`), colours (`red green blue`, `r g b` or
/// `diffuse_red diffuse_green diffuse_blue`) and quality (`quality`, `confidence` or the first
/// `scalar_*` property, as written by CloudCompare). Other properties, and other elements such
/// as `face` or the `range_grid` of the Stanford scans, are skipped, list properties included.
///
/// Colours stored as `uchar`/`char`/`short`/`int`/`uint` are taken as 0..255; as `ushort` as
/// 0..65535 and scaled; as `float`/`double` as 0..1 and scaled. Values are rounded and clamped.
///
/// The whole file is read into memory, then decoded; pre-allocation never exceeds what the file
/// size can hold, so a lying header cannot trigger a huge allocation. Any truncation or
/// corruption gives a [`CloudError`] naming the file and the line (ASCII) or byte offset
/// (binary).
///
/// ```no_run
/// let cloud = sl_cloud::read_ply(std::path::Path::new("bun000.ply"))?;
/// println!("{} points", cloud.len());
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn read_ply(path: &Path) -> Result<PointCloud, CloudError> {
    let bytes = std::fs::read(path).map_err(|e| CloudError::io(path, "read", e))?;
    parse_ply(&bytes, &path.display().to_string())
}

/// Reads a PLY file held in memory (errors name the file `<memory>`). See [`read_ply`].
///
/// ```
/// let text = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
/// property float z\nend_header\n1 2 3\n4 5 6\n";
/// let cloud = sl_cloud::read_ply_from_bytes(text)?;
/// assert_eq!(cloud.positions()[1].z, 6.0);
/// assert!(sl_cloud::read_ply_from_bytes(&text[..text.len() - 3]).is_err());
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn read_ply_from_bytes(bytes: &[u8]) -> Result<PointCloud, CloudError> {
    parse_ply(bytes, MEMORY)
}

/// Reads a PLY file from any reader, to its end (errors name the file `<memory>`). See
/// [`read_ply`].
pub fn read_ply_from_reader<R: Read>(mut reader: R) -> Result<PointCloud, CloudError> {
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|e| CloudError::io(MEMORY, "read", e))?;
    parse_ply(&bytes, MEMORY)
}

/// Where each cloud attribute lives among the properties of the vertex element.
struct AttrMap {
    pos: [usize; 3],
    normal: Option<[usize; 3]>,
    color: Option<([usize; 3], f64)>,
    quality: Option<usize>,
}

impl AttrMap {
    fn new(e: &PlyElement, file: &str) -> Result<Self, CloudError> {
        // Index of a scalar property called `name`.
        let find = |name: &str| {
            e.properties
                .iter()
                .position(|p| p.name == name && matches!(p.kind, PlyPropertyKind::Scalar(_)))
        };
        let find3 = |names: [&str; 3]| -> Option<[usize; 3]> {
            Some([find(names[0])?, find(names[1])?, find(names[2])?])
        };
        let mut pos = [0; 3];
        for (slot, name) in pos.iter_mut().zip(["x", "y", "z"]) {
            *slot = find(name).ok_or_else(|| CloudError::PlyMissing {
                file: file.to_owned(),
                what: format!("scalar property '{name}' in element 'vertex'"),
            })?;
        }
        let normal =
            find3(["nx", "ny", "nz"]).or_else(|| find3(["normal_x", "normal_y", "normal_z"]));
        let color = find3(["red", "green", "blue"])
            .or_else(|| find3(["r", "g", "b"]))
            .or_else(|| find3(["diffuse_red", "diffuse_green", "diffuse_blue"]))
            .map(|idx| {
                let scale = match e.properties.get(idx[0]).map(|p| p.kind) {
                    Some(PlyPropertyKind::Scalar(PlyScalarType::UShort)) => 255.0 / 65535.0,
                    Some(PlyPropertyKind::Scalar(PlyScalarType::Float | PlyScalarType::Double)) => {
                        255.0
                    }
                    _ => 1.0,
                };
                (idx, scale)
            });
        let quality = find("quality").or_else(|| find("confidence")).or_else(|| {
            e.properties.iter().position(|p| {
                p.name.starts_with("scalar_") && matches!(p.kind, PlyPropertyKind::Scalar(_))
            })
        });
        Ok(Self {
            pos,
            normal,
            color,
            quality,
        })
    }
}

#[inline]
fn to_u8(v: f64, scale: f64) -> u8 {
    // `as` saturates and maps NaN to 0: no panic on any input.
    (v * scale).round().clamp(0.0, 255.0) as u8
}

/// Accumulates vertices one at a time (ASCII and irregular binary layouts).
struct Sink {
    map: AttrMap,
    positions: Vec<Point3<f64>>,
    normals: Option<Vec<Vector3<f64>>>,
    colors: Option<Vec<[u8; 3]>>,
    quality: Option<Vec<f32>>,
}

impl Sink {
    fn new(map: AttrMap, capacity: usize) -> Self {
        Self {
            positions: Vec::with_capacity(capacity),
            normals: map.normal.map(|_| Vec::with_capacity(capacity)),
            colors: map.color.map(|_| Vec::with_capacity(capacity)),
            quality: map.quality.map(|_| Vec::with_capacity(capacity)),
            map,
        }
    }

    fn push(&mut self, values: &[f64]) {
        let v = |i: usize| values.get(i).copied().unwrap_or(f64::NAN);
        let [x, y, z] = self.map.pos;
        self.positions.push(Point3::new(v(x), v(y), v(z)));
        if let (Some(out), Some([a, b, c])) = (&mut self.normals, self.map.normal) {
            out.push(Vector3::new(v(a), v(b), v(c)));
        }
        if let (Some(out), Some(([r, g, b], s))) = (&mut self.colors, self.map.color) {
            out.push([to_u8(v(r), s), to_u8(v(g), s), to_u8(v(b), s)]);
        }
        if let (Some(out), Some(q)) = (&mut self.quality, self.map.quality) {
            out.push(v(q) as f32);
        }
    }

    fn finish(self) -> Result<PointCloud, CloudError> {
        PointCloud::from_parts(self.positions, self.normals, self.colors, self.quality)
    }
}

pub(crate) fn parse_ply(bytes: &[u8], file: &str) -> Result<PointCloud, CloudError> {
    let header = parse_header(bytes, file)?;
    let Some(vi) = header.elements.iter().position(|e| e.name == "vertex") else {
        return Err(CloudError::PlyMissing {
            file: file.to_owned(),
            what: "element 'vertex'".into(),
        });
    };
    let vertex = header
        .elements
        .get(vi)
        .ok_or_else(|| CloudError::PlyMissing {
            file: file.to_owned(),
            what: "element 'vertex'".into(),
        })?;
    let before = header.elements.get(..vi).unwrap_or(&[]);
    let map = AttrMap::new(vertex, file)?;
    let start = usize::try_from(header.body_offset)
        .unwrap_or(usize::MAX)
        .min(bytes.len());
    match header.encoding {
        PlyEncoding::Ascii => {
            let header_lines = bytes
                .get(..start)
                .unwrap_or(&[])
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            let mut tokens = Tokens {
                data: bytes,
                pos: start,
                line: header_lines + 1,
                tok_line: header_lines,
                file,
            };
            for e in before {
                tokens.skip_element(e)?;
            }
            read_ascii_vertices(&mut tokens, vertex, map)
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let big = header.encoding == PlyEncoding::BinaryBigEndian;
            let mut cur = Cursor {
                data: bytes,
                pos: start,
                big,
                file,
            };
            for e in before {
                cur.skip_element(e)?;
            }
            match vertex.fixed_size() {
                Some(stride) => read_binary_fixed(&cur, vertex, stride, map),
                None => read_binary_irregular(&mut cur, vertex, map),
            }
        }
    }
}

/// Position in a binary body; offsets in errors are absolute in the file.
pub(crate) struct Cursor<'a> {
    pub(crate) data: &'a [u8],
    pub(crate) pos: usize,
    pub(crate) big: bool,
    pub(crate) file: &'a str,
}

impl Cursor<'_> {
    fn err(&self, offset: usize, message: String) -> CloudError {
        CloudError::PlyBinary {
            file: self.file.to_owned(),
            offset: offset as u64,
            message,
        }
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    /// Reads one scalar, advancing; `what` names it in the error if the data ends.
    pub(crate) fn scalar(
        &mut self,
        ty: PlyScalarType,
        what: impl FnOnce() -> String,
    ) -> Result<f64, CloudError> {
        let size = ty.size();
        let rec = self.data.get(self.pos..self.pos + size).ok_or_else(|| {
            self.err(
                self.pos,
                format!(
                    "file ends inside {} ({} bytes needed, {} left)",
                    what(),
                    size,
                    self.remaining()
                ),
            )
        })?;
        let v = read_dyn(ty, self.big, rec, 0);
        self.pos += size;
        Ok(v)
    }

    /// Reads a list count, checks it is a non-negative integer and skips the items.
    fn skip_list(
        &mut self,
        count_ty: PlyScalarType,
        item: PlyScalarType,
        what: &dyn Fn() -> String,
    ) -> Result<(), CloudError> {
        let at = self.pos;
        let n = self.scalar(count_ty, || format!("the list count of {}", what()))?;
        if n < 0.0 {
            return Err(self.err(at, format!("negative list length {n} in {}", what())));
        }
        let len = (n as usize).saturating_mul(item.size());
        if len > self.remaining() {
            return Err(self.err(
                self.pos,
                format!(
                    "list of {n} items in {} runs past the end of the file",
                    what()
                ),
            ));
        }
        self.pos += len;
        Ok(())
    }

    /// Reads a list count and its items into `out` (cleared first).
    pub(crate) fn read_list(
        &mut self,
        count_ty: PlyScalarType,
        item: PlyScalarType,
        what: &dyn Fn() -> String,
        out: &mut Vec<f64>,
    ) -> Result<(), CloudError> {
        out.clear();
        let at = self.pos;
        let n = self.scalar(count_ty, || format!("the list count of {}", what()))?;
        if !(n >= 0.0 && n.fract() == 0.0) {
            return Err(self.err(at, format!("bad list length {n} in {}", what())));
        }
        if (n as usize).saturating_mul(item.size()) > self.remaining() {
            return Err(self.err(
                self.pos,
                format!(
                    "list of {n} items in {} runs past the end of the file",
                    what()
                ),
            ));
        }
        for _ in 0..n as usize {
            out.push(self.scalar(item, what)?);
        }
        Ok(())
    }

    pub(crate) fn skip_element(&mut self, e: &PlyElement) -> Result<(), CloudError> {
        if e.properties.is_empty() || e.count == 0 {
            return Ok(());
        }
        if let Some(size) = e.fixed_size() {
            let need = e.count.saturating_mul(size as u64);
            if need > self.remaining() as u64 {
                let whole = self.remaining() / size.max(1);
                return Err(self.err(
                    self.pos + whole * size,
                    format!(
                        "element '{}' is cut short: {} instances of {} bytes declared, data ends in instance {}",
                        e.name, e.count, size, whole
                    ),
                ));
            }
            self.pos += need as usize;
            return Ok(());
        }
        // Each instance consumes at least one byte (a list count), so this loop ends with the data.
        for i in 0..e.count {
            for p in &e.properties {
                let what = || format!("property '{}' of {} {i}", p.name, e.name);
                match p.kind {
                    PlyPropertyKind::Scalar(t) => {
                        self.scalar(t, what)?;
                    }
                    PlyPropertyKind::List { count, item } => self.skip_list(count, item, &what)?,
                }
            }
        }
        Ok(())
    }
}

fn read_binary_fixed(
    cur: &Cursor<'_>,
    vertex: &PlyElement,
    stride: usize,
    map: AttrMap,
) -> Result<PointCloud, CloudError> {
    let remaining = cur.remaining();
    let count = vertex.count;
    let need = count.saturating_mul(stride as u64);
    if need > remaining as u64 {
        let whole = remaining / stride.max(1);
        return Err(cur.err(
            cur.pos + whole * stride,
            format!(
                "vertex {whole} of {count} is cut short: the header declares {count} vertices of \
                 {stride} bytes ({need} bytes) but only {remaining} bytes follow the header"
            ),
        ));
    }
    let block = cur
        .data
        .get(cur.pos..cur.pos + need as usize)
        .unwrap_or(&[]);
    // Byte offset and type of each property within a record.
    let mut layout = Vec::with_capacity(vertex.properties.len());
    let mut off = 0;
    for p in &vertex.properties {
        let ty = match p.kind {
            PlyPropertyKind::Scalar(t) => t,
            // Unreachable for a fixed-size element; a harmless placeholder keeps this total.
            PlyPropertyKind::List { count, .. } => count,
        };
        layout.push((off, ty));
        off += ty.size();
    }
    let at = |i: usize| layout.get(i).copied().unwrap_or((0, PlyScalarType::UChar));
    let at3 = |idx: [usize; 3]| idx.map(at);
    let big = cur.big;
    let positions = decode_column(block, stride, at3(map.pos), big, |[x, y, z]| {
        Point3::new(x, y, z)
    });
    let normals = map.normal.map(|idx| {
        decode_column(block, stride, at3(idx), big, |[x, y, z]| {
            Vector3::new(x, y, z)
        })
    });
    let colors = map.color.map(|(idx, s)| {
        decode_column(block, stride, at3(idx), big, |[r, g, b]| {
            [to_u8(r, s), to_u8(g, s), to_u8(b, s)]
        })
    });
    let quality = map
        .quality
        .map(|i| decode_column(block, stride, [at(i)], big, |[q]| q as f32));
    PointCloud::from_parts(positions, normals, colors, quality)
}

fn read_binary_irregular(
    cur: &mut Cursor<'_>,
    vertex: &PlyElement,
    map: AttrMap,
) -> Result<PointCloud, CloudError> {
    // Every vertex takes at least this many bytes: caps the pre-allocation by the file size.
    let min_size: usize = vertex
        .properties
        .iter()
        .map(|p| match p.kind {
            PlyPropertyKind::Scalar(t) => t.size(),
            PlyPropertyKind::List { count, .. } => count.size(),
        })
        .sum();
    let cap = (vertex.count.min((cur.remaining() / min_size.max(1)) as u64)) as usize;
    let mut sink = Sink::new(map, cap);
    let mut values = vec![f64::NAN; vertex.properties.len()];
    for i in 0..vertex.count {
        for (p, slot) in vertex.properties.iter().zip(values.iter_mut()) {
            let what = || format!("property '{}' of vertex {i}", p.name);
            match p.kind {
                PlyPropertyKind::Scalar(t) => *slot = cur.scalar(t, what)?,
                PlyPropertyKind::List { count, item } => cur.skip_list(count, item, &what)?,
            }
        }
        sink.push(&values);
    }
    sink.finish()
}

/// Whitespace-separated tokens of an ASCII body, with the current line number.
pub(crate) struct Tokens<'a> {
    pub(crate) data: &'a [u8],
    pub(crate) pos: usize,
    /// Line of the next byte.
    pub(crate) line: usize,
    /// Line of the last token returned: where errors point (for a parse error the bad token, for
    /// an early end of file the last data line).
    pub(crate) tok_line: usize,
    pub(crate) file: &'a str,
}

impl<'a> Tokens<'a> {
    fn err(&self, message: String) -> CloudError {
        CloudError::PlyAscii {
            file: self.file.to_owned(),
            line: self.tok_line,
            message,
        }
    }

    fn next(&mut self) -> Option<&'a [u8]> {
        let data = self.data;
        while let Some(&b) = data.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while data.get(self.pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            self.pos += 1;
        }
        if self.pos == start {
            return None;
        }
        self.tok_line = self.line;
        data.get(start..self.pos)
    }

    pub(crate) fn number(&mut self, what: &dyn Fn() -> String) -> Result<f64, CloudError> {
        let Some(tok) = self.next() else {
            return Err(self.err(format!("file ends before {}", what())));
        };
        std::str::from_utf8(tok)
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
            .ok_or_else(|| {
                self.err(format!(
                    "cannot read '{}' as a number ({})",
                    String::from_utf8_lossy(tok),
                    what()
                ))
            })
    }

    fn skip_list(&mut self, what: &dyn Fn() -> String) -> Result<(), CloudError> {
        let n = self.number(&|| format!("the list count of {}", what()))?;
        if !(n >= 0.0 && n.fract() == 0.0) {
            return Err(self.err(format!("bad list length {n} in {}", what())));
        }
        // Each item is a token, so a lying count ends with the data.
        let mut k = 0.0;
        while k < n {
            if self.next().is_none() {
                return Err(self.err(format!("file ends inside the list of {}", what())));
            }
            k += 1.0;
        }
        Ok(())
    }

    /// Reads a list count and its items into `out` (cleared first).
    pub(crate) fn read_list(
        &mut self,
        what: &dyn Fn() -> String,
        out: &mut Vec<f64>,
    ) -> Result<(), CloudError> {
        out.clear();
        let n = self.number(&|| format!("the list count of {}", what()))?;
        if !(n >= 0.0 && n.fract() == 0.0) {
            return Err(self.err(format!("bad list length {n} in {}", what())));
        }
        // Each item is a token, so a lying count ends with the data.
        let mut k = 0.0;
        while k < n {
            out.push(self.number(what)?);
            k += 1.0;
        }
        Ok(())
    }

    pub(crate) fn skip_element(&mut self, e: &PlyElement) -> Result<(), CloudError> {
        if e.properties.is_empty() {
            return Ok(());
        }
        for i in 0..e.count {
            for p in &e.properties {
                let what = || format!("property '{}' of {} {i}", p.name, e.name);
                match p.kind {
                    PlyPropertyKind::Scalar(_) => {
                        if self.next().is_none() {
                            return Err(self.err(format!("file ends before {}", what())));
                        }
                    }
                    PlyPropertyKind::List { .. } => self.skip_list(&what)?,
                }
            }
        }
        Ok(())
    }
}

fn read_ascii_vertices(
    tokens: &mut Tokens<'_>,
    vertex: &PlyElement,
    map: AttrMap,
) -> Result<PointCloud, CloudError> {
    // A vertex takes at least two bytes per property ("0 "): caps the pre-allocation.
    let left = tokens.data.len().saturating_sub(tokens.pos);
    let per_vertex = 2 * vertex.properties.len().max(1);
    let cap = vertex.count.min((left / per_vertex) as u64 + 1) as usize;
    let mut sink = Sink::new(map, cap);
    let mut values = vec![f64::NAN; vertex.properties.len()];
    for i in 0..vertex.count {
        for (p, slot) in vertex.properties.iter().zip(values.iter_mut()) {
            let what = || format!("property '{}' of vertex {i} (of {})", p.name, vertex.count);
            match p.kind {
                // A `float` property holds an f32: round what the text says to it, as a binary
                // file would have.
                PlyPropertyKind::Scalar(PlyScalarType::Float) => {
                    *slot = f64::from(tokens.number(&what)? as f32);
                }
                PlyPropertyKind::Scalar(_) => *slot = tokens.number(&what)?,
                PlyPropertyKind::List { .. } => tokens.skip_list(&what)?,
            }
        }
        sink.push(&values);
    }
    sink.finish()
}
