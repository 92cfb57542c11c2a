//! Simulated sensors and actuators in raw units, as the firmware's board
//! sees them: 16-bit quadrature counters and an H-bridge taking integer duty
//! and a direction. They implement controller-core's runtime traits, so the
//! runtime runs against them unchanged (only the registers are simulated).

use crate::plant::Drive;
use controller_core::runtime::{
    DutyCommand, EncoderParams, MotorDriver, MotorModel, WheelEncoders,
};

/// Two quadrature encoders: the wheel angles quantised to counts
/// (floor), negated on a mirrored mounting, wrapping like 16-bit timers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimEncoders {
    counts_per_rad: f64,
    inverted: [bool; 2],
    angle_rad: [f64; 2],
    /// Per wheel: the count a dead encoder is stuck at.
    frozen: [Option<u16>; 2],
}

impl SimEncoders {
    /// Encoders of this resolution and mounting, both wheels at angle 0.
    pub fn new(params: &EncoderParams) -> Self {
        Self {
            counts_per_rad: params.counts_per_wheel_rev as f64 / core::f64::consts::TAU,
            inverted: params.inverted,
            angle_rad: [0.0; 2],
            frozen: [None; 2],
        }
    }

    /// The wheels' true angles φ `[right, left]` \[rad\].
    pub fn set_angles(&mut self, angle_rad: [f64; 2]) {
        self.angle_rad = angle_rad;
    }

    /// Fault injection: the encoder of `wheel` (0 = right, 1 = left) stops
    /// counting at its current reading (a broken wire).
    pub fn kill(&mut self, wheel: usize) {
        if wheel < 2 && self.frozen[wheel].is_none() {
            self.frozen[wheel] = Some(self.raw(wheel));
        }
    }

    fn raw(&self, i: usize) -> u16 {
        let c = libm::floor(self.angle_rad[i] * self.counts_per_rad) as i64;
        let c = if self.inverted[i] { -c } else { c };
        c as u16 // two's complement wrap, like a 16-bit timer
    }
}

impl WheelEncoders for SimEncoders {
    fn counts(&mut self) -> [u16; 2] {
        core::array::from_fn(|i| self.frozen[i].unwrap_or_else(|| self.raw(i)))
    }
}

/// The H-bridge: remembers what the runtime last wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SimDriver {
    /// Duty and direction `[right, left]` as written (after the runtime's
    /// mirrored-motor flip).
    pub duty: [DutyCommand; 2],
    /// Bridge enabled.
    pub enabled: bool,
}

impl MotorDriver for SimDriver {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        self.duty = cmd;
        self.enabled = true;
    }
    fn disable(&mut self) {
        self.duty = [DutyCommand::ZERO; 2];
        self.enabled = false;
    }
}

/// The motors behind a [`SimDriver`]: duty held over the period, torque
/// from the DC-motor model at each instant's wheel rate (back-EMF).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorDrive {
    /// The motor model (the runtime's own, run forward).
    pub model: MotorModel,
    /// What the bridge outputs.
    pub bridge: SimDriver,
    /// Per wheel: the motor is mounted mirrored (turns opposite to its wheel).
    pub inverted: [bool; 2],
}

impl Drive for MotorDrive {
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        if !self.bridge.enabled {
            return [0.0; 2];
        }
        core::array::from_fn(|i| {
            let sign = if self.inverted[i] { -1.0 } else { 1.0 };
            let motor_rate = (sign * wheel_rates_radps[i]) as f32;
            sign * self.model.torque_for_duty(self.bridge.duty[i], motor_rate) as f64
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mirrored encoder counts down while its wheel turns forward, and the
    /// 16-bit reading wraps: the wrap-safe delta recovers the true change.
    #[test]
    fn mirrored_encoder_counts_down_and_wraps() {
        let p = EncoderParams {
            counts_per_wheel_rev: 1000.0,
            inverted: [false, true],
            speed_window_ticks: 1,
            ..EncoderParams::EXAMPLE
        };
        let mut e = SimEncoders::new(&p);
        // 70 revolutions in 100 steps: 70 000 counts, more than one 16-bit
        // wrap; summing the wrap-safe per-step deltas recovers them.
        let mut prev = e.counts();
        let mut total = [0i32; 2];
        for k in 1..=100 {
            e.set_angles([0.7 * core::f64::consts::TAU * k as f64; 2]);
            let now = e.counts();
            for w in 0..2 {
                total[w] += controller_core::runtime::count_delta(prev[w], now[w]) as i32;
            }
            prev = now;
        }
        assert_eq!(total, [70_000, -70_000]);
    }

    #[test]
    fn dead_encoder_is_stuck() {
        let mut e = SimEncoders::new(&EncoderParams::EXAMPLE);
        e.set_angles([1.0, 1.0]);
        e.kill(1);
        let before = e.counts();
        e.set_angles([2.0, 2.0]);
        let after = e.counts();
        assert_ne!(before[0], after[0]);
        assert_eq!(before[1], after[1]);
    }

    /// A disabled bridge gives no torque; an enabled one at zero speed gives
    /// the motor model's stall torque, with the sign flipped for a mirrored motor.
    #[test]
    fn motor_drive_signs() {
        use controller_core::runtime::MotorParams;
        let model = MotorModel::new(MotorParams::EXAMPLE).unwrap();
        let cmd = DutyCommand {
            duty: 1000,
            reverse: false,
        };
        let mut drive = MotorDrive {
            model,
            bridge: SimDriver::default(),
            inverted: [false, true],
        };
        assert_eq!(drive.torque_nm([0.0; 2]), [0.0; 2]);
        drive.bridge.set([cmd; 2]);
        let t = drive.torque_nm([0.0; 2]);
        let stall = model.torque_for_duty(cmd, 0.0) as f64;
        assert!(stall > 0.0);
        assert_eq!(t, [stall, -stall]);
    }
}
