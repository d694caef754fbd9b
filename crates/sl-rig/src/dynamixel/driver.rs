//! The turntable driver: a Dynamixel MX-64 (Protocol 2.0) in extended position mode, on the
//! `dynamixel2` crate.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use dynamixel2::{Bus, InvalidMessage, ReadError, WriteError};
use sl_camera::TurntableAxis;

use super::control_table::{
    self as ct, ACCELERATION_UNIT_DEG_S2, DEG_PER_TICK, EXTENDED_POSITION_LIMIT_TICKS,
    EXTENDED_POSITION_MODE, MX64_MODEL_NUMBER, Profile, TICKS_PER_TURN, VELOCITY_UNIT_DEG_S,
};
use super::error::{DynamixelError, HardwareErrorStatus, status_error_meaning};
use super::wire::{instruction, status_error};
use crate::{RigError, Turntable};

/// Factory id of every Dynamixel.
pub(crate) const DEFAULT_ID: u8 = 1;
/// Factory baud rate of the MX-64 (2.0).
pub(crate) const DEFAULT_BAUD: u32 = 57_600;
/// How long to wait for each answer. An FTDI-based adapter (U2D2, most USB–RS485 sticks)
/// holds received bytes for up to its latency timer, 16 ms by default; the servo adds its
/// Return Delay Time (0.5 ms by default) and a 30-byte answer takes 5 ms at 57 600 baud:
/// 50 ms leaves a margin without making a dead servo slow to report.
pub(crate) const DEFAULT_RESPONSE_TIMEOUT: Duration = Duration::from_millis(50);
/// Times an instruction is sent before giving up: a lone bit error on a long RS-485 cable
/// costs one retry; three silent answers in a row mean the servo is not there.
pub(crate) const DEFAULT_ATTEMPTS: u32 = 3;
/// Profile velocity: 45°/s, a turn in 8 s, slow enough that an object standing loose on the
/// platter does not slide.
pub(crate) const DEFAULT_PROFILE_VELOCITY_DEG_S: f64 = 45.0;
/// Profile acceleration: 90°/s², full speed in half a second, gentle on loose objects.
pub(crate) const DEFAULT_PROFILE_ACCELERATION_DEG_S2: f64 = 90.0;
/// Position tolerance: 4 ticks (0.35°). The MX-64's position loop settles within 1–2 ticks
/// of the goal unloaded; 4 absorbs a slightly off-centre load without waiting forever.
pub(crate) const DEFAULT_TOLERANCE_DEG: f64 = 4.0 * DEG_PER_TICK;
/// Interval between two polls of `Moving` and `Present Position` during a move: 20 ms
/// keeps the bus mostly idle and adds at most 20 ms to each move.
pub(crate) const DEFAULT_POLL_INTERVAL: Duration = Duration::from_millis(20);
/// Time allowed beyond the planned profile before a move times out: the position loop
/// needs a few hundred milliseconds to settle; a blocked platter needs to be reported soon.
pub(crate) const DEFAULT_SETTLE_TIMEOUT: Duration = Duration::from_secs(3);
/// How long a reboot may take before the servo answers again (the MX-64 boots in well under
/// a second).
pub(crate) const DEFAULT_REBOOT_TIMEOUT: Duration = Duration::from_secs(3);

/// Size of the `dynamixel2` bus buffers: the longest packet here is a 4-byte write (14 bytes
/// stuffed at worst) or a status with 4 parameters (15 bytes); 128 is the library's default.
const BUFFER_LEN: usize = 128;

/// How to reach and drive the servo. `Default` is a factory-fresh MX-64 (2.0): id 1,
/// 57 600 baud; each field says its default and the source says why.
#[derive(Clone, Debug, PartialEq)]
pub struct DynamixelConfig {
    /// Servo id on the bus (0–252); 1 by default (the factory id).
    pub id: u8,
    /// Baud rate of the serial port; must match the servo's Baud Rate register. 57 600 by
    /// default (the factory setting).
    pub baud: u32,
    /// Model number the servo must report, or `None` to accept any Protocol 2.0 servo with
    /// the same control table (X-series). [`MX64_MODEL_NUMBER`] by default.
    pub expected_model: Option<u16>,
    /// How long to wait for each answer; 50 ms by default (see `DEFAULT_RESPONSE_TIMEOUT` in
    /// the source for why).
    pub response_timeout: Duration,
    /// How many times each instruction is sent before giving up (at least 1); 3 by default.
    pub attempts: u32,
    /// Profile velocity in motor degrees per second (> 0); rounded to the servo's unit of
    /// 0.229 rev/min (1.374°/s). 45°/s by default.
    pub profile_velocity_deg_s: f64,
    /// Profile acceleration in motor degrees per second² (≥ 0, 0 = as fast as possible);
    /// rounded to the servo's unit of 214.577 rev/min² (21.46°/s²). 90°/s² by default.
    pub profile_acceleration_deg_s2: f64,
    /// A move is complete when `Moving` is 0 and the servo is within this many degrees of
    /// the goal; 4 ticks (0.35°) by default.
    pub tolerance_deg: f64,
    /// Interval between two polls during a move; 20 ms by default.
    pub poll_interval: Duration,
    /// Time allowed beyond the planned profile before a move times out; 3 s by default.
    pub settle_timeout: Duration,
    /// How long a reboot may take; 3 s by default.
    pub reboot_timeout: Duration,
    /// Encoder position (ticks, extended range) that is motor angle 0.
    pub zero_ticks: i64,
    /// Reboot the servo when it reports a hardware error at [`DynamixelTurntable::open`]
    /// instead of failing.
    pub reboot_on_hardware_error: bool,
}

impl Default for DynamixelConfig {
    fn default() -> Self {
        Self {
            id: DEFAULT_ID,
            baud: DEFAULT_BAUD,
            expected_model: Some(MX64_MODEL_NUMBER),
            response_timeout: DEFAULT_RESPONSE_TIMEOUT,
            attempts: DEFAULT_ATTEMPTS,
            profile_velocity_deg_s: DEFAULT_PROFILE_VELOCITY_DEG_S,
            profile_acceleration_deg_s2: DEFAULT_PROFILE_ACCELERATION_DEG_S2,
            tolerance_deg: DEFAULT_TOLERANCE_DEG,
            poll_interval: DEFAULT_POLL_INTERVAL,
            settle_timeout: DEFAULT_SETTLE_TIMEOUT,
            reboot_timeout: DEFAULT_REBOOT_TIMEOUT,
            zero_ticks: 0,
            reboot_on_hardware_error: false,
        }
    }
}

impl DynamixelConfig {
    /// Checks every field; the error names the field.
    pub fn validate(&self) -> Result<(), RigError> {
        let p = RigError::param;
        if self.id > 252 {
            return Err(p("id", format!("must be 0..=252, found {}", self.id)));
        }
        if self.baud == 0 {
            return Err(RigError::param("baud", "must be positive"));
        }
        if self.attempts == 0 {
            return Err(RigError::param("attempts", "must be at least 1"));
        }
        if self.response_timeout.is_zero() {
            return Err(RigError::param("response_timeout", "must be positive"));
        }
        let v = self.profile_velocity_deg_s;
        if !(v.is_finite() && v > 0.0 && v / VELOCITY_UNIT_DEG_S <= f64::from(u32::MAX)) {
            return Err(p(
                "profile_velocity_deg_s",
                format!("must be a positive number of degrees per second, found {v}"),
            ));
        }
        let a = self.profile_acceleration_deg_s2;
        if !(a.is_finite() && a >= 0.0 && a / ACCELERATION_UNIT_DEG_S2 <= f64::from(u32::MAX)) {
            return Err(p(
                "profile_acceleration_deg_s2",
                format!("must be a finite number ≥ 0, found {a}"),
            ));
        }
        let t = self.tolerance_deg;
        if !(t.is_finite() && t >= 0.0) {
            return Err(p("tolerance_deg", format!("must be ≥ 0, found {t}")));
        }
        if self.zero_ticks.abs() > EXTENDED_POSITION_LIMIT_TICKS {
            return Err(p(
                "zero_ticks",
                format!(
                    "must be within ±{EXTENDED_POSITION_LIMIT_TICKS}, found {}",
                    self.zero_ticks
                ),
            ));
        }
        Ok(())
    }

    /// Profile Velocity register value (at least 1: 0 would mean "unlimited").
    fn velocity_raw(&self) -> u32 {
        // Validated: finite, positive, fits in u32.
        ((self.profile_velocity_deg_s / VELOCITY_UNIT_DEG_S).round() as u32).max(1)
    }

    /// Profile Acceleration register value (0 = unlimited).
    fn acceleration_raw(&self) -> u32 {
        (self.profile_acceleration_deg_s2 / ACCELERATION_UNIT_DEG_S2).round() as u32
    }
}

/// What the servo reports about itself ([`DynamixelTurntable::status`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoStatus {
    /// Motor angle in degrees (relative to [`DynamixelConfig::zero_ticks`], continuous across
    /// reboots).
    pub angle_deg: f64,
    /// Present Position register, ticks (the servo's own count, reset to one turn by a reboot).
    pub present_ticks: i64,
    /// Whether a profile is being executed.
    pub moving: bool,
    /// Torque Enable.
    pub torque_enabled: bool,
    /// Internal temperature, °C.
    pub temperature_c: f64,
    /// Input voltage, volts.
    pub input_voltage_v: f64,
    /// Hardware Error Status.
    pub hardware_error: HardwareErrorStatus,
}

/// A turntable driven by a Dynamixel MX-64 (2.0) over Protocol 2.0: a U2D2 or USB–RS485
/// adapter (or an Arduino with a Dynamixel shield acting as one) on a serial port.
///
/// [`open`](Self::open) pings the servo, checks its model, switches the torque off, sets
/// extended position mode (operating mode 4: multi-turn, so a 360° sequence goes on to
/// 360° instead of unwinding to 0°), writes the profile velocity and acceleration and
/// switches the torque on. [`Turntable::rotate_to`] writes Goal Position and polls `Moving`
/// and `Present Position` until the servo stands within tolerance of the goal, and returns
/// the angle the servo reports.
///
/// Angles are **motor degrees**: 4096 ticks per turn, counted from
/// [`DynamixelConfig::zero_ticks`] — the reading that
/// [`TurntableAxis::table_angle_deg`] and [`TurntableAxis::motion`] take, so the calibrated
/// offset and scale are applied once, downstream;
/// [`rotate_table_to`](Self::rotate_table_to) commands a platter angle through the axis.
///
/// Every instruction is retried ([`DynamixelConfig::attempts`]) on silence, a bad CRC or a
/// malformed answer; every answer's alert bit is checked, and a hardware error (overload,
/// overheating, input voltage, electrical shock, encoder) is reported as
/// [`DynamixelError::Hardware`] naming the bits. [`reboot`](Self::reboot) clears it and
/// keeps the angle continuous (a reboot resets the servo's turn count).
///
/// Dropping it closes (and unlocks) the port; the servo keeps holding its position with the
/// torque on — call [`set_torque(false)`](Self::set_torque) first to free the platter.
///
/// ```
/// use sl_rig::{DynamixelConfig, DynamixelTurntable, EmulatorConfig, Mx64Emulator, Turntable};
/// # fn main() -> Result<(), sl_rig::RigError> {
/// // An emulated MX-64 on a pseudo-terminal stands in for the hardware.
/// let servo = Mx64Emulator::spawn(EmulatorConfig::default())?;
/// let config = DynamixelConfig { profile_velocity_deg_s: 360.0, ..DynamixelConfig::default() };
/// let mut table = DynamixelTurntable::open(servo.port_path(), config)?;
/// let reached = table.rotate_to(30.0)?;
/// assert!((reached - 30.0).abs() <= sl_rig::DEG_PER_TICK * 4.0);
/// # Ok(())
/// # }
/// ```
#[derive(Debug)]
pub struct DynamixelTurntable {
    bus: Bus<Vec<u8>, Vec<u8>>,
    path: PathBuf,
    config: DynamixelConfig,
    model: u16,
    firmware: u8,
    /// Extended ticks = Present Position + `turn_offset`: keeps angles continuous across
    /// reboots, which reset the servo's position to within one turn.
    turn_offset: i64,
}

/// An answer to an instruction.
struct Reply {
    params: Vec<u8>,
    alert: bool,
}

/// Why one attempt failed.
enum Failure {
    /// Worth another attempt.
    Retry(Retry),
    /// Not worth it.
    Fatal(DynamixelError),
}

/// Failures another attempt may cure.
enum Retry {
    Silence,
    Crc { received: u16, computed: u16 },
    Malformed(String),
    ServoSawBadCrc,
}

impl DynamixelTurntable {
    /// Opens the serial port `path` at `config.baud`, finds the servo and configures it (see
    /// the type's docs).
    ///
    /// # Errors
    /// [`RigError::InvalidParameter`] for a bad configuration; [`RigError::Dynamixel`] with
    /// [`DynamixelError::PortAbsent`], [`PortPermission`](DynamixelError::PortPermission),
    /// [`PortBusy`](DynamixelError::PortBusy) or [`Port`](DynamixelError::Port) when the port
    /// cannot be used, [`NoAnswer`](DynamixelError::NoAnswer) when the id does not answer,
    /// [`WrongModel`](DynamixelError::WrongModel), or
    /// [`Hardware`](DynamixelError::Hardware) when the servo reports a hardware error (unless
    /// [`DynamixelConfig::reboot_on_hardware_error`]).
    pub fn open(path: impl AsRef<Path>, config: DynamixelConfig) -> Result<Self, RigError> {
        config.validate()?;
        let path = path.as_ref().to_path_buf();
        let bus =
            Bus::open_with_buffers(&path, config.baud, vec![0; BUFFER_LEN], vec![0; BUFFER_LEN])
                .map_err(|e| open_error(&path, config.baud, e))?;
        // An advisory exclusive lock, as pyserial's `exclusive=True` takes it: two programs
        // talking to one servo corrupt each other's packets.
        match rustix::fs::flock(
            bus.serial_port(),
            rustix::fs::FlockOperation::NonBlockingLockExclusive,
        ) {
            Err(e) if e == rustix::io::Errno::WOULDBLOCK => {
                return Err(DynamixelError::PortBusy { path }.into());
            }
            // Other failures (a file system without locks) do not stop us.
            _ => {}
        }
        let mut table = Self {
            bus,
            path,
            config,
            model: 0,
            firmware: 0,
            turn_offset: 0,
        };
        let ping = table.transact("ping", instruction::PING, &[], 3, false)?;
        let (model, firmware) = match ping.params.as_slice() {
            [lo, hi, fw] => (u16::from_le_bytes([*lo, *hi]), *fw),
            _ => (0, 0), // unreachable: transact checked the length
        };
        table.model = model;
        table.firmware = firmware;
        if let Some(expected) = table.config.expected_model
            && expected != model
        {
            return Err(DynamixelError::WrongModel {
                id: table.config.id,
                model,
                firmware,
                expected,
            }
            .into());
        }
        let status = table.hardware_error()?;
        if !status.is_empty() {
            if table.config.reboot_on_hardware_error {
                return table.reboot().map(|()| table);
            }
            return Err(DynamixelError::Hardware {
                id: table.config.id,
                status,
            }
            .into());
        }
        table.configure()?;
        Ok(table)
    }

    /// The serial port.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The configuration in use.
    pub fn config(&self) -> &DynamixelConfig {
        &self.config
    }

    /// Model number the servo reported (311 for an MX-64 2.0).
    pub fn model(&self) -> u16 {
        self.model
    }

    /// Firmware version the servo reported.
    pub fn firmware(&self) -> u8 {
        self.firmware
    }

    /// The Hardware Error Status register.
    ///
    /// # Errors
    /// Communication errors ([`RigError::Dynamixel`]).
    pub fn hardware_error(&mut self) -> Result<HardwareErrorStatus, RigError> {
        let status = self.read_u8(ct::HARDWARE_ERROR_STATUS, "Hardware Error Status", false)?;
        Ok(HardwareErrorStatus(status))
    }

    /// Position, motion, torque, temperature, voltage and hardware error, as the servo
    /// reports them.
    ///
    /// # Errors
    /// Communication errors ([`RigError::Dynamixel`]); a hardware error is reported in the
    /// result, not as an error.
    pub fn status(&mut self) -> Result<ServoStatus, RigError> {
        let present = self.read_i32(ct::PRESENT_POSITION, "Present Position", false)?;
        let moving = self.read_u8(ct::MOVING, "Moving", false)?;
        let torque = self.read_u8(ct::TORQUE_ENABLE, "Torque Enable", false)?;
        let temperature = self.read_u8(ct::PRESENT_TEMPERATURE, "Present Temperature", false)?;
        let voltage = u16::from_le_bytes(self.read(
            ct::PRESENT_INPUT_VOLTAGE,
            "Present Input Voltage",
            false,
        )?);
        Ok(ServoStatus {
            angle_deg: self.ticks_to_deg(present),
            present_ticks: present,
            moving: moving != 0,
            torque_enabled: torque != 0,
            temperature_c: f64::from(temperature),
            input_voltage_v: f64::from(voltage) * 0.1,
            hardware_error: self.hardware_error()?,
        })
    }

    /// Switches the torque on (the servo holds its position) or off (the platter turns
    /// freely by hand).
    ///
    /// # Errors
    /// Communication errors and hardware errors ([`RigError::Dynamixel`]).
    pub fn set_torque(&mut self, on: bool) -> Result<(), RigError> {
        self.write(ct::TORQUE_ENABLE, "Torque Enable", &[u8::from(on)])
    }

    /// Changes the profile velocity (°/s, > 0) and acceleration (°/s², ≥ 0, 0 = unlimited)
    /// of the following moves.
    ///
    /// # Errors
    /// [`RigError::InvalidParameter`] for values out of range; communication errors.
    pub fn set_profile(
        &mut self,
        velocity_deg_s: f64,
        acceleration_deg_s2: f64,
    ) -> Result<(), RigError> {
        let mut config = self.config.clone();
        config.profile_velocity_deg_s = velocity_deg_s;
        config.profile_acceleration_deg_s2 = acceleration_deg_s2;
        config.validate()?;
        self.write(
            ct::PROFILE_ACCELERATION,
            "Profile Acceleration",
            &config.acceleration_raw().to_le_bytes(),
        )?;
        self.write(
            ct::PROFILE_VELOCITY,
            "Profile Velocity",
            &config.velocity_raw().to_le_bytes(),
        )?;
        self.config = config;
        Ok(())
    }

    /// Reboots the servo — the only way to clear a hardware error — waits until it answers
    /// again and configures it as [`open`](Self::open) does. The motor angle stays continuous:
    /// the servo forgets its turn count, the driver does not.
    ///
    /// # Errors
    /// Communication errors; [`DynamixelError::Hardware`] if the error persists after the
    /// reboot (the cause is still there: overload, heat, supply).
    pub fn reboot(&mut self) -> Result<(), RigError> {
        // Where we are, to restore the turn count (reads work despite a hardware error).
        let before = self
            .read_i32(ct::PRESENT_POSITION, "Present Position", false)
            .ok()
            .map(|raw| raw + self.turn_offset);
        self.transact("reboot", instruction::REBOOT, &[], 0, false)?;
        let deadline = Instant::now() + self.config.reboot_timeout;
        loop {
            std::thread::sleep(self.config.poll_interval);
            match self.transact("ping", instruction::PING, &[], 3, false) {
                Ok(_) => break,
                Err(RigError::Dynamixel(DynamixelError::NoAnswer { .. }))
                    if Instant::now() < deadline => {}
                Err(e) => return Err(e),
            }
        }
        let status = self.hardware_error()?;
        if !status.is_empty() {
            return Err(DynamixelError::Hardware {
                id: self.config.id,
                status,
            }
            .into());
        }
        self.configure()?;
        let after = self.read_i32(ct::PRESENT_POSITION, "Present Position", true)?;
        self.turn_offset = match before {
            Some(b) => ((b - after) as f64 / TICKS_PER_TURN as f64).round() as i64 * TICKS_PER_TURN,
            None => 0,
        };
        Ok(())
    }

    /// Rotates the platter to the **platter** angle `table_deg` through the calibrated
    /// `axis` (`θ = angle_scale · m + angle_offset_deg`, solved for the motor angle `m`) and
    /// returns the platter angle reached.
    ///
    /// # Errors
    /// [`RigError::InvalidParameter`] if the axis scale is zero or not finite; as
    /// [`Turntable::rotate_to`].
    pub fn rotate_table_to(
        &mut self,
        table_deg: f64,
        axis: &TurntableAxis,
    ) -> Result<f64, RigError> {
        let scale = axis.angle_scale;
        if !(scale.is_finite() && scale != 0.0 && axis.angle_offset_deg.is_finite()) {
            return Err(RigError::param(
                "turntable.angle_scale",
                format!("must be finite and non-zero, found {scale}"),
            ));
        }
        let motor = (table_deg - axis.angle_offset_deg) / scale;
        let reached = self.rotate_to(motor)?;
        Ok(axis.table_angle_deg(reached))
    }

    /// Torque off, extended position mode, profile, torque on.
    fn configure(&mut self) -> Result<(), RigError> {
        // EEPROM registers (Operating Mode) are writable only with the torque off.
        self.write(ct::TORQUE_ENABLE, "Torque Enable", &[0])?;
        let mode = self.read_u8(ct::OPERATING_MODE, "Operating Mode", true)?;
        if mode != EXTENDED_POSITION_MODE {
            // Written only when different: EEPROM cells wear out.
            self.write(
                ct::OPERATING_MODE,
                "Operating Mode",
                &[EXTENDED_POSITION_MODE],
            )?;
        }
        let (v, a) = (self.config.velocity_raw(), self.config.acceleration_raw());
        self.write(
            ct::PROFILE_ACCELERATION,
            "Profile Acceleration",
            &a.to_le_bytes(),
        )?;
        self.write(ct::PROFILE_VELOCITY, "Profile Velocity", &v.to_le_bytes())?;
        self.write(ct::TORQUE_ENABLE, "Torque Enable", &[1])
    }

    /// Motor degrees for a Present Position.
    fn ticks_to_deg(&self, present: i64) -> f64 {
        (present + self.turn_offset - self.config.zero_ticks) as f64 * DEG_PER_TICK
    }

    /// Reads `N` bytes from `address` (`name` for messages). Registers are read one at a
    /// time: `dynamixel2` 0.9 misses the byte stuffing of `FF FF FF FD` runs, which a
    /// multi-register read (a velocity of −1 followed by a position byte `FD`) can contain.
    fn read<const N: usize>(
        &mut self,
        address: u16,
        name: &str,
        check_alert: bool,
    ) -> Result<[u8; N], RigError> {
        let len = u16::try_from(N).unwrap_or(u16::MAX);
        let r = self.transact(
            &format!("read {name}"),
            instruction::READ,
            &read_params(address, len),
            N,
            check_alert,
        )?;
        // `transact` checked the length.
        Ok(<[u8; N]>::try_from(r.params.as_slice()).unwrap_or([0; N]))
    }

    fn read_u8(&mut self, address: u16, name: &str, check_alert: bool) -> Result<u8, RigError> {
        let [v] = self.read(address, name, check_alert)?;
        Ok(v)
    }

    /// A signed 4-byte register (positions), widened.
    fn read_i32(&mut self, address: u16, name: &str, check_alert: bool) -> Result<i64, RigError> {
        Ok(i64::from(i32::from_le_bytes(self.read(
            address,
            name,
            check_alert,
        )?)))
    }

    fn write(&mut self, address: u16, name: &str, data: &[u8]) -> Result<(), RigError> {
        let mut params = address.to_le_bytes().to_vec();
        params.extend_from_slice(data);
        self.transact(
            &format!("write {name}"),
            instruction::WRITE,
            &params,
            0,
            true,
        )
        .map(|_| ())
    }

    /// Sends an instruction and reads the answer, retrying on silence, bad CRC and malformed
    /// answers; with `check_alert`, an answer with the alert bit turns into
    /// [`DynamixelError::Hardware`].
    fn transact(
        &mut self,
        what: &str,
        instruction: u8,
        params: &[u8],
        expected_len: usize,
        check_alert: bool,
    ) -> Result<Reply, RigError> {
        let mut last = Retry::Silence;
        for _ in 0..self.config.attempts {
            match self.attempt(instruction, params, expected_len) {
                Ok(reply) => {
                    if check_alert && reply.alert {
                        let status = self.hardware_error()?;
                        if !status.is_empty() {
                            return Err(DynamixelError::Hardware {
                                id: self.config.id,
                                status,
                            }
                            .into());
                        }
                    }
                    return Ok(reply);
                }
                Err(Failure::Fatal(e)) => return Err(self.name_fatal(e, what).into()),
                Err(Failure::Retry(r)) => last = r,
            }
        }
        let (path, id, attempts) = (self.path.clone(), self.config.id, self.config.attempts);
        if self.hung_up() {
            return Err(DynamixelError::PortClosed { path, id }.into());
        }
        Err(match last {
            Retry::Silence => DynamixelError::NoAnswer {
                path,
                id,
                baud: self.config.baud,
                attempts,
            },
            Retry::Crc { received, computed } => DynamixelError::BadCrc {
                path,
                id,
                attempts,
                received,
                computed,
            },
            Retry::Malformed(detail) => DynamixelError::BadAnswer {
                path,
                id,
                instruction: what.to_owned(),
                detail,
            },
            Retry::ServoSawBadCrc => DynamixelError::Refused {
                id,
                instruction: what.to_owned(),
                code: status_error::CRC,
                meaning: status_error_meaning(status_error::CRC),
            },
        }
        .into())
    }

    /// Fills in the instruction name of a [`DynamixelError::Refused`].
    fn name_fatal(&self, e: DynamixelError, what: &str) -> DynamixelError {
        match e {
            DynamixelError::Refused {
                id, code, meaning, ..
            } => DynamixelError::Refused {
                id,
                instruction: what.to_owned(),
                code,
                meaning,
            },
            other => other,
        }
    }

    /// One instruction, one answer.
    fn attempt(
        &mut self,
        instruction: u8,
        params: &[u8],
        expected_len: usize,
    ) -> Result<Reply, Failure> {
        let id = self.config.id;
        self.bus
            .write_instruction(id, instruction, params.len(), |buf| {
                buf.copy_from_slice(params);
            })
            .map_err(|e| match e {
                WriteError::DiscardBuffer(io) | WriteError::Write(io) => {
                    Failure::Fatal(self_io(&self.path, id, io))
                }
                WriteError::BufferTooSmall(b) => Failure::Fatal(DynamixelError::Io {
                    path: self.path.clone(),
                    id,
                    source: std::io::Error::other(format!(
                        "instruction of {} bytes exceeds the {}-byte buffer",
                        b.required_size, b.total_size
                    )),
                }),
            })?;
        let deadline = Instant::now() + self.config.response_timeout;
        // `dynamixel2` 0.9 subtracts 2 from the length field of a status header without
        // checking it, which panics (debug builds) on a corrupted length below 2: a noisy
        // line must not crash the scanner, so such a panic counts as a malformed answer.
        let bus = &mut self.bus;
        let received = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            bus.read_status_response_deadline(deadline)
                .map(|p| (p.packet_id(), p.alert(), p.parameters().to_vec()))
        }))
        .map_err(|_| {
            Failure::Retry(Retry::Malformed(
                "status header with an impossible length".to_owned(),
            ))
        })?;
        match received {
            Ok((packet_id, alert, params)) => {
                if packet_id != id {
                    return Err(Failure::Retry(Retry::Malformed(format!(
                        "answer from id {packet_id}"
                    ))));
                }
                if params.len() != expected_len {
                    return Err(Failure::Retry(Retry::Malformed(format!(
                        "{} parameter bytes, expected {expected_len}",
                        params.len()
                    ))));
                }
                Ok(Reply { params, alert })
            }
            Err(ReadError::Io(e)) if e.kind() == std::io::ErrorKind::TimedOut => {
                Err(Failure::Retry(Retry::Silence))
            }
            Err(ReadError::Io(e)) => Err(Failure::Fatal(self_io(&self.path, id, e))),
            Err(ReadError::InvalidMessage(InvalidMessage::InvalidChecksum(c))) => {
                Err(Failure::Retry(Retry::Crc {
                    received: c.message,
                    computed: c.computed,
                }))
            }
            Err(ReadError::InvalidMessage(m)) => {
                Err(Failure::Retry(Retry::Malformed(m.to_string())))
            }
            Err(ReadError::BufferFull(b)) => Err(Failure::Retry(Retry::Malformed(format!(
                "answer of {} bytes exceeds the {}-byte buffer",
                b.required_size, b.total_size
            )))),
            Err(ReadError::MotorError(m)) if m.error_number() == status_error::CRC => {
                Err(Failure::Retry(Retry::ServoSawBadCrc))
            }
            Err(ReadError::MotorError(m)) => Err(Failure::Fatal(DynamixelError::Refused {
                id,
                instruction: String::new(),
                code: m.error_number(),
                meaning: status_error_meaning(m.error_number()),
            })),
        }
    }

    /// Whether the other end of the port has gone (a pseudo-terminal whose master closed, a
    /// USB adapter unplugged).
    fn hung_up(&self) -> bool {
        use rustix::event::{PollFd, PollFlags};
        let mut fds = [PollFd::new(self.bus.serial_port(), PollFlags::IN)];
        let zero = rustix::event::Timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        match rustix::event::poll(&mut fds, Some(&zero)) {
            Ok(_) => fds[0]
                .revents()
                .intersects(PollFlags::HUP | PollFlags::ERR | PollFlags::NVAL),
            Err(_) => true,
        }
    }
}

impl Turntable for DynamixelTurntable {
    /// Moves to the motor angle `angle_deg` and waits until the servo stands within
    /// [`DynamixelConfig::tolerance_deg`] of it; returns the angle the servo reports.
    ///
    /// # Errors
    /// [`RigError::InvalidParameter`] for a non-finite angle;
    /// [`DynamixelError::AngleOutOfRange`] beyond ±256 turns;
    /// [`DynamixelError::MoveTimeout`] when the servo does not arrive in the planned time
    /// plus [`DynamixelConfig::settle_timeout`]; [`DynamixelError::Hardware`] when it reports
    /// a hardware error on the way; [`DynamixelError::PortClosed`] when the port goes away;
    /// other communication errors.
    fn rotate_to(&mut self, angle_deg: f64) -> Result<f64, RigError> {
        if !angle_deg.is_finite() {
            return Err(RigError::param(
                "angle_deg",
                format!("must be finite, found {angle_deg}"),
            ));
        }
        let limit_deg = EXTENDED_POSITION_LIMIT_TICKS as f64 * DEG_PER_TICK;
        let goal_extended = (angle_deg / DEG_PER_TICK).round() + self.config.zero_ticks as f64;
        let goal = goal_extended - self.turn_offset as f64;
        if goal.abs() > EXTENDED_POSITION_LIMIT_TICKS as f64 {
            return Err(DynamixelError::AngleOutOfRange {
                angle_deg,
                limit_deg,
            }
            .into());
        }
        // In range, so it fits an i32.
        let goal = goal as i64;
        let start = self.read_i32(ct::PRESENT_POSITION, "Present Position", true)?;
        let goal_bytes = i32::try_from(goal).unwrap_or(0).to_le_bytes();
        self.write(ct::GOAL_POSITION, "Goal Position", &goal_bytes)?;
        let profile = Profile {
            distance: (goal - start).abs() as f64,
            velocity: ct::velocity_ticks_s(self.config.velocity_raw()),
            acceleration: ct::acceleration_ticks_s2(self.config.acceleration_raw()),
        };
        let budget = profile.duration() + self.config.settle_timeout;
        let tolerance_ticks = self.config.tolerance_deg / DEG_PER_TICK;
        let t0 = Instant::now();
        loop {
            std::thread::sleep(self.config.poll_interval);
            let moving = self.read_u8(ct::MOVING, "Moving", true)? != 0;
            let present = self.read_i32(ct::PRESENT_POSITION, "Present Position", true)?;
            if !moving && ((present - goal).abs() as f64) <= tolerance_ticks {
                return Ok(self.ticks_to_deg(present));
            }
            let waited = t0.elapsed();
            if waited > budget {
                return Err(DynamixelError::MoveTimeout {
                    id: self.config.id,
                    goal_deg: self.ticks_to_deg(goal),
                    present_deg: self.ticks_to_deg(present),
                    moving,
                    waited,
                }
                .into());
            }
        }
    }

    fn angle_deg(&mut self) -> Result<f64, RigError> {
        let present = self.read_i32(ct::PRESENT_POSITION, "Present Position", true)?;
        Ok(self.ticks_to_deg(present))
    }
}

/// Parameters of a read instruction.
fn read_params(address: u16, len: u16) -> [u8; 4] {
    let [a0, a1] = address.to_le_bytes();
    let [l0, l1] = len.to_le_bytes();
    [a0, a1, l0, l1]
}

/// The typed error for a failure to open the port.
fn open_error(path: &Path, baud: u32, e: std::io::Error) -> RigError {
    let path = path.to_path_buf();
    use std::io::ErrorKind as K;
    match e.kind() {
        K::NotFound => DynamixelError::PortAbsent { path },
        K::PermissionDenied => DynamixelError::PortPermission { path },
        K::ResourceBusy => DynamixelError::PortBusy { path },
        _ => DynamixelError::Port {
            path,
            baud,
            source: e,
        },
    }
    .into()
}

/// The typed error for a read or write failure: the port going away, or anything else.
fn self_io(path: &Path, id: u8, e: std::io::Error) -> DynamixelError {
    use rustix::io::Errno;
    let gone = e.kind() == std::io::ErrorKind::BrokenPipe
        || matches!(
            Errno::from_io_error(&e),
            Some(Errno::IO | Errno::NXIO | Errno::NODEV | Errno::BADF)
        );
    if gone {
        DynamixelError::PortClosed {
            path: path.to_path_buf(),
            id,
        }
    } else {
        DynamixelError::Io {
            path: path.to_path_buf(),
            id,
            source: e,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_profile_registers() {
        let c = DynamixelConfig::default();
        c.validate().unwrap();
        // 45°/s ÷ 1.374°/s = 32.75 → 33; 90°/s² ÷ 21.4577°/s² = 4.19 → 4.
        assert_eq!(c.velocity_raw(), 33);
        assert_eq!(c.acceleration_raw(), 4);
    }

    #[test]
    fn open_errors_are_typed() {
        let p = Path::new("/dev/ttyUSB9");
        let kinds = [
            (std::io::ErrorKind::NotFound, "not found"),
            (std::io::ErrorKind::PermissionDenied, "dialout"),
            (std::io::ErrorKind::ResourceBusy, "busy"),
        ];
        for (kind, needle) in kinds {
            let msg = open_error(p, 57_600, kind.into()).to_string();
            assert!(
                msg.contains("/dev/ttyUSB9") && msg.contains(needle),
                "{msg}"
            );
        }
    }

    #[test]
    fn rejects_bad_configs() {
        let breakers: [fn(&mut DynamixelConfig); 6] = [
            |c| c.id = 253,
            |c| c.baud = 0,
            |c| c.attempts = 0,
            |c| c.profile_velocity_deg_s = 0.0,
            |c| c.profile_acceleration_deg_s2 = f64::NAN,
            |c| c.tolerance_deg = -1.0,
        ];
        for breaker in breakers {
            let mut c = DynamixelConfig::default();
            breaker(&mut c);
            assert!(
                matches!(c.validate(), Err(RigError::InvalidParameter { .. })),
                "{c:?}"
            );
        }
    }
}
