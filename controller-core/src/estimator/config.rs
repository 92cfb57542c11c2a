//! The estimator's parameters, validated at construction.

use crate::types::Pose;

/// A rejected [`EstimatorConfig`] field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EstimatorConfigError {
    /// The initial pose or the centre-of-mass offset is not finite.
    NonFinitePose,
    /// A standard deviation or noise density is negative, zero where it
    /// must be positive, or not finite.
    InvalidNoise,
    /// A chi-square gate is not finite or not > 0.
    InvalidGate,
    /// `gyro_saturation_radps` must be finite and > 0, `gyro_stale_us` > 0.
    InvalidGyroLimit,
    /// `max_consecutive_outliers` and `standstill_ticks` must be >= 1, and
    /// the history at least one tick long.
    InvalidCount,
}

impl core::fmt::Display for EstimatorConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::NonFinitePose => "estimator: initial pose and com offset must be finite",
            Self::InvalidNoise => "estimator: std devs and noise densities must be finite, > 0",
            Self::InvalidGate => "estimator: chi-square gates must be finite, > 0",
            Self::InvalidGyroLimit => "estimator: gyro saturation and staleness must be > 0",
            Self::InvalidCount => "estimator: outlier and standstill counts must be >= 1",
        })
    }
}

/// Chi-square 99.9 % quantile, 2 degrees of freedom (position only).
pub const CHI2_999_2DOF: f32 = 13.82;
/// Chi-square 99.9 % quantile, 3 degrees of freedom (position and heading).
pub const CHI2_999_3DOF: f32 = 16.27;

/// Parameters of the [`PoseEstimator`](super::PoseEstimator).
///
/// Noise densities are continuous-time: over a tick of `dt` the variance
/// added is density²·dt.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorConfig {
    /// Distance d from the axle midpoint to G \[m\] (measurements are of G).
    /// A [`ControlLoop`](crate::runtime::ControlLoop) sets it from its
    /// robot's geometry.
    pub com_offset_m: f32,
    /// Pose of G where the estimate starts. A
    /// [`ControlLoop`](crate::runtime::ControlLoop) sets it to its
    /// configuration's initial pose.
    pub initial_pose: Pose,
    /// Initial std. dev. of each position coordinate \[m\].
    pub initial_position_std_m: f32,
    /// Initial std. dev. of the heading \[rad\].
    pub initial_heading_std_rad: f32,
    /// Initial std. dev. of the gyro bias \[rad/s\].
    pub initial_bias_std_radps: f32,
    /// Initial std. dev. of the speed scale (body / wheel speed, starts at 1).
    pub initial_speed_scale_std: f32,
    /// Random walk of the speed scale \[1/√s\] (how fast slip and faults
    /// may change it).
    pub speed_scale_walk: f32,
    /// White noise on the wheel-derived speed \[m/s/√Hz\].
    pub speed_noise_mps_per_sqrt_hz: f32,
    /// Relative wheel-odometry error from slip and actuator faults (a
    /// fraction of the speed and of the wheel yaw rate, as a density per √s).
    pub slip_fraction: f32,
    /// Gyro angle random walk \[rad/s/√Hz\].
    pub gyro_noise_density: f32,
    /// Gyro bias random walk \[rad/s/√s\].
    pub gyro_bias_walk: f32,
    /// White noise on the wheel yaw rate used without a gyro \[rad/s/√Hz\].
    pub wheel_yaw_noise: f32,
    /// A gyro reading at or beyond this |rate| \[rad/s\] is saturated.
    pub gyro_saturation_radps: f32,
    /// A gyro sample older than this \[µs\] is stale.
    pub gyro_stale_us: u32,
    /// Gate of a position-only measurement (squared Mahalanobis distance).
    pub chi2_gate_2dof: f32,
    /// Gate of a position-and-heading measurement.
    pub chi2_gate_3dof: f32,
    /// After this many gated measurements in a row the estimate is taken
    /// to have drifted: the covariance is reset and the next is used.
    pub max_consecutive_outliers: u16,
    /// Longest time constant \[s\] over which a correction's jump reaches
    /// the output pose ([`Estimate::pose`](super::Estimate::pose)); the
    /// time constant is two mean measurement intervals up to this; 0 =
    /// jumps pass straight through.
    pub output_smoothing_s: f32,
    /// Ticks with both wheels still before the gyro's reading is taken as
    /// its bias (zero-rate update).
    pub standstill_ticks: u16,
    /// The gyro's yaw against the wheels' updates the speed scale (a
    /// pseudo-measurement every history snapshot interval, D36): it assumes
    /// one scale for v and ω (the actuator fault, uniform slip); one wheel
    /// slipping alone biases it (external poses, when present, still
    /// correct it).
    pub gyro_speed_scale: bool,
    /// Smallest |wheel turn| \[rad\] over the interval for that update
    /// (driving straight says nothing about the scale).
    pub gyro_scale_min_turn_rad: f32,
    /// White noise of the body's yaw rate about s × the wheels' in that
    /// update \[rad/s/√Hz\] (uneven wheel slip, quantisation).
    pub gyro_scale_yaw_noise: f32,
}

impl EstimatorConfig {
    /// Example tuning for a small robot with a MEMS gyro, starting at
    /// `initial_pose` with G `com_offset_m` ahead of the axle.
    pub const fn example(com_offset_m: f32, initial_pose: Pose) -> Self {
        Self {
            com_offset_m,
            initial_pose,
            initial_position_std_m: 0.05,
            initial_heading_std_rad: 0.05,
            initial_bias_std_radps: 0.02,
            initial_speed_scale_std: 0.1,
            speed_scale_walk: 0.05,
            speed_noise_mps_per_sqrt_hz: 0.02,
            slip_fraction: 0.02,
            gyro_noise_density: 0.001,
            gyro_bias_walk: 0.0005,
            wheel_yaw_noise: 0.05,
            gyro_saturation_radps: 34.0,
            gyro_stale_us: 20_000,
            chi2_gate_2dof: CHI2_999_2DOF,
            chi2_gate_3dof: CHI2_999_3DOF,
            max_consecutive_outliers: 10,
            standstill_ticks: 200,
            output_smoothing_s: 0.2,
            gyro_speed_scale: true,
            gyro_scale_min_turn_rad: 0.005,
            gyro_scale_yaw_noise: 0.15,
        }
    }

    /// Checks every field.
    pub fn validate(self) -> Result<Self, EstimatorConfigError> {
        use crate::math::{all_non_negative, all_positive};
        if !(self.initial_pose.is_finite() && self.com_offset_m.is_finite()) {
            return Err(EstimatorConfigError::NonFinitePose);
        }
        if !(all_positive(&[
            self.initial_position_std_m,
            self.initial_heading_std_rad,
            self.initial_bias_std_radps,
            self.initial_speed_scale_std,
            self.speed_scale_walk,
            self.speed_noise_mps_per_sqrt_hz,
            self.gyro_noise_density,
            self.gyro_bias_walk,
            self.wheel_yaw_noise,
            self.gyro_scale_min_turn_rad,
            self.gyro_scale_yaw_noise,
        ]) && all_non_negative(&[self.slip_fraction, self.output_smoothing_s]))
        {
            return Err(EstimatorConfigError::InvalidNoise);
        }
        if !all_positive(&[self.chi2_gate_2dof, self.chi2_gate_3dof]) {
            return Err(EstimatorConfigError::InvalidGate);
        }
        if !all_positive(&[self.gyro_saturation_radps]) || self.gyro_stale_us == 0 {
            return Err(EstimatorConfigError::InvalidGyroLimit);
        }
        if self.max_consecutive_outliers == 0 || self.standstill_ticks == 0 {
            return Err(EstimatorConfigError::InvalidCount);
        }
        Ok(self)
    }
}
