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
        wheel_rates(
            1.0 / self.wheel_radius_m,
            self.half_track_m,
            [eta.v_mps, eta.omega_radps],
        )
    }

    /// η from wheel angular rates `[right, left]` \[rad/s\] (inverse of
    /// [`Self::wheel_rates_radps`]).
    pub fn eta_from_wheel_rates(&self, rates_radps: [f32; 2]) -> crate::Vel2 {
        let [v_mps, omega_radps] =
            eta_from_wheel_rates(self.wheel_radius_m, self.half_track_m, rates_radps);
        crate::Vel2 { v_mps, omega_radps }
    }
}

/// The arithmetic of the model formulas below: `f32` (the controller) and
/// `f64` (the simulated plant, sim-robot) share one definition of each.
pub trait Real:
    Copy
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::Mul<Output = Self>
    + core::ops::Div<Output = Self>
    + From<f32>
{
}

impl<T> Real for T where
    T: Copy
        + core::ops::Add<Output = T>
        + core::ops::Sub<Output = T>
        + core::ops::Mul<Output = T>
        + core::ops::Div<Output = T>
        + From<f32>
{
}

/// Eq. (3), rows 4-5: the wheel rates φ̇ = \[(v + hω)/r, (v − hω)/r\]
/// \[rad/s\] of η = \[v, ω\], from 1/r \[1/m\] and h \[m\] (a product, not a
/// quotient: the plant evaluates it at every integration stage).
#[inline]
pub fn wheel_rates<T: Real>(inv_r_per_m: T, half_track_m: T, eta: [T; 2]) -> [T; 2] {
    let hw = half_track_m * eta[1];
    [(eta[0] + hw) * inv_r_per_m, (eta[0] - hw) * inv_r_per_m]
}

/// The inverse of eq. (3), rows 4-5: \[v, ω\] = \[r(φ̇_R + φ̇_L)/2,
/// r(φ̇_R − φ̇_L)/(2h)\] from wheel rates `[right, left]` (also the plant's
/// slip velocities σ of the wheel slip ϖ).
#[inline]
pub fn eta_from_wheel_rates<T: Real>(
    wheel_radius_m: T,
    half_track_m: T,
    rates_radps: [T; 2],
) -> [T; 2] {
    let half_r = T::from(0.5) * wheel_radius_m;
    [
        half_r * (rates_radps[0] + rates_radps[1]),
        half_r * (rates_radps[0] - rates_radps[1]) / half_track_m,
    ]
}

/// Diagonal of M1 = SᵀM0S (eq. 6; derivation in `book/src/explanation/paper-departures.md`, D1):
/// \[m + 2I_w/r², I + 3md² + 2I_w h²/r²\] from m, I, I_w, r, h, d.
#[inline]
pub fn m1_diagonal<T: Real>(
    mass_kg: T,
    inertia_kgm2: T,
    wheel_inertia_kgm2: T,
    wheel_radius_m: T,
    half_track_m: T,
    com_offset_m: T,
) -> [T; 2] {
    let (m, i, iw, r, h, d) = (
        mass_kg,
        inertia_kgm2,
        wheel_inertia_kgm2,
        wheel_radius_m,
        half_track_m,
        com_offset_m,
    );
    let (two, three) = (T::from(2.0), T::from(3.0));
    [
        m + two * iw / (r * r),
        i + three * m * d * d + two * iw * h * h / (r * r),
    ]
}

impl Default for RobotParams {
    fn default() -> Self {
        Self::paper()
    }
}
