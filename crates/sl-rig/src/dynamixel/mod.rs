//! The Dynamixel MX-64 turntable: a driver on the `dynamixel2` crate (Protocol 2.0) and an
//! emulated MX-64 that speaks the same wire protocol on the other end of a pseudo-terminal.
//!
//! - [`control_table`]: the MX-64 (2.0) control-table addresses and units both sides use, and
//!   the trapezoidal velocity profile the servo follows;
//! - [`wire`]: the Protocol 2.0 packet format (CRC-16, byte stuffing) written independently
//!   of `dynamixel2`, for the emulator and as a cross-check of the library;
//! - [`error`]: [`DynamixelError`] and [`HardwareErrorStatus`];
//! - [`driver`]: [`DynamixelTurntable`], configured by [`DynamixelConfig`];
//! - [`emulator`]: [`Mx64Emulator`], a protocol peer for tests and for running `slscan`
//!   without hardware.
//!
//! The user-facing story (wiring, permissions, troubleshooting) is in
//! `docs/hardware-turntable.md`.

pub(crate) mod control_table;
pub(crate) mod driver;
pub(crate) mod emulator;
pub(crate) mod error;
pub(crate) mod wire;

pub use control_table::{
    DEG_PER_TICK, EXTENDED_POSITION_LIMIT_TICKS, MX64_MODEL_NUMBER, TICKS_PER_TURN,
};
pub use driver::{DynamixelConfig, DynamixelTurntable, ServoStatus};
pub use emulator::{EmulatorConfig, EmulatorSnapshot, MidMoveFault, Mx64Emulator};
pub use error::{DynamixelError, HardwareErrorStatus};
pub use wire::dynamixel_crc16;
