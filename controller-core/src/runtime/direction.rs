//! The runtime direction check: a wheel whose measured acceleration keeps
//! the opposite sign of the torque it is driven with is wired backwards
//! (a motor inversion flag that disagrees with its encoder's), which turns
//! the speed loop into positive feedback. Latches
//! [`StopReason::DirectionMismatch`](super::StopReason::DirectionMismatch).
//!
//! A wheel wired backwards (its motor or its encoder) behaves as if the
//! voltage applied to it had the opposite sign: with wheel torque
//! τ = b_V·V − b·φ̇ (b_V = η_g·N·k/R per volt, b = η_g·N²·k²/R the
//! back-EMF damping), the commanded torque τ_c = b_V·V − b·φ̇ becomes
//! −b_V·V − b·φ̇ = −τ_c − 2·b·φ̇ (an inverted encoder gives the same in the
//! measured frame). So the check decides, per block, which of the two
//! hypotheses the measured acceleration is nearer: *correct* (eq. 7 at the
//! mean commanded torques, as the controller's model predicts) or
//! *inverted* (the same with this wheel's torque replaced by −τ_c − 2·b·φ̇).
//! The midpoint between them is the prediction minus W_ii·τ_V, where
//! τ_V = τ_c + b·φ̇ is the torque the applied voltage alone would give at
//! standstill (W_ii the wheel's own entry of eq. 7's map from torques to
//! wheel accelerations, positive).
//!
//! Why the voltage and not the commanded torque (D109): a motor constant
//! that differs from the model's by a factor (1 + ε) makes the real torque
//! (1 + ε)·τ_V − (1 + ε)²·b·φ̇, which for a fast wheel of a strongly geared
//! robot differs from τ_c by several N·m (the 10 kg BTS7960 example:
//! b = 1.15 N·m per rad/s, so ε = 0.2 at 12 rad/s is 2.9 N·m): a check on
//! the commanded torque's prediction false-trips at cruise, while the
//! midpoint test flips only when (1 + ε)·τ_V < ε·(2 + ε)·b·φ̇, i.e. under
//! regenerative braking harder than 1.0·b·φ̇ (beyond the torque limit at
//! speed for that robot).
//!
//! Through the body the wheels are coupled (eq. 7: η̇ = Mη + Nτ,
//! N = M1⁻¹B1 with both wheels' torques in each row), so a wheel driven
//! lightly backwards while the other wheel drives hard forward accelerates
//! *forwards* (the paper's Case 1 starts that way: τ = \[10, −2.5\] N·m,
//! the left wheel speeding up forward at 20 rad/s²): both hypotheses use
//! eq. (7) with both wheels' mean torques and the measured η.
//!
//! The measured acceleration is the change of the windowed wheel-rate estimate over
//! a *block* of `direction_block_ticks` ticks divided by the block's true
//! duration, not a per-tick derivative: the rate estimate is quantised to
//! one count per speed window (0.065 rad/s with the example encoder and its
//! 4 ms window), so a per-tick difference would be ±65 rad/s² of noise,
//! while over a 20 ms block it is ±3.3 rad/s². The torque is the mean of
//! the torques *delivered* during the block (the torque written at a tick
//! acts until the next one): the commanded torque, or, at a tick whose duty
//! clamped at the duty limit, the torque the clamped duty gives by the
//! runtime's motor model, b_V·V_supply·duty − b·φ̇ (`ControlLoop::duty_for`,
//! D111). A block is a mismatch for a wheel when
//!
//! * the prediction is clear, |prediction| ≥ `direction_accel_radps2` × the
//!   block's duration, and either
//!   - the measured rate change is against it by at least that much (the
//!     runaway's acceleration), or
//!   - the change is smaller than that while the wheel turns against its
//!     voltage's torque (φ̇·τ_V < 0) at |φ̇| ≥ the same number in rad/s
//!     (D111: the runaway's *equilibrium*: at the torque limit a wheel
//!     wired backwards settles within a block or two at φ̇ = −τ_c/(2b),
//!     where it no longer accelerates; a correctly wired wheel turning
//!     against a voltage that large without accelerating needs an
//!     unmodelled force beyond `direction_torque_nm`; a wheel that does not
//!     turn is a stall, the stall check's),
//! * |τ_V| ≥ `direction_torque_nm` (the hypotheses are apart by
//!   2·W_ii·|τ_V|, and friction, which the model leaves out, shifts the
//!   measurement by W_ii times the friction torque: the tolerance is above
//!   the wheel's friction), and
//! * the measured rate change is on the inverted side of the midpoint by at
//!   least `direction_accel_radps2` × the block's duration,
//!
//! and `direction_blocks` mismatching blocks in a row latch: longer than
//! the ESO's and the sliding loop's transients after a disturbance step or
//! arming (a few ms to a few tens of ms), short enough that a wrongly wired
//! wheel is stopped while its speed is still small. Any other block (a
//! consistent one, one below the tolerances) restarts the count.
//!
//! **Saturation (D111).** Two limits cut what a wheel gets. The
//! controller's torque limit clamps the *command*: the check sees the
//! clamped command, which the bridge delivers, so nothing is special about
//! it (a runaway drives the command to the limit, and the equilibrium case
//! above is what catches it there). The duty limit clamps
//! the *voltage*: the bridge then delivers less than the command (at speed
//! the back-EMF can make the delivered torque of the opposite sign, a
//! correctly wired wheel decelerating under a positive command), so the
//! check is fed the clamped duty's torque instead; a saturated block is
//! judged like any other (before D111 a block in which either wheel's duty
//! clamped gave no verdict). The delivered torque is the model's: a supply
//! that sags below `motor.supply_voltage_v` delivers less still, which the
//! midpoint's margin (W_ii·τ_V) absorbs as it absorbs a motor-constant
//! error (D109).
//!
//! **Thresholds (D112).** `SafetyLimits::validate_direction` refuses
//! thresholds that can never fire or that false-trip: `direction_torque_nm`
//! above half the torque limit (the equilibrium's τ_V is τ_c/2), an
//! acceleration tolerance under 2 rate quanta over a block, or above half
//! W_ii × the limit (the equilibrium's distance from the midpoint). The
//! robot file lengthens the block for coarse encoders (derive.rs).
//!
//! **What it cannot see.** A wheel held at 0 rate (a stall or a dead
//! encoder: `check_stall`); a wheel driven below `direction_torque_nm`; a
//! miswired wheel whose controller keeps reversing its torque before a run
//! of `direction_blocks` blocks forms; and an inverted *encoder* where the
//! body's coupling is strong: the inverted hypothesis flips only the
//! wheel's own term (exact for a backwards motor), while a backwards
//! encoder negates the measured wheel's whole acceleration, the other
//! wheel's share W_ij·τ_j included, so with the two shares nearly
//! cancelling the measurement lies near the correct hypothesis (the paper
//! robot's tuned gains, hil-sim/tests/direction_robots.rs, D113).

use super::config::SafetyLimits;
use super::hardware::Wheel;
use super::motor::MotorModel;
use super::state::StopReason;
use crate::model::ReducedModel;

/// Eq. (7) mapped to wheel-rate changes over a block, derived once from
/// the model, the motor, the limits and the control period (rebuilt on
/// reconfigure): φ̈_i = W_i0·τ_R + W_i1·τ_L + c_ω²·ω² ∓ c_ωv·ω·v
/// (− right, + left), each term multiplied out to what it gives over a
/// block, so a verdict is a few multiply-adds (bench-m4's tick budget).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Prediction {
    /// W·T (W = S·N with S = \[\[1/r, h/r\], \[1/r, −h/r\]\], T the control
    /// period): the rate change per N·m applied for one tick
    /// \[rad/s per N·m·tick\]; times a block's torque sum, its predicted change.
    w_tick: [[f32; 2]; 2],
    /// Coriolis coefficients of ω² and ω·v times the block's duration
    /// \[rad/s per (rad/s)², per rad/s·m/s\].
    c_w2_block: f32,
    c_wv_block: f32,
    /// 1 / ticks per block (a torque sum to its mean).
    inv_block_ticks: f32,
    /// Back-EMF damping at the wheel b = η_g·N²·k²/R \[N·m per rad/s\]
    /// (the motor model's).
    damping_nms_per_rad: f32,
    /// `direction_accel_radps2` × the block's duration \[rad/s\].
    tol_change_radps: f32,
    /// `direction_torque_nm` \[N·m\].
    tol_torque_nm: f32,
    /// W_ii × the block's duration: a wheel's own share of the prediction
    /// per N·m of mean torque \[rad/s per N·m\].
    own_block: [f32; 2],
    /// Ticks per block and blocks in a row that latch (the limits').
    block_ticks: u32,
    blocks: u16,
}

impl Prediction {
    /// From the controller's reduced model, the runtime's motor model,
    /// the (validated) safety limits and the control period `period_s`.
    pub(crate) fn new(
        model: &ReducedModel,
        motor: &MotorModel,
        limits: &SafetyLimits,
        period_s: f32,
    ) -> Self {
        let (h, inv_r) = (model.params.half_track_m, 1.0 / model.params.wheel_radius_m);
        let block_s = limits.direction_block_ticks as f32 * period_s;
        let w_tick = model.wheel_accel_map().map(|row| row.map(|x| x * period_s));
        Self {
            w_tick,
            c_w2_block: model.n1_coeff / model.m1_diag[0] * inv_r * block_s,
            c_wv_block: h * model.n1_coeff / model.m1_diag[1] * inv_r * block_s,
            inv_block_ticks: 1.0 / limits.direction_block_ticks as f32,
            damping_nms_per_rad: motor.back_emf_damping_nms_per_rad(),
            tol_change_radps: limits.direction_accel_radps2 * block_s,
            tol_torque_nm: limits.direction_torque_nm,
            own_block: [
                w_tick[0][0] * limits.direction_block_ticks as f32,
                w_tick[1][1] * limits.direction_block_ticks as f32,
            ],
            block_ticks: limits.direction_block_ticks as u32,
            blocks: limits.direction_blocks,
        }
    }
}

/// The direction check's state: one block in progress for both wheels.
/// Blocks are counted on the run's tick count (`Status::run_ticks`), so
/// a tick inside a block only adds two torques.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct DirectionCheck {
    /// Σ of the delivered torques over the block \[N·m\] `[right, left]`.
    torque_sum_nm: [f32; 2],
    /// Wheel rates at the start of the block \[rad/s\].
    rate_start_radps: [f32; 2],
    /// The ended block's start rates \[rad/s\] (with its change, its mean rate).
    ended_start_radps: [f32; 2],
    /// The ended block awaiting its verdicts (the right wheel's one tick
    /// after its end, the left wheel's two ticks after: no tick does more
    /// than one wheel's arithmetic): torque sums and rate changes.
    ended_torque_sum_nm: [f32; 2],
    ended_change_radps: [f32; 2],
    /// Consecutive mismatching blocks per wheel.
    strikes: [u16; 2],
}

impl DirectionCheck {
    /// A check whose first block starts now, at arming: wheel rates
    /// `rate_radps`.
    pub(crate) fn start(rate_radps: [f32; 2]) -> Self {
        Self {
            rate_start_radps: rate_radps,
            ..Self::default()
        }
    }

    /// One running tick: `run_ticks` the steps since arming before this
    /// one (`Status::run_ticks`), `delivered_nm` the torque that acted
    /// during the elapsed tick (written at the previous one: the commanded
    /// torque, or where the duty clamped, the clamped duty's torque by the
    /// motor model), `rate_radps` the wheel rates measured now (the block
    /// time is ticks × period: a late tick only shifts the tolerance
    /// slightly, and sustained lateness latches `LoopOverrun` anyway),
    /// `eta` the measured \[v, ω\] (eq. 7's Coriolis term). Returns the
    /// stop when a wheel has mismatched `direction_blocks` blocks in a row.
    /// `direction_block_ticks` >= 3 (validated).
    #[inline]
    pub(crate) fn update(
        &mut self,
        prediction: &Prediction,
        run_ticks: u32,
        eta: [f32; 2],
        delivered_nm: [f32; 2],
        rate_radps: [f32; 2],
    ) -> Option<StopReason> {
        self.torque_sum_nm[0] += delivered_nm[0];
        self.torque_sum_nm[1] += delivered_nm[1];
        match run_ticks % prediction.block_ticks {
            0 if run_ticks > 0 => self.end_block(rate_radps),
            // (Before the first block's end the ended block is all zero:
            // no clear prediction, no verdict.)
            1 => return self.judge(prediction, eta, Wheel::Right),
            2 => return self.judge(prediction, eta, Wheel::Left),
            _ => {}
        }
        None
    }

    /// The block's end: its sums and rate changes kept for the verdicts,
    /// the next block started.
    #[inline(never)]
    fn end_block(&mut self, rate_radps: [f32; 2]) {
        self.ended_torque_sum_nm = self.torque_sum_nm;
        self.ended_change_radps = [
            rate_radps[0] - self.rate_start_radps[0],
            rate_radps[1] - self.rate_start_radps[1],
        ];
        self.ended_start_radps = self.rate_start_radps;
        self.torque_sum_nm = [0.0; 2];
        self.rate_start_radps = rate_radps;
    }

    /// One wheel's verdict on the ended block: eq. (7) at its mean
    /// delivered torques and the measured η, against the inverted-wiring
    /// hypothesis (module docs), from its rate change; all in rate change
    /// over the block \[rad/s\].
    #[inline(never)]
    fn judge(&mut self, p: &Prediction, eta: [f32; 2], wheel: Wheel) -> Option<StopReason> {
        let i = wheel.index();
        let w = &p.w_tick[i];
        let coriolis = p.c_w2_block * eta[1] * eta[1];
        let cross = p.c_wv_block * eta[1] * eta[0];
        let sum = &self.ended_torque_sum_nm;
        let predicted = w[0] * sum[0]
            + w[1] * sum[1]
            + if i == 0 {
                coriolis - cross
            } else {
                coriolis + cross
            };
        let change = self.ended_change_radps[i];
        let tol = p.tol_change_radps;
        // A clear prediction, and either a clear change against it (the
        // runaway's acceleration) or no clear change while the wheel turns
        // against its voltage at a clear rate (the runaway's equilibrium at
        // the torque limit, φ̇ = −τ_c / 2b); a wheel that does not turn is a
        // stall, `check_stall`'s. (The cheap exits first: bench-m4's tick.)
        let small = change.abs() < tol;
        if predicted.abs() < tol || (!small && predicted * change >= 0.0) {
            self.strikes[i] = 0;
            return None;
        }
        let mean_rate = self.ended_start_radps[i] + 0.5 * change;
        // τ_V = τ_c + b·φ̇ at the block's mean rate (the voltage's torque).
        let tau_v = sum[i] * p.inv_block_ticks + p.damping_nms_per_rad * mean_rate;
        // ... and nearer the inverted hypothesis than the correct one: the
        // midpoint is the prediction minus W_ii·τ_V over the block.
        let beyond = change - predicted + p.own_block[i] * tau_v;
        let against = (!small || (mean_rate * tau_v < 0.0 && mean_rate.abs() >= tol))
            && beyond * tau_v < 0.0
            && tau_v.abs() >= p.tol_torque_nm
            && beyond.abs() >= tol;
        let k = &mut self.strikes[i];
        *k = if against { k.saturating_add(1) } else { 0 };
        (*k >= p.blocks).then_some(StopReason::DirectionMismatch { wheel })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD_S: f32 = 1e-3;

    /// The model's wheel accelerations per N·m \[rad/s² per N·m\].
    fn accel_map(m: &Prediction) -> [[f32; 2]; 2] {
        m.w_tick.map(|row| row.map(|x| x / PERIOD_S))
    }

    fn model() -> Prediction {
        Prediction::new(
            &ReducedModel::new(&crate::RobotParams::paper()).unwrap(),
            &MotorModel::new(super::super::motor::MotorParams::EXAMPLE).unwrap(),
            &SafetyLimits::EXAMPLE,
            PERIOD_S,
        )
    }

    /// The model without back-EMF damping (b = 0: the voltage's torque is
    /// the commanded torque), for the scripted-acceleration tests below,
    /// whose rates grow without a motor law.
    fn undamped() -> Prediction {
        Prediction {
            damping_nms_per_rad: 0.0,
            ..model()
        }
    }

    /// `ticks` ticks of constant torques and measured accelerations, the
    /// rates going on from `rate` (the undamped model).
    fn run(
        check: &mut DirectionCheck,
        tick: &mut u32,
        rate: &mut [f32; 2],
        torque: [f32; 2],
        accel: [f32; 2],
        ticks: u32,
    ) -> Option<StopReason> {
        let m = undamped();
        let mut stop = None;
        for _ in 0..ticks {
            for i in 0..2 {
                rate[i] += accel[i] * 1e-3;
            }
            stop = stop.or(check.update(&m, *tick, [0.0; 2], torque, *rate));
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
        let (mut c, mut t, mut r) = (DirectionCheck::start([0.0; 2]), 0u32, [0.0f32; 2]);
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
        // A turn on the spot: each wheel's midpoint between the hypotheses
        // is its prediction minus its own torque's share (W_ii·τ_i).
        let w = accel_map(&undamped());
        let spin = [5.0f32, -5.0];
        let midpoint = |i: usize| w[i][0] * spin[0] + w[i][1] * spin[1] - w[i][i] * spin[i];
        for (torque, accel) in [
            // Below the torque tolerance.
            ([small_torque, small_torque], [-100.0, -100.0]),
            // On the inverted side of the midpoint, within the tolerance.
            (spin, [midpoint(0) - small_accel, midpoint(1) + small_accel]),
            // Consistent (a turn on the spot).
            ([5.0, -5.0], [50.0, -50.0]),
            // The coupling through the body (Case 1's start): the left
            // wheel braked lightly, the right driven hard: the model
            // predicts the left wheel speeding up forwards, as measured.
            ([10.0, -2.5], [60.0, 20.0]),
        ] {
            let (mut c, mut t, mut r) = (DirectionCheck::start([0.0; 2]), 0u32, [0.0f32; 2]);
            assert_eq!(
                run(&mut c, &mut t, &mut r, torque, accel, long),
                None,
                "{torque:?} {accel:?}"
            );
        }
        let (mut c, mut t, mut r) = (DirectionCheck::start([0.0; 2]), 0u32, [0.0f32; 2]);
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

    /// Drives the check with a DC-motor plant on the model's own coupling:
    /// commanded torques `tau_c` at each tick, the real wheel torques from
    /// the applied voltage's torque τ_V = τ_c + b·φ̇ through a motor whose
    /// constant is (1 + ε) times the model's, wheel `inverted` (if any)
    /// wired backwards (its voltage's sign flipped). Accelerations from the
    /// prediction's torque map (straight driving, η = 0 in the Coriolis
    /// terms). Returns the first stop and the tick.
    fn motor_plant(
        eps: f32,
        inverted: Option<usize>,
        rate0: [f32; 2],
        tau_c: impl Fn(u32, [f32; 2]) -> [f32; 2],
        ticks: u32,
    ) -> Option<(u32, StopReason)> {
        supply_plant(
            eps,
            inverted,
            rate0,
            tau_c,
            ticks,
            f32::INFINITY,
            Feed::Delivered,
        )
    }

    /// What the check is fed (the runtime feeds the delivered torque).
    #[derive(Clone, Copy, PartialEq)]
    enum Feed {
        Delivered,
        Commanded,
    }

    /// [`motor_plant`] with the duty clamped: the voltage's torque
    /// b_V·V limited to ±`tau_v_max` (the supply at the duty limit; the
    /// runtime's `duty_for` clamps the same way), so the torque delivered
    /// is clamp(τ_c + b·φ̇) − b·φ̇ by the model. `feed` says which torque
    /// the check gets.
    fn supply_plant(
        eps: f32,
        inverted: Option<usize>,
        rate0: [f32; 2],
        tau_c: impl Fn(u32, [f32; 2]) -> [f32; 2],
        ticks: u32,
        tau_v_max: f32,
        feed: Feed,
    ) -> Option<(u32, StopReason)> {
        let m = model();
        let w = accel_map(&m);
        let b = m.damping_nms_per_rad;
        let mut c = DirectionCheck::start(rate0);
        let mut rate = rate0;
        for k in 0..ticks {
            let tc = tau_c(k, rate);
            let mut real = [0.0f32; 2];
            let mut delivered = tc;
            for i in 0..2 {
                let mut tau_v = (tc[i] + b * rate[i]).clamp(-tau_v_max, tau_v_max);
                delivered[i] = tau_v - b * rate[i];
                if inverted == Some(i) {
                    tau_v = -tau_v;
                }
                real[i] = (1.0 + eps) * tau_v - (1.0 + eps) * (1.0 + eps) * b * rate[i];
            }
            for i in 0..2 {
                rate[i] += (w[i][0] * real[0] + w[i][1] * real[1]) * PERIOD_S;
            }
            let fed = match feed {
                Feed::Delivered => delivered,
                Feed::Commanded => tc,
            };
            if let Some(stop) = c.update(&m, k, [0.0; 2], fed, rate) {
                return Some((k, stop));
            }
        }
        None
    }

    /// A miswired wheel whose duty saturates at every tick latches within
    /// the window, naming the wheel: saturated blocks are judged (before
    /// D111 every block in which the duty saturated was dropped, so this
    /// never latched). The supply gives at most 3 N·m of voltage torque, the
    /// loop asks for 8 N·m, so τ_V = 8 + b·φ̇ stays above 3 while the
    /// runaway wheel is slower than −8.2 rad/s, and its equilibrium under
    /// the clamp is −3/b = −4.9 rad/s: saturated throughout. Also with the
    /// motor constant ±20 % off.
    #[test]
    fn a_saturated_miswired_wheel_latches() {
        let l = SafetyLimits::EXAMPLE;
        let window = (l.direction_block_ticks * l.direction_blocks) as u32;
        let start = |_: u32, rate: [f32; 2]| speed_loop(5.0, rate);
        for eps in [-0.2f32, 0.0, 0.2] {
            for wheel in [0usize, 1] {
                let (k, stop) = supply_plant(
                    eps,
                    Some(wheel),
                    [0.0; 2],
                    start,
                    10 * window,
                    3.0,
                    Feed::Delivered,
                )
                .unwrap_or_else(|| panic!("ε = {eps}, wheel {wheel}: no stop"));
                assert_eq!(
                    stop,
                    StopReason::DirectionMismatch {
                        wheel: Wheel::BOTH[wheel]
                    }
                );
                // One block more than the window: a 20 % weaker motor's
                // first block is below the acceleration tolerance.
                let bound = window + l.direction_block_ticks as u32 + 2;
                assert!(k <= bound, "ε = {eps}: latched at tick {k}");
            }
        }
    }

    /// Correctly wired wheels at 30 rad/s (b·φ̇ = 18.4 N·m of back-EMF)
    /// under +8 N·m commanded, on a supply that gives only 6 N·m of voltage
    /// torque (a sagging battery): the duty saturates at every tick and the
    /// wheels *decelerate* under a positive command (delivered
    /// 6 − 18.4 = −12.4 N·m at first). Judged on the delivered torque, 2 s
    /// never latch; judged on the commanded torque the same run latches
    /// (the hypotheses' midpoint alone does not cover it: the two wheels'
    /// coupling W_ij·(τ_c − τ_delivered) outweighs W_ii·τ_V when the
    /// shortfall exceeds 1.6 τ_V), so the delivered torque is what keeps it
    /// from false-tripping.
    #[test]
    fn a_saturated_correct_wheel_decelerating_does_not_latch() {
        let push = |_: u32, _: [f32; 2]| [8.0f32, 8.0];
        for eps in [-0.2f32, 0.0, 0.2] {
            assert_eq!(
                supply_plant(eps, None, [30.0; 2], push, 2000, 6.0, Feed::Delivered),
                None,
                "ε = {eps}"
            );
        }
        assert!(
            supply_plant(0.0, None, [30.0; 2], push, 2000, 6.0, Feed::Commanded).is_some(),
            "negative control: the commanded torque false-trips"
        );
    }

    /// A wheel-speed P loop (as the dynamic loop acts at the wheels): the
    /// torque that drives the wheel rates to `ref_radps`, within ±8 N·m.
    fn speed_loop(ref_radps: f32, rate: [f32; 2]) -> [f32; 2] {
        let p = |r: f32| (2.0 * (ref_radps - r)).clamp(-8.0, 8.0);
        [p(rate[0]), p(rate[1])]
    }

    /// A motor constant 30 % off the model's, the wheels speeding up and
    /// slowing down between 4 and 10 rad/s (0.4-1 m/s at r = 0.1 m, where
    /// the back-EMF torque b·φ̇ is 2.4-6.1 N·m for the example motor and
    /// the real torque differs from the commanded one by
    /// ε·τ_c − ε·(1 + ε)·b·φ̇, up to 2.6 N·m): never a stop. With one
    /// motor wired backwards the same loop latches within the window,
    /// naming that wheel. (D74's torque-based check passes this open P
    /// loop too: what tells the two apart is the closed loop of the 10 kg
    /// robot, hil-sim/tests/mismatch_sweep.rs, k_motor +20 %.)
    #[test]
    fn motor_constant_mismatch_is_not_a_wiring_fault() {
        let l = SafetyLimits::EXAMPLE;
        let window = (l.direction_block_ticks * l.direction_blocks) as u32;
        let b = model().damping_nms_per_rad;
        assert!(b * 10.0 > 6.0, "b = {b}");
        let steps =
            |k: u32, rate: [f32; 2]| speed_loop(if (k / 400) % 2 == 0 { 10.0 } else { 4.0 }, rate);
        for eps in [-0.3f32, -0.2, 0.2, 0.3] {
            assert_eq!(
                motor_plant(eps, None, [4.0; 2], steps, 8000),
                None,
                "ε = {eps}"
            );
        }
        // A miswired right motor at standstill, the loop asking for 5 rad/s.
        let start = |_: u32, rate: [f32; 2]| speed_loop(5.0, rate);
        for eps in [-0.2f32, 0.0, 0.2] {
            let (k, stop) = motor_plant(eps, Some(0), [0.0; 2], start, 10 * window)
                .unwrap_or_else(|| panic!("ε = {eps}: no stop"));
            assert_eq!(
                stop,
                StopReason::DirectionMismatch {
                    wheel: Wheel::Right
                }
            );
            assert!(k <= window + 2, "ε = {eps}: latched at tick {k}");
        }
    }
}
