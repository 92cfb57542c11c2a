//! Robot, motor, encoder and safety constants: the one place to set them for
//! your robot. Units are SI and named in the field names; the types document
//! every field (`controller_core::RobotParams`,
//! `controller_core::runtime::{MotorParams, EncoderParams, SafetyLimits}`).

use controller_core::runtime::{EncoderParams, MotorParams, RuntimeConfig, SafetyLimits};
use controller_core::trajectory::{PaperCurve, PaperHeading, Reference, Trajectory};
use controller_core::{ControllerConfig, ControllerKind, RobotParams};

/// Which of the paper's controllers runs.
pub const CONTROLLER: ControllerKind = ControllerKind::Proposed;

/// Robot body: mass, inertia, wheel radius, half track, centre-of-mass
/// offset. Default: the paper's Table 1 (15 kg, r = 0.1 m, track 0.4 m,
/// d = 0.05 m): measure and replace for a real robot.
pub const ROBOT: RobotParams = RobotParams::paper();

/// Motors, gearbox, supply and PWM (example 24 V gear-motor, see
/// `MotorParams::EXAMPLE`). `duty_full_scale` is replaced at start-up by the
/// PWM timer's real resolution.
pub const MOTOR: MotorParams = MotorParams {
    torque_constant_nm_per_a: 0.05, // k [N·m/A] = back-EMF [V·s/rad], motor side
    winding_resistance_ohm: 0.5,    // R [Ω], winding + bridge on-resistance
    gear_ratio: 12.0,               // motor revs per wheel rev
    gear_efficiency: 0.85,          // η_g
    supply_voltage_v: 24.0,         // battery [V]
    max_duty_fraction: 0.95,        // duty limit (bootstrap drivers need < 1)
    duty_full_scale: 4800,          // placeholder: set from the timer at boot
};

/// Encoders: counts per *wheel* revolution after ×4 decoding and gearbox
/// (500 lines × 4 × 12 = 24 000), which counter runs backwards when driving
/// forward, and the speed window.
pub const ENCODER: EncoderParams = EncoderParams {
    counts_per_wheel_rev: 24_000.0,
    inverted: [false, true], // left encoder mirrored
    speed_window_ticks: 4,   // 4 ms window: 0.065 rad/s quantization, 2 ms delay
};

/// Per wheel `[right, left]`: flip the DIR output (left motor mirrored).
pub const MOTOR_INVERTED: [bool; 2] = [false, true];

/// Safety thresholds (see `SafetyLimits`): jump > 400 counts/ms
/// (2.6× the 40 rad/s no-load speed), stall at >= 2 N·m for 250 ms,
/// overrun > 1.5 ms with 5 in a row latching, first bad input latching.
pub const SAFETY: SafetyLimits = SafetyLimits::EXAMPLE;

/// The full runtime configuration; `pwm_full_scale` is the PWM timer's
/// counts at 100 % duty.
pub fn runtime_config(pwm_full_scale: u16) -> RuntimeConfig {
    let controller = ControllerConfig {
        robot: ROBOT,
        period_s: 1.0 / crate::board::CONTROL_HZ as f32,
        ..ControllerConfig::paper(CONTROLLER)
    };
    // The paper's reference curve; odometry starts on its initial pose, so
    // place the robot there (x = 4 m, y = 3 m from the origin, facing +x).
    let reference = Reference::Paper(PaperCurve::paper(PaperHeading::SignedSmooth));
    RuntimeConfig {
        controller,
        reference,
        initial_pose: reference.sample(0.0).pose,
        encoder: ENCODER,
        motor: MotorParams {
            duty_full_scale: pwm_full_scale,
            ..MOTOR
        },
        motor_inverted: MOTOR_INVERTED,
        safety: SAFETY,
    }
}
