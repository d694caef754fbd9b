//! The Dynamixel turntable driver against the emulated MX-64 on a pseudo-terminal: the real
//! wire protocol both ways, with injected faults.
//!
//! Expected angles are closed forms: a goal of `a` degrees is `round(a · 4096 / 360)` ticks,
//! and the emulator stops `settle_error_ticks` past the goal, so the driver must report
//! `(round(a · 4096 / 360) + settle) · 360 / 4096` — the servo's reading, not the command.
#![cfg(unix)]
// Helpers outside `#[test]` functions unwrap too: a failure there is a failed test.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use approx::assert_abs_diff_eq;
use nalgebra::{Point3, Vector3};
use sl_camera::TurntableAxis;
use sl_rig::{
    DEG_PER_TICK, DynamixelConfig, DynamixelError, DynamixelTurntable, EmulatorConfig,
    HardwareErrorStatus, MidMoveFault, Mx64Emulator, RigError, Turntable,
};

/// Fast moves (720°/s, 7200°/s²) and polls so that the suite takes seconds; a response
/// timeout of 200 ms so that a machine loaded by parallel builds does not turn a late
/// emulator thread into lost answers.
fn fast() -> DynamixelConfig {
    DynamixelConfig {
        profile_velocity_deg_s: 720.0,
        profile_acceleration_deg_s2: 7200.0,
        poll_interval: Duration::from_millis(5),
        response_timeout: Duration::from_millis(200),
        ..DynamixelConfig::default()
    }
}

/// The angle the servo reports after a move to `deg` (see the file docs).
fn reported(deg: f64, settle_ticks: i32) -> f64 {
    ((deg / DEG_PER_TICK).round() + f64::from(settle_ticks)) * DEG_PER_TICK
}

fn emulator() -> Mx64Emulator {
    Mx64Emulator::spawn(EmulatorConfig::default()).unwrap()
}

fn dxl(e: RigError) -> DynamixelError {
    match e {
        RigError::Dynamixel(d) => d,
        other => panic!("expected a Dynamixel error, got {other:?}"),
    }
}

#[test]
fn full_turn_in_36_steps_never_unwinds() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    assert_eq!(table.model(), 311);
    let snap = servo.snapshot();
    assert_eq!(snap.operating_mode, 4, "extended position mode");
    assert!(snap.torque_enabled);
    // 720°/s = 524.0 units of 0.229 rev/min; 7200°/s² = 335.5 → 336 units of 214.577 rev/min².
    assert_eq!(snap.profile_velocity, 524);
    assert_eq!(snap.profile_acceleration, 336);
    for k in 1..=36 {
        let goal = 10.0 * f64::from(k);
        let reached = table.rotate_to(goal).unwrap();
        // Exact: the reading is an integer number of ticks.
        assert_abs_diff_eq!(reached, reported(goal, 1), epsilon = 1e-9);
        assert_abs_diff_eq!(table.angle_deg().unwrap(), reached, epsilon = 1e-9);
    }
    let snap = servo.snapshot();
    // 360° is 4096 ticks, plus the settle error: the servo went on past one turn.
    assert_eq!(snap.present_ticks, 4097);
    assert_eq!(snap.backward_ticks, 0.0, "the sequence must never unwind");
    // Each move starts one tick past the last goal: 4096 ticks plus the last settle error.
    assert_abs_diff_eq!(snap.forward_ticks, 4097.0, epsilon = 1e-6);
    // Operating Mode written once (EEPROM), not at every move.
    assert_eq!(snap.eeprom_writes, 1);
}

#[test]
fn moves_take_the_profile_time() {
    // 90° at 180°/s with 21.4577·17 = 364.8°/s²: ramps of 0.4934 s covering 88.8°, hence a
    // triangle: 2·sqrt(90 / 364.78) = 0.993 s. The driver must wait for it.
    let servo = emulator();
    let config = DynamixelConfig {
        profile_velocity_deg_s: 180.0,
        profile_acceleration_deg_s2: 17.0 * 21.4577,
        poll_interval: Duration::from_millis(5),
        ..DynamixelConfig::default()
    };
    let mut table = DynamixelTurntable::open(servo.port_path(), config).unwrap();
    let t0 = std::time::Instant::now();
    table.rotate_to(90.0).unwrap();
    let took = t0.elapsed().as_secs_f64();
    // The profile planner rounds 180°/s to 131 units (179.99°/s) — still a triangle. The
    // lower bound is the point (the driver waits for the servo); the upper one only catches
    // a driver that waits for its timeout, with room for a loaded machine.
    let expected = 2.0 * (90.0 / (17.0 * 21.4577f64)).sqrt();
    assert!(
        took >= expected && took < expected + 1.5,
        "took {took} s, expected {expected}"
    );
}

#[test]
fn platter_angles_through_the_calibrated_axis() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    let mut axis = TurntableAxis::new(Vector3::y(), Point3::new(0.0, 0.0, 500.0)).unwrap();
    axis.angle_scale = 0.5; // a 2:1 belt
    axis.angle_offset_deg = 10.0;
    // Platter 100° = motor (100 − 10) / 0.5 = 180°.
    let reached = table.rotate_table_to(100.0, &axis).unwrap();
    assert_abs_diff_eq!(reached, 10.0 + 0.5 * reported(180.0, 1), epsilon = 1e-9);
    assert_eq!(servo.snapshot().present_ticks, 2048 + 1);
}

#[test]
fn absent_port() {
    let err = dxl(DynamixelTurntable::open("/dev/ttyNO_SUCH_ADAPTER", fast()).unwrap_err());
    assert!(
        matches!(&err, DynamixelError::PortAbsent { path } if path.ends_with("ttyNO_SUCH_ADAPTER"))
    );
    assert!(err.to_string().contains("/dev/ttyNO_SUCH_ADAPTER"));
}

#[test]
fn busy_port() {
    let servo = emulator();
    let _first = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    let err = dxl(DynamixelTurntable::open(servo.port_path(), fast()).unwrap_err());
    assert!(matches!(err, DynamixelError::PortBusy { .. }), "{err}");
}

#[test]
fn unknown_id_does_not_answer() {
    let servo = emulator();
    let config = DynamixelConfig { id: 7, ..fast() };
    let err = dxl(DynamixelTurntable::open(servo.port_path(), config).unwrap_err());
    assert!(
        matches!(
            err,
            DynamixelError::NoAnswer {
                id: 7,
                baud: 57_600,
                attempts: 3,
                ..
            }
        ),
        "{err}"
    );
    let msg = err.to_string();
    assert!(msg.contains("id 7") && msg.contains("57600 baud"), "{msg}");
}

#[test]
fn wrong_baud_rate_is_silence() {
    let servo = emulator();
    let config = DynamixelConfig {
        baud: 115_200,
        ..fast()
    };
    let err = dxl(DynamixelTurntable::open(servo.port_path(), config).unwrap_err());
    assert!(
        matches!(err, DynamixelError::NoAnswer { baud: 115_200, .. }),
        "{err}"
    );
    assert_eq!(servo.snapshot().instructions, 0);
}

#[test]
fn wrong_model() {
    let servo = Mx64Emulator::spawn(EmulatorConfig {
        model_number: 1020, // XM430-W350
        ..EmulatorConfig::default()
    })
    .unwrap();
    let err = dxl(DynamixelTurntable::open(servo.port_path(), fast()).unwrap_err());
    assert!(
        matches!(
            err,
            DynamixelError::WrongModel {
                model: 1020,
                expected: 311,
                ..
            }
        ),
        "{err}"
    );
    // Accepted when asked for any model.
    let config = DynamixelConfig {
        expected_model: None,
        ..fast()
    };
    assert!(DynamixelTurntable::open(servo.port_path(), config).is_ok());
}

#[test]
fn silence_is_retried_then_reported() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    // Two lost instructions: the third attempt gets through.
    servo.drop_answers(2);
    assert_abs_diff_eq!(
        table.rotate_to(20.0).unwrap(),
        reported(20.0, 1),
        epsilon = 1e-9
    );
    // A servo that lost power.
    servo.set_silent(true);
    let err = dxl(table.rotate_to(30.0).unwrap_err());
    assert!(
        matches!(
            err,
            DynamixelError::NoAnswer {
                id: 1,
                attempts: 3,
                ..
            }
        ),
        "{err}"
    );
    servo.set_silent(false);
    assert_abs_diff_eq!(
        table.rotate_to(30.0).unwrap(),
        reported(30.0, 1),
        epsilon = 1e-9
    );
}

#[test]
fn bad_crc_is_retried_then_reported() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    servo.corrupt_crc(2);
    assert_abs_diff_eq!(table.angle_deg().unwrap(), 0.0);
    servo.corrupt_crc(3);
    let err = dxl(table.angle_deg().unwrap_err());
    match err {
        DynamixelError::BadCrc {
            id: 1,
            attempts: 3,
            received,
            computed,
            ..
        } => assert_ne!(received, computed),
        other => panic!("expected BadCrc, got {other}"),
    }
    // The link recovers.
    assert_abs_diff_eq!(table.angle_deg().unwrap(), 0.0);
}

#[test]
fn malformed_headers_do_not_crash() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    servo.send_bad_length(1);
    assert_abs_diff_eq!(table.angle_deg().unwrap(), 0.0);
    servo.send_bad_length(3);
    let err = dxl(table.angle_deg().unwrap_err());
    // Debug builds: dynamixel2's length underflow panics, caught as a malformed answer.
    // Release builds: the length wraps and the packet fails its CRC check instead.
    assert!(
        matches!(
            err,
            DynamixelError::BadAnswer { .. } | DynamixelError::BadCrc { .. }
        ),
        "{err}"
    );
}

#[test]
fn slow_answers() {
    let servo = emulator();
    let config = DynamixelConfig {
        response_timeout: Duration::from_millis(100),
        ..fast()
    };
    let mut table = DynamixelTurntable::open(servo.port_path(), config).unwrap();
    // Within the 100 ms response timeout: fine.
    servo.set_answer_delay(Duration::from_millis(15));
    assert_abs_diff_eq!(
        table.rotate_to(10.0).unwrap(),
        reported(10.0, 1),
        epsilon = 1e-9
    );
    // Beyond all three attempts (300 ms): silence.
    servo.set_answer_delay(Duration::from_millis(500));
    let err = dxl(table.angle_deg().unwrap_err());
    assert!(matches!(err, DynamixelError::NoAnswer { .. }), "{err}");
}

#[test]
fn hardware_error_mid_move_then_reboot_clears_it() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    // More than a turn first, so that the reboot's loss of the turn count would show.
    table.rotate_to(400.0).unwrap();
    servo.arm_mid_move_fault(MidMoveFault::HardwareError(HardwareErrorStatus::OVERLOAD));
    let err = dxl(table.rotate_to(500.0).unwrap_err());
    assert!(
        matches!(err, DynamixelError::Hardware { id: 1, status } if status == HardwareErrorStatus::OVERLOAD),
        "{err}"
    );
    assert!(err.to_string().contains("overload"), "{err}");
    let status = table.status().unwrap();
    assert_eq!(status.hardware_error, HardwareErrorStatus::OVERLOAD);
    assert!(!status.torque_enabled);
    // Stopped on the way (half way in time, give or take the emulator thread's latency).
    assert!(
        status.angle_deg > 400.0 && status.angle_deg < 500.0,
        "{}",
        status.angle_deg
    );
    let stopped_at = status.angle_deg;

    table.reboot().unwrap();
    let snap = servo.snapshot();
    assert_eq!(snap.reboots, 1);
    assert!(snap.hardware_error.is_empty());
    assert!(snap.torque_enabled);
    // The servo now counts within one turn; the driver's angle is continuous.
    assert!(snap.present_ticks < 4096);
    assert_abs_diff_eq!(table.angle_deg().unwrap(), stopped_at, epsilon = 1e-9);
    assert_abs_diff_eq!(
        table.rotate_to(500.0).unwrap(),
        reported(500.0, 1),
        epsilon = 1e-9
    );
    assert_eq!(servo.snapshot().backward_ticks, 0.0);
}

#[test]
fn hardware_error_at_open() {
    let servo = emulator();
    servo.raise_hardware_error(
        HardwareErrorStatus::INPUT_VOLTAGE | HardwareErrorStatus::OVERHEATING,
    );
    let err = dxl(DynamixelTurntable::open(servo.port_path(), fast()).unwrap_err());
    let msg = err.to_string();
    assert!(msg.contains("input voltage, overheating (0x05)"), "{msg}");
    let config = DynamixelConfig {
        reboot_on_hardware_error: true,
        ..fast()
    };
    let mut table = DynamixelTurntable::open(servo.port_path(), config).unwrap();
    assert!(table.hardware_error().unwrap().is_empty());
    table.rotate_to(10.0).unwrap();
}

#[test]
fn stalled_platter_times_out() {
    let servo = emulator();
    let config = DynamixelConfig {
        settle_timeout: Duration::from_millis(300),
        ..fast()
    };
    let mut table = DynamixelTurntable::open(servo.port_path(), config).unwrap();
    servo.arm_mid_move_fault(MidMoveFault::Stall);
    let err = dxl(table.rotate_to(180.0).unwrap_err());
    match err {
        DynamixelError::MoveTimeout {
            goal_deg,
            present_deg,
            moving,
            ..
        } => {
            assert!(moving);
            assert_abs_diff_eq!(goal_deg, 180.0, epsilon = 1e-9);
            // Stalled half way in time (give or take the emulator thread's latency).
            assert!(present_deg > 0.0 && present_deg < 180.0, "{present_deg}");
        }
        other => panic!("expected MoveTimeout, got {other}"),
    }
}

#[test]
fn port_closed_mid_move() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    servo.arm_mid_move_fault(MidMoveFault::ClosePort);
    let err = dxl(table.rotate_to(180.0).unwrap_err());
    assert!(
        matches!(err, DynamixelError::PortClosed { id: 1, .. }),
        "{err}"
    );
    assert!(!servo.snapshot().port_open);
    // And it stays closed, with the same error.
    let err = dxl(table.angle_deg().unwrap_err());
    assert!(matches!(err, DynamixelError::PortClosed { .. }), "{err}");
}

#[test]
fn status_reports_temperature_and_voltage() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    let s = table.status().unwrap();
    assert_abs_diff_eq!(s.input_voltage_v, 12.0, epsilon = 1e-9);
    assert_abs_diff_eq!(s.temperature_c, 28.0);
    assert!(!s.moving && s.torque_enabled && s.hardware_error.is_empty());
}

#[test]
fn torque_and_profile() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    table.set_torque(false).unwrap();
    assert!(!servo.snapshot().torque_enabled);
    table.set_torque(true).unwrap();
    table.set_profile(90.0, 0.0).unwrap();
    // 90 / 1.374 = 65.5 → 66 (round half away from zero, 65.502...).
    assert_eq!(servo.snapshot().profile_velocity, 66);
    assert_eq!(servo.snapshot().profile_acceleration, 0);
    assert!(matches!(
        table.set_profile(-1.0, 0.0),
        Err(RigError::InvalidParameter { .. })
    ));
}

#[test]
fn angles_out_of_range() {
    let servo = emulator();
    let mut table = DynamixelTurntable::open(servo.port_path(), fast()).unwrap();
    let err = dxl(table.rotate_to(100_000.0).unwrap_err());
    assert!(
        matches!(err, DynamixelError::AngleOutOfRange { .. }),
        "{err}"
    );
    assert!(matches!(
        table.rotate_to(f64::NAN),
        Err(RigError::InvalidParameter { .. })
    ));
}
