//! What goes into and comes out of the [`PoseEstimator`](super::PoseEstimator):
//! sensor samples, measurements, the reasons a measurement is refused and
//! the status for logs and telemetry.

use crate::types::Pose;

/// One z-gyro reading: the body's yaw rate as the sensor measured it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GyroSample {
    /// Measured yaw rate \[rad/s\] (with the sensor's bias and noise).
    pub rate_radps: f32,
    /// When it was taken, in the robot's µs clock (the loop's `now_us`).
    pub stamp_us: u32,
}

/// An external measurement of the pose of G (motion capture, a lidar
/// localiser, a camera, UWB), with its own uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseMeasurement {
    /// When the pose was *taken*, in the robot's µs clock (it may arrive
    /// up to the estimator's history length later).
    pub stamp_us: u32,
    /// Measured pose of G (`theta_rad` ignored without `heading_std_rad`).
    pub pose: Pose,
    /// Std. dev. of each position coordinate \[m\] (> 0).
    pub position_std_m: f32,
    /// Std. dev. of the heading \[rad\] (> 0), or `None` for a
    /// position-only measurement (UWB, GPS).
    pub heading_std_rad: Option<f32>,
}

/// Why a pose measurement was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RejectReason {
    /// A coordinate is NaN, infinite or implausibly large (> 100 km).
    NonFinite,
    /// A standard deviation is zero, negative, not finite or > 1000.
    BadStdDev,
    /// Its timestamp is after the current tick.
    FromFuture,
    /// Its timestamp is older than the history buffer.
    TooOld,
    /// Its timestamp is before the last accepted measurement's.
    OutOfOrder,
    /// The innovation failed the chi-square gate (an outlier).
    Outlier,
}

/// Rejected measurements by [`RejectReason`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RejectCounts {
    /// [`RejectReason::NonFinite`].
    pub non_finite: u32,
    /// [`RejectReason::BadStdDev`].
    pub bad_std_dev: u32,
    /// [`RejectReason::FromFuture`].
    pub from_future: u32,
    /// [`RejectReason::TooOld`].
    pub too_old: u32,
    /// [`RejectReason::OutOfOrder`].
    pub out_of_order: u32,
    /// [`RejectReason::Outlier`].
    pub outlier: u32,
}

impl RejectCounts {
    /// Counts one rejection.
    pub fn count(&mut self, r: RejectReason) {
        let c = match r {
            RejectReason::NonFinite => &mut self.non_finite,
            RejectReason::BadStdDev => &mut self.bad_std_dev,
            RejectReason::FromFuture => &mut self.from_future,
            RejectReason::TooOld => &mut self.too_old,
            RejectReason::OutOfOrder => &mut self.out_of_order,
            RejectReason::Outlier => &mut self.outlier,
        };
        *c = c.saturating_add(1);
    }

    /// All rejections.
    pub fn total(&self) -> u32 {
        self.non_finite
            .saturating_add(self.bad_std_dev)
            .saturating_add(self.from_future)
            .saturating_add(self.too_old)
            .saturating_add(self.out_of_order)
            .saturating_add(self.outlier)
    }
}

/// What the estimator made of the gyro on the latest tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum GyroState {
    /// Used for the yaw prediction.
    Ok,
    /// No sample (no gyro fitted, or it does not answer): wheel yaw rate used.
    #[default]
    Absent,
    /// The latest sample is older than `gyro_stale_us`: wheel yaw rate used.
    Stale,
    /// |rate| at or beyond `gyro_saturation_radps`: wheel yaw rate used.
    Saturated,
    /// NaN or infinite rate: wheel yaw rate used.
    NonFinite,
}

/// The estimate at the latest tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// Fused pose of G for the controller: `filter_pose` with each
    /// correction's jump spread over `output_smoothing_s`.
    pub pose: Pose,
    /// The filter's estimate of the pose of G (what a late measurement
    /// leaves exactly as an on-time one would).
    pub filter_pose: Pose,
    /// Wheel-derived linear velocity of the axle midpoint \[m/s\].
    pub v_mps: f32,
    /// Body yaw rate used in the prediction \[rad/s\] (gyro minus the
    /// estimated bias, or the wheels' when the gyro is not usable).
    pub yaw_rate_radps: f32,
}

/// Status for logs and telemetry.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorStatus {
    /// Diagonal of the covariance at the latest tick: var(x), var(y) of the
    /// axle midpoint \[m²\], var(θ) \[rad²\], var(gyro bias) \[(rad/s)²\],
    /// var(speed scale).
    pub covariance_diag: [f32; 5],
    /// Innovation of the last accepted or gated measurement
    /// \[m, m, rad\] (heading 0 without heading).
    pub last_innovation: [f32; 3],
    /// Its squared Mahalanobis distance.
    pub last_mahalanobis_sq: f32,
    /// Pose measurements used.
    pub accepted: u32,
    /// Pose measurements refused, by reason.
    pub rejected: RejectCounts,
    /// Covariance resets after `max_consecutive_outliers` gated
    /// measurements in a row (the estimate had drifted, e.g. after a long
    /// outage).
    pub resets: u32,
    /// Time from the latest accepted measurement's stamp to the latest
    /// tick \[µs\] (`u32::MAX` until the first).
    pub since_accepted_us: u32,
    /// The gyro on the latest tick.
    pub gyro: GyroState,
    /// Estimated gyro bias \[rad/s\].
    pub gyro_bias_radps: f32,
    /// Estimated speed scale: body speed / wheel-derived speed (1 = no
    /// slip; 0.8 = the body moves 20 % slower than the wheels say).
    pub speed_scale: f32,
    /// Zero-rate updates of the bias while standing still.
    pub standstill_updates: u32,
}
