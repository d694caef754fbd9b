//! V4L2 control names and ids: the pure part of the V4L2 camera, compiled without the `v4l`
//! feature so that it is tested everywhere.
// Without the `v4l` feature only the tests use the ids and the conversion.
#![cfg_attr(not(feature = "v4l"), allow(dead_code))]

use crate::RigError;

/// `V4L2_CID_AUTO_WHITE_BALANCE` (`V4L2_CID_BASE + 12`, linux/v4l2-controls.h).
pub(crate) const CID_AUTO_WHITE_BALANCE: u32 = 0x0098_090c;
/// `V4L2_CID_AUTOGAIN` (`V4L2_CID_BASE + 18`).
pub(crate) const CID_AUTOGAIN: u32 = 0x0098_0912;
/// `V4L2_CID_GAIN` (`V4L2_CID_BASE + 19`).
pub(crate) const CID_GAIN: u32 = 0x0098_0913;
/// `V4L2_CID_WHITE_BALANCE_TEMPERATURE` (`V4L2_CID_BASE + 26`), in kelvin.
pub(crate) const CID_WHITE_BALANCE_TEMPERATURE: u32 = 0x0098_091a;
/// `V4L2_CID_EXPOSURE_AUTO` (`V4L2_CID_CAMERA_CLASS_BASE + 1`), a menu.
pub(crate) const CID_EXPOSURE_AUTO: u32 = 0x009a_0901;
/// `V4L2_CID_EXPOSURE_ABSOLUTE` (`V4L2_CID_CAMERA_CLASS_BASE + 2`), in units of 100 µs.
pub(crate) const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
/// `V4L2_CID_EXPOSURE_AUTO_PRIORITY` (`V4L2_CID_CAMERA_CLASS_BASE + 3`): when set, the
/// camera may lower its frame rate to lengthen the exposure; we clear it so that frame timing
/// stays predictable.
pub(crate) const CID_EXPOSURE_AUTO_PRIORITY: u32 = 0x009a_0903;
/// `V4L2_EXPOSURE_MANUAL`, the value of the `EXPOSURE_AUTO` menu that turns auto exposure off.
pub(crate) const EXPOSURE_MANUAL: i64 = 1;
/// Unit of `V4L2_CID_EXPOSURE_ABSOLUTE`: 100 µs = 0.1 ms.
pub(crate) const EXPOSURE_UNIT_MS: f64 = 0.1;

/// A V4L2 control, named by its numeric id or by its name.
///
/// Names match the driver's (`Exposure Time, Absolute`) or the form `v4l2-ctl` prints
/// (`exposure_time_absolute`): case, spaces and punctuation are ignored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ControlKey {
    /// A control id, e.g. `0x009a0902`.
    Id(u32),
    /// A control name, normalised (lower case, words joined by `_`).
    Name(String),
}

impl ControlKey {
    /// Parses `0x…` hexadecimal or decimal ids, anything else as a name.
    ///
    /// ```
    /// use sl_rig::ControlKey;
    /// assert_eq!(ControlKey::parse("0x009a0902"), ControlKey::Id(0x009a_0902));
    /// assert_eq!(ControlKey::parse("Exposure Time, Absolute"), ControlKey::parse("exposure_time_absolute"));
    /// ```
    pub fn parse(key: &str) -> Self {
        let key = key.trim();
        let id = match key.strip_prefix("0x").or_else(|| key.strip_prefix("0X")) {
            Some(hex) => u32::from_str_radix(hex, 16).ok(),
            None => key.parse().ok(),
        };
        id.map_or_else(|| Self::Name(normalise_control_name(key)), Self::Id)
    }

    /// `true` when this key names the control with id `id` and driver name `name`.
    pub fn matches(&self, id: u32, name: &str) -> bool {
        match self {
            Self::Id(i) => *i == id,
            Self::Name(n) => *n == normalise_control_name(name),
        }
    }
}

impl std::fmt::Display for ControlKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Id(id) => write!(f, "{id:#010x}"),
            Self::Name(name) => f.write_str(name),
        }
    }
}

/// `Exposure Time, Absolute` → `exposure_time_absolute`, as `v4l2-ctl --list-ctrls` prints it.
pub(crate) fn normalise_control_name(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.is_empty() && !out.ends_with('_') {
            out.push('_');
        }
    }
    while out.ends_with('_') {
        out.pop();
    }
    out
}

/// An exposure time in milliseconds as a value of `V4L2_CID_EXPOSURE_ABSOLUTE` (100 µs
/// units, rounded to the nearest, at least 1).
pub(crate) fn exposure_ms_to_v4l(exposure_ms: f64) -> Result<i64, RigError> {
    // The control is a 32-bit integer: 2^31 units of 100 µs are 59 hours.
    if !(exposure_ms.is_finite()
        && exposure_ms > 0.0
        && exposure_ms < f64::from(i32::MAX) * EXPOSURE_UNIT_MS)
    {
        return Err(RigError::param(
            "exposure_ms",
            format!("{exposure_ms} is not a positive exposure time in milliseconds"),
        ));
    }
    #[allow(clippy::cast_possible_truncation)] // bounded above
    let units = (exposure_ms / EXPOSURE_UNIT_MS).round() as i64;
    Ok(units.max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_normalise_like_v4l2_ctl() {
        // The names `v4l2-ctl --list-ctrls` prints for the uvcvideo driver's controls.
        for (driver, ctl) in [
            ("Exposure Time, Absolute", "exposure_time_absolute"),
            ("Auto Exposure", "auto_exposure"),
            (
                "White Balance Temperature, Auto",
                "white_balance_temperature_auto",
            ),
            ("Gain", "gain"),
            ("  Power Line Frequency ", "power_line_frequency"),
        ] {
            assert_eq!(normalise_control_name(driver), ctl);
            assert!(ControlKey::parse(ctl).matches(7, driver));
            assert!(ControlKey::parse(driver).matches(7, ctl));
        }
        assert!(!ControlKey::parse("gain").matches(CID_GAIN, "Brightness"));
    }

    #[test]
    fn ids_parse_in_hex_and_decimal() {
        assert_eq!(ControlKey::parse("0x00980913"), ControlKey::Id(CID_GAIN));
        assert_eq!(ControlKey::parse("9963795"), ControlKey::Id(CID_GAIN));
        assert!(ControlKey::parse("0x00980913").matches(CID_GAIN, "whatever"));
        assert_eq!(ControlKey::Id(CID_GAIN).to_string(), "0x00980913");
        // Not a number: a name, even if it starts like one.
        assert_eq!(ControlKey::parse("0xzz"), ControlKey::Name("0xzz".into()));
    }

    #[test]
    fn exposure_converts_to_100_us_units() {
        assert_eq!(exposure_ms_to_v4l(10.0).unwrap(), 100);
        assert_eq!(exposure_ms_to_v4l(33.36).unwrap(), 334);
        assert_eq!(exposure_ms_to_v4l(0.01).unwrap(), 1);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e12] {
            let err = exposure_ms_to_v4l(bad).unwrap_err().to_string();
            assert!(err.contains("exposure_ms"), "{err}");
        }
    }
}
