//! The estimate's uncertainty in the shape ROS's `/odom` reports it
//! (`base_link` = the axle midpoint O_B, the filter's own state), computed
//! on demand: only when a telemetry frame carrying it is sent, never in the
//! control tick (book/src/explanation/decisions.md D155, D156).

use super::{ix, PoseEstimator};
use crate::estimator::GyroState;

/// Pose covariance of O_B and twist variances of the latest tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OdomCovariance {
    /// Upper triangle of the covariance of (x, y, θ) of the axle midpoint,
    /// row by row: xx \[m²\], xy \[m²\], xθ \[m·rad\], yy \[m²\], yθ
    /// \[m·rad\], θθ \[rad²\].
    pub pose: [f32; 6],
    /// Variance of the forward speed v \[(m/s)²\] and of the yaw rate ω
    /// \[(rad/s)²\].
    pub twist: [f32; 2],
}

impl<const H: usize> PoseEstimator<H> {
    /// The pose covariance of O_B (the filter's x, y, θ block) and the
    /// twist variances at the latest tick.
    ///
    /// The twist: v = k·v_wheel, so var(v) = v²·(var(k) + slip²) + σ_v²;
    /// ω = gyro − bias with the gyro, var(ω) = var(bias) + σ_g², else the
    /// wheels' ω, var(ω) = ω²·slip² + σ_w². The white-noise densities
    /// (`speed_noise_mps_per_sqrt_hz`, `gyro_noise_density`,
    /// `wheel_yaw_noise`) are taken over 1 Hz of bandwidth: the variance
    /// of a rate averaged over 1 s (D156).
    pub fn odom_covariance(&self) -> OdomCovariance {
        let p = &self.filter.p;
        let c = &self.cfg;
        let v = self.estimate.v_mps;
        let w = self.estimate.yaw_rate_radps;
        let slip_sq = c.slip_fraction * c.slip_fraction;
        let var_v = v * v * (p[ix(4, 4)] + slip_sq)
            + c.speed_noise_mps_per_sqrt_hz * c.speed_noise_mps_per_sqrt_hz;
        let var_w = if self.status.gyro == GyroState::Ok {
            p[ix(3, 3)] + c.gyro_noise_density * c.gyro_noise_density
        } else {
            w * w * slip_sq + c.wheel_yaw_noise * c.wheel_yaw_noise
        };
        OdomCovariance {
            pose: [
                p[ix(0, 0)],
                p[ix(0, 1)],
                p[ix(0, 2)],
                p[ix(1, 1)],
                p[ix(1, 2)],
                p[ix(2, 2)],
            ],
            twist: [var_v, var_w],
        }
    }
}
