//! Wavefront OBJ with a texture: `NAME.obj` (positions, texture coordinates, normals, faces),
//! `NAME.mtl` (one material whose diffuse map is the texture) and `NAME.png` (the atlas), the
//! three named relative to one another so they move together.

use std::fmt::Write as _;
#[cfg(feature = "image-files")]
use std::path::Path;
use std::path::PathBuf;

use sl_cloud::TriangleMesh;

use crate::MeshError;
use crate::adjacency::check_indices;
use crate::atlas::TextureAtlas;
use crate::measure::vertex_normals;

/// Name of the one material of the files.
const MATERIAL: &str = "scan";

/// The text of a textured OBJ and of its material library: the result of
/// [`textured_obj_to_strings`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TexturedObjText {
    /// The OBJ: `mtllib NAME.mtl`, `v` (17 significant digits: exact), `vt` (three per
    /// triangle, exact `f32`), `vn` (per vertex), `usemtl`, faces `f v/vt/vn` (1-based).
    pub obj: String,
    /// The MTL: one material, white, without specular highlight, `map_Kd NAME.png`.
    pub mtl: String,
}

/// The files written by [`write_obj_textured`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TexturedObjFiles {
    /// The OBJ file (the path given).
    pub obj: PathBuf,
    /// The material library, beside it: `NAME.mtl`.
    pub mtl: PathBuf,
    /// The texture, beside it: `NAME.png`.
    pub png: PathBuf,
}

/// The OBJ and MTL text of `mesh` textured by `atlas`, for files named `NAME.obj`, `NAME.mtl`
/// and `NAME.png` with `NAME = name` (the OBJ names the MTL, the MTL the PNG, both relative).
///
/// # Errors
/// [`MeshError::InvalidMesh`] for a triangle index out of range,
/// [`MeshError::AttributeLength`] when the atlas does not have texture coordinates for every
/// triangle, [`MeshError::InvalidParameter`] for an empty `name` or one with white space or a
/// path separator (OBJ readers split `mtllib` and `map_Kd` lines at white space).
///
/// ```
/// use nalgebra::Point3;
/// use sl_mesh::{TextureConfig, TriangleMesh, bake_texture, textured_obj_to_strings};
/// let mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)],
///     triangles: vec![[0, 1, 2]],
/// };
/// let atlas = bake_texture(&mesh, &TextureConfig::default(), |_, _| Some([200, 120, 40]))?;
/// let text = textured_obj_to_strings(&mesh, &atlas, "part")?;
/// assert!(text.obj.contains("mtllib part.mtl\n") && text.obj.contains("f 1/1/1 2/2/2 3/3/3\n"));
/// assert!(text.mtl.contains("map_Kd part.png\n"));
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn textured_obj_to_strings(
    mesh: &TriangleMesh,
    atlas: &TextureAtlas,
    name: &str,
) -> Result<TexturedObjText, MeshError> {
    check_indices(mesh)?;
    if atlas.uv.len() != mesh.triangles.len() {
        return Err(MeshError::AttributeLength {
            attribute: "texture coordinate triples",
            found: atlas.uv.len(),
            expected: mesh.triangles.len(),
            of: "triangles",
        });
    }
    if name.is_empty()
        || name
            .chars()
            .any(|c| c.is_whitespace() || c == '/' || c == '\\')
    {
        return Err(MeshError::invalid(
            "name",
            format!("'{name}'"),
            "the OBJ's file name must be non-empty, without white space or path separators (OBJ readers split mtllib and map_Kd lines at white space)",
        ));
    }
    let mut obj = String::with_capacity(mesh.vertices.len() * 100 + mesh.triangles.len() * 110);
    obj.push_str("# written by sl-mesh (structured-light)\n");
    let _ = writeln!(obj, "mtllib {name}.mtl");
    for p in &mesh.vertices {
        let _ = writeln!(obj, "v {:?} {:?} {:?}", p.x, p.y, p.z);
    }
    for corners in &atlas.uv {
        for [u, v] in corners {
            let _ = writeln!(obj, "vt {u:?} {v:?}");
        }
    }
    for n in vertex_normals(mesh) {
        let _ = writeln!(obj, "vn {:.6} {:.6} {:.6}", n.x, n.y, n.z);
    }
    let _ = writeln!(obj, "usemtl {MATERIAL}");
    for (k, t) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| i + 1);
        let (ta, tb, tc) = (3 * k + 1, 3 * k + 2, 3 * k + 3);
        let _ = writeln!(obj, "f {a}/{ta}/{a} {b}/{tb}/{b} {c}/{tc}/{c}");
    }
    let mtl = format!(
        "# written by sl-mesh (structured-light)\nnewmtl {MATERIAL}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\nmap_Kd {name}.png\n"
    );
    Ok(TexturedObjText { obj, mtl })
}

/// Writes `mesh` textured by `atlas` as `NAME.obj` at `path`, with `NAME.mtl` and `NAME.png`
/// beside it (see [`textured_obj_to_strings`]). The texture is written first and the OBJ last,
/// each atomically: an OBJ on disk always has its material and texture.
///
/// # Errors
/// [`MeshError::InvalidParameter`] when `path` does not end in `.obj` or its name does not
/// suit an OBJ (see [`textured_obj_to_strings`]), [`MeshError::Io`] and [`MeshError::Png`]
/// naming the file that could not be written, and the errors of [`textured_obj_to_strings`].
///
/// ```
/// use nalgebra::Point3;
/// use sl_mesh::{TextureConfig, TriangleMesh, bake_texture, write_obj_textured};
/// let mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)],
///     triangles: vec![[0, 1, 2]],
/// };
/// let atlas = bake_texture(&mesh, &TextureConfig::default(), |p, _| Some([(200.0 * p.x) as u8, 0, 0]))?;
/// let dir = std::env::temp_dir().join(format!("sl-mesh-doc-obj-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).ok();
/// let files = write_obj_textured(&dir.join("part.obj"), &mesh, &atlas)?;
/// assert!(files.mtl.ends_with("part.mtl") && files.png.is_file());
/// assert_eq!(sl_mesh::read_obj(&files.obj)?, mesh);
/// # std::fs::remove_dir_all(&dir).ok();
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
#[cfg(feature = "image-files")]
pub fn write_obj_textured(
    path: &Path,
    mesh: &TriangleMesh,
    atlas: &TextureAtlas,
) -> Result<TexturedObjFiles, MeshError> {
    let is_obj = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned());
    let (true, Some(name)) = (is_obj, name) else {
        return Err(MeshError::invalid(
            "path",
            path.display(),
            "a textured OBJ's path must end in .obj (its .mtl and .png go beside it)",
        ));
    };
    let text = textured_obj_to_strings(mesh, atlas, &name)?;
    let files = TexturedObjFiles {
        obj: path.to_path_buf(),
        mtl: path.with_extension("mtl"),
        png: path.with_extension("png"),
    };
    crate::files::write_atomically(&files.png, &png_bytes(&atlas.image, &files.png)?)?;
    crate::files::write_atomically(&files.mtl, text.mtl.as_bytes())?;
    crate::files::write_atomically(&files.obj, text.obj.as_bytes())?;
    Ok(files)
}

/// The PNG of `image` (8-bit RGB); `path` names the file in errors.
#[cfg(feature = "image-files")]
fn png_bytes(image: &sl_image::ColourImage, path: &Path) -> Result<Vec<u8>, MeshError> {
    let png_error = |source| MeshError::Png {
        path: path.to_path_buf(),
        source,
    };
    let (Ok(w), Ok(h)) = (u32::try_from(image.width()), u32::try_from(image.height())) else {
        return Err(png_error(png::EncodingError::LimitsExceeded));
    };
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(png_error)?;
    writer
        .write_image_data(image.data().as_flattened())
        .map_err(png_error)?;
    writer.finish().map_err(png_error)?;
    Ok(out)
}

#[cfg(all(test, feature = "image-files"))]
mod tests {
    use super::*;
    use crate::atlas::tests::{linear_colour, mm_per_texel};
    use crate::test_shapes::sphere_mesh;
    use crate::{TextureConfig, bake_texture, read_obj};

    /// The OBJ, MTL and PNG written, read back by a parser of their own: positions exact, the
    /// texture coordinates of every face corner those of the atlas, the material naming the
    /// PNG, and the PNG's texel at each face's texture centroid the colour baked there.
    ///
    /// Tolerance of that colour, per channel: 0.5 for the 8-bit rounding, plus the colour's
    /// gradient times the distance from the centroid to the centre of the texel it falls in
    /// (at most √2 / 2 texels, times the triangle's mm per texel).
    #[test]
    fn files_read_back() {
        let mesh = sphere_mesh(10.0, 5);
        let slope = 6.0;
        let atlas = bake_texture(&mesh, &TextureConfig::default(), |p, _| {
            Some(linear_colour(p, slope).map(|c| c.round().clamp(0.0, 255.0) as u8))
        })
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let files = write_obj_textured(&dir.path().join("ball.obj"), &mesh, &atlas).unwrap();
        assert_eq!(files.png, dir.path().join("ball.png"));
        // Our own mesh reader sees the same mesh.
        assert_eq!(read_obj(&files.obj).unwrap(), mesh);
        // The OBJ, parsed here.
        let obj = std::fs::read_to_string(&files.obj).unwrap();
        let (mut v, mut vt, mut vn, mut faces) = (Vec::new(), Vec::new(), 0, Vec::new());
        let (mut mtllib, mut usemtl) = (None, None);
        for line in obj.lines() {
            let mut it = line.split_whitespace();
            let key = it.next();
            let rest: Vec<&str> = it.collect();
            match key {
                Some("mtllib") => mtllib = Some(rest.join(" ")),
                Some("usemtl") => usemtl = Some(rest.join(" ")),
                Some("v") => v.push(
                    rest.iter()
                        .map(|s| s.parse::<f64>().unwrap())
                        .collect::<Vec<_>>(),
                ),
                Some("vt") => vt.push([rest[0].parse::<f32>().unwrap(), rest[1].parse().unwrap()]),
                Some("vn") => vn += 1,
                Some("f") => faces.push(
                    rest.iter()
                        .map(|c| {
                            let ix: Vec<usize> = c.split('/').map(|s| s.parse().unwrap()).collect();
                            [ix[0] - 1, ix[1] - 1, ix[2] - 1]
                        })
                        .collect::<Vec<_>>(),
                ),
                _ => {}
            }
        }
        assert_eq!(mtllib.as_deref(), Some("ball.mtl"));
        assert_eq!(v.len(), mesh.vertices.len());
        for (p, q) in mesh.vertices.iter().zip(&v) {
            assert_eq!(&[p.x, p.y, p.z][..], &q[..]);
        }
        assert_eq!(vn, mesh.vertices.len());
        assert_eq!(faces.len(), mesh.triangles.len());
        // The MTL: the material the OBJ uses, its diffuse map.
        let mtl = std::fs::read_to_string(dir.path().join(mtllib.unwrap())).unwrap();
        let material = format!("newmtl {}", usemtl.unwrap());
        assert!(mtl.lines().any(|l| l == material), "{mtl}");
        let map = mtl.lines().find_map(|l| l.strip_prefix("map_Kd ")).unwrap();
        let png = image::open(dir.path().join(map)).unwrap().to_rgb8();
        let (w, h) = png.dimensions();
        assert_eq!(
            (w as usize, h as usize),
            (atlas.image.width(), atlas.image.height())
        );
        for (t, (face, tri)) in faces.iter().zip(&mesh.triangles).enumerate() {
            let mut centroid = nalgebra::Vector3::zeros();
            let mut uv = [0.0f64; 2];
            for (k, corner) in face.iter().enumerate() {
                assert_eq!(corner[0], tri[k] as usize);
                assert_eq!(corner[2], tri[k] as usize);
                assert_eq!(vt[corner[1]], atlas.uv[t][k]);
                centroid += mesh.vertices[tri[k] as usize].coords / 3.0;
                uv[0] += f64::from(vt[corner[1]][0]) / 3.0;
                uv[1] += f64::from(vt[corner[1]][1]) / 3.0;
            }
            let (x, y) = (
                (uv[0] * f64::from(w)) as u32,
                ((1.0 - uv[1]) * f64::from(h)) as u32,
            );
            let got = png.get_pixel(x, y).0;
            assert_eq!(Some(got), atlas.image.get(x as usize, y as usize));
            let want = linear_colour(&centroid.into(), slope);
            let tol = 0.5 + slope * 0.5f64.sqrt() * mm_per_texel(&mesh, &atlas, t) + 0.01;
            for k in 0..3 {
                assert!(
                    (f64::from(got[k]) - want[k]).abs() <= tol,
                    "face {t}: {got:?} vs {want:?} (tolerance {tol})"
                );
            }
        }
    }

    /// Bad paths, names and atlases are refused, naming what is wrong; a folder that does not
    /// exist is named in the error.
    #[test]
    fn bad_requests_are_named() {
        let mesh = sphere_mesh(5.0, 4);
        let atlas = bake_texture(&mesh, &TextureConfig::default(), |_, _| Some([9; 3])).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let e = write_obj_textured(&dir.path().join("ball.ply"), &mesh, &atlas).unwrap_err();
        assert!(e.to_string().contains("ball.ply"), "{e}");
        let e = write_obj_textured(&dir.path().join("my ball.obj"), &mesh, &atlas).unwrap_err();
        assert!(e.to_string().contains("my ball"), "{e}");
        let mut short = atlas.clone();
        short.uv.pop();
        let e = write_obj_textured(&dir.path().join("ball.obj"), &mesh, &short).unwrap_err();
        assert!(
            matches!(
                e,
                MeshError::AttributeLength {
                    of: "triangles",
                    ..
                }
            ),
            "{e}"
        );
        let e = write_obj_textured(&dir.path().join("no/ball.obj"), &mesh, &atlas).unwrap_err();
        assert!(
            matches!(e, MeshError::Io { .. }) && e.to_string().contains("ball.png"),
            "{e}"
        );
        assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none());
    }
}
