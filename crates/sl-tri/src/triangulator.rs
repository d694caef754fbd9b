//! The triangulator: built once per calibration, run on every correspondence map.

use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;
use sl_camera::{Calibration, CameraModel, RayTable};
use sl_cloud::PointCloud;
use sl_codec::{Axis, CorrespondenceMap};

use crate::grid_normals::grid_normals;
use crate::lens::Lens;
use crate::linear::linear_point;
use crate::midpoint::midpoint;
use crate::mixed_pixels::filter_mixed_pixels;
use crate::optimal::refine;
use crate::ray_plane::ray_surface_depth;
use crate::stereo::Stereo;
use crate::{Method, PointStatus, Texture, TriCounts, TriError, TriOptions, Triangulation};

/// Turns correspondence maps into points for one calibration.
///
/// Building it computes what every map needs: the undistorted ray of every camera pixel
/// ([`RayTable`]), the projector's ray table, the pose both ways and flat copies of both lens
/// models. [`Triangulator::triangulate`] then runs row-parallel (rayon) without allocating
/// per pixel.
#[derive(Clone, Debug)]
pub struct Triangulator {
    camera: CameraModel,
    camera_rays: RayTable,
    stereo: Stereo,
}

/// One pixel's answer of the first pass.
struct Solved {
    p: Vector3<f64>,
    reprojection: f64,
}

impl Triangulator {
    /// Precomputes everything for `calibration`.
    ///
    /// # Errors
    /// [`TriError::MissingCalibration`] if the projector model or `t_cam_proj` is absent;
    /// [`TriError::Camera`] if a model is invalid.
    pub fn new(calibration: &Calibration) -> Result<Self, TriError> {
        let projector = calibration
            .projector
            .ok_or(TriError::MissingCalibration { what: "projector" })?;
        let t_cam_proj = calibration
            .t_cam_proj
            .ok_or(TriError::MissingCalibration { what: "t_cam_proj" })?;
        Self::from_models(&calibration.camera, &projector, &t_cam_proj)
    }

    /// Precomputes everything for a camera, a projector and `T_cam_proj` (maps projector
    /// coordinates into camera coordinates).
    ///
    /// # Errors
    /// [`TriError::Camera`] if a model is invalid; [`TriError::InvalidParameter`] if the pose
    /// is not finite.
    pub fn from_models(
        camera: &CameraModel,
        projector: &CameraModel,
        t_cam_proj: &Isometry3<f64>,
    ) -> Result<Self, TriError> {
        camera.validate()?;
        projector.validate()?;
        let finite = t_cam_proj
            .translation
            .vector
            .iter()
            .chain(t_cam_proj.rotation.coords.iter())
            .all(|v| v.is_finite());
        if !finite {
            return Err(TriError::param("t_cam_proj", "pose is not finite"));
        }
        let t_proj_cam = t_cam_proj.inverse();
        let r_pc = *t_proj_cam.rotation.to_rotation_matrix().matrix();
        let r_cp = *t_cam_proj.rotation.to_rotation_matrix().matrix();
        let stereo = Stereo {
            cam: Lens::new(camera),
            proj: Lens::new(projector),
            r_pc,
            t_pc: t_proj_cam.translation.vector,
            r_cp,
            c_p: t_cam_proj.translation.vector,
            proj_model: *projector,
            proj_rays: projector.ray_table(),
        };
        Ok(Self {
            camera: *camera,
            camera_rays: camera.ray_table(),
            stereo,
        })
    }

    /// The camera model.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// The per-pixel undistorted camera rays.
    pub fn camera_rays(&self) -> &RayTable {
        &self.camera_rays
    }

    /// Triangulates a correspondence map (camera-sized) without colours.
    ///
    /// # Errors
    /// [`TriError::SizeMismatch`] if the map is not the camera's size or its vectors are
    /// short; [`TriError::InvalidParameter`] for a bad option.
    pub fn triangulate(
        &self,
        map: &CorrespondenceMap,
        options: &TriOptions,
    ) -> Result<Triangulation, TriError> {
        self.triangulate_textured(map, None, options)
    }

    /// Triangulates a correspondence map, colouring the cloud from `texture` (a fully lit
    /// camera frame, one value per pixel).
    ///
    /// # Errors
    /// As [`Triangulator::triangulate`], and [`TriError::SizeMismatch`] for a texture of the
    /// wrong length.
    pub fn triangulate_textured(
        &self,
        map: &CorrespondenceMap,
        texture: Option<Texture<'_>>,
        options: &TriOptions,
    ) -> Result<Triangulation, TriError> {
        options.validate()?;
        let size = self.camera.size;
        let (width, height) = (size.width as usize, size.height as usize);
        let n = width * height;
        if map.width != width || map.height != height {
            return Err(TriError::SizeMismatch {
                what: "correspondence map",
                expected: size.to_string(),
                found: format!("{}x{}", map.width, map.height),
            });
        }
        let shortest = map
            .col
            .len()
            .min(map.row.len())
            .min(map.quality.len())
            .min(map.invalid.len());
        if shortest != n {
            return Err(TriError::SizeMismatch {
                what: "correspondence map vectors",
                expected: n.to_string(),
                found: shortest.to_string(),
            });
        }
        if let Some(t) = &texture
            && t.len() != n
        {
            return Err(TriError::SizeMismatch {
                what: "texture",
                expected: n.to_string(),
                found: t.len().to_string(),
            });
        }

        let nan = Point3::new(f64::NAN, f64::NAN, f64::NAN);
        let mut points = vec![nan; n];
        let mut reprojection = vec![f32::NAN; n];
        let mut status = vec![PointStatus::NotDecoded; n];
        if width > 0 {
            points
                .par_chunks_mut(width)
                .zip(reprojection.par_chunks_mut(width))
                .zip(status.par_chunks_mut(width))
                .enumerate()
                .for_each(|(y, ((p_row, e_row), s_row))| {
                    self.row(map, options, y, p_row, e_row, s_row);
                });
        }
        filter_mixed_pixels(&mut points, &mut status, width, options.max_depth_jump);
        let normals = options.normals.then(|| grid_normals(&points, width));

        // Compaction into the cloud.
        let counts = TriCounts::from_status(&status);
        let mut positions = Vec::with_capacity(counts.valid);
        let mut quality = Vec::with_capacity(counts.valid);
        let mut cloud_pixels = Vec::with_capacity(counts.valid);
        let mut colors = texture.map(|_| Vec::with_capacity(counts.valid));
        let mut cloud_normals = normals.as_ref().map(|_| Vec::with_capacity(counts.valid));
        for (i, (p, s)) in points.iter().zip(&status).enumerate() {
            if *s != PointStatus::Valid {
                continue;
            }
            positions.push(*p);
            quality.push(map.quality.get(i).copied().unwrap_or(f32::NAN));
            cloud_pixels.push(i as u32);
            if let (Some(c), Some(t)) = (colors.as_mut(), texture.as_ref()) {
                c.push(t.color(i));
            }
            if let (Some(out), Some(all)) = (cloud_normals.as_mut(), normals.as_ref()) {
                out.push(all.get(i).copied().unwrap_or_else(Vector3::zeros));
            }
        }
        let cloud = PointCloud::from_parts(positions, cloud_normals, colors, Some(quality))?;
        Ok(Triangulation {
            width,
            height,
            points,
            reprojection_px: reprojection,
            status,
            cloud,
            cloud_pixels,
            counts,
        })
    }

    /// First pass over one camera row: solve, then the per-pixel filters.
    fn row(
        &self,
        map: &CorrespondenceMap,
        options: &TriOptions,
        y: usize,
        p_row: &mut [Point3<f64>],
        e_row: &mut [f32],
        s_row: &mut [PointStatus],
    ) {
        let width = p_row.len();
        let base = y * width;
        let rays = self.camera_rays.as_slice();
        for (x, ((p_out, e_out), s_out)) in p_row
            .iter_mut()
            .zip(e_row.iter_mut())
            .zip(s_row.iter_mut())
            .enumerate()
        {
            let i = base + x;
            let (Some(c), Some(r), Some(q), Some(inv)) = (
                map.col.get(i),
                map.row.get(i),
                map.quality.get(i),
                map.invalid.get(i),
            ) else {
                continue;
            };
            let (c, r) = (f64::from(*c), f64::from(*r));
            let decoded = inv.is_valid()
                && match options.method {
                    Method::RayPlane { axis: Axis::Column } => c.is_finite(),
                    Method::RayPlane { axis: Axis::Row } => r.is_finite(),
                    _ => c.is_finite() && r.is_finite(),
                };
            if !decoded {
                continue;
            }
            if !(*q >= options.min_quality) {
                *s_out = PointStatus::LowQuality;
                continue;
            }
            let Some(Some(n)) = rays.get(i) else {
                *s_out = PointStatus::NoSolution;
                continue;
            };
            let ray = Vector3::new(n.x, n.y, 1.0);
            let Some(solved) = self.solve(options, &ray, (x as f64, y as f64), c, r) else {
                *s_out = PointStatus::NoSolution;
                continue;
            };
            *e_out = solved.reprojection as f32;
            let z = solved.p.z;
            *s_out = if !(z >= options.min_depth_mm && z <= options.max_depth_mm) {
                PointStatus::OutOfDepthRange
            } else if !(solved.reprojection <= options.max_reprojection_px) {
                PointStatus::Reprojection
            } else {
                *p_out = Point3::from(solved.p);
                PointStatus::Valid
            };
        }
    }

    #[inline]
    fn solve(
        &self,
        options: &TriOptions,
        ray: &Vector3<f64>,
        (u, v): (f64, f64),
        c: f64,
        r: f64,
    ) -> Option<Solved> {
        let s = &self.stereo;
        let p = match options.method {
            Method::RayPlane { axis } => {
                let target = if axis == Axis::Column { c } else { r };
                ray * ray_surface_depth(s, ray, target, axis)?
            }
            Method::Linear => {
                let (xp, yp) = s.proj_normalised(c, r)?;
                linear_point(s, ray, xp, yp)?
            }
            Method::Midpoint => {
                let (xp, yp) = s.proj_normalised(c, r)?;
                midpoint(s, ray, xp, yp)?
            }
            Method::Optimal => {
                let start = ray * ray_surface_depth(s, ray, c, Axis::Column)?;
                refine(s, start, (u, v), (c, r), options.optimal_iterations)?
            }
        };
        let reprojection = s.reprojection(&p, u, v, c, r)?;
        Some(Solved { p, reprojection })
    }
}
