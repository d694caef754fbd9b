//! Per-pixel undistorted rays of a whole image, computed once per calibration.

use nalgebra::{Point2, Vector3};
use rayon::prelude::*;

use crate::{CameraError, CameraModel, ImageSize};

/// The undistorted normalised ray `(x, y, 1)` of every pixel centre of an image, row-major.
///
/// Triangulation needs the ray of each pixel once per calibration; computing the table once
/// and reusing it saves the Newton undistortion per frame. Rows are computed in parallel
/// (rayon); within a row each pixel's Newton iteration starts from its left neighbour's
/// solution (extrapolated from the two before it), which converges in 1–2 steps (and falls back to the full radial start if it
/// does not), so the table is several times faster than unprojecting each pixel alone. The
/// answers are the same: every entry passes the same convergence and validity checks as
/// [`CameraModel::unproject`].
///
/// ```
/// use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
/// use nalgebra::Point2;
/// let cam = CameraModel::new(
///     Intrinsics::new(500.0, 500.0, 31.5, 23.5),
///     Distortion::from_opencv(&[-0.1, 0.01, 0.0, 0.0, 0.0])?,
///     ImageSize::new(64, 48),
/// )?;
/// let table = cam.ray_table();
/// let ray = table.get(10, 20).unwrap();
/// let direct = cam.unproject(&Point2::new(10.0, 20.0)).unwrap();
/// assert!((ray - direct).norm() < 1e-12);
/// assert!(table.get(64, 0).is_none()); // outside the image
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct RayTable {
    size: ImageSize,
    /// Normalised `x` of every pixel, row-major; NaN where the model has no ray.
    x: Vec<f64>,
    /// Normalised `y` of every pixel, row-major; NaN where the model has no ray.
    y: Vec<f64>,
}

impl RayTable {
    /// Computes the table of a camera (see [`CameraModel::ray_table`]).
    pub fn new(camera: &CameraModel) -> Self {
        let width = camera.size.width as usize;
        let n = camera.size.pixel_count();
        // Zero-initialised (the allocator hands out fresh zero pages without writing them);
        // every entry is then written once, by the worker that owns its row.
        let mut x = vec![0.0; n];
        let mut y = vec![0.0; n];
        if width > 0 {
            x.par_chunks_mut(width)
                .zip(y.par_chunks_mut(width))
                .enumerate()
                .for_each(|(row, (xs, ys))| fill_row(camera, row, xs, ys));
        }
        Self {
            size: camera.size,
            x,
            y,
        }
    }

    /// A table from normalised points computed elsewhere (e.g. by a vectorised
    /// undistortion): `x[i]`, `y[i]` is the undistorted normalised point of pixel `i`
    /// (row-major, `i = y · width + x`), NaN where the model has no ray. The caller answers
    /// for the values; [`RayTable::new`] is the reference they should equal.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] if `x` or `y` does not have one entry per pixel.
    pub fn from_parts(size: ImageSize, x: Vec<f64>, y: Vec<f64>) -> Result<Self, CameraError> {
        let n = size.pixel_count();
        if x.len() != n || y.len() != n {
            return Err(CameraError::invalid(
                "ray table",
                format!(
                    "{} x and {} y values for {n} pixels ({}x{})",
                    x.len(),
                    y.len(),
                    size.width,
                    size.height
                ),
            ));
        }
        Ok(Self { size, x, y })
    }

    /// Image size.
    pub fn size(&self) -> ImageSize {
        self.size
    }

    /// Ray `(x, y, 1)` of pixel column `x`, row `y`; `None` outside the image or where the
    /// model is not invertible.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Option<Vector3<f64>> {
        self.normalised(x, y).map(|n| Vector3::new(n.x, n.y, 1.0))
    }

    /// Undistorted normalised point `(x, y)` of a pixel; `None` outside the image or where
    /// the model is not invertible.
    #[inline]
    pub fn normalised(&self, x: u32, y: u32) -> Option<Point2<f64>> {
        if x >= self.size.width || y >= self.size.height {
            return None;
        }
        let index = y as usize * self.size.width as usize + x as usize;
        let (nx, ny) = (*self.x.get(index)?, *self.y.get(index)?);
        nx.is_finite().then(|| Point2::new(nx, ny))
    }

    /// Normalised `x` of every pixel, row-major (`index = y · width + x`), NaN where the
    /// model has no ray: the structure-of-arrays layout hot loops stream through.
    pub fn xs(&self) -> &[f64] {
        &self.x
    }

    /// Normalised `y` of every pixel, row-major, NaN where the model has no ray.
    pub fn ys(&self) -> &[f64] {
        &self.y
    }

    /// Number of pixels with a ray.
    pub fn valid_count(&self) -> usize {
        self.x.iter().filter(|v| v.is_finite()).count()
    }
}

fn fill_row(camera: &CameraModel, row: usize, xs: &mut [f64], ys: &mut [f64]) {
    let v = row as f64;
    // Solutions at the two previous pixels: their linear extrapolation is within ~1e-7 of
    // this pixel's solution, so Newton needs 1–2 steps.
    let mut previous: [Option<Point2<f64>>; 2] = [None, None];
    for (col, (ox, oy)) in xs.iter_mut().zip(ys.iter_mut()).enumerate() {
        let pd = camera
            .intrinsics
            .normalised_from_pixel(&Point2::new(col as f64, v));
        let n = match previous {
            [Some(a), Some(b)] => camera
                .distortion
                .undistort_from(&pd, &Point2::from(2.0 * a.coords - b.coords)),
            [Some(a), None] => camera.distortion.undistort_from(&pd, &a),
            _ => camera.distortion.undistort(&pd),
        };
        (*ox, *oy) = n.map_or((f64::NAN, f64::NAN), |p| (p.x, p.y));
        previous = [n, previous[0]];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Distortion, Intrinsics};
    use approx::assert_relative_eq;

    #[test]
    fn table_equals_unproject_everywhere() {
        let cam = CameraModel::new(
            Intrinsics::new(144.04, 143.71, 66.78, 35.42),
            Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1]).unwrap(),
            ImageSize::new(128, 72),
        )
        .unwrap();
        let t = cam.ray_table();
        assert_eq!(t.size(), cam.size);
        assert_eq!(t.xs().len(), 128 * 72);
        assert_eq!(t.ys().len(), 128 * 72);
        for y in 0..72 {
            for x in 0..128 {
                let a = t.get(x, y);
                let b = cam.unproject(&Point2::new(f64::from(x), f64::from(y)));
                assert_eq!(a.is_some(), b.is_some(), "pixel {x},{y}");
                if let (Some(a), Some(b)) = (a, b) {
                    // Two Newton runs to the same root from different starts: a few ulps.
                    assert_relative_eq!(a, b, epsilon = 1e-14);
                }
            }
        }
        assert_eq!(t.valid_count(), 128 * 72);
        assert!(t.get(0, 72).is_none());
    }

    #[test]
    fn from_parts_checks_the_lengths() {
        let size = ImageSize::new(4, 2);
        let mut x = vec![0.5; 8];
        x[5] = f64::NAN;
        let t = RayTable::from_parts(size, x, vec![0.25; 8]).unwrap();
        assert_eq!(t.size(), size);
        assert!(t.get(1, 1).is_none()); // NaN: no ray
        assert_eq!(t.normalised(0, 1), Some(Point2::new(0.5, 0.25)));
        let e = RayTable::from_parts(size, vec![0.0; 8], vec![0.0; 7]).unwrap_err();
        assert!(e.to_string().contains("7 y values for 8 pixels"), "{e}");
    }
}
