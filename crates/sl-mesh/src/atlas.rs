//! Texture atlas of a mesh by a trivial per-triangle parametrisation (as MeshLab's "Trivial
//! Per-Triangle Parametrization"): every triangle gets its own right isosceles triangle of
//! texels, two to a square cell, the cells in a grid.
//!
//! # Layout
//!
//! A cell is `s = L + 4` texels square, `L` the length in texels of the two short sides
//! ([`TextureAtlas::texels_per_edge`]). In the cell's texel coordinates (x right, y down, texel
//! `(i, j)` covering `[i, i + 1) × [j, j + 1)`, centre at `+ 0.5`), the first triangle of the
//! cell has its right angle at `(1.5, 1.5)` and its short sides along +x and +y; the second has
//! its right angle at `(s − 0.5, s − 0.5)` and its short sides along −x and −y. Every corner sits
//! on a texel centre. The first triangle owns the texels with `i + j ≤ s`, the second the
//! others.
//!
//! No texel is touched by two triangles: the first touches those with `i, j ≥ 1` and
//! `i + j ≤ s − 1`, the second those with `i, j ≤ s − 1` and `i + j ≥ s + 1`, so a gutter of
//! one texel (column and row 0 of the cell, and the diagonal `i + j = s`) separates every
//! triangle from every other. Bilinear filtering at a point reads the four texels whose centres
//! are less than one texel away from it along x and along y: the first triangle's points
//! (`x, y ≥ 1.5`, `x + y ≤ s − 1`) read texels with `i, j ≥ 1` and `i + j < s`, the second's
//! (`x, y ≤ s − 0.5`, `x + y ≥ s + 3`) texels with `i, j ≤ s − 1` and `i + j > s`: each
//! triangle reads only texels it owns, and no colour of another triangle can bleed in.
//! (Mipmaps average larger blocks and do bleed at coarse levels; the atlas is meant for
//! magnified or one-to-one viewing.)
//!
//! Every texel a triangle owns is coloured: its centre is moved to the nearest point of the
//! triangle (itself when inside) and mapped to 3-D by barycentric coordinates, where the colour
//! is sampled. The gutter is so filled by the colours of the triangle's rim, the dilation of the
//! triangle. Texels whose sample is unknown take the colour of the nearest texel of the same
//! triangle whose sample is known (nearest in steps of one texel, diagonals included), or
//! [`UNKNOWN_COLOUR`] when the triangle has none.

use std::collections::VecDeque;

use nalgebra::{Point2, Point3, Vector2, Vector3};
use rayon::prelude::*;
use sl_cloud::TriangleMesh;
use sl_image::ColourImage;

use crate::MeshError;
use crate::adjacency::check_indices;
use crate::measure::{triangle_normal, vertex_normals};

/// Texels of a cell beyond the triangles' short sides: one-texel gutters at the cell's sides
/// (the first triangle starts at 1.5, the second ends at `s − 0.5`) plus a diagonal gap of two
/// texels (along x) between the two hypotenuses. See the module's layout.
const CELL_MARGIN: u32 = 4;

/// Largest [`TextureConfig::max_side`]: 16384 texels is the largest texture today's graphics
/// cards take (and 805 MB of RGB).
pub const MAX_TEXTURE_SIDE: u32 = 16384;

/// Colour of texels no sample of their triangle knows: mid grey, the colour that reads as
/// "no data" without looking like a measured dark or bright surface.
pub const UNKNOWN_COLOUR: [u8; 3] = [128, 128, 128];

/// Options of [`bake_texture`].
#[derive(Debug, Clone, PartialEq)]
pub struct TextureConfig {
    /// Wanted length, in texels, of the two short sides of each triangle's place in the atlas
    /// (its long side is √2 times this). Lowered when the atlas would exceed `max_side`.
    pub texels_per_edge: u32,
    /// Largest width or height of the atlas image, in texels: 4096 is the texture size every
    /// WebGL implementation and 3-D program accepts.
    pub max_side: u32,
}

impl Default for TextureConfig {
    fn default() -> Self {
        Self {
            // A scanner's triangles are 0.3–1 mm and its camera pixels 0.05–0.2 mm: 8 texels
            // per edge keeps most of the camera's detail; a 100k-triangle mesh gets a
            // 2688 × 2688 atlas.
            texels_per_edge: 8,
            max_side: 4096,
        }
    }
}

/// A texture image and the texture coordinates of every triangle corner: the result of
/// [`bake_texture`].
#[derive(Debug, Clone, PartialEq)]
pub struct TextureAtlas {
    /// The texture, row 0 at the top.
    pub image: ColourImage,
    /// Texture coordinates `[u, v]` of the corners of each triangle, in the mesh's triangle and
    /// corner order, in OBJ's convention: `u` from 0 at the left edge of the image to 1 at the
    /// right edge, `v` from 0 at the bottom edge to 1 at the top edge. Every corner sits on a
    /// texel centre.
    pub uv: Vec<[[f32; 2]; 3]>,
    /// Length in texels of the short sides of each triangle's place (the configured one, or
    /// less to fit [`TextureConfig::max_side`]).
    pub texels_per_edge: u32,
    /// Texels whose sample was unknown (`None`), filled from their triangle's known texels.
    pub unknown_texels: usize,
}

/// Placement of the cells in the image.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Layout {
    /// Short side of a triangle, texels.
    leg: u32,
    /// Side of a cell, texels.
    cell: u32,
    /// Cells per row of the image.
    cols: u32,
    /// Rows of cells.
    rows: u32,
}

impl Layout {
    fn new(triangles: usize, cfg: &TextureConfig) -> Result<Self, MeshError> {
        if cfg.texels_per_edge == 0 {
            return Err(MeshError::invalid(
                "TextureConfig::texels_per_edge",
                0,
                "must be at least 1",
            ));
        }
        if cfg.max_side > MAX_TEXTURE_SIDE {
            return Err(MeshError::invalid(
                "TextureConfig::max_side",
                cfg.max_side,
                "at most 16384: no graphics card takes larger textures",
            ));
        }
        if triangles == 0 {
            return Err(MeshError::InvalidMesh(
                "a mesh without triangles has no texture to bake".into(),
            ));
        }
        let pairs = triangles.div_ceil(2) as u64;
        let mut cols = (pairs as f64).sqrt().ceil() as u64;
        while cols * cols < pairs {
            cols += 1;
        }
        let rows = pairs.div_ceil(cols);
        // The widest cell that fits, and the wanted one.
        let fit = u64::from(cfg.max_side) / cols;
        let cell = fit.min(u64::from(cfg.texels_per_edge) + u64::from(CELL_MARGIN));
        if cell < u64::from(CELL_MARGIN) + 1 {
            return Err(MeshError::invalid(
                "TextureConfig::max_side",
                cfg.max_side,
                "too small for the mesh: each pair of triangles needs a cell of 5 x 5 texels",
            ));
        }
        let cell = cell as u32;
        Ok(Self {
            leg: cell - CELL_MARGIN,
            cell,
            cols: cols as u32,
            rows: rows as u32,
        })
    }

    fn width(&self) -> usize {
        self.cols as usize * self.cell as usize
    }

    fn height(&self) -> usize {
        self.rows as usize * self.cell as usize
    }

    /// Corners of the right angle and the ends of the two short sides, in the cell's texel
    /// coordinates, of the first (`half = 0`) or second triangle of a cell.
    fn corners(&self, half: usize) -> [Point2<f64>; 3] {
        let (leg, s) = (f64::from(self.leg), f64::from(self.cell));
        if half == 0 {
            let r = Point2::new(1.5, 1.5);
            // Right angle, +y, +x: counter-clockwise once v points up.
            [r, r + Vector2::new(0.0, leg), r + Vector2::new(leg, 0.0)]
        } else {
            let r = Point2::new(s - 0.5, s - 0.5);
            [r, r - Vector2::new(0.0, leg), r - Vector2::new(leg, 0.0)]
        }
    }
}

/// The corner of triangle `t` put at the right angle: the one of the largest angle (opposite
/// the longest side), so the affine map to 3-D is as little sheared as a right isosceles
/// triangle allows.
fn right_angle_corner(p: &[Point3<f64>; 3]) -> usize {
    let opposite = |k: usize| (p[(k + 1) % 3] - p[(k + 2) % 3]).norm_squared();
    (0..3)
        .max_by(|&a, &b| opposite(a).total_cmp(&opposite(b)))
        .unwrap_or(0)
}

/// Barycentric coordinates of the point of the 2-D triangle `c` nearest to `q`.
fn nearest_barycentric(c: &[Point2<f64>; 3], q: &Point2<f64>) -> [f64; 3] {
    let (e1, e2, d) = (c[1] - c[0], c[2] - c[0], q - c[0]);
    let det = e1.x * e2.y - e1.y * e2.x;
    if det != 0.0 {
        let b1 = (d.x * e2.y - d.y * e2.x) / det;
        let b2 = (e1.x * d.y - e1.y * d.x) / det;
        if b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 {
            return [1.0 - b1 - b2, b1, b2];
        }
    }
    // Outside: the nearest point of the nearest side.
    let mut best = (f64::INFINITY, [1.0, 0.0, 0.0]);
    for k in 0..3 {
        let (a, b) = (c[k], c[(k + 1) % 3]);
        let ab = b - a;
        let t = ((q - a).dot(&ab) / ab.norm_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        let dist = (a + ab * t - q).norm_squared();
        if dist < best.0 {
            let mut w = [0.0; 3];
            w[k] = 1.0 - t;
            w[(k + 1) % 3] = t;
            best = (dist, w);
        }
    }
    best.1
}

/// Bakes the colour of the surface of `mesh` into a texture atlas: `sample(point, normal)`
/// gives the colour at a point of the surface with its unit normal (interpolated from the
/// vertex normals), or `None` where the colour is unknown. See the module's layout; sampled on
/// the global rayon pool, one row of cells per task.
///
/// # Errors
/// [`MeshError::InvalidMesh`] for a triangle index out of range or a mesh without triangles,
/// [`MeshError::InvalidParameter`] for zero `texels_per_edge` or a `max_side` too small to give
/// every triangle a place.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// use sl_mesh::{TextureConfig, bake_texture};
/// let mesh = TriangleMesh {
///     vertices: vec![Point3::origin(), Point3::new(10.0, 0.0, 0.0), Point3::new(0.0, 10.0, 0.0)],
///     triangles: vec![[0, 1, 2]],
/// };
/// // Red grows along x; nothing is known below y = 1.
/// let atlas = bake_texture(&mesh, &TextureConfig::default(), |p, _normal| {
///     (p.y >= 1.0).then(|| [(25.0 * p.x) as u8, 0, 0])
/// })?;
/// assert_eq!(atlas.uv.len(), 1);
/// assert!(atlas.unknown_texels > 0);
/// // The texel at vertex 1's texture coordinates is red (x = 10), taken from the texels
/// // above it.
/// let [u, v] = atlas.uv[0][1];
/// let (x, y) = ((u * atlas.image.width() as f32) as usize, ((1.0 - v) * atlas.image.height() as f32) as usize);
/// assert!(atlas.image.get(x, y).is_some_and(|c| c[0] > 200));
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn bake_texture(
    mesh: &TriangleMesh,
    cfg: &TextureConfig,
    sample: impl Fn(&Point3<f64>, &Vector3<f64>) -> Option<[u8; 3]> + Sync,
) -> Result<TextureAtlas, MeshError> {
    check_indices(mesh)?;
    let layout = Layout::new(mesh.triangles.len(), cfg)?;
    let (width, height) = (layout.width(), layout.height());
    let cell = layout.cell as usize;
    let normals = vertex_normals(mesh);
    // The right-angle corner of each triangle, and its texture coordinates.
    let first: Vec<usize> = mesh
        .triangles
        .iter()
        .map(|t| right_angle_corner(&t.map(|i| mesh.vertices[i as usize])))
        .collect();
    let uv = first
        .iter()
        .enumerate()
        .map(|(t, &r)| {
            let (col, row) = (
                (t / 2) % layout.cols as usize,
                (t / 2) / layout.cols as usize,
            );
            let origin = Vector2::new((col * cell) as f64, (row * cell) as f64);
            let local = layout.corners(t % 2);
            let mut out = [[0.0f32; 2]; 3];
            for (k, c) in local.iter().enumerate() {
                let q = c + origin;
                out[(r + k) % 3] = [
                    (q.x / width as f64) as f32,
                    (1.0 - q.y / height as f64) as f32,
                ];
            }
            out
        })
        .collect();
    let mut data = vec![UNKNOWN_COLOUR; width * height];
    let unknown_texels = data
        .par_chunks_mut(width * cell)
        .enumerate()
        .map(|(row, band)| {
            let mut unknown = 0;
            let mut grid: Vec<Option<[u8; 3]>> = vec![None; cell * cell];
            let mut queue = VecDeque::new();
            for col in 0..layout.cols as usize {
                for half in 0..2 {
                    let t = 2 * (row * layout.cols as usize + col) + half;
                    let Some(tri) = mesh.triangles.get(t) else {
                        continue;
                    };
                    let owns = |i: usize, j: usize| (i + j <= cell) == (half == 0);
                    let local = layout.corners(half);
                    let r = first[t];
                    let corner = |k: usize| tri[(r + k) % 3] as usize;
                    let p = [0, 1, 2].map(|k| mesh.vertices[corner(k)]);
                    let n = [0, 1, 2].map(|k| normals[corner(k)]);
                    let face = triangle_normal(&mesh.vertices, tri);
                    let mut missing = 0;
                    for j in 0..cell {
                        for i in (0..cell).filter(|&i| owns(i, j)) {
                            let q = Point2::new(i as f64 + 0.5, j as f64 + 0.5);
                            let b = nearest_barycentric(&local, &q);
                            let point = Point3::from(
                                p[0].coords * b[0] + p[1].coords * b[1] + p[2].coords * b[2],
                            );
                            let normal = n[0] * b[0] + n[1] * b[1] + n[2] * b[2];
                            let normal = if normal.norm() > 0.0 {
                                normal.normalize()
                            } else if face.norm() > 0.0 {
                                face.normalize()
                            } else {
                                normal
                            };
                            let colour = sample(&point, &normal);
                            grid[j * cell + i] = colour;
                            if colour.is_some() {
                                queue.push_back((i, j));
                            } else {
                                missing += 1;
                            }
                        }
                    }
                    // Unknown texels take the colour of the nearest known one, in steps of one
                    // texel (diagonals included): a breadth-first flood from all known texels,
                    // linear in the texels of the triangle.
                    while let Some((i, j)) = queue.pop_front() {
                        let colour = grid[j * cell + i];
                        for (di, dj) in NEIGHBOURS {
                            let (Some(a), Some(b)) =
                                (i.checked_add_signed(di), j.checked_add_signed(dj))
                            else {
                                continue;
                            };
                            if a < cell && b < cell && owns(a, b) && grid[b * cell + a].is_none() {
                                grid[b * cell + a] = colour;
                                queue.push_back((a, b));
                            }
                        }
                    }
                    unknown += missing;
                    for j in 0..cell {
                        for i in (0..cell).filter(|&i| owns(i, j)) {
                            let texel = &mut grid[j * cell + i];
                            band[j * width + col * cell + i] =
                                texel.take().unwrap_or(UNKNOWN_COLOUR);
                        }
                    }
                }
            }
            unknown
        })
        .sum();
    Ok(TextureAtlas {
        image: ColourImage::new(width, height, data)?,
        uv,
        texels_per_edge: layout.leg,
        unknown_texels,
    })
}

/// The eight neighbours of a texel.
const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::test_shapes::{cube_mesh, sphere_mesh};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// Bilinear lookup at `uv` (OBJ convention), texel centres at `+ 0.5`, clamped at the
    /// image's edges, as OpenGL's `LINEAR` with `CLAMP_TO_EDGE`.
    pub(crate) fn bilinear(image: &ColourImage, uv: [f64; 2]) -> [f64; 3] {
        let (w, h) = (image.width(), image.height());
        let x = uv[0] * w as f64 - 0.5;
        let y = (1.0 - uv[1]) * h as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |dx: f64, dy: f64| {
            let xi = (x0 + dx).clamp(0.0, (w - 1) as f64) as usize;
            let yi = (y0 + dy).clamp(0.0, (h - 1) as f64) as usize;
            image.data()[yi * w + xi].map(f64::from)
        };
        let mut out = [0.0; 3];
        for (dx, dy, wgt) in [
            (0.0, 0.0, (1.0 - fx) * (1.0 - fy)),
            (1.0, 0.0, fx * (1.0 - fy)),
            (0.0, 1.0, (1.0 - fx) * fy),
            (1.0, 1.0, fx * fy),
        ] {
            // A texel of zero weight is not read (it may belong to another triangle).
            if wgt > 0.0 {
                let c = texel(dx, dy);
                for k in 0..3 {
                    out[k] += wgt * c[k];
                }
            }
        }
        out
    }

    /// A random point of triangle `t` by barycentric weights (corners and sides included),
    /// and its texture coordinates by the same weights.
    fn random_point(
        mesh: &TriangleMesh,
        atlas: &TextureAtlas,
        t: usize,
        rng: &mut Pcg64,
    ) -> (Point3<f64>, [f64; 2]) {
        let mut b = [
            rng.random::<f64>(),
            rng.random::<f64>(),
            rng.random::<f64>(),
        ];
        // One point in eight on a side, one in sixteen on a corner: where bleeding shows.
        match rng.random_range(0..16) {
            0 => b = [1.0, 0.0, 0.0],
            1 | 2 => b[rng.random_range(0..3)] = 0.0,
            _ => {}
        }
        let s: f64 = b.iter().sum();
        let b = b.map(|x| x / s);
        let tri = mesh.triangles[t];
        let p = (0..3).fold(Vector3::zeros(), |acc, k| {
            acc + mesh.vertices[tri[k] as usize].coords * b[k]
        });
        let uv = (0..3).fold([0.0; 2], |acc, k| {
            [
                acc[0] + f64::from(atlas.uv[t][k][0]) * b[k],
                acc[1] + f64::from(atlas.uv[t][k][1]) * b[k],
            ]
        });
        (Point3::from(p), uv)
    }

    /// Colour as a linear function of position: grey 128 at the origin, ±`slope` per mm.
    pub(crate) fn linear_colour(p: &Point3<f64>, slope: f64) -> [f64; 3] {
        [
            128.0 + slope * p.x,
            128.0 + slope * p.y,
            128.0 - slope * (p.x + p.z) * 0.5,
        ]
    }

    /// Largest distance in 3-D, in mm, that one texel spans on triangle `t` (the norm of the
    /// texel-to-surface map's Jacobian, bounded by its Frobenius norm).
    pub(crate) fn mm_per_texel(mesh: &TriangleMesh, atlas: &TextureAtlas, t: usize) -> f64 {
        let tri = mesh.triangles[t];
        let (w, h) = (atlas.image.width() as f64, atlas.image.height() as f64);
        let q = |k: usize| {
            Vector2::new(
                f64::from(atlas.uv[t][k][0]) * w,
                f64::from(atlas.uv[t][k][1]) * h,
            )
        };
        let p = |k: usize| mesh.vertices[tri[k] as usize];
        let (a, b) = (q(1) - q(0), q(2) - q(0));
        let det = a.x * b.y - a.y * b.x;
        // J [a b] = [p1 - p0, p2 - p0]  →  J = [p1 - p0, p2 - p0] [a b]^-1.
        let inv = nalgebra::Matrix2::new(b.y, -b.x, -a.y, a.x) / det;
        let e = nalgebra::Matrix3x2::from_columns(&[p(1) - p(0), p(2) - p(0)]);
        (e * inv).norm()
    }

    /// A linear colour baked on a sphere and on a cube is found again at random points of
    /// random triangles, through their texture coordinates and bilinear filtering.
    ///
    /// Tolerance, per channel: 0.5 for the rounding of the texels to 8 bits, plus, for the
    /// texels of the gutter (sampled at the triangle's nearest point instead of the affine
    /// extension of the colour), the colour's gradient times the √2 texels a gutter centre may
    /// be from the triangle times the triangle's mm per texel; 0.01 for float rounding.
    #[test]
    fn linear_colour_comes_back_through_the_uvs() {
        for (name, mesh) in [
            ("sphere", sphere_mesh(10.0, 5)),
            ("cube", cube_mesh(8.0, 3)),
        ] {
            let slope = 6.0;
            let atlas = bake_texture(&mesh, &TextureConfig::default(), |p, _| {
                Some(linear_colour(p, slope).map(|c| c.round().clamp(0.0, 255.0) as u8))
            })
            .unwrap();
            assert_eq!(atlas.unknown_texels, 0);
            assert_eq!(atlas.texels_per_edge, 8);
            assert_eq!(atlas.uv.len(), mesh.triangles.len());
            // The steepest channel (red, green) changes by `slope` per mm.
            let gradient = slope;
            let mut rng = Pcg64::seed_from_u64(7);
            let mut worst = 0.0f64;
            for _ in 0..5000 {
                let t = rng.random_range(0..mesh.triangles.len());
                let (p, uv) = random_point(&mesh, &atlas, t, &mut rng);
                let got = bilinear(&atlas.image, uv);
                let want = linear_colour(&p, slope);
                let tol = 0.5 + gradient * 2f64.sqrt() * mm_per_texel(&mesh, &atlas, t) + 0.01;
                let err = (0..3).map(|k| (got[k] - want[k]).abs()).fold(0.0, f64::max);
                assert!(
                    err <= tol,
                    "{name}: triangle {t}, {p}: {got:?} vs {want:?} (tolerance {tol})"
                );
                worst = worst.max(err / tol);
            }
            println!("{name}: worst error {worst:.2} of the tolerance");
        }
    }

    /// A triangle soup where every triangle has its own colour: bilinear lookups anywhere in a
    /// triangle, its sides and corners included, read that colour: the gutters let no other
    /// triangle's colour in. Tolerance 0.01 of a level: the texture coordinates are `f32`, off
    /// by up to 2⁻²⁴ of the image's side (a few millionths of a texel here), which can give a
    /// texel at exactly one texel's distance (another triangle's) that weight; a missing gutter
    /// would let in weights up to one half.
    #[test]
    fn gutters_do_not_leak() {
        let mut rng = Pcg64::seed_from_u64(3);
        let mut mesh = TriangleMesh::default();
        let count = 301;
        for k in 0..count {
            // Triangle k lies within 1 mm of (10 k, 0, 0): far from every other one. Slivers
            // and needles included.
            let c = Vector3::new(10.0 * k as f64, 0.0, 0.0);
            for _ in 0..3 {
                let d = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * 0.5;
                mesh.vertices.push(Point3::from(c + d));
            }
            let i = 3 * k as u32;
            mesh.triangles.push([i, i + 1, i + 2]);
        }
        let palette = |k: usize| [(k * 37 % 256) as u8, (k * 101 % 256) as u8, (k * 13) as u8];
        let owner = |p: &Point3<f64>| (p.x / 10.0).round() as usize;
        for texels_per_edge in [1, 2, 5, 8] {
            let cfg = TextureConfig {
                texels_per_edge,
                ..TextureConfig::default()
            };
            let atlas = bake_texture(&mesh, &cfg, |p, _| Some(palette(owner(p)))).unwrap();
            for _ in 0..20_000 {
                let t = rng.random_range(0..count);
                let (_, uv) = random_point(&mesh, &atlas, t, &mut rng);
                let got = bilinear(&atlas.image, uv);
                let want = palette(t).map(f64::from);
                for k in 0..3 {
                    assert!(
                        (got[k] - want[k]).abs() < 0.01,
                        "{texels_per_edge} texels: triangle {t} at {uv:?}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }

    /// Unknown samples take the nearest known colour of the same triangle; a triangle with no
    /// known sample is grey; the texel size shrinks to fit `max_side`; bad parameters are named.
    #[test]
    fn unknown_colours_and_limits() {
        let mesh = cube_mesh(5.0, 2);
        // Known only on the +x face, red; unknown elsewhere.
        let atlas = bake_texture(&mesh, &TextureConfig::default(), |p, _| {
            (p.x > 4.999).then_some([255, 0, 0])
        })
        .unwrap();
        assert!(atlas.unknown_texels > 0);
        let mut rng = Pcg64::seed_from_u64(5);
        for t in 0..mesh.triangles.len() {
            let on_face = mesh.triangles[t]
                .iter()
                .all(|&i| mesh.vertices[i as usize].x > 4.999);
            let touches = mesh.triangles[t]
                .iter()
                .any(|&i| mesh.vertices[i as usize].x > 4.999);
            for _ in 0..50 {
                let (_, uv) = random_point(&mesh, &atlas, t, &mut rng);
                let got = bilinear(&atlas.image, uv);
                // Known along a side or at a corner (a texel centre sits on every corner):
                // the red fills the triangle. Known nowhere: grey.
                let want = if touches {
                    [255.0, 0.0, 0.0]
                } else {
                    [128.0; 3]
                };
                assert!(
                    (0..3).all(|k| (got[k] - want[k]).abs() < 0.01),
                    "{t} (on the face: {on_face}): {got:?}"
                );
            }
        }
        // 48 triangles: 24 cells in a 5 x 5 grid; at most 60 texels a side: cells of 12.
        let cfg = TextureConfig {
            texels_per_edge: 50,
            max_side: 60,
        };
        let atlas = bake_texture(&mesh, &cfg, |_, _| Some([1, 2, 3])).unwrap();
        assert_eq!(atlas.texels_per_edge, 8);
        assert_eq!((atlas.image.width(), atlas.image.height()), (60, 60));
        let small = TextureConfig {
            texels_per_edge: 8,
            max_side: 20,
        };
        let e = bake_texture(&mesh, &small, |_, _| None).unwrap_err();
        assert!(e.to_string().contains("max_side"), "{e}");
        let zero = TextureConfig {
            texels_per_edge: 0,
            ..TextureConfig::default()
        };
        let e = bake_texture(&mesh, &zero, |_, _| None).unwrap_err();
        assert!(e.to_string().contains("texels_per_edge"), "{e}");
        let e = bake_texture(&TriangleMesh::default(), &cfg, |_, _| None).unwrap_err();
        assert!(matches!(e, MeshError::InvalidMesh(_)), "{e}");
        let huge = TextureConfig {
            texels_per_edge: 8,
            max_side: MAX_TEXTURE_SIDE + 1,
        };
        let e = bake_texture(&mesh, &huge, |_, _| None).unwrap_err();
        assert!(e.to_string().contains("16384"), "{e}");
        // One big triangle known on a corner only (a few texels of 2 million): the flood fills
        // it all with that corner's colour, in linear time.
        let one = TriangleMesh {
            vertices: vec![
                Point3::origin(),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2]],
        };
        let big = TextureConfig {
            texels_per_edge: 2000,
            max_side: 4096,
        };
        let atlas = bake_texture(&one, &big, |p, _| {
            (p.coords.norm() < 1e-3).then_some([10, 20, 30])
        })
        .unwrap();
        assert_eq!(atlas.texels_per_edge, 2000);
        for _ in 0..100 {
            let (_, uv) = random_point(&one, &atlas, 0, &mut rng);
            let got = bilinear(&atlas.image, uv);
            assert!(
                (0..3).all(|k| (got[k] - [10.0, 20.0, 30.0][k]).abs() < 1e-9),
                "{got:?}"
            );
        }
    }

    /// The normal handed to the sampler is the interpolated vertex normal: on a sphere centred
    /// at the origin it points along the position.
    #[test]
    fn sampler_gets_unit_normals() {
        let mesh = sphere_mesh(10.0, 4);
        let worst = std::sync::Mutex::new(0.0f64);
        bake_texture(&mesh, &TextureConfig::default(), |p, n| {
            let mut w = worst.lock().unwrap();
            *w = w.max((n.norm() - 1.0).abs() + (1.0 - n.dot(&p.coords.normalize())));
            Some([0; 3])
        })
        .unwrap();
        let w = *worst.lock().unwrap();
        assert!(w < 0.05, "{w}");
    }
}
