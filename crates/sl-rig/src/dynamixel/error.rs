//! What can go wrong between the computer and the servo, each with the path, id, baud rate
//! or register at fault, and what to do about it.

use std::fmt;
use std::path::PathBuf;
use std::time::Duration;

/// The Hardware Error Status register (address 70) of an MX-64 (2.0): one bit per fault the
/// servo detected. On any of them the servo switches its torque off and sets the alert bit
/// of every status packet until it is rebooted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct HardwareErrorStatus(pub u8);

impl HardwareErrorStatus {
    /// Bit 0: the input voltage is outside the configured limits.
    pub const INPUT_VOLTAGE: Self = Self(1 << 0);
    /// Bit 2: the internal temperature exceeded the Temperature Limit.
    pub const OVERHEATING: Self = Self(1 << 2);
    /// Bit 3: the motor encoder does not work as expected.
    pub const MOTOR_ENCODER: Self = Self(1 << 3);
    /// Bit 4: an electrical shock, or the input power is too low for the load.
    pub const ELECTRICAL_SHOCK: Self = Self(1 << 4);
    /// Bit 5: a persistent load exceeded the maximum output.
    pub const OVERLOAD: Self = Self(1 << 5);

    /// Every named bit with its name, in bit order.
    const NAMED: [(Self, &'static str); 5] = [
        (Self::INPUT_VOLTAGE, "input voltage"),
        (Self::OVERHEATING, "overheating"),
        (Self::MOTOR_ENCODER, "motor encoder"),
        (Self::ELECTRICAL_SHOCK, "electrical shock"),
        (Self::OVERLOAD, "overload"),
    ];

    /// No bit set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Whether every bit of `other` is set in `self`.
    pub fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    /// The names of the set bits (`"overload"`, `"overheating"`, ...), in bit order; bits
    /// the manual does not define are named `"bit N"`.
    pub fn names(self) -> Vec<String> {
        (0..8)
            .filter(|bit| self.0 & (1 << bit) != 0)
            .map(|bit| {
                Self::NAMED
                    .iter()
                    .find(|(flag, _)| flag.0 == 1 << bit)
                    .map_or_else(|| format!("bit {bit}"), |(_, name)| (*name).to_owned())
            })
            .collect()
    }
}

impl std::ops::BitOr for HardwareErrorStatus {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        Self(self.0 | rhs.0)
    }
}

impl fmt::Display for HardwareErrorStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_empty() {
            return write!(f, "none (0x00)");
        }
        write!(f, "{} ({:#04x})", self.names().join(", "), self.0)
    }
}

/// Everything that can go wrong with a Dynamixel turntable. Reaches callers inside
/// [`RigError::Dynamixel`](crate::RigError::Dynamixel).
///
/// Messages name the serial port, the servo id and baud rate, the register or angle at
/// fault, and what to try (`docs/hardware-turntable.md` has the troubleshooting table).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DynamixelError {
    /// The serial port does not exist.
    #[error(
        "serial port {}: not found; is the adapter plugged in? (`ls /dev/ttyUSB* /dev/ttyACM*`)",
        path.display()
    )]
    PortAbsent {
        /// The port.
        path: PathBuf,
    },
    /// The serial port exists but may not be opened by this user.
    #[error(
        "serial port {}: permission denied; add yourself to the `dialout` group \
         (`sudo usermod -aG dialout $USER`, then log in again) or install the udev rule of \
         docs/hardware-turntable.md",
        path.display()
    )]
    PortPermission {
        /// The port.
        path: PathBuf,
    },
    /// Another program holds the serial port.
    #[error(
        "serial port {}: busy, another program holds it (Dynamixel Wizard, a serial monitor, \
         ModemManager or another slscan); close it and retry",
        path.display()
    )]
    PortBusy {
        /// The port.
        path: PathBuf,
    },
    /// The serial port could not be opened or configured for another reason.
    #[error("serial port {}: cannot open or configure it at {baud} baud: {source}", path.display())]
    Port {
        /// The port.
        path: PathBuf,
        /// The baud rate asked for.
        baud: u32,
        /// The system's error.
        source: std::io::Error,
    },
    /// The servo did not answer, after every retry.
    #[error(
        "servo id {id} does not answer on {} at {baud} baud ({attempts} attempts): check the \
         12 V supply, the data cable, the id and the baud rate (Dynamixel Wizard's scan finds \
         both)",
        path.display()
    )]
    NoAnswer {
        /// The port.
        path: PathBuf,
        /// The servo id asked.
        id: u8,
        /// The baud rate used.
        baud: u32,
        /// How many times the instruction was sent.
        attempts: u32,
    },
    /// Every answer had a wrong CRC.
    #[error(
        "servo id {id} on {}: bad CRC in {attempts} answers in a row (last: received {received:#06x}, \
         computed {computed:#06x}); noise on the bus, a missing ground or a wrong baud rate",
        path.display()
    )]
    BadCrc {
        /// The port.
        path: PathBuf,
        /// The servo id.
        id: u8,
        /// How many answers were refused.
        attempts: u32,
        /// The CRC in the last answer.
        received: u16,
        /// The CRC computed over it.
        computed: u16,
    },
    /// Every answer was malformed (wrong id, wrong length, not a status packet).
    #[error("servo id {id} on {}: malformed answer to {instruction} ({detail})", path.display())]
    BadAnswer {
        /// The port.
        path: PathBuf,
        /// The servo id.
        id: u8,
        /// The instruction that was answered (`read Present Position`, ...).
        instruction: String,
        /// What was wrong with the last answer.
        detail: String,
    },
    /// The servo refused an instruction (the error field of its status packet).
    #[error("servo id {id} refused {instruction}: status error {code} ({meaning})")]
    Refused {
        /// The servo id.
        id: u8,
        /// The instruction (`write Operating Mode`, ...).
        instruction: String,
        /// The error number (1 to 7).
        code: u8,
        /// Its meaning in the Protocol 2.0 specification.
        meaning: &'static str,
    },
    /// The servo is not the model the configuration asks for.
    #[error(
        "servo id {id} is model {model} (firmware {firmware}), expected model {expected} \
         (MX-64 2.0 is 311; Protocol 1.0 firmwares must be updated with Dynamixel Wizard)"
    )]
    WrongModel {
        /// The servo id.
        id: u8,
        /// The model number it reports.
        model: u16,
        /// Its firmware version.
        firmware: u8,
        /// The model number expected.
        expected: u16,
    },
    /// The servo reports a hardware error and has switched its torque off.
    #[error(
        "servo id {id}: hardware error: {status}; the torque is off until the cause is fixed \
         and the servo rebooted (`DynamixelTurntable::reboot`)"
    )]
    Hardware {
        /// The servo id.
        id: u8,
        /// The Hardware Error Status register.
        status: HardwareErrorStatus,
    },
    /// The servo did not reach the goal in time.
    #[error(
        "servo id {id}: not at the goal {goal_deg:.3}° after {:.2} s (at {present_deg:.3}°, \
         moving = {moving}); blocked platter, too heavy a load, or too low a profile velocity",
        waited.as_secs_f64()
    )]
    MoveTimeout {
        /// The servo id.
        id: u8,
        /// The goal, motor degrees.
        goal_deg: f64,
        /// Where the servo was last seen, motor degrees.
        present_deg: f64,
        /// Whether it still reported `Moving`.
        moving: bool,
        /// How long the driver waited.
        waited: Duration,
    },
    /// The serial port went away while in use (adapter unplugged, emulator stopped).
    #[error(
        "serial port {}: closed while talking to servo id {id} (adapter unplugged?)",
        path.display()
    )]
    PortClosed {
        /// The port.
        path: PathBuf,
        /// The servo id.
        id: u8,
    },
    /// Reading or writing the port failed for another reason.
    #[error("serial port {} (servo id {id}): {source}", path.display())]
    Io {
        /// The port.
        path: PathBuf,
        /// The servo id.
        id: u8,
        /// The system's error.
        source: std::io::Error,
    },
    /// A goal angle outside the extended-position range (±256 turns).
    #[error(
        "angle {angle_deg}° is outside the servo's extended-position range (±{limit_deg:.0}° \
         around the configured zero)"
    )]
    AngleOutOfRange {
        /// The angle asked, motor degrees.
        angle_deg: f64,
        /// The largest magnitude allowed.
        limit_deg: f64,
    },
}

/// Meaning of a status error number, as the Protocol 2.0 specification names it.
pub(crate) fn status_error_meaning(code: u8) -> &'static str {
    use super::wire::status_error as e;
    match code {
        e::RESULT_FAIL => "result fail: the instruction could not be executed",
        e::INSTRUCTION => "instruction error: undefined or not allowed now",
        e::CRC => "CRC error: the servo received a corrupted packet",
        e::DATA_RANGE => "data range error: value out of range",
        e::DATA_LENGTH => "data length error: packet too short",
        e::DATA_LIMIT => "data limit error: value beyond a limit",
        e::ACCESS => {
            "access error: read-only or undefined address, or EEPROM written with the torque on"
        }
        _ => "undefined error number",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hardware_status_names_its_bits() {
        let s = HardwareErrorStatus::OVERLOAD | HardwareErrorStatus::OVERHEATING;
        assert_eq!(s.0, 0b0010_0100);
        assert_eq!(s.names(), ["overheating", "overload"]);
        assert_eq!(s.to_string(), "overheating, overload (0x24)");
        assert_eq!(HardwareErrorStatus(0b10).names(), ["bit 1"]);
        assert!(s.contains(HardwareErrorStatus::OVERLOAD));
        assert!(!s.contains(HardwareErrorStatus::INPUT_VOLTAGE));
    }
}
