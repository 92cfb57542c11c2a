//! Robot physical parameters (paper Table 1): the one place robot constants live.

use crate::error::ConfigError;

/// Physical parameters of the differential-drive robot.
///
/// Build with [`RobotParams::paper`] (Table 1) or set the fields and call
/// [`RobotParams::validate`]; every consumer ([`crate::ReducedModel::new`],
/// [`crate::Controller::new`]) validates again, so an invalid set never
/// reaches the control path.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotParams {
    /// Total mass m \[kg\].
    pub mass_kg: f32,
    /// Body yaw moment of inertia I \[kg·m²\] (the `m33` entry of M0).
    pub inertia_kgm2: f32,
    /// Moment of inertia of one driving wheel I_w \[kg·m²\].
    pub wheel_inertia_kgm2: f32,
    /// Wheel radius r \[m\].
    pub wheel_radius_m: f32,
    /// Half of the wheel track, h \[m\] (the paper's 2h is the track).
    pub half_track_m: f32,
    /// Offset d \[m\] of the centre of mass G ahead of the axle midpoint O_B.
    pub com_offset_m: f32,
}

impl RobotParams {
    /// Table 1 of the paper: m = 15 kg, r = 0.1 m, I = 2.5 kg·m²,
    /// I_w = 0.001 kg·m², 2h = 0.4 m, d = 0.05 m.
    pub const fn paper() -> Self {
        Self {
            mass_kg: 15.0,
            inertia_kgm2: 2.5,
            wheel_inertia_kgm2: 0.001,
            wheel_radius_m: 0.1,
            half_track_m: 0.2,
            com_offset_m: 0.05,
        }
    }

    /// Checks every field; returns the first problem found.
    pub fn validate(&self) -> Result<Self, ConfigError> {
        // (value, zero allowed, the error naming it), checked in order by
        // one loop (flash, see `math::all_positive`).
        let checks = [
            (self.mass_kg, false, ConfigError::NonPositiveMass),
            (self.inertia_kgm2, false, ConfigError::NonPositiveInertia),
            (
                self.wheel_inertia_kgm2,
                true,
                ConfigError::NegativeWheelInertia,
            ),
            (
                self.wheel_radius_m,
                false,
                ConfigError::NonPositiveWheelRadius,
            ),
            (self.half_track_m, false, ConfigError::NonPositiveHalfTrack),
            (self.com_offset_m, true, ConfigError::NegativeComOffset),
        ];
        for (x, zero_ok, err) in checks {
            if !(x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0))) {
                return Err(err);
            }
        }
        Ok(*self)
    }

    /// Wheel angular rates \[rad/s\] `[right, left]` that realise η (from S(q), eq. 3).
    pub fn wheel_rates_radps(&self, eta: crate::Vel2) -> [f32; 2] {
        let r = self.wheel_radius_m;
        let h = self.half_track_m;
        [
            (eta.v_mps + h * eta.omega_radps) / r,
            (eta.v_mps - h * eta.omega_radps) / r,
        ]
    }

    /// η from wheel angular rates `[right, left]` \[rad/s\] (inverse of
    /// [`Self::wheel_rates_radps`]).
    pub fn eta_from_wheel_rates(&self, rates_radps: [f32; 2]) -> crate::Vel2 {
        let r = self.wheel_radius_m;
        let h = self.half_track_m;
        crate::Vel2 {
            v_mps: 0.5 * r * (rates_radps[0] + rates_radps[1]),
            omega_radps: 0.5 * r * (rates_radps[0] - rates_radps[1]) / h,
        }
    }
}

impl Default for RobotParams {
    fn default() -> Self {
        Self::paper()
    }
}
