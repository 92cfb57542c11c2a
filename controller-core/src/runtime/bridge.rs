//! How the H-bridge of each motor is wired: the three common input schemes,
//! the PWM frequency and what an idle (zero-duty, enabled) bridge does.
//!
//! The runtime itself only produces a [`DutyCommand`](super::DutyCommand)
//! (duty magnitude and direction) per wheel; a board's
//! [`MotorDriver`](super::MotorDriver) turns it into pin levels according to
//! the [`BridgeMode`]. Every mode drives the armature in sign-magnitude with
//! slow decay (drive/brake), so the mean armature voltage is
//! ±(duty/full scale)·V_supply as [`MotorModel`](super::MotorModel) assumes.

use super::error::RuntimeConfigError;

/// Input scheme of one motor's H-bridge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BridgeMode {
    /// One PWM input (duty) and one direction input per motor, plus a shared
    /// enable (e.g. Cytron MD10C, Pololu G2, DRV8801 in PWM/PHASE mode).
    #[default]
    PwmDir,
    /// Two PWM inputs per motor, IN1/IN2 (e.g. DRV8871, BTS7960 RPWM/LPWM).
    /// Forward: IN1 high, IN2 PWM low for the duty (drive/brake, slow decay);
    /// reverse mirrored.
    TwoPwm,
    /// One PWM input and two direction inputs per motor, plus a shared
    /// standby (e.g. TB6612FNG PWMx/xIN1/xIN2/STBY, L298N ENx/INx).
    PwmIn1In2,
}

/// What an enabled bridge does at zero duty (the runtime's zero-torque
/// command while running). Disabled (not running, stopped, fault) is always
/// coast with every motor line low.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum IdleMode {
    /// Short the armature (both low-side or both high-side switches on):
    /// dynamic braking, what the motor model's duty 0 means.
    #[default]
    Brake,
    /// All switches off: the motor freewheels.
    Coast,
}

/// Bridge wiring and PWM frequency, one for both motors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BridgeParams {
    /// Input scheme.
    pub mode: BridgeMode,
    /// PWM frequency \[Hz\], within [`Self::PWM_FREQUENCY_RANGE_HZ`].
    pub pwm_frequency_hz: u32,
    /// Zero-duty behaviour while enabled.
    pub idle: IdleMode,
}

impl BridgeParams {
    /// PWM frequencies accepted \[Hz\]: from 1 kHz (audible, but what some
    /// L298N boards need) to 100 kHz (above it switching losses dominate and
    /// a 16-bit timer at ~100 MHz keeps < 1,000 duty levels).
    pub const PWM_FREQUENCY_RANGE_HZ: (u32, u32) = (1_000, 100_000);

    /// Today's wiring: PWM + DIR at 20 kHz, braking at zero duty.
    pub const EXAMPLE: Self = Self {
        mode: BridgeMode::PwmDir,
        pwm_frequency_hz: 20_000,
        idle: IdleMode::Brake,
    };

    /// Checks the frequency.
    pub fn validate(self) -> Result<Self, RuntimeConfigError> {
        let (lo, hi) = Self::PWM_FREQUENCY_RANGE_HZ;
        if (lo..=hi).contains(&self.pwm_frequency_hz) {
            Ok(self)
        } else {
            Err(RuntimeConfigError::InvalidPwmFrequency)
        }
    }

    /// Duty counts at 100 % for a timer clocked at `timer_clock_hz` in
    /// edge-aligned up-counting mode (ARR + 1 = clock / frequency), or
    /// `None` when that does not fit a 16-bit timer or gives fewer than 100
    /// levels.
    pub fn duty_full_scale(&self, timer_clock_hz: u32) -> Option<u16> {
        let levels = timer_clock_hz / self.pwm_frequency_hz.max(1);
        if (100..=u16::MAX as u32).contains(&levels) {
            Some(levels as u16)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn example_is_todays_20_khz_pwm_dir() {
        let b = BridgeParams::EXAMPLE.validate().unwrap();
        assert_eq!(b.mode, BridgeMode::PwmDir);
        // 96 MHz / 20 kHz = 4,800: MotorParams::EXAMPLE's duty resolution.
        assert_eq!(
            b.duty_full_scale(96_000_000),
            Some(super::super::MotorParams::EXAMPLE.duty_full_scale)
        );
    }

    #[test]
    fn frequency_out_of_range_is_refused() {
        for f in [0, 999, 100_001, u32::MAX] {
            let b = BridgeParams {
                pwm_frequency_hz: f,
                ..BridgeParams::EXAMPLE
            };
            assert_eq!(b.validate(), Err(RuntimeConfigError::InvalidPwmFrequency));
        }
    }

    #[test]
    fn duty_levels_must_fit_a_16_bit_timer() {
        let b = |f| BridgeParams {
            pwm_frequency_hz: f,
            ..BridgeParams::EXAMPLE
        };
        // 168 MHz / 1 kHz = 168,000 > 65,535: does not fit.
        assert_eq!(b(1_000).duty_full_scale(168_000_000), None);
        // 1 MHz / 20 kHz = 50 levels: too coarse.
        assert_eq!(b(20_000).duty_full_scale(1_000_000), None);
        assert_eq!(b(25_000).duty_full_scale(84_000_000), Some(3_360));
    }
}
