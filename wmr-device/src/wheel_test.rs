//! The commissioning wheel test (issue 18, `wmr commission`): in hold
//! only, one wheel driven open-loop at a bounded torque for a bounded time,
//! the robot ending it itself; both wheels' count changes and the gyro's
//! yaw integral reported at the end.
//!
//! The smallest safe path to the motors (D88): the control loop stays
//! disarmed and runs every tick as in hold (encoder reading, its jump
//! check, the estimator). Its per-tick `disable()` of the motors is held
//! back by [`HoldOff`] during the tick only, and after the tick the device
//! either applies the test duty (the test goes on, the loop is still
//! disarmed and latched nothing) or forwards the disable. Every end of a
//! test (time up, another request, link silence, a latched stop) disables
//! the motors on the tick it happens.

use controller_core::estimator::GyroSample;
use controller_core::runtime::{DutyCommand, Gyro, MotorDriver, MotorModel, RuntimeConfig};
use wmr_protocol::{ErrorCode, WheelTestCmd, WheelTestEnd, WheelTestResult, WHEEL_TEST_MAX_MS};

/// The largest wheel-test torque of a robot \[N·m\]: the commissioning cap,
/// the torque limit (the current the driver is rated for, book/src/how-to/robot-file.md)
/// and never above the motor's stall torque at its duty limit (the duty of
/// a larger torque at standstill does not exist). It was a fifth of stall
/// (D88), below the Coulomb friction of small plastic gearboxes (issue 34,
/// D170): the host picks the torque above the wheel's friction.
pub fn torque_cap_nm(rt: &RuntimeConfig) -> f32 {
    let m = &rt.motor;
    let stall_nm = m.torque_constant_nm_per_a
        * m.gear_ratio
        * m.gear_efficiency
        * m.supply_voltage_v
        * m.max_duty_fraction
        / m.winding_resistance_ohm;
    stall_nm.min(rt.controller.torque_limit_nm)
}

/// A wheel test in progress.
#[derive(Clone, Copy, Debug)]
pub struct WheelTest {
    seq: u16,
    cmd: WheelTestCmd,
    duty: [DutyCommand; 2],
    ticks_left: u32,
    ticks: u32,
    counts: [i32; 2],
    gyro_yaw_rad: f32,
    gyro_seen: bool,
}

impl WheelTest {
    /// Validates `cmd` against the robot (`rt`) and the control period:
    /// the duty of the driven wheel at standstill (its motor inversion
    /// flag applied), the other wheel at zero duty.
    pub fn start(seq: u16, cmd: WheelTestCmd, rt: &RuntimeConfig) -> Result<Self, ErrorCode> {
        let w = cmd.wheel as usize;
        if w > 1
            || !cmd.torque_nm.is_finite()
            || cmd.torque_nm == 0.0
            || cmd.duration_ms == 0
            || cmd.duration_ms > WHEEL_TEST_MAX_MS
        {
            return Err(ErrorCode::InvalidValue);
        }
        if cmd.torque_nm.abs() > torque_cap_nm(rt) {
            return Err(ErrorCode::AboveTestCap);
        }
        let model = MotorModel::new(rt.motor).map_err(|_| ErrorCode::InvalidValue)?;
        let mut c = model.duty_for_torque(cmd.torque_nm, 0.0).command;
        if rt.motor_inverted[w] && c.duty > 0 {
            c.reverse = !c.reverse;
        }
        let mut duty = [DutyCommand::ZERO; 2];
        duty[w] = c;
        let period_s = rt.controller.period_s;
        // At least one tick; never longer than asked.
        let ticks = ((cmd.duration_ms as f32 * 1e-3) / period_s) as u32;
        Ok(Self {
            seq,
            cmd,
            duty,
            ticks_left: ticks.max(1),
            ticks: 0,
            counts: [0; 2],
            gyro_yaw_rad: 0.0,
            gyro_seen: false,
        })
    }

    /// The `WheelTest` request's sequence number.
    pub fn seq(&self) -> u16 {
        self.seq
    }

    /// One tick of the test after the loop's tick: adds the tick's count
    /// changes and gyro rate; `None` while it goes on (the caller applies
    /// [`Self::duty`]), else why it ends (time up, or `jumped`: the loop
    /// counted an encoder jump this tick, which it latches only while
    /// running).
    pub fn step(
        &mut self,
        delta: [i32; 2],
        gyro: Option<GyroSample>,
        period_s: f32,
        jumped: bool,
    ) -> Option<WheelTestEnd> {
        for (a, d) in self.counts.iter_mut().zip(delta) {
            *a = a.saturating_add(d);
        }
        if jumped {
            return Some(WheelTestEnd::EncoderJump);
        }
        if let Some(g) = gyro.filter(|g| g.rate_radps.is_finite()) {
            self.gyro_yaw_rad += g.rate_radps * period_s;
            self.gyro_seen = true;
        }
        if self.ticks_left == 0 {
            return Some(WheelTestEnd::Completed);
        }
        self.ticks_left -= 1;
        self.ticks += 1;
        None
    }

    /// The duty `[right, left]` to apply while the test goes on.
    pub fn duty(&self) -> [DutyCommand; 2] {
        self.duty
    }

    /// The result, ended for `end`.
    pub fn result(&self, end: WheelTestEnd) -> WheelTestResult {
        WheelTestResult {
            wheel: self.cmd.wheel,
            torque_nm: self.cmd.torque_nm,
            duty: self.duty[self.cmd.wheel as usize & 1].signed(),
            ticks: self.ticks,
            end,
            counts: self.counts,
            gyro_yaw_rad: self.gyro_seen.then_some(self.gyro_yaw_rad),
        }
    }
}

/// The motor driver during a test tick: `set` goes through, `disable` is
/// held back (remembered) until the device has decided after the tick.
pub struct HoldOff<'a, M: MotorDriver> {
    /// The board's driver.
    pub inner: &'a mut M,
    /// The loop asked for the motors off this tick.
    pub disable_asked: bool,
}

impl<M: MotorDriver> MotorDriver for HoldOff<'_, M> {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        self.inner.set(cmd);
    }
    fn disable(&mut self) {
        self.disable_asked = true;
    }
}

/// The gyro during a test tick: the loop's own reading, remembered.
pub struct Tap<'a, G: Gyro> {
    /// The board's gyro.
    pub inner: &'a mut G,
    /// The sample the loop read this tick.
    pub last: Option<GyroSample>,
}

impl<G: Gyro> Gyro for Tap<'_, G> {
    fn sample(&mut self) -> Option<GyroSample> {
        let s = self.inner.sample();
        self.last = s;
        s
    }
}
