//! Hardware-agnostic control-loop runtime shared by the firmware and the
//! simulator: everything between the encoder registers and the PWM registers
//! that is not a register access.
//!
//! Per tick, [`ControlLoop::tick`]:
//!
//! 1. checks the reported loop time against the overrun limit;
//! 2. reads both encoders ([`WheelEncoders`]), forms 16-bit wrap-safe count
//!    deltas ([`count_delta`]), rejects implausible jumps, estimates wheel
//!    rates over a short window and η = \[v, ω\]
//!    ([`RobotParams::eta_from_wheel_rates`](crate::RobotParams::eta_from_wheel_rates));
//! 3. integrates wheel odometry of the tracked point G ([`Odometry`]), or
//!    takes an external pose from a [`PoseSource`];
//! 4. samples the reference at t = (ticks since arming) × period and runs one
//!    [`Controller::step`](crate::Controller::step);
//! 5. maps the wheel torques to PWM duty and direction through the motor
//!    model ([`MotorModel`]) and writes the [`MotorDriver`];
//! 6. latches a safe stop ([`StopReason`]: zero duty, driver disabled) on a
//!    controller input fault, an encoder jump, a stalled encoder or
//!    repeated loop overruns.
//!
//! The motors stay disabled from construction until [`ControlLoop::arm`];
//! a latched stop is only cleared by [`ControlLoop::reset`] (back to
//! disarmed).
//!
//! Conventions: wheel arrays are `[right, left]`; time is passed in as the
//! measured loop time \[µs\], the control period is the controller's
//! `period_s`.

mod encoder;
mod motor;
mod odometry;
mod stats;
mod supervisor;

pub use encoder::{count_delta, CountSample, EncoderParams, WheelCounts, MAX_SPEED_WINDOW};
pub use motor::{DutyCommand, DutyRequest, MotorModel, MotorParams};
pub use odometry::Odometry;
pub use stats::CycleStats;
pub use supervisor::{
    ArmError, ControlLoop, RunState, RuntimeConfig, SafetyLimits, Status, StopReason, TickReport,
};

use crate::error::ConfigError;
use crate::types::Pose;

/// A wheel, for fault reports and indexing `[right, left]` arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Wheel {
    /// Right wheel (index 0).
    Right,
    /// Left wheel (index 1).
    Left,
}

impl Wheel {
    /// Both wheels in array order.
    pub const BOTH: [Wheel; 2] = [Wheel::Right, Wheel::Left];

    /// Index into a `[right, left]` array.
    pub const fn index(self) -> usize {
        match self {
            Wheel::Right => 0,
            Wheel::Left => 1,
        }
    }
}

/// One quadrature encoder: the raw free-running 16-bit hardware count
/// (e.g. a timer in encoder mode, or a simulated counter).
pub trait Encoder {
    /// Current raw count (wraps at 2¹⁶).
    fn count(&mut self) -> u16;
}

/// Both wheel encoders, read together once per tick.
///
/// Implemented for a `(right, left)` tuple and a `[right, left]` array of
/// [`Encoder`]s.
pub trait WheelEncoders {
    /// Raw counts `[right, left]`.
    fn counts(&mut self) -> [u16; 2];
}

impl<R: Encoder, L: Encoder> WheelEncoders for (R, L) {
    fn counts(&mut self) -> [u16; 2] {
        [self.0.count(), self.1.count()]
    }
}

impl<E: Encoder> WheelEncoders for [E; 2] {
    fn counts(&mut self) -> [u16; 2] {
        let [r, l] = self;
        [r.count(), l.count()]
    }
}

/// The motor driver (H-bridge) of both wheels. Implementations must start
/// disabled (outputs off) and stay disabled until the first [`Self::set`].
pub trait MotorDriver {
    /// Enables the bridge (if disabled) and applies `[right, left]` duty and
    /// direction. Duty is in counts of [`MotorParams::duty_full_scale`].
    fn set(&mut self, cmd: [DutyCommand; 2]);
    /// Zero duty and bridge disabled (motors coast). Called on every tick
    /// while not running, so it must be idempotent and cheap.
    fn disable(&mut self);
}

/// An optional external measurement of the pose of G (motion capture, a
/// camera, a lidar localiser...). Wheel odometry cannot see wheel slip or an
/// actuator fault that changes the body's motion, so the fault observer
/// only works with such a measurement.
pub trait PoseSource {
    /// A new measurement taken since the last call, or `None` (then the
    /// runtime uses wheel odometry).
    fn pose(&mut self) -> Option<Pose>;
}

/// The default [`PoseSource`]: never has a measurement (wheel odometry only).
#[derive(Clone, Copy, Debug, Default)]
pub struct WheelOdometryOnly;

impl PoseSource for WheelOdometryOnly {
    fn pose(&mut self) -> Option<Pose> {
        None
    }
}

/// A runtime parameter rejected at construction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RuntimeConfigError {
    /// The controller configuration or the reference trajectory is invalid.
    Core(ConfigError),
    /// Encoder counts per wheel revolution must be finite and > 0.
    NonPositiveEncoderResolution,
    /// Speed window must be in `1..=MAX_SPEED_WINDOW` ticks.
    InvalidSpeedWindow,
    /// Motor torque constant must be finite and > 0.
    NonPositiveTorqueConstant,
    /// Winding resistance must be finite and > 0.
    NonPositiveResistance,
    /// Gear ratio must be finite and > 0.
    NonPositiveGearRatio,
    /// Gear efficiency must be in (0, 1].
    InvalidGearEfficiency,
    /// Supply voltage must be finite and > 0.
    NonPositiveSupplyVoltage,
    /// Max duty fraction must be in (0, 1].
    InvalidMaxDuty,
    /// Duty full scale must be > 0 counts.
    ZeroDutyResolution,
    /// A safety limit is zero, non-finite or out of range.
    InvalidSafetyLimit,
    /// The initial pose is not finite.
    NonFiniteInitialPose,
}

impl From<ConfigError> for RuntimeConfigError {
    fn from(e: ConfigError) -> Self {
        Self::Core(e)
    }
}

impl core::fmt::Display for RuntimeConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let s = match self {
            Self::Core(e) => return write!(f, "controller: {e}"),
            Self::NonPositiveEncoderResolution => "encoder counts per wheel rev must be > 0",
            Self::InvalidSpeedWindow => "speed window must be 1..=32 ticks",
            Self::NonPositiveTorqueConstant => "motor torque constant must be > 0",
            Self::NonPositiveResistance => "winding resistance must be > 0",
            Self::NonPositiveGearRatio => "gear ratio must be > 0",
            Self::InvalidGearEfficiency => "gear efficiency must be in (0, 1]",
            Self::NonPositiveSupplyVoltage => "supply voltage must be > 0",
            Self::InvalidMaxDuty => "max duty fraction must be in (0, 1]",
            Self::ZeroDutyResolution => "duty full scale must be > 0",
            Self::InvalidSafetyLimit => "invalid safety limit",
            Self::NonFiniteInitialPose => "initial pose must be finite",
        };
        f.write_str(s)
    }
}

#[cfg(test)]
mod closed_loop_tests;
