//! Hardware-agnostic control-loop runtime shared by the firmware and the
//! simulator: everything between the encoder registers and the PWM registers
//! that is not a register access.
//!
//! Per tick, [`ControlLoop::tick`]:
//!
//! 1. takes the tick's [`TickTiming`] from a [`LoopTimer`] (lateness
//!    against the schedule t₀ + n·period, true elapsed time) and latches on a
//!    sustained overrun;
//! 2. reads both encoders ([`WheelEncoders`]), forms 16-bit wrap-safe count
//!    deltas ([`count_delta`]), rejects implausible jumps, estimates wheel
//!    rates over a short window and η = \[v, ω\]
//!    ([`RobotParams::eta_from_wheel_rates`](crate::RobotParams::eta_from_wheel_rates));
//! 3. estimates the pose of G ([`PoseEstimator`](crate::estimator::PoseEstimator)):
//!    predicts from the wheels and the [`Gyro`] (if any), corrects with
//!    the timestamped, possibly late measurements of a [`PoseSource`] (if
//!    any); without either the estimate is wheel odometry ([`Odometry`]
//!    integrates the same map on its own, outside the loop);
//! 4. samples the reference at t = (ticks since arming) × period and runs one
//!    [`Controller::step`](crate::Controller::step);
//! 5. maps the wheel torques to PWM duty and direction through the motor
//!    model ([`MotorModel`]) and writes the [`MotorDriver`];
//! 6. latches a safe stop ([`StopReason`]: zero duty, driver disabled) on a
//!    controller input fault, an encoder jump, a stalled encoder, a wheel
//!    accelerating against its torque (a motor or encoder wired backwards,
//!    `direction` module) or repeated loop overruns.
//!
//! The motors stay disabled from construction until [`ControlLoop::arm`];
//! a latched stop is only cleared by [`ControlLoop::reset`] (back to
//! disarmed).
//!
//! Conventions: wheel arrays are `[right, left]`; time comes in as each
//! tick's [`TickTiming`] (true elapsed time for the rate estimate), the
//! control period (reference time, controller steps) is the controller's
//! `period_s`.

mod arming;
pub mod bounds;
mod bridge;
mod config;
mod control_loop;
mod direction;
mod encoder;
mod error;
mod hardware;
mod motor;
mod odometry;
pub mod param_table;
mod state;
mod stats;
#[cfg(any(test, feature = "test-doubles"))]
pub mod test_doubles;
mod timing;

pub use arming::{ArmingButton, ArmingEvent};
pub use bridge::{BridgeMode, BridgeParams, IdleMode};
pub use config::{RuntimeConfig, SafetyLimits};
pub use control_loop::{ControlLoop, MAX_REPROPAGATION_PER_TICK};
pub use encoder::{count_delta, CountSample, EncoderParams, WheelCounts, MAX_SPEED_WINDOW};
pub use error::RuntimeConfigError;
pub use hardware::{
    Encoder, Gyro, MotorDriver, NoGyro, PoseSource, Wheel, WheelEncoders, WheelOdometryOnly,
    MAX_POSES_PER_TICK, MIRRORED_LEFT,
};
pub use motor::{DutyCommand, DutyRequest, MotorModel, MotorParams};
pub use odometry::Odometry;
pub use state::{ArmError, ReconfigureError, RunState, Status, StopReason, TickReport};
pub use stats::CycleStats;
pub use timing::{LoopTimer, TickTiming, TimingStats};
