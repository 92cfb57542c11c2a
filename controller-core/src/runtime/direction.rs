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

/// The direction check's state (one block in progress per wheel).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct DirectionCheck {
    /// Ticks in the current block.
    ticks: u16,
    /// Block duration so far \[s\].
    elapsed_s: f32,
    /// Sum of the applied torques over the block \[N·m\] `[right, left]`.
    torque_sum_nm: [f32; 2],
    /// Wheel rates at the start of the block \[rad/s\].
    rate_start_radps: [f32; 2],
    /// A wheel's duty saturated during the block.
    saturated: [bool; 2],
    /// Consecutive mismatching blocks per wheel.
    strikes: [u16; 2],
    /// The first block has its start rate (the first tick after arming
    /// only sets it).
    started: bool,
}

impl DirectionCheck {
    /// A check whose first block starts at `rate_radps` (the default
    /// starts at the first [`Self::update`]'s rates).
    pub(crate) fn start(rate_radps: [f32; 2]) -> Self {
        Self {
            rate_start_radps: rate_radps,
            started: true,
            ..Self::default()
        }
    }

    /// One running tick: `applied_nm` is the torque that acted during the
    /// elapsed tick (written at the previous one), `saturated` whether its
    /// duty was clamped, `rate_radps` the wheel rates measured now,
    /// `elapsed_s` the tick's true duration, `eta` the measured \[v, ω\]
    /// (for eq. 7's Coriolis term). Returns the stop when a wheel has
    /// mismatched `direction_blocks` blocks in a row (the first wheel
    /// found).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn update(
        &mut self,
        limits: &SafetyLimits,
        model: &ReducedModel,
        eta: [f32; 2],
        applied_nm: [f32; 2],
        saturated: [bool; 2],
        rate_radps: [f32; 2],
        elapsed_s: f32,
    ) -> Option<StopReason> {
        if !self.started {
            *self = Self::start(rate_radps);
            return None;
        }
        self.ticks += 1;
        self.elapsed_s += elapsed_s;
        for i in 0..2 {
            self.torque_sum_nm[i] += applied_nm[i];
            self.saturated[i] |= saturated[i];
        }
        if self.ticks < limits.direction_block_ticks {
            return None;
        }
        let mut stop = None;
        let n = self.ticks as f32;
        let torque = [self.torque_sum_nm[0] / n, self.torque_sum_nm[1] / n];
        // Eq. (7): η̇ = Mη + Nτ; wheels φ̈ = (v̇ ± h·ω̇)/r.
        let (tau_eta, m_eta) = (model.n_tau(torque), model.m_eta(eta));
        let (v_dot, w_dot) = (tau_eta[0] + m_eta[0], tau_eta[1] + m_eta[1]);
        let (h, inv_r) = (model.params.half_track_m, 1.0 / model.params.wheel_radius_m);
        let predicted = [(v_dot + h * w_dot) * inv_r, (v_dot - h * w_dot) * inv_r];
        for w in Wheel::BOTH {
            let i = w.index();
            let change = rate_radps[i] - self.rate_start_radps[i];
            let against = predicted[i] * change < 0.0
                && torque[i].abs() >= limits.direction_torque_nm
                && predicted[i].abs() >= limits.direction_accel_radps2
                && change.abs() >= limits.direction_accel_radps2 * self.elapsed_s
                && !self.saturated[i];
            self.strikes[i] = if against {
                self.strikes[i].saturating_add(1)
            } else {
                0
            };
            if self.strikes[i] >= limits.direction_blocks && stop.is_none() {
                stop = Some(StopReason::DirectionMismatch { wheel: w });
            }
        }
        let strikes = self.strikes;
        *self = Self::start(rate_radps);
        self.strikes = strikes;
        stop
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> ReducedModel {
        ReducedModel::new(&crate::RobotParams::paper()).unwrap()
    }

    /// `ticks` ticks of constant torques and measured accelerations, the
    /// rates going on from `rate`.
    fn run(
        check: &mut DirectionCheck,
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
            stop = stop.or(check.update(&l, &m, [0.0; 2], torque, [false; 2], *rate, 1e-3));
        }
        stop
    }

    /// A wheel accelerating against its torque latches after exactly
    /// `direction_blocks` blocks, not before; the other wheel is named.
    #[test]
    fn opposite_acceleration_latches_after_the_window() {
        let l = SafetyLimits::EXAMPLE;
        let window = (l.direction_block_ticks * l.direction_blocks) as u32;
        let (mut c, mut r) = (DirectionCheck::start([0.0; 2]), [0.0f32; 2]);
        // Both wheels +5 N·m (straight ahead: both predicted forward),
        // the left measured −50 rad/s² (an inverted encoder).
        assert_eq!(
            run(&mut c, &mut r, [5.0, 5.0], [50.0, -50.0], window - 1),
            None
        );
        assert_eq!(
            run(&mut c, &mut r, [5.0, 5.0], [50.0, -50.0], 1),
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
            let (mut c, mut r) = (DirectionCheck::start([0.0; 2]), [0.0f32; 2]);
            assert_eq!(
                run(&mut c, &mut r, torque, accel, long),
                None,
                "{torque:?} {accel:?}"
            );
        }
        let (mut c, mut r) = (DirectionCheck::start([0.0; 2]), [0.0f32; 2]);
        let block = l.direction_block_ticks as u32;
        for _ in 0..20 {
            assert_eq!(
                run(
                    &mut c,
                    &mut r,
                    [5.0, 5.0],
                    [-50.0, 0.0],
                    block * (l.direction_blocks as u32 - 1)
                ),
                None
            );
            assert_eq!(run(&mut c, &mut r, [5.0, 5.0], [50.0, 50.0], block), None);
        }
    }

    /// A saturated duty in a block makes it no mismatch (the supply could
    /// not deliver the torque).
    #[test]
    fn saturated_blocks_do_not_count() {
        let l = SafetyLimits::EXAMPLE;
        let mut c = DirectionCheck::start([0.0; 2]);
        let mut rate = [0.0f32; 2];
        for _ in 0..(20 * l.direction_block_ticks * l.direction_blocks) {
            rate[0] -= 0.05;
            let stop = c.update(
                &l,
                &model(),
                [0.0; 2],
                [5.0, 0.0],
                [true, false],
                rate,
                1e-3,
            );
            assert_eq!(stop, None);
        }
    }
}
