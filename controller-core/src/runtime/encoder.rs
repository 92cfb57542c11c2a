//! Quadrature encoder counts: 16-bit wrap-around, per-tick deltas and a
//! windowed wheel-rate estimate.

use super::error::RuntimeConfigError;
use super::hardware::Wheel;

/// Largest speed-estimation window \[ticks\] ([`EncoderParams::speed_window_ticks`]).
pub const MAX_SPEED_WINDOW: usize = 32;

/// Signed count change from `prev` to `now` of a free-running 16-bit
/// counter, assuming it moved less than half a revolution of the counter
/// (|Δ| < 32768) since the last read.
///
/// `0xFFFF -> 0x0002` is `+3`; `0x0002 -> 0xFFFF` is `-3`.
#[inline]
pub const fn count_delta(prev: u16, now: u16) -> i16 {
    now.wrapping_sub(prev) as i16
}

/// How raw counts relate to wheel rotation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EncoderParams {
    /// Counts per wheel revolution \[counts/rev\], after quadrature decoding
    /// (×4 of the encoder's lines) and through the gearbox when the encoder
    /// sits on the motor shaft: `lines × 4 × gear_ratio`.
    pub counts_per_wheel_rev: f32,
    /// Per wheel `[right, left]`: true when the counter counts down while
    /// the wheel drives the robot forward (mirrored mounting).
    pub inverted: [bool; 2],
    /// Window N \[ticks\] of the rate estimate
    /// `(count_k − count_{k−N}) / (t_k − t_{k−N})` (the true time the N
    /// ticks took), in `1..=`[`MAX_SPEED_WINDOW`].
    /// Larger N: finer speed quantization (one count per N·dt) but a group
    /// delay of N·dt/2.
    pub speed_window_ticks: u8,
    /// Per wheel `[right, left]`: the wheel's radius over the controller
    /// model's (mean) radius, r_i/r̄, in [`Self::RADIUS_SCALE_RANGE`]. The
    /// runtime's wheel angle per count is `2π·radius_scale/cpr`, so the
    /// model's r̄ times it is the wheel's true arc per count (book/src/explanation/decisions.md
    /// D60). 1 for equal wheels.
    pub radius_scale: [f32; 2],
}

impl EncoderParams {
    /// Example: 500-line encoder on the motor shaft, 12:1 gearbox
    /// (24 000 counts per wheel revolution), left encoder mirrored, 4-tick window.
    pub const EXAMPLE: Self = Self {
        counts_per_wheel_rev: 24_000.0,
        inverted: super::hardware::MIRRORED_LEFT,
        speed_window_ticks: 4,
        radius_scale: [1.0; 2],
    };

    /// Accepted [`Self::radius_scale`]: the wheels may differ from their
    /// mean by at most 10 %.
    pub const RADIUS_SCALE_RANGE: (f32, f32) = (0.9, 1.1);

    /// Checks the resolution and the window.
    pub fn validate(self) -> Result<Self, RuntimeConfigError> {
        if !(self.counts_per_wheel_rev.is_finite() && self.counts_per_wheel_rev > 0.0) {
            return Err(RuntimeConfigError::NonPositiveEncoderResolution);
        }
        let n = self.speed_window_ticks as usize;
        if n == 0 || n > MAX_SPEED_WINDOW {
            return Err(RuntimeConfigError::InvalidSpeedWindow);
        }
        let (lo, hi) = Self::RADIUS_SCALE_RANGE;
        if !self.radius_scale.iter().all(|s| (lo..=hi).contains(s)) {
            return Err(RuntimeConfigError::InvalidRadiusScale);
        }
        Ok(self)
    }

    /// Wheel angle per count of a wheel of the model's radius \[rad/count\]
    /// `[right, left]`: `2π·radius_scale/cpr`.
    pub fn rad_per_count(&self) -> [f32; 2] {
        let base = 2.0 * core::f32::consts::PI / self.counts_per_wheel_rev;
        [base * self.radius_scale[0], base * self.radius_scale[1]]
    }

    /// The windowed rate estimate's resolution \[rad/s\]: one count of
    /// the coarser wheel over one speed window of `period_s` ticks.
    pub fn rate_quantum_radps(&self, period_s: f32) -> f32 {
        let [q0, q1] = self.rad_per_count();
        q0.max(q1) / (self.speed_window_ticks as f32 * period_s)
    }
}

/// Per-wheel count tracking: previous raw count, accumulated position and
/// the history window of the rate estimate.
#[derive(Clone, Debug)]
pub struct WheelCounts {
    params: EncoderParams,
    rad_per_count: [f32; 2],
    prev_raw: [u16; 2],
    primed: bool,
    /// Accumulated signed position \[counts\] (wrapping i32).
    position: [i32; 2],
    /// Ring buffer of past positions, `history[head]` is the oldest.
    history: [[i32; 2]; MAX_SPEED_WINDOW],
    /// Elapsed time \[s\] of the tick that produced each `history` entry.
    dt_history: [f32; MAX_SPEED_WINDOW],
    head: usize,
    filled: usize,
    /// Last rate, kept when a window's time is zero.
    last_rate: [f32; 2],
    /// The coarser wheel's angle per count \[rad\].
    coarse_rad_per_count: f32,
}

/// One tick's encoder result.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CountSample {
    /// Signed count change this tick `[right, left]`, forward positive
    /// (after [`EncoderParams::inverted`]).
    pub delta: [i32; 2],
    /// Wheel angle change this tick \[rad\] `[right, left]`.
    pub dphi_rad: [f32; 2],
    /// Windowed wheel-rate estimate \[rad/s\] `[right, left]`.
    pub rate_radps: [f32; 2],
    /// The estimate's resolution this tick \[rad/s\]: one count of the
    /// coarser wheel over the window's true span (coarser while the window
    /// fills after a start: one count over the ticks seen so far; 0 when no
    /// time passed). Each wheel's true mean rate over the window is within
    /// this of its `rate_radps`.
    pub rate_quantum_radps: f32,
}

impl WheelCounts {
    /// Tracker for validated `params`; the first [`Self::update`] only
    /// primes the previous counts (delta 0).
    pub fn new(params: EncoderParams) -> Result<Self, RuntimeConfigError> {
        let params = params.validate()?;
        Ok(Self {
            params,
            rad_per_count: params.rad_per_count(),
            coarse_rad_per_count: {
                let [a, b] = params.rad_per_count();
                a.max(b)
            },
            prev_raw: [0; 2],
            primed: false,
            position: [0; 2],
            history: [[0; 2]; MAX_SPEED_WINDOW],
            dt_history: [0.0; MAX_SPEED_WINDOW],
            head: 0,
            filled: 0,
            last_rate: [0.0; 2],
        })
    }

    /// The parameters.
    pub fn params(&self) -> &EncoderParams {
        &self.params
    }

    /// The last windowed wheel-rate estimate \[rad/s\] `[right, left]`
    /// (0 before the first update).
    pub fn last_rate_radps(&self) -> [f32; 2] {
        self.last_rate
    }

    /// Signed per-tick deltas `[right, left]` of new raw counts, forward
    /// positive, without changing any state (for plausibility checks before
    /// [`Self::update`]).
    pub fn peek_delta(&self, raw: [u16; 2]) -> [i32; 2] {
        if !self.primed {
            return [0; 2];
        }
        let mut d = [0i32; 2];
        for w in Wheel::BOTH {
            let i = w.index();
            let x = count_delta(self.prev_raw[i], raw[i]) as i32;
            d[i] = if self.params.inverted[i] { -x } else { x };
        }
        d
    }

    /// Takes new raw counts as the reference for the next delta without
    /// integrating the change (used after an implausible jump).
    pub fn resync(&mut self, raw: [u16; 2]) {
        self.prev_raw = raw;
        self.primed = true;
    }

    /// Accepts new raw counts: integrates the delta and updates the rate
    /// estimate. `dt_s` is the true time since the previous update \[s\]
    /// (>= 0; see [`TickTiming`](super::TickTiming)): the rate is the count
    /// change over the window divided by the sum of its ticks' `dt_s`, so
    /// late or bunched-up ticks do not bias it.
    pub fn update(&mut self, raw: [u16; 2], dt_s: f32) -> CountSample {
        let delta = self.peek_delta(raw);
        self.apply(raw, delta, dt_s)
    }

    /// [`Self::update`] with `delta` = [`Self::peek_delta`]`(raw)` already
    /// computed (the runtime peeks first to check for jumps).
    pub(crate) fn apply(&mut self, raw: [u16; 2], delta: [i32; 2], dt_s: f32) -> CountSample {
        debug_assert_eq!(delta, self.peek_delta(raw));
        self.resync(raw);
        for (p, d) in self.position.iter_mut().zip(delta) {
            *p = p.wrapping_add(d);
        }
        // Window of positions: push the new one, rate over the oldest kept.
        let n = self.params.speed_window_ticks as usize;
        let oldest = if self.filled == 0 {
            self.position
        } else {
            // Element `min(filled, n)` ticks ago.
            let back = self.filled.min(n);
            let idx = (self.head + MAX_SPEED_WINDOW - back) % MAX_SPEED_WINDOW;
            self.history[idx]
        };
        // Time from the oldest kept position to now: this tick's dt plus
        // the dts of the ticks after the oldest one.
        let back = self.filled.min(n);
        let mut span_s = dt_s;
        for j in 1..back {
            span_s += self.dt_history[(self.head + MAX_SPEED_WINDOW - j) % MAX_SPEED_WINDOW];
        }
        self.history[self.head] = self.position;
        self.dt_history[self.head] = dt_s;
        self.head = (self.head + 1) % MAX_SPEED_WINDOW;
        self.filled = (self.filled + 1).min(MAX_SPEED_WINDOW);
        let mut rate = [0.0f32; 2];
        let mut dphi = [0.0f32; 2];
        for i in 0..2 {
            let counts = self.position[i].wrapping_sub(oldest[i]) as f32;
            rate[i] = if self.filled <= 1 {
                0.0
            } else if span_s > 0.0 {
                counts * self.rad_per_count[i] / span_s
            } else {
                self.last_rate[i] // no time passed (never on a real clock)
            };
            dphi[i] = delta[i] as f32 * self.rad_per_count[i];
        }
        self.last_rate = rate;
        let quantum = if span_s > 0.0 {
            self.coarse_rad_per_count / span_s
        } else {
            0.0
        };
        CountSample {
            delta,
            dphi_rad: dphi,
            rate_radps: rate,
            rate_quantum_radps: quantum,
        }
    }

    /// Accumulated forward position \[counts\] `[right, left]` since construction.
    pub fn position_counts(&self) -> [i32; 2] {
        self.position
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    #[test]
    fn delta_wraps_both_ways() {
        assert_eq!(count_delta(0xFFFF, 0x0002), 3);
        assert_eq!(count_delta(0x0002, 0xFFFF), -3);
        assert_eq!(count_delta(100, 100), 0);
        assert_eq!(count_delta(0x7FF0, 0x8010), 0x20);
        assert_eq!(count_delta(0, 32767), 32767);
        assert_eq!(count_delta(0, 32768), -32768);
    }

    fn params(cpr: f32, window: u8) -> EncoderParams {
        EncoderParams {
            counts_per_wheel_rev: cpr,
            inverted: [false, true],
            speed_window_ticks: window,
            ..EncoderParams::EXAMPLE
        }
    }

    /// Each wheel's arc per count is right with unequal wheels: a wheel 5 %
    /// larger than the mean advances 5 % more per count in the model's
    /// radius, and a scale outside 0.9..=1.1 is refused.
    #[test]
    fn radius_scale_makes_each_wheels_arc_right() {
        let p = EncoderParams {
            radius_scale: [1.05, 0.95],
            ..params(1000.0, 1)
        };
        let mut wc = WheelCounts::new(p).unwrap();
        wc.update([0, 0], 1e-3);
        // Right +100 counts; the left counter is inverted, so -100 raw is +100.
        let s = wc.update([100, 0u16.wrapping_sub(100)], 1e-3);
        let true_angle = 100.0 * 2.0 * PI / 1000.0;
        assert!((s.dphi_rad[0] - 1.05 * true_angle).abs() < 1e-5);
        assert!((s.dphi_rad[1] - 0.95 * true_angle).abs() < 1e-5);
        for bad in [0.89, 1.11, f32::NAN] {
            let p = EncoderParams {
                radius_scale: [1.0, bad],
                ..params(1000.0, 1)
            };
            assert_eq!(p.validate(), Err(RuntimeConfigError::InvalidRadiusScale));
        }
    }

    /// A wheel turning at a constant number of counts per tick, across the
    /// 16-bit wrap, accumulates exactly k·n counts and its rate is
    /// 2π·n/(cpr·dt) (and the inverted left counter still reads forward).
    #[test]
    fn constant_rate_across_wrap() {
        let cpr = 4000.0;
        let dt = 1e-3;
        let mut wc = WheelCounts::new(params(cpr, 8)).unwrap();
        let per_tick = 37i32;
        let mut raw_r: u16 = 65_000;
        let mut raw_l: u16 = 500;
        wc.update([raw_r, raw_l], dt);
        let mut last = CountSample::default();
        for _ in 0..200 {
            raw_r = raw_r.wrapping_add(per_tick as u16);
            raw_l = raw_l.wrapping_sub(per_tick as u16); // mirrored: counts down going forward
            last = wc.update([raw_r, raw_l], dt);
        }
        assert_eq!(wc.position_counts(), [200 * per_tick, 200 * per_tick]);
        let expect = 2.0 * PI * per_tick as f32 / (cpr * dt);
        for i in 0..2 {
            assert_eq!(last.delta[i], per_tick);
            assert!((last.rate_radps[i] - expect).abs() < 1e-3 * expect);
            assert!((last.dphi_rad[i] - expect * dt).abs() < 1e-6);
        }
    }

    /// One count every 4 ticks: a 1-tick window reads 0 or a full count per
    /// tick, an 8-tick window reads the true average (2 counts per 8 ticks).
    #[test]
    fn window_averages_slow_rates() {
        let dt = 1e-3;
        let cpr = 1000.0;
        let mut w1 = WheelCounts::new(params(cpr, 1)).unwrap();
        let mut w8 = WheelCounts::new(params(cpr, 8)).unwrap();
        let mut raw = 0u16;
        let mut s8 = CountSample::default();
        let mut max1 = 0.0f32;
        for k in 0..100 {
            if k % 4 == 0 {
                raw = raw.wrapping_add(1);
            }
            let s1 = w1.update([raw, 0], dt);
            s8 = w8.update([raw, 0], dt);
            max1 = max1.max(s1.rate_radps[0]);
        }
        let count_rate = 2.0 * PI / cpr / dt; // one count in one tick
        assert!((max1 - count_rate).abs() < 1e-3);
        let truth = count_rate / 4.0;
        assert!((s8.rate_radps[0] - truth).abs() < 1e-3 * truth);
    }

    /// Irregular ticks (0.5 ms and 1.5 ms alternating, as a late tick
    /// followed by a catch-up one) at one count per tick: the window rate
    /// divides by the true window time, so a 4-tick window reads exactly
    /// 4 counts per 4 ms, and a 1-tick window reads each tick's own rate.
    #[test]
    fn window_uses_true_elapsed_time() {
        let cpr = 1000.0;
        let mut w4 = WheelCounts::new(params(cpr, 4)).unwrap();
        let mut w1 = WheelCounts::new(params(cpr, 1)).unwrap();
        let mut raw = 0u16;
        let count_rad = 2.0 * PI / cpr;
        for k in 0..20 {
            let dt = if k % 2 == 0 { 0.5e-3 } else { 1.5e-3 };
            raw = raw.wrapping_add(1);
            let s4 = w4.update([raw, 0], dt);
            let s1 = w1.update([raw, 0], dt);
            if k >= 4 {
                let expect = count_rad / 1e-3; // 4 counts in 4 ms
                assert!((s4.rate_radps[0] - expect).abs() < 1e-3 * expect, "{k}");
                let own = count_rad / dt;
                assert!((s1.rate_radps[0] - own).abs() < 1e-3 * own, "{k}");
            }
        }
    }

    #[test]
    fn peek_does_not_change_state_and_resync_drops_jump() {
        let mut wc = WheelCounts::new(params(1000.0, 2)).unwrap();
        wc.update([10, 10], 1e-3);
        assert_eq!(wc.peek_delta([5010, 10]), [5000, 0]);
        wc.resync([5010, 10]);
        let s = wc.update([5012, 10], 1e-3);
        assert_eq!(s.delta, [2, 0]);
        assert_eq!(wc.position_counts(), [2, 0]);
    }

    #[test]
    fn invalid_params_rejected() {
        assert_eq!(
            WheelCounts::new(params(0.0, 2)).err(),
            Some(RuntimeConfigError::NonPositiveEncoderResolution)
        );
        assert_eq!(
            WheelCounts::new(params(f32::NAN, 2)).err(),
            Some(RuntimeConfigError::NonPositiveEncoderResolution)
        );
        assert_eq!(
            WheelCounts::new(params(100.0, 0)).err(),
            Some(RuntimeConfigError::InvalidSpeedWindow)
        );
        assert_eq!(
            WheelCounts::new(params(100.0, 33)).err(),
            Some(RuntimeConfigError::InvalidSpeedWindow)
        );
    }
}
