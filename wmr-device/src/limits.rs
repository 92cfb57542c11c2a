//! Physical limits, in one place with their units (D41): the robot's top
//! speed, yaw rate and wheel torque derived from its configuration, the
//! range of every writable parameter, of the built-in references'
//! geometry, and the bound on the length of a controlled stop.
//!
//! A value that passes these checks is not only finite but possible: no
//! gain that makes the loop faster than the control rate can follow, no
//! reference faster than the motors can drive, no controlled stop that
//! takes longer than [`RobotLimits::stop_bound_s`].

use controller_core::runtime::bounds::max_gain_rate_per_s;
pub use controller_core::runtime::bounds::{
    MAX_ACCEL_MPS2, MAX_ANG_ACCEL_RADPS2, MAX_SPEED_MPS, MAX_YAW_RATE_RADPS, MIN_ACCEL_MPS2,
    MIN_ANG_ACCEL_RADPS2, MIN_BRAKE_DECEL_MPS2, MIN_COMMAND_LIMIT, MIN_GAIN, MIN_TORQUE_NM,
};
use controller_core::runtime::param_table::{Access, Param, RangeError, RobotBounds};
use controller_core::runtime::RuntimeConfig;
use wmr_protocol::ParamId;

/// Smallest and largest length of a built-in shape (radius, amplitude)
/// \[m\].
pub const SHAPE_LENGTH_M: (f32, f32) = (0.01, 1000.0);
/// Largest |coordinate| of a start pose or an external pose \[m\] (f32
/// resolves 0.1 mm there).
pub const MAX_POSITION_M: f32 = 1000.0;
/// A controlled stop ends when both wheels' measured ground speeds
/// (r·φ̇, from the windowed encoder rates) have stayed at or below this
/// \[m/s\], or [`REST_QUANTA`] of the encoder's rate resolution when
/// that is coarser ([`RobotLimits::rest_speed_mps`]), for [`REST_HOLD_S`]
/// (issue 31: "stopped" means at rest, not the braking reference at rest).
pub const REST_SPEED_MPS: f32 = 0.02;
/// The rest threshold in quanta of the windowed rate estimate: a wheel
/// held in place by the controller may read ±1 count per window (a
/// 1,320-count encoder over an 8-tick window reads 0.6 rad/s steps, 2 cm/s
/// on a 3.3 cm wheel), which is no motion.
pub const REST_QUANTA: f32 = 1.5;
/// How long both wheels must stay below [`REST_SPEED_MPS`] for a
/// controlled stop to end \[s\].
pub const REST_HOLD_S: f32 = 0.1;
/// The time a controlled stop may hold its braking reference at rest,
/// waiting for the robot to come to rest, before the stop's bound cuts
/// the motors whatever the robot does \[s\].
pub const REST_SETTLE_MAX_S: f32 = 2.0;

/// A quantity of a reference the robot's limits bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Quantity {
    /// Speed |v| \[m/s\] against [`RobotLimits::top_speed_mps`].
    SpeedMps,
    /// Yaw rate |ω| \[rad/s\] against [`RobotLimits::top_yaw_rate_radps`].
    YawRateRadps,
    /// Acceleration \[m/s²\] against [`RobotLimits::top_accel_mps2`].
    AccelMps2,
}

impl Quantity {
    /// Its name and unit, for messages.
    pub fn describe(self) -> (&'static str, &'static str) {
        match self {
            Quantity::SpeedMps => ("speed", "m/s"),
            Quantity::YawRateRadps => ("yaw rate", "rad/s"),
            Quantity::AccelMps2 => ("acceleration", "m/s²"),
        }
    }
}

/// A reference beyond one of the robot's limits: what, how much, and the
/// limit (`value` may be NaN).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LimitExceeded {
    /// The quantity beyond its limit.
    pub quantity: Quantity,
    /// Its value (the peak found), in its unit.
    pub value: f32,
    /// The limit, in the same unit.
    pub limit: f32,
}

/// The robot's physical limits, derived from its runtime configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotLimits {
    /// No-load ground speed V/(k·N)·r \[m/s\] (at most [`MAX_SPEED_MPS`]).
    pub top_speed_mps: f32,
    /// Top speed / half track \[rad/s\] (turning on the spot at top wheel
    /// speed; at most [`MAX_YAW_RATE_RADPS`]).
    pub top_yaw_rate_radps: f32,
    /// Wheel stall torque η·N·k·V/R \[N·m\].
    pub stall_torque_nm: f32,
    /// Largest acceleration of the robot's path 2·τ_stall/(r·m_eff) with
    /// m_eff = m + 2·I_w/r² \[m/s²\] (both wheels at the stall torque; the
    /// reduced model's (6) linear row). A reference that asks more cannot
    /// be followed by any motor of this robot.
    pub top_accel_mps2: f32,
    /// Fastest closed-loop rate a gain may ask, half the control rate
    /// 1/(2·period) \[1/s\].
    pub max_rate_per_s: f32,
    /// Control period \[s\].
    pub period_s: f32,
    /// A wheel at or below this measured ground speed is at rest \[m/s\]:
    /// [`REST_SPEED_MPS`], or [`REST_QUANTA`] rate quanta of the encoder
    /// times the wheel radius when coarser.
    pub rest_speed_mps: f32,
}

impl RobotLimits {
    /// The limits of no particular robot: [`MAX_SPEED_MPS`],
    /// [`MAX_YAW_RATE_RADPS`], an unbounded torque, a 1 kHz loop.
    pub const ABSOLUTE: Self = Self {
        top_speed_mps: MAX_SPEED_MPS,
        top_yaw_rate_radps: MAX_YAW_RATE_RADPS,
        stall_torque_nm: f32::MAX,
        top_accel_mps2: f32::MAX,
        max_rate_per_s: 500.0,
        period_s: 1e-3,
        rest_speed_mps: REST_SPEED_MPS,
    };

    /// The limits of the robot `rt` describes (a validated configuration).
    pub fn of(rt: &RuntimeConfig) -> Self {
        let m = &rt.motor;
        let r = &rt.controller.robot;
        let wheel_radps = m.supply_voltage_v / (m.torque_constant_nm_per_a * m.gear_ratio);
        let stall_torque_nm =
            m.gear_efficiency * m.gear_ratio * m.torque_constant_nm_per_a * m.supply_voltage_v
                / m.winding_resistance_ohm;
        // The parameter table's bounds, by the formulas the robot file
        // uses (`RobotBounds::of`).
        let b = RobotBounds::of(
            stall_torque_nm,
            wheel_radps * r.wheel_radius_m,
            r.half_track_m,
            rt.controller.period_s,
        );
        let top_speed_mps = b.top_speed_mps;
        let rw = r.wheel_radius_m;
        let m_eff = r.mass_kg + 2.0 * r.wheel_inertia_kgm2 / (rw * rw);
        Self {
            top_speed_mps,
            top_yaw_rate_radps: b.top_yaw_rate_radps,
            stall_torque_nm,
            top_accel_mps2: 2.0 * stall_torque_nm / (rw * m_eff),
            max_rate_per_s: max_gain_rate_per_s(rt.controller.period_s),
            period_s: rt.controller.period_s,
            rest_speed_mps: REST_SPEED_MPS.max(
                REST_QUANTA
                    * rt.encoder.rate_quantum_radps(rt.controller.period_s)
                    * r.wheel_radius_m,
            ),
        }
    }

    /// The numbers of the parameter table's robot-dependent bounds
    /// (controller-core `param_table`).
    pub fn bounds(&self) -> RobotBounds {
        RobotBounds {
            stall_torque_nm: self.stall_torque_nm,
            top_speed_mps: self.top_speed_mps,
            top_yaw_rate_radps: self.top_yaw_rate_radps,
            period_s: self.period_s,
        }
    }

    /// The physical range \[min, max\] of a writable parameter, in its
    /// unit, from the parameter table (controller-core `param_table`);
    /// `None` for the integer and read-only ones (checked apart).
    ///
    /// The gains bound the closed loop's rates by half the control rate
    /// `R`: k_x, k_θ, k_s ≤ R \[1/s\]; the lateral mode of eq. (14)
    /// linearised about the reference, ë_y + k_θ·ė_y + k_y·v²·e_y = 0, has
    /// the rate v·√k_y ≤ R at top speed, so k_y ≤ (R/v_top)² \[rad/m²\].
    pub fn range(&self, id: ParamId) -> Option<(f32, f32)> {
        let p = id.param();
        if p.integer || p.access == Access::ReadOnly {
            return None;
        }
        Some(p.range(&self.bounds()))
    }

    /// Checks `value` of parameter `p` against its range for this robot:
    /// the refusal names the field, the value and the limit.
    pub fn check(&self, p: &Param, value: f32) -> Result<(), RangeError> {
        p.check(value, &self.bounds())
    }

    /// Checks one reference sample against the robot's limits: |v| within
    /// the top speed, |ω| within the top yaw rate and, unless `braking`
    /// (the controlled stop decelerates at the link's braking settings,
    /// toward rest), |v̇| within [`Self::top_accel_mps2`]. A relative
    /// tolerance of 1e-3 covers f32 rounding. The first quantity beyond
    /// its limit, with its value and the limit; NaN is beyond every limit.
    pub fn check_sample(
        &self,
        r: &controller_core::trajectory::RefSample,
        braking: bool,
    ) -> Result<(), LimitExceeded> {
        let within = |x: f32, lim: f32| x.abs() <= lim * (1.0 + 1e-3);
        let q = if !within(r.v_mps, self.top_speed_mps) {
            (Quantity::SpeedMps, r.v_mps, self.top_speed_mps)
        } else if !within(r.omega_radps, self.top_yaw_rate_radps) {
            (
                Quantity::YawRateRadps,
                r.omega_radps,
                self.top_yaw_rate_radps,
            )
        } else if !braking && !within(r.v_dot_mps2, self.top_accel_mps2) {
            (Quantity::AccelMps2, r.v_dot_mps2, self.top_accel_mps2)
        } else {
            return Ok(());
        };
        Err(LimitExceeded {
            quantity: q.0,
            value: q.1,
            limit: q.2,
        })
    }

    /// `value` lies in the range of `id` (false for NaN; the integer and
    /// read-only ones are checked apart).
    pub fn allows(&self, id: ParamId, value: f32) -> bool {
        self.range(id).is_none() || self.check(id.param(), value).is_ok()
    }

    /// The longest braking ramp with deceleration `decel_mps2` and angular
    /// acceleration `ang_accel_radps2` \[s\]: from top speed and top yaw
    /// rate, v and ω falling together. With the least values allowed
    /// ([`MIN_BRAKE_DECEL_MPS2`], [`MIN_ANG_ACCEL_RADPS2`]) and the paper
    /// robot (4 m/s, 20 rad/s) it is 20 s; with the defaults (1 m/s²,
    /// 3 rad/s²) 6.7 s.
    pub fn brake_ramp_bound_s(&self, decel_mps2: f32, ang_accel_radps2: f32) -> f32 {
        let t_v = self.top_speed_mps / decel_mps2.max(MIN_BRAKE_DECEL_MPS2);
        let t_w = self.top_yaw_rate_radps / ang_accel_radps2.max(MIN_ANG_ACCEL_RADPS2);
        t_v.max(t_w)
    }

    /// The longest controlled stop \[s\]: the longest braking ramp
    /// ([`Self::brake_ramp_bound_s`]) and then at most
    /// [`REST_SETTLE_MAX_S`] holding the reference at rest until the robot
    /// is at rest. After it the device cuts the motors whatever the robot
    /// does (paper robot, default braking: 6.7 + 2 = 8.7 s).
    pub fn stop_bound_s(&self, decel_mps2: f32, ang_accel_radps2: f32) -> f32 {
        self.brake_ramp_bound_s(decel_mps2, ang_accel_radps2) + REST_SETTLE_MAX_S
    }

    /// [`Self::stop_bound_s`] in ticks (rounded up, plus the tick that
    /// disarms).
    pub fn stop_bound_ticks(&self, decel_mps2: f32, ang_accel_radps2: f32) -> u32 {
        let t = self.stop_bound_s(decel_mps2, ang_accel_radps2);
        ((t / self.period_s) as u32).saturating_add(2)
    }
}
