//! A shaded preview render of a point cloud, so that a user sees a result without another tool.
//!
//! Orthographic splatting into a z-buffer, then Lambertian shading with a head light: from the
//! cloud's normals when it has them, otherwise from the gradient of the depth buffer. Points are
//! coloured by their own colours, by a scalar field through a colour map (error maps), or grey.
//!
//! The view is framed on robust bounds: per axis, the [`FRAME_PERCENTILE`] and
//! `100 - FRAME_PERCENTILE` percentiles of the points, widened by [`FRAME_SLACK`] of their
//! largest extent. A few far specks (a real capture's background) therefore no longer shrink
//! the object to a dot; they fall outside the picture and [`PreviewImage::left_out`] counts
//! them, so that callers can say so.

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
/// Percentile (in %) of each coordinate that bounds the framed part of the cloud from below
/// (and `100 -` it from above): 0.5 % leaves out up to 1 % of the points per axis before the
/// slack below takes the object's own edges back in, while a speck cluster needs more than
/// 0.5 % of the points to move the frame.
pub const FRAME_PERCENTILE: f64 = 0.5;
/// Slack added on every side of the percentile box, as a fraction of its largest extent: the
/// object's own extreme points lie just beyond the percentiles (on a sphere the 0.5 %
/// percentile of `x` is at 0.99 of the radius), far outliers lie well beyond them. A quarter
/// keeps any point within 25 % of the object's size of its bounds in the picture.
pub const FRAME_SLACK: f64 = 0.25;

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
    /// Finite points that fall outside the picture: far outliers left out of the robust frame
    /// (see the module docs). Callers should say so, e.g. with [`PreviewImage::left_out_note`].
    pub left_out: usize,
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

    /// A sentence for the user when points were left out of the picture, `None` otherwise:
    /// `"3 far outliers outside the preview (of 120000 points)"`.
    pub fn left_out_note(&self, points: usize) -> Option<String> {
        (self.left_out > 0).then(|| {
            let s = if self.left_out == 1 { "" } else { "s" };
            format!(
                "{} far outlier{s} outside the preview (of {points} points)",
                self.left_out
            )
        })
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

/// Renders `cloud` as seen from the direction in `config`, orthographically, fitted to the image
/// on robust bounds: far outliers are left out of the picture and counted in
/// [`PreviewImage::left_out`].
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
    let Some(frame) = robust_frame(cloud.positions()) else {
        return Ok(PreviewImage {
            width: config.width,
            height: config.height,
            rgb,
            left_out: 0,
        });
    };
    let (center, radius) = (frame.center, frame.radius);
    let view = Rotation3::from_axis_angle(&Vector3::x_axis(), config.elevation_deg.to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), config.azimuth_deg.to_radians());
    // Pixels per unit of length, so that the bounding sphere fits the smaller side.
    let scale = (w.min(h) as f64) * (0.5 - MARGIN) / radius;

    // Z-buffer splatting: depth and the index of the nearest point of each pixel.
    let mut depth = vec![f64::INFINITY; w * h];
    let mut owner = vec![u32::MAX; w * h];
    let r = config.point_radius_px as i64;
    let mut left_out = 0;
    for (i, p) in cloud.positions().iter().enumerate() {
        let q = view * (p - center);
        if !q.iter().all(|c| c.is_finite()) {
            continue;
        }
        let u = (w as f64 * 0.5 + scale * q.x).round() as i64;
        let v = (h as f64 * 0.5 + scale * q.y).round() as i64;
        if u < 0 || v < 0 || u >= w as i64 || v >= h as i64 {
            left_out += 1;
            continue;
        }
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
        left_out,
    })
}

/// The sphere a preview is fitted to.
struct Frame {
    center: nalgebra::Point3<f64>,
    radius: f64,
}

/// Centre of the percentile box of the finite points and the radius that holds every point
/// inside that box widened by [`FRAME_SLACK`]; `None` without finite points.
fn robust_frame(points: &[nalgebra::Point3<f64>]) -> Option<Frame> {
    let finite: Vec<&nalgebra::Point3<f64>> = points
        .iter()
        .filter(|p| p.coords.iter().all(|c| c.is_finite()))
        .collect();
    if finite.is_empty() {
        return None;
    }
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    let mut axis: Vec<f64> = Vec::with_capacity(finite.len());
    let last = finite.len() - 1;
    // Nearest-rank percentiles: the lowest and highest kept ranks.
    let k_lo = ((FRAME_PERCENTILE / 100.0) * last as f64).floor() as usize;
    let k_hi = last - k_lo;
    for a in 0..3 {
        axis.clear();
        axis.extend(finite.iter().map(|p| p[a]));
        let (_, &mut l, _) = axis.select_nth_unstable_by(k_lo, f64::total_cmp);
        let (_, &mut u, _) = axis.select_nth_unstable_by(k_hi, f64::total_cmp);
        (lo[a], hi[a]) = (l, u);
    }
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    let slack = FRAME_SLACK * extent;
    let center = nalgebra::Point3::new(
        0.5 * (lo[0] + hi[0]),
        0.5 * (lo[1] + hi[1]),
        0.5 * (lo[2] + hi[2]),
    );
    let inside =
        |p: &nalgebra::Point3<f64>| (0..3).all(|a| p[a] >= lo[a] - slack && p[a] <= hi[a] + slack);
    let radius = finite
        .iter()
        .filter(|p| inside(p))
        .map(|p| (*p - center).norm())
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    Some(Frame { center, radius })
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

    /// A sphere of radius 50 with five specks 5 m away: framed on the specks it would be a
    /// dot of ~1 px radius; framed robustly it fills the disc of radius 90 px as without them,
    /// and the specks are counted as left out.
    #[test]
    fn far_specks_do_not_shrink_the_object() {
        let clean = sphere(50_000, 50.0);
        let mut pts = clean.positions().to_vec();
        for k in 0..5 {
            let s = 5000.0 * (1.0 + f64::from(k));
            pts.push(Point3::new(s, -s, 500.0 + s));
        }
        let specked = PointCloud::from_positions(pts);
        let cfg = PreviewConfig {
            width: 200,
            height: 200,
            ..Default::default()
        };
        let a = render_preview(&clean, PreviewColoring::Grey, &cfg).unwrap();
        let b = render_preview(&specked, PreviewColoring::Grey, &cfg).unwrap();
        assert_eq!(a.left_out, 0);
        assert!(a.left_out_note(clean.len()).is_none());
        assert_eq!(b.left_out, 5);
        assert_eq!(
            b.left_out_note(specked.len()).unwrap(),
            "5 far outliers outside the preview (of 50005 points)"
        );
        // The object fills the same disc: drawn 80 px from the centre, not at 97 px.
        let covered = |img: &PreviewImage| img.rgb.chunks(3).filter(|p| *p != BACKGROUND).count();
        assert!(!b.is_background(100 + 80, 100));
        assert!(b.is_background(100 + 97, 100));
        // The same picture up to the frame's shift by 5 ranks of 50 000 (~0.01 px).
        let (ca, cb) = (covered(&a) as f64, covered(&b) as f64);
        assert!((ca - cb).abs() < 0.01 * ca, "{ca} vs {cb}");
        // pi 90^2 = 25447 px: the object fills the picture's disc.
        assert!(covered(&b) > 24_000, "{}", covered(&b));
    }

    /// Points just past the percentiles (the object's own extremes, a thin feature) stay in.
    #[test]
    fn a_thin_spike_within_the_slack_stays_in_the_picture() {
        let mut pts = sphere(20_000, 50.0).positions().to_vec();
        // 20 points (0.1 %) on a spike reaching 20 mm beyond the sphere along +x.
        for k in 0..20 {
            pts.push(Point3::new(50.0 + f64::from(k), 0.0, 500.0));
        }
        let cloud = PointCloud::from_positions(pts);
        let img = render_preview(&cloud, PreviewColoring::Grey, &PreviewConfig::default()).unwrap();
        assert_eq!(img.left_out, 0);
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
