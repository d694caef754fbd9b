//! The parsers of slscan's numeric options: every number is checked where it is given, by
//! clap, so a bad value exits 2 with clap's line naming the option and its value
//! (`invalid value 'NaN' for '--square <SQUARE>': must be a finite number > 0`). Each option
//! names one of these in its `value_parser`; the checks that need more than the value (a period
//! against the projector it codes, a depth scale against the cloud's depths) are made at run
//! time and name the option too.
//!
//! The ranges, shared so that the messages read the same everywhere:
//! - [`positive`]: finite and > 0 (sizes, scales, distances that must be something);
//! - [`non_negative`]: finite and ≥ 0 (thresholds and distances where 0 means "none");
//! - [`finite`]: any finite number (angles, coordinates);
//! - [`positive_or_inf`]: > 0, `inf` allowed (an upper bound that `inf` turns off);
//! - [`in_range`], [`positive_up_to`]: finite and within a range (gamma, fractions, lengths);
//! - [`grey_level`]: 0 to 255 (the decoder's and the triangulation's thresholds);
//! - [`at_least`], [`count_in`]: whole numbers from a least value (views, iterations);
//! - [`projector_size`], [`camera_size`], [`board_size`]: `WxH` sizes with a largest side.

use std::ops::RangeInclusive;

use clap::builder::RangedU64ValueParser;
use sl_calib::BoardSize;
use sl_codec::ImageSize;

/// The largest side of a projector (`--projector`, `--projector-size`), in pixels: 16384, twice
/// the 8K UHD projectors (7680x4320) that are the largest made, so any real projector fits
/// while one pattern image stays under 256 MiB at 8 bits (a 100000x100000 set would need
/// 10 GB per image); the per-pixel Gray code reaches 2^16 stripes, beyond this.
pub(crate) const MAX_PROJECTOR_SIDE: u32 = 16_384;

/// The largest side of a camera image (`--camera-size`), in pixels: 65536, beyond the largest
/// sensors made (a 150 MP medium-format camera is 14204x10652).
pub(crate) const MAX_CAMERA_SIDE: u32 = 65_536;

/// The most inner corners along a side of a checkerboard (`--board`): 100, ten times the usual
/// 9x6 board; more corners than that cannot be resolved by a camera of any size on one board.
pub(crate) const MAX_BOARD_CORNERS: u32 = 100;

/// The largest checkerboard square (`--square`, `--square-mm`), in mm: a board of 1 m squares
/// is 10 m wide, beyond any calibration target; smaller values are anything > 0.
pub(crate) const MAX_SQUARE_MM: f64 = 1000.0;

/// Parses a number (`f64`, so `NaN`, `inf`, `1e308` are read as such and then judged).
fn number(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .map_err(|_| format!("not a number: {s:?}"))
}

/// Finite and > 0.
pub(crate) fn positive(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err("must be a finite number > 0".to_owned())
    }
}

/// Finite and ≥ 0.
pub(crate) fn non_negative(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err("must be a finite number ≥ 0".to_owned())
    }
}

/// Finite.
pub(crate) fn finite(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err("must be a finite number".to_owned())
    }
}

/// > 0, `inf` allowed (for an upper bound that `inf` turns off).
pub(crate) fn positive_or_inf(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err("must be a number > 0 (inf turns the bound off)".to_owned())
    }
}

/// `--exposures`: `auto`, `camera`, or exposure times in milliseconds (`2,8,32`).
pub(crate) fn exposures(s: &str) -> Result<structured_light::scan::Exposures, String> {
    s.parse()
        .map_err(|e: structured_light::scan::ScanError| e.to_string())
}

/// OpenCV's distortion coefficients, comma-separated: 4, 5, 8, 12 or 14 finite numbers (thin
/// prism and tilt terms must be zero: `sl_camera::Distortion::from_opencv`).
pub(crate) fn distortion(s: &str) -> Result<structured_light::camera::Distortion, String> {
    let k = s
        .split(',')
        .map(|v| number(v.trim()))
        .collect::<Result<Vec<f64>, String>>()?;
    structured_light::camera::Distortion::from_opencv(&k).map_err(|e| e.to_string())
}

/// Finite and within `range` (both ends included).
pub(crate) fn in_range(
    range: RangeInclusive<f64>,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |s| {
        let v = number(s)?;
        if v.is_finite() && range.contains(&v) {
            Ok(v)
        } else {
            Err(format!(
                "must be a number from {} to {}",
                range.start(),
                range.end()
            ))
        }
    }
}

/// Finite, > 0 and at most `max`.
pub(crate) fn positive_up_to(
    max: f64,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |s| {
        let v = number(s)?;
        if v.is_finite() && v > 0.0 && v <= max {
            Ok(v)
        } else {
            Err(format!("must be a number > 0 and at most {max}"))
        }
    }
}

/// `parse` read as `f32` (the decoder's thresholds and tolerances are `f32`).
pub(crate) fn as_f32(
    parse: impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static,
) -> impl Fn(&str) -> Result<f32, String> + Clone + Send + Sync + 'static {
    move |s| {
        let v = parse(s)?;
        let f = v as f32;
        if f.is_finite() && (f != 0.0 || v == 0.0) {
            Ok(f)
        } else {
            Err(format!("{v} does not fit a 32-bit number"))
        }
    }
}

/// The finest length slscan takes in mm (`--voxel`, `--max-distance`): 1 µm, below the noise
/// of any structured-light scanner (tens of µm); a finer one only overflows grids.
pub(crate) const MIN_LENGTH_MM: f64 = 1e-3;

/// A voxel size in mm: 0 (keep every point), or finite and at least [`MIN_LENGTH_MM`].
pub(crate) fn voxel_or_zero(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v == 0.0 || (v.is_finite() && v >= MIN_LENGTH_MM) {
        Ok(v)
    } else {
        Err(format!(
            "must be 0 (keep every point) or a size of at least {MIN_LENGTH_MM} mm"
        ))
    }
}

/// A length in mm: finite and at least [`MIN_LENGTH_MM`].
pub(crate) fn length_mm(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v >= MIN_LENGTH_MM {
        Ok(v)
    } else {
        Err(format!("must be a length of at least {MIN_LENGTH_MM} mm"))
    }
}

/// The factors `--scale` takes: 1e-6 to 1e6, from µm to km and back to mm (1000 for metres,
/// 25.4 for inches, 0.001 for µm).
pub(crate) fn scale(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && (1e-6..=1e6).contains(&v) {
        Ok(v)
    } else {
        Err("must be a factor from 1e-6 to 1e6 (1000 for metres, 25.4 for inches)".to_owned())
    }
}

/// A fraction in [0, 1).
pub(crate) fn fraction_below_one(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if (0.0..1.0).contains(&v) {
        Ok(v)
    } else {
        Err("must be a fraction from 0 up to, not including, 1".to_owned())
    }
}

/// A threshold in 8-bit grey levels, 0 to 255 (no pixel passes a higher one).
pub(crate) fn grey_level(s: &str) -> Result<f32, String> {
    as_f32(in_range(0.0..=255.0))(s)
}

/// A whole number ≥ `least` (clap's own range check: `0 is not in 1..=4294967295`).
pub(crate) fn at_least<T>(least: u64) -> RangedU64ValueParser<T>
where
    T: TryFrom<u64> + Clone + Send + Sync + 'static,
    <T as TryFrom<u64>>::Error: std::fmt::Display + Send + Sync + 'static,
{
    RangedU64ValueParser::<T>::new().range(least..)
}

/// A whole number in `range`.
pub(crate) fn count_in<T>(range: RangeInclusive<u64>) -> RangedU64ValueParser<T>
where
    T: TryFrom<u64> + Clone + Send + Sync + 'static,
    <T as TryFrom<u64>>::Error: std::fmt::Display + Send + Sync + 'static,
{
    RangedU64ValueParser::<T>::new().range(range)
}

/// The most `--downscale` divides the virtual rig's resolution by: 8, a 160x90 camera and a
/// 240x135 projector, the least that still resolves the hybrid code's 15 px periods.
pub(crate) const MAX_DOWNSCALE: u64 = 8;

/// `--downscale`: 1 to [`MAX_DOWNSCALE`].
pub(crate) fn downscale() -> RangedU64ValueParser<u32> {
    count_in(1..=MAX_DOWNSCALE)
}

/// The longest display latency (`--latency-ms`): 10 s, a hundred times the default 100 ms and
/// beyond any display; a longer wait per pattern makes a session of hours.
pub(crate) const MAX_LATENCY_MS: u64 = 10_000;

/// `--latency-ms`: 0 to [`MAX_LATENCY_MS`].
pub(crate) fn latency_ms() -> RangedU64ValueParser<u64> {
    count_in(0..=MAX_LATENCY_MS)
}

/// The most turntable views of a session (`--views`): 3600, one every 0.1°, finer than any
/// turntable's repeatability; a session of more would run for days.
pub(crate) const MAX_VIEWS: u64 = 3600;

/// `--views`: 1 to [`MAX_VIEWS`].
pub(crate) fn views() -> RangedU64ValueParser<usize> {
    count_in(1..=MAX_VIEWS)
}

/// 8 or 16 (bits per pixel of an image file).
pub(crate) fn bit_depth<T: From<u8>>(s: &str) -> Result<T, String> {
    match s.trim() {
        "8" => Ok(T::from(8)),
        "16" => Ok(T::from(16)),
        _ => Err("must be 8 or 16".to_owned()),
    }
}

/// `WIDTHxHEIGHT` with each side in `1..=max`.
fn size_up_to(s: &str, max: u32) -> Result<ImageSize, String> {
    let size: ImageSize = s.parse().map_err(|e: sl_codec::ImageError| e.to_string())?;
    if size.width > max || size.height > max {
        return Err(format!("each side must be at most {max} pixels"));
    }
    Ok(size)
}

/// A projector's `WIDTHxHEIGHT`, each side in `1..=`[`MAX_PROJECTOR_SIDE`].
pub(crate) fn projector_size(s: &str) -> Result<ImageSize, String> {
    size_up_to(s, MAX_PROJECTOR_SIDE)
}

/// A camera's `WIDTHxHEIGHT`, each side in `1..=`[`MAX_CAMERA_SIDE`].
pub(crate) fn camera_size(s: &str) -> Result<ImageSize, String> {
    size_up_to(s, MAX_CAMERA_SIDE)
}

/// A board's inner corners `COLSxROWS`, each in `2..=`[`MAX_BOARD_CORNERS`].
pub(crate) fn board_size(s: &str) -> Result<BoardSize, String> {
    let b: BoardSize = s.parse().map_err(|e: sl_calib::CalibError| e.to_string())?;
    if b.cols > MAX_BOARD_CORNERS || b.rows > MAX_BOARD_CORNERS {
        return Err(format!(
            "at most {MAX_BOARD_CORNERS} inner corners along a side"
        ));
    }
    Ok(b)
}

#[cfg(test)]
mod tests {
    //! The parsers on their own: what each accepts and refuses.

    #[test]
    fn each_parser_refuses_what_is_out_of_its_range() {
        for bad in ["NaN", "inf", "-inf", "0", "-1", "x", ""] {
            assert!(super::positive(bad).is_err(), "{bad}");
        }
        assert_eq!(super::positive("1e-300"), Ok(1e-300));
        assert_eq!(super::non_negative("0"), Ok(0.0));
        assert!(super::non_negative("-1e-300").is_err());
        assert_eq!(super::positive_or_inf("inf"), Ok(f64::INFINITY));
        assert!(super::positive_or_inf("NaN").is_err());
        assert!(super::finite("1e309").is_err());
        let gamma = super::in_range(0.1..=10.0);
        assert!(gamma("10.000001").is_err());
        assert_eq!(gamma("2.2"), Ok(2.2));
        assert!(super::projector_size("16385x10").is_err());
        assert!(super::projector_size("16384x1").is_ok());
        assert!(super::board_size("101x6").is_err());
        assert_eq!(super::bit_depth::<u8>("16"), Ok(16));
        assert!(super::bit_depth::<u8>("12").is_err());
    }
}
