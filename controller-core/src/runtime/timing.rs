//! Loop timing measured against the schedule.
//!
//! A periodic ticker that fires at once when its deadline has already
//! passed (embassy's `Ticker`, which advances its deadline by one period per
//! tick) delivers late ticks back to back. Measured as the interval between
//! two ticks, that hides overruns:
//!
//! * a step that always takes 1.2 ms gives 1.2 ms intervals: below a 1.5 ms
//!   interval limit forever, while the loop silently runs at 833 Hz;
//! * a 20 ms stall gives one 20 ms interval, then a burst of near-zero
//!   intervals while the ticker catches up, which resets any "consecutive
//!   overruns" count, and a speed estimate that assumes dt = 1 ms reads
//!   nearly zero during the burst.
//!
//! [`LoopTimer`] measures each tick's start against its scheduled time
//! t₀ + n·period instead. The lateness of a sustained overrun grows without
//! bound; after a stall the catch-up ticks stay late until the loop is back
//! on schedule, so the stall is one overrun episode that is not "reset" by
//! the burst. It also reports the true elapsed time since the previous tick,
//! which the runtime's wheel-rate estimate uses instead of the nominal
//! period.
//!
//! Timestamps are `u32` microseconds from any free-running clock (the
//! firmware's `Instant::now().as_micros() as u32`, a simulated clock on the
//! host); differences are taken with wrapping arithmetic, so the 71.6 min
//! wrap of a `u32` µs counter is harmless as long as two ticks are less than
//! 35 min apart.

use super::config::RuntimeConfig;
use super::error::RuntimeConfigError;

/// What the [`LoopTimer`] measured for one tick, passed to
/// [`ControlLoop::tick`](super::ControlLoop::tick).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickTiming {
    /// When this tick started, in the robot's µs clock (the timestamps of
    /// gyro samples and pose measurements are in the same clock).
    pub now_us: u32,
    /// True time since the previous tick started \[µs\] (the nominal period
    /// on the first tick).
    pub elapsed_us: u32,
    /// `elapsed_us` in whole periods, rounded up, at least 1 (a count-rate
    /// plausibility limit per period scales with it).
    pub elapsed_periods: u32,
    /// How far this tick started behind its scheduled time t₀ + n·period
    /// \[µs\] (0 when on time or early).
    pub lateness_us: u32,
    /// `lateness_us` exceeds the late limit.
    pub late: bool,
    /// This is the first late tick of an overrun episode (the episode ends
    /// with the first tick that is not late).
    pub new_overrun: bool,
    /// Late ticks in a row, this one included (0 when not late).
    pub consecutive_late: u16,
    /// `consecutive_late` reached the limit: the loop cannot keep its
    /// schedule (the runtime latches a stop when running).
    pub sustained_overrun: bool,
}

impl TickTiming {
    /// A tick exactly on schedule for a loop of period `period_us` (for
    /// tests of code that does not care about timing).
    pub const fn on_schedule(period_us: u32) -> Self {
        Self::on_schedule_at(0, period_us)
    }

    /// A tick at `now_us`, exactly on schedule for a loop of period `period_us`.
    pub const fn on_schedule_at(now_us: u32, period_us: u32) -> Self {
        Self {
            now_us,
            elapsed_us: period_us,
            elapsed_periods: 1,
            lateness_us: 0,
            late: false,
            new_overrun: false,
            consecutive_late: 0,
            sustained_overrun: false,
        }
    }

    /// [`Self::elapsed_us`] in seconds.
    pub fn elapsed_s(&self) -> f32 {
        self.elapsed_us as f32 * 1e-6
    }
}

/// Lifetime timing counters of a [`LoopTimer`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TimingStats {
    /// Ticks measured.
    pub ticks: u32,
    /// Ticks that started more than the late limit behind schedule.
    pub late_ticks: u32,
    /// Runs of consecutive late ticks (a stall and the catch-up burst after
    /// it count once).
    pub overrun_episodes: u32,
    /// Largest lateness \[µs\].
    pub max_lateness_us: u32,
    /// Largest time between two ticks \[µs\].
    pub max_elapsed_us: u32,
}

/// Measures every tick against the schedule t₀ + n·period (t₀ = the first
/// tick), counts late ticks and overrun episodes, and flags a sustained
/// overrun.
#[derive(Clone, Debug)]
pub struct LoopTimer {
    period_us: u32,
    late_limit_us: u32,
    max_consecutive_late: u16,
    /// Scheduled start of the next tick.
    due_us: u32,
    prev_us: u32,
    started: bool,
    consecutive_late: u16,
    stats: TimingStats,
}

impl LoopTimer {
    /// A timer for a loop of period `period_us` (> 0): a tick starting more
    /// than `late_limit_us` (> 0) behind schedule is late, and
    /// `max_consecutive_late` (>= 1) late ticks in a row are a sustained
    /// overrun.
    pub fn new(
        period_us: u32,
        late_limit_us: u32,
        max_consecutive_late: u16,
    ) -> Result<Self, RuntimeConfigError> {
        if period_us == 0 || late_limit_us == 0 || max_consecutive_late == 0 {
            return Err(RuntimeConfigError::InvalidSafetyLimit);
        }
        Ok(Self {
            period_us,
            late_limit_us,
            max_consecutive_late,
            due_us: 0,
            prev_us: 0,
            started: false,
            consecutive_late: 0,
            stats: TimingStats::default(),
        })
    }

    /// The timer for `cfg`: the controller's period, the safety limits'
    /// `overrun_limit_us` and `max_consecutive_overruns`.
    pub fn from_config(cfg: &RuntimeConfig) -> Result<Self, RuntimeConfigError> {
        let p = cfg.controller.period_s;
        if !(p.is_finite() && p > 0.0 && p <= 0.1) {
            return Err(RuntimeConfigError::Core(crate::ConfigError::InvalidPeriod));
        }
        let period_us = (p * 1e6 + 0.5) as u32;
        Self::new(
            period_us,
            cfg.safety.overrun_limit_us,
            cfg.safety.max_consecutive_overruns,
        )
    }

    /// The period \[µs\].
    pub fn period_us(&self) -> u32 {
        self.period_us
    }

    /// Counters since construction.
    pub fn stats(&self) -> &TimingStats {
        &self.stats
    }

    /// Restarts the schedule at the next tick (t₀ := its start, elapsed one
    /// period, not late) after a deliberate pause of the loop in hold with
    /// the motors off (a flash erase: robot-app's robot-record write), so
    /// the pause is neither late ticks nor an overrun episode. The
    /// statistics are kept.
    pub fn resync(&mut self) {
        self.started = false;
        self.consecutive_late = 0;
    }

    /// Measures the tick starting at `now_us`.
    pub fn tick(&mut self, now_us: u32) -> TickTiming {
        let p = self.period_us;
        let (elapsed_us, lateness_us) = if self.started {
            let elapsed = now_us.wrapping_sub(self.prev_us);
            // Signed: a tick may start a little before our schedule (its
            // anchor is the first tick's actual start, after wake-up latency).
            let behind = now_us.wrapping_sub(self.due_us) as i32;
            (elapsed, behind.max(0) as u32)
        } else {
            self.started = true;
            self.due_us = now_us;
            (p, 0)
        };
        self.prev_us = now_us;
        self.due_us = self.due_us.wrapping_add(p);

        let late = lateness_us > self.late_limit_us;
        let new_overrun = late && self.consecutive_late == 0;
        self.consecutive_late = if late {
            self.consecutive_late.saturating_add(1)
        } else {
            0
        };
        let s = &mut self.stats;
        s.ticks = s.ticks.saturating_add(1);
        s.late_ticks = s.late_ticks.saturating_add(late as u32);
        s.overrun_episodes = s.overrun_episodes.saturating_add(new_overrun as u32);
        s.max_lateness_us = s.max_lateness_us.max(lateness_us);
        s.max_elapsed_us = s.max_elapsed_us.max(elapsed_us);
        TickTiming {
            now_us,
            elapsed_us,
            elapsed_periods: elapsed_us.div_ceil(p).max(1),
            lateness_us,
            late,
            new_overrun,
            consecutive_late: self.consecutive_late,
            sustained_overrun: self.consecutive_late >= self.max_consecutive_late,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::ControllerKind;
    use crate::runtime::test_doubles::RecordingDriver;
    use crate::runtime::{
        ControlLoop, NoGyro, RunState, StopReason, WheelEncoders, WheelOdometryOnly,
    };

    const P: u32 = 1000;
    /// `SafetyLimits::EXAMPLE`: late beyond 500 µs, 5 in a row sustained.
    fn timer() -> LoopTimer {
        LoopTimer::from_config(&RuntimeConfig::example(ControllerKind::Proposed)).unwrap()
    }

    /// A pause of 3 s followed by `resync` is not late and not an
    /// overrun; without `resync` the same pause is (the check is not blind).
    #[test]
    fn resync_forgives_a_deliberate_pause() {
        for resync in [true, false] {
            let mut t = timer();
            for k in 0..10 {
                t.tick(k * P);
            }
            if resync {
                t.resync();
            }
            let mut late = 0;
            for k in 0..10 {
                let tt = t.tick(3_000_000 + k * P);
                late += tt.late as u32;
                if resync {
                    assert_eq!(tt.elapsed_us, P);
                }
            }
            if resync {
                assert_eq!((late, t.stats().overrun_episodes), (0, 0));
            } else {
                assert!(late == 10 && t.stats().overrun_episodes == 1);
            }
        }
    }

    #[test]
    fn example_limits() {
        let t = timer();
        assert_eq!(t.period_us(), P);
        assert_eq!((t.late_limit_us, t.max_consecutive_late), (500, 5));
    }

    /// Ticks on schedule (with jitter below the limit) across the u32 wrap:
    /// never late, elapsed = the true interval.
    #[test]
    fn on_schedule_with_jitter_across_wrap_is_never_late() {
        let mut t = timer();
        let t0 = u32::MAX - 5_500; // wraps after a few ticks
        for n in 0..20u32 {
            let jitter = [0u32, 40, 499, 7][n as usize % 4];
            let now = t0.wrapping_add(n * P + jitter);
            let r = t.tick(now);
            assert!(!r.late && !r.sustained_overrun, "tick {n}: {r:?}");
            assert_eq!(r.lateness_us, jitter);
            if n > 0 {
                let prev_jitter = [0u32, 40, 499, 7][(n as usize - 1) % 4];
                assert_eq!(r.elapsed_us, P + jitter - prev_jitter);
            }
        }
        assert_eq!(t.stats().late_ticks, 0);
        assert_eq!(t.stats().overrun_episodes, 0);
    }

    /// Every step takes 1.2 ms, so the ticker fires at once each time: the
    /// intervals are a steady 1.2 ms (an interval limit of 1.5 ms never
    /// fires), but tick n starts 200·n µs behind schedule. With the example
    /// limits it is late from n = 3 (600 µs > 500 µs) and sustained at the
    /// fifth late tick, n = 7.
    #[test]
    fn sustained_1200us_steps_are_flagged() {
        let mut t = timer();
        let mut sustained_at = None;
        for n in 0..20u32 {
            let r = t.tick(5_000 + n * 1200);
            if n > 0 {
                assert_eq!(r.elapsed_us, 1200);
                assert_eq!(r.elapsed_periods, 2);
            }
            assert_eq!(r.lateness_us, 200 * n);
            assert_eq!(r.late, n >= 3);
            assert_eq!(r.new_overrun, n == 3);
            if r.sustained_overrun && sustained_at.is_none() {
                sustained_at = Some(n);
            }
        }
        assert_eq!(sustained_at, Some(7));
        assert_eq!(t.stats().overrun_episodes, 1);
        assert_eq!(t.stats().late_ticks, 17);
    }

    /// On schedule, then one step takes 20 ms, then the ticker catches up
    /// with back-to-back ticks 30 µs apart (the step time), then on
    /// schedule again. Tick k after the stall starts 19 000 − 970·k µs
    /// behind, so ticks k = 0..=19 are late: one episode of 20 late ticks
    /// whose consecutive count the burst does not reset.
    #[test]
    fn one_20ms_stall_is_one_episode_not_reset_by_the_burst() {
        let mut t = timer();
        let mut now = 0u32;
        for _ in 0..10 {
            assert!(!t.tick(now).late);
            now += P;
        }
        // The tick at `now - P` ran 20 ms instead of a few µs.
        now = now - P + 20_000;
        let mut k = 0u32;
        loop {
            let r = t.tick(now);
            let behind = 19_000i64 - 970 * k as i64;
            if behind <= 0 {
                break;
            }
            assert_eq!(r.lateness_us as i64, behind, "k={k}");
            assert_eq!(r.late, behind > 500, "k={k}");
            if r.late {
                assert_eq!(r.consecutive_late as u32, k + 1, "burst reset the count");
                assert_eq!(r.new_overrun, k == 0);
                assert_eq!(r.sustained_overrun, k + 1 >= 5);
                assert_eq!(r.elapsed_us, if k == 0 { 20_000 } else { 30 });
            } else {
                assert_eq!(r.consecutive_late, 0);
            }
            now += 30;
            k += 1;
        }
        assert_eq!(t.stats().late_ticks, 20);
        assert_eq!(t.stats().overrun_episodes, 1);
        assert_eq!(t.stats().max_lateness_us, 19_000);
        assert_eq!(t.stats().max_elapsed_us, 20_000);
    }

    /// A single tick 700 µs late: one late tick, one episode, no sustained
    /// overrun, and the count restarts after it.
    #[test]
    fn isolated_late_tick_recovers() {
        let mut t = timer();
        for n in 0..10u32 {
            let late = if n == 4 { 700 } else { 0 };
            let r = t.tick(n * P + late);
            assert_eq!(r.late, n == 4);
            assert_eq!(r.consecutive_late, (n == 4) as u16);
            assert!(!r.sustained_overrun);
        }
        assert_eq!(t.stats().overrun_episodes, 1);
    }

    #[test]
    fn invalid_parameters_rejected() {
        for (p, l, m) in [(0, 500, 5), (1000, 0, 5), (1000, 500, 0)] {
            assert_eq!(
                LoopTimer::new(p, l, m).err(),
                Some(RuntimeConfigError::InvalidSafetyLimit)
            );
        }
        let mut cfg = RuntimeConfig::example(ControllerKind::Proposed);
        cfg.controller.period_s = f32::NAN;
        assert!(LoopTimer::from_config(&cfg).is_err());
    }

    // ---- through the runtime ----

    /// Both wheels turning forward at `rate` rad/s, read as quantized ×4
    /// counts at the tick instants (left counter mirrored).
    struct Wheels {
        rate_radps: f64,
        cpr: f64,
        t_s: f64,
    }
    impl WheelEncoders for Wheels {
        fn counts(&mut self) -> [u16; 2] {
            let c = (self.rate_radps * self.t_s * self.cpr / (2.0 * core::f64::consts::PI)).floor()
                as i64;
            [c as u16, (-c) as u16]
        }
    }

    fn line_cfg() -> RuntimeConfig {
        crate::runtime::test_doubles::line_config(0.5)
    }

    /// Tick start instants \[µs\] of a ticker with period `P` that fires at
    /// once when late (tick n starts at max(n·P, end of tick n − 1)), for
    /// step times of 30 µs, except 30 steps of 1.2 ms from tick 20 and one
    /// 20 ms stall at tick 80: two overrun episodes, each followed by a
    /// catch-up burst of ticks 30 µs apart.
    fn irregular_instants() -> impl Iterator<Item = u32> {
        let mut end = 0u32;
        (0..150u32).map(move |n| {
            let start = end.max(n * P);
            let step_us = match n {
                20..=49 => 1200,
                80 => 20_000,
                _ => 30,
            };
            end = start + step_us;
            start
        })
    }

    /// The wheel-rate estimate uses the true elapsed time: at a constant
    /// 20 rad/s it stays within one count per window time of the truth
    /// through sustained overruns, a stall and the catch-up burst (with
    /// dt = 1 ms it would read 20 % low at 1.2 ms steps and near zero in
    /// the burst).
    #[test]
    fn speed_estimate_sees_the_real_dt() {
        let cfg = line_cfg();
        let mut cl = ControlLoop::new(cfg).unwrap();
        let mut timer = LoopTimer::from_config(&cfg).unwrap();
        let rate = 20.0;
        let cpr = cfg.encoder.counts_per_wheel_rev as f64;
        let r_m = cfg.controller.robot.wheel_radius_m;
        let window = cfg.encoder.speed_window_ticks as usize;
        let mut wheels = Wheels {
            rate_radps: rate,
            cpr,
            t_s: 0.0,
        };
        let mut instants = std::vec::Vec::new();
        for (i, now) in irregular_instants().enumerate() {
            instants.push(now);
            wheels.t_s = now as f64 * 1e-6;
            let timing = timer.tick(now);
            let rep = cl.tick(
                &mut wheels,
                &mut RecordingDriver::default(),
                &mut NoGyro,
                &mut WheelOdometryOnly,
                timing,
            );
            assert_eq!(rep.state, RunState::Disarmed);
            if i > window {
                let span_s = (now - instants[i - window]) as f64 * 1e-6;
                // ±1 count over the window, in wheel rate, then in v = r·ω.
                let bound = 2.0 * core::f64::consts::PI / cpr / span_s * r_m as f64 * 1.0001;
                let truth = rate * r_m as f64;
                let err = (rep.eta.v_mps as f64 - truth).abs();
                assert!(
                    err <= bound,
                    "tick {i}: v {} truth {truth} bound {bound}",
                    rep.eta.v_mps
                );
                assert!(rep.eta.omega_radps.abs() < 1e-3);
            }
        }
        assert_eq!(timer.stats().overrun_episodes, 2);
    }

    /// Overruns latch only while running, at the sustained-overrun tick, and
    /// a stall at speed latches `LoopOverrun`, not an encoder jump (the jump
    /// limit scales with the elapsed periods).
    #[test]
    fn sustained_overrun_latches_only_when_running() {
        let cfg = line_cfg();
        let step = |cl: &mut ControlLoop, timer: &mut LoopTimer, w: &mut Wheels, now: u32| {
            w.t_s = now as f64 * 1e-6;
            let timing = timer.tick(now);
            cl.tick(
                w,
                &mut RecordingDriver::default(),
                &mut NoGyro,
                &mut WheelOdometryOnly,
                timing,
            )
        };
        // 40 rad/s (the example motor's no-load speed): 153 counts per ms,
        // 3056 in the 20 ms stall, beyond the 400 counts/period jump limit.
        let mut w = Wheels {
            rate_radps: 40.0,
            cpr: cfg.encoder.counts_per_wheel_rev as f64,
            t_s: 0.0,
        };
        // Disarmed: counted, never latched.
        let mut cl = ControlLoop::new(cfg).unwrap();
        let mut timer = LoopTimer::from_config(&cfg).unwrap();
        for now in irregular_instants() {
            assert_eq!(step(&mut cl, &mut timer, &mut w, now).stopped, None);
        }
        assert_eq!(cl.status().overruns, 2);
        assert_eq!(cl.status().encoder_jumps, 0);

        // Running, 20 ms stall then the burst: latched on the fifth late tick.
        let mut cl = ControlLoop::new(cfg).unwrap();
        let mut timer = LoopTimer::from_config(&cfg).unwrap();
        cl.arm().unwrap();
        let mut now = 0;
        for _ in 0..10 {
            assert_eq!(step(&mut cl, &mut timer, &mut w, now).stopped, None);
            now += P;
        }
        now += 19_000;
        let mut stopped = None;
        for k in 0..10u32 {
            let rep = step(&mut cl, &mut timer, &mut w, now);
            if let Some(r) = rep.stopped {
                stopped = Some((k, r));
                break;
            }
            now += 30;
        }
        let (k, reason) = stopped.expect("no stop");
        assert_eq!(k, 4);
        assert_eq!(
            reason,
            StopReason::LoopOverrun {
                lateness_us: 19_000 - 4 * 970
            }
        );
        assert_eq!(cl.status().encoder_jumps, 0);
        assert_eq!(cl.status().overruns, 1);
        assert_eq!(cl.status().consecutive_overruns, 5);
    }
}
