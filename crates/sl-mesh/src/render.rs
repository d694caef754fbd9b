//! A shaded picture of a mesh (z-buffered triangles, Lambertian head light), framed and
//! oriented as `sl_cloud`'s point-cloud previews so the two can be set side by side.

use nalgebra::{Rotation3, Vector3};
use sl_cloud::{PreviewConfig, PreviewImage, TriangleMesh, colormap};

use crate::MeshError;
use crate::adjacency::check_indices;
use crate::measure::vertex_normals;

/// Background colour: the one of `sl_cloud`'s previews (a dark grey).
const BACKGROUND: [u8; 3] = [30, 30, 34];
/// Base colour of an uncoloured mesh (light grey, as MeshLab shows meshes).
const GREY: [f64; 3] = [0.82, 0.82, 0.82];
/// Share of light independent of orientation (as `sl_cloud`'s previews).
const AMBIENT: f64 = 0.2;
/// Fraction of the smaller image side left as margin on each side.
const MARGIN: f64 = 0.05;

/// How [`render_mesh`] colours the surface.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum MeshColoring<'a> {
    /// Uniform light grey, shaded.
    #[default]
    Grey,
    /// One scalar per vertex through `sl_cloud::colormap` over `[min, max]` (blue to red),
    /// interpolated over the triangles; NaN is drawn grey.
    Scalar {
        /// One value per vertex.
        values: &'a [f32],
        /// Value drawn blue.
        min: f32,
        /// Value drawn red.
        max: f32,
    },
}

/// Renders `mesh` orthographically from the direction in `config` (azimuth about the y axis,
/// elevation; `point_radius_px` is unused), fitted to the picture, smooth-shaded with
/// per-vertex normals and lit from the viewer's side.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for an empty picture or values not one per vertex;
/// [`MeshError::InvalidMesh`] for a triangle index out of range.
///
/// ```
/// use sl_cloud::PreviewConfig;
/// use sl_mesh::{MeshColoring, render_mesh};
/// # let mesh = sl_cloud::TriangleMesh::default();
/// let cfg = PreviewConfig { width: 64, height: 48, ..PreviewConfig::default() };
/// let img = render_mesh(&mesh, MeshColoring::Grey, &cfg)?;
/// assert_eq!(img.rgb.len(), 64 * 48 * 3);
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn render_mesh(
    mesh: &TriangleMesh,
    coloring: MeshColoring<'_>,
    config: &PreviewConfig,
) -> Result<PreviewImage, MeshError> {
    if config.width == 0 || config.height == 0 {
        return Err(MeshError::invalid(
            "PreviewConfig::width/height",
            format!("{}x{}", config.width, config.height),
            "the picture needs at least one pixel",
        ));
    }
    if let MeshColoring::Scalar { values, .. } = coloring
        && values.len() != mesh.vertices.len()
    {
        return Err(MeshError::invalid(
            "MeshColoring::Scalar::values",
            values.len(),
            "must hold one value per vertex",
        ));
    }
    check_indices(mesh)?;
    let (w, h) = (config.width as usize, config.height as usize);
    let mut rgb = vec![0u8; w * h * 3];
    for px in rgb.chunks_exact_mut(3) {
        px.copy_from_slice(&BACKGROUND);
    }
    let finite: Vec<_> = mesh
        .vertices
        .iter()
        .filter(|p| p.coords.iter().all(|c| c.is_finite()))
        .collect();
    let Some(first) = finite.first() else {
        return Ok(PreviewImage {
            width: config.width,
            height: config.height,
            rgb,
            left_out: 0,
        });
    };
    let (mut lo, mut hi) = (**first, **first);
    for p in &finite {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let centre = nalgebra::center(&lo, &hi);
    let radius = ((hi - lo).norm() * 0.5).max(f64::MIN_POSITIVE);
    let view = Rotation3::from_axis_angle(&Vector3::x_axis(), config.elevation_deg.to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), config.azimuth_deg.to_radians());
    let scale = (w.min(h) as f64) * (0.5 - MARGIN) / radius;
    let screen: Vec<[f64; 3]> = mesh
        .vertices
        .iter()
        .map(|p| {
            let q = view * (p - centre);
            [
                w as f64 * 0.5 + scale * q.x,
                h as f64 * 0.5 + scale * q.y,
                q.z,
            ]
        })
        .collect();
    let normals: Vec<Vector3<f64>> = vertex_normals(mesh).iter().map(|n| view * n).collect();
    let light = Vector3::new(-0.3, -0.5, -1.0).normalize();
    let base = |i: usize| -> [f64; 3] {
        match coloring {
            MeshColoring::Grey => GREY,
            MeshColoring::Scalar { values, min, max } => {
                let v = values[i];
                if v.is_nan() {
                    GREY
                } else {
                    let span = f64::from(max - min);
                    let t = if span > 0.0 {
                        f64::from(v - min) / span
                    } else {
                        0.5
                    };
                    colormap(t).map(|c| f64::from(c) / 255.0)
                }
            }
        }
    };
    let mut depth = vec![f64::INFINITY; w * h];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| screen[i as usize]);
        if ![a, b, c].iter().flatten().all(|v| v.is_finite()) {
            continue;
        }
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
        if area.abs() < 1e-12 {
            continue;
        }
        let x0 = a[0].min(b[0]).min(c[0]).floor().max(0.0) as usize;
        let x1 = (a[0].max(b[0]).max(c[0]).ceil() as i64).min(w as i64 - 1);
        let y0 = a[1].min(b[1]).min(c[1]).floor().max(0.0) as usize;
        let y1 = (a[1].max(b[1]).max(c[1]).ceil() as i64).min(h as i64 - 1);
        if x1 < 0 || y1 < 0 {
            continue;
        }
        let cols = t.map(|i| base(i as usize));
        let nrm = t.map(|i| normals[i as usize]);
        for y in y0..=y1 as usize {
            for x in x0..=x1 as usize {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let wa = ((b[0] - px) * (c[1] - py) - (c[0] - px) * (b[1] - py)) / area;
                let wb = ((c[0] - px) * (a[1] - py) - (a[0] - px) * (c[1] - py)) / area;
                let wc = 1.0 - wa - wb;
                if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                    continue;
                }
                let z = wa * a[2] + wb * b[2] + wc * c[2];
                let k = y * w + x;
                if z >= depth[k] {
                    continue;
                }
                depth[k] = z;
                let mut n = nrm[0] * wa + nrm[1] * wb + nrm[2] * wc;
                if n.norm_squared() > 0.0 {
                    n.normalize_mut();
                }
                let n = if n.z > 0.0 { -n } else { n };
                let shade = AMBIENT + (1.0 - AMBIENT) * n.dot(&light).max(0.0);
                for ch in 0..3 {
                    let v = (cols[0][ch] * wa + cols[1][ch] * wb + cols[2][ch] * wc) * shade;
                    rgb[k * 3 + ch] = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                }
            }
        }
    }
    Ok(PreviewImage {
        width: config.width,
        height: config.height,
        rgb,
        left_out: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_shapes::sphere_mesh;

    /// A sphere fills a disc of the picture: the share of non-background pixels is the disc's
    /// share (π r² over the picture, r = 0.45 of the side as framed) to a few per cent, and the
    /// centre is lit brighter than the rim.
    #[test]
    fn sphere_fills_a_disc() {
        let mesh = sphere_mesh(10.0, 5);
        let cfg = PreviewConfig {
            width: 200,
            height: 200,
            ..PreviewConfig::default()
        };
        let img = render_mesh(&mesh, MeshColoring::Grey, &cfg).unwrap();
        let lit = (0..200u32)
            .flat_map(|y| (0..200u32).map(move |x| (x, y)))
            .filter(|&(x, y)| !img.is_background(x, y))
            .count();
        // The framing radius is half the box diagonal, √3 times the sphere's radius.
        let r = 0.45 * 200.0 / 3f64.sqrt();
        let disc = std::f64::consts::PI * r * r;
        assert!((lit as f64 - disc).abs() < 0.05 * disc, "{lit} vs {disc}");
        let centre = img.pixel(100, 100).unwrap()[0];
        let rim = img.pixel(100 + (0.9 * r) as u32, 100).unwrap()[0];
        assert!(centre > rim, "{centre} vs {rim}");
        let values = vec![f32::NAN; 3];
        let e = render_mesh(
            &mesh,
            MeshColoring::Scalar {
                values: &values,
                min: 0.0,
                max: 1.0,
            },
            &cfg,
        );
        assert!(e.is_err());
    }
}
