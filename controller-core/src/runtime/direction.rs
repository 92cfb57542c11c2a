//! The runtime direction check: a wheel whose measured acceleration keeps
//! the opposite sign of the torque it is driven with is wired backwards
//! (a motor inversion flag that disagrees with its encoder's), which turns
//! the speed loop into positive feedback. Latches
//! [`StopReason::DirectionMismatch`](super::StopReason::DirectionMismatch).
//!
//! The expected acceleration is the model's, not the torque's sign alone:
//! through the body the wheels are coupled (eq. 7: η̇ = Mη + Nτ, N = M1⁻¹B1
//! with both wheels' torques in each row), so a wheel driven lightly
//! backwards while the other wheel drives hard forward accelerates
//! *forwards* (the paper's Case 1 starts that way: τ = \[10, −2.5\] N·m,
//! the left wheel speeding up forward at 20 rad/s²). Per block the mean
//! torques give the predicted wheel accelerations φ̈ = (v̇ ± h·ω̇)/r from
//! eq. (7) at the measured η; the check compares their signs with the
//! measured ones.
//!
//! The measured acceleration is the change of the windowed wheel-rate estimate over
//! a *block* of `direction_block_ticks` ticks divided by the block's true
//! duration, not a per-tick derivative: the rate estimate is quantised to
//! one count per speed window (0.065 rad/s with the example encoder and its
//! 4 ms window), so a per-tick difference would be ±65 rad/s² of noise,
//! while over a 20 ms block it is ±3.3 rad/s². The torque is the mean of
//! the torques applied during the block (the torque written at a tick acts
//! until the next one). A block is a mismatch for a wheel when
//!
//! * |mean torque| ≥ `direction_torque_nm` (above the wheel's friction,
//!   which the model leaves out),
//! * |predicted acceleration| ≥ `direction_accel_radps2` (a clear
//!   prediction, not one the model's errors could flip), and
//! * the rate changed against the prediction by at least
//!   `direction_accel_radps2` × the block's duration (above the estimate's
//!   quantisation and what friction alone gives),
//!
//! and `direction_blocks` mismatching blocks in a row latch: longer than
//! the ESO's and the sliding loop's transients after a disturbance step or
//! arming (a few ms to a few tens of ms), short enough that a wrongly wired
//! wheel is stopped while its speed is still small. Any other block (a
//! consistent one, one below the tolerances, or one where the duty
//! saturated: the supply then delivers less than the commanded torque, so
//! a decelerating wheel is legitimate) restarts the count.

use super::config::SafetyLimits;
use super::hardware::Wheel;
use super::state::StopReason;
use crate::model::ReducedModel;

/// Eq. (7) mapped to wheel accelerations, derived once from the model:
/// φ̈_i = W_i0·τ_R + W_i1·τ_L + c_ω²·ω² ∓ c_ωv·ω·v (− right, + left).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Prediction {
    /// W = S·N with S = \[\[1/r, h/r\], \[1/r, −h/r\]\] \[rad/s² per N·m\].
    w: [[f32; 2]; 2],
    /// Coriolis coefficient of ω² \[rad/s² per (rad/s)²\].
    c_w2: f32,
    /// Coriolis coefficient of ω·v \[rad/s² per rad/s·m/s\].
    c_wv: f32,
}

impl Prediction {
    /// From the controller's reduced model.
    pub(crate) fn new(model: &ReducedModel) -> Self {
        let (h, inv_r) = (model.params.half_track_m, 1.0 / model.params.wheel_radius_m);
        let n = model.n;
        let w = [
            [
                (n[0][0] + h * n[1][0]) * inv_r,
                (n[0][1] + h * n[1][1]) * inv_r,
            ],
            [
                (n[0][0] - h * n[1][0]) * inv_r,
                (n[0][1] - h * n[1][1]) * inv_r,
            ],
        ];
        Self {
            w,
            c_w2: model.n1_coeff / model.m1_diag[0] * inv_r,
            c_wv: h * model.n1_coeff / model.m1_diag[1] * inv_r,
        }
    }
}

/// The direction check's state: one block in progress for both wheels.
/// Blocks are counted on the run's tick count (`Status::run_ticks`), so
/// a tick inside a block only adds two torques.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct DirectionCheck {
    /// Σ of the applied torques over the block \[N·m\] `[right, left]`.
    torque_sum_nm: [f32; 2],
    /// Wheel rates at the start of the block \[rad/s\].
    rate_start_radps: [f32; 2],
    /// The duty-saturation counter (`Status::duty_saturated`) at the
    /// block's start: a block in which it moved gives no verdict.
    saturated_at_start: u32,
    /// The ended block awaiting its verdicts (the right wheel's one tick
    /// after its end, the left wheel's two ticks after: no tick does more
    /// than one wheel's arithmetic): torque sums and rate changes.
    ended_torque_sum_nm: [f32; 2],
    ended_change_radps: [f32; 2],
    /// The ended block gets verdicts (its duty did not saturate).
    ended_valid: bool,
    /// Consecutive mismatching blocks per wheel.
    strikes: [u16; 2],
}

impl DirectionCheck {
    /// A check whose first block starts now, at arming: wheel rates
    /// `rate_radps`, duty-saturation counter `saturated_count`.
    pub(crate) fn start(rate_radps: [f32; 2], saturated_count: u32) -> Self {
        Self {
            rate_start_radps: rate_radps,
            saturated_at_start: saturated_count,
            ..Self::default()
        }
    }

    /// One running tick: `run_ticks` the steps since arming before this
    /// one (`Status::run_ticks`), `applied_nm` the torque that acted
    /// during the elapsed tick (written at the previous one),
    /// `saturated_count` the duty-saturation counter so far, `rate_radps`
    /// the wheel rates measured now, `period_s` the control period (the
    /// block time is ticks × period: a late tick only shifts the tolerance
    /// slightly, and sustained lateness latches `LoopOverrun` anyway),
    /// `eta` the measured \[v, ω\] (eq. 7's Coriolis term). Returns the
    /// stop when a wheel has mismatched `direction_blocks` blocks in a
    /// row. `direction_block_ticks` >= 3 (validated).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(crate) fn update(
        &mut self,
        limits: &SafetyLimits,
        prediction: &Prediction,
        run_ticks: u32,
        eta: [f32; 2],
        applied_nm: [f32; 2],
        saturated_count: u32,
        rate_radps: [f32; 2],
        period_s: f32,
    ) -> Option<StopReason> {
        self.torque_sum_nm[0] += applied_nm[0];
        self.torque_sum_nm[1] += applied_nm[1];
        let n = limits.direction_block_ticks as u32;
        match run_ticks % n {
            0 if run_ticks > 0 => self.end_block(saturated_count, rate_radps),
            1 if self.ended_valid => {
                return self.judge(limits, prediction, eta, Wheel::Right, n, period_s)
            }
            2 if self.ended_valid => {
                return self.judge(limits, prediction, eta, Wheel::Left, n, period_s)
            }
            _ => {}
        }
        None
    }

    /// The block's end: its sums and rate changes kept for the verdicts,
    /// the next block started (a block in which the duty saturated gives
    /// none and clears the counts).
    #[inline(never)]
    fn end_block(&mut self, saturated_count: u32, rate_radps: [f32; 2]) {
        self.ended_valid = saturated_count == self.saturated_at_start;
        if self.ended_valid {
            self.ended_torque_sum_nm = self.torque_sum_nm;
            self.ended_change_radps = [
                rate_radps[0] - self.rate_start_radps[0],
                rate_radps[1] - self.rate_start_radps[1],
            ];
        } else {
            self.strikes = [0; 2];
        }
        self.torque_sum_nm = [0.0; 2];
        self.rate_start_radps = rate_radps;
        self.saturated_at_start = saturated_count;
    }

    /// One wheel's verdict on the ended block of `n` ticks: eq. (7) at its
    /// mean torques and the measured η against its rate change.
    #[inline(never)]
    fn judge(
        &mut self,
        limits: &SafetyLimits,
        prediction: &Prediction,
        eta: [f32; 2],
        wheel: Wheel,
        n: u32,
        period_s: f32,
    ) -> Option<StopReason> {
        let i = wheel.index();
        let n = n as f32;
        let inv_n = 1.0 / n;
        let w = &prediction.w[i];
        let coriolis = prediction.c_w2 * eta[1] * eta[1];
        let cross = prediction.c_wv * eta[1] * eta[0];
        let sum = &self.ended_torque_sum_nm;
        let predicted = (w[0] * sum[0] + w[1] * sum[1]) * inv_n
            + if i == 0 {
                coriolis - cross
            } else {
                coriolis + cross
            };
        let change = self.ended_change_radps[i];
        let against = predicted * change < 0.0
            && (sum[i] * inv_n).abs() >= limits.direction_torque_nm
            && predicted.abs() >= limits.direction_accel_radps2
            && change.abs() >= limits.direction_accel_radps2 * n * period_s;
        let k = &mut self.strikes[i];
        *k = if against { k.saturating_add(1) } else { 0 };
        (*k >= limits.direction_blocks).then_some(StopReason::DirectionMismatch { wheel })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Prediction {
        Prediction::new(&ReducedModel::new(&crate::RobotParams::paper()).unwrap())
    }

    /// `ticks` ticks of constant torques and measured accelerations, the
    /// rates going on from `rate`.
    fn run(
        check: &mut DirectionCheck,
        tick: &mut u32,
        rate: &mut [f32; 2],
        torque: [f32; 2],
        accel: [f32; 2],
        ticks: u32,
    ) -> Option<StopReason> {
        let l = SafetyLimits::EXAMPLE;
        let m = model();
        let mut stop = None;
        for _ in 0..ticks {
            for i in 0..2 {
                rate[i] += accel[i] * 1e-3;
            }
            stop = stop.or(check.update(&l, &m, *tick, [0.0; 2], torque, 0, *rate, 1e-3));
            *tick += 1;
        }
        stop
    }

    /// A wheel accelerating against its torque latches after exactly
    /// `direction_blocks` blocks, not before; the other wheel is named.
    /// (The right wheel is judged one tick after the block's end, the
    /// left one two ticks after.)
    #[test]
    fn opposite_acceleration_latches_after_the_window() {
        let l = SafetyLimits::EXAMPLE;
        let window = (l.direction_block_ticks * l.direction_blocks) as u32;
        let (mut c, mut t, mut r) = (DirectionCheck::start([0.0; 2], 0), 0u32, [0.0f32; 2]);
        // Both wheels +5 N·m (straight ahead: both predicted forward),
        // the left measured −50 rad/s² (an inverted encoder).
        assert_eq!(
            run(
                &mut c,
                &mut t,
                &mut r,
                [5.0, 5.0],
                [50.0, -50.0],
                window + 2
            ),
            None
        );
        assert_eq!(
            run(&mut c, &mut t, &mut r, [5.0, 5.0], [50.0, -50.0], 1),
            Some(StopReason::DirectionMismatch { wheel: Wheel::Left })
        );
    }

    /// Below either tolerance, or with consistent signs, nothing latches;
    /// one consistent block restarts the count.
    #[test]
    fn within_tolerance_or_consistent_never_latches() {
        let l = SafetyLimits::EXAMPLE;
        let long = 20 * (l.direction_block_ticks * l.direction_blocks) as u32;
        let small_torque = 0.9 * l.direction_torque_nm;
        let small_accel = 0.9 * l.direction_accel_radps2;
        for (torque, accel) in [
            // Below the torque tolerance.
            ([small_torque, small_torque], [-100.0, -100.0]),
            // Below the measured-acceleration tolerance.
            ([5.0, -5.0], [-small_accel, small_accel]),
            // Consistent (a turn on the spot).
            ([5.0, -5.0], [50.0, -50.0]),
            // The coupling through the body (Case 1's start): the left
            // wheel braked lightly, the right driven hard: the model
            // predicts the left wheel speeding up forwards, as measured.
            ([10.0, -2.5], [60.0, 20.0]),
        ] {
            let (mut c, mut t, mut r) = (DirectionCheck::start([0.0; 2], 0), 0u32, [0.0f32; 2]);
            assert_eq!(
                run(&mut c, &mut t, &mut r, torque, accel, long),
                None,
                "{torque:?} {accel:?}"
            );
        }
        let (mut c, mut t, mut r) = (DirectionCheck::start([0.0; 2], 0), 0u32, [0.0f32; 2]);
        let block = l.direction_block_ticks as u32;
        for _ in 0..20 {
            assert_eq!(
                run(
                    &mut c,
                    &mut t,
                    &mut r,
                    [5.0, 5.0],
                    [-50.0, 0.0],
                    block * (l.direction_blocks as u32 - 1)
                ),
                None
            );
            assert_eq!(
                run(&mut c, &mut t, &mut r, [5.0, 5.0], [50.0, 50.0], block),
                None
            );
        }
    }

    /// A saturated duty in a block makes it no mismatch (the supply could
    /// not deliver the torque).
    #[test]
    fn saturated_blocks_do_not_count() {
        let l = SafetyLimits::EXAMPLE;
        let mut c = DirectionCheck::start([0.0; 2], 0);
        let mut rate = [0.0f32; 2];
        for k in 0..(20 * l.direction_block_ticks * l.direction_blocks) as u32 {
            rate[0] -= 0.05;
            // The duty-saturation counter moves in every block.
            let stop = c.update(&l, &model(), k, [0.0; 2], [5.0, 5.0], k, rate, 1e-3);
            assert_eq!(stop, None);
        }
    }
}
