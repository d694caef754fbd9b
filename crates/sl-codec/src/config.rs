//! Decoder thresholds.

use crate::CodecError;

/// Default [`DecodeConfig::min_direct`]: 8 grey levels of direct light. Camera noise on the
/// 8-bit sensors we target is 1-2 levels rms, so a pattern/inverse pair of 8 levels apart is
/// still 3-4 sigma from a coin toss; OpenCV's default black threshold (40) throws away the dark
/// parts of low-albedo objects that decode perfectly well.
pub const DEFAULT_MIN_DIRECT: f32 = 8.0;

/// Default [`DecodeConfig::min_contrast`]: a bit is certain when pattern and inverse differ by
/// at least 4 grey levels (about 2 sigma of the difference of two samples with 1.5 levels of
/// noise each); weaker bits are treated as unreadable and resolved by the stripe-edge rule.
pub const DEFAULT_MIN_CONTRAST: f32 = 4.0;

/// Default [`DecodeConfig::direct_global_bits`]: the 3 finest Gray bits (stripes 2, 4 and 8
/// projector pixels wide for a per-pixel code) are fine enough for Nayar's high-frequency
/// assumption and coarse enough that every camera pixel is fully lit in one of them.
pub const DEFAULT_DIRECT_GLOBAL_BITS: u32 = 3;

/// Default [`DecodeConfig::min_modulation`]: 5 grey levels of fringe amplitude. With 4 steps
/// and 1.5 levels of noise the phase noise is then `sqrt(2/N) * 1.5 / 5 = 0.21` rad, the most
/// a 3-frequency heterodyne tolerates before its unwrapping test rejects the pixel.
pub const DEFAULT_MIN_MODULATION: f32 = 5.0;

/// Default [`DecodeConfig::saturation_level`]: the top 8-bit level (65535 for 16-bit frames).
pub const DEFAULT_SATURATION_LEVEL: f32 = 255.0;

/// Default [`DecodeConfig::unwrap_tolerance`]: a temporal-unwrapping step is trusted when the
/// predicted and measured phases agree to within 0.35 period. Rounding goes wrong only past 0.5,
/// and a wrong step shows a residual of at least 0.65 unless the error is larger than a whole
/// period. 0.35 rather than 0.25 because real projectors are not linear: SLMaster's heterodyne
/// capture carries ~0.08 rad of gamma ripple per frequency, which the last heterodyne step
/// amplifies tenfold; at 0.25 that rejected 7% of its pixels although 99% of those agree with
/// the independent Gray-coded capture of the same scene, at 0.35 almost none.
pub const DEFAULT_UNWRAP_TOLERANCE: f32 = 0.35;

/// Default [`DecodeConfig::rows_per_task`]: 8 camera rows per rayon task (10 KB of each 8-bit
/// 1280-px frame, so a task's working set stays in L2 while there are ~90 tasks for 720 rows
/// to balance two or more cores).
pub const DEFAULT_ROWS_PER_TASK: usize = 8;

/// Thresholds and options of the decoders.
///
/// Grey-level thresholds are in 8-bit grey levels; for 16-bit frames they are multiplied by
/// 257.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodeConfig {
    /// Gray code: smallest direct light `Ld` (Nayar's split) for a pixel to be decoded;
    /// below it the pixel is `Shadow` (or `LowModulation` when its darkest value is above it).
    pub min_direct: f32,
    /// Gray code: smallest `|pattern - inverse|` (or `2 |frame - threshold|` with white/black or
    /// phase-mean references) for a bit to count as read.
    pub min_contrast: f32,
    /// Gray code with inverses: apply Xu & Aliaga's rules when global light is strong
    /// (`Ld <= Lg`); with `false` every bit is a plain pattern-against-inverse comparison.
    pub robust: bool,
    /// Gray code with inverses: how many of the finest bits estimate direct and global light.
    pub direct_global_bits: u32,
    /// Projector black level as a fraction of white, Nayar's `b` in `[0, 1)`: light the
    /// projector leaks when showing black.
    pub black_level: f32,
    /// Phase shift: smallest fringe modulation `B` for a pixel to be decoded.
    pub min_modulation: f32,
    /// A sample at or above this level is saturated.
    pub saturation_level: f32,
    /// Temporal unwrapping: largest accepted disagreement between a predicted and a measured
    /// phase, in periods (cycles).
    pub unwrap_tolerance: f32,
    /// Camera rows per parallel task.
    pub rows_per_task: usize,
    /// Phase shift and hybrid: the projector's measured response (`slscan calibrate
    /// response`, a calibration's `projector_response`). When given and not linear, every
    /// phase is corrected for the error the response causes with the block's step count
    /// ([`crate::PhaseCorrection`]); `None` (the default) trusts the fringes to be sinusoids.
    pub projector_response: Option<sl_image::ToneCurve>,
}

impl Default for DecodeConfig {
    fn default() -> Self {
        Self {
            min_direct: DEFAULT_MIN_DIRECT,
            min_contrast: DEFAULT_MIN_CONTRAST,
            robust: true,
            direct_global_bits: DEFAULT_DIRECT_GLOBAL_BITS,
            black_level: 0.0,
            min_modulation: DEFAULT_MIN_MODULATION,
            saturation_level: DEFAULT_SATURATION_LEVEL,
            unwrap_tolerance: DEFAULT_UNWRAP_TOLERANCE,
            rows_per_task: DEFAULT_ROWS_PER_TASK,
            projector_response: None,
        }
    }
}

impl DecodeConfig {
    /// Checks the domains of the fields.
    ///
    /// # Errors
    /// [`CodecError::Parameter`] naming the first bad field.
    pub fn validate(&self) -> Result<(), CodecError> {
        for (name, v) in [
            ("min_direct", self.min_direct),
            ("min_contrast", self.min_contrast),
            ("min_modulation", self.min_modulation),
            ("saturation_level", self.saturation_level),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CodecError::parameter(
                    name,
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        if !(0.0..1.0).contains(&self.black_level) {
            return Err(CodecError::parameter(
                "black_level",
                format!("must be in [0, 1), got {}", self.black_level),
            ));
        }
        if !(self.unwrap_tolerance > 0.0 && self.unwrap_tolerance <= 0.5) {
            return Err(CodecError::parameter(
                "unwrap_tolerance",
                format!("must be in (0, 0.5] periods, got {}", self.unwrap_tolerance),
            ));
        }
        if self.rows_per_task == 0 {
            return Err(CodecError::parameter("rows_per_task", "must be at least 1"));
        }
        Ok(())
    }
}

/// A grey-level threshold scaled to the sample type, as an integer (clamped to `u16`).
#[inline]
pub(crate) fn level_u16(value_8bit: f32, scale: f32) -> u16 {
    (value_8bit * scale).round().clamp(0.0, 65535.0) as u16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_bad_fields_are_named() {
        DecodeConfig::default().validate().unwrap();
        let c = DecodeConfig {
            black_level: 1.0,
            ..DecodeConfig::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("black_level")
        );
        let c = DecodeConfig {
            min_modulation: f32::NAN,
            ..DecodeConfig::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("min_modulation")
        );
        assert_eq!(level_u16(255.0, 257.0), 65535);
        assert_eq!(level_u16(1e9, 257.0), 65535);
    }
}
