//! What the runtime is configured with: the controller, the reference, the
//! hardware constants and the safety thresholds, validated by
//! [`ControlLoop::new`](super::ControlLoop::new)(super::ControlLoop::new).

use super::encoder::EncoderParams;
use super::error::RuntimeConfigError;
use super::hardware::MIRRORED_LEFT;
use super::motor::MotorParams;
use crate::controller::{ControllerConfig, ControllerKind};
use crate::pacer::PacingConfig;
use crate::trajectory::{PaperCurve, PaperHeading, Reference, Trajectory};
use crate::types::Pose;

/// Thresholds of the safety supervisor.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafetyLimits {
    /// Largest plausible |count change| of one wheel in one period \[counts\]
    /// (1..=32767; scaled by the periods a late tick spans); beyond it the
    /// reading is a glitch ([`StopReason::EncoderJump`](super::StopReason::EncoderJump)).
    /// Set it to about twice the no-load wheel speed in counts per tick.
    pub max_counts_per_tick: u16,
    /// |Commanded wheel torque| \[N·m\] at or above which a wheel must move.
    pub stall_torque_nm: f32,
    /// Consecutive ticks at or above `stall_torque_nm` with no count change
    /// that mean a stalled wheel or a dead encoder ([`StopReason::EncoderStalled`](super::StopReason::EncoderStalled)).
    pub stall_ticks: u16,
    /// A tick that starts more than this \[µs\] behind its scheduled time
    /// t₀ + n·period is late ([`LoopTimer`](super::LoopTimer)).
    pub overrun_limit_us: u32,
    /// Consecutive late ticks that latch [`StopReason::LoopOverrun`](super::StopReason::LoopOverrun) (>= 1).
    pub max_consecutive_overruns: u16,
    /// Consecutive controller input faults that latch
    /// [`StopReason::ControllerInput`](super::StopReason::ControllerInput) (>= 1; 1 latches on the first).
    pub max_consecutive_input_faults: u16,
    /// Direction check ([`StopReason::DirectionMismatch`](super::StopReason::DirectionMismatch)):
    /// |mean wheel torque| over a block \[N·m\] at or above which the
    /// wheel must not accelerate against it (above the wheel's friction and
    /// the torques the body's cross-coupling can overcome).
    pub direction_torque_nm: f32,
    /// Direction check: the acceleration against the torque \[rad/s²\]
    /// that counts (above the rate estimate's quantisation over a block:
    /// 2π / counts per rev / speed window / block time, 3.3 rad/s² with the
    /// example encoder over 20 ms, and above friction's deceleration).
    pub direction_accel_radps2: f32,
    /// Direction check: the block \[ticks\] over which the acceleration and
    /// the mean torque are taken (>= 3: the two wheels' verdicts come one
    /// and two ticks after a block's end).
    pub direction_block_ticks: u16,
    /// Direction check: mismatching blocks in a row that latch (>= 1): the
    /// window is `direction_block_ticks × direction_blocks` ticks.
    pub direction_blocks: u16,
}

impl SafetyLimits {
    /// Example limits for a 1 kHz loop with [`EncoderParams::EXAMPLE`] and
    /// [`MotorParams::EXAMPLE`] (no-load wheel speed 40 rad/s = 153 counts/ms):
    /// jump > 400 counts/tick, stall at >= 2 N·m for 250 ms, a tick more
    /// than 0.5 ms behind schedule late with 5 in a row latching, the first
    /// NaN/implausible input latching; the direction check at >= 1 N·m
    /// against >= 10 rad/s² for 4 blocks of 20 ms (80 ms; book/src/explanation/decisions.md D74).
    pub const EXAMPLE: Self = Self {
        max_counts_per_tick: 400,
        stall_torque_nm: 2.0,
        stall_ticks: 250,
        overrun_limit_us: 500,
        max_consecutive_overruns: 5,
        max_consecutive_input_faults: 1,
        direction_torque_nm: 1.0,
        direction_accel_radps2: 10.0,
        direction_block_ticks: 20,
        direction_blocks: 4,
    };

    /// Checks every field on its own (positive, finite, in range); the
    /// direction check's thresholds against the robot they run on are
    /// [`Self::validate_direction`]'s (both run in `ControlLoop::new` and
    /// `reconfigure`).
    pub fn validate(self) -> Result<Self, RuntimeConfigError> {
        use RuntimeConfigError as E;
        let ok = self.max_counts_per_tick > 0
            && self.max_counts_per_tick <= i16::MAX as u16
            && self.stall_torque_nm.is_finite()
            && self.stall_torque_nm > 0.0
            && self.stall_ticks > 0
            && self.overrun_limit_us > 0
            && self.max_consecutive_overruns > 0
            && self.max_consecutive_input_faults > 0;
        if !ok {
            return Err(E::InvalidSafetyLimit);
        }
        if !(self.direction_torque_nm.is_finite() && self.direction_torque_nm > 0.0) {
            return Err(E::DirectionTorqueOutOfRange);
        }
        if !(self.direction_accel_radps2.is_finite() && self.direction_accel_radps2 > 0.0) {
            return Err(E::DirectionAccelBelowQuantisation);
        }
        if self.direction_block_ticks < 3 || self.direction_blocks == 0 {
            return Err(E::InvalidDirectionBlock);
        }
        Ok(self)
    }

    /// The direction check's thresholds against the robot (D112): each
    /// bound is one a useful check must meet, each violation names its
    /// field.
    ///
    /// * `direction_torque_nm` ≤ ½ `torque_limit_nm`: a miswired wheel's
    ///   runaway settles where the voltage's torque τ_V = τ_c + b·φ̇ is
    ///   −b·φ̇ = τ_c/2 (φ̇ = −τ_c/2b), so above half the limit the
    ///   equilibrium never gets a verdict
    ///   ([`RuntimeConfigError::DirectionTorqueOutOfRange`]).
    /// * `direction_accel_radps2` × block ≥ 2 quanta of the windowed rate
    ///   estimate (`rate_quantum_radps`, one count per speed window): a
    ///   block's rate change is the difference of two estimates, each
    ///   within one quantum of the window's true mean, so a healthy wheel's
    ///   quantisation alone reaches just under 2 quanta and a lower
    ///   tolerance false-trips ([`RuntimeConfigError::DirectionAccelBelowQuantisation`]).
    /// * `direction_accel_radps2` ≤ ½ W_ii·`torque_limit_nm`
    ///   (`wheel_accel_radps2_per_nm` = W_ii, eq. 7's own-wheel entry,
    ///   `ReducedModel::wheel_accel_map`): at the runaway's equilibrium
    ///   the measurement lies W_ii·τ_c/2 from the midpoint between the
    ///   hypotheses, at most ½ W_ii × the limit; a larger tolerance never
    ///   fires there ([`RuntimeConfigError::DirectionAccelUnreachable`]).
    pub fn validate_direction(
        self,
        torque_limit_nm: f32,
        wheel_accel_radps2_per_nm: f32,
        rate_quantum_radps: f32,
        period_s: f32,
    ) -> Result<Self, RuntimeConfigError> {
        use RuntimeConfigError as E;
        // The fields are finite and positive (`validate`); the robot's
        // values come from validated configurations.
        let s = self.validate()?;
        if s.direction_torque_nm > 0.5 * torque_limit_nm {
            return Err(E::DirectionTorqueOutOfRange);
        }
        let block_s = s.direction_block_ticks as f32 * period_s;
        if s.direction_accel_radps2 * block_s < 2.0 * rate_quantum_radps {
            return Err(E::DirectionAccelBelowQuantisation);
        }
        if s.direction_accel_radps2 > 0.5 * wheel_accel_radps2_per_nm * torque_limit_nm {
            return Err(E::DirectionAccelUnreachable);
        }
        Ok(s)
    }
}

/// Everything the runtime needs, validated by [`ControlLoop::new`](super::ControlLoop::new).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RuntimeConfig {
    /// The controller (kind, robot parameters, gains, torque limit, period).
    pub controller: ControllerConfig,
    /// The reference trajectory, sampled at t = ticks since arming × period.
    pub reference: Reference,
    /// Pose of G where wheel odometry starts.
    pub initial_pose: Pose,
    /// Encoder resolution, mounting and speed window.
    pub encoder: EncoderParams,
    /// Motor, gearbox, supply and PWM constants.
    pub motor: MotorParams,
    /// Per wheel `[right, left]`: flip the direction output (mirrored motor).
    pub motor_inverted: [bool; 2],
    /// Safety thresholds.
    pub safety: SafetyLimits,
    /// Reference governor and health machine ([`crate::pacer`]); on in
    /// [`Self::example`].
    pub pacing: PacingConfig,
}

impl RuntimeConfig {
    /// Example: `kind` with the paper's gains, the paper's curve
    /// ([`PaperHeading::SignedSmooth`]), odometry starting on the reference's
    /// initial pose, and the `EXAMPLE` encoder, motor and safety constants.
    pub fn example(kind: ControllerKind) -> Self {
        let reference = Reference::Paper(PaperCurve::paper(PaperHeading::SignedSmooth));
        Self {
            controller: ControllerConfig::paper(kind),
            reference,
            initial_pose: reference.sample(0.0).pose,
            encoder: EncoderParams::EXAMPLE,
            motor: MotorParams::EXAMPLE,
            motor_inverted: MIRRORED_LEFT,
            safety: SafetyLimits::EXAMPLE,
            pacing: PacingConfig::on(),
        }
    }
}
