//! Brushed DC gear-motor and H-bridge model: wheel torque ⇄ PWM duty.
//!
//! Per wheel, SI units, steady state within one PWM period (the electrical
//! time constant L/R is taken as short against the 1 ms control period, so
//! inductance is neglected):
//!
//! * motor speed ω_m = N·ω_w (N: gear ratio, ω_w: wheel rate \[rad/s\]);
//! * armature: V = R·i + k·ω_m (k: torque constant \[N·m/A\], equal to the
//!   back-EMF constant \[V·s/rad\] in SI units);
//! * wheel torque τ_w = η_g·N·k·i (η_g: gear efficiency, applied as a
//!   constant torque factor in both power-flow directions: a simplification);
//! * H-bridge in sign-magnitude drive with slow decay (drive/brake), so the
//!   mean armature voltage is V = ±(duty/full_scale)·V_supply. Duty 0 with
//!   the bridge enabled therefore shorts the motor (dynamic braking); a
//!   disabled bridge lets the motor coast (zero torque).
//!
//! [`MotorModel::duty_for_torque`] inverts this: V = R·τ_w/(η_g·N·k) + k·N·ω_w,
//! duty = V/V_supply, clamped to ±`max_duty_fraction` and rounded to the
//! duty resolution. [`MotorModel::torque_for_duty`] is the forward model for
//! a simulator's actuator.

use super::error::RuntimeConfigError;

/// Motor, gearbox, supply and PWM constants (one motor type on both wheels).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorParams {
    /// Torque constant k \[N·m/A\] (= back-EMF constant \[V·s/rad\]), motor side.
    pub torque_constant_nm_per_a: f32,
    /// Armature (winding) resistance R \[Ω\], including the bridge's on-resistance.
    pub winding_resistance_ohm: f32,
    /// Gear ratio N = motor revolutions per wheel revolution (> 0).
    pub gear_ratio: f32,
    /// Gearbox efficiency η_g in (0, 1].
    pub gear_efficiency: f32,
    /// Supply (battery) voltage V_supply \[V\].
    pub supply_voltage_v: f32,
    /// Largest duty magnitude allowed, as a fraction of full scale, in (0, 1]
    /// (bootstrap gate drivers usually need < 1).
    pub max_duty_fraction: f32,
    /// Duty counts at 100 % (PWM timer's maximum duty, i.e. its resolution).
    pub duty_full_scale: u16,
}

impl MotorParams {
    /// Example 24 V gear-motor sized for the paper's 15 kg robot: k = 0.05 N·m/A,
    /// R = 0.5 Ω, N = 12, η_g = 0.85, 24 V, duty ≤ 95 % of 4800 counts
    /// (a 96 MHz timer at 20 kHz). Wheel no-load speed
    /// V/(k·N) = 40 rad/s (4 m/s at r = 0.1 m); wheel stall torque
    /// η_g·N·k·V/R = 24.5 N·m.
    pub const EXAMPLE: Self = Self {
        torque_constant_nm_per_a: 0.05,
        winding_resistance_ohm: 0.5,
        gear_ratio: 12.0,
        gear_efficiency: 0.85,
        supply_voltage_v: 24.0,
        max_duty_fraction: 0.95,
        duty_full_scale: 4800,
    };

    /// Checks every field; returns the first problem.
    pub fn validate(self) -> Result<Self, RuntimeConfigError> {
        // (value, upper bound, the error naming it): 0 < value <= bound,
        // checked in order by one loop (flash, see `math::all_positive`).
        use RuntimeConfigError as E;
        let checks = [
            (
                self.torque_constant_nm_per_a,
                f32::MAX,
                E::NonPositiveTorqueConstant,
            ),
            (
                self.winding_resistance_ohm,
                f32::MAX,
                E::NonPositiveResistance,
            ),
            (self.gear_ratio, f32::MAX, E::NonPositiveGearRatio),
            (self.gear_efficiency, 1.0, E::InvalidGearEfficiency),
            (self.supply_voltage_v, f32::MAX, E::NonPositiveSupplyVoltage),
            (self.max_duty_fraction, 1.0, E::InvalidMaxDuty),
        ];
        for (x, hi, err) in checks {
            if !(x > 0.0 && x <= hi) {
                return Err(err);
            }
        }
        if self.duty_full_scale == 0 {
            return Err(RuntimeConfigError::ZeroDutyResolution);
        }
        Ok(self)
    }
}

/// One wheel's PWM command: duty magnitude in counts and direction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DutyCommand {
    /// Duty magnitude \[counts\], 0..=`duty_full_scale`.
    pub duty: u16,
    /// Drive the motor backwards (direction pin state).
    pub reverse: bool,
}

impl DutyCommand {
    /// Zero duty, forward.
    pub const ZERO: Self = Self {
        duty: 0,
        reverse: false,
    };

    /// Signed duty in counts (negative when `reverse`).
    pub const fn signed(self) -> i32 {
        if self.reverse {
            -(self.duty as i32)
        } else {
            self.duty as i32
        }
    }
}

/// Result of a torque -> duty conversion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DutyRequest {
    /// The command to write.
    pub command: DutyCommand,
    /// Unclamped duty the torque needed, as a signed fraction of full scale.
    pub requested_fraction: f32,
    /// True when the request was clamped to `max_duty_fraction`
    /// (the wheel gets less torque than asked).
    pub saturated: bool,
}

/// The validated motor model with its derived constants.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorModel {
    params: MotorParams,
    /// η_g·N·k: wheel torque per ampere \[N·m/A\].
    torque_per_amp: f32,
    /// k·N: back-EMF per wheel rate \[V·s/rad\].
    emf_per_wheel_rate: f32,
    /// Largest duty magnitude \[counts\].
    max_duty: u16,
    /// Back-EMF damping b = η_g·N²·k²/R \[N·m per rad/s\].
    emf_damping_nms_per_rad: f32,
    /// Wheel torque of half a duty count at a given rate \[N·m\]: the
    /// rounding error of [`Self::duty_for_torque`].
    half_count_torque_nm: f32,
}

impl MotorModel {
    /// Model from validated parameters.
    pub fn new(params: MotorParams) -> Result<Self, RuntimeConfigError> {
        let p = params.validate()?;
        let max = p.max_duty_fraction * p.duty_full_scale as f32;
        // Floor (+ a little for exact products like 0.5·4800), never above full scale.
        let max_duty = ((max + 1e-3) as u32).min(p.duty_full_scale as u32) as u16;
        let torque_per_amp = p.gear_efficiency * p.gear_ratio * p.torque_constant_nm_per_a;
        let emf_per_wheel_rate = p.torque_constant_nm_per_a * p.gear_ratio;
        let r = p.winding_resistance_ohm;
        Ok(Self {
            params: p,
            torque_per_amp,
            emf_per_wheel_rate,
            max_duty,
            emf_damping_nms_per_rad: torque_per_amp * emf_per_wheel_rate / r,
            half_count_torque_nm: 0.5 * torque_per_amp * p.supply_voltage_v
                / (p.duty_full_scale as f32 * r),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &MotorParams {
        &self.params
    }

    /// Largest duty magnitude the model will command \[counts\].
    pub fn max_duty(&self) -> u16 {
        self.max_duty
    }

    /// Back-EMF damping at the wheel b = η_g·N²·k²/R \[N·m per rad/s\]: at a
    /// fixed voltage the wheel torque falls by b per rad/s of wheel rate.
    pub fn back_emf_damping_nms_per_rad(&self) -> f32 {
        self.emf_damping_nms_per_rad
    }

    /// The largest torque to command so that the torque *delivered* (the
    /// armature current) stays within `limit_nm` while the true wheel rate
    /// may differ from the estimate the duty is computed at by up to
    /// `rate_uncertainty_radps` \[N·m\], never negative:
    ///
    /// limit − b·δ − (half a duty count's torque).
    ///
    /// The delivered torque at the true rate φ̇ is the commanded one plus
    /// b·(φ̇_est − φ̇) (the back-EMF term of [`Self::voltage_for_torque`]
    /// evaluated at the estimate), and the duty's rounding adds at most half
    /// a count (D176).
    #[inline]
    pub fn torque_bound_nm(&self, limit_nm: f32, rate_uncertainty_radps: f32) -> f32 {
        let b = limit_nm
            - self.emf_damping_nms_per_rad * rate_uncertainty_radps
            - self.half_count_torque_nm;
        if b > 0.0 {
            b
        } else {
            0.0
        }
    }

    /// Mean armature voltage \[V\] that produces `torque_nm` at the wheel
    /// while the wheel turns at `wheel_rate_radps`.
    pub fn voltage_for_torque(&self, torque_nm: f32, wheel_rate_radps: f32) -> f32 {
        let current = torque_nm / self.torque_per_amp;
        self.params.winding_resistance_ohm * current + self.emf_per_wheel_rate * wheel_rate_radps
    }

    /// Wheel torque \[N·m\] from a mean armature voltage `voltage_v` at
    /// `wheel_rate_radps` (inverse of [`Self::voltage_for_torque`]).
    pub fn torque_for_voltage(&self, voltage_v: f32, wheel_rate_radps: f32) -> f32 {
        let current = (voltage_v - self.emf_per_wheel_rate * wheel_rate_radps)
            / self.params.winding_resistance_ohm;
        self.torque_per_amp * current
    }

    /// Duty command for `torque_nm` at the wheel at `wheel_rate_radps`:
    /// rounded to the nearest count and clamped to the duty limit.
    /// Non-finite inputs give zero duty (flagged as saturated).
    pub fn duty_for_torque(&self, torque_nm: f32, wheel_rate_radps: f32) -> DutyRequest {
        let frac =
            self.voltage_for_torque(torque_nm, wheel_rate_radps) / self.params.supply_voltage_v;
        if !frac.is_finite() {
            return DutyRequest {
                command: DutyCommand::ZERO,
                requested_fraction: 0.0,
                saturated: true,
            };
        }
        let counts = frac.abs() * self.params.duty_full_scale as f32 + 0.5;
        let saturated = counts > self.max_duty as f32 + 0.5;
        // `as` saturates; the min keeps the limit.
        let duty = (counts as u32).min(self.max_duty as u32) as u16;
        DutyRequest {
            command: DutyCommand {
                duty,
                reverse: frac < 0.0 && duty > 0,
            },
            requested_fraction: frac,
            saturated,
        }
    }

    /// Mean armature voltage \[V\] a duty command applies (bridge enabled).
    pub fn voltage_for_duty(&self, cmd: DutyCommand) -> f32 {
        let duty = cmd.duty.min(self.params.duty_full_scale) as f32;
        let v = duty / self.params.duty_full_scale as f32 * self.params.supply_voltage_v;
        if cmd.reverse {
            -v
        } else {
            v
        }
    }

    /// Wheel torque \[N·m\] a duty command produces at `wheel_rate_radps`
    /// with the bridge enabled (the simulator's actuator model). A disabled
    /// bridge produces zero torque (coasting).
    pub fn torque_for_duty(&self, cmd: DutyCommand, wheel_rate_radps: f32) -> f32 {
        self.torque_for_voltage(self.voltage_for_duty(cmd), wheel_rate_radps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> MotorModel {
        MotorModel::new(MotorParams::EXAMPLE).unwrap()
    }

    /// Stall (ω = 0): V = R·τ/(η·N·k). 2 N·m -> i = 2/(0.85·12·0.05) = 3.9216 A,
    /// V = 1.9608 V, duty = V/24·4800 = 392.16 -> 392 counts.
    #[test]
    fn stall_torque_to_duty_analytic() {
        let m = model();
        let r = m.duty_for_torque(2.0, 0.0);
        let i = 2.0 / (0.85 * 12.0 * 0.05);
        let v = 0.5 * i;
        assert!((m.voltage_for_torque(2.0, 0.0) - v).abs() < 1e-5);
        assert_eq!(r.command.duty, libm::roundf(v / 24.0 * 4800.0) as u16);
        assert!(!r.command.reverse && !r.saturated);
        let back = m.duty_for_torque(-2.0, 0.0);
        assert_eq!(back.command.duty, r.command.duty);
        assert!(back.command.reverse);
    }

    /// Zero torque at speed needs exactly the back-EMF voltage k·N·ω:
    /// 20 rad/s -> 0.05·12·20 = 12 V = half of 24 V -> 2400 counts.
    #[test]
    fn zero_torque_needs_back_emf() {
        let m = model();
        let r = m.duty_for_torque(0.0, 20.0);
        assert_eq!(r.command.duty, 2400);
        assert!(!r.command.reverse);
        // Braking while driving forward slowly still needs forward voltage
        // when the EMF exceeds the resistive drop: τ = −1 N·m at 20 rad/s:
        // V = 12 − 0.5·1/0.51 = 11.0196 V.
        let b = m.duty_for_torque(-1.0, 20.0);
        let v = 12.0 - 0.5 / 0.51;
        assert_eq!(b.command.duty, libm::roundf(v / 24.0 * 4800.0) as u16);
        assert!(!b.command.reverse);
    }

    /// Round trip: torque -> duty -> torque recovers the request within one
    /// duty count's worth of torque, η_g·N·k·(V_s/full_scale)/R.
    #[test]
    fn forward_model_inverts_within_quantization() {
        let m = model();
        let lsb_torque = 0.85 * 12.0 * 0.05 * (24.0 / 4800.0) / 0.5;
        for i in -40..=40 {
            let tau = i as f32 * 0.25;
            for w in [-30.0f32, -5.0, 0.0, 3.3, 25.0] {
                let r = m.duty_for_torque(tau, w);
                if r.saturated {
                    continue;
                }
                let back = m.torque_for_duty(r.command, w);
                assert!(
                    (back - tau).abs() <= 0.5 * lsb_torque + 1e-4,
                    "τ {tau} ω {w}: {back}"
                );
            }
        }
    }

    /// Beyond the supply the duty clamps at ⌊0.95·4800⌋ = 4560 and is flagged.
    #[test]
    fn duty_saturates_at_limit() {
        let m = model();
        assert_eq!(m.max_duty(), 4560);
        let r = m.duty_for_torque(50.0, 0.0);
        assert!(r.saturated);
        assert_eq!(r.command.duty, 4560);
        let r = m.duty_for_torque(-50.0, -30.0);
        assert!(r.saturated && r.command.reverse && r.command.duty == 4560);
        // Stall torque at full voltage: η·N·k·V/R = 24.48 N·m.
        let full = DutyCommand {
            duty: 4800,
            reverse: false,
        };
        assert!((m.torque_for_duty(full, 0.0) - 24.48).abs() < 1e-3);
        // No-load speed V/(k·N) = 40 rad/s: zero torque there.
        assert!(m.torque_for_duty(full, 40.0).abs() < 1e-4);
    }

    #[test]
    fn non_finite_gives_zero_duty() {
        let m = model();
        for (t, w) in [(f32::NAN, 0.0), (0.0, f32::INFINITY), (f32::INFINITY, 1.0)] {
            let r = m.duty_for_torque(t, w);
            assert_eq!(r.command, DutyCommand::ZERO);
        }
    }

    #[test]
    fn invalid_params_rejected() {
        let p = MotorParams::EXAMPLE;
        let cases = [
            (
                MotorParams {
                    torque_constant_nm_per_a: 0.0,
                    ..p
                },
                RuntimeConfigError::NonPositiveTorqueConstant,
            ),
            (
                MotorParams {
                    winding_resistance_ohm: f32::NAN,
                    ..p
                },
                RuntimeConfigError::NonPositiveResistance,
            ),
            (
                MotorParams {
                    gear_ratio: -1.0,
                    ..p
                },
                RuntimeConfigError::NonPositiveGearRatio,
            ),
            (
                MotorParams {
                    gear_efficiency: 1.5,
                    ..p
                },
                RuntimeConfigError::InvalidGearEfficiency,
            ),
            (
                MotorParams {
                    supply_voltage_v: 0.0,
                    ..p
                },
                RuntimeConfigError::NonPositiveSupplyVoltage,
            ),
            (
                MotorParams {
                    max_duty_fraction: 0.0,
                    ..p
                },
                RuntimeConfigError::InvalidMaxDuty,
            ),
            (
                MotorParams {
                    duty_full_scale: 0,
                    ..p
                },
                RuntimeConfigError::ZeroDutyResolution,
            ),
        ];
        for (bad, err) in cases {
            assert_eq!(MotorModel::new(bad).err(), Some(err));
        }
    }
}
