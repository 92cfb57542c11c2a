//! Configuration errors of the runtime.

use crate::error::ConfigError;
use crate::estimator::EstimatorConfigError;

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
    /// Encoder radius scale outside `EncoderParams::RADIUS_SCALE_RANGE`.
    InvalidRadiusScale,
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
    /// `direction_torque_nm` must be finite, > 0 and at most half the
    /// torque limit (`SafetyLimits::validate_direction`).
    DirectionTorqueOutOfRange,
    /// `direction_accel_radps2` must be finite, > 0, and over a block at
    /// least 2 quanta of the windowed wheel-rate estimate.
    DirectionAccelBelowQuantisation,
    /// `direction_accel_radps2` must be at most half the wheel
    /// acceleration the torque limit gives (W_ii × the limit / 2).
    DirectionAccelUnreachable,
    /// `direction_block_ticks` must be >= 3 and `direction_blocks` >= 1.
    InvalidDirectionBlock,
    /// The initial pose is not finite.
    NonFiniteInitialPose,
    /// Button debounce must be >= 1 tick.
    InvalidDebounce,
    /// PWM frequency outside `BridgeParams::PWM_FREQUENCY_RANGE_HZ`.
    InvalidPwmFrequency,
    /// The pose estimator's configuration is invalid.
    Estimator(EstimatorConfigError),
}

impl From<EstimatorConfigError> for RuntimeConfigError {
    fn from(e: EstimatorConfigError) -> Self {
        Self::Estimator(e)
    }
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
            Self::Estimator(e) => return write!(f, "{e}"),
            Self::NonPositiveEncoderResolution => "encoder counts per wheel rev must be > 0",
            Self::InvalidSpeedWindow => "speed window must be 1..=32 ticks",
            Self::InvalidRadiusScale => "encoder radius scale must be within 0.9..=1.1",
            Self::NonPositiveTorqueConstant => "motor torque constant must be > 0",
            Self::NonPositiveResistance => "winding resistance must be > 0",
            Self::NonPositiveGearRatio => "gear ratio must be > 0",
            Self::InvalidGearEfficiency => "gear efficiency must be in (0, 1]",
            Self::NonPositiveSupplyVoltage => "supply voltage must be > 0",
            Self::InvalidMaxDuty => "max duty fraction must be in (0, 1]",
            Self::ZeroDutyResolution => "duty full scale must be > 0",
            Self::InvalidSafetyLimit => "invalid safety limit",
            Self::DirectionTorqueOutOfRange => {
                "direction_torque_nm must be > 0 and at most half the torque limit (a runaway's equilibrium torque)"
            }
            Self::DirectionAccelBelowQuantisation => {
                "direction_accel_radps2 over a block must be at least 2 quanta of the wheel-rate estimate (else quantisation trips it)"
            }
            Self::DirectionAccelUnreachable => {
                "direction_accel_radps2 must be at most half the wheel acceleration at the torque limit (else it never fires)"
            }
            Self::InvalidDirectionBlock => {
                "direction_block_ticks must be >= 3 and direction_blocks >= 1"
            }
            Self::NonFiniteInitialPose => "initial pose must be finite",
            Self::InvalidDebounce => "button debounce must be >= 1 tick",
            Self::InvalidPwmFrequency => "PWM frequency must be in 1..=100 kHz",
        };
        f.write_str(s)
    }
}
