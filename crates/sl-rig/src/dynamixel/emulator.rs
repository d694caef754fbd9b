//! An emulated Dynamixel MX-64 (2.0) on the other end of a pseudo-terminal: a real protocol
//! peer for tests, and a way to run the scanner's turntable code without the hardware.
//!
//! The emulator owns the master side of a pseudo-terminal pair; its slave side
//! (`/dev/pts/N`, [`Mx64Emulator::port_path`]) is a serial port like `/dev/ttyUSB0` to
//! whoever opens it. A thread reads instruction packets (Protocol 2.0, with CRC and byte
//! stuffing, written from the specification in `wire.rs`, independently of the driver's
//! `dynamixel2`), executes them against a control table, and answers with status packets.
//! Motion follows the servo's trapezoidal velocity profile in real time; temperature and
//! voltage drift with the load.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rustix::fs::{Mode, OFlags};
use rustix::pty::OpenptFlags;

use super::control_table::{
    self as ct, EXTENDED_POSITION_LIMIT_TICKS, EXTENDED_POSITION_MODE, MX64_MODEL_NUMBER, Profile,
    TABLE_SIZE, TICKS_PER_TURN,
};
use super::error::HardwareErrorStatus;
use super::wire::{self, Received, instruction, status_error};
use crate::RigError;

/// Broadcast id: every servo executes, only pings are answered.
const BROADCAST_ID: u8 = 0xFE;
/// Profile Velocity used when the register is 0 ("unlimited"): the MX-64's no-load speed,
/// 63 rev/min at 12 V, in units of 0.229 rev/min.
const NO_LOAD_VELOCITY_RAW: u32 = 275;
/// How long the emulator thread waits for input before updating the motion again: short
/// enough that Present Position is fresh to within a couple of milliseconds.
const POLL_STEP: Duration = Duration::from_millis(2);
/// Temperature rise per second of motion, °C: a loaded MX-64 warms by a few degrees over a
/// minute of turning.
const HEATING_C_PER_S: f64 = 0.05;
/// Time constant of cooling back to ambient, seconds.
const COOLING_TIME_CONSTANT_S: f64 = 120.0;
/// Input voltage drop while moving, volts (supply cable resistance under motor current).
const VOLTAGE_SAG_V: f64 = 0.2;
/// Operating Mode values the MX-64 (2.0) accepts.
const VALID_MODES: [u8; 6] = [0, 1, 3, 4, 5, 16];

/// The emulated servo's identity and physics. `Default` is a factory-fresh MX-64 (2.0) at
/// id 1 and 57 600 baud, standing at position 0.
#[derive(Clone, Debug, PartialEq)]
pub struct EmulatorConfig {
    /// Servo id.
    pub id: u8,
    /// Model number reported ([`MX64_MODEL_NUMBER`]).
    pub model_number: u16,
    /// Firmware version reported.
    pub firmware: u8,
    /// Baud rate of the servo: bytes sent while the port is set to another rate are
    /// garbage to it, as on a real bus.
    pub baud: u32,
    /// Present Position at start, ticks.
    pub initial_position_ticks: i32,
    /// Operating Mode at start (3 = position control, the factory setting).
    pub initial_operating_mode: u8,
    /// Where a move ends relative to its goal, ticks: a real position loop stops a tick or
    /// so short of or past the goal.
    pub settle_error_ticks: i32,
    /// Time after a reboot during which the servo does not answer.
    pub boot_time: Duration,
    /// Ambient (and initial) temperature, °C.
    pub ambient_temperature_c: f64,
    /// Supply voltage, volts.
    pub supply_voltage_v: f64,
}

/// Firmware version the emulator reports by default (a current MX (2.0) firmware).
const DEFAULT_FIRMWARE: u8 = 45;

impl Default for EmulatorConfig {
    fn default() -> Self {
        Self {
            id: 1,
            model_number: MX64_MODEL_NUMBER,
            firmware: DEFAULT_FIRMWARE,
            baud: 57_600,
            initial_position_ticks: 0,
            initial_operating_mode: 3,
            settle_error_ticks: 1,
            boot_time: Duration::from_millis(50),
            ambient_temperature_c: 28.0,
            supply_voltage_v: 12.0,
        }
    }
}

/// A fault that strikes when the next move is half done.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MidMoveFault {
    /// The servo raises these Hardware Error Status bits and switches its torque off.
    HardwareError(HardwareErrorStatus),
    /// The emulator closes its end of the port (an unplugged adapter).
    ClosePort,
    /// The platter blocks: the servo stops where it is but keeps reporting `Moving`.
    Stall,
}

/// The emulated servo's state, for tests to compare with what the driver reports.
#[derive(Clone, Debug, PartialEq)]
pub struct EmulatorSnapshot {
    /// Present Position, ticks.
    pub present_ticks: i32,
    /// Goal Position, ticks.
    pub goal_ticks: i32,
    /// Moving.
    pub moving: bool,
    /// Torque Enable.
    pub torque_enabled: bool,
    /// Operating Mode.
    pub operating_mode: u8,
    /// Hardware Error Status.
    pub hardware_error: HardwareErrorStatus,
    /// Profile Velocity register.
    pub profile_velocity: u32,
    /// Profile Acceleration register.
    pub profile_acceleration: u32,
    /// Present temperature, °C.
    pub temperature_c: f64,
    /// Present input voltage, volts.
    pub input_voltage_v: f64,
    /// Instruction packets addressed to the servo and executed.
    pub instructions: u64,
    /// Reboots.
    pub reboots: u32,
    /// Writes to the EEPROM area (addresses below 64).
    pub eeprom_writes: u32,
    /// Ticks travelled in the positive direction since start.
    pub forward_ticks: f64,
    /// Ticks travelled in the negative direction since start (0 for a sequence that never
    /// unwinds).
    pub backward_ticks: f64,
    /// Whether the emulator's end of the port is still open.
    pub port_open: bool,
}

/// An emulated MX-64 (2.0) answering Protocol 2.0 on a pseudo-terminal (see the module
/// docs). Dropping it stops the thread and closes the port.
///
/// Fault injection: [`drop_answers`](Self::drop_answers),
/// [`set_silent`](Self::set_silent), [`corrupt_crc`](Self::corrupt_crc),
/// [`set_answer_delay`](Self::set_answer_delay), [`send_bad_length`](Self::send_bad_length),
/// [`raise_hardware_error`](Self::raise_hardware_error),
/// [`arm_mid_move_fault`](Self::arm_mid_move_fault), [`close_port`](Self::close_port).
///
/// The control table holds the entries the driver uses: Model Number, Firmware Version,
/// ID, Baud Rate, Operating Mode, Torque Enable, Hardware Error Status, Profile
/// Acceleration and Velocity, Goal Position, Moving, Present Position, Present Input
/// Voltage and Present Temperature; writes elsewhere are refused with an access error.
///
/// ```
/// use sl_rig::{EmulatorConfig, Mx64Emulator};
/// # fn main() -> Result<(), sl_rig::RigError> {
/// let servo = Mx64Emulator::spawn(EmulatorConfig::default())?;
/// // Open `servo.port_path()` like /dev/ttyUSB0, e.g. with `DynamixelTurntable::open`.
/// assert!(servo.port_path().starts_with("/dev/pts"));
/// assert_eq!(servo.snapshot().present_ticks, 0);
/// # Ok(())
/// # }
/// ```
#[derive(Debug)]
pub struct Mx64Emulator {
    path: PathBuf,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

#[derive(Debug)]
struct Shared {
    servo: Mutex<Servo>,
    stop: AtomicBool,
}

/// A move in progress.
#[derive(Clone, Copy, Debug)]
struct Motion {
    from: f64,
    to: f64,
    profile: Profile,
    start: Instant,
    stalled: bool,
}

#[derive(Debug)]
struct Servo {
    config: EmulatorConfig,
    table: [u8; TABLE_SIZE],
    /// Extended position, ticks (fractional during a move).
    position: f64,
    motion: Option<Motion>,
    temperature_c: f64,
    booting_until: Option<Instant>,
    last_tick: Instant,
    // Faults.
    drop_next: u32,
    silent: bool,
    corrupt_next: u32,
    bad_length_next: u32,
    answer_delay: Duration,
    mid_move_fault: Option<MidMoveFault>,
    close_requested: bool,
    port_open: bool,
    // Statistics.
    instructions: u64,
    reboots: u32,
    eeprom_writes: u32,
    forward_ticks: f64,
    backward_ticks: f64,
}

fn lock(m: &Mutex<Servo>) -> MutexGuard<'_, Servo> {
    // A panic elsewhere while holding the lock leaves a servo state that is still valid.
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl Mx64Emulator {
    /// Opens a pseudo-terminal pair and starts the servo's thread.
    ///
    /// # Errors
    /// [`RigError::Io`] (naming `/dev/ptmx` or the slave's path) when the pseudo-terminal
    /// cannot be opened or configured; [`RigError::InvalidParameter`] for an id above 252
    /// or a zero baud rate.
    pub fn spawn(config: EmulatorConfig) -> Result<Self, RigError> {
        if config.id > 252 {
            return Err(RigError::param(
                "id",
                format!("must be 0..=252, found {}", config.id),
            ));
        }
        if config.baud == 0 {
            return Err(RigError::param("baud", "must be positive"));
        }
        let ptmx = Path::new("/dev/ptmx");
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |e: rustix::io::Errno| RigError::io(path, e.into())
        };
        let master =
            rustix::pty::openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY).map_err(io(ptmx))?;
        rustix::pty::grantpt(&master).map_err(io(ptmx))?;
        rustix::pty::unlockpt(&master).map_err(io(ptmx))?;
        let name = rustix::pty::ptsname(&master, Vec::new()).map_err(io(ptmx))?;
        let path = PathBuf::from(name.to_string_lossy().into_owned());
        // The emulator keeps the slave open too: the master then never sees a hang-up
        // between two users of the port, and the emulator can read the line settings.
        let slave = rustix::fs::open(
            &path,
            OFlags::RDWR | OFlags::NOCTTY | OFlags::CLOEXEC,
            Mode::empty(),
        )
        .map_err(io(&path))?;
        let mut termios = rustix::termios::tcgetattr(&slave).map_err(io(&path))?;
        termios.make_raw();
        termios.set_speed(config.baud).map_err(io(&path))?;
        rustix::termios::tcsetattr(&slave, rustix::termios::OptionalActions::Now, &termios)
            .map_err(io(&path))?;

        let shared = Arc::new(Shared {
            servo: Mutex::new(Servo::new(config)),
            stop: AtomicBool::new(false),
        });
        let thread_shared = Arc::clone(&shared);
        let master = std::fs::File::from(master);
        let thread = std::thread::Builder::new()
            .name("mx64-emulator".to_owned())
            .spawn(move || serve(&thread_shared, master, slave))
            .map_err(|e| RigError::io(&path, e))?;
        Ok(Self {
            path,
            shared,
            thread: Some(thread),
        })
    }

    /// The serial port to open (`/dev/pts/N`).
    pub fn port_path(&self) -> &Path {
        &self.path
    }

    /// The servo's state now.
    pub fn snapshot(&self) -> EmulatorSnapshot {
        let mut s = lock(&self.shared.servo);
        s.update(Instant::now());
        s.snapshot()
    }

    /// Ignores the next `n` instruction packets addressed to the servo (lost on the line:
    /// not executed, not answered).
    pub fn drop_answers(&self, n: u32) {
        lock(&self.shared.servo).drop_next = n;
    }

    /// Ignores every packet while `silent` (a servo without power, or a wrong id).
    pub fn set_silent(&self, silent: bool) {
        lock(&self.shared.servo).silent = silent;
    }

    /// Sends the next `n` status packets with a wrong CRC (the instruction is executed).
    pub fn corrupt_crc(&self, n: u32) {
        lock(&self.shared.servo).corrupt_next = n;
    }

    /// Sends the next `n` status packets with a length field of 1, shorter than any packet
    /// can be (a corrupted header; the instruction is executed).
    pub fn send_bad_length(&self, n: u32) {
        lock(&self.shared.servo).bad_length_next = n;
    }

    /// Delays every answer by `delay` (a slow adapter or a long Return Delay Time).
    pub fn set_answer_delay(&self, delay: Duration) {
        lock(&self.shared.servo).answer_delay = delay;
    }

    /// Raises Hardware Error Status bits now: the servo switches its torque off, stops, and
    /// sets the alert bit of every answer until rebooted.
    pub fn raise_hardware_error(&self, status: HardwareErrorStatus) {
        let mut s = lock(&self.shared.servo);
        s.update(Instant::now());
        s.raise(status);
    }

    /// Arms `fault` to strike when the next move is half done.
    pub fn arm_mid_move_fault(&self, fault: MidMoveFault) {
        lock(&self.shared.servo).mid_move_fault = Some(fault);
    }

    /// Closes the emulator's end of the port now (the servo's adapter unplugged).
    pub fn close_port(&self) {
        lock(&self.shared.servo).close_requested = true;
    }
}

impl Drop for Mx64Emulator {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            // The thread only returns; a panic in it has already been reported.
            let _ = t.join();
        }
    }
}

/// The emulator thread: read, execute, answer, until stopped or told to close the port.
fn serve(shared: &Shared, mut master: std::fs::File, slave: rustix::fd::OwnedFd) {
    use rustix::event::{PollFd, PollFlags, Timespec};
    let step = Timespec {
        tv_sec: 0,
        tv_nsec: i64::from(POLL_STEP.subsec_nanos()),
    };
    let mut buf = Vec::new();
    let mut chunk = [0u8; 256];
    while !shared.stop.load(Ordering::Relaxed) {
        {
            let mut s = lock(&shared.servo);
            s.update(Instant::now());
            if s.close_requested {
                s.port_open = false;
                break;
            }
        }
        let mut fds = [PollFd::new(&master, PollFlags::IN)];
        let readable = matches!(rustix::event::poll(&mut fds, Some(&step)), Ok(n) if n > 0)
            && fds[0].revents().contains(PollFlags::IN);
        if !readable {
            continue;
        }
        match master.read(&mut chunk) {
            Ok(n) => buf.extend_from_slice(chunk.get(..n).unwrap_or_default()),
            Err(_) => {
                std::thread::sleep(POLL_STEP);
                continue;
            }
        }
        // Bytes sent at another baud rate are noise to the servo.
        let baud = lock(&shared.servo).config.baud;
        let line_speed = rustix::termios::tcgetattr(&slave).map(|t| t.output_speed());
        if line_speed.is_ok_and(|speed| speed != baud) {
            buf.clear();
            continue;
        }
        while let Some(packet) = wire::take_packet(&mut buf) {
            let answer = lock(&shared.servo).execute(packet, Instant::now());
            if let Some((bytes, delay)) = answer {
                if !delay.is_zero() {
                    std::thread::sleep(delay);
                }
                if master.write_all(&bytes).is_err() {
                    std::thread::sleep(POLL_STEP);
                }
            }
        }
    }
    lock(&shared.servo).port_open = false;
    drop(master);
    drop(slave);
}

impl Servo {
    fn new(config: EmulatorConfig) -> Self {
        let mut s = Self {
            table: [0; TABLE_SIZE],
            position: f64::from(config.initial_position_ticks),
            motion: None,
            temperature_c: config.ambient_temperature_c,
            booting_until: None,
            last_tick: Instant::now(),
            drop_next: 0,
            silent: false,
            corrupt_next: 0,
            bad_length_next: 0,
            answer_delay: Duration::ZERO,
            mid_move_fault: None,
            close_requested: false,
            port_open: true,
            instructions: 0,
            reboots: 0,
            eeprom_writes: 0,
            forward_ticks: 0.0,
            backward_ticks: 0.0,
            config,
        };
        s.set(ct::MODEL_NUMBER, &s.config.model_number.to_le_bytes());
        s.set(ct::FIRMWARE_VERSION, &[s.config.firmware]);
        s.set(ct::ID, &[s.config.id]);
        s.set(ct::BAUD_RATE, &[baud_code(s.config.baud)]);
        s.set(ct::OPERATING_MODE, &[s.config.initial_operating_mode]);
        s.reset_ram();
        s
    }

    /// RAM area at power-up or reboot: torque off, no error, no profile, goal = present.
    fn reset_ram(&mut self) {
        for b in self.table.iter_mut().skip(usize::from(ct::RAM_START)) {
            *b = 0;
        }
        self.motion = None;
        let present = self.present_ticks();
        self.set(ct::GOAL_POSITION, &present.to_le_bytes());
        self.refresh();
    }

    fn set(&mut self, address: u16, bytes: &[u8]) {
        let start = usize::from(address);
        if let Some(dst) = self.table.get_mut(start..start + bytes.len()) {
            dst.copy_from_slice(bytes);
        }
    }

    fn get_u8(&self, address: u16) -> u8 {
        self.table.get(usize::from(address)).copied().unwrap_or(0)
    }

    fn get_u32(&self, address: u16) -> u32 {
        let a = usize::from(address);
        match self.table.get(a..a + 4) {
            Some([b0, b1, b2, b3]) => u32::from_le_bytes([*b0, *b1, *b2, *b3]),
            _ => 0,
        }
    }

    fn present_ticks(&self) -> i32 {
        // Positions stay within ±256 turns (goals are range-checked).
        self.position.round() as i32
    }

    fn hardware_error(&self) -> HardwareErrorStatus {
        HardwareErrorStatus(self.get_u8(ct::HARDWARE_ERROR_STATUS))
    }

    /// Advances the motion, the temperature and the present values to `now`.
    fn update(&mut self, now: Instant) {
        let dt = now.saturating_duration_since(self.last_tick).as_secs_f64();
        self.last_tick = now;
        let before = self.position;
        if let Some(mut m) = self.motion {
            let t = now.saturating_duration_since(m.start).as_secs_f64();
            let total = m.profile.duration().as_secs_f64();
            if !m.stalled {
                let sign = if m.to >= m.from { 1.0 } else { -1.0 };
                self.position = m.from + sign * m.profile.travelled(t);
            }
            if m.profile.distance > 0.0
                && t >= 0.5 * total
                && let Some(fault) = self.mid_move_fault.take()
            {
                match fault {
                    MidMoveFault::HardwareError(bits) => self.raise(bits),
                    MidMoveFault::ClosePort => self.close_requested = true,
                    MidMoveFault::Stall => {
                        m.stalled = true;
                        self.motion = Some(m);
                    }
                }
            }
            if let Some(m) = self.motion
                && !m.stalled
                && t >= total
            {
                self.position = m.to + f64::from(self.config.settle_error_ticks);
                self.motion = None;
            }
        }
        let delta = self.position - before;
        if delta > 0.0 {
            self.forward_ticks += delta;
        } else {
            self.backward_ticks -= delta;
        }
        let moving = self.motion.is_some();
        let ambient = self.config.ambient_temperature_c;
        if moving {
            self.temperature_c += HEATING_C_PER_S * dt;
        }
        self.temperature_c -=
            (self.temperature_c - ambient) * (dt / COOLING_TIME_CONSTANT_S).min(1.0);
        self.refresh();
    }

    /// Writes the present values into the table.
    fn refresh(&mut self) {
        let moving = self.motion.is_some();
        let present = self.present_ticks();
        self.set(ct::PRESENT_POSITION, &present.to_le_bytes());
        self.set(ct::MOVING, &[u8::from(moving)]);
        let volts = self.config.supply_voltage_v - if moving { VOLTAGE_SAG_V } else { 0.0 };
        let decivolts = (volts * 10.0).round().clamp(0.0, f64::from(u16::MAX)) as u16;
        self.set(ct::PRESENT_INPUT_VOLTAGE, &decivolts.to_le_bytes());
        let celsius = self.temperature_c.round().clamp(0.0, 255.0) as u8;
        self.set(ct::PRESENT_TEMPERATURE, &[celsius]);
    }

    fn raise(&mut self, status: HardwareErrorStatus) {
        let bits = self.hardware_error().0 | status.0;
        self.set(ct::HARDWARE_ERROR_STATUS, &[bits]);
        self.set(ct::TORQUE_ENABLE, &[0]);
        self.motion = None;
        self.refresh();
    }

    fn snapshot(&self) -> EmulatorSnapshot {
        EmulatorSnapshot {
            present_ticks: self.present_ticks(),
            goal_ticks: self.get_u32(ct::GOAL_POSITION) as i32,
            moving: self.motion.is_some(),
            torque_enabled: self.get_u8(ct::TORQUE_ENABLE) != 0,
            operating_mode: self.get_u8(ct::OPERATING_MODE),
            hardware_error: self.hardware_error(),
            profile_velocity: self.get_u32(ct::PROFILE_VELOCITY),
            profile_acceleration: self.get_u32(ct::PROFILE_ACCELERATION),
            temperature_c: self.temperature_c,
            input_voltage_v: f64::from(u16::from_le_bytes([
                self.get_u8(ct::PRESENT_INPUT_VOLTAGE),
                self.get_u8(ct::PRESENT_INPUT_VOLTAGE + 1),
            ])) * 0.1,
            instructions: self.instructions,
            reboots: self.reboots,
            eeprom_writes: self.eeprom_writes,
            forward_ticks: self.forward_ticks,
            backward_ticks: self.backward_ticks,
            port_open: self.port_open,
        }
    }

    /// Executes one received packet; returns the answer and how long to wait before sending
    /// it, or `None` when the servo stays silent.
    fn execute(&mut self, received: Received, now: Instant) -> Option<(Vec<u8>, Duration)> {
        self.update(now);
        if self.booting_until.is_some_and(|t| now < t) || self.silent {
            return None;
        }
        let my_id = self.config.id;
        let (id, answer) = match received {
            Received::BadCrc { id } => (id, (status_error::CRC, Vec::new())),
            Received::Packet {
                id,
                instruction,
                params,
            } => {
                if id != my_id && id != BROADCAST_ID {
                    return None;
                }
                if self.drop_next > 0 {
                    self.drop_next -= 1;
                    return None;
                }
                self.instructions += 1;
                let answer = self.instruction(instruction, &params, now);
                if id == BROADCAST_ID && instruction != instruction::PING {
                    return None;
                }
                (id, answer)
            }
        };
        if id != my_id && id != BROADCAST_ID {
            return None;
        }
        let (error, params) = answer;
        let alert = if self.hardware_error().is_empty() {
            0
        } else {
            status_error::ALERT
        };
        let mut packet = wire::status_packet(my_id, error | alert, &params);
        if self.corrupt_next > 0 {
            self.corrupt_next -= 1;
            if let Some(last) = packet.last_mut() {
                *last ^= 0x5A;
            }
        }
        if self.bad_length_next > 0 {
            self.bad_length_next -= 1;
            if let Some(len) = packet.get_mut(5..7) {
                len.copy_from_slice(&[1, 0]);
            }
        }
        Some((packet, self.answer_delay))
    }

    /// Executes an instruction: the status error number and parameters to answer.
    fn instruction(&mut self, instruction: u8, params: &[u8], now: Instant) -> (u8, Vec<u8>) {
        match instruction {
            instruction::PING => {
                let [lo, hi] = self.config.model_number.to_le_bytes();
                (0, vec![lo, hi, self.config.firmware])
            }
            instruction::READ => {
                let [a0, a1, l0, l1] = params else {
                    return (status_error::DATA_LENGTH, Vec::new());
                };
                let start = usize::from(u16::from_le_bytes([*a0, *a1]));
                let len = usize::from(u16::from_le_bytes([*l0, *l1]));
                match self.table.get(start..start + len) {
                    Some(bytes) => (0, bytes.to_vec()),
                    None => (status_error::ACCESS, Vec::new()),
                }
            }
            instruction::WRITE => match params {
                [a0, a1, data @ ..] if !data.is_empty() => (
                    self.write(u16::from_le_bytes([*a0, *a1]), data, now),
                    Vec::new(),
                ),
                _ => (status_error::DATA_LENGTH, Vec::new()),
            },
            instruction::REBOOT => {
                // Answer first, then boot: the turn count is lost (position within one turn).
                self.reboots += 1;
                self.position = self.position.rem_euclid(TICKS_PER_TURN as f64).round();
                self.set(ct::HARDWARE_ERROR_STATUS, &[0]);
                self.reset_ram();
                self.booting_until = Some(now + self.config.boot_time);
                (0, Vec::new())
            }
            _ => (status_error::INSTRUCTION, Vec::new()),
        }
    }

    /// Executes a write; returns the status error number.
    fn write(&mut self, address: u16, data: &[u8], now: Instant) -> u8 {
        let torque_on = self.get_u8(ct::TORQUE_ENABLE) != 0;
        let as_u32 = |d: &[u8]| match d {
            [b0, b1, b2, b3] => Some(u32::from_le_bytes([*b0, *b1, *b2, *b3])),
            _ => None,
        };
        match (address, data) {
            (ct::OPERATING_MODE, [mode]) => {
                if torque_on {
                    return status_error::ACCESS;
                }
                if !VALID_MODES.contains(mode) {
                    return status_error::DATA_RANGE;
                }
                self.eeprom_writes += 1;
                self.set(address, &[*mode]);
                0
            }
            (ct::TORQUE_ENABLE, [on]) => {
                if *on > 1 {
                    return status_error::DATA_RANGE;
                }
                // With a hardware error the torque stays off; the alert bit says why.
                let on = *on == 1 && self.hardware_error().is_empty();
                if on && !torque_on {
                    // Holding starts where the servo stands.
                    let present = self.present_ticks();
                    self.set(ct::GOAL_POSITION, &present.to_le_bytes());
                }
                if !on {
                    self.motion = None;
                }
                self.set(address, &[u8::from(on)]);
                self.refresh();
                0
            }
            (ct::PROFILE_ACCELERATION | ct::PROFILE_VELOCITY, d) => match as_u32(d) {
                Some(v) if v <= 32_767 => {
                    self.set(address, d);
                    0
                }
                Some(_) => status_error::DATA_LIMIT,
                None => status_error::DATA_LENGTH,
            },
            (ct::GOAL_POSITION, d) => {
                let Some(raw) = as_u32(d) else {
                    return status_error::DATA_LENGTH;
                };
                let goal = i64::from(raw as i32);
                let extended = self.get_u8(ct::OPERATING_MODE) == EXTENDED_POSITION_MODE;
                let in_range = if extended {
                    goal.abs() <= EXTENDED_POSITION_LIMIT_TICKS
                } else {
                    (0..TICKS_PER_TURN).contains(&goal)
                };
                if !in_range {
                    return status_error::DATA_LIMIT;
                }
                self.set(address, d);
                if torque_on {
                    self.start_move(goal as f64, now);
                }
                0
            }
            // Read-only registers, and the entries this emulator does not model.
            _ => status_error::ACCESS,
        }
    }

    fn start_move(&mut self, goal: f64, now: Instant) {
        let raw_v = match self.get_u32(ct::PROFILE_VELOCITY) {
            0 => NO_LOAD_VELOCITY_RAW,
            v => v,
        };
        let profile = Profile {
            distance: (goal - self.position).abs(),
            velocity: ct::velocity_ticks_s(raw_v),
            acceleration: ct::acceleration_ticks_s2(self.get_u32(ct::PROFILE_ACCELERATION)),
        };
        self.motion = Some(Motion {
            from: self.position,
            to: goal,
            profile,
            start: now,
            stalled: false,
        });
        self.refresh();
    }
}

/// The Baud Rate register code for a baud rate (the MX (2.0) table; 1 = 57 600 otherwise).
fn baud_code(baud: u32) -> u8 {
    match baud {
        9_600 => 0,
        115_200 => 2,
        1_000_000 => 3,
        2_000_000 => 4,
        3_000_000 => 5,
        4_000_000 => 6,
        4_500_000 => 7,
        _ => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reboot_keeps_the_position_within_one_turn() {
        let mut s = Servo::new(EmulatorConfig {
            initial_position_ticks: 3 * 4096 + 100,
            ..Default::default()
        });
        s.raise(HardwareErrorStatus::OVERLOAD);
        let now = Instant::now();
        assert_eq!(s.instruction(instruction::REBOOT, &[], now).0, 0);
        assert_eq!(s.present_ticks(), 100);
        assert!(s.hardware_error().is_empty());
        // Booting: silent.
        let ping = Received::Packet {
            id: 1,
            instruction: instruction::PING,
            params: vec![],
        };
        assert_eq!(s.execute(ping.clone(), now), None);
        assert!(s.execute(ping, now + Duration::from_secs(1)).is_some());
    }

    #[test]
    fn eeprom_needs_torque_off() {
        let mut s = Servo::new(EmulatorConfig::default());
        let now = Instant::now();
        assert_eq!(s.write(ct::TORQUE_ENABLE, &[1], now), 0);
        assert_eq!(s.write(ct::OPERATING_MODE, &[4], now), status_error::ACCESS);
        assert_eq!(s.write(ct::TORQUE_ENABLE, &[0], now), 0);
        assert_eq!(
            s.write(ct::OPERATING_MODE, &[2], now),
            status_error::DATA_RANGE
        );
        assert_eq!(s.write(ct::OPERATING_MODE, &[4], now), 0);
        // Read-only registers.
        assert_eq!(
            s.write(ct::PRESENT_POSITION, &[0; 4], now),
            status_error::ACCESS
        );
    }
}
