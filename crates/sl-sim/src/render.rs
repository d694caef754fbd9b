//! Rendering a projected image through a view's geometry cache: a lookup per sub-sample.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::UNLIT;
use crate::{GreyImage, RigError, SimError, ViewGeometry, blur};
use sl_camera::ToneCurve;

/// The light in the scene: the room's ambient light and the projector's response and optics.
///
/// A surface point of albedo `ρ` lit by projector value `v` (a fraction of full scale) under
/// an angle `θ` to its normal has radiance
/// `ρ · (ambient + power · (black_level + (1 − black_level) · r(v)) · cos θ)`, where the
/// response `r` is `v^gamma` ([`ResponseShape::Power`]) or the curve of a measured projector
/// ([`ResponseShape::Measured`]).
///
/// Where the projector image has pixels, `v` is not the value of one pixel: each pixel lights
/// a square (a box of one projector pixel) that the projection lens blurs with a Gaussian of
/// standard deviation [`projector_blur_px`](Self::projector_blur_px), so the light at the
/// continuous projector coordinate `(x, y)` is `Σ P(v_ij) K(x − i) K(y − j)` with
/// `K = box ⊗ Gaussian` (see [`Illumination::pixel_spread`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Illumination {
    /// Ambient light reaching every surface (in units of the projector's full white at normal
    /// incidence).
    pub ambient: f64,
    /// Projector white at normal incidence (1 = the unit of radiance).
    pub projector_power: f64,
    /// Exponent of the projector's response curve (2.2 for a display-calibrated projector, 1
    /// for a linear one), with [`ResponseShape::Power`].
    pub gamma: f64,
    /// The shape of the projector's response: a power law of [`Self::gamma`] (the default) or
    /// a measured projector's curve.
    #[serde(default)]
    pub response: ResponseShape,
    /// Light the projector emits for a black pixel, as a fraction of white (a DLP's contrast
    /// ratio of 1000:1 is 0.001).
    pub black_level: f64,
    /// Standard deviation (projector pixels) of the projection lens's point-spread function,
    /// a Gaussian applied to the square of every projector pixel. 0 renders ideal hard-edged
    /// pixels: their stair-stepped fringes, sampled by camera pixels of another pitch, put a
    /// moiré error of ~0.16 px rms on the decoded phase (docs/triangulation.md), which real
    /// projectors do not show because their optics do not resolve the pixel grid that sharply.
    #[serde(default = "default_projector_blur_px")]
    pub projector_blur_px: f64,
    /// Share of a projector pixel's pitch that emits light, along each axis (the rest is the
    /// dark gap between micromirrors or LCD cells): 1 for gapless pixels. The pixel's light is
    /// spread over its lit square, so a full-white image still delivers
    /// [`projector_power`](Self::projector_power).
    #[serde(default = "default_projector_fill")]
    pub projector_fill: f64,
}

impl Illumination {
    /// Default of [`Illumination::projector_blur_px`]: a Gaussian of σ = 0.5 px leaves a contrast
    /// (MTF) of 0.29 at the pixel grid's Nyquist frequency (0.5 cycle/px; 0.18 with the pixel's own
    /// box), as a projection lens that is sharp but does not resolve the micromirror gaps, and
    /// damps the grid's 1 cycle/px harmonics of a fringe by 100×.
    pub const DEFAULT_PROJECTOR_BLUR_PX: f64 = 0.5;

    /// Largest projector blur accepted (px): a wider blur is a badly defocused projector, and
    /// the kernel (and its cost) grows with it.
    pub const MAX_PROJECTOR_BLUR_PX: f64 = 8.0;

    /// Default of [`Illumination::projector_fill`]: a DLP's micromirrors fill about 90 % of
    /// their pitch along each axis (the gap and the mirror's via, 0.3–0.7 µm of a 5.4–7.6 µm
    /// pitch).
    pub const DEFAULT_PROJECTOR_FILL: f64 = 0.9;

    /// Smallest projector fill accepted: below, the pixel is a point source, a projector
    /// that does not exist.
    pub const MIN_PROJECTOR_FILL: f64 = 0.1;

    /// Light that one projector pixel sends to the point `d` pixels from its centre (along
    /// one axis), as a fraction of its value: its lit square (a box of width `f =`
    /// [`projector_fill`](Self::projector_fill), scaled by `1/f`) blurred by a Gaussian of
    /// standard deviation `σ =` [`projector_blur_px`](Self::projector_blur_px),
    /// `(Φ((d + f/2)/σ) − Φ((d − f/2)/σ)) / f` (`Φ` the normal distribution function); the box
    /// itself when `σ = 0`. For touching pixels (`f = 1`) it sums to 1 over any grid of unit
    /// spacing; with gaps, on average over the pixel (the gaps are darker).
    ///
    /// ```
    /// let light = sl_sim::Illumination { projector_fill: 1.0, ..Default::default() };
    /// let total: f64 = (-5..=5).map(|m| light.pixel_spread(m as f64 + 0.3)).sum();
    /// assert!((total - 1.0).abs() < 1e-6);
    /// ```
    pub fn pixel_spread(&self, d: f64) -> f64 {
        self.spread().at(d)
    }

    /// The shape of one projector pixel's light.
    fn spread(&self) -> PixelSpread {
        PixelSpread {
            sigma: self.projector_blur_px,
            fill: self.projector_fill,
        }
    }

    /// Whether the projector's pixels are shown as ideal touching squares (no lens blur, no
    /// gap), which renders as a lookup of the pixel under each sub-sample.
    fn hard_pixels(&self) -> bool {
        self.projector_blur_px <= 0.0 && self.projector_fill >= 1.0
    }
}

fn default_projector_blur_px() -> f64 {
    Illumination::DEFAULT_PROJECTOR_BLUR_PX
}

fn default_projector_fill() -> f64 {
    Illumination::DEFAULT_PROJECTOR_FILL
}

/// The light of one projector pixel along one axis: a lit box of width `fill` (pixels)
/// blurred by a Gaussian of standard deviation `sigma`, normalised to a unit total.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PixelSpread {
    pub(crate) sigma: f64,
    pub(crate) fill: f64,
}

impl PixelSpread {
    /// Light sent `d` pixels from the pixel's centre.
    pub(crate) fn at(self, d: f64) -> f64 {
        pixel_spread(d, self.sigma, self.fill)
    }

    /// Half-width (pixels) of the light that is kept: half a pixel of box plus the Gaussian's
    /// [`PSF_TRUNCATE_SIGMAS`].
    fn radius(self) -> isize {
        (PSF_TRUNCATE_SIGMAS * self.sigma + 0.5).ceil() as isize
    }
}

/// The kernel is cut where the Gaussian's tail holds under 1e-4 of the light (4σ), well below
/// one grey level of a 16-bit frame's noise.
const PSF_TRUNCATE_SIGMAS: f64 = 4.0;

/// Samples per projector pixel of the tabulated light of a one-dimensional pattern (stripes or
/// fringes), read by linear interpolation: its own 1 cycle/px ripple is then
/// `sinc²(1 − 1/(16 λ))`, under 1e-5 of the fringe for any period `λ ≥ 2` px.
const FIELD_SAMPLES_PER_PIXEL: usize = 16;

/// Light that projector pixel `i` sends to the projector coordinate `i + d` (pixels), as a
/// fraction of its value: a lit box of width `fill` (≤ 1 pixel, centred) blurred by a Gaussian
/// of standard deviation `sigma`, `(Φ((d + f/2)/σ) − Φ((d − f/2)/σ)) / f`. Sums to 1 over any
/// grid of unit spacing. `sigma <= 0` gives the box itself.
pub(crate) fn pixel_spread(d: f64, sigma: f64, fill: f64) -> f64 {
    let half = 0.5 * fill;
    if sigma <= 0.0 {
        return if (-half..half).contains(&d) {
            1.0 / fill
        } else {
            0.0
        };
    }
    let z = std::f64::consts::FRAC_1_SQRT_2 / sigma;
    0.5 * (erfc(-(d + half) * z) - erfc(-(d - half) * z)) / fill
}

/// Complementary error function, with a fractional error below 1.2e-7 everywhere (the
/// Chebyshev fit of Numerical Recipes' `erfcc`): far below a 16-bit grey level.
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

impl Default for Illumination {
    /// A dim room (10 % ambient), a linear projector with a 1000:1 contrast ratio and a
    /// [`Self::DEFAULT_PROJECTOR_BLUR_PX`] lens blur. Linear (`gamma = 1`) because structured-light
    /// projectors are normally run that way; set 2.2 to test gamma pre-compensation.
    fn default() -> Self {
        Self {
            ambient: 0.1,
            projector_power: 1.0,
            gamma: 1.0,
            response: ResponseShape::Power,
            black_level: 0.001,
            projector_blur_px: Self::DEFAULT_PROJECTOR_BLUR_PX,
            projector_fill: Self::DEFAULT_PROJECTOR_FILL,
        }
    }
}

impl Illumination {
    /// Checks that every value is finite and non-negative, the gamma positive and the black
    /// level below 1.
    pub fn validate(&self) -> Result<(), SimError> {
        for (name, v) in [
            ("ambient", self.ambient),
            ("projector_power", self.projector_power),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SimError::param(
                    format!("illumination {name}"),
                    format!("{v} is not a non-negative number"),
                ));
            }
        }
        if !(self.gamma.is_finite() && self.gamma > 0.0) {
            return Err(SimError::param(
                "illumination gamma",
                format!("{} is not positive", self.gamma),
            ));
        }
        if !(0.0..=Self::MAX_PROJECTOR_BLUR_PX).contains(&self.projector_blur_px) {
            return Err(SimError::param(
                "illumination projector_blur_px",
                format!(
                    "{} is not in [0, {}]",
                    self.projector_blur_px,
                    Self::MAX_PROJECTOR_BLUR_PX
                ),
            ));
        }
        if !(Self::MIN_PROJECTOR_FILL..=1.0).contains(&self.projector_fill) {
            return Err(SimError::param(
                "illumination projector_fill",
                format!(
                    "{} is not in [{}, 1]",
                    self.projector_fill,
                    Self::MIN_PROJECTOR_FILL
                ),
            ));
        }
        if !(0.0..1.0).contains(&self.black_level) {
            return Err(SimError::param(
                "illumination black_level",
                format!("{} is not in [0, 1)", self.black_level),
            ));
        }
        Ok(())
    }

    /// Light leaving the projector for value `v` in `[0, 1]`, in units of full white.
    pub fn projector_output(&self, v: f64) -> f64 {
        self.projector_power * (self.black_level + (1.0 - self.black_level) * self.relative(v))
    }

    /// The response `r(v)` in `[0, 1]`: the share of the light between black and white.
    fn relative(&self, v: f64) -> f64 {
        let v = v.clamp(0.0, 1.0);
        match self.response {
            ResponseShape::Power => v.powf(self.gamma),
            ResponseShape::Measured => ResponseShape::measured(v),
        }
    }

    /// The projector's true response as a [`ToneCurve`] (the truth a measured response is
    /// compared with); `None` when it is linear.
    pub fn response_curve(&self) -> Option<ToneCurve> {
        match self.response {
            ResponseShape::Power if self.gamma == 1.0 => None,
            _ => Some(ToneCurve::from_fn(|v| self.relative(v))),
        }
    }
}

/// The shape of a virtual projector's response ([`Illumination::response`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResponseShape {
    /// `v^gamma`.
    #[default]
    Power,
    /// The curve of a consumer DLP projector in its default picture mode, as measured
    /// responses look ([`ResponseShape::measured`]): the darkest 3 % of values crushed to
    /// black, a gamma of about 2.4 in the shadows and mid-tones, and a shoulder that rolls
    /// the brightest values off ("brilliant colour" white boost), with a ripple of a few
    /// tenths of a percent from the colour wheel's segments. `gamma` is ignored.
    Measured,
}

impl ResponseShape {
    /// [`ResponseShape::Measured`]'s curve: `r(v)` for `v` in `[0, 1]`, from 0 to 1, never
    /// decreasing.
    pub fn measured(v: f64) -> f64 {
        // Black crush below 3 %, full white reached at 98 %.
        let x = ((v.clamp(0.0, 1.0) - 0.03) / 0.95).clamp(0.0, 1.0);
        // Power law with a shoulder: (x^2.4 - 0.25 x^6.4) / 0.75 rises on [0, 1]
        // (its slope, 2.4 x^1.4 - 1.6 x^5.4, is positive for x^4 < 1.5).
        let base = (x.powf(2.4) - 0.25 * x.powf(6.4)) / 0.75;
        // A small ripple that vanishes at both ends and never makes the curve fall:
        // amplitude 0.004, slope at most 0.004 * 2 pi * 3 ~ 0.075, below the base's slope
        // wherever the ripple is large.
        let ripple = 0.004 * (std::f64::consts::TAU * 3.0 * x).sin() * x * (1.0 - x);
        (base + ripple).clamp(0.0, 1.0)
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
    ) -> Result<Vec<f32>, SimError> {
        let weights = [Weights {
            lit: &self.lit_weight,
            ambient: &self.ambient_weight,
        }];
        let mut images = self.render_image_weighted(image, light, &weights)?;
        Ok(images.pop().unwrap_or_default())
    }

    /// The direct images under the projector image `image`, one per set of `weights` (the
    /// grey weights, or a colour channel's), the projector's light computed once.
    pub(crate) fn render_image_weighted(
        &self,
        image: &GreyImage,
        light: &Illumination,
        weights: &[Weights<'_>],
    ) -> Result<Vec<Vec<f32>>, SimError> {
        let size = image.size();
        if (size.width, size.height) != (self.projector_width, self.projector_height) {
            return Err(RigError::ImageSize {
                what: "projector image".to_owned(),
                expected_width: self.projector_width,
                expected_height: self.projector_height,
                width: size.width,
                height: size.height,
            }
            .into());
        }
        if !light.hard_pixels() {
            let (w, h) = (image.width(), image.height());
            let sigma = light.spread();
            let field = match image {
                GreyImage::U8(f) => {
                    let p = f.data();
                    let lut = output_lut(light, u8::MAX.into());
                    LightField::new(p, w, h, sigma, |v| {
                        lut.get(usize::from(v)).copied().unwrap_or(0.0)
                    })
                }
                GreyImage::U16(f) => {
                    let p = f.data();
                    let lut = output_lut(light, u16::MAX.into());
                    LightField::new(p, w, h, sigma, |v| {
                        lut.get(usize::from(v)).copied().unwrap_or(0.0)
                    })
                }
            };
            return Ok(weights
                .iter()
                .map(|wt| self.render_light(&field, light, wt))
                .collect());
        }
        Ok(weights
            .iter()
            .map(|wt| match image {
                GreyImage::U8(f) => {
                    let p = f.data();
                    let lut = output_lut(light, u8::MAX.into());
                    self.lookup(light, wt, |i| {
                        p.get(i)
                            .and_then(|&v| lut.get(usize::from(v)))
                            .copied()
                            .unwrap_or(0.0)
                    })
                }
                GreyImage::U16(f) => {
                    let p = f.data();
                    let lut = output_lut(light, u16::MAX.into());
                    self.lookup(light, wt, |i| {
                        p.get(i)
                            .and_then(|&v| lut.get(usize::from(v)))
                            .copied()
                            .unwrap_or(0.0)
                    })
                }
            })
            .collect())
    }

    /// The direct image under a pattern given as a function of the projector coordinate
    /// `(x, y)` (pixels, pixel centres at integers) returning a value in `[0, 1]`: the fast
    /// path for patterns that are cheap to evaluate. With [`ProjectorSampling::Nearest`] the
    /// pattern is read at projector pixel centres and shown through the lens blur, exactly as
    /// [`render_image`](Self::render_image) shows an image of those values;
    /// [`ProjectorSampling::Continuous`] is an ideal projector (no pixels, no blur).
    pub fn render_fn<F>(
        &self,
        pattern: F,
        sampling: ProjectorSampling,
        light: &Illumination,
    ) -> Vec<f32>
    where
        F: Fn(f64, f64) -> f64 + Sync,
    {
        if sampling == ProjectorSampling::Nearest && !light.hard_pixels() {
            let pw = self.projector_width.max(1) as usize;
            let n = pw * self.projector_height as usize;
            let out: Vec<f32> = (0..n)
                .into_par_iter()
                .map(|i| light.projector_output(pattern((i % pw) as f64, (i / pw) as f64)) as f32)
                .collect();
            let field = LightField::new(
                &out,
                pw,
                self.projector_height as usize,
                light.spread(),
                |v| v,
            );
            let weights = Weights {
                lit: &self.lit_weight,
                ambient: &self.ambient_weight,
            };
            return self.render_light(&field, light, &weights);
        }
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

    /// The direct image under the projector's light `field` (units of full white, after the
    /// lens): the light reaching each sub-sample is read at its continuous projector coordinate.
    fn render_light(
        &self,
        field: &LightField,
        light: &Illumination,
        weights: &Weights<'_>,
    ) -> Vec<f32> {
        let per_pixel = (self.supersampling * self.supersampling) as usize;
        let ambient = light.ambient as f32;
        let inv = 1.0 / per_pixel as f32;
        let mut img = vec![0.0f32; self.width as usize * self.height as usize];
        let row_samples = (self.width as usize * per_pixel).max(1);
        img.par_chunks_mut(self.width.max(1) as usize)
            .zip(self.proj_xy.par_chunks(row_samples))
            .zip(weights.lit.par_chunks(row_samples))
            .zip(weights.ambient.par_chunks(row_samples))
            .for_each(|(((row, xy), lit), amb)| {
                for (((o, xy), lit), amb) in row
                    .iter_mut()
                    .zip(xy.chunks_exact(per_pixel))
                    .zip(lit.chunks_exact(per_pixel))
                    .zip(amb.chunks_exact(per_pixel))
                {
                    let mut acc = 0.0f32;
                    for ((&[qx, qy], &l), &a) in xy.iter().zip(lit).zip(amb) {
                        acc += a * ambient;
                        if !qx.is_nan() {
                            acc += l * field.at(qx, qy);
                        }
                    }
                    *o = acc * inv;
                }
            });
        img
    }

    /// Averages `ambient · albedo + value(projector pixel) · albedo · cos` over the sub-samples.
    fn lookup<V>(&self, light: &Illumination, weights: &Weights<'_>, value: V) -> Vec<f32>
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
            .zip(weights.lit.par_chunks(row_samples.max(1)))
            .zip(weights.ambient.par_chunks(row_samples.max(1)))
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

/// The per-sub-sample weights of one rendered image ([`ViewGeometry`]'s layout): the weight of
/// the projector's light (`(albedo + specular lobe) · cos`) and of the ambient light
/// (`albedo`), for the grey albedo or one colour channel's.
pub(crate) struct Weights<'a> {
    pub(crate) lit: &'a [f32],
    pub(crate) ambient: &'a [f32],
}

/// `P(v)` for every value of a `max + 1`-level image.
fn output_lut(light: &Illumination, max: u32) -> Vec<f32> {
    (0..=max)
        .map(|v| light.projector_output(f64::from(v) / f64::from(max)) as f32)
        .collect()
}

/// The light leaving the projector lens as a function of the continuous projector coordinate,
/// tabulated on a grid and read by bilinear interpolation.
///
/// Grid sample `(j, k)` sits at projector coordinate `((j + ½)/scale_x − ½, (k + ½)/scale_y − ½)`.
/// A pattern that varies along one axis only (every Gray code and fringe pattern) is tabulated
/// exactly at [`FIELD_SAMPLES_PER_PIXEL`] samples per pixel along that axis; any other image at
/// the pixel centres (one sample per pixel), where the interpolation adds a ripple of
/// `sinc²(1 − f)` at a spatial frequency `f` (0.1 % of a 30 px fringe).
struct LightField {
    data: Vec<f32>,
    width: usize,
    height: usize,
    scale_x: f32,
    scale_y: f32,
}

impl LightField {
    /// The field of a `width × height` projector whose pixel `i` holds `pixels[i]` and emits
    /// `emit(pixels[i])`, each pixel's light spread by `sigma` (its fill and lens blur).
    /// Whether the image varies along one axis only is decided on the raw pixels, so that a
    /// stripe pattern converts one line, not the whole image.
    fn new<T, E>(pixels: &[T], width: usize, height: usize, sigma: PixelSpread, emit: E) -> Self
    where
        T: PartialEq + Copy + Sync,
        E: Fn(T) -> f32 + Sync,
    {
        let width = width.max(1);
        let first_row = pixels.get(..width).unwrap_or(&[]);
        let u = FIELD_SAMPLES_PER_PIXEL;
        if pixels.chunks_exact(width).all(|r| r == first_row) {
            let row: Vec<f32> = first_row.iter().map(|&v| emit(v)).collect();
            return Self {
                data: upsample(&row, sigma),
                width: row.len() * u,
                height: 1,
                scale_x: u as f32,
                scale_y: 1.0,
            };
        }
        if pixels
            .chunks_exact(width)
            .all(|r| r.iter().all(|&v| r.first() == Some(&v)))
        {
            let column: Vec<f32> = pixels.iter().step_by(width).map(|&v| emit(v)).collect();
            return Self {
                data: upsample(&column, sigma),
                width: 1,
                height: column.len() * u,
                scale_x: 1.0,
                scale_y: u as f32,
            };
        }
        let r = sigma.radius();
        let kernel: Vec<f32> = (-r..=r).map(|m| sigma.at(m as f64) as f32).collect();
        let out: Vec<f32> = pixels.par_iter().map(|&v| emit(v)).collect();
        Self {
            data: blur::separable(&out, width, height, &kernel),
            width,
            height,
            scale_x: 1.0,
            scale_y: 1.0,
        }
    }

    /// The light at projector coordinate `(x, y)`, bilinearly interpolated (clamped to the
    /// edge samples outside the grid).
    fn at(&self, x: f32, y: f32) -> f32 {
        if self.height == 1 {
            let gx = ((x + 0.5) * self.scale_x - 0.5).clamp(0.0, (self.width - 1) as f32);
            let x0 = gx as usize;
            let a = self.data.get(x0).copied().unwrap_or(0.0);
            let b = self.data.get(x0 + 1).copied().unwrap_or(a);
            return a + (gx - x0 as f32) * (b - a);
        }
        let gx = ((x + 0.5) * self.scale_x - 0.5).clamp(0.0, (self.width - 1) as f32);
        let gy = ((y + 0.5) * self.scale_y - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (gx as usize, gy as usize);
        let (fx, fy) = (gx - x0 as f32, gy - y0 as f32);
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let v = |x: usize, y: usize| self.data.get(y * self.width + x).copied().unwrap_or(0.0);
        let top = v(x0, y0) + fx * (v(x1, y0) - v(x0, y0));
        if y1 == y0 {
            return top;
        }
        let bottom = v(x0, y1) + fx * (v(x1, y1) - v(x0, y1));
        top + fy * (bottom - top)
    }
}

/// The light of a one-dimensional projector line (`v[i]` from pixel `i`) blurred by
/// [`pixel_spread`], at [`FIELD_SAMPLES_PER_PIXEL`] points per pixel; beyond the ends the
/// edge pixels are repeated.
fn upsample(v: &[f32], sigma: PixelSpread) -> Vec<f32> {
    let u = FIELD_SAMPLES_PER_PIXEL;
    let r = sigma.radius();
    // weights[p][m + r]: light of pixel i + m at sub-position p of pixel i.
    let weights: Vec<Vec<f32>> = (0..u)
        .map(|p| {
            let offset = (p as f64 + 0.5) / u as f64 - 0.5;
            (-r..=r)
                .map(|m| sigma.at(offset - m as f64) as f32)
                .collect()
        })
        .collect();
    let last = v.len() as isize - 1;
    (0..v.len() * u)
        .into_par_iter()
        .map(|j| {
            let i = (j / u) as isize;
            weights.get(j % u).map_or(0.0, |w| {
                w.iter()
                    .zip(-r..=r)
                    .map(|(&w, m)| {
                        let k = (i + m).clamp(0, last.max(0)) as usize;
                        w * v.get(k).copied().unwrap_or(0.0)
                    })
                    .sum()
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_measured_response_rises_from_black_to_white() {
        assert_eq!(ResponseShape::measured(0.0), 0.0);
        assert_eq!(ResponseShape::measured(1.0), 1.0);
        // Crushed below 3 %, rolled off at the top (steeper than a power law mid-way).
        assert_eq!(ResponseShape::measured(0.02), 0.0);
        let mut last = 0.0;
        for i in 0..=10_000 {
            let r = ResponseShape::measured(f64::from(i) / 10_000.0);
            assert!(r >= last, "falls at {i}: {r} < {last}");
            last = r;
        }
        let linear = Illumination::default();
        assert!(linear.response_curve().is_none());
        let measured = Illumination {
            response: ResponseShape::Measured,
            ..linear
        };
        let curve = measured.response_curve().unwrap();
        assert!((curve.light(0.5) - ResponseShape::measured(0.5)).abs() < 1e-4);
        // The projector's output keeps the black level and the power around the curve.
        let out = measured.projector_output(0.5);
        let expected =
            linear.black_level + (1.0 - linear.black_level) * ResponseShape::measured(0.5);
        assert!((out - expected).abs() < 1e-12);
    }
    use approx::assert_abs_diff_eq;

    #[test]
    fn pixel_spread_is_a_blurred_box() {
        for fill in [1.0, 0.9, 0.6] {
            for sigma in [0.2, 0.5, 1.0, 2.5] {
                // A full-white image: the grid sum at any point is 1 for touching pixels (Φ
                // differences telescope; 1e-6 is the erfc fit's error); with gaps the white
                // field has the dark grid in it, and only its mean over a pixel is 1.
                let sum_at = |shift: f64| -> f64 {
                    (-40..=40)
                        .map(|m| pixel_spread(f64::from(m) + shift, sigma, fill))
                        .sum()
                };
                if fill >= 1.0 {
                    for shift in [0.0, 0.25, 0.5, 0.9] {
                        assert_abs_diff_eq!(sum_at(shift), 1.0, epsilon = 1e-6);
                    }
                }
                let mean = (0..1000)
                    .map(|k| sum_at((k as f64 + 0.5) / 1000.0))
                    .sum::<f64>()
                    / 1000.0;
                assert_abs_diff_eq!(mean, 1.0, epsilon = 1e-5);
                // Variance of box ⊗ Gaussian = fill²/12 + σ² (variances add); integrated finely.
                let h = 1e-3;
                let (mut m0, mut m2) = (0.0, 0.0);
                for i in -20_000..=20_000 {
                    let d = f64::from(i) * h;
                    let k = pixel_spread(d, sigma, fill);
                    m0 += k * h;
                    m2 += k * d * d * h;
                }
                assert_abs_diff_eq!(m0, 1.0, epsilon = 1e-6);
                assert_abs_diff_eq!(m2, fill * fill / 12.0 + sigma * sigma, epsilon = 1e-5);
            }
        }
        assert_abs_diff_eq!(pixel_spread(0.49, 0.0, 1.0), 1.0);
        assert_abs_diff_eq!(pixel_spread(0.5, 0.0, 1.0), 0.0);
        // A gap: 0.45 px from the centre of a 0.8-wide lit square is dark, 0.39 lit at 1/0.8.
        assert_abs_diff_eq!(pixel_spread(0.45, 0.0, 0.8), 0.0);
        assert_abs_diff_eq!(pixel_spread(0.39, 0.0, 0.8), 1.25);
    }

    #[test]
    fn blurred_fringes_have_the_closed_form_amplitude_and_no_phase_shift() {
        // A projector row showing 1/2 + 1/2 cos(2π i / λ): the light field is the sampled
        // fringe convolved with box ⊗ Gaussian. Its fundamental is the fringe scaled by the
        // kernel's transfer function sinc(1/λ) · exp(−2π²σ²/λ²), unshifted; the grid's
        // replicas at 1 ± 1/λ cycle/px are scaled by sinc(1 ∓ 1/λ) · exp(−2π²σ²(1 ∓ 1/λ)²),
        // under 2.5e-4 each for σ = 0.5 and λ = 30: the bound below is their sum, plus 1e-5
        // for the linear interpolation of the 16-per-pixel table (sinc²(1 − 1/480)).
        let (lambda, sigma, width) = (30.0f64, 0.5f64, 600usize);
        let row: Vec<f32> = (0..width)
            .map(|i| (0.5 + 0.5 * (std::f64::consts::TAU * i as f64 / lambda).cos()) as f32)
            .collect();
        let out: Vec<f32> = (0..4).flat_map(|_| row.iter().copied()).collect();
        let field = LightField::new(&out, width, 4, PixelSpread { sigma, fill: 1.0 }, |v| v);
        assert_eq!(
            (field.height, field.width),
            (1, width * FIELD_SAMPLES_PER_PIXEL)
        );
        let sinc = |f: f64| (std::f64::consts::PI * f).sin() / (std::f64::consts::PI * f);
        let gauss = |f: f64| (-2.0 * (std::f64::consts::PI * sigma * f).powi(2)).exp();
        let gain = sinc(1.0 / lambda) * gauss(1.0 / lambda);
        let alias: f64 = [1.0 - 1.0 / lambda, 1.0 + 1.0 / lambda]
            .iter()
            .map(|&f| (sinc(f) * gauss(f)).abs() * 0.5)
            .sum();
        let mut worst = 0.0f64;
        for k in 0..4000 {
            let x = 50.0 + k as f64 * 0.1237;
            let want = 0.5 + 0.5 * gain * (std::f64::consts::TAU * x / lambda).cos();
            let got = f64::from(field.at(x as f32, 2.0));
            worst = worst.max((got - want).abs());
        }
        assert!(
            worst <= alias + 1e-5,
            "worst {worst}, bound {}",
            alias + 1e-5
        );
        // Hard-edged pixels (the staircase) miss by far more: the same bound fails there.
        let hard_alias = [1.0 - 1.0 / lambda, 1.0 + 1.0 / lambda]
            .iter()
            .map(|&f| sinc(f).abs() * 0.5)
            .sum::<f64>();
        assert!(hard_alias > 20.0 * alias);
    }

    #[test]
    fn images_that_vary_in_two_dimensions_are_blurred_separably() {
        // A single lit pixel: its light at offset (dx, dy) is K(dx) K(dy) at the pixel
        // centres, where the table is exact (bilinear reads grid points unchanged).
        let (w, h) = (21usize, 15usize);
        let mut out = vec![0.0f32; w * h];
        out[7 * w + 10] = 1.0;
        let sigma = 0.7;
        let field = LightField::new(&out, w, h, PixelSpread { sigma, fill: 1.0 }, |v| v);
        assert_eq!((field.width, field.height), (w, h));
        for dy in -3i32..=3 {
            for dx in -3i32..=3 {
                let want = pixel_spread(f64::from(dx), sigma, 1.0)
                    * pixel_spread(f64::from(dy), sigma, 1.0);
                let got = field.at((10 + dx) as f32, (7 + dy) as f32);
                // f32 storage: 1e-7 relative, plus the erfc fit.
                assert_abs_diff_eq!(f64::from(got), want, epsilon = 1e-6);
            }
        }
    }
}
