//! Error and fault enums: small, `Copy`, `#[non_exhaustive]`.

/// A parameter rejected at construction. Each variant names what was wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ConfigError {
    /// Robot mass must be finite and > 0.
    NonPositiveMass,
    /// Body yaw inertia must be finite and > 0.
    NonPositiveInertia,
    /// Wheel inertia must be finite and >= 0.
    NegativeWheelInertia,
    /// Wheel radius must be finite and > 0.
    NonPositiveWheelRadius,
    /// Half track h must be finite and > 0.
    NonPositiveHalfTrack,
    /// Centre-of-mass offset d must be finite and >= 0.
    NegativeComOffset,
    /// A controller gain must be finite and > 0 (k_x, k_y, k_th, k_s, l1, l2, λ).
    NonPositiveGain,
    /// fal parameters: need 0 < α < 1 and ζ > 0.
    InvalidFal,
    /// Adaptive gain: need γ >= 0, dead zone >= 0, leakage >= 0, 0 <= ρ_min <= ρ0 <= ρ_max.
    InvalidAdaptation,
    /// Torque limit must be finite and > 0.
    NonPositiveTorqueLimit,
    /// Control period must be finite and in (0, 0.1] s.
    InvalidPeriod,
    /// Input plausibility limits must be finite and > 0.
    InvalidInputLimits,
    /// A trajectory parameter (radius, amplitude, period, speed) is not finite or not > 0.
    InvalidTrajectory,
    /// Component not enabled for this controller kind (e.g. a fault observer on SMC).
    KindMismatch,
    /// Reference governor: thresholds must be finite, positive and ordered
    /// (start < stop), the error floor in (0, 1], rates > 0.
    InvalidGovernor,
    /// Health machine: thresholds finite and > 0, exit fraction in (0, 1),
    /// degraded speed scale in (0, 1], dwell times >= 0.
    InvalidHealth,
    /// Wheel friction: b, c finite and >= 0, smoothing rate > 0, and c
    /// below the torque limit.
    InvalidFriction,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let s = match self {
            Self::NonPositiveMass => "robot mass must be finite and > 0",
            Self::NonPositiveInertia => "body inertia must be finite and > 0",
            Self::NegativeWheelInertia => "wheel inertia must be finite and >= 0",
            Self::NonPositiveWheelRadius => "wheel radius must be finite and > 0",
            Self::NonPositiveHalfTrack => "half track must be finite and > 0",
            Self::NegativeComOffset => "centre-of-mass offset must be finite and >= 0",
            Self::NonPositiveGain => "controller gains must be finite and > 0",
            Self::InvalidFal => "fal needs 0 < alpha < 1 and zeta > 0",
            Self::InvalidAdaptation => "invalid adaptive-gain parameters",
            Self::NonPositiveTorqueLimit => "torque limit must be finite and > 0",
            Self::InvalidPeriod => "control period must be in (0, 0.1] s",
            Self::InvalidInputLimits => "input limits must be finite and > 0",
            Self::InvalidFriction => {
                "wheel friction must be finite and >= 0, its smoothing rate > 0, and the Coulomb torque below the torque limit"
            }
            Self::InvalidTrajectory => "trajectory parameters must be finite and > 0",
            Self::KindMismatch => "component not available for this controller kind",
            Self::InvalidGovernor => "invalid reference-governor parameters",
            Self::InvalidHealth => "invalid health-machine parameters",
        };
        f.write_str(s)
    }
}

/// Why a control step rejected its input (and output zero torque).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum InputFault {
    /// A measured pose coordinate is NaN or infinite.
    NonFinitePose,
    /// A measured velocity is NaN or infinite.
    NonFiniteVelocity,
    /// A reference sample field is NaN or infinite.
    NonFiniteReference,
    /// Position magnitude beyond [`crate::InputLimits::max_position_m`].
    ImplausiblePosition,
    /// |v| or |ω| beyond the plausible limits.
    ImplausibleVelocity,
    /// An internal state became non-finite; the controller reset itself.
    InternalStateReset,
}
