//! The triangulator: built once per calibration, run on every correspondence map.

use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;
use sl_camera::{Calibration, CameraModel, RayTable};
use sl_cloud::PointCloud;
use sl_codec::CorrespondenceMap;

use crate::grid_normals::normal_at;
use crate::kernel::{BLOCK, BlockOut, Pass};
use crate::mixed_pixels::filter_mixed_pixels;
use crate::stereo::Stereo;
use crate::{PointStatus, Texture, TriCounts, TriError, TriOptions, Triangulation};

/// Smallest number of blocks a parallel task takes: 16 blocks (2048 pixels), so that the
/// task overhead is negligible while the two cores still get dozens of tasks each to
/// balance.
const MIN_BLOCKS_PER_TASK: usize = 16;

/// Pixels per band of the cloud compaction: as many as a task of the pass.
const MIN_PIXELS_PER_TASK: usize = MIN_BLOCKS_PER_TASK * BLOCK;

/// Turns correspondence maps into points for one calibration.
///
/// Building it computes what every map needs: the undistorted ray of every camera pixel
/// ([`RayTable`], structure of arrays), the pose both ways and the lens models. The
/// projector's ray table, which only the methods using both decoded coordinates need, is
/// built on their first use. [`Triangulator::triangulate`] then runs in parallel (rayon)
/// without allocating per pixel.
#[derive(Clone, Debug)]
pub struct Triangulator {
    camera: CameraModel,
    camera_rays: RayTable,
    stereo: Stereo,
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
        Ok(Self {
            camera: *camera,
            camera_rays: camera.ray_table(),
            stereo: Stereo::new(camera, projector, t_cam_proj),
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

        let proj_rays = options
            .method
            .needs_both()
            .then(|| self.stereo.proj_rays());
        let pass = Pass {
            stereo: &self.stereo,
            rays: &self.camera_rays,
            proj_rays,
            map,
            options,
            width,
            arch: pulp::Arch::new(),
        };
        // The per-pixel pass, block by block, collected straight into the three organised
        // vectors by an indexed parallel iterator (each worker writes its own range, nothing
        // is initialised twice), then flattened without a copy.
        type Blocks = (
            Vec<[Point3<f64>; BLOCK]>,
            (Vec<[f32; BLOCK]>, Vec<[PointStatus; BLOCK]>),
        );
        let (points, (reprojection, status)): Blocks = (0..n.div_ceil(BLOCK))
            .into_par_iter()
            .with_min_len(MIN_BLOCKS_PER_TASK)
            .map(|b| {
                let BlockOut {
                    points,
                    reprojection,
                    status,
                } = pass.block(b * BLOCK);
                (points, (reprojection, status))
            })
            .unzip();
        let mut points = points.into_flattened();
        let mut reprojection = reprojection.into_flattened();
        let mut status = status.into_flattened();
        points.truncate(n);
        reprojection.truncate(n);
        status.truncate(n);
        filter_mixed_pixels(&mut points, &mut status, width, options.max_depth_jump);
        let counts = TriCounts::from_status(&status);
        let cloud_pixels = valid_pixels(&status, width, counts.valid);

        // The cloud: gathers of the organised vectors at the valid pixels, in parallel.
        let nan = Point3::new(f64::NAN, f64::NAN, f64::NAN);
        let positions: Vec<Point3<f64>> = cloud_pixels
            .par_iter()
            .map(|&i| points.get(i as usize).copied().unwrap_or(nan))
            .collect();
        let quality: Vec<f32> = cloud_pixels
            .par_iter()
            .map(|&i| map.quality.get(i as usize).copied().unwrap_or(f32::NAN))
            .collect();
        let colors = texture.map(|t| {
            cloud_pixels
                .par_iter()
                .map(|&i| t.color(i as usize))
                .collect::<Vec<_>>()
        });
        let normals = options.normals.then(|| {
            cloud_pixels
                .par_iter()
                .map(|&i| normal_at(&points, width, i as usize).unwrap_or_else(Vector3::zeros))
                .collect::<Vec<_>>()
        });
        let cloud = PointCloud::from_parts(positions, normals, colors, Some(quality))?;
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
}

/// Indices of the valid pixels, in order: counts per band of rows, prefix sums, then every
/// band fills its own slice of the output in parallel.
fn valid_pixels(status: &[PointStatus], width: usize, valid: usize) -> Vec<u32> {
    let chunk = MIN_PIXELS_PER_TASK.div_ceil(width.max(1)).max(1) * width.max(1);
    let counts: Vec<usize> = status
        .par_chunks(chunk)
        .map(|band| band.iter().filter(|s| **s == PointStatus::Valid).count())
        .collect();
    let mut out = vec![0u32; valid];
    let mut slices = Vec::with_capacity(counts.len());
    let mut rest: &mut [u32] = &mut out;
    for &c in &counts {
        let (head, tail) = rest.split_at_mut(c.min(rest.len()));
        slices.push(head);
        rest = tail;
    }
    slices
        .into_par_iter()
        .zip(status.par_chunks(chunk))
        .enumerate()
        .for_each(|(k, (slice, band))| {
            let base = k * chunk;
            let indices = band
                .iter()
                .enumerate()
                .filter(|(_, s)| **s == PointStatus::Valid)
                .map(|(x, _)| (base + x) as u32);
            for (o, i) in slice.iter_mut().zip(indices) {
                *o = i;
            }
        });
    out
}
