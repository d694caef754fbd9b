//! A shaded preview render of a point cloud, so that a user sees a result without another tool.
//!
//! Orthographic splatting into a z-buffer, then Lambertian shading with a head light: from the
//! cloud's normals when it has them, otherwise from the gradient of the depth buffer. Points are
//! coloured by their own colours, by a scalar field through a colour map (error maps), or grey.

use nalgebra::{Rotation3, Vector3};

use crate::{CloudError, PointCloud};

/// Share of light that does not depend on the surface orientation: keeps surfaces that face
/// away from the head light readable instead of black.
const AMBIENT: f64 = 0.2;
/// Background colour (a dark grey, against which grey and colour-mapped clouds both read well).
const BACKGROUND: [u8; 3] = [30, 30, 34];
/// Colour of points without a colour of their own (light grey, as MeshLab and Open3D use).
const GREY: [f64; 3] = [0.82, 0.82, 0.82];
/// Fraction of the smaller image side left as margin on each side of the cloud.
const MARGIN: f64 = 0.05;

/// How the points of a preview are coloured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum PreviewColoring<'a> {
    /// Uniform light grey, shaded.
    #[default]
    Grey,
    /// The cloud's own colours, shaded (grey when the cloud has none).
    Colors,
    /// One scalar per point mapped through a blue–cyan–green–yellow–red colour map over
    /// `[min, max]` (values outside are clamped), shaded; NaN values are drawn grey.
    Scalar {
        /// One value per point.
        values: &'a [f32],
        /// Value drawn blue.
        min: f32,
        /// Value drawn red.
        max: f32,
    },
}

/// Where a preview looks from and how large it is.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewConfig {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Rotation of the view about the vertical axis (the camera frame's y axis), degrees.
    pub azimuth_deg: f64,
    /// Elevation of the view: positive looks down on the cloud from above, degrees.
    pub elevation_deg: f64,
    /// Splat radius in pixels (0 draws one pixel a point).
    pub point_radius_px: u32,
}

impl Default for PreviewConfig {
    fn default() -> Self {
        Self {
            width: 800,
            height: 600,
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            point_radius_px: 1,
        }
    }
}

/// An 8-bit RGB image, row-major, 3 bytes a pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PreviewImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 3` bytes, rows top to bottom.
    pub rgb: Vec<u8>,
}

impl PreviewImage {
    /// The colour of pixel `(x, y)`, or `None` outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        self.rgb.get(i..i + 3).map(|p| [p[0], p[1], p[2]])
    }

    /// Whether pixel `(x, y)` shows the background (no point was drawn there).
    pub fn is_background(&self, x: u32, y: u32) -> bool {
        self.pixel(x, y) == Some(BACKGROUND)
    }
}

/// Maps `t` in `[0, 1]` to blue → cyan → green → yellow → red.
pub fn colormap(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [0.10, 0.20, 0.90],
        [0.10, 0.80, 0.90],
        [0.20, 0.80, 0.20],
        [0.95, 0.85, 0.10],
        [0.90, 0.10, 0.10],
    ];
    let c = colormap_f(t, &STOPS);
    [to_u8(c[0]), to_u8(c[1]), to_u8(c[2])]
}

fn colormap_f(t: f64, stops: &[[f64; 3]; 5]) -> [f64; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (stops.len() - 1) as f64;
    let i = (x.floor() as usize).min(stops.len() - 2);
    let f = x - i as f64;
    let (a, b) = (stops[i], stops[i + 1]);
    [
        a[0] + f * (b[0] - a[0]),
        a[1] + f * (b[1] - a[1]),
        a[2] + f * (b[2] - a[2]),
    ]
}

fn to_u8(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Renders `cloud` as seen from the direction in `config`, orthographically, fitted to the image.
///
/// The camera frame convention (x right, y down, z forward) is kept: with azimuth and elevation
/// zero the preview looks along +z, as the scanner's camera does, so a scan's preview shows what
/// the camera saw.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{render_preview, PointCloud, PreviewColoring, PreviewConfig};
/// let pts = (0..400).map(|i| Point3::new((i % 20) as f64, (i / 20) as f64, 100.0)).collect();
/// let config = PreviewConfig { width: 64, height: 64, ..PreviewConfig::default() };
/// let img = render_preview(&PointCloud::from_positions(pts), PreviewColoring::Grey, &config)?;
/// assert!(!img.is_background(32, 32));
/// assert!(img.is_background(0, 0));
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
///
/// # Errors
/// [`CloudError::InvalidParameter`] for a zero image size or a scalar field whose length is not
/// the number of points. A cloud without finite points renders as background only.
pub fn render_preview(
    cloud: &PointCloud,
    coloring: PreviewColoring<'_>,
    config: &PreviewConfig,
) -> Result<PreviewImage, CloudError> {
    let (w, h) = (config.width as usize, config.height as usize);
    if w == 0 || h == 0 {
        return Err(CloudError::invalid(
            "PreviewConfig::width/height",
            format!("{}x{}", config.width, config.height),
            "the preview needs at least one pixel",
        ));
    }
    if let PreviewColoring::Scalar { values, .. } = coloring
        && values.len() != cloud.len()
    {
        return Err(CloudError::invalid(
            "PreviewColoring::Scalar::values",
            values.len(),
            "needs exactly one value per point",
        ));
    }
    let mut rgb = vec![0u8; w * h * 3];
    for px in rgb.chunks_exact_mut(3) {
        px.copy_from_slice(&BACKGROUND);
    }
    let (Some(bbox), Some(_)) = (cloud.bounding_box(), cloud.centroid()) else {
        return Ok(PreviewImage {
            width: config.width,
            height: config.height,
            rgb,
        });
    };
    let center = bbox.center();
    let radius = cloud
        .positions()
        .iter()
        .filter(|p| p.coords.iter().all(|c| c.is_finite()))
        .map(|p| (p - center).norm())
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let view = Rotation3::from_axis_angle(&Vector3::x_axis(), config.elevation_deg.to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), config.azimuth_deg.to_radians());
    // Pixels per unit of length, so that the bounding sphere fits the smaller side.
    let scale = (w.min(h) as f64) * (0.5 - MARGIN) / radius;

    // Z-buffer splatting: depth and the index of the nearest point of each pixel.
    let mut depth = vec![f64::INFINITY; w * h];
    let mut owner = vec![u32::MAX; w * h];
    let r = config.point_radius_px as i64;
    for (i, p) in cloud.positions().iter().enumerate() {
        let q = view * (p - center);
        if !q.iter().all(|c| c.is_finite()) {
            continue;
        }
        let u = (w as f64 * 0.5 + scale * q.x).round() as i64;
        let v = (h as f64 * 0.5 + scale * q.y).round() as i64;
        for dv in -r..=r {
            for du in -r..=r {
                if du * du + dv * dv > r * r + r {
                    continue;
                }
                let (x, y) = (u + du, v + dv);
                if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                    continue;
                }
                let k = y as usize * w + x as usize;
                if q.z < depth[k] {
                    depth[k] = q.z;
                    owner[k] = i as u32;
                }
            }
        }
    }

    let light = Vector3::new(-0.3, -0.5, -1.0).normalize();
    let normals = cloud.normals();
    let colors = cloud.colors();
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            let Some(i) = usize::try_from(owner[k]).ok().filter(|&i| i < cloud.len()) else {
                continue;
            };
            let n = match normals
                .map(|ns| view * ns[i])
                .filter(|n| n.norm_squared() > 0.5)
            {
                Some(n) => n,
                None => depth_normal(&depth, w, h, x, y, scale),
            };
            // Two-sided: a surface is lit from the side that faces the viewer.
            let n = if n.z > 0.0 { -n } else { n };
            let shade = AMBIENT + (1.0 - AMBIENT) * n.dot(&light).max(0.0);
            let base = match coloring {
                PreviewColoring::Grey => GREY,
                PreviewColoring::Colors => colors.map_or(GREY, |c| {
                    [
                        c[i][0] as f64 / 255.0,
                        c[i][1] as f64 / 255.0,
                        c[i][2] as f64 / 255.0,
                    ]
                }),
                PreviewColoring::Scalar { values, min, max } => {
                    let v = values[i];
                    if v.is_nan() {
                        GREY
                    } else {
                        let span = (max - min) as f64;
                        let t = if span > 0.0 {
                            (v - min) as f64 / span
                        } else {
                            0.5
                        };
                        colormap(t).map(|c| c as f64 / 255.0)
                    }
                }
            };
            let px = &mut rgb[k * 3..k * 3 + 3];
            for c in 0..3 {
                px[c] = to_u8(base[c] * shade);
            }
        }
    }
    Ok(PreviewImage {
        width: config.width,
        height: config.height,
        rgb,
    })
}

/// Surface normal from the depth buffer's central differences (one-sided at holes and borders).
fn depth_normal(depth: &[f64], w: usize, h: usize, x: usize, y: usize, scale: f64) -> Vector3<f64> {
    let at = |x: usize, y: usize| depth[y * w + x];
    let d0 = at(x, y);
    let grad = |a: Option<f64>, b: Option<f64>| -> f64 {
        match (a.filter(|v| v.is_finite()), b.filter(|v| v.is_finite())) {
            (Some(a), Some(b)) => (b - a) * 0.5,
            (Some(a), None) => d0 - a,
            (None, Some(b)) => b - d0,
            (None, None) => 0.0,
        }
    };
    let left = (x > 0).then(|| at(x - 1, y));
    let right = (x + 1 < w).then(|| at(x + 1, y));
    let up = (y > 0).then(|| at(x, y - 1));
    let down = (y + 1 < h).then(|| at(x, y + 1));
    // Depth change per unit length across the image: per pixel times pixels per unit.
    let gx = grad(left, right) * scale;
    let gy = grad(up, down) * scale;
    Vector3::new(gx, gy, -1.0).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    fn sphere(n: usize, r: f64) -> PointCloud {
        // Fibonacci sphere: evenly spread points, deterministic.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let pts = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let rho = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                Point3::new(r * rho * t.cos(), r * rho * t.sin(), 500.0 + r * z)
            })
            .collect();
        PointCloud::from_positions(pts)
    }

    #[test]
    fn sphere_fills_a_disc_and_is_brightest_toward_the_light() {
        let cloud = sphere(200_000, 50.0);
        let cfg = PreviewConfig {
            width: 200,
            height: 200,
            point_radius_px: 1,
            ..Default::default()
        };
        let img = render_preview(&cloud, PreviewColoring::Grey, &cfg).unwrap();
        // The disc has radius (0.5 - MARGIN) * 200 = 90 px about the centre.
        assert!(!img.is_background(100, 100));
        assert!(!img.is_background(100 + 80, 100));
        assert!(img.is_background(100 + 97, 100));
        assert!(img.is_background(2, 2));
        // The head light comes from the upper left: that side is brighter than the lower right.
        let ul = img.pixel(100 - 40, 100 - 60).unwrap()[0];
        let lr = img.pixel(100 + 60, 100 + 40).unwrap()[0];
        assert!(
            ul > lr + 40,
            "upper-left {ul} should be brighter than lower-right {lr}"
        );
    }

    #[test]
    fn normals_and_depth_gradient_shade_a_plane_alike() {
        let pts: Vec<_> = (0..250_000)
            .map(|i| Point3::new((i % 500) as f64, (i / 500) as f64, 300.0))
            .collect();
        let plain = PointCloud::from_positions(pts);
        let with_n = plain
            .clone()
            .with_normals(vec![-Vector3::z(); plain.len()])
            .unwrap();
        let cfg = PreviewConfig {
            width: 120,
            height: 120,
            ..Default::default()
        };
        let a = render_preview(&plain, PreviewColoring::Grey, &cfg).unwrap();
        let b = render_preview(&with_n, PreviewColoring::Grey, &cfg).unwrap();
        let (pa, pb) = (a.pixel(60, 60).unwrap(), b.pixel(60, 60).unwrap());
        assert_eq!(pa, pb);
        // A plane facing the viewer: shade = AMBIENT + (1 - AMBIENT) * light.z.
        let lz = Vector3::<f64>::new(-0.3, -0.5, -1.0).normalize().z.abs();
        let expect = to_u8(GREY[0] * (AMBIENT + (1.0 - AMBIENT) * lz));
        assert_eq!(pa[0], expect);
    }

    #[test]
    fn scalar_field_maps_min_to_blue_and_max_to_red() {
        let pts: Vec<_> = (0..40_000)
            .map(|i| Point3::new((i % 200) as f64, (i / 200) as f64, 0.0))
            .collect();
        let values: Vec<f32> = pts.iter().map(|p| p.x as f32).collect();
        let cloud = PointCloud::from_positions(pts);
        let cfg = PreviewConfig {
            width: 100,
            height: 100,
            ..Default::default()
        };
        let col = PreviewColoring::Scalar {
            values: &values,
            min: 0.0,
            max: 199.0,
        };
        let img = render_preview(&cloud, col, &cfg).unwrap();
        // The 200 x 200 square spans 100 * 0.9 / sqrt(2) ≈ 64 px about the centre: x in 18..82.
        let left = img.pixel(22, 50).unwrap();
        let right = img.pixel(78, 50).unwrap();
        assert!(
            left[2] > left[0] && right[0] > right[2],
            "left {left:?} right {right:?}"
        );
    }

    #[test]
    fn bad_parameters_are_errors() {
        let cloud = sphere(100, 1.0);
        let zero = PreviewConfig {
            width: 0,
            ..Default::default()
        };
        assert!(render_preview(&cloud, PreviewColoring::Grey, &zero).is_err());
        let short = [0.0f32; 3];
        let col = PreviewColoring::Scalar {
            values: &short,
            min: 0.0,
            max: 1.0,
        };
        assert!(render_preview(&cloud, col, &PreviewConfig::default()).is_err());
        let empty = render_preview(
            &PointCloud::new(),
            PreviewColoring::Grey,
            &Default::default(),
        );
        assert!(empty.unwrap().rgb.chunks(3).all(|p| p == BACKGROUND));
    }
}
