//! Camera effects after the direct image: global illumination, defocus, photon and read
//! noise, exposure, saturation and quantisation. Seeded and reproducible.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use sl_image::Frame;

use crate::{GreyImage, SimError, blur};

/// Bits per pixel of the frames a camera delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BitDepth {
    /// 8-bit frames (0–255).
    Eight,
    /// 16-bit frames (0–65535).
    Sixteen,
}

impl BitDepth {
    /// The largest pixel value.
    pub fn max_value(self) -> f64 {
        match self {
            Self::Eight => f64::from(u8::MAX),
            Self::Sixteen => f64::from(u16::MAX),
        }
    }
}

/// The image sensor: how radiance becomes electrons and electrons become pixel values.
///
/// A pixel that receives a (sub-sample averaged) radiance `L` collects on average
/// `e = exposure · full_well_electrons · L` electrons; photon (shot) noise adds a zero-mean
/// Gaussian of variance `e` (the Poisson law's variance; the Gaussian shape is exact to well
/// under 1 % above ~20 electrons), read noise one of standard deviation
/// `read_noise_electrons`; the result is clipped to `[0, full_well_electrons]` (saturation),
/// scaled so that a full well is the largest pixel value, rounded and clamped.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorConfig {
    /// Electrons a pixel holds before it saturates (typical small CMOS pixels: 5 000–20 000).
    pub full_well_electrons: f64,
    /// Standard deviation of the read noise, in electrons (typical CMOS: 2–10).
    pub read_noise_electrons: f64,
    /// Add photon (shot) noise.
    pub photon_noise: bool,
    /// Exposure: the fraction of the full well that a radiance of 1 fills in one frame.
    pub exposure: f64,
    /// Bits per pixel of the frames.
    pub bit_depth: BitDepth,
    /// The sensor's black level (pedestal), in grey levels of an 8-bit frame (scaled for 16
    /// bits): what a pixel reads in the dark, so that noise is not clipped at 0.
    #[serde(default = "default_dark_level_dn")]
    pub dark_level_dn: f64,
}

impl SensorConfig {
    /// Default of [`SensorConfig::full_well_electrons`]: fitted to the noise of a real
    /// capture (`procam_kamino`: variance 0.056 grey level² per grey level, 18 e⁻ a level,
    /// `benches/peers/capture_stats.py`), the small pixels of the cameras such rigs use.
    pub const DEFAULT_FULL_WELL_ELECTRONS: f64 = 5_000.0;

    /// Default of [`SensorConfig::dark_level_dn`]: a real camera's black frame reads 6–8
    /// grey levels (`procam_kamino`), of which a few are the sensor's pedestal.
    pub const DEFAULT_DARK_LEVEL_DN: f64 = 5.0;
}

fn default_dark_level_dn() -> f64 {
    SensorConfig::DEFAULT_DARK_LEVEL_DN
}

impl Default for SensorConfig {
    /// A [`SensorConfig::DEFAULT_FULL_WELL_ELECTRONS`] full well, 5 e⁻ read noise, photon
    /// noise on, an exposure that puts white paper (albedo 0.9) lit head-on at 75 % of full
    /// scale with the default ambient light, 8-bit frames with a black level of
    /// [`SensorConfig::DEFAULT_DARK_LEVEL_DN`]: about 2.6 grey levels of noise at mid-scale,
    /// as measured on a real capture.
    fn default() -> Self {
        Self {
            full_well_electrons: Self::DEFAULT_FULL_WELL_ELECTRONS,
            read_noise_electrons: 5.0,
            photon_noise: true,
            exposure: 0.75,
            bit_depth: BitDepth::Eight,
            dark_level_dn: Self::DEFAULT_DARK_LEVEL_DN,
        }
    }
}

impl SensorConfig {
    /// Checks that every value is finite and in range.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(self.full_well_electrons.is_finite() && self.full_well_electrons >= 1.0) {
            return Err(SimError::param(
                "sensor full_well_electrons",
                format!("{} is not at least 1", self.full_well_electrons),
            ));
        }
        if !(self.read_noise_electrons.is_finite() && self.read_noise_electrons >= 0.0) {
            return Err(SimError::param(
                "sensor read_noise_electrons",
                format!("{} is not a non-negative number", self.read_noise_electrons),
            ));
        }
        if !(self.dark_level_dn.is_finite() && (0.0..255.0).contains(&self.dark_level_dn)) {
            return Err(SimError::param(
                "sensor dark_level_dn",
                format!("{} is not in [0, 255)", self.dark_level_dn),
            ));
        }
        if !(self.exposure.is_finite() && self.exposure > 0.0) {
            return Err(SimError::param(
                "sensor exposure",
                format!("{} is not positive", self.exposure),
            ));
        }
        Ok(())
    }
}

/// Depth-dependent defocus of a thin lens.
///
/// A point at depth `z` is imaged as a disc of diameter
/// `fx · aperture_mm · |z − focus_distance_mm| / (z · focus_distance_mm)` pixels (thin lens,
/// focus distance much larger than the focal length), rendered as a Gaussian of the disc's
/// standard deviation, a quarter of its diameter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Defocus {
    /// Distance in focus (mm, along the optical axis).
    pub focus_distance_mm: f64,
    /// Diameter of the entrance pupil (mm): focal length / f-number.
    pub aperture_mm: f64,
}

impl Default for Defocus {
    /// Focused at 450 mm, a 12 mm lens at f/4 (3 mm pupil): ±50 mm of depth blurs by up to
    /// about 1 px (σ ≈ 0.25 px).
    fn default() -> Self {
        Self {
            focus_distance_mm: 450.0,
            aperture_mm: 3.0,
        }
    }
}

/// Largest defocus blur rendered (standard deviation in px): beyond, a structured-light scan
/// is hopeless anyway and the blur stack would only cost time.
const MAX_DEFOCUS_SIGMA_PX: f64 = 8.0;
/// Step between the blur levels of the defocus stack (px of σ); linear interpolation between
/// two neighbouring levels is within a few percent of the exact Gaussian at this spacing.
const DEFOCUS_LEVEL_STEP_PX: f64 = 0.5;

impl Defocus {
    /// Standard deviation of the blur (px) at depth `z_mm` for a camera of focal length `fx`
    /// pixels.
    pub fn sigma_px(&self, fx: f64, z_mm: f64) -> f64 {
        if !(z_mm > 0.0 && self.focus_distance_mm > 0.0) {
            return 0.0;
        }
        let diameter = fx * self.aperture_mm * (z_mm - self.focus_distance_mm).abs()
            / (z_mm * self.focus_distance_mm);
        (diameter / 4.0).min(MAX_DEFOCUS_SIGMA_PX)
    }
}

/// A global-illumination term: interreflections and subsurface scattering modelled as a
/// blurred copy of the direct image, added with a weight. Structured-light decoders that
/// claim robustness to global light are tested against it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GlobalIllumination {
    /// Weight of the blurred copy (0.1 = 10 % of the direct light comes back as global light).
    pub weight: f64,
    /// Standard deviation of the blur (px): much wider than a pattern's finest stripe, so that
    /// the global light is (nearly) the same under a pattern and its inverse.
    pub sigma_px: f64,
}

impl Default for GlobalIllumination {
    /// 20 % of the direct light, spread over ~40 px.
    fn default() -> Self {
        Self {
            weight: 0.2,
            sigma_px: 40.0,
        }
    }
}

/// Everything that happens between the direct image and the frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraEffects {
    /// The sensor.
    pub sensor: SensorConfig,
    /// Standard deviation (camera pixels) of the lens's point spread in focus: a Gaussian
    /// applied to the pixel-integrated image (diffraction, aberrations, the sensor's
    /// cross-talk); the defocus, when there is one, adds to it in quadrature. 0 for an ideal
    /// lens.
    #[serde(default = "default_lens_blur_px")]
    pub lens_blur_px: f64,
    /// Depth-dependent defocus; `None` for a pinhole (everything sharp).
    pub defocus: Option<Defocus>,
    /// Global illumination; `None` for direct light only.
    pub global_illumination: Option<GlobalIllumination>,
}

impl CameraEffects {
    /// Default of [`CameraEffects::lens_blur_px`]: fitted so that the renders' board edges
    /// spread as real ones do, σ = 0.93–0.97 px (an erf fitted across the edges of OpenCV's
    /// samples and `procam_kamino`'s white frames by `benches/peers/capture_stats.py`, the
    /// same tool on both; see `docs/virtual-rig.md`, "Renders against real captures").
    pub const DEFAULT_LENS_BLUR_PX: f64 = 0.75;

    /// The default global light: light scattered far from where it should land (projector and
    /// camera optics, the room). The contrast of `procam_kamino`'s Gray-code stripes against
    /// their width fits a point spread with 16–20 % of the light in a tail of σ = 16–37 px;
    /// this weight gives the renders the same fit.
    pub const DEFAULT_SCATTER: GlobalIllumination = GlobalIllumination {
        weight: 0.3,
        sigma_px: 25.0,
    };

    /// Largest lens blur accepted (px).
    pub const MAX_LENS_BLUR_PX: f64 = 8.0;

    /// Checks the sensor and the lens blur.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(0.0..=Self::MAX_LENS_BLUR_PX).contains(&self.lens_blur_px) {
            return Err(SimError::param(
                "camera lens_blur_px",
                format!(
                    "{} is not in [0, {}]",
                    self.lens_blur_px,
                    Self::MAX_LENS_BLUR_PX
                ),
            ));
        }
        self.sensor.validate()
    }
}

impl Default for CameraEffects {
    /// The default sensor, a lens spread of [`CameraEffects::DEFAULT_LENS_BLUR_PX`], no defocus,
    /// and the measured scatter [`CameraEffects::DEFAULT_SCATTER`] as the global light.
    fn default() -> Self {
        Self {
            sensor: SensorConfig::default(),
            lens_blur_px: Self::DEFAULT_LENS_BLUR_PX,
            defocus: None,
            global_illumination: Some(Self::DEFAULT_SCATTER),
        }
    }
}

fn default_lens_blur_px() -> f64 {
    CameraEffects::DEFAULT_LENS_BLUR_PX
}

/// Identifies one frame's noise: the same `(seed, view, frame)` always gives the same noise,
/// whatever the number of threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NoiseKey {
    /// The rig's seed.
    pub seed: u64,
    /// View index (turntable position, board pose, ...).
    pub view: u64,
    /// Frame index within the view.
    pub frame: u64,
}

/// `SplitMix64`'s finaliser: a bijective mix with full avalanche, so that neighbouring keys give
/// unrelated generator seeds.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl NoiseKey {
    /// The seed of the random stream of image row `row`.
    pub fn row_seed(&self, row: u64) -> u64 {
        mix(mix(mix(mix(self.seed) ^ self.view) ^ self.frame) ^ row)
    }
}

/// Applies the camera effects to a direct image of radiances (`width × height`, row-major)
/// and returns the frame. `depth_mm` (same layout, NaN where nothing was hit) drives the
/// defocus; `fx` is the camera's focal length in pixels.
///
/// # Errors
/// [`SimError::Image`] for an image of no pixels.
pub(crate) fn expose(
    mut radiance: Vec<f32>,
    width: usize,
    height: usize,
    depth_mm: &[f32],
    fx: f64,
    effects: &CameraEffects,
    key: NoiseKey,
) -> Result<GreyImage, SimError> {
    if let Some(gi) = effects.global_illumination.filter(|g| g.weight > 0.0) {
        let blurred = blur::box3(&radiance, width, height, gi.sigma_px);
        let w = gi.weight as f32;
        radiance
            .iter_mut()
            .zip(&blurred)
            .for_each(|(r, b)| *r += w * b);
    }
    radiance = match effects.defocus {
        Some(d) => defocus(
            &radiance,
            width,
            height,
            depth_mm,
            fx,
            &d,
            effects.lens_blur_px,
        ),
        None => blur::point_spread(&radiance, width, height, effects.lens_blur_px),
    };
    let s = &effects.sensor;
    let gain_e = s.exposure * s.full_well_electrons;
    let max_dn = s.bit_depth.max_value();
    let dn_per_e = max_dn / s.full_well_electrons;
    let dark_dn = s.dark_level_dn * max_dn / f64::from(u8::MAX);
    let to_dn = |row_index: usize, row: &[f32], out: &mut dyn FnMut(usize, f64)| {
        let mut rng = Pcg64Mcg::seed_from_u64(key.row_seed(row_index as u64));
        for (x, &r) in row.iter().enumerate() {
            let e = gain_e * f64::from(r.max(0.0));
            let var = if s.photon_noise { e } else { 0.0 }
                + s.read_noise_electrons * s.read_noise_electrons;
            let noisy = if var > 0.0 {
                let n: f64 = StandardNormal.sample(&mut rng);
                e + var.sqrt() * n
            } else {
                e
            };
            let electrons = noisy.clamp(0.0, s.full_well_electrons);
            out(
                x,
                round_non_negative(dark_dn + electrons * dn_per_e).clamp(0.0, max_dn),
            );
        }
    };
    Ok(match s.bit_depth {
        BitDepth::Eight => {
            let mut px = vec![0u8; width * height];
            px.par_chunks_mut(width.max(1))
                .zip(radiance.par_chunks(width.max(1)))
                .enumerate()
                .for_each(|(y, (o, row))| {
                    to_dn(y, row, &mut |x, v| {
                        if let Some(p) = o.get_mut(x) {
                            *p = v as u8;
                        }
                    });
                });
            GreyImage::U8(Frame::new(width, height, px)?)
        }
        BitDepth::Sixteen => {
            let mut px = vec![0u16; width * height];
            px.par_chunks_mut(width.max(1))
                .zip(radiance.par_chunks(width.max(1)))
                .enumerate()
                .for_each(|(y, (o, row))| {
                    to_dn(y, row, &mut |x, v| {
                        if let Some(p) = o.get_mut(x) {
                            *p = v as u16;
                        }
                    });
                });
            GreyImage::U16(Frame::new(width, height, px)?)
        }
    })
}

/// Depth-dependent blur by a stack of Gaussian blurs at σ = 0, 0.5, 1, ... px, each pixel
/// interpolating linearly between the two levels around its own σ, the defocus at its depth
/// and the lens's own spread `lens_px` added in quadrature.
fn defocus(
    src: &[f32],
    width: usize,
    height: usize,
    depth_mm: &[f32],
    fx: f64,
    d: &Defocus,
    lens_px: f64,
) -> Vec<f32> {
    let sigmas: Vec<f64> = depth_mm
        .iter()
        .map(|&z| {
            let s = if z.is_finite() {
                d.sigma_px(fx, f64::from(z))
            } else {
                0.0
            };
            s.hypot(lens_px).min(MAX_DEFOCUS_SIGMA_PX)
        })
        .collect();
    let max_sigma = sigmas.iter().copied().fold(0.0, f64::max);
    let levels = (max_sigma / DEFOCUS_LEVEL_STEP_PX).ceil() as usize;
    if levels == 0 {
        return src.to_vec();
    }
    let stack: Vec<Vec<f32>> = (0..=levels)
        .map(|l| blur::point_spread(src, width, height, l as f64 * DEFOCUS_LEVEL_STEP_PX))
        .collect();
    (0..src.len())
        .into_par_iter()
        .map(|i| {
            let s = sigmas.get(i).copied().unwrap_or(0.0) / DEFOCUS_LEVEL_STEP_PX;
            let lo = (s.floor() as usize).min(levels);
            let hi = (lo + 1).min(levels);
            let f = (s - lo as f64) as f32;
            let a = stack.get(lo).and_then(|v| v.get(i)).copied().unwrap_or(0.0);
            let b = stack.get(hi).and_then(|v| v.get(i)).copied().unwrap_or(0.0);
            a + f * (b - a)
        })
        .collect()
}

/// `v.round()` for `0 <= v < 2^63` (NaN gives 0, where `round` gives NaN; both become 0 once
/// the caller clamps and casts). `f64::round` is a libm call on the baseline x86-64 target, one per
/// pixel of every rendered frame; a truncating cast and one comparison give the same value,
/// halves away from zero included (`v - trunc(v)` is exact).
#[inline]
fn round_non_negative(v: f64) -> f64 {
    let t = v as i64 as f64;
    if v - t >= 0.5 { t + 1.0 } else { t }
}

#[cfg(test)]
mod tests {

    /// The cast-based rounding agrees with `f64::round` on halves, their neighbours one ulp
    /// away, and seeded random values over the range of digital numbers.
    #[test]
    fn round_non_negative_is_round() {
        use rand::{Rng, SeedableRng};
        let mut values = vec![0.0, 1e-300, 0.5, 1.5, 2.5, 65535.5, 0.49999999999999994];
        for k in 0..70_000u32 {
            let h = f64::from(k) + 0.5;
            values.extend([h, h.next_down(), h.next_up()]);
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        values.extend((0..100_000).map(|_| rng.random_range(0.0..70_000.0)));
        for v in values {
            assert_eq!(round_non_negative(v).to_bits(), v.round().to_bits(), "{v}");
        }
    }

    use super::*;
    use approx::assert_abs_diff_eq;

    fn stats(img: &GreyImage) -> (f64, f64) {
        let v: Vec<f64> = match img {
            GreyImage::U8(f) => f.data().iter().map(|&x| f64::from(x)).collect(),
            GreyImage::U16(f) => f.data().iter().map(|&x| f64::from(x)).collect(),
        };
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var)
    }

    #[test]
    fn noise_has_the_configured_statistics() {
        let (w, h) = (500, 400);
        let n = (w * h) as f64;
        for (bit_depth, photon) in [
            (BitDepth::Eight, true),
            (BitDepth::Sixteen, true),
            (BitDepth::Sixteen, false),
        ] {
            let sensor = SensorConfig {
                bit_depth,
                photon_noise: photon,
                ..SensorConfig::default()
            };
            let effects = CameraEffects {
                sensor,
                global_illumination: None,
                ..CameraEffects::default()
            };
            let radiance = 0.5f32;
            let img = expose(
                vec![radiance; w * h],
                w,
                h,
                &[],
                1000.0,
                &effects,
                NoiseKey {
                    seed: 7,
                    view: 0,
                    frame: 0,
                },
            )
            .unwrap();
            let (mean, var) = stats(&img);
            // Closed form: e = exposure * full_well * L electrons, variance e + read², scaled by
            // g = max / full_well, plus 1/12 for uniform rounding.
            let e = sensor.exposure * sensor.full_well_electrons * f64::from(radiance);
            let g = bit_depth.max_value() / sensor.full_well_electrons;
            let want_mean = sensor.dark_level_dn * bit_depth.max_value() / 255.0 + e * g;
            let want_var =
                (if photon { e } else { 0.0 } + sensor.read_noise_electrons.powi(2)) * g * g
                    + 1.0 / 12.0;
            // Standard error of the mean: sqrt(var / n); 5 of them (a 1-in-2-million miss).
            assert_abs_diff_eq!(
                mean,
                want_mean,
                epsilon = 5.0 * (want_var / n).sqrt() + 1e-9
            );
            // Sample variance of a Gaussian has relative standard error sqrt(2 / (n - 1));
            // 5 of them, plus 2 % for the rounding noise not being exactly independent of
            // the Gaussian when the noise is below one grey level (8-bit case).
            let tol = want_var * (5.0 * (2.0 / (n - 1.0)).sqrt() + 0.02);
            assert_abs_diff_eq!(var, want_var, epsilon = tol);
        }
    }

    #[test]
    fn saturation_and_reproducibility() {
        let (w, h) = (64, 32);
        let effects = CameraEffects::default();
        let key = NoiseKey {
            seed: 1,
            view: 2,
            frame: 3,
        };
        let img = expose(vec![10.0; w * h], w, h, &[], 1000.0, &effects, key).unwrap();
        assert_eq!(img, GreyImage::filled_u8(w, h, 255).unwrap());
        let a = expose(vec![0.3; w * h], w, h, &[], 1000.0, &effects, key).unwrap();
        let b = expose(vec![0.3; w * h], w, h, &[], 1000.0, &effects, key).unwrap();
        assert_eq!(a, b);
        let c = expose(
            vec![0.3; w * h],
            w,
            h,
            &[],
            1000.0,
            &effects,
            NoiseKey { frame: 4, ..key },
        )
        .unwrap();
        assert_ne!(a, c);
    }

    #[test]
    fn global_light_and_defocus_act_as_configured() {
        let (w, h) = (200, 100);
        let quiet = SensorConfig {
            photon_noise: false,
            read_noise_electrons: 0.0,
            bit_depth: BitDepth::Sixteen,
            dark_level_dn: 0.0,
            ..SensorConfig::default()
        };
        let key = NoiseKey {
            seed: 0,
            view: 0,
            frame: 0,
        };
        // Uniform radiance: the blurred copy is the same image, so GI multiplies it by 1 + w.
        let gi = CameraEffects {
            sensor: quiet,
            global_illumination: Some(GlobalIllumination {
                weight: 0.25,
                sigma_px: 10.0,
            }),
            ..CameraEffects::default()
        };
        let img = expose(vec![0.4; w * h], w, h, &[], 1000.0, &gi, key).unwrap();
        let want = (0.4 * 1.25 * quiet.exposure * 65535.0f64).round() as u16;
        let GreyImage::U16(px) = &img else {
            panic!("16-bit expected")
        };
        let px = px.data();
        // f32 radiance: within one grey level of the closed form.
        assert!(
            px.iter().all(|&v| v.abs_diff(want) <= 1),
            "{} vs {want}",
            px[0]
        );
        // Defocus: a vertical edge stays sharp at the focus distance and is blurred by the
        // thin-lens sigma elsewhere.
        let edge: Vec<f32> = (0..w * h)
            .map(|i| if i % w < w / 2 { 0.0 } else { 0.8 })
            .collect();
        let d = Defocus {
            focus_distance_mm: 450.0,
            aperture_mm: 3.0,
        };
        let fx = 3000.0;
        let blur = CameraEffects {
            sensor: quiet,
            defocus: Some(d),
            lens_blur_px: 0.0,
            global_illumination: None,
        };
        let sharp = expose(edge.clone(), w, h, &vec![450.0; w * h], fx, &blur, key).unwrap();
        let soft = expose(edge.clone(), w, h, &vec![600.0; w * h], fx, &blur, key).unwrap();
        let row = |img: &GreyImage| -> Vec<f64> {
            let GreyImage::U16(p) = img else {
                return Vec::new();
            };
            let p = p.data();
            (0..w).map(|x| f64::from(p[50 * w + x])).collect()
        };
        let (a, b) = (row(&sharp), row(&soft));
        assert_eq!(a[w / 2 - 1], 0.0);
        // sigma = 3000 * 3 * 150 / (600 * 450) / 4 = 1.25 px: the pixel left of the edge
        // (centre 0.5 px from it) gets 0.8 * (1 - Phi(0.5 / 1.25)) = 0.8 * 0.3446 of full light
        // The stack interpolates linearly between sigma 1 and 1.5 (0.339 for continuous
        // Gaussians) and samples its kernels at integer taps: within 0.015 of the exact value.
        let full = 0.8 * quiet.exposure * 65535.0;
        assert_abs_diff_eq!(b[w / 2 - 1] / full, 0.3446, epsilon = 0.015);
        assert_abs_diff_eq!(b[w / 2] / full, 1.0 - 0.3446, epsilon = 0.015);
    }

    #[test]
    fn defocus_sigma_closed_form() {
        let d = Defocus {
            focus_distance_mm: 450.0,
            aperture_mm: 3.0,
        };
        assert_abs_diff_eq!(d.sigma_px(1440.0, 450.0), 0.0);
        // 1440 * 3 * 50 / (500 * 450) / 4 = 0.24 px
        assert_abs_diff_eq!(d.sigma_px(1440.0, 500.0), 0.24, epsilon = 1e-12);
    }
}
