//! The run state machine's states, the reasons for a safe stop, the status
//! counters and the per-tick report.

use super::encoder::CountSample;
use super::hardware::Wheel;
use super::motor::DutyCommand;
use crate::controller::Diagnostics;
use crate::error::InputFault;
use crate::estimator::{Estimate, GyroState};
use crate::health::HealthReason;
use crate::pacer::PaceReport;
use crate::trajectory::RefSample;
use crate::types::{Pose, Vel2};

/// Why the loop latched a safe stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StopReason {
    /// The controller rejected its input (NaN, infinite or implausible pose,
    /// velocity or reference, or its internal state reset).
    ControllerInput(InputFault),
    /// A wheel's count changed by more than `max_counts_per_tick`.
    EncoderJump {
        /// Which wheel.
        wheel: Wheel,
        /// The implausible change \[counts\].
        delta: i32,
    },
    /// A wheel did not move for `stall_ticks` while commanded at least
    /// `stall_torque_nm`.
    EncoderStalled {
        /// Which wheel.
        wheel: Wheel,
    },
    /// `max_consecutive_overruns` late ticks in a row (see
    /// [`LoopTimer`](super::LoopTimer)).
    LoopOverrun {
        /// How far behind schedule the latching tick started \[µs\].
        lateness_us: u32,
    },
    /// Stopped on request ([`ControlLoop::stop`](super::ControlLoop::stop)).
    Commanded,
    /// A wheel accelerated against its commanded torque beyond the
    /// tolerances for the whole window (`SafetyLimits::direction_*`): its
    /// motor or its encoder is wired backwards (positive feedback).
    DirectionMismatch {
        /// Which wheel.
        wheel: Wheel,
    },
    /// The health machine found a hard fault ([`crate::health`]).
    Health(HealthReason),
}

/// Supervisor state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunState {
    /// Motors disabled, waiting for [`ControlLoop::arm`](super::ControlLoop::arm) (the boot state).
    Disarmed,
    /// Controller running, motors driven.
    Running,
    /// Latched safe stop: motors disabled until [`ControlLoop::reset`](super::ControlLoop::reset).
    Stopped(StopReason),
}

/// Why [`ControlLoop::arm`](super::ControlLoop::arm) refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ArmError {
    /// A safe stop is latched; [`ControlLoop::reset`](super::ControlLoop::reset) first.
    Latched(StopReason),
}

/// Why [`ControlLoop::reconfigure`](super::ControlLoop::reconfigure) refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ReconfigureError {
    /// Not while running: disarm first.
    Running,
    /// The new configuration is invalid.
    Invalid(super::error::RuntimeConfigError),
}

/// Counters for logging (lifetime totals unless noted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status {
    /// Current state.
    pub state: RunState,
    /// Ticks since construction.
    pub ticks: u32,
    /// Controller steps since the last arming (the reference time base).
    pub run_ticks: u32,
    /// Overrun episodes: runs of late ticks (a stall and the catch-up
    /// burst after it count once).
    pub overruns: u32,
    /// Current run of consecutive late ticks.
    pub consecutive_overruns: u16,
    /// Largest time between two ticks \[µs\].
    pub max_loop_time_us: u32,
    /// Implausible encoder jumps (also counted while disarmed).
    pub encoder_jumps: u32,
    /// Controller steps rejected for bad input.
    pub input_faults: u32,
    /// Steps where the controller clamped its torque request.
    pub torque_saturated: u32,
    /// Wheel-steps where the duty was clamped (the supply could not deliver
    /// the torque at that speed).
    pub duty_saturated: u32,
    /// Ticks where the torque was scaled down so that the delivered torque
    /// stays within the limit at the rate estimate's resolution (D176).
    pub torque_bounded: u32,
    /// External pose measurements accepted by the estimator.
    pub external_poses: u32,
    /// Safe stops latched.
    pub stops: u32,
}

/// What one tick did, for telemetry and for the simulator.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickReport {
    /// State after this tick.
    pub state: RunState,
    /// Set on the tick that latched a safe stop.
    pub stopped: Option<StopReason>,
    /// Reference time of this step \[s\] (ticks since arming × period).
    pub t_s: f32,
    /// Pose given to the controller: the estimator's fused pose of G.
    pub pose: Pose,
    /// True when a measurement from the [`PoseSource`](super::PoseSource)
    /// was accepted this tick.
    pub external_pose: bool,
    /// The estimator's output (fused pose, speed, body yaw rate).
    pub estimate: Estimate,
    /// What the estimator made of the gyro this tick.
    pub gyro: GyroState,
    /// Encoder deltas and wheel rates.
    pub counts: CountSample,
    /// Measured η = \[v, ω\] from the wheel rates.
    pub eta: Vel2,
    /// Reference sample.
    pub reference: RefSample,
    /// Wheel torques commanded this tick \[N·m\] `[right, left]` (0 when not running).
    pub torque_nm: [f32; 2],
    /// Duty written `[right, left]` (after `motor_inverted`).
    pub duty: [DutyCommand; 2],
    /// True when the driver was enabled and written; false when disabled.
    pub motors_enabled: bool,
    /// Controller diagnostics (default when the controller did not run).
    pub diag: Diagnostics,
    /// Reference governor (time scale, τ) and health mode after this tick.
    pub pace: PaceReport,
}
