//! The colour of a scan: each view's colour image (`sl_codec::read_capture_colour`) gives its
//! points their colour, and the surface's colour is blended across the views that see it,
//! weighted by how squarely each saw it ([`ScanColours::colour_at`]): the mesh's vertex
//! colours and its texture come from there.
//!
//! A view sees a surface point when the point projects into its camera in front of it, its
//! own depth map holds a depth within [`ColourConfig::depth_tolerance_mm`] of the point's at
//! that pixel (else something nearer hides it, or the view did not decode there: a shadow of
//! the projector is dark in the white frame too), and the surface's normal is within
//! [`ColourConfig::max_view_angle_deg`] of the direction to the camera. Its weight is
//! `cos(angle)^power` ([`ColourConfig::view_angle_power`]): a grazing view sees a texel
//! smeared over many pixels and, with the projector beside the camera, lit at a grazing angle
//! too.

use nalgebra::{Isometry3, Point3, Vector3};
use serde::Serialize;
use sl_camera::CameraModel;
use sl_codec::{ColourImage, ColourSource};

use crate::ScanError;
use crate::error::stage_err;

/// Whether a scan's clouds carry colour.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ColourMode {
    /// Colour when the capture holds colour: a `colour` frame in its manifest, or frames
    /// saved in colour (`sl_codec::capture_in_colour`, from the first frame's header) whose
    /// channels differ somewhere. A grey capture gives a cloud without colours, as before
    /// colour existed, and none of its frames is read twice.
    #[default]
    Auto,
    /// Always: grey captures give grey colours (from their white frame, fringe mean or
    /// brightest frames, `sl_codec::read_capture_colour`).
    Always,
    /// Never.
    Never,
}

impl ColourMode {
    /// `"auto"`, `"always"` or `"never"`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Always => "always",
            Self::Never => "never",
        }
    }

    /// Parses [`ColourMode::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Auto, Self::Always, Self::Never]
            .into_iter()
            .find(|m| m.name() == name)
    }
}

/// How the views' colours are blended on the surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ColourConfig {
    /// A view's weight is `cos(angle)^power`, `angle` between the surface normal and the
    /// direction to the camera. Default 2.
    pub view_angle_power: f64,
    /// Views that see the surface more obliquely than this (degrees) give it no colour.
    /// Default 75.
    pub max_view_angle_deg: f64,
    /// A view sees a point when its depth map at the point's pixel is within this of the
    /// point's depth (mm). Default 1.
    pub depth_tolerance_mm: f64,
}

impl Default for ColourConfig {
    fn default() -> Self {
        Self {
            view_angle_power: 2.0,
            max_view_angle_deg: 75.0,
            depth_tolerance_mm: 1.0,
        }
    }
}

impl ColourConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`ScanError::Stage`] naming the field.
    pub fn validate(&self) -> Result<(), ScanError> {
        let bad = |name: &str, v: f64, want: &str| {
            stage_err(
                "colour",
                format!("ColourConfig::{name} must be {want}, got {v}"),
            )
        };
        if !(self.view_angle_power.is_finite() && self.view_angle_power >= 0.0) {
            return Err(bad(
                "view_angle_power",
                self.view_angle_power,
                "finite and ≥ 0",
            ));
        }
        if !(self.max_view_angle_deg > 0.0 && self.max_view_angle_deg <= 90.0) {
            return Err(bad(
                "max_view_angle_deg",
                self.max_view_angle_deg,
                "in (0, 90]",
            ));
        }
        if !(self.depth_tolerance_mm.is_finite() && self.depth_tolerance_mm > 0.0) {
            return Err(bad(
                "depth_tolerance_mm",
                self.depth_tolerance_mm,
                "finite and positive",
            ));
        }
        Ok(())
    }
}

/// One view's colour: its image, its depth map (what it saw, for visibility) and its pose.
#[derive(Clone, Debug)]
pub struct ColourView {
    /// `T_world_view`: the view's camera frame into the scan's (the merged cloud's).
    pub t_world_view: Isometry3<f64>,
    /// The colour image (camera-sized).
    pub image: ColourImage,
    /// Depth (mm, camera z) of each camera pixel, row-major; NaN where the view has no point.
    pub depth_mm: Vec<f32>,
    /// Which frames the colour came from.
    pub source: ColourSource,
}

/// The views' colours of a scan, to colour its surface.
#[derive(Clone, Debug)]
pub struct ScanColours {
    /// The camera of every view.
    pub camera: CameraModel,
    /// The views with a colour image.
    pub views: Vec<ColourView>,
    /// How they are blended.
    pub config: ColourConfig,
}

impl ScanColours {
    /// The colour of the surface at `p` (scan frame, mm) with unit normal `n`, blended over
    /// the views that see it (module documentation); `None` when none does.
    pub fn colour_at(&self, p: &Point3<f64>, n: &Vector3<f64>) -> Option<[u8; 3]> {
        let cos_min = self.config.max_view_angle_deg.to_radians().cos();
        let (mut sum, mut total) = ([0.0f64; 3], 0.0f64);
        for v in &self.views {
            let Some((rgb, cos)) = self.seen(v, p, n) else {
                continue;
            };
            if cos < cos_min {
                continue;
            }
            let w = cos
                .powf(self.config.view_angle_power)
                .max(f64::MIN_POSITIVE);
            for c in 0..3 {
                sum[c] += w * rgb[c];
            }
            total += w;
        }
        (total > 0.0).then(|| sum.map(|s| (s / total).round().clamp(0.0, 255.0) as u8))
    }

    /// The colour `view` sees at `p` (bilinear) and the cosine of its view angle, when it
    /// sees `p`.
    fn seen(
        &self,
        view: &ColourView,
        p: &Point3<f64>,
        n: &Vector3<f64>,
    ) -> Option<([f64; 3], f64)> {
        let q = view.t_world_view.inverse_transform_point(p);
        if q.z <= 0.0 {
            return None;
        }
        let px = self.camera.project(&q)?;
        let (w, h) = (view.image.width(), view.image.height());
        let (xi, yi) = (px.x.round(), px.y.round());
        if !(xi >= 0.0 && yi >= 0.0 && xi < w as f64 && yi < h as f64) {
            return None;
        }
        let (xi, yi) = (xi as usize, yi as usize);
        // Visible when a depth of the 3 × 3 neighbourhood matches (a point on the silhouette
        // rounds to a pixel beside the object as often as on it).
        let tol = self.config.depth_tolerance_mm;
        let visible = (yi.saturating_sub(1)..=(yi + 1).min(h - 1)).any(|y| {
            (xi.saturating_sub(1)..=(xi + 1).min(w - 1)).any(|x| {
                // A depth map of another size than the image (a view built by hand) sees
                // nothing where it has no value.
                let d = f64::from(view.depth_mm.get(y * w + x).copied().unwrap_or(f32::NAN));
                d.is_finite() && (d - q.z).abs() <= tol
            })
        });
        if !visible {
            return None;
        }
        let to_camera = -q.coords / q.coords.norm();
        let cos = view
            .t_world_view
            .inverse_transform_vector(n)
            .dot(&to_camera);
        Some((bilinear(&view.image, px.x, px.y), cos))
    }

    /// The texture's texels per triangle edge for `mesh`: about one texel per camera pixel on
    /// the surface (a finer texture holds no more detail, and baking costs a projection into
    /// every view per texel). The camera's pixel is `depth / fx` at the median depth the
    /// first view saw; the mesh's mean edge over it, rounded, within 2 to 8.
    pub fn texels_per_edge(&self, mesh: &sl_cloud::TriangleMesh) -> u32 {
        let mut depths: Vec<f32> = self
            .views
            .first()
            .map(|v| {
                v.depth_mm
                    .iter()
                    .copied()
                    .filter(|d| d.is_finite())
                    .collect()
            })
            .unwrap_or_default();
        if depths.is_empty() || mesh.triangles.is_empty() {
            return 8;
        }
        let mid = depths.len() / 2;
        let depth = f64::from(*depths.select_nth_unstable_by(mid, f32::total_cmp).1);
        let pixel_mm = depth / self.camera.intrinsics.fx;
        let at = |i: u32| mesh.vertices.get(i as usize).copied();
        let (sum, n) = mesh.triangles.iter().fold((0.0, 0usize), |(s, n), t| {
            match (at(t[0]), at(t[1]), at(t[2])) {
                (Some(a), Some(b), Some(c)) => {
                    (s + (b - a).norm() + (c - b).norm() + (a - c).norm(), n + 3)
                }
                _ => (s, n),
            }
        });
        let edge_mm = sum / n.max(1) as f64;
        let texels = (edge_mm / pixel_mm).round();
        if texels.is_finite() {
            texels.clamp(2.0, 8.0) as u32
        } else {
            8
        }
    }

    /// Colours of `points` with their unit `normals` (mid grey where no view sees one), in
    /// parallel.
    ///
    /// # Errors
    /// [`ScanError::Stage`] when `normals` is not one per point.
    pub fn colours_of(
        &self,
        points: &[Point3<f64>],
        normals: &[Vector3<f64>],
    ) -> Result<Vec<[u8; 3]>, ScanError> {
        use rayon::prelude::*;
        if points.len() != normals.len() {
            return Err(stage_err(
                "colour",
                format!("{} points but {} normals", points.len(), normals.len()),
            ));
        }
        Ok(points
            .par_iter()
            .zip(normals)
            .map(|(p, n)| self.colour_at(p, n).unwrap_or(UNSEEN_COLOUR))
            .collect())
    }
}

/// The views' colours of several placements (each placement's [`crate::SessionScan::colours`])
/// in the first placement's frame: placement `k`'s views moved by `alignments[k - 1].pose` (`T_first_this`); `None` when no view has colour.
///
/// # Errors
/// [`ScanError::Stage`] for an alignment pose that is not a rigid motion, or fewer alignments
/// than placements after the first.
pub fn placed_colours<'a>(
    placements: impl IntoIterator<Item = Option<&'a ScanColours>>,
    alignments: &[crate::PlacementAlignment],
) -> Result<Option<ScanColours>, ScanError> {
    let mut out: Option<ScanColours> = None;
    for (k, colours) in placements.into_iter().enumerate() {
        let Some(colours) = colours else {
            continue;
        };
        let t_first_this = match k {
            0 => Isometry3::identity(),
            _ => {
                let a = alignments.get(k - 1).ok_or_else(|| {
                    stage_err("colour", format!("placement {} has no alignment", k + 1))
                })?;
                sl_camera::pose_from_matrix(&a.pose).map_err(|e| {
                    stage_err("colour", format!("placement {}'s alignment: {e}", k + 1))
                })?
            }
        };
        let moved = colours.views.iter().map(|v| ColourView {
            t_world_view: t_first_this * v.t_world_view,
            ..v.clone()
        });
        match &mut out {
            Some(all) => all.views.extend(moved),
            None => {
                out = Some(ScanColours {
                    camera: colours.camera,
                    views: moved.collect(),
                    config: colours.config,
                });
            }
        }
    }
    Ok(out)
}

/// A scan's colours against the true albedo of the surface they were measured on.
///
/// The camera's levels are the albedo times the light: the projector's irradiance, the
/// exposure and the camera's gain per channel. One gain per channel is fitted (least squares,
/// the white balance and exposure a user sets once), and what remains is the error: the
/// shading the white frame carries (the projector's angle and distance to each point), the
/// noise, and the blur at the patches' edges. The angle between the measured and the true RGB
/// vectors (after the gains) is blind to the shading, which scales all three channels alike:
/// it measures the hue and saturation alone.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ColourAccuracy {
    /// Points compared (those with a true colour).
    pub points: usize,
    /// Fitted gain per channel (levels per unit albedo).
    pub gain: [f64; 3],
    /// RMS over points and channels of the measured level minus the gain times the albedo
    /// (8-bit levels).
    pub rms_levels: f64,
    /// `rms_levels` over the mean measured level.
    pub rms_relative: f64,
    /// Median angle between the measured and the true colour (degrees, after the gains).
    pub angle_median_deg: f64,
    /// 95th percentile of that angle (degrees).
    pub angle_p95_deg: f64,
}

/// Compares `colours` (8-bit) of `points` with `truth`, the true RGB albedo in `[0, 1]` at a
/// point (`None`: no surface near it, the point is left out). `None` when no point has a
/// truth or the truth is black everywhere.
pub fn colour_accuracy(
    points: &[Point3<f64>],
    colours: &[[u8; 3]],
    truth: impl Fn(&Point3<f64>) -> Option<[f64; 3]> + Sync,
) -> Option<ColourAccuracy> {
    use rayon::prelude::*;
    let pairs: Vec<([f64; 3], [f64; 3])> = points
        .par_iter()
        .zip(colours)
        .filter_map(|(p, c)| truth(p).map(|a| (c.map(f64::from), a)))
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let mut gain = [0.0; 3];
    for (k, g) in gain.iter_mut().enumerate() {
        let (ca, aa) = pairs.iter().fold((0.0, 0.0), |(ca, aa), (c, a)| {
            (ca + c[k] * a[k], aa + a[k] * a[k])
        });
        if aa <= 0.0 {
            return None;
        }
        *g = ca / aa;
    }
    let n = pairs.len() as f64;
    let sq: f64 = pairs
        .iter()
        .map(|(c, a)| (0..3).map(|k| (c[k] - gain[k] * a[k]).powi(2)).sum::<f64>())
        .sum();
    let rms_levels = (sq / (3.0 * n)).sqrt();
    let mean_level = pairs
        .iter()
        .map(|(c, _)| c.iter().sum::<f64>())
        .sum::<f64>()
        / (3.0 * n);
    let mut angles: Vec<f64> = pairs
        .iter()
        .map(|(c, a)| {
            let t: [f64; 3] = std::array::from_fn(|k| gain[k] * a[k]);
            let dot: f64 = (0..3).map(|k| c[k] * t[k]).sum();
            let norms = c.iter().map(|v| v * v).sum::<f64>().sqrt()
                * t.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norms > 0.0 {
                (dot / norms).clamp(-1.0, 1.0).acos().to_degrees()
            } else {
                90.0
            }
        })
        .collect();
    angles.sort_by(f64::total_cmp);
    let at = |q: f64| angles[((angles.len() - 1) as f64 * q).round() as usize];
    Some(ColourAccuracy {
        points: pairs.len(),
        gain,
        rms_levels,
        rms_relative: if mean_level > 0.0 {
            rms_levels / mean_level
        } else {
            f64::NAN
        },
        angle_median_deg: at(0.5),
        angle_p95_deg: at(0.95),
    })
}

/// The colour given to surface no view sees (the unseen bottom a second placement did not
/// cover): mid grey.
pub const UNSEEN_COLOUR: [u8; 3] = [128, 128, 128];

/// `image` at `(x, y)` (pixel centres at whole numbers), bilinear, clamped at the border.
fn bilinear(image: &ColourImage, x: f64, y: f64) -> [f64; 3] {
    let (w, h) = (image.width(), image.height());
    let x = x.clamp(0.0, (w - 1) as f64);
    let y = y.clamp(0.0, (h - 1) as f64);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |x: usize, y: usize| image.data()[y * w + x].map(f64::from);
    let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
    std::array::from_fn(|k| {
        (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_camera::{Distortion, ImageSize, Intrinsics};

    /// A 40 × 30 camera; `depth` everywhere; the image red on the left half, blue on the
    /// right.
    fn view(t_world_view: Isometry3<f64>, depth: f32) -> (CameraModel, ColourView) {
        let camera = CameraModel::new(
            Intrinsics::new(50.0, 50.0, 19.5, 14.5),
            Distortion::default(),
            ImageSize::new(40, 30),
        )
        .unwrap();
        let data = (0..30 * 40)
            .map(|i| {
                if i % 40 < 20 {
                    [200, 0, 0]
                } else {
                    [0, 0, 200]
                }
            })
            .collect();
        let v = ColourView {
            t_world_view,
            image: ColourImage::new(40, 30, data).unwrap(),
            depth_mm: vec![depth; 40 * 30],
            source: ColourSource::ColourFrame,
        };
        (camera, v)
    }

    #[test]
    fn a_visible_point_takes_its_pixel_colour_and_a_hidden_one_none() {
        let (camera, v) = view(Isometry3::identity(), 100.0);
        let colours = ScanColours {
            camera,
            views: vec![v],
            config: ColourConfig::default(),
        };
        let n = Vector3::new(0.0, 0.0, -1.0);
        // 100 mm ahead, left of the centre: pixel x = 19.5 - 50 * 10 / 100 = 14.5 (red).
        assert_eq!(
            colours.colour_at(&Point3::new(-10.0, 0.0, 100.0), &n),
            Some([200, 0, 0])
        );
        assert_eq!(
            colours.colour_at(&Point3::new(10.0, 0.0, 100.0), &n),
            Some([0, 0, 200])
        );
        // Behind the surface the view saw (hidden), behind the camera, outside the image, or
        // facing away: no colour.
        for (p, n) in [
            (Point3::new(-10.0, 0.0, 110.0), n),
            (Point3::new(0.0, 0.0, -100.0), n),
            (Point3::new(500.0, 0.0, 100.0), n),
            (Point3::new(-10.0, 0.0, 100.0), -n),
        ] {
            assert_eq!(colours.colour_at(&p, &n), None, "{p:?} {n:?}");
        }
    }

    #[test]
    fn views_are_weighted_by_how_squarely_they_see() {
        // Two views of the point (0, 0, 100) with normal −z: one straight on (red at its
        // centre-left pixel: the point sits at x = 19.5, between red 19 and blue 20 → shift it),
        // one from 60° (weight cos²60° = 0.25 against 1).
        let p = Point3::new(-2.0, 0.0, 100.0);
        let n = Vector3::new(0.0, 0.0, -1.0);
        let (camera, straight) = view(Isometry3::identity(), 100.0);
        // The second camera on a circle around p, 60° off the normal, looking at p; its image
        // all blue.
        let angle = 60f64.to_radians();
        let eye = Point3::new(-2.0 - 100.0 * angle.sin(), 0.0, 100.0 - 100.0 * angle.cos());
        let rot = nalgebra::UnitQuaternion::face_towards(&(p - eye), &Vector3::new(0.0, -1.0, 0.0));
        let t = Isometry3::from_parts(eye.coords.into(), rot);
        let (_, mut oblique) = view(t, 100.0);
        oblique.image = ColourImage::filled(40, 30, [0, 0, 200]).unwrap();
        let colours = ScanColours {
            camera,
            views: vec![straight, oblique],
            config: ColourConfig::default(),
        };
        let c = colours.colour_at(&p, &n).unwrap();
        // Red 200 · 1 / 1.25 = 160, blue 200 · 0.25 / 1.25 = 40.
        assert!((i32::from(c[0]) - 160).abs() <= 1, "{c:?}");
        assert!((i32::from(c[2]) - 40).abs() <= 1, "{c:?}");
    }

    #[test]
    fn colour_accuracy_fits_the_gains_and_measures_what_remains() {
        let points: Vec<Point3<f64>> = (0..4)
            .map(|i| Point3::new(f64::from(i), 0.0, 0.0))
            .collect();
        let albedo = |p: &Point3<f64>| -> Option<[f64; 3]> {
            match p.x as i32 {
                0 | 1 => Some([0.8, 0.1, 0.1]),
                2 => Some([0.1, 0.7, 0.2]),
                _ => None,
            }
        };
        // Exact: gains (250, 200, 150), no error, no angle.
        let exact: Vec<[u8; 3]> = points
            .iter()
            .map(|p| {
                let a = albedo(p).unwrap_or([1.0; 3]);
                [250.0 * a[0], 200.0 * a[1], 150.0 * a[2]].map(|v| v.round() as u8)
            })
            .collect();
        let acc = colour_accuracy(&points, &exact, albedo).unwrap();
        assert_eq!(acc.points, 3);
        assert!(
            (acc.gain[0] - 250.0).abs() < 0.5 && (acc.gain[2] - 150.0).abs() < 2.0,
            "{acc:?}"
        );
        assert!(acc.rms_levels < 0.6 && acc.angle_p95_deg < 1.0, "{acc:?}");
        // A shading of one point (half as bright) leaves the angles small (the gains the fit
        // moves a little, channel by channel: 2.5° here) but not the levels.
        let mut shaded = exact.clone();
        shaded[1] = shaded[1].map(|v| v / 2);
        let acc = colour_accuracy(&points, &shaded, albedo).unwrap();
        assert!(acc.rms_levels > 10.0 && acc.angle_p95_deg < 5.0, "{acc:?}");
        // A wrong hue shows in the angle: the red patch measured green.
        let mut wrong = exact;
        wrong[0] = [20, 160, 20];
        let acc = colour_accuracy(&points, &wrong, albedo).unwrap();
        assert!(acc.angle_p95_deg > 30.0, "{acc:?}");
        assert!(colour_accuracy(&points[3..], &shaded[3..], albedo).is_none());
    }

    #[test]
    fn about_one_texel_per_camera_pixel() {
        // 50 px focal length at 100 mm: 2 mm a pixel. Right triangles of legs 6 mm: mean edge
        // (6 + 6 + 8.49) / 3 = 6.83 mm, 3.4 pixels: 3 texels an edge.
        let (camera, v) = view(Isometry3::identity(), 100.0);
        let colours = ScanColours {
            camera,
            views: vec![v],
            config: ColourConfig::default(),
        };
        let mesh = |leg: f64| sl_cloud::TriangleMesh {
            vertices: vec![
                Point3::origin(),
                Point3::new(leg, 0.0, 0.0),
                Point3::new(0.0, leg, 0.0),
            ],
            triangles: vec![[0, 1, 2]],
        };
        assert_eq!(colours.texels_per_edge(&mesh(6.0)), 3);
        // Within 2 to 8 texels.
        assert_eq!(colours.texels_per_edge(&mesh(0.1)), 2);
        assert_eq!(colours.texels_per_edge(&mesh(100.0)), 8);
    }

    #[test]
    fn bad_settings_are_named() {
        for (cfg, name) in [
            (
                ColourConfig {
                    view_angle_power: f64::NAN,
                    ..ColourConfig::default()
                },
                "view_angle_power",
            ),
            (
                ColourConfig {
                    max_view_angle_deg: 95.0,
                    ..ColourConfig::default()
                },
                "max_view_angle_deg",
            ),
            (
                ColourConfig {
                    depth_tolerance_mm: 0.0,
                    ..ColourConfig::default()
                },
                "depth_tolerance_mm",
            ),
        ] {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
    }
}
