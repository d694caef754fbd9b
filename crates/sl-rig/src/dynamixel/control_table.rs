//! The MX-64 (Protocol 2.0 firmware) control table: the entries the driver and the emulator
//! use, their units, and the velocity profile the servo follows in position modes.
//!
//! Addresses and units are those of the ROBOTIS e-Manual page "MX-64T/R/AR (2.0)".

use std::time::Duration;

/// Model number an MX-64 with the Protocol 2.0 firmware reports at address 0 and in its ping
/// answer (MX-64T/R/AR 2.0). The driver refuses any other model unless told otherwise
/// ([`DynamixelConfig::expected_model`](crate::DynamixelConfig::expected_model)).
pub const MX64_MODEL_NUMBER: u16 = 311;

/// Encoder ticks per output-shaft turn (12-bit magnetic encoder).
pub const TICKS_PER_TURN: i64 = 4096;

/// Degrees per encoder tick: 360 / 4096 ≈ 0.088°.
pub const DEG_PER_TICK: f64 = 360.0 / TICKS_PER_TURN as f64;

/// Largest goal position in extended position mode, in ticks either side of zero (±256
/// turns): the e-Manual's range for Goal Position in operating mode 4.
pub const EXTENDED_POSITION_LIMIT_TICKS: i64 = 1_048_575;

// Control-table addresses (bytes) and sizes.

/// Model Number, 2 bytes, read only (EEPROM).
pub(crate) const MODEL_NUMBER: u16 = 0;
/// Firmware Version, 1 byte, read only (EEPROM).
pub(crate) const FIRMWARE_VERSION: u16 = 6;
/// ID, 1 byte (EEPROM).
pub(crate) const ID: u16 = 7;
/// Baud Rate code, 1 byte (EEPROM).
pub(crate) const BAUD_RATE: u16 = 8;
/// Operating Mode, 1 byte (EEPROM, writable only with torque off).
pub(crate) const OPERATING_MODE: u16 = 11;
/// First address of the RAM area: EEPROM addresses below it are writable only with the
/// torque off.
pub(crate) const RAM_START: u16 = 64;
/// Torque Enable, 1 byte.
pub(crate) const TORQUE_ENABLE: u16 = 64;
/// Hardware Error Status, 1 byte, read only.
pub(crate) const HARDWARE_ERROR_STATUS: u16 = 70;
/// Profile Acceleration, 4 bytes, unit [`ACCELERATION_UNIT_DEG_S2`].
pub(crate) const PROFILE_ACCELERATION: u16 = 108;
/// Profile Velocity, 4 bytes, unit [`VELOCITY_UNIT_DEG_S`].
pub(crate) const PROFILE_VELOCITY: u16 = 112;
/// Goal Position, 4 bytes, signed ticks.
pub(crate) const GOAL_POSITION: u16 = 116;
/// Moving, 1 byte, read only: 1 while a profile is being executed.
pub(crate) const MOVING: u16 = 122;
/// Present Position, 4 bytes, signed ticks, read only.
pub(crate) const PRESENT_POSITION: u16 = 132;
/// Present Input Voltage, 2 bytes, unit 0.1 V, read only.
pub(crate) const PRESENT_INPUT_VOLTAGE: u16 = 144;
/// Present Temperature, 1 byte, °C, read only.
pub(crate) const PRESENT_TEMPERATURE: u16 = 146;
/// Size of the control table the emulator holds (last entry used + 1).
pub(crate) const TABLE_SIZE: usize = 147;

/// Operating Mode value of extended position control (multi-turn): positions run over
/// ±256 turns, so a 360° sequence never unwinds.
pub(crate) const EXTENDED_POSITION_MODE: u8 = 4;

/// Profile Velocity unit: 0.229 rev/min, in degrees per second (0.229 · 360 / 60).
pub(crate) const VELOCITY_UNIT_DEG_S: f64 = 0.229 * 6.0;
/// Profile Acceleration unit: 214.577 rev/min², in degrees per second² (· 360 / 3600).
pub(crate) const ACCELERATION_UNIT_DEG_S2: f64 = 214.577 / 10.0;

/// The velocity profile of a position move, as the servo plans it with "velocity-based"
/// profiles (Drive Mode bit 2 clear): accelerate at `a` up to `v`, cruise, decelerate —
/// a trapezoid, or a triangle when the distance is too short to reach `v`.
///
/// A zero acceleration means an infinite one (a rectangular velocity profile); the velocity
/// must be positive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Profile {
    /// Distance to travel in ticks (non-negative).
    pub(crate) distance: f64,
    /// Cruise velocity in ticks per second (positive).
    pub(crate) velocity: f64,
    /// Acceleration in ticks per second² (0 = infinite).
    pub(crate) acceleration: f64,
}

impl Profile {
    /// Time from start to standstill at the goal.
    pub(crate) fn duration(&self) -> Duration {
        Duration::from_secs_f64(self.duration_s().max(0.0))
    }

    fn duration_s(&self) -> f64 {
        let (d, v, a) = (self.distance, self.velocity, self.acceleration);
        if d <= 0.0 || v <= 0.0 {
            return 0.0;
        }
        if a <= 0.0 {
            return d / v;
        }
        let d_ramp = v * v / a; // accelerating plus decelerating
        if d_ramp >= d {
            2.0 * (d / a).sqrt()
        } else {
            2.0 * v / a + (d - d_ramp) / v
        }
    }

    /// Distance covered after `t` seconds (clamped to `[0, distance]`).
    pub(crate) fn travelled(&self, t: f64) -> f64 {
        let (d, v, a) = (self.distance, self.velocity, self.acceleration);
        let total = self.duration_s();
        if t <= 0.0 || d <= 0.0 {
            return 0.0;
        }
        if t >= total {
            return d;
        }
        if a <= 0.0 {
            return (v * t).min(d);
        }
        // Peak velocity: v, or lower for a triangle.
        let peak = v.min((a * d).sqrt());
        let t_ramp = peak / a;
        let travelled = if t < t_ramp {
            0.5 * a * t * t
        } else if t < total - t_ramp {
            0.5 * peak * t_ramp + peak * (t - t_ramp)
        } else {
            let left = total - t;
            d - 0.5 * a * left * left
        };
        travelled.clamp(0.0, d)
    }
}

/// Ticks per second for a Profile Velocity register value.
pub(crate) fn velocity_ticks_s(raw: u32) -> f64 {
    f64::from(raw) * VELOCITY_UNIT_DEG_S / DEG_PER_TICK
}

/// Ticks per second² for a Profile Acceleration register value.
pub(crate) fn acceleration_ticks_s2(raw: u32) -> f64 {
    f64::from(raw) * ACCELERATION_UNIT_DEG_S2 / DEG_PER_TICK
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn trapezoid_matches_closed_form() {
        // 180 ticks at 30 ticks/s with 10 ticks/s²: ramps of v/a = 3 s covering ½·10·3² = 45
        // ticks each, then 90 ticks of cruise at 30/s = 3 s: 9 s in total.
        let p = Profile {
            distance: 180.0,
            velocity: 30.0,
            acceleration: 10.0,
        };
        assert_relative_eq!(p.duration().as_secs_f64(), 9.0, epsilon = 1e-9);
        assert_relative_eq!(p.travelled(3.0), 45.0, epsilon = 1e-12);
        // Cruising: 45 + 30 · 1 s.
        assert_relative_eq!(p.travelled(4.0), 75.0, epsilon = 1e-12);
        // Symmetric: half way in time is half way in distance.
        assert_relative_eq!(p.travelled(4.5), 90.0, epsilon = 1e-12);
        // Decelerating: 1 s before the end, ½·10·1² short of the goal.
        assert_relative_eq!(p.travelled(8.0), 175.0, epsilon = 1e-12);
        assert_relative_eq!(p.travelled(9.0), 180.0, epsilon = 1e-12);
    }

    #[test]
    fn triangle_and_rectangle() {
        // Too short to reach the cruise velocity: 2·sqrt(d/a).
        let p = Profile {
            distance: 40.0,
            velocity: 100.0,
            acceleration: 10.0,
        };
        assert_relative_eq!(p.duration().as_secs_f64(), 4.0, epsilon = 1e-9);
        assert_relative_eq!(p.travelled(2.0), 20.0, epsilon = 1e-12);
        // Infinite acceleration.
        let p = Profile {
            distance: 40.0,
            velocity: 10.0,
            acceleration: 0.0,
        };
        assert_relative_eq!(p.duration().as_secs_f64(), 4.0, epsilon = 1e-9);
        assert_relative_eq!(p.travelled(1.0), 10.0, epsilon = 1e-12);
    }

    #[test]
    fn units_match_the_manual() {
        // 0.229 rev/min per unit: 100 units = 22.9 rev/min = 137.4°/s.
        assert_relative_eq!(velocity_ticks_s(100) * DEG_PER_TICK, 137.4, epsilon = 1e-9);
        // 214.577 rev/min² per unit = 21.4577°/s².
        assert_relative_eq!(
            acceleration_ticks_s2(1) * DEG_PER_TICK,
            21.4577,
            epsilon = 1e-9
        );
    }
}
