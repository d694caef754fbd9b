//! The per-view geometry cache: every camera ray cast once per view, so that each projected
//! image renders as a cheap lookup; and the ground truth at pixel centres.

use nalgebra::{Isometry3, Point2, Point3, Vector3};
use rayon::prelude::*;

use crate::PlacedScene;

/// What the virtual rig needs of a projector model: its image size and the projection of a
/// point of its frame to a pixel.
pub(crate) trait Lens: Sync {
    /// Image size `(width, height)` in pixels.
    fn size(&self) -> (u32, u32);
    /// Pixel of `p` (a point in the device frame, mm), with distortion; `None` when the model
    /// cannot project it (behind, or outside the region where the model is valid).
    fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>>;
}

/// The camera's rays, computed once per rig (the camera never moves; only the turntable
/// does): the undistorted normalised ray `(x, y)` (with `z = 1`) of every sub-sample, in f32
/// (3e-8 relative, 1e-5 mm at the working distance: far below a rendered pixel), and of every
/// pixel centre in f64 for the ground truth. NaN where the camera model has no ray.
#[derive(Debug, Clone)]
pub struct CameraRays {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) supersampling: u32,
    pub(crate) sub: Vec<[f32; 2]>,
    pub(crate) centre: Vec<[f64; 2]>,
}

impl CameraRays {
    /// The rays of `camera` with `supersampling × supersampling` sub-samples per pixel.
    pub fn new(camera: &sl_camera::CameraModel, supersampling: u32) -> Self {
        let (w, h) = (camera.size.width, camera.size.height);
        let s = supersampling.max(1);
        let per_pixel = (s * s) as usize;
        let offsets: Vec<f64> = (0..s)
            .map(|i| (f64::from(i) + 0.5) / f64::from(s) - 0.5)
            .collect();
        let mut sub = vec![[f32::NAN; 2]; w as usize * h as usize * per_pixel];
        sub.par_chunks_mut((w as usize * per_pixel).max(1))
            .enumerate()
            .for_each(|(y, row)| {
                let mut k = 0usize;
                for x in 0..w {
                    for oy in &offsets {
                        for ox in &offsets {
                            let px = Point2::new(f64::from(x) + ox, y as f64 + oy);
                            if let (Some(r), Some(o)) = (camera.unproject(&px), row.get_mut(k)) {
                                *o = [r.x as f32, r.y as f32];
                            }
                            k += 1;
                        }
                    }
                }
            });
        let table = camera.ray_table();
        let centre = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| table.normalised(x, y).map_or([f64::NAN; 2], |p| [p.x, p.y]))
            .collect();
        Self {
            width: w,
            height: h,
            supersampling: s,
            sub,
            centre,
        }
    }

    /// Sub-samples per pixel along each axis.
    pub fn supersampling(&self) -> u32 {
        self.supersampling
    }

    /// The normalised ray of sub-sample `(gx, gy)` of the sub-sample grid (`gx` in
    /// `0..width·s`), or `None` outside the grid or where the model has no ray.
    fn grid_ray(&self, gx: i64, gy: i64) -> Option<[f64; 2]> {
        let s = i64::from(self.supersampling);
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        if gx < 0 || gy < 0 || gx >= w * s || gy >= h * s {
            return None;
        }
        let index = ((gy / s) * w + gx / s) * s * s + (gy % s) * s + gx % s;
        let r = self.sub.get(usize::try_from(index).ok()?)?;
        (r[0].is_finite() && r[1].is_finite()).then(|| [f64::from(r[0]), f64::from(r[1])])
    }

    /// The change of the normalised ray over one sub-sample step (`1/s` px) along the camera's
    /// `x` and `y` at sub-sample `(gx, gy)`: central differences of the ray table, one-sided
    /// at its borders. `None` where no neighbour has a ray.
    pub(crate) fn differentials(&self, gx: i64, gy: i64) -> Option<([f64; 2], [f64; 2])> {
        let step = |dx: i64, dy: i64| -> Option<[f64; 2]> {
            let ahead = self.grid_ray(gx + dx, gy + dy);
            let behind = self.grid_ray(gx - dx, gy - dy);
            let here = self.grid_ray(gx, gy);
            match (behind, ahead) {
                (Some(b), Some(a)) => Some([(a[0] - b[0]) / 2.0, (a[1] - b[1]) / 2.0]),
                (None, Some(a)) => here.map(|c| [a[0] - c[0], a[1] - c[1]]),
                (Some(b), None) => here.map(|c| [c[0] - b[0], c[1] - b[1]]),
                (None, None) => None,
            }
        };
        Some((step(1, 0)?, step(0, 1)?))
    }
}

/// Sentinel of [`ViewGeometry`]'s projector pixel index for a sample the projector does not
/// light (background, shadow, outside the projector's image, or facing away).
pub(crate) const UNLIT: u32 = u32::MAX;

/// Farthest distance a camera ray is followed (mm): 100 m, far beyond any rig.
const MAX_RAY_MM: f64 = 1e5;

/// Cosine between a camera ray and the surface normal below which the footprint of a
/// sub-sample is not computed (the point albedo is kept): at 89.9° the footprint is 600 times
/// longer than wide, and the surface is invisible anyway.
const GRAZING_COS: f64 = 1.7e-3;

/// Everything the renderer needs about one view, per camera sub-sample.
///
/// Sub-sample `k` of pixel `(x, y)` is at index `(y · width + x) · s² + k`; the sub-samples of a
/// pixel sit on a regular `s × s` grid at offsets `(i + ½)/s − ½` from the pixel centre.
#[derive(Debug, Clone)]
pub struct ViewGeometry {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) supersampling: u32,
    pub(crate) projector_width: u32,
    pub(crate) projector_height: u32,
    /// Continuous projector coordinate of each sub-sample (NaN when unlit).
    pub(crate) proj_xy: Vec<[f32; 2]>,
    /// Index `y · projector_width + x` of the projector pixel whose square contains the
    /// coordinate, or [`UNLIT`].
    pub(crate) proj_index: Vec<u32>,
    /// `(albedo + specular lobe) · cos(angle to the projector)` (0 when unlit).
    pub(crate) lit_weight: Vec<f32>,
    /// `albedo` (0 when the ray hits nothing).
    pub(crate) ambient_weight: Vec<f32>,
    /// Depth at pixel centres (mm; NaN where nothing was hit), for the defocus blur.
    pub(crate) depth_mm: Vec<f32>,
    /// For a scene with colour textures, per sub-sample the RGB albedo and the cosine toward
    /// the projector (0 when unlit): a channel's weights are `lit + (albedo_c − albedo) · cos`
    /// and `albedo_c`. Empty for a grey scene, whose channels all take the grey weights.
    pub(crate) colour: Vec<[f32; 4]>,
}

impl ViewGeometry {
    /// Camera image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Camera image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Sub-samples per pixel along each axis (`s`; `s²` per pixel).
    pub fn supersampling(&self) -> u32 {
        self.supersampling
    }
    /// Fraction of sub-samples lit by the projector.
    pub fn lit_fraction(&self) -> f64 {
        if self.proj_index.is_empty() {
            return 0.0;
        }
        self.proj_index.iter().filter(|&&i| i != UNLIT).count() as f64
            / self.proj_index.len() as f64
    }
}

/// Result of one camera ray: where it went, and how the projector sees that point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sample {
    pub(crate) hit: Option<crate::Hit>,
    /// Projector pixel coordinate (continuous) when the point is lit.
    pub(crate) proj: Option<Point2<f64>>,
    /// `cos` of the angle between the normal and the direction to the projector (when lit).
    pub(crate) cos: f64,
    /// The object's specular lobe toward the camera ([`crate::Gloss::lobe`]), 0 for a matte
    /// object or an unlit point.
    pub(crate) specular: f64,
}

/// The camera, the projector and the scene of one view.
pub(crate) struct Caster<'a, P: Lens> {
    pub(crate) scene: &'a PlacedScene,
    pub(crate) rays: &'a CameraRays,
    pub(crate) projector: &'a P,
    /// `T_cam_proj`.
    pub(crate) t_cam_proj: &'a Isometry3<f64>,
}

impl<P: Lens> Caster<'_, P> {
    /// Casts the camera ray `(nx, ny, 1)` (normalised image coordinates; NaN for none).
    pub(crate) fn sample(&self, nx: f64, ny: f64) -> Sample {
        let none = Sample {
            hit: None,
            proj: None,
            cos: 0.0,
            specular: 0.0,
        };
        if !(nx.is_finite() && ny.is_finite()) {
            return none;
        }
        let d = Vector3::new(nx, ny, 1.0).normalize();
        let Some(hit) = self.scene.cast(&Point3::origin(), &d, MAX_RAY_MM) else {
            return none;
        };
        let unlit = Sample {
            hit: Some(hit),
            proj: None,
            cos: 0.0,
            specular: 0.0,
        };
        let centre = Point3::from(self.t_cam_proj.translation.vector);
        let to_proj = centre - hit.point;
        let Some(l) = to_proj.try_normalize(0.0) else {
            return unlit;
        };
        let cos = hit.normal.dot(&l);
        if cos <= 0.0 {
            return unlit;
        }
        let p_proj = crate::raycast::inverse_transform(self.t_cam_proj, &hit.point);
        let Some(q) = self.projector.project(&p_proj) else {
            return unlit;
        };
        let (pw, ph) = self.projector.size();
        // The projector's image spans [-0.5, w - 0.5) x [-0.5, h - 0.5) (pixel centres at
        // integers).
        if !(q.x >= -0.5 && q.y >= -0.5 && q.x < f64::from(pw) - 0.5 && q.y < f64::from(ph) - 0.5) {
            return unlit;
        }
        if self.scene.occluded(&hit.point, &hit.normal, &centre) {
            return unlit;
        }
        // The lobe about the half vector between the directions to the camera (-d) and to
        // the projector (l).
        let specular = self.scene.gloss(hit.object).map_or(0.0, |g| {
            (l - d)
                .try_normalize(0.0)
                .map_or(0.0, |h| g.lobe(hit.normal.dot(&h)))
        });
        Sample {
            hit: Some(hit),
            proj: Some(q),
            cos,
            specular,
        }
    }

    /// The edges (camera frame, mm) of the footprint of `hit`'s sub-sample (`k`-th of camera
    /// row `y`, whose normalised ray is `ray`): the parallelogram that the sub-sample's square
    /// covers on the tangent plane at the hit ([`crate::footprint`]). `None` for untextured
    /// surfaces, rays grazing the surface, and sub-samples without neighbours, where the
    /// point albedo is kept.
    fn footprint_edges(
        &self,
        hit: &crate::Hit,
        ray: &[f32; 2],
        y: usize,
        k: usize,
    ) -> Option<(Vector3<f64>, Vector3<f64>)> {
        if !self.scene.is_textured(hit.object) {
            return None;
        }
        let s = self.rays.supersampling as usize;
        let per_pixel = s * s;
        let (x, sub) = (k / per_pixel, k % per_pixel);
        let gx = (x * s + sub % s) as i64;
        let gy = (y * s + sub / s) as i64;
        let (dx, dy) = self.rays.differentials(gx, gy)?;
        let r = Vector3::new(f64::from(ray[0]), f64::from(ray[1]), 1.0);
        let n = hit.normal;
        let nr = n.dot(&r);
        if nr.abs() < GRAZING_COS * r.norm() {
            return None;
        }
        // A ray r' meets the tangent plane n·X = n·p at X = r' (n·p)/(n·r'); its change for a
        // change δ of the ray is ((n·r) δ − r (n·δ)) (n·p)/(n·r)².
        let c = n.dot(&hit.point.coords) / (nr * nr);
        let edge = |d: [f64; 2]| {
            let delta = Vector3::new(d[0], d[1], 0.0);
            (delta * nr - r * n.dot(&delta)) * c
        };
        Some((edge(dx), edge(dy)))
    }

    /// The albedo of `hit` averaged over the footprint of its sub-sample
    /// ([`Caster::footprint_edges`]), or its point albedo.
    fn footprint_albedo(&self, hit: &crate::Hit, ray: &[f32; 2], y: usize, k: usize) -> f64 {
        match self.footprint_edges(hit, ray, y, k) {
            Some((ex, ey)) => self.scene.albedo_over(hit, &ex, &ey),
            None => hit.albedo,
        }
    }

    /// The RGB albedo of `hit` averaged over the footprint of its sub-sample, or at its point.
    fn footprint_albedo_rgb(
        &self,
        hit: &crate::Hit,
        ray: &[f32; 2],
        y: usize,
        k: usize,
    ) -> [f64; 3] {
        match self.footprint_edges(hit, ray, y, k) {
            Some((ex, ey)) => self.scene.albedo_rgb_over(hit, &ex, &ey),
            None => self.scene.albedo_rgb_at(hit),
        }
    }

    /// Casts every sub-sample of the view.
    pub(crate) fn geometry(&self) -> ViewGeometry {
        let (w, h) = (self.rays.width, self.rays.height);
        let (pw, ph) = self.projector.size();
        let s = self.rays.supersampling;
        let per_pixel = (s * s) as usize;
        let n = self.rays.sub.len();
        let mut proj_xy = vec![[f32::NAN; 2]; n];
        let mut proj_index = vec![UNLIT; n];
        let mut lit_weight = vec![0.0f32; n];
        let mut ambient_weight = vec![0.0f32; n];
        let row_len = (w as usize * per_pixel).max(1);
        let coloured = self.scene.has_colour();
        let mut colour = vec![[0.0f32; 4]; if coloured { n } else { 0 }];
        // A grey scene's empty colour buffer still zips with every row: an empty slice each.
        let mut colour_rows: Vec<&mut [[f32; 4]]> = if coloured {
            colour.chunks_mut(row_len).collect()
        } else {
            (0..self.rays.height.max(1) as usize)
                .map(|_| &mut [][..])
                .collect()
        };
        proj_xy
            .par_chunks_mut(row_len)
            .zip(proj_index.par_chunks_mut(row_len))
            .zip(lit_weight.par_chunks_mut(row_len))
            .zip(ambient_weight.par_chunks_mut(row_len))
            .zip(self.rays.sub.par_chunks(row_len))
            .zip(colour_rows.par_iter_mut())
            .enumerate()
            .for_each(|(y, (((((xy, idx), lit), amb), rays), rgb))| {
                for (k, r) in rays.iter().enumerate() {
                    let smp = self.sample(f64::from(r[0]), f64::from(r[1]));
                    if let (Some(hit), Some(a)) = (smp.hit, amb.get_mut(k)) {
                        let albedo = self.footprint_albedo(&hit, r, y, k);
                        *a = albedo as f32;
                        if let Some(c) = rgb.get_mut(k) {
                            let [cr, cg, cb] = self.footprint_albedo_rgb(&hit, r, y, k);
                            let cos = if smp.proj.is_some() { smp.cos } else { 0.0 };
                            *c = [cr as f32, cg as f32, cb as f32, cos as f32];
                        }
                        if let (Some(q), Some(l), Some(i), Some(c)) =
                            (smp.proj, lit.get_mut(k), idx.get_mut(k), xy.get_mut(k))
                        {
                            *l = ((albedo + smp.specular) * smp.cos) as f32;
                            *c = [q.x as f32, q.y as f32];
                            // Nearest projector pixel: the square containing q.
                            let qx = ((q.x + 0.5).floor() as u32).min(pw.saturating_sub(1));
                            let qy = ((q.y + 0.5).floor() as u32).min(ph.saturating_sub(1));
                            *i = qy * pw + qx;
                        }
                    }
                }
            });
        ViewGeometry {
            width: w,
            height: h,
            supersampling: s,
            projector_width: pw,
            projector_height: ph,
            proj_xy,
            proj_index,
            lit_weight,
            ambient_weight,
            depth_mm: Vec::new(),
            colour,
        }
    }
}
