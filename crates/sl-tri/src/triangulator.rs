//! The triangulator: built once per calibration, run on every correspondence map.

use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;
use sl_camera::{Calibration, CameraModel, RayTable};
use sl_cloud::PointCloud;
use sl_codec::{Axis, CorrespondenceMap};

use crate::camera_rays::camera_ray_table;
use crate::grid_normals::cloud_normals;
use crate::kernel::{BLOCK, BlockOut, Pass};
use crate::mixed_pixels::filter_mixed_pixels;
use crate::options::Solver;
use crate::stereo::Stereo;
use crate::{PointStatus, Texture, TriConfig, TriCounts, TriError, Triangulation};

/// Smallest number of blocks a parallel task takes: 16 blocks (2048 pixels), so that the
/// task overhead is negligible while the two cores still get dozens of tasks each to
/// balance.
const MIN_BLOCKS_PER_TASK: usize = 16;

/// Pixels per band of the cloud compaction: as many as a task of the pass.
const MIN_PIXELS_PER_TASK: usize = MIN_BLOCKS_PER_TASK * BLOCK;

/// Turns correspondence maps into points for one calibration.
///
/// Building it computes what every map needs: the undistorted ray of every camera pixel
/// ([`RayTable`], structure of arrays), the pose both ways and the lens models. The methods
/// that use both decoded coordinates undistort the projector points per pixel (vectorised
/// Newton steps from the neighbouring pixels' answers), so no projector table is built.
/// [`Triangulator::triangulate`] then runs in parallel (rayon) without allocating per pixel.
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
            camera_rays: camera_ray_table(camera)?,
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
    /// short; [`TriError::InvalidParameter`] for a bad option; [`TriError::MissingAxis`] if
    /// the method needs a projector axis the map does not code (midpoint on a column-only
    /// capture; linear and optimal work with one axis, see [`crate::Method`]).
    pub fn triangulate(
        &self,
        map: &CorrespondenceMap,
        options: &TriConfig,
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
        options: &TriConfig,
    ) -> Result<Triangulation, TriError> {
        let mut out = Triangulation::empty();
        self.triangulate_into(map, texture, options, &mut out)?;
        Ok(out)
    }

    /// [`Triangulator::triangulate_textured`] into an existing [`Triangulation`], reusing the
    /// memory of its vectors: for a stream of maps (the views of a scan) this saves the
    /// allocation and the first touch of ~60 MB per 1280×720 map, which on a virtual machine
    /// costs as much as the triangulation itself (page faults; see `docs/triangulation.md`).
    /// `out` is entirely overwritten; on error it is left in an unspecified but valid state.
    ///
    /// ```
    /// # use nalgebra::{Isometry3, Translation3};
    /// # use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
    /// # use sl_codec::CorrespondenceMap;
    /// # use sl_tri::{TriConfig, Triangulation, Triangulator};
    /// # let k = Intrinsics::new(80.0, 80.0, 31.5, 23.5);
    /// # let cam = CameraModel::new(k, Distortion::none(), ImageSize::new(64, 48))?;
    /// # let pose = Isometry3::from_parts(Translation3::new(100.0, 0.0, 0.0), Default::default());
    /// let tri = Triangulator::from_models(&cam, &cam, &pose)?;
    /// let mut result = tri.triangulate(&CorrespondenceMap::new(64, 48), &TriConfig::default())?;
    /// for _view in 0..3 {
    ///     let map = CorrespondenceMap::new(64, 48); // the next decoded view
    ///     tri.triangulate_into(&map, None, &TriConfig::default(), &mut result)?;
    /// }
    /// # Ok::<(), sl_tri::TriError>(())
    /// ```
    ///
    /// # Errors
    /// As [`Triangulator::triangulate_textured`].
    pub fn triangulate_into(
        &self,
        map: &CorrespondenceMap,
        texture: Option<Texture<'_>>,
        options: &TriConfig,
        out: &mut Triangulation,
    ) -> Result<(), TriError> {
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

        // The axes the map codes: a one-axis capture changes what linear and optimal solve and
        // is refused by the midpoint method.
        let coded = |v: &[f32]| v.iter().any(|x| x.is_finite());
        let solver = options
            .method
            .solver(coded(&map.col), coded(&map.row))?
            // No axis coded: every pixel ends `NotDecoded` whatever the solver.
            .unwrap_or(Solver::RayPlane(Axis::Column));
        let pass = Pass {
            stereo: &self.stereo,
            rays: &self.camera_rays,
            map,
            options,
            solver,
            width,
            arch: pulp::Arch::new(),
        };
        // The per-pixel pass, block by block in parallel, straight into the organised
        // vectors (sized, and filled in parallel, only when their length changes: the pass
        // overwrites every entry).
        let nan = Point3::new(f64::NAN, f64::NAN, f64::NAN);
        resize(&mut out.points, n, nan);
        resize(&mut out.reprojection_px, n, f32::NAN);
        resize(&mut out.status, n, PointStatus::NotDecoded);
        out.points
            .par_chunks_mut(BLOCK)
            .zip(out.reprojection_px.par_chunks_mut(BLOCK))
            .zip(out.status.par_chunks_mut(BLOCK))
            .enumerate()
            .with_min_len(MIN_BLOCKS_PER_TASK)
            .for_each(|(b, ((points, reprojection), status))| {
                let block = BlockOut {
                    points,
                    reprojection,
                    status,
                };
                pass.block(b * BLOCK, block);
            });
        let points = &mut out.points;
        let status = &mut out.status;
        filter_mixed_pixels(points, status, width, options.max_depth_jump);
        let counts = TriCounts::from_status(status);
        let band_rows = MIN_PIXELS_PER_TASK.div_ceil(width.max(1)).max(1);
        let band_counts = valid_pixels(
            status,
            width,
            band_rows,
            counts.valid,
            &mut out.cloud_pixels,
        );

        // The cloud: gathers of the organised vectors at the valid pixels, in parallel, into
        // the previous cloud's vectors.
        let (mut positions, old_normals, old_colors, old_quality) =
            std::mem::take(&mut out.cloud).into_parts();
        let cloud_pixels = &out.cloud_pixels;
        let points = &out.points;
        positions.clear();
        positions.par_extend(
            cloud_pixels
                .par_iter()
                .map(|&i| points.get(i as usize).copied().unwrap_or(nan)),
        );
        let mut quality = old_quality.unwrap_or_default();
        quality.clear();
        quality.par_extend(
            cloud_pixels
                .par_iter()
                .map(|&i| map.quality.get(i as usize).copied().unwrap_or(f32::NAN)),
        );
        let colors = texture.map(|t| {
            let mut colors = old_colors.unwrap_or_default();
            colors.clear();
            colors.par_extend(cloud_pixels.par_iter().map(|&i| t.color(i as usize)));
            colors
        });
        let normals = options.normals.then(|| {
            let mut normals = old_normals.unwrap_or_default();
            resize(&mut normals, counts.valid, Vector3::zeros());
            cloud_normals(points, width, band_rows, &band_counts, &mut normals);
            normals
        });
        out.cloud = PointCloud::from_parts(positions, normals, colors, Some(quality))?;
        out.width = width;
        out.height = height;
        out.counts = counts;
        Ok(())
    }
}

/// Gives `v` the length `n`; when the length changes, refilled with `fill` in parallel (so
/// the first touch of fresh pages is shared by the cores).
fn resize<T: Copy + Send + Sync>(v: &mut Vec<T>, n: usize, fill: T) {
    if v.len() != n {
        v.clear();
        v.par_extend(rayon::iter::repeat_n(fill, n));
    }
}

/// Indices of the valid pixels, in order, into `out`: counts per band of `band_rows` rows
/// (returned), prefix sums, then every band fills its own slice of the output in parallel.
fn valid_pixels(
    status: &[PointStatus],
    width: usize,
    band_rows: usize,
    valid: usize,
    out: &mut Vec<u32>,
) -> Vec<usize> {
    let chunk = band_rows * width.max(1);
    let counts: Vec<usize> = status
        .par_chunks(chunk)
        .map(|band| band.iter().filter(|s| **s == PointStatus::Valid).count())
        .collect();
    if out.capacity() >= valid {
        out.clear();
        out.resize(valid, 0);
    } else {
        // Fresh zeroed memory: no page is written before its band fills it.
        *out = vec![0u32; valid];
    }
    let mut slices = Vec::with_capacity(counts.len());
    let mut rest: &mut [u32] = out;
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
    counts
}
