//! A small synthetic camera for round-trip tests, examples and benchmarks.
//!
//! It is not the virtual rig (which renders real geometry): it maps each camera pixel to a
//! projector point through a homography (a plane seen in perspective), and models what makes
//! decoding hard: the pixel footprint and defocus (a box filter along the coded axis), albedo
//! from dark to bright, ambient light, a global-illumination term (a fraction of the light the
//! projector sends within a radius, as inter-reflections and subsurface scattering bring it),
//! projector gamma and black level, a shadowed rectangle, Gaussian noise and clipping.
//!
//! The patterns are sampled exactly as a projector shows them: rendered at the pattern bit depth,
//! one constant value per projector pixel.

use rayon::prelude::*;

use crate::sequence::pattern_profile;
use crate::{Axis, BitDepth, CodecError, Frame, ImageSize, Pattern, PatternSequence, Sample};

/// A plane in front of a projector and a camera, with its lighting.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticScene {
    /// Camera image width.
    pub camera_width: usize,
    /// Camera image height.
    pub camera_height: usize,
    /// Homography from camera pixel `(x, y, 1)` to projector point (row-major 3x3); pixel
    /// centres at integers on both sides.
    pub camera_to_projector: [f64; 9],
    /// Projector size.
    pub projector: ImageSize,
    /// Grey level (8-bit scale) of a fully white projector pixel seen directly at albedo 1.
    pub gain: f64,
    /// Smallest albedo; the albedo varies smoothly across the image between `albedo_min` and
    /// `albedo_max`.
    pub albedo_min: f64,
    /// Largest albedo.
    pub albedo_max: f64,
    /// Ambient light, 8-bit grey levels, independent of the projector.
    pub ambient: f64,
    /// Global illumination: this fraction of the mean projector light within `global_radius`
    /// (along the coded axis) reaches the pixel indirectly, scaled by its albedo.
    pub global: f64,
    /// Radius of the global-illumination window, projector pixels.
    pub global_radius: f64,
    /// Centre of the global-illumination window relative to the pixel's own projector point,
    /// projector pixels along the coded axis: 0 for light scattered from the neighbourhood,
    /// a few hundred for an inter-reflection from another wall of a concave corner.
    pub global_offset: f64,
    /// Defocus: extra box-filter width along the coded axis, projector pixels (added to the
    /// pixel's own footprint).
    pub blur: f64,
    /// Standard deviation of the additive Gaussian noise, 8-bit grey levels.
    pub noise_sigma: f64,
    /// Projector response: light = black + (1 - black) * value^gamma.
    pub projector_gamma: f64,
    /// Projector black level as a fraction of white.
    pub projector_black: f64,
    /// Bit depth the patterns are rendered at before projection.
    pub pattern_depth: BitDepth,
    /// Camera rectangle `[x0, y0, x1, y1)` the projector cannot reach (cast shadow).
    pub shadow: Option<[usize; 4]>,
    /// Seed of the noise.
    pub seed: u64,
}

impl SyntheticScene {
    /// A camera of `camera_width x camera_height` looking at the middle ~80% of the projector
    /// image through a mild perspective; no noise, no ambient or global light, albedo 1,
    /// gain 200.
    pub fn looking_at(projector: ImageSize, camera_width: usize, camera_height: usize) -> Self {
        let (pw, ph) = (f64::from(projector.width), f64::from(projector.height));
        let (cw, ch) = (camera_width.max(1) as f64, camera_height.max(1) as f64);
        // Affine part: camera image onto the central 80% of the projector, slightly rotated...
        let sx = 0.8 * pw / cw;
        let sy = 0.8 * ph / ch;
        let (a, b) = (sx * 0.995, 0.02 * sx);
        let (c, d) = (-0.015 * sy, sy * 0.995);
        let tx = 0.1 * pw;
        let ty = 0.1 * ph;
        // ...plus a small perspective term (about 3% over the image).
        let g = 0.03 / cw;
        let h = -0.02 / ch;
        Self {
            camera_width,
            camera_height,
            camera_to_projector: [a, b, tx, c, d, ty, g, h, 1.0],
            projector,
            gain: 200.0,
            albedo_min: 1.0,
            albedo_max: 1.0,
            ambient: 0.0,
            global: 0.0,
            global_radius: 50.0,
            global_offset: 0.0,
            blur: 0.0,
            noise_sigma: 0.0,
            projector_gamma: 1.0,
            projector_black: 0.0,
            pattern_depth: BitDepth::Eight,
            shadow: None,
            seed: 1,
        }
    }

    /// A camera of `camera_width x camera_height` whose pixels each cover about `scale`
    /// projector pixels, centred on the projector image, with a slight rotation and perspective
    /// (a few per cent across the image); otherwise as [`SyntheticScene::looking_at`].
    ///
    /// Choose `scale` near 1-1.5 for per-pixel Gray codes: a camera that cannot resolve the
    /// finest stripes (2 projector pixels wide) cannot read their bits either.
    pub fn window(
        projector: ImageSize,
        camera_width: usize,
        camera_height: usize,
        scale: f64,
    ) -> Self {
        let base = Self::looking_at(projector, camera_width, camera_height);
        let (cw, ch) = (camera_width.max(1) as f64, camera_height.max(1) as f64);
        let (cx, cy) = (
            f64::from(projector.width) / 2.0,
            f64::from(projector.height) / 2.0,
        );
        let (a, b, c, d) = (scale * 0.998, 0.03 * scale, -0.025 * scale, scale * 0.998);
        let g = 0.03 / cw;
        let h = -0.02 / ch;
        // Map the camera centre to the projector centre: with w = g x + h y + 1 at the centre.
        let (mx, my) = (cw / 2.0, ch / 2.0);
        let w0 = g * mx + h * my + 1.0;
        let tx = cx * w0 - (a * mx + b * my);
        let ty = cy * w0 - (c * mx + d * my);
        Self {
            camera_to_projector: [a, b, tx, c, d, ty, g, h, 1.0],
            ..base
        }
    }

    /// The projector point `(x, y)` seen at the centre of camera pixel `(x, y)` (ground truth).
    pub fn projector_point(&self, x: f64, y: f64) -> (f64, f64) {
        let m = &self.camera_to_projector;
        let w = m[6] * x + m[7] * y + m[8];
        (
            (m[0] * x + m[1] * y + m[2]) / w,
            (m[3] * x + m[4] * y + m[5]) / w,
        )
    }

    /// Albedo at camera pixel `(x, y)`.
    pub fn albedo(&self, x: f64, y: f64) -> f64 {
        let (cw, ch) = (
            self.camera_width.max(1) as f64,
            self.camera_height.max(1) as f64,
        );
        let s = 0.5
            + 0.5 * (std::f64::consts::TAU * x / cw).sin() * (std::f64::consts::PI * y / ch).cos();
        self.albedo_min + (self.albedo_max - self.albedo_min) * s
    }

    /// Does direct projector light reach camera pixel `(x, y)`?
    pub fn is_lit(&self, x: usize, y: usize) -> bool {
        if let Some([x0, y0, x1, y1]) = self.shadow
            && (x0..x1).contains(&x)
            && (y0..y1).contains(&y)
        {
            return false;
        }
        let (u, v) = self.projector_point(x as f64, y as f64);
        let (w, h) = (
            f64::from(self.projector.width),
            f64::from(self.projector.height),
        );
        (-0.5..w - 0.5).contains(&u) && (-0.5..h - 0.5).contains(&v)
    }

    /// Renders the camera frames of the whole sequence, in its order.
    ///
    /// # Errors
    /// Validation errors of the sequence, and [`CodecError::Parameter`] if the sequence's
    /// projector differs from the scene's.
    pub fn render<T: Sample>(
        &self,
        sequence: &PatternSequence,
    ) -> Result<Vec<Frame<T>>, CodecError> {
        sequence.validate()?;
        if sequence.projector != self.projector {
            return Err(CodecError::parameter(
                "projector",
                format!(
                    "the sequence is for {}, the scene for {}",
                    sequence.projector, self.projector
                ),
            ));
        }
        let (w, h) = (self.camera_width, self.camera_height);
        if w == 0 || h == 0 {
            return Err(CodecError::parameter(
                "camera_width/camera_height",
                "the camera image must not be empty",
            ));
        }
        let geometry = self.geometry();
        let mut jobs = Vec::new();
        for block in &sequence.blocks {
            for f in 0..block.frame_count() {
                jobs.push((block, f));
            }
        }
        jobs.par_iter()
            .enumerate()
            .map(|(index, (block, f))| self.render_frame::<T>(&geometry, block, *f, index))
            .collect()
    }

    /// Per-pixel projector coordinates, footprints, albedo and direct-light mask.
    fn geometry(&self) -> Geometry {
        let (w, h) = (self.camera_width, self.camera_height);
        let mut g = Geometry {
            u: Vec::with_capacity(w * h),
            v: Vec::with_capacity(w * h),
            ru: Vec::with_capacity(w * h),
            rv: Vec::with_capacity(w * h),
            albedo: Vec::with_capacity(w * h),
            lit: Vec::with_capacity(w * h),
        };
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                let (u, v) = self.projector_point(xf, yf);
                let (ux, vx) = self.projector_point(xf + 0.5, yf);
                let (ux0, vx0) = self.projector_point(xf - 0.5, yf);
                let (uy, vy) = self.projector_point(xf, yf + 0.5);
                let (uy0, vy0) = self.projector_point(xf, yf - 0.5);
                // Half-width of the box: half the footprint's extent along the axis plus half
                // the defocus.
                g.ru.push(0.5 * (ux - ux0).hypot(uy - uy0) + 0.5 * self.blur);
                g.rv.push(0.5 * (vx - vx0).hypot(vy - vy0) + 0.5 * self.blur);
                g.u.push(u);
                g.v.push(v);
                g.albedo.push(self.albedo(xf, yf));
                g.lit.push(self.is_lit(x, y));
            }
        }
        g
    }

    fn render_frame<T: Sample>(
        &self,
        g: &Geometry,
        block: &Pattern,
        frame: usize,
        index: usize,
    ) -> Result<Frame<T>, CodecError> {
        let profile: Vec<f64> = match self.pattern_depth {
            BitDepth::Eight => pattern_profile::<u8>(block, frame, self.projector)?
                .into_iter()
                .map(|v| f64::from(v) / 255.0)
                .collect(),
            BitDepth::Sixteen => pattern_profile::<u16>(block, frame, self.projector)?
                .into_iter()
                .map(|v| f64::from(v) / 65535.0)
                .collect(),
        };
        let light: Vec<f64> = profile
            .iter()
            .map(|&p| {
                self.projector_black + (1.0 - self.projector_black) * p.powf(self.projector_gamma)
            })
            .collect();
        let integral = Integral::new(&light);
        let (t, r) = match block.axis() {
            Axis::Column => (&g.u, &g.ru),
            Axis::Row => (&g.v, &g.rv),
        };
        let mut rng =
            SplitMix64::new(self.seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let scale = f64::from(T::SCALE_FROM_8BIT);
        let max = f64::from(T::MAX_VALUE.to_u16());
        let data = (0..t.len())
            .map(|i| {
                let (ti, ri, a, lit) = (t[i], r[i], g.albedo[i], g.lit[i]);
                let direct = if lit {
                    integral.mean(ti - ri, ti + ri)
                } else {
                    0.0
                };
                let gc = ti + self.global_offset;
                let global =
                    self.global * integral.mean(gc - self.global_radius, gc + self.global_radius);
                let mut v = a * self.gain * (direct + global) + self.ambient;
                if self.noise_sigma > 0.0 {
                    v += self.noise_sigma * rng.normal();
                }
                let q = (v * scale).round().clamp(0.0, max);
                T::from_u16_saturating(q as u16)
            })
            .collect();
        Ok(Frame::new(self.camera_width, self.camera_height, data)?)
    }
}

struct Geometry {
    u: Vec<f64>,
    v: Vec<f64>,
    ru: Vec<f64>,
    rv: Vec<f64>,
    albedo: Vec<f64>,
    lit: Vec<bool>,
}

/// Exact box means of a piecewise-constant profile (pixel `j` covers `[j - 0.5, j + 0.5)`;
/// outside the profile there is no light).
struct Integral {
    values: Vec<f64>,
    cumulative: Vec<f64>,
}

impl Integral {
    fn new(values: &[f64]) -> Self {
        let mut cumulative = Vec::with_capacity(values.len() + 1);
        let mut s = 0.0;
        cumulative.push(0.0);
        for v in values {
            s += v;
            cumulative.push(s);
        }
        Self {
            values: values.to_vec(),
            cumulative,
        }
    }

    /// Integral from the projector's leading edge to `t`.
    fn at(&self, t: f64) -> f64 {
        let n = self.values.len();
        let z = (t + 0.5).clamp(0.0, n as f64);
        let k = z.floor() as usize;
        let base = self.cumulative.get(k).copied().unwrap_or(0.0);
        base + (z - k as f64) * self.values.get(k).copied().unwrap_or(0.0)
    }

    /// Mean over `[a, b]`; the value at `a` if the window is empty.
    fn mean(&self, a: f64, b: f64) -> f64 {
        if b - a > 1e-9 {
            (self.at(b) - self.at(a)) / (b - a)
        } else {
            let k = (a + 0.5).floor();
            if k < 0.0 {
                0.0
            } else {
                self.values.get(k as usize).copied().unwrap_or(0.0)
            }
        }
    }
}

/// `SplitMix64` with Box-Muller normals: tiny, seedable, good enough for noise.
struct SplitMix64(u64);

impl SplitMix64 {
    fn new(seed: u64) -> Self {
        Self(seed)
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `(0, 1]`.
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn integral_of_piecewise_constant_profile() {
        let it = Integral::new(&[1.0, 3.0, 5.0]);
        // Pixel 1 covers [0.5, 1.5): mean 3.
        assert_abs_diff_eq!(it.mean(0.5, 1.5), 3.0, epsilon = 1e-12);
        // Half of pixel 0 and half of pixel 1.
        assert_abs_diff_eq!(it.mean(0.0, 1.0), 2.0, epsilon = 1e-12);
        // Outside the projector there is no light.
        assert_abs_diff_eq!(it.mean(-1.5, -0.5), 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(it.mean(2.0, 3.0), 2.5, epsilon = 1e-12);
        assert_abs_diff_eq!(it.mean(1.2, 1.2), 3.0, epsilon = 1e-12);
    }

    #[test]
    fn normal_noise_has_unit_variance() {
        let mut r = SplitMix64::new(7);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        // Standard errors: 1/sqrt(n) = 0.0022 for the mean, sqrt(2/n) = 0.0032 for the variance.
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.015, "{var}");
    }

    #[test]
    fn identity_camera_sees_the_pattern() {
        let p = ImageSize::new(32, 8);
        let mut s = SyntheticScene::looking_at(p, 32, 8);
        s.camera_to_projector = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        s.gain = 255.0;
        let seq = PatternSequence::new(p).with(Pattern::Gray(crate::GrayCodeSpec::per_pixel(
            Axis::Column,
            p,
            false,
        )));
        let frames: Vec<Frame<u8>> = s.render(&seq).unwrap();
        for (i, f) in frames.iter().enumerate() {
            let expect: Frame<u8> = seq.render(i).unwrap();
            // The footprint of an identity pixel is exactly one projector pixel.
            assert_eq!(f.data(), expect.data(), "frame {i}");
        }
    }
}
