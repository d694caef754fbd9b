//! Mesh files: binary STL (read also ASCII), Wavefront OBJ, PLY with faces (reading is
//! `sl_cloud::read_ply_mesh`, which also knows the Stanford range grids).
//!
//! Every write goes to a temporary file in the target folder renamed into place, so a failed
//! write never leaves half a file where a good one was.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Point3, Vector3};
use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::check_indices;
use crate::measure::vertex_normals;

/// Name used in errors for data that did not come from a file.
const MEMORY: &str = "<memory>";
/// Size of the binary STL header (free text) before the triangle count.
const STL_HEADER: usize = 80;
/// Bytes of one binary STL triangle: normal and three corners (12 `f32`), attribute `u16`.
const STL_TRIANGLE: usize = 50;

pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), MeshError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(|e| MeshError::io(&tmp, "write", e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        MeshError::io(path, "rename", e)
    })
}

fn read_file(path: &Path) -> Result<Vec<u8>, MeshError> {
    std::fs::read(path).map_err(|e| MeshError::io(path, "read", e))
}

/// The binary STL of `mesh` (`f32` coordinates, facet normals from the winding).
///
/// # Errors
/// [`MeshError::InvalidMesh`] when a triangle index is out of range.
pub fn stl_to_bytes(mesh: &TriangleMesh) -> Result<Vec<u8>, MeshError> {
    check_indices(mesh)?;
    let mut out = Vec::with_capacity(STL_HEADER + 4 + STL_TRIANGLE * mesh.triangles.len());
    let mut header = b"binary STL written by sl-mesh (structured-light)".to_vec();
    header.resize(STL_HEADER, b' ');
    out.extend_from_slice(&header);
    let count = u32::try_from(mesh.triangles.len()).map_err(|_| {
        MeshError::InvalidMesh("more than 2^32 triangles do not fit a binary STL".into())
    })?;
    out.extend_from_slice(&count.to_le_bytes());
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        let n = (b - a).cross(&(c - a));
        let n = if n.norm() > 0.0 { n.normalize() } else { n };
        for v in [n.x, n.y, n.z, a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z] {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        }
        out.extend_from_slice(&0u16.to_le_bytes());
    }
    Ok(out)
}

/// Writes `mesh` as a binary STL file. See [`stl_to_bytes`].
///
/// # Errors
/// [`MeshError::Io`] naming the file, [`MeshError::InvalidMesh`].
pub fn write_stl(path: &Path, mesh: &TriangleMesh) -> Result<(), MeshError> {
    write_atomically(path, &stl_to_bytes(mesh)?)
}

/// Reads an STL file (binary, or ASCII `solid … endsolid`), merging corners with identical
/// coordinates into shared vertices.
///
/// # Errors
/// [`MeshError::Io`], and [`MeshError::Stl`] naming the file and byte offset for a short or
/// malformed file.
pub fn read_stl(path: &Path) -> Result<TriangleMesh, MeshError> {
    parse_stl(&read_file(path)?, &path.display().to_string())
}

/// Reads an STL file held in memory. See [`read_stl`].
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// let mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)],
///     triangles: vec![[0, 1, 2]],
/// };
/// let bytes = sl_mesh::stl_to_bytes(&mesh)?;
/// assert_eq!(sl_mesh::read_stl_from_bytes(&bytes)?, mesh);
/// assert!(sl_mesh::read_stl_from_bytes(&bytes[..100]).is_err());
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn read_stl_from_bytes(bytes: &[u8]) -> Result<TriangleMesh, MeshError> {
    parse_stl(bytes, MEMORY)
}

fn parse_stl(bytes: &[u8], file: &str) -> Result<TriangleMesh, MeshError> {
    let err = |offset: usize, message: String| MeshError::Stl {
        file: file.to_owned(),
        offset: offset as u64,
        message,
    };
    let binary_len = |b: &[u8]| -> Option<usize> {
        let c = u32::from_le_bytes(b.get(STL_HEADER..STL_HEADER + 4)?.try_into().ok()?);
        Some(STL_HEADER + 4 + STL_TRIANGLE * c as usize)
    };
    let looks_ascii =
        bytes.trim_ascii_start().starts_with(b"solid") && binary_len(bytes) != Some(bytes.len());
    if looks_ascii {
        return parse_stl_ascii(bytes, file);
    }
    if bytes.len() < STL_HEADER + 4 {
        return Err(err(
            bytes.len(),
            format!(
                "file of {} bytes is shorter than the {}-byte binary STL header and count",
                bytes.len(),
                STL_HEADER + 4
            ),
        ));
    }
    let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    let need = STL_HEADER + 4 + STL_TRIANGLE * count;
    if bytes.len() < need {
        let whole = (bytes.len() - STL_HEADER - 4) / STL_TRIANGLE;
        return Err(err(
            STL_HEADER + 4 + whole * STL_TRIANGLE,
            format!(
                "truncated: the header announces {count} triangles ({need} bytes) but the file has {} bytes",
                bytes.len()
            ),
        ));
    }
    let mut builder = SoupBuilder::default();
    for k in 0..count {
        let base = STL_HEADER + 4 + k * STL_TRIANGLE + 12;
        let f = |i: usize| {
            let o = base + 4 * i;
            f64::from(f32::from_le_bytes([
                bytes[o],
                bytes[o + 1],
                bytes[o + 2],
                bytes[o + 3],
            ]))
        };
        let corners = [
            Point3::new(f(0), f(1), f(2)),
            Point3::new(f(3), f(4), f(5)),
            Point3::new(f(6), f(7), f(8)),
        ];
        if corners
            .iter()
            .any(|p| p.coords.iter().any(|c| !c.is_finite()))
        {
            return Err(err(
                base,
                format!("triangle {k} has a non-finite coordinate"),
            ));
        }
        builder.push(corners);
    }
    Ok(builder.mesh)
}

fn parse_stl_ascii(bytes: &[u8], file: &str) -> Result<TriangleMesh, MeshError> {
    let text = std::str::from_utf8(bytes).map_err(|e| MeshError::Stl {
        file: file.to_owned(),
        offset: e.valid_up_to() as u64,
        message: "ASCII STL is not valid UTF-8".into(),
    })?;
    let mut builder = SoupBuilder::default();
    let mut corners: Vec<Point3<f64>> = Vec::new();
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("vertex") => {
                let mut v = [0.0; 3];
                for c in &mut v {
                    *c = it
                        .next()
                        .and_then(|s| s.parse::<f64>().ok())
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| MeshError::Stl {
                            file: file.to_owned(),
                            offset: offset as u64,
                            message: format!("bad vertex line '{}'", line.trim()),
                        })?;
                }
                corners.push(Point3::from(v));
            }
            Some("endfacet") => {
                if corners.len() != 3 {
                    return Err(MeshError::Stl {
                        file: file.to_owned(),
                        offset: offset as u64,
                        message: format!("facet with {} vertices (3 expected)", corners.len()),
                    });
                }
                builder.push([corners[0], corners[1], corners[2]]);
                corners.clear();
            }
            _ => {}
        }
        offset += line.len();
    }
    if !corners.is_empty() {
        return Err(MeshError::Stl {
            file: file.to_owned(),
            offset: offset as u64,
            message: "truncated: a facet has no 'endfacet'".into(),
        });
    }
    Ok(builder.mesh)
}

/// Builds an indexed mesh from triangle corners, sharing identical positions.
#[derive(Default)]
struct SoupBuilder {
    mesh: TriangleMesh,
    index: HashMap<[u64; 3], u32>,
}

impl SoupBuilder {
    fn push(&mut self, corners: [Point3<f64>; 3]) {
        let t = corners.map(|p| {
            let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            *self.index.entry(key).or_insert_with(|| {
                self.mesh.vertices.push(p);
                (self.mesh.vertices.len() - 1) as u32
            })
        });
        self.mesh.triangles.push(t);
    }
}

/// The Wavefront OBJ text of `mesh`: `v` lines (17 significant digits: exact round trip),
/// `vn` per-vertex normals, `f a//a b//b c//c` faces (1-based).
///
/// # Errors
/// [`MeshError::InvalidMesh`] when a triangle index is out of range.
pub fn obj_to_string(mesh: &TriangleMesh) -> Result<String, MeshError> {
    check_indices(mesh)?;
    let mut s = String::with_capacity(mesh.vertices.len() * 60 + mesh.triangles.len() * 30);
    s.push_str("# written by sl-mesh (structured-light)\n");
    for p in &mesh.vertices {
        let _ = writeln!(s, "v {:?} {:?} {:?}", p.x, p.y, p.z);
    }
    for n in vertex_normals(mesh) {
        let _ = writeln!(s, "vn {:.6} {:.6} {:.6}", n.x, n.y, n.z);
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
    }
    Ok(s)
}

/// Writes `mesh` as an OBJ file. See [`obj_to_string`].
///
/// # Errors
/// [`MeshError::Io`] naming the file, [`MeshError::InvalidMesh`].
pub fn write_obj(path: &Path, mesh: &TriangleMesh) -> Result<(), MeshError> {
    write_atomically(path, obj_to_string(mesh)?.as_bytes())
}

/// Reads an OBJ file: `v` and `f` lines (`f` corners as `i`, `i/t`, `i//n` or `i/t/n`,
/// negative indices counted from the end, polygons split into fans); other lines are ignored.
///
/// # Errors
/// [`MeshError::Io`], and [`MeshError::Obj`] naming the file and line of a malformed vertex or
/// an index out of range.
pub fn read_obj(path: &Path) -> Result<TriangleMesh, MeshError> {
    let bytes = read_file(path)?;
    parse_obj(&bytes, &path.display().to_string())
}

/// Reads an OBJ file held in memory. See [`read_obj`].
///
/// ```
/// let mesh = sl_mesh::read_obj_from_bytes(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")?;
/// assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
/// assert!(sl_mesh::read_obj_from_bytes(b"v 0 0 0\nf 1 2 3\n").is_err());
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn read_obj_from_bytes(bytes: &[u8]) -> Result<TriangleMesh, MeshError> {
    parse_obj(bytes, MEMORY)
}

fn parse_obj(bytes: &[u8], file: &str) -> Result<TriangleMesh, MeshError> {
    let text = String::from_utf8_lossy(bytes);
    let mut mesh = TriangleMesh::default();
    let mut faces: Vec<(usize, Vec<i64>)> = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let err = |message: String| MeshError::Obj {
            file: file.to_owned(),
            line: ln + 1,
            message,
        };
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut v = [0.0; 3];
                for c in &mut v {
                    *c = it
                        .next()
                        .and_then(|s| s.parse::<f64>().ok())
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| err(format!("bad vertex '{line}'")))?;
                }
                mesh.vertices.push(Point3::from(v));
            }
            Some("f") => {
                let idx: Result<Vec<i64>, _> = it
                    .map(|c| {
                        c.split('/')
                            .next()
                            .and_then(|s| s.parse::<i64>().ok())
                            .ok_or_else(|| err(format!("bad face corner '{c}'")))
                    })
                    .collect();
                let idx = idx?;
                if idx.len() < 3 {
                    return Err(err(format!("face with {} corners", idx.len())));
                }
                faces.push((ln + 1, idx));
            }
            _ => {}
        }
    }
    let n = mesh.vertices.len() as i64;
    for (line, idx) in faces {
        let resolve = |i: i64| -> Result<u32, MeshError> {
            let r = if i < 0 { n + i } else { i - 1 };
            if i == 0 || r < 0 || r >= n {
                Err(MeshError::Obj {
                    file: file.to_owned(),
                    line,
                    message: format!("vertex index {i} out of range (the file has {n} vertices)"),
                })
            } else {
                Ok(r as u32)
            }
        };
        let a = resolve(idx[0])?;
        for w in idx[1..].windows(2) {
            mesh.triangles.push([a, resolve(w[0])?, resolve(w[1])?]);
        }
    }
    Ok(mesh)
}

/// The binary little-endian PLY of `mesh`: `double` vertex positions (exact round trip),
/// `float` normals when `normals` is given (one per vertex), `face` lists of `uchar`/`int`.
/// Open3D, MeshLab and `sl_cloud::read_ply_mesh` read it.
///
/// # Errors
/// [`MeshError::InvalidMesh`] when a triangle index is out of range,
/// [`MeshError::AttributeLength`] when the normals are not one per vertex.
pub fn ply_mesh_to_bytes(
    mesh: &TriangleMesh,
    normals: Option<&[Vector3<f64>]>,
) -> Result<Vec<u8>, MeshError> {
    ply_bytes(mesh, normals, None)
}

/// The binary little-endian PLY of `mesh` with a colour per vertex: as [`ply_mesh_to_bytes`],
/// plus the `uchar` properties `red green blue` after the position (and normal) of each vertex,
/// the names MeshLab, Open3D, CloudCompare and `sl_cloud::read_ply` read as vertex colours.
///
/// # Errors
/// [`MeshError::AttributeLength`] when `colours` (or `normals`) is not one per vertex,
/// [`MeshError::InvalidMesh`] when a triangle index is out of range.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// let mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)],
///     triangles: vec![[0, 1, 2]],
/// };
/// let colours = [[255, 0, 0], [0, 255, 0], [0, 0, 255]];
/// let bytes = sl_mesh::ply_mesh_to_bytes_coloured(&mesh, None, &colours)?;
/// let cloud = sl_cloud::read_ply_from_bytes(&bytes)?;
/// assert_eq!(cloud.colors(), Some(&colours[..]));
/// assert_eq!(sl_cloud::read_ply_mesh_from_bytes(&bytes)?, mesh);
/// // One colour short: refused, naming what is wrong.
/// let err = sl_mesh::ply_mesh_to_bytes_coloured(&mesh, None, &colours[1..]).unwrap_err();
/// assert_eq!(err.to_string(), "2 colours for 3 vertices");
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn ply_mesh_to_bytes_coloured(
    mesh: &TriangleMesh,
    normals: Option<&[Vector3<f64>]>,
    colours: &[[u8; 3]],
) -> Result<Vec<u8>, MeshError> {
    ply_bytes(mesh, normals, Some(colours))
}

/// `Ok` when `values` holds one value per vertex of `mesh`.
pub(crate) fn check_per_vertex<T>(
    mesh: &TriangleMesh,
    values: &[T],
    attribute: &'static str,
) -> Result<(), MeshError> {
    if values.len() == mesh.vertices.len() {
        Ok(())
    } else {
        Err(MeshError::AttributeLength {
            attribute,
            found: values.len(),
            expected: mesh.vertices.len(),
            of: "vertices",
        })
    }
}

fn ply_bytes(
    mesh: &TriangleMesh,
    normals: Option<&[Vector3<f64>]>,
    colours: Option<&[[u8; 3]]>,
) -> Result<Vec<u8>, MeshError> {
    check_indices(mesh)?;
    if let Some(n) = normals {
        check_per_vertex(mesh, n, "normals")?;
    }
    if let Some(c) = colours {
        check_per_vertex(mesh, c, "colours")?;
    }
    let mut header = String::from(
        "ply\nformat binary_little_endian 1.0\ncomment written by sl-mesh (structured-light)\n",
    );
    let _ = writeln!(header, "element vertex {}", mesh.vertices.len());
    header.push_str("property double x\nproperty double y\nproperty double z\n");
    if normals.is_some() {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if colours.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    let _ = writeln!(header, "element face {}", mesh.triangles.len());
    header.push_str("property list uchar int vertex_indices\nend_header\n");
    let mut out = header.into_bytes();
    out.reserve(mesh.vertices.len() * 39 + mesh.triangles.len() * 13);
    for (i, p) in mesh.vertices.iter().enumerate() {
        for c in [p.x, p.y, p.z] {
            out.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(n) = normals {
            for c in [n[i].x, n[i].y, n[i].z] {
                out.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        if let Some(c) = colours {
            out.extend_from_slice(&c[i]);
        }
    }
    for t in &mesh.triangles {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    Ok(out)
}

/// Writes `mesh` (with per-vertex normals) as a PLY file. See [`ply_mesh_to_bytes`].
///
/// # Errors
/// [`MeshError::Io`] naming the file, [`MeshError::InvalidMesh`].
pub fn write_ply_mesh(path: &Path, mesh: &TriangleMesh) -> Result<(), MeshError> {
    let normals = vertex_normals(mesh);
    write_atomically(path, &ply_mesh_to_bytes(mesh, Some(&normals))?)
}

/// Writes `mesh` with per-vertex normals and the colour `colours[i]` of vertex `i` as a PLY
/// file. See [`ply_mesh_to_bytes_coloured`]; `sl_cloud::read_ply` reads the colours back as
/// the cloud's, [`read_mesh`] the mesh.
///
/// # Errors
/// [`MeshError::AttributeLength`] when `colours` is not one per vertex (nothing is written),
/// [`MeshError::Io`] naming the file, [`MeshError::InvalidMesh`].
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// let mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)],
///     triangles: vec![[0, 1, 2]],
/// };
/// let path = std::env::temp_dir().join(format!("sl-mesh-doc-{}.ply", std::process::id()));
/// sl_mesh::write_ply_mesh_coloured(&path, &mesh, &[[200, 30, 30]; 3])?;
/// let cloud = sl_cloud::read_ply(&path)?;
/// assert_eq!(cloud.colors(), Some(&[[200, 30, 30]; 3][..]));
/// # std::fs::remove_file(&path).ok();
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn write_ply_mesh_coloured(
    path: &Path,
    mesh: &TriangleMesh,
    colours: &[[u8; 3]],
) -> Result<(), MeshError> {
    let normals = vertex_normals(mesh);
    write_atomically(
        path,
        &ply_mesh_to_bytes_coloured(mesh, Some(&normals), colours)?,
    )
}

/// Reads a mesh file by its extension: `.stl`, `.obj`, or `.ply` (through
/// `sl_cloud::read_ply_mesh`).
///
/// # Errors
/// The reader's errors, or [`MeshError::InvalidParameter`] for another extension.
pub fn read_mesh(path: &Path) -> Result<TriangleMesh, MeshError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "stl" => read_stl(path),
        "obj" => read_obj(path),
        "ply" => Ok(sl_cloud::read_ply_mesh(path)?),
        _ => Err(MeshError::invalid(
            "path",
            path.display(),
            "unknown mesh file extension (expected .stl, .obj or .ply)",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PoissonConfig, check_topology, poisson_reconstruct};
    use sl_cloud::PointCloud;

    /// A closed mesh of a sphere of radius 10 (Poisson at depth 5).
    fn ball() -> TriangleMesh {
        let n = 2000;
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (pts, nrm): (Vec<_>, Vec<_>) = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                let v = Vector3::new(r * t.cos(), r * t.sin(), z);
                (Point3::from(v * 10.0 + Vector3::new(1.0, 2.0, 3.0)), v)
            })
            .unzip();
        let cloud = PointCloud::from_positions(pts).with_normals(nrm).unwrap();
        let cfg = PoissonConfig {
            depth: 5,
            ..PoissonConfig::default()
        };
        poisson_reconstruct(&cloud, &cfg).unwrap().mesh
    }

    /// STL stores `f32`: the round trip is exact to `f32` rounding, keeps the triangles and
    /// their order and winding, and the shared vertices are found again (the mesh stays closed).
    #[test]
    fn stl_round_trip() {
        let mesh = ball();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ball.stl");
        write_stl(&path, &mesh).unwrap();
        assert_eq!(
            std::fs::metadata(&path).unwrap().len() as usize,
            STL_HEADER + 4 + STL_TRIANGLE * mesh.triangles.len()
        );
        let back = read_mesh(&path).unwrap();
        assert_eq!(back.triangles.len(), mesh.triangles.len());
        assert_eq!(back.vertices.len(), mesh.vertices.len());
        for (t, u) in mesh.triangles.iter().zip(&back.triangles) {
            for k in 0..3 {
                let (p, q) = (mesh.vertices[t[k] as usize], back.vertices[u[k] as usize]);
                assert!((p - q).norm() < 1e-5 * p.coords.norm(), "{p} vs {q}");
            }
        }
        assert!(check_topology(&back).is_watertight_manifold());
    }

    /// OBJ writes 17 significant digits: the round trip is exact.
    #[test]
    fn obj_round_trip() {
        let mesh = ball();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ball.obj");
        write_obj(&path, &mesh).unwrap();
        assert_eq!(read_mesh(&path).unwrap(), mesh);
    }

    /// PLY writes `double` positions: exact; `sl_cloud` reads the normals back as the cloud's.
    #[test]
    fn ply_round_trip() {
        let mesh = ball();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ball.ply");
        write_ply_mesh(&path, &mesh).unwrap();
        assert_eq!(read_mesh(&path).unwrap(), mesh);
        let cloud = sl_cloud::read_ply(&path).unwrap();
        let normals = cloud.normals().unwrap();
        for (n, m) in normals.iter().zip(vertex_normals(&mesh)) {
            assert!((n - m).norm() < 1e-6);
        }
    }

    /// Coloured PLY: `sl_cloud::read_ply` gives back every vertex's colour, position and
    /// normal in order, `read_mesh` the mesh; a colour array of the wrong length is refused
    /// before anything is written.
    #[test]
    fn coloured_ply_round_trip() {
        let mesh = ball();
        let colours: Vec<[u8; 3]> = (0..mesh.vertices.len())
            .map(|i| [(i % 256) as u8, (i * 7 % 256) as u8, (i * 13 % 251) as u8])
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ball.ply");
        write_ply_mesh_coloured(&path, &mesh, &colours).unwrap();
        assert_eq!(read_mesh(&path).unwrap(), mesh);
        let cloud = sl_cloud::read_ply(&path).unwrap();
        assert_eq!(cloud.colors().unwrap(), &colours[..]);
        assert_eq!(cloud.positions(), &mesh.vertices[..]);
        for (n, m) in cloud.normals().unwrap().iter().zip(vertex_normals(&mesh)) {
            assert!((n - m).norm() < 1e-6);
        }
        let bad = dir.path().join("bad.ply");
        let e = write_ply_mesh_coloured(&bad, &mesh, &colours[1..]).unwrap_err();
        assert!(
            matches!(e, MeshError::AttributeLength { attribute: "colours", found, expected, .. }
                if found + 1 == expected && expected == mesh.vertices.len()),
            "{e}"
        );
        assert!(!bad.exists());
    }

    #[test]
    fn ascii_stl_is_read() {
        let text = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
        let mesh = read_stl_from_bytes(text).unwrap();
        assert_eq!(mesh.vertices.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [1, 3, 2]]);
    }

    /// Corrupt files give typed errors naming the file and where.
    #[test]
    fn corrupt_files_are_named() {
        let mesh = ball();
        let dir = tempfile::tempdir().unwrap();
        // A truncated binary STL.
        let bytes = stl_to_bytes(&mesh).unwrap();
        let path = dir.path().join("cut.stl");
        std::fs::write(&path, &bytes[..bytes.len() - 7]).unwrap();
        let e = read_stl(&path).unwrap_err();
        assert!(matches!(e, MeshError::Stl { .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains("cut.stl") && msg.contains("truncated"),
            "{msg}"
        );
        // Shorter than the header.
        let e = read_stl_from_bytes(&bytes[..50]).unwrap_err();
        assert!(matches!(e, MeshError::Stl { offset: 50, .. }), "{e}");
        // A NaN coordinate.
        let mut nan = bytes.clone();
        nan[STL_HEADER + 4 + 12..STL_HEADER + 4 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
        let e = read_stl_from_bytes(&nan).unwrap_err();
        assert!(e.to_string().contains("non-finite"), "{e}");
        // ASCII STL with a facet of two vertices.
        let e = read_stl_from_bytes(b"solid x\nfacet\nvertex 0 0 0\nvertex 1 0 0\nendfacet\n")
            .unwrap_err();
        assert!(e.to_string().contains("2 vertices"), "{e}");
        // OBJ: a bad vertex, an index out of range; the line is named.
        let path = dir.path().join("bad.obj");
        std::fs::write(&path, "v 0 0 0\nv 1 x 0\n").unwrap();
        let e = read_obj(&path).unwrap_err();
        assert!(matches!(e, MeshError::Obj { line: 2, .. }), "{e}");
        assert!(e.to_string().contains("bad.obj"), "{e}");
        let e = read_obj_from_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n").unwrap_err();
        assert!(matches!(e, MeshError::Obj { line: 5, .. }), "{e}");
        // PLY: a face list cut short.
        let ply = ply_mesh_to_bytes(&mesh, None).unwrap();
        let path = dir.path().join("cut.ply");
        std::fs::write(&path, &ply[..ply.len() - 5]).unwrap();
        let e = read_mesh(&path).unwrap_err();
        assert!(matches!(e, MeshError::Cloud(_)), "{e}");
        assert!(e.to_string().contains("cut.ply"), "{e}");
        // Missing file, unknown extension.
        let e = read_mesh(&dir.path().join("none.stl")).unwrap_err();
        assert!(matches!(e, MeshError::Io { .. }), "{e}");
        let e = read_mesh(&dir.path().join("mesh.3ds")).unwrap_err();
        assert!(e.to_string().contains("mesh.3ds"), "{e}");
        // Writing a mesh with an index out of range is refused.
        let broken = TriangleMesh {
            vertices: vec![Point3::origin()],
            triangles: vec![[0, 1, 2]],
        };
        assert!(matches!(
            stl_to_bytes(&broken),
            Err(MeshError::InvalidMesh(_))
        ));
    }
}
