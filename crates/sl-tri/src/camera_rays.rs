//! The camera's ray table, built with the vectorised undistortion of [`crate::undistort`].
//!
//! `sl_camera::RayTable::new` undistorts each pixel by a scalar Newton iteration (warm-started
//! from its left neighbours); here each row is undistorted [`LANES`] pixels at a time inside
//! `pulp`'s runtime dispatch, with the same acceptance test and the same scalar fallback, so
//! the table holds the same rays (tested against `RayTable::new`) for a fraction of the time
//! of `Triangulator::new`.

use rayon::prelude::*;
use sl_camera::{CameraModel, RayTable};

use crate::TriError;
use crate::kernel::LANES;
use crate::undistort::{UndistortWarm, undistort_lanes};

/// The undistorted normalised ray of every pixel of `camera` (NaN where it has none).
///
/// # Errors
/// [`TriError::Camera`] if the table cannot be assembled (not for any valid model).
pub(crate) fn camera_ray_table(camera: &CameraModel) -> Result<RayTable, TriError> {
    let width = camera.size.width as usize;
    let n = camera.size.pixel_count();
    // Zero-initialised (fresh zero pages, not written twice); every entry is written once by
    // the worker that owns its row.
    let mut x = vec![0.0; n];
    let mut y = vec![0.0; n];
    if width > 0 {
        let arch = pulp::Arch::new();
        x.par_chunks_mut(width)
            .zip(y.par_chunks_mut(width))
            .enumerate()
            .for_each(|(row, (xs, ys))| {
                arch.dispatch(RowJob {
                    camera,
                    row: row as f64,
                    xs,
                    ys,
                });
            });
    }
    Ok(RayTable::from_parts(camera.size, x, y)?)
}

/// One row of the table as a `pulp` operation.
struct RowJob<'a> {
    camera: &'a CameraModel,
    row: f64,
    xs: &'a mut [f64],
    ys: &'a mut [f64],
}

impl pulp::WithSimd for RowJob<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        let mut warm = UndistortWarm::default();
        let r = [self.row; LANES];
        for (k, (xs, ys)) in self
            .xs
            .chunks_mut(LANES)
            .zip(self.ys.chunks_mut(LANES))
            .enumerate()
        {
            let first = (k * LANES) as f64;
            // Lanes past the row's end get NaN (no ray, nothing to solve).
            let c: [f64; LANES] = std::array::from_fn(|l| {
                if l < xs.len() {
                    first + l as f64
                } else {
                    f64::NAN
                }
            });
            let (gx, gy) = undistort_lanes(self.camera, &c, &r, &mut warm);
            for ((ox, oy), (gx, gy)) in xs.iter_mut().zip(ys.iter_mut()).zip(gx.iter().zip(&gy)) {
                (*ox, *oy) = (*gx, *gy);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_camera::{Distortion, ImageSize, Intrinsics};

    /// The table equals `RayTable::new`'s (both solve the same equation to its rounding
    /// level with the same acceptance test: 1e-13 normalised is 1e-10 px) everywhere, with
    /// NaN at the same pixels: the virtual rig's camera, the strong lens of SLStudio's
    /// example calibration (where the valid region ends inside the image) and a width that
    /// is not a multiple of the lane count.
    #[test]
    fn equals_the_scalar_table() {
        let rig = sl_sim::RigConfig::default().calibration().camera;
        let small = |d: Distortion| {
            CameraModel::new(
                Intrinsics::new(144.04, 143.71, 66.78, 35.42),
                d,
                ImageSize::new(131, 72),
            )
            .unwrap()
        };
        let cameras = [
            rig,
            small(Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1]).unwrap()),
            small(Distortion::from_opencv(&[-0.3, 0.1, 0.001, -0.002, 0.0]).unwrap()),
            small(Distortion::none()),
        ];
        for camera in cameras {
            let ours = camera_ray_table(&camera).unwrap();
            let reference = camera.ray_table();
            assert_eq!(ours.size(), reference.size());
            let mut worst = 0.0f64;
            for (i, ((x, y), (rx, ry))) in ours
                .xs()
                .iter()
                .zip(ours.ys())
                .zip(reference.xs().iter().zip(reference.ys()))
                .enumerate()
            {
                assert_eq!(x.is_nan(), rx.is_nan(), "pixel {i}: {x} vs {rx}");
                if rx.is_finite() {
                    let e = (x - rx).abs().max((y - ry).abs());
                    worst = worst.max(e);
                    assert!(e < 1e-13, "pixel {i}: ({x}, {y}) vs ({rx}, {ry})");
                }
            }
            eprintln!(
                "{:?}: {} rays, worst {worst:e}",
                camera.distortion.coefficients(),
                reference.valid_count()
            );
        }
    }
}
