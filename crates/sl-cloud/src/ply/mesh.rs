//! Triangle meshes from PLY: `face` elements, or the `range_grid` of the Stanford range scans.

use std::path::Path;

use nalgebra::Point3;

use super::PlyEncoding;
use super::PlyPropertyKind;
use super::header::parse_header;
use super::read::{Cursor, Tokens, parse_ply};
use crate::{CloudError, PlyHeader};

/// Name used in errors for data that did not come from a file.
const MEMORY: &str = "<memory>";

/// A range-grid cell pair is joined into a triangle only if no edge is longer than this many
/// times the median edge length of the grid: the Stanford scans leave depth discontinuities as
/// neighbouring cells, and joining across them would build walls that the object does not have.
/// Four median edges is what a steep but real surface reaches on those scans.
pub const RANGE_GRID_MAX_EDGE_FACTOR: f64 = 4.0;

/// A triangle mesh: vertex positions and triangles as indices into them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriangleMesh {
    /// Vertex positions, in the file's units.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles, each three indices into `vertices`, in the file's winding order.
    pub triangles: Vec<[u32; 3]>,
}

/// Reads a triangle mesh from a PLY file.
///
/// The vertices are those [`read_ply`](crate::read_ply) reads. Triangles come from the `face`
/// element (`vertex_indices` or `vertex_index`; polygons with more than three corners are split
/// into a fan) or, when the file has no faces, from a Stanford `range_grid` element: the grid of
/// `num_cols` × `num_rows` cells given by the `obj_info` lines, each cell listing zero or one
/// vertex. Two triangles are made per square of four neighbouring cells (one when only three
/// have a vertex), skipping any with an edge longer than [`RANGE_GRID_MAX_EDGE_FACTOR`] times the
/// median grid edge.
///
/// # Errors
/// Everything [`read_ply`](crate::read_ply) reports, plus [`CloudError::PlyMissing`] when the
/// file has neither faces nor a range grid, and a data error naming the face or cell whose vertex
/// index is out of range.
///
/// ```
/// let text = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
/// property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
/// 0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
/// let mesh = sl_cloud::read_ply_mesh_from_bytes(text)?;
/// assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn read_ply_mesh(path: &Path) -> Result<TriangleMesh, CloudError> {
    let bytes = std::fs::read(path).map_err(|e| CloudError::io(path, "read", e))?;
    parse_mesh(&bytes, &path.display().to_string())
}

/// Reads a triangle mesh from a PLY file held in memory. See [`read_ply_mesh`].
pub fn read_ply_mesh_from_bytes(bytes: &[u8]) -> Result<TriangleMesh, CloudError> {
    parse_mesh(bytes, MEMORY)
}

/// The body reader of either encoding.
enum Body<'a> {
    Ascii(Tokens<'a>),
    Binary(Cursor<'a>),
}

impl Body<'_> {
    fn skip_element(&mut self, e: &super::PlyElement) -> Result<(), CloudError> {
        match self {
            Body::Ascii(t) => t.skip_element(e),
            Body::Binary(c) => c.skip_element(e),
        }
    }

    fn scalar(
        &mut self,
        kind: PlyPropertyKind,
        what: &dyn Fn() -> String,
    ) -> Result<(), CloudError> {
        match (self, kind) {
            (Body::Ascii(t), PlyPropertyKind::Scalar(_)) => t.number(what).map(drop),
            (Body::Binary(c), PlyPropertyKind::Scalar(ty)) => c.scalar(ty, what).map(drop),
            (body, PlyPropertyKind::List { count, item }) => {
                let mut scratch = Vec::new();
                body.list(count, item, what, &mut scratch)
            }
        }
    }

    fn list(
        &mut self,
        count: super::PlyScalarType,
        item: super::PlyScalarType,
        what: &dyn Fn() -> String,
        out: &mut Vec<f64>,
    ) -> Result<(), CloudError> {
        match self {
            Body::Ascii(t) => t.read_list(what, out),
            Body::Binary(c) => c.read_list(count, item, what, out),
        }
    }

    fn data_error(&self, message: String) -> CloudError {
        match self {
            Body::Ascii(t) => CloudError::PlyAscii {
                file: t.file.to_owned(),
                line: t.tok_line,
                message,
            },
            Body::Binary(c) => CloudError::PlyBinary {
                file: c.file.to_owned(),
                offset: c.pos as u64,
                message,
            },
        }
    }
}

fn parse_mesh(bytes: &[u8], file: &str) -> Result<TriangleMesh, CloudError> {
    let header = parse_header(bytes, file)?;
    let vertices = parse_ply(bytes, file)?.positions().to_vec();
    let start = usize::try_from(header.body_offset)
        .unwrap_or(usize::MAX)
        .min(bytes.len());
    let mut body = match header.encoding {
        PlyEncoding::Ascii => {
            let lines = bytes
                .get(..start)
                .unwrap_or(&[])
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            Body::Ascii(Tokens {
                data: bytes,
                pos: start,
                line: lines + 1,
                tok_line: lines,
                file,
            })
        }
        enc => Body::Binary(Cursor {
            data: bytes,
            pos: start,
            big: enc == PlyEncoding::BinaryBigEndian,
            file,
        }),
    };
    let n = vertices.len();
    let mut triangles = Vec::new();
    let mut grid: Option<Vec<Option<u32>>> = None;
    let mut list = Vec::new();
    for e in &header.elements {
        let is_face = e.name == "face";
        let is_grid = e.name == "range_grid";
        if !is_face && !is_grid {
            body.skip_element(e)?;
            continue;
        }
        let mut cells = Vec::new();
        for i in 0..e.count {
            for p in &e.properties {
                let what = || format!("property '{}' of {} {i}", p.name, e.name);
                let wanted = is_grid || p.name == "vertex_indices" || p.name == "vertex_index";
                let PlyPropertyKind::List { count, item } = p.kind else {
                    body.scalar(p.kind, &what)?;
                    continue;
                };
                if !wanted {
                    body.scalar(p.kind, &what)?;
                    continue;
                }
                body.list(count, item, &what, &mut list)?;
                let index = |v: f64| -> Result<u32, CloudError> {
                    if v >= 0.0 && v.fract() == 0.0 && (v as usize) < n {
                        Ok(v as u32)
                    } else {
                        Err(body.data_error(format!(
                            "{}: vertex index {v} out of range (the file has {n} vertices)",
                            what()
                        )))
                    }
                };
                if is_face {
                    if let Some((&first, rest)) = list.split_first() {
                        let a = index(first)?;
                        for w in rest.windows(2) {
                            triangles.push([a, index(w[0])?, index(w[1])?]);
                        }
                    }
                } else {
                    cells.push(match list.first() {
                        Some(&v) => Some(index(v)?),
                        None => None,
                    });
                }
            }
        }
        if is_grid {
            grid = Some(cells);
        }
    }
    if triangles.is_empty() {
        if let Some(cells) = grid {
            triangles = triangulate_range_grid(&header, &vertices, &cells, file)?;
        } else if header.element("face").is_none() {
            return Err(CloudError::PlyMissing {
                file: file.to_owned(),
                what: "element 'face' or 'range_grid' (no triangles to read)".into(),
            });
        }
    }
    Ok(TriangleMesh {
        vertices,
        triangles,
    })
}

fn obj_info_usize(header: &PlyHeader, key: &str) -> Option<usize> {
    header.obj_info.iter().find_map(|line| {
        let mut it = line.split_whitespace();
        (it.next() == Some(key))
            .then(|| it.next()?.parse().ok())
            .flatten()
    })
}

fn triangulate_range_grid(
    header: &PlyHeader,
    vertices: &[Point3<f64>],
    cells: &[Option<u32>],
    file: &str,
) -> Result<Vec<[u32; 3]>, CloudError> {
    let (Some(cols), Some(rows)) = (
        obj_info_usize(header, "num_cols"),
        obj_info_usize(header, "num_rows"),
    ) else {
        return Err(CloudError::PlyMissing {
            file: file.to_owned(),
            what: "'obj_info num_cols'/'num_rows' lines for the range_grid".into(),
        });
    };
    if cols.checked_mul(rows) != Some(cells.len()) {
        return Err(CloudError::PlyMissing {
            file: file.to_owned(),
            what: format!(
                "range_grid of num_cols x num_rows = {cols} x {rows} cells (it has {})",
                cells.len()
            ),
        });
    }
    let at = |r: usize, c: usize| cells[r * cols + c];
    let p = |i: u32| vertices[i as usize];
    // Median length of the horizontal and vertical grid edges.
    let mut edges: Vec<f64> = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            if let Some(a) = at(r, c) {
                if c + 1 < cols
                    && let Some(b) = at(r, c + 1)
                {
                    edges.push((p(a) - p(b)).norm());
                }
                if r + 1 < rows
                    && let Some(b) = at(r + 1, c)
                {
                    edges.push((p(a) - p(b)).norm());
                }
            }
        }
    }
    if edges.is_empty() {
        return Ok(Vec::new());
    }
    let mid = edges.len() / 2;
    let median = *edges.select_nth_unstable_by(mid, f64::total_cmp).1;
    let max_edge = RANGE_GRID_MAX_EDGE_FACTOR * median;
    let short = |a: u32, b: u32| (p(a) - p(b)).norm() <= max_edge;
    let mut tris = Vec::new();
    let mut push = |a: u32, b: u32, c: u32| {
        if short(a, b) && short(b, c) && short(c, a) {
            tris.push([a, b, c]);
        }
    };
    for r in 0..rows.saturating_sub(1) {
        for c in 0..cols.saturating_sub(1) {
            // Square: a b / d e (rows top to bottom).
            let (a, b, d, e) = (at(r, c), at(r, c + 1), at(r + 1, c), at(r + 1, c + 1));
            match (a, b, d, e) {
                (Some(a), Some(b), Some(d), Some(e)) => {
                    push(a, d, b);
                    push(b, d, e);
                }
                (Some(a), Some(b), Some(d), None) => push(a, d, b),
                (Some(a), Some(b), None, Some(e)) => push(a, e, b),
                (Some(a), None, Some(d), Some(e)) => push(a, d, e),
                (None, Some(b), Some(d), Some(e)) => push(b, d, e),
                _ => {}
            }
        }
    }
    Ok(tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GRID_HEADER: &str = "ply\nformat ascii 1.0\nobj_info num_cols 3\nobj_info num_rows 2\n\
element vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
element range_grid 6\nproperty list uchar int vertex_indices\nend_header\n";

    #[test]
    fn range_grid_makes_two_triangles_per_full_square() {
        // Cells: row 0 = v0 v1 v2, row 1 = v3 v4 (none): one full square and one with three.
        let body = "0 0 0\n1 0 0\n2 0 0\n0 1 0\n1 1 0\n1 0\n1 1\n1 2\n1 3\n1 4\n0\n";
        let mesh = read_ply_mesh_from_bytes(format!("{GRID_HEADER}{body}").as_bytes()).unwrap();
        assert_eq!(mesh.vertices.len(), 5);
        assert_eq!(mesh.triangles, vec![[0, 3, 1], [1, 3, 4], [1, 4, 2]]);
    }

    #[test]
    fn range_grid_does_not_bridge_depth_jumps() {
        // v2 sits 100 units behind its neighbours: its triangle must not be built.
        let body = "0 0 0\n1 0 0\n2 0 100\n0 1 0\n1 1 0\n1 0\n1 1\n1 2\n1 3\n1 4\n0\n";
        let mesh = read_ply_mesh_from_bytes(format!("{GRID_HEADER}{body}").as_bytes()).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 3, 1], [1, 3, 4]]);
    }

    #[test]
    fn binary_faces_and_bad_indices() {
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
property float x\nproperty float y\nproperty float z\nelement face 1\n\
property uchar flags\nproperty list uchar int vertex_indices\nend_header\n"
            .to_vec();
        for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.push(7); // flags
        bytes.push(3);
        for i in [0i32, 1, 2] {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
        let mesh = read_ply_mesh_from_bytes(&bytes).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
        // Index 9 does not exist.
        let n = bytes.len();
        bytes[n - 4..].copy_from_slice(&9i32.to_le_bytes());
        let err = read_ply_mesh_from_bytes(&bytes).unwrap_err().to_string();
        assert!(err.contains("vertex index 9 out of range"), "{err}");
        // Truncated inside the face list.
        assert!(read_ply_mesh_from_bytes(&bytes[..n - 2]).is_err());
    }

    #[test]
    fn a_point_cloud_without_faces_is_an_error() {
        let text = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\n1 2 3\n";
        let err = read_ply_mesh_from_bytes(text).unwrap_err().to_string();
        assert!(err.contains("no element 'face' or 'range_grid'"), "{err}");
    }

    #[test]
    fn stanford_bunny_range_grid() {
        let Ok(root) = std::env::var("SL_DATA") else {
            eprintln!("SL_DATA not set: skipping the Stanford bunny mesh test");
            return;
        };
        let path = Path::new(&root).join("bunny").join("bun000.ply");
        let mesh = read_ply_mesh(&path).unwrap();
        assert_eq!(mesh.vertices.len(), 40256);
        // A closed-ish grid of ~40k vertices has about two triangles per vertex; the holes and
        // the discontinuities remove some. Every vertex index must be in range.
        assert!(
            mesh.triangles.len() > 60_000 && mesh.triangles.len() < 82_000,
            "{}",
            mesh.triangles.len()
        );
        assert!(
            mesh.triangles
                .iter()
                .flatten()
                .all(|&i| (i as usize) < mesh.vertices.len())
        );
        // Triangles are small: the scan spacing is about 0.5 mm (in metres here).
        let longest = mesh
            .triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (mesh.vertices[a as usize] - mesh.vertices[b as usize]).norm())
            .fold(0.0, f64::max);
        assert!(longest < 0.005, "longest edge {longest} m");
    }
}
