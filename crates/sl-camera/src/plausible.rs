//! Whether a camera or projector model makes physical sense: what every calibration file must
//! pass to be read ([`crate::Calibration::load`]). A model can be valid (finite, positive focal
//! lengths) and still describe no lens: `fx = 1e308` squeezes the image into 1e-303°, `k1 = 1e6`
//! makes the distortion, not the focal length, decide where every ray lands. Such a file is a
//! typo or a failed calibration, and the scan made with it a cloud of a few points with exit 0.

use std::fmt;

use nalgebra::Point2;

use crate::{CameraModel, DISTORTION_PARAMETERS, DistortionModel};

/// Narrowest field of view accepted across the image (degrees). 0.1° over 1000 px is a focal
/// length of 5.7e5 px: the longest lenses on the smallest pixels stay above it (600 mm on
/// 1.4 µm pixels is 4.3e5 px, 0.17° over 1280 px), while a focal length in the wrong unit or a
/// typo (`1e308`) falls far below.
pub const MIN_FIELD_OF_VIEW_DEG: f64 = 0.1;

/// Widest field of view accepted across the image (degrees). A pinhole images less than 180°
/// across, and the distortion models are not one-to-one beyond 89.4° off-axis anyway (see
/// [`crate::Distortion::max_radius`]); a wider figure comes from a focal length of a pixel or
/// less.
pub const MAX_FIELD_OF_VIEW_DEG: f64 = 179.0;

/// Largest factor by which the distortion may scale the radius of an image border pixel
/// (distorted radius over undistorted). Real pincushion distortion moves the corners out by a
/// few per cent (telephoto lenses) to a few tens of per cent (strong projector optics, or a
/// polynomial extrapolated to corners no board reached): 10 is far beyond all of them, while
/// `k1 = 1e6` on a 1280 px camera scales the corners by ~64. Barrel distortion (a factor below
/// 1, down to ~0.1 for the widest lenses these models fit) is bounded by
/// [`MAX_FIELD_OF_VIEW_DEG`] instead.
pub const MAX_RADIAL_SCALE: f64 = 10.0;

/// A border pixel unprojected to its ray and projected again must come back within this (px):
/// where it does not, the distortion cannot be inverted there. Newton's undistortion is exact
/// to ~1e-10 px, so 0.01 px flags only a model that is not invertible.
pub const ROUND_TRIP_PX: f64 = 0.01;

/// A parameter of a [`CameraModel`], as [`CameraModel::check_physical`] names the one at fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelParameter {
    /// An intrinsic: `fx`, `fy`, `cx`, `cy` or `skew`.
    Intrinsic(&'static str),
    /// A distortion coefficient: `k1` … `k6`, `p1`, `p2`.
    Distortion(&'static str),
}

impl ModelParameter {
    /// Its name: `fx`, `k1`, ….
    pub fn name(self) -> &'static str {
        match self {
            Self::Intrinsic(n) | Self::Distortion(n) => n,
        }
    }

    /// Its key in this project's JSON under a device: `intrinsics.fx`, `distortion.k1`.
    pub fn json_key(self) -> String {
        match self {
            Self::Intrinsic(n) => format!("intrinsics.{n}"),
            Self::Distortion(n) => format!("distortion.{n}"),
        }
    }
}

/// Why a model makes no physical sense (see [`CameraModel::check_physical`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Implausibility {
    /// The parameter at fault (for a distortion that misbehaves, the coefficient whose term
    /// weighs most where it does).
    pub parameter: ModelParameter,
    /// What is wrong, beginning with the parameter and its value: `fx = 1e308 px: …`.
    pub message: String,
}

impl fmt::Display for Implausibility {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Implausibility {}

/// An angle in degrees, readable however small.
fn degrees(v: f64) -> String {
    if v.abs() >= 0.01 || v == 0.0 {
        format!("{v:.2}°")
    } else {
        format!("{v:.1e}°")
    }
}

/// A number as a message gives it: plain, or in exponent form when very large or small
/// (`1e308`, not 309 digits).
fn number(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// The coefficient whose term of the distortion weighs most at squared normalised radius `s`
/// (`k = [k1, k2, p1, p2, k3, k4, k5, k6]`): the radial terms `|k_i| s^i`, the tangential ones
/// about `3 |p| r`.
fn dominant(k: &[f64; 8], s: f64) -> (&'static str, f64) {
    let r = s.sqrt();
    let weight = [
        k[0].abs() * s,
        k[1].abs() * s * s,
        3.0 * k[2].abs() * r,
        3.0 * k[3].abs() * r,
        k[4].abs() * s * s * s,
        k[5].abs() * s,
        k[6].abs() * s * s,
        k[7].abs() * s * s * s,
    ];
    let i = (0..8)
        .max_by(|&a, &b| weight[a].total_cmp(&weight[b]))
        .unwrap_or(0);
    (DISTORTION_PARAMETERS[i], k[i])
}

impl CameraModel {
    /// Checks that the model describes a lens: focal lengths finite and positive, principal
    /// point, skew and distortion coefficients finite, a field of view across the image
    /// between [`MIN_FIELD_OF_VIEW_DEG`] and [`MAX_FIELD_OF_VIEW_DEG`], and a distortion that
    /// is one-to-one out to the image border (the radial map increasing from the centre out to
    /// the corners; each border pixel, unprojected then projected, back within
    /// [`ROUND_TRIP_PX`]) and scales no border pixel's radius by more than
    /// [`MAX_RADIAL_SCALE`]. The border pixels are the four corners and the middles of the
    /// four edges (pixel centres at integers, so the image spans `-0.5 .. width - 0.5`).
    /// A principal point outside the image is fine (projectors often have `cy` beyond the
    /// bottom edge).
    ///
    /// ```
    /// use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics};
    /// let size = ImageSize::new(1280, 720);
    /// let good = CameraModel::new(
    ///     Intrinsics::new(1440.0, 1440.0, 639.5, 359.5),
    ///     Distortion::from_opencv(&[-0.08, 0.12, 0.0004, -0.0003, 0.0])?,
    ///     size,
    /// )?;
    /// assert!(good.check_physical().is_ok());
    /// let mut bad = good;
    /// bad.intrinsics.fx = 1e308;
    /// let why = bad.check_physical().unwrap_err();
    /// assert_eq!(why.parameter.name(), "fx");
    /// bad = good;
    /// bad.distortion = Distortion::from_opencv(&[1e6, 0.0, 0.0, 0.0, 0.0])?;
    /// assert_eq!(bad.check_physical().unwrap_err().parameter.json_key(), "distortion.k1");
    /// # Ok::<(), sl_camera::CameraError>(())
    /// ```
    ///
    /// # Errors
    /// An [`Implausibility`] naming the parameter at fault and saying why, with the figures.
    pub fn check_physical(&self) -> Result<(), Implausibility> {
        let intrinsic = |name, message| {
            Err(Implausibility {
                parameter: ModelParameter::Intrinsic(name),
                message,
            })
        };
        let k = &self.intrinsics;
        for (name, v) in [("fx", k.fx), ("fy", k.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return intrinsic(
                    name,
                    format!(
                        "{name} = {} px: a focal length must be finite and positive",
                        number(v)
                    ),
                );
            }
        }
        for (name, v) in [("cx", k.cx), ("cy", k.cy), ("skew", k.skew)] {
            if !v.is_finite() {
                return intrinsic(name, format!("{name} = {} px: must be finite", number(v)));
            }
        }
        let coefficients = self.distortion.coefficients();
        for (name, v) in DISTORTION_PARAMETERS.into_iter().zip(coefficients) {
            if !v.is_finite() {
                return Err(Implausibility {
                    parameter: ModelParameter::Distortion(name),
                    message: format!(
                        "{name} = {}: a distortion coefficient must be finite",
                        number(v)
                    ),
                });
            }
        }
        let (w, h) = (f64::from(self.size.width), f64::from(self.size.height));
        let fov_ok = |fov: f64| (MIN_FIELD_OF_VIEW_DEG..=MAX_FIELD_OF_VIEW_DEG).contains(&fov);
        // The pinhole alone: the angle between the rays through the first and the last pixel
        // edge of each axis.
        for (name, f, c, extent, across) in
            [("fx", k.fx, k.cx, w, "wide"), ("fy", k.fy, k.cy, h, "high")]
        {
            let fov = (((extent - 0.5 - c) / f).atan() - ((-0.5 - c) / f).atan()).to_degrees();
            if !fov_ok(fov) {
                return intrinsic(
                    name,
                    format!(
                        "{name} = {} px: the {extent} px {across} image would span {} (a lens \
                         sees between {MIN_FIELD_OF_VIEW_DEG}° and {MAX_FIELD_OF_VIEW_DEG}° \
                         across)",
                        number(f),
                        degrees(fov)
                    ),
                );
            }
        }
        if self.distortion.model() == DistortionModel::None {
            return Ok(());
        }
        let (l, t, r, b) = (-0.5, -0.5, w - 0.5, h - 0.5);
        let (mx, my) = (0.5 * (l + r), 0.5 * (t + b));
        let border = [
            ("top-left corner", l, t),
            ("top-right corner", r, t),
            ("bottom-left corner", l, b),
            ("bottom-right corner", r, b),
            ("left edge's middle", l, my),
            ("right edge's middle", r, my),
            ("top edge's middle", mx, t),
            ("bottom edge's middle", mx, b),
        ];
        for (place, u, v) in border {
            let px = Point2::new(u, v);
            let pd = k.normalised_from_pixel(&px);
            let fault = |s: f64, why: String| {
                let (name, value) = dominant(&coefficients, s);
                Err(Implausibility {
                    parameter: ModelParameter::Distortion(name),
                    message: format!("{name} = {}: {why}", number(value)),
                })
            };
            let Some(p) = self.distortion.undistort(&pd) else {
                let limit = self.distortion.max_radius().atan().to_degrees();
                return fault(
                    pd.coords.norm_squared(),
                    format!(
                        "the distortion is not one-to-one out to the image's {place} ({u}, {v}): \
                         the radial map stops increasing {} off-axis, inside the image",
                        degrees(limit)
                    ),
                );
            };
            let s = p.coords.norm_squared();
            let moved = (self.project_normalised(p.x, p.y) - px).norm();
            if moved.is_nan() || moved > ROUND_TRIP_PX {
                return fault(
                    s,
                    format!(
                        "the image's {place} ({u}, {v}), unprojected and projected again, moves \
                         by {moved:.3} px (at most {ROUND_TRIP_PX}): the distortion cannot be \
                         inverted there"
                    ),
                );
            }
            let scale = pd.coords.norm() / p.coords.norm();
            if scale > MAX_RADIAL_SCALE {
                return fault(
                    s,
                    format!(
                        "the distortion scales the radius of the image's {place} ({u}, {v}) by \
                         {scale:.1} (a lens's by at most {MAX_RADIAL_SCALE}): it, not the focal \
                         length, would decide where the rays land"
                    ),
                );
            }
        }
        // With the distortion: the angle between the rays through the edges' middles.
        if let Some(fov) = self.field_of_view() {
            for (deg, (u, v)) in [(fov.horizontal_deg, (r, my)), (fov.vertical_deg, (mx, b))] {
                if !fov_ok(deg) {
                    let pd = k.normalised_from_pixel(&Point2::new(u, v));
                    let (name, value) = dominant(&coefficients, pd.coords.norm_squared());
                    return Err(Implausibility {
                        parameter: ModelParameter::Distortion(name),
                        message: format!(
                            "{name} = {}: with the distortion the image spans {} (a lens sees \
                             between {MIN_FIELD_OF_VIEW_DEG}° and {MAX_FIELD_OF_VIEW_DEG}° \
                             across)",
                            number(value),
                            degrees(deg)
                        ),
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Distortion, ImageSize, Intrinsics};

    fn camera(fx: f64, d: &[f64]) -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics::new(fx, fx, 639.5, 359.5),
            distortion: Distortion::from_opencv(d).unwrap(),
            size: ImageSize::new(1280, 720),
        }
    }

    fn fault(m: &CameraModel) -> Option<String> {
        m.check_physical()
            .err()
            .map(|e| format!("{}: {}", e.parameter.json_key(), e.message))
    }

    #[test]
    fn real_lenses_pass() {
        // The virtual rig's camera, a wide barrel lens (70° across, 20 % barrel at the corners),
        // OpenCV's sample of a strong polynomial, a projector with the principal point below
        // the image, and no distortion at all.
        for m in [
            camera(1440.0, &[-0.08, 0.12, 0.0004, -0.0003, 0.0]),
            camera(900.0, &[-0.28, 0.07, 0.0, 0.0, 0.0]),
            camera(1440.4, &[0.5466, -20.20, -0.02203, 0.008259, 211.1]),
            camera(1440.0, &[]),
            CameraModel {
                intrinsics: Intrinsics::new(2210.0, 2208.5, 955.0, 1102.0),
                distortion: Distortion::from_opencv(&[0.04, -0.05, 0.0, 0.0, 0.0]).unwrap(),
                size: ImageSize::new(1920, 1080),
            },
        ] {
            assert_eq!(fault(&m), None, "{m:?}");
        }
    }

    #[test]
    fn each_fault_names_its_parameter() {
        let cases: [(CameraModel, &str); 6] = [
            (camera(1e308, &[]), "intrinsics.fx"),
            (camera(1e6, &[]), "intrinsics.fx"),
            (camera(0.001, &[]), "intrinsics.fx"),
            (camera(1440.0, &[1e6, 0.0, 0.0, 0.0, 0.0]), "distortion.k1"),
            (camera(1440.0, &[-1e6, 0.0, 0.0, 0.0, 0.0]), "distortion.k1"),
            (
                camera(1440.0, &[0.0, 0.0, 0.0, 0.0, -50.0]),
                "distortion.k3",
            ),
        ];
        for (m, key) in cases {
            let f = fault(&m).unwrap_or_else(|| panic!("{m:?} passed"));
            assert!(f.starts_with(key), "{key}: {f}");
        }
        let mut m = camera(1440.0, &[]);
        m.intrinsics.fy = 1e308;
        assert!(
            fault(&m)
                .unwrap()
                .starts_with("intrinsics.fy: fy = 1e308 px: the 720 px high")
        );
        m.intrinsics.cx = f64::NAN;
        assert!(fault(&m).unwrap().starts_with("intrinsics.cx"));
    }
}
