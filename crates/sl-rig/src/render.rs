//! Rendering a projected image through a view's geometry cache: a lookup per sub-sample.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::UNLIT;
use crate::{GreyImage, Pixels, RigError, ViewGeometry};

/// The light in the scene: the room's ambient light and the projector's response.
///
/// A surface point of albedo `ρ` lit by projector value `v` (a fraction of full scale) under
/// an angle `θ` to its normal has radiance
/// `ρ · (ambient + power · (black_level + (1 − black_level) · v^gamma) · cos θ)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Illumination {
    /// Ambient light reaching every surface (in units of the projector's full white at normal
    /// incidence).
    pub ambient: f64,
    /// Projector white at normal incidence (1 = the unit of radiance).
    pub projector_power: f64,
    /// Exponent of the projector's response curve (2.2 for a display-calibrated projector, 1
    /// for a linear one).
    pub gamma: f64,
    /// Light the projector emits for a black pixel, as a fraction of white (a DLP's contrast
    /// ratio of 1000:1 is 0.001).
    pub black_level: f64,
}

impl Default for Illumination {
    /// A dim room (10 % ambient), a linear projector with a 1000:1 contrast ratio. Linear
    /// (`gamma = 1`) because structured-light projectors are normally run that way; set 2.2 to
    /// test gamma pre-compensation.
    fn default() -> Self {
        Self {
            ambient: 0.1,
            projector_power: 1.0,
            gamma: 1.0,
            black_level: 0.001,
        }
    }
}

impl Illumination {
    /// Checks that every value is finite and non-negative, the gamma positive and the black
    /// level below 1.
    pub fn validate(&self) -> Result<(), RigError> {
        for (name, v) in [
            ("ambient", self.ambient),
            ("projector_power", self.projector_power),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(RigError::param(
                    format!("illumination {name}"),
                    format!("{v} is not a non-negative number"),
                ));
            }
        }
        if !(self.gamma.is_finite() && self.gamma > 0.0) {
            return Err(RigError::param(
                "illumination gamma",
                format!("{} is not positive", self.gamma),
            ));
        }
        if !(0.0..1.0).contains(&self.black_level) {
            return Err(RigError::param(
                "illumination black_level",
                format!("{} is not in [0, 1)", self.black_level),
            ));
        }
        Ok(())
    }

    /// Light leaving the projector for value `v` in `[0, 1]`, in units of full white.
    pub fn projector_output(&self, v: f64) -> f64 {
        self.projector_power
            * (self.black_level + (1.0 - self.black_level) * v.clamp(0.0, 1.0).powf(self.gamma))
    }
}

/// How a pattern function is sampled by [`ViewGeometry::render_fn`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ProjectorSampling {
    /// At the centre of the projector pixel that contains the point, as a real projector shows
    /// square pixels: identical to rendering the pattern's image.
    #[default]
    Nearest,
    /// At the continuous projector coordinate (an ideal projector with infinite resolution).
    Continuous,
}

impl ViewGeometry {
    /// The direct image (radiance per camera pixel, sub-samples averaged) under the projector
    /// image `image`, which must have the projector's size.
    pub fn render_image(
        &self,
        image: &GreyImage,
        light: &Illumination,
    ) -> Result<Vec<f32>, RigError> {
        if image.width != self.projector_width || image.height != self.projector_height {
            return Err(RigError::ImageSize {
                what: "projector image".to_owned(),
                expected_width: self.projector_width,
                expected_height: self.projector_height,
                width: image.width,
                height: image.height,
            });
        }
        Ok(match &image.pixels {
            Pixels::U8(p) => {
                let lut: Vec<f32> = (0..=u8::MAX)
                    .map(|v| light.projector_output(f64::from(v) / f64::from(u8::MAX)) as f32)
                    .collect();
                self.lookup(light, |i| {
                    p.get(i)
                        .and_then(|&v| lut.get(usize::from(v)))
                        .copied()
                        .unwrap_or(0.0)
                })
            }
            Pixels::U16(p) => {
                let lut: Vec<f32> = (0..=u16::MAX)
                    .map(|v| light.projector_output(f64::from(v) / f64::from(u16::MAX)) as f32)
                    .collect();
                self.lookup(light, |i| {
                    p.get(i)
                        .and_then(|&v| lut.get(usize::from(v)))
                        .copied()
                        .unwrap_or(0.0)
                })
            }
        })
    }

    /// The direct image under a pattern given as a function of the projector coordinate
    /// `(x, y)` (pixels, pixel centres at integers) returning a value in `[0, 1]`: the fast
    /// path for patterns that are cheap to evaluate, with no projector image in memory.
    pub fn render_fn<F>(
        &self,
        pattern: F,
        sampling: ProjectorSampling,
        light: &Illumination,
    ) -> Vec<f32>
    where
        F: Fn(f64, f64) -> f64 + Sync,
    {
        let per_pixel = (self.supersampling * self.supersampling) as usize;
        let ambient = light.ambient as f32;
        let mut out = vec![0.0f32; self.width as usize * self.height as usize];
        out.par_chunks_mut(self.width.max(1) as usize)
            .enumerate()
            .for_each(|(y, row)| {
                let base = y * self.width as usize * per_pixel;
                for (x, o) in row.iter_mut().enumerate() {
                    let mut acc = 0.0f32;
                    for k in 0..per_pixel {
                        let i = base + x * per_pixel + k;
                        let amb = self.ambient_weight.get(i).copied().unwrap_or(0.0);
                        acc += amb * ambient;
                        let Some(&[qx, qy]) = self.proj_xy.get(i) else {
                            continue;
                        };
                        if qx.is_nan() {
                            continue;
                        }
                        let (sx, sy) = match sampling {
                            ProjectorSampling::Nearest => {
                                (f64::from(qx).round(), f64::from(qy).round())
                            }
                            ProjectorSampling::Continuous => (f64::from(qx), f64::from(qy)),
                        };
                        let v = light.projector_output(pattern(sx, sy)) as f32;
                        acc += self.lit_weight.get(i).copied().unwrap_or(0.0) * v;
                    }
                    *o = acc / per_pixel as f32;
                }
            });
        out
    }

    /// Averages `ambient · albedo + value(projector pixel) · albedo · cos` over the sub-samples.
    fn lookup<V>(&self, light: &Illumination, value: V) -> Vec<f32>
    where
        V: Fn(usize) -> f32 + Sync,
    {
        let per_pixel = (self.supersampling * self.supersampling) as usize;
        let ambient = light.ambient as f32;
        let inv = 1.0 / per_pixel as f32;
        let mut out = vec![0.0f32; self.width as usize * self.height as usize];
        let row_samples = self.width as usize * per_pixel;
        out.par_chunks_mut(self.width.max(1) as usize)
            .zip(self.proj_index.par_chunks(row_samples.max(1)))
            .zip(self.lit_weight.par_chunks(row_samples.max(1)))
            .zip(self.ambient_weight.par_chunks(row_samples.max(1)))
            .for_each(|(((row, idx), lit), amb)| {
                for (((o, idx), lit), amb) in row
                    .iter_mut()
                    .zip(idx.chunks_exact(per_pixel))
                    .zip(lit.chunks_exact(per_pixel))
                    .zip(amb.chunks_exact(per_pixel))
                {
                    let mut acc = 0.0f32;
                    for ((&i, &l), &a) in idx.iter().zip(lit).zip(amb) {
                        acc += a * ambient;
                        if i != UNLIT {
                            acc += l * value(i as usize);
                        }
                    }
                    *o = acc * inv;
                }
            });
        out
    }
}
